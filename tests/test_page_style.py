"""The results page and the API's plots: no two schemes of a figure share a colour, a scheme
has one colour and one marker across the figures of a page; a crowded figure greys the schemes off the Pareto front; the
capability matrix says "lost" where a scheme lost the solution; the inline SVGs share no id."""
import re
from collections import Counter

import pytest

import longtime
from longtime.reporting.figures.style import GREY, MARKERS, PALETTE, emphasis, scheme_style, styles, unique_ids


@pytest.fixture(scope="module")
def rows():
    return longtime.sweep("kepler", ["verlet", "rk4"], dt=[0.02, 0.01], t_final=10, executor="serial",
                          repeats=1).to_dict("records")


def test_a_scheme_has_the_same_colour_in_every_figure_of_a_page(rows):
    from longtime import plot
    from longtime.reporting.figures.results import drift_svg, work_precision_svg
    from longtime.reporting.figures.verdict import scheme_colours

    page = styles(["verlet", "rk4", "euler", "dop853", "heyoka"])  # the page's schemes
    colour, other = page["verlet"]["color"], page["rk4"]["color"]
    assert colour != other
    precision = work_precision_svg(rows, "l2_error", page)
    drift, _ = drift_svg(rows, page)
    for figure in (precision, drift):
        assert f"stroke: {colour}" in figure and f"stroke: {other}" in figure
    assert scheme_colours(["verlet", "rk4"], page)["verlet"] == colour  # the winner maps
    assert scheme_colours(["verlet"])["verlet"] == scheme_style("verlet")["color"]  # a map drawn alone
    assert plot.scheme_styles(["verlet", "euler"]) == styles(["verlet", "euler"])  # the API's plots


def _lab(colour: str) -> tuple[float, float, float]:
    """CIELAB of an sRGB hex colour (D65)."""
    r, g, b = (int(colour[i:i + 2], 16) / 255 for i in (1, 3, 5))
    r, g, b = (((c + 0.055) / 1.055) ** 2.4 if c > 0.04045 else c / 12.92 for c in (r, g, b))
    x = (0.4124 * r + 0.3576 * g + 0.1805 * b) / 0.95047
    y = 0.2126 * r + 0.7152 * g + 0.0722 * b
    z = (0.0193 * r + 0.1192 * g + 0.9505 * b) / 1.08883
    f = [c ** (1 / 3) if c > 0.008856 else 7.787 * c + 16 / 116 for c in (x, y, z)]
    return 116 * f[1] - 16, 500 * (f[0] - f[1]), 200 * (f[1] - f[2])


def _delta_e(a: str, b: str) -> float:
    return sum((p - q) ** 2 for p, q in zip(_lab(a), _lab(b))) ** 0.5


@pytest.mark.parametrize("n", [2, 7, 10, 14, 20])
def test_no_two_schemes_of_a_figure_share_a_colour(n):
    from longtime.core import registry

    own = sorted(name for name, c in registry.integrators().items() if c.__module__.startswith("longtime."))
    # schemes whose own looks (by their place among all) collide: every 20th by name
    for schemes in (own[:n], own[::20][:n] + own[1::20][:max(0, n - len(own[::20]))], own[-n:]):
        colours = [c["color"] for c in styles(schemes).values()]
        assert len(set(colours)) == len(colours) == len(set(schemes))
        # told apart by eye: at least 23 apart in CIELAB (about 10 just-noticeable differences)
        assert min(_delta_e(a, b) for k, a in enumerate(colours) for b in colours[k + 1:]) > 23
        assert min(_delta_e(c, GREY) for c in colours) > 23 and min(_delta_e(c, "#ffffff") for c in colours) > 40
    # henon-heiles as in the report of three schemes in one green
    seven = ["rk4", "verlet", "gauss4", "yoshida8", "rk45", "heyoka", "symplectic-euler"]
    colours = [c["color"] for c in styles(seven).values()]
    assert min(_delta_e(a, b) for k, a in enumerate(colours) for b in colours[k + 1:]) > 27
    # past twenty the colours repeat, the (colour, marker) pairs do not
    many = styles(own[:40])
    assert len({(c["color"], c["marker"]) for c in many.values()}) == len(many)


def test_the_looks_follow_a_fixed_rule():
    from longtime.core import registry

    own = sorted(n for n, c in registry.integrators().items() if c.__module__.startswith("longtime."))
    looks = [(scheme_style(s)["color"], scheme_style(s)["marker"]) for s in own]
    assert len(set(looks)) == len(own)  # every built-in scheme its own pair
    assert looks[0] == (PALETTE[0], MARKERS[0]) and looks[1] == (PALETTE[1], MARKERS[1])
    plugin = scheme_style("some-plugin-scheme")
    assert (plugin["color"], plugin["marker"]) not in looks and plugin == scheme_style("some-plugin-scheme")


def test_a_crowded_figure_greys_the_schemes_off_the_front():
    schemes = [f"s{k}" for k in range(12)]
    style = {s: {"color": "#123456", "marker": "o"} for s in schemes}
    shown, greyed = emphasis(style, schemes, ["s0", "s5"])
    assert greyed == set(schemes) - {"s0", "s5"} and shown["s3"]["color"] == GREY and shown["s5"] == style["s5"]
    assert emphasis(style, schemes[:10], ["s0"]) == (style, set())


def test_the_capability_matrix_flags_a_lost_solution():
    from longtime.reporting.page_tables import capability_matrix

    rows = [{"problem": "kepler", "integrator": "euler", "status": "ok", "solution_lost": True},
            {"problem": "kepler", "integrator": "euler", "status": "ok", "solution_lost": True},
            {"problem": "kepler", "integrator": "rk4", "status": "ok", "solution_lost": False},
            {"problem": "fpu", "integrator": "rk4", "status": "ok", "solution_lost": True},
            {"problem": "fpu", "integrator": "rk4", "status": "ok"}]
    html = capability_matrix(rows)
    cells = re.findall(r'<td class="(\w+) cap"[^>]*>([^<]*)</td>', html)
    # schemes by name, problems by name: euler (fpu: not in the run), rk4 on fpu, rk4 on kepler
    assert cells == [("lost", "lost"), ("lost", "lost 1/2"), ("ok", "ok")]


def test_the_inline_figures_share_no_id(rows):
    from longtime.reporting.page import build_page

    page = build_page(rows, [], drift=True, jobs=1)
    ids = Counter(re.findall(r'\bid="([^"]+)"', page))
    assert len(ids) > 20 and [k for k, n in ids.items() if n > 1] == []
    # every reference to an id points at one of the page's
    refs = set(re.findall(r'url\(#([^)]+)\)', page)) | set(re.findall(r'href="#([^"]+)"', page))
    assert refs <= set(ids)
    svg = '<svg><defs><path id="m1"/></defs><use xlink:href="#m1"/><g clip-path="url(#m1)"/></svg>'
    once, twice = unique_ids(svg), unique_ids(svg)
    assert once != twice and 'xlink:href="#' in once and re.search(r'id="(f\w+-m1)"', once)


def test_winners_of_one_map_whose_colours_are_alike_are_told_apart_by_a_hatch():
    from longtime.reporting.figures.verdict import HATCHES, hatches

    colours = {"a": "#1f77b4", "b": "#3182bd", "c": "#d62728", "d": "#1f77b4"}  # b and d: blues like a's
    found = hatches(["a", "b", "c", "d"], colours)
    assert found == {"a": HATCHES[0], "b": HATCHES[1], "c": HATCHES[0], "d": HATCHES[2]}


def test_the_page_says_which_library_keeps_a_target_cheapest_per_problem():
    from longtime.reporting.libraries import library_of, library_table
    from longtime.reporting.page import build_page

    def row(scheme, cpu, err, t_final=10.0, status="ok", lost=False):
        return {"problem": "kepler", "integrator": scheme, "status": status, "t_final": t_final, "cpu_s": cpu,
                "l2_error": err, "solution_lost": lost, "dt": 0.01, "tol": None, "wall_s": cpu, "id": 1}

    rows = [row("rk4", 0.5, 1e-7), row("verlet", 0.1, 1e-3), row("gauss4", 0.3, 1e-8),
            row("scipy-rk45", 0.9, 1e-7), row("scipy-radau", 0.2, 1e-7, t_final=1.0),
            row("heyoka", 0.05, 1e-12, lost=True), row("heyoka", 0.08, 1e-12)]
    assert library_of("scipy-rk45") == "scipy" and library_of("gauss4") == "longtime"
    header, body = library_table(rows)
    assert header == ["problem", "T", "longtime", "heyoka", "scipy"]
    (kepler,) = body
    # the cheapest setting that keeps 1e-6, of each library: gauss4 (not verlet, which misses it);
    # heyoka's lost run is not counted; scipy's radau ran a shorter T and is not compared
    assert kepler[2].startswith("gauss4 ") and "0.3 s" in kepler[2]
    assert kepler[3].startswith("heyoka ") and "0.08 s" in kepler[3]
    assert kepler[4].startswith("scipy-rk45 ") and "0.9 s" in kepler[4]
    page = build_page(rows, [], drift=False, stability=False)
    assert 'id="libraries"' in page and "scipy-rk45" in page[page.index('id="libraries"'):]


def test_which_library_gives_the_ratio_to_the_best_and_why_a_library_has_no_entry():
    from longtime.reporting.libraries import best_of_library, library_table

    def row(scheme, cpu, err, status="ok", t_reached=10.0, tol=None):
        return {"problem": "toda", "integrator": scheme, "status": status, "t_final": 10.0, "cpu_s": cpu,
                "l2_error": err, "solution_lost": False, "dt": 0.1, "tol": tol, "wall_s": cpu, "id": 1,
                "t_reached": t_reached}

    rows = [row("gauss4", 0.2, 1e-8), row("scipy-rk45", 0.5, 1e-7, tol=1e-10),
            row("cvode-adams", 3.0, None, status="timeout", t_reached=2.5, tol=1e-13),
            row("cvode-adams", 0.1, 1e-4, tol=1e-7), row("diffrax-tsit5", None, None, status="skipped")]
    rows[-1]["message"] = 'diffrax-tsit5 needs the package diffrax: pip install "longtime[diffrax]"'
    header, (toda,) = library_table(rows)
    assert header == ["problem", "T", "longtime", "diffrax", "scipy", "sundials"]
    cells = dict(zip(header, toda))
    assert cells["longtime"].endswith("best") and cells["scipy"].endswith("x2.5")
    assert cells["diffrax"] == "not installed"
    # an ok setting that misses the target beside a timeout at the same T: none keeps it, and the
    # tighter setting was too slow
    assert cells["sundials"] == ("none keeps it (best 0.0001: cvode-adams tol=1e-07); "
                                 "too slow: cvode-adams tol=1e-13 ran 3 s for t=2.5 of 10")
    slow = [r for r in rows if r["status"] == "timeout"]
    (only,) = library_table(rows[:1] + slow)[1]
    assert only[3] == "too slow: cvode-adams tol=1e-13 ran 3 s for t=2.5 of 10"
    assert best_of_library(rows, "scipy") == {"toda": cells["scipy"]} and best_of_library(rows, "nope") == {}
