"""The results page: built from a tiny real run, its content checked, and opened in a real
browser (headless Chromium) that must render every figure without a console message."""
import os
import re
import shutil
import subprocess
from pathlib import Path

import pytest

from longtime.commands import cli
from longtime.execution.store import Store
from longtime.reporting.report import pareto, summary

ARTEFACTS = Path(os.environ.get("LONGTIME_TEST_ARTEFACTS", Path(__file__).resolve().parents[1] / "test-artefacts"))
BROWSERS = ("chromium", "chromium-browser", "google-chrome", "chrome")


def figures_beside_the_checks(text: str) -> int:
    """The figures of a page outside its checks section: the checks a matrix re-runs, and so
    their figure, depend on the rows' CPU times (the checks' budget), which the machine's
    load decides; every other figure does not."""
    head, rest = text.split('<h2 id="checks">', 1) if '<h2 id="checks">' in text else (text, "")
    tail = rest[rest.find("<h2 "):] if "<h2 " in rest else ""
    return (head + tail).count('<figure class="plot">')


@pytest.fixture(scope="module")
def page(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("html")
    db = tmp / "runs.sqlite"
    # a tiny matrix: two problems, a skipped pair (dirac-1 needs constraints), a dt sweep for the order fit
    assert cli.main(["matrix", "-p", "harmonic,kepler", "-i", "rk4,verlet,dirac-1", "--dt", "0.04,0.02,0.01",
                     "--t-final", "20", "--repeats", "3", "--min-time", "0", "--db", str(db),
                     "--executor", "serial", "--no-progress", "--no-report"]) == 0
    assert cli.main(["report", "--db", str(db), "--html", str(tmp / "page")]) == 0
    return tmp / "page" / "index.html", Store(db).rows()


def test_page_content(page):
    path, rows = page
    text = path.read_text()
    # nothing loaded from anywhere but the page's own folder (SVG namespaces are names, not loads)
    assert not re.search(r"""(src|href)=["']?(https?:|//)|url\(\s*["']?https?:|@import""", text)
    # the folder is complete: every figure an <img> of an SVG file beside the page, with its size
    assert "<svg" not in text
    images = re.findall(r'<img src="([^"]+)" loading="lazy" alt="[^"]+" width="(\d+)" height="(\d+)">', text)
    assert len(images) == text.count("<img") == 7
    for src, width, height in images:
        figure = path.parent / src
        assert src.startswith("figures/") and figure.is_file() and int(width) > 50 and int(height) > 50
        assert figure.read_text().lstrip().startswith("<?xml") and "<svg" in figure.read_text()
    assert sorted(f.name for f in (path.parent / "figures").iterdir()) == sorted(Path(s).name for s, _, _ in images)
    # the winner map, work-precision and drift per problem, and the run's calibrations
    assert figures_beside_the_checks(text) == 7
    assert "14 cells</b> (12 ok, 2 skipped)" in text
    assert 'title="skipped: needs constraints, which harmonic does not provide">-<' in text
    # measured from the schemes' own steps: RK4's 2 sqrt 2 and Verlet's 2 on the imaginary axis
    assert "<td>rk4</td><td>[0, 2.82]" in text and "<td>verlet</td><td>[0, 2]" in text
    assert re.search(r"<td>commit</td><td>[0-9a-f]{7,}|<td>commit</td><td>-", text)
    # rk4 on the harmonic oscillator: the fitted order is 4 and its interval holds it
    m = re.search(r"<td>rk4</td><td class=\"num\">4</td><td class=\"num\">([0-9.]+)</td>"
                  r"<td class=\"num\">\+- ([0-9.]+)</td>", text)
    assert m and abs(float(m.group(1)) - 4) <= max(float(m.group(2)), 0.1)


def test_summary_starts_with_counts_and_pareto(page):
    _, rows = page
    text = summary(rows)
    assert text.startswith("14 cells: 12 ok, 2 skipped")
    harmonic = [r for r in rows if r["problem"] == "harmonic"]
    front = pareto(harmonic)
    assert front and front[0]["target"] == 0.1
    # the fastest row meeting each target is never slower than one that meets a looser target
    cpu = [p["best"]["cpu_s"] for p in front]
    assert cpu == sorted(cpu)
    for p in front:
        # ranked by the largest error over the run (the verdict's measure), not its RMS
        assert p["field"] == "max_error"
        meets = [r for r in harmonic if r["status"] == "ok" and r["max_error"] <= p["target"]]
        assert p["best"]["cpu_s"] == min(r["cpu_s"] for r in meets)
    # a screen per problem: the verdict first, then what failed, the Pareto front
    for part in text.split("\n\n")[1:]:
        lines = part.splitlines()
        assert len(lines) <= 60 and lines[1].startswith("  verdict:"), part


def test_page_leads_with_the_verdict(page):
    """The page's order: the answers (one row per problem) and which library on the first
    screen, the verdict per problem (an answer, the winner map), the checks, the evidence
    (folded), the capability matrix, the run and machine last; the footer names the command
    that wrote it."""
    path, _ = page
    text = path.read_text()
    order = ['<nav><b>Contents:</b>', '<h2 id="answers">', '<table class="answers">', '<h2 id="libraries">',
             '<h2 id="verdict">', '<h3 id="verdict-harmonic">', 'class="answer"', "Winner map:",
             '<h3 id="verdict-kepler">', '<h2 id="checks">', '<h2 id="evidence">', '<h3 id="harmonic">',
             "<details><summary>Fastest scheme per accuracy", '<h2 id="capabilities">', '<h2 id="about">',
             'class="meta"', "by <code>longtime report --html</code>"]
    at = [text.find(x) for x in order]
    assert -1 not in at and at == sorted(at), dict(zip(order, at))
    # the answers table: a row per problem, linked to its verdict
    answers = text[text.find('<table class="answers">'):text.find('<h2 id="libraries">')]
    assert '<a href="#verdict-harmonic">harmonic</a>' in answers and '<a href="#verdict-kepler">kepler</a>' in answers
    # the calibration and the metadata come after everything else
    assert text.find("<figcaption>Run 1: the reference workload") > text.find('<h2 id="about">')


def test_the_answers_say_why_which_library_names_another_setting(page):
    """The Answers (predicted a hundred times past the runs) and "Which library" (measured at
    the runs' final time) ask different questions: where the library table's cheapest setting
    is not the answer, the Answers section names it and why; where it is, nothing is added."""
    from longtime.predict.decision import verdicts
    from longtime.reporting.libraries import cheapest_kept
    from longtime.reporting.page_answers import example_answer, why_not_library_best

    path, rows = page
    text = path.read_text()
    answers = text[text.find('<h2 id="answers">'):text.find('<h2 id="libraries">')]
    for p, v in verdicts(rows).items():
        mine = [r for r in rows if r["problem"] == p]
        found = example_answer(v)
        library = cheapest_kept(mine)
        if found is None or library is None:
            continue
        t, h, d = found
        note = f"{p}: Which library&#x27;s cheapest, {library['integrator']}"
        why = why_not_library_best(v, t, h, d.best, mine)
        assert (note in answers) == (why is not None), (p, why)
        # an answer other than the library's setting: the line names that setting and a reason
        other = next(c for c in v.candidates if c.scheme != library["integrator"])
        said = why_not_library_best(v, t, h, other, mine)
        assert said.startswith(f"Which library's cheapest, {library['integrator']}"), said
        assert re.search(r"not predicted up to T|predicted O\(1\)|past \d|dearer than|no candidate", said), said


def _browser():
    found = next((shutil.which(b) for b in BROWSERS if shutil.which(b)), None)
    if found is None:
        if os.environ.get("LONGTIME_REQUIRE_BROWSER"):
            pytest.fail("LONGTIME_REQUIRE_BROWSER is set but no Chromium was found")
        pytest.skip("no headless browser: install Debian's 'chromium' package (.ci/run does)")
    return found


def test_page_in_headless_chromium(page):
    browser = _browser()
    path, _ = page
    flags = [browser, "--headless", "--no-sandbox", "--disable-gpu", "--hide-scrollbars",
             "--enable-logging=stderr", "--v=0", "--virtual-time-budget=5000"]
    res = subprocess.run(flags + ["--dump-dom", path.as_uri()], capture_output=True, text=True, timeout=120)
    body = re.search(r"<body[^>]*>", res.stdout)
    assert body, res.stderr[-2000:]
    attrs = dict(re.findall(r'data-(\w+)="([^"]*)"', body.group(0)))
    # every figure drawn, the folded ones too
    assert attrs.get("figures") == "7" and attrs.get("rendered") == "7", attrs
    assert attrs.get("errors") == "", attrs
    console = [line for line in res.stderr.splitlines() if ":CONSOLE" in line]
    assert console == [], console
    ARTEFACTS.mkdir(parents=True, exist_ok=True)
    shot = ARTEFACTS / "results-page.png"
    shot.unlink(missing_ok=True)
    subprocess.run(flags + ["--window-size=1280,2000", f"--screenshot={shot}", path.as_uri()],
                   capture_output=True, text=True, timeout=120)
    assert shot.exists() and shot.stat().st_size > 20_000


def test_whole_store_as_parquet_and_csv(page, tmp_path):
    import pandas as pd

    db = str(page[0].parent.parent / "runs.sqlite")
    assert cli.main(["report", "--db", db, "--run", "all", "--format", "csv", "--out", str(tmp_path / "r.csv")]) == 0
    assert len(pd.read_csv(tmp_path / "r.csv")) == 14
    pytest.importorskip("pyarrow", reason="parquet needs pyarrow (the extra longtime[parquet])")
    assert cli.main(["report", "--db", db, "--run", "all", "--format", "parquet",
                     "--out", str(tmp_path / "r.parquet")]) == 0
    df = pd.read_parquet(tmp_path / "r.parquet")
    assert len(df) == 14 and (df["status"] == "ok").sum() == 12


def test_drift_figure_comes_from_the_rows_without_running_anything(page, monkeypatch):
    from longtime.execution import cells
    from longtime.reporting.figures.results import drift_svg
    from longtime.reporting.figures.style import styles

    _, rows = page
    assert all(r["drift_curve"]["invariant"] == "H" and len(r["drift_curve"]["t"]) <= 80
               for r in rows if r["status"] == "ok")

    def no_run(*args, **kwargs):
        raise AssertionError("the page ran a cell")

    monkeypatch.setattr(cells, "integrate_cell", no_run)
    kepler = [r for r in rows if r["problem"] == "kepler"]
    figure, notes = drift_svg(kepler, styles(sorted({r["integrator"] for r in kepler})))
    assert figure and "<path" in figure and not notes


@pytest.mark.slow
def test_main_job_page_takes_the_figures_its_workers_drew(tmp_path, monkeypatch):
    """`longtime matrix` on the process pool: each problem's figures are drawn by a worker
    with no cell left (figures_ahead.FiguresAhead), and the page uses them as drawn; the
    stability intervals too, measured there into an empty cache."""
    from longtime.measure import stability
    from longtime.reporting import figures_ahead

    monkeypatch.setenv("LONGTIME_CACHE_DIR", str(tmp_path / "cache"))  # the pool's workers inherit it
    taken = []
    original = figures_ahead.FiguresAhead.figures

    def spy(self, problem, *args):
        figures = original(self, problem, *args)
        taken.append((problem, figures is not None))
        return figures

    def not_here(*args, **kwargs):
        raise AssertionError("an interval measured after the matrix")

    monkeypatch.setattr(figures_ahead.FiguresAhead, "figures", spy)
    monkeypatch.setattr(stability, "imaginary_interval", not_here)
    assert cli.main(["matrix", "-p", "harmonic,kepler", "-i", "rk4,verlet", "--dt", "0.04,0.02", "--t-final", "20",
                     "--repeats", "3", "--min-time", "0", "--db", str(tmp_path / "r.sqlite"), "--jobs", "2",
                     "--no-progress", "--html", str(tmp_path / "page")]) == 0
    assert sorted(taken) == [("harmonic", True), ("kepler", True)]
    text = (tmp_path / "page" / "index.html").read_text()
    # a winner map, work-precision and drift per problem, the run's calibrations, and the
    # figure of the checked predictions where the matrix checked one
    checked = Store(tmp_path / "r.sqlite").checks(1)
    assert figures_beside_the_checks(text) == 7
    assert text.count('<figure class="plot">') == 7 + bool([c for c in checked if c.get("measured_error")])
    assert "by <code>longtime matrix</code>" in text
    assert "<td>rk4</td><td>[0, 2.82]" in text and "<td>verlet</td><td>[0, 2]" in text


def test_figures_drawn_ahead_serve_only_the_rows_they_were_drawn_from():
    from longtime.execution.cells import Cell
    from longtime.reporting.figures.results import FIGURE_GROUPS
    from longtime.reporting.figures_ahead import FiguresAhead

    cells = [Cell("harmonic", s, {}, {}, 10.0) for s in ("rk4", "verlet")]
    ahead = FiguresAhead(cells, run_id=7)
    ahead.add(cells[0], {"problem": "harmonic", "integrator": "rk4", "status": "ok", "cpu_s": 0.1})
    fn, args, done = ahead.task()  # rk4's cells are all in: its interval and structure, not yet the figures
    assert fn.__name__ == "scheme_ahead" and args == ("rk4", None) and ahead.task() is None
    done({"rk4": "[0, 2.83]"})
    assert ahead.interval("rk4", None) == "[0, 2.83]" and ahead.interval("rk4", [10]) is None
    ahead.add(cells[1], {"problem": "harmonic", "integrator": "verlet", "status": "ok", "cpu_s": 0.2})
    fn, (rows, style, drift, groups), done = ahead.task()
    assert fn.__name__ == "problem_figures" and [r["run_id"] for r in rows] == [7, 7]
    assert groups == ("work_precision", "drift")
    assert ahead.task()[1] == ("verlet", None) and ahead.task() is None
    drawn = {f: f"<{f}>" for fields in FIGURE_GROUPS.values() for f in fields}
    done(drawn)
    assert ahead.figures("harmonic", rows, style, drift) == drawn
    older = [{**rows[0], "cpu_s": 0.3}, rows[1]]  # e.g. a resumed run's page: other rows
    assert ahead.figures("harmonic", older, style, drift) is None  # rows without kept curves: drawn from all
    # a scheme's style that no drift figure draws: only the work-precision figures change
    assert set(ahead.figures("harmonic", rows, {**style, "euler": {}}, drift)) == set(FIGURE_GROUPS["drift"])
    assert ahead.figures("harmonic", rows, {**style, "rk4": {"color": "#000000", "marker": "o"}}, drift) is None
    assert ahead.figures("kepler", rows, style, drift) is None


def test_a_scheme_measured_ahead_leaves_its_interval_and_structure_in_the_caches(tmp_path, monkeypatch):
    """What a pool worker measures ahead is what the page's card then reads without compiling."""
    from longtime.measure import structure
    from longtime.measure.stability import cached_texts
    from longtime.reporting.figures_ahead import scheme_ahead

    monkeypatch.setenv("LONGTIME_CACHE_DIR", str(tmp_path))
    texts = scheme_ahead("verlet", None)
    assert texts["verlet"] == cached_texts({"verlet": None})[0]["verlet"]
    found = structure.measure("verlet")  # from the cache: the file the worker wrote
    assert found.symplectic and found.reversible
    assert list((tmp_path / "structure").glob("verlet-*.json"))


def test_drift_figures_drawn_ahead_outlive_any_new_cpu_time():
    """Rows that keep their curves: CPU times measured again (the timing processes after the
    matrix) leave the drift figures as drawn, not the work-precision ones, even where they
    reorder the schemes or a scheme's settings by cost: the drawn setting is a scheme's row
    of median steps. A changed curve leaves neither."""
    from longtime.execution.cells import Cell
    from longtime.reporting.figures.results import FIGURE_GROUPS, representative
    from longtime.reporting.figures_ahead import FiguresAhead

    def curve(scale):
        return {"invariant": "H", "t": [1.0, 10.0], "error": [1e-9 * scale, 1e-8 * scale]}

    cells = [Cell("harmonic", s, {}, {"dt": dt}, 10.0) for s in ("rk4", "verlet") for dt in (0.1, 0.05, 0.02)]
    ahead = FiguresAhead(cells, run_id=7, timed_again=True)
    for k, cell in enumerate(cells):
        dt = cell.integrator_settings["dt"]
        ahead.add(cell, {"problem": "harmonic", "integrator": cell.integrator, "status": "ok", "dt": dt,
                         "steps": round(10.0 / dt), "cpu_s": 0.01 * (k + 1) / dt, "l2_error": dt**4,
                         "drift_curve": curve(dt),
                         "drift_curves": [curve(dt)]})
    task = next(t for t in iter(ahead.task, None) if t[0].__name__ == "problem_figures")
    fn, (rows, style, drift, groups), done = task
    assert groups == ("drift",)  # the work-precision figures wait for the final CPU times
    drift_figs = {f: f"<{f}>" for f in FIGURE_GROUPS["drift"]}
    done(drift_figs)
    # verlet's rows retimed cheaper than rk4's, each scheme's order by cost kept
    retimed = [{**r, "cpu_s": r["cpu_s"] * (0.1 if r["integrator"] == "verlet" else 1.0),
                "cpu_s_processes": [r["cpu_s"]]} for r in rows]
    assert ahead.figures("harmonic", retimed, style, drift) == drift_figs
    # rk4 at dt 0.02 made cheaper than at 0.05: its setting of median steps is still dt 0.05
    moved = [{**r, "cpu_s": 1e-4} if r["integrator"] == "rk4" and r["dt"] == 0.02 else r for r in rows]
    assert ahead.figures("harmonic", moved, style, drift) == drift_figs
    assert {s: r["dt"] for s, r in representative(moved).items()} == {"rk4": 0.05, "verlet": 0.05}
    other_curve = [{**r, "drift_curves": [curve(7.0)]} if r["integrator"] == "verlet" else r for r in rows]
    assert ahead.figures("harmonic", other_curve, style, drift) is None


def test_a_tol_sweep_whose_order_follows_tol_is_one_curve_and_set_orders_split():
    from longtime.reporting.figures.results import sweeps

    def row(scheme, tol=None, order=None, eps=None):
        return {"integrator": scheme, "t_final": 10.0, "settings": "", "tol": tol, "order": order, "eps_res": eps}

    heyoka = [row("heyoka", 1e-6, 8), row("heyoka", 1e-9, 12), row("heyoka", 1e-12, 15)]  # N from tol
    bpl = [row("bpl", None, n, e) for n in (10, 15) for e in (1e-6, 1e-9)]  # N set, eps_res swept
    curves = sweeps(heyoka + bpl)
    assert list(curves) == [("bpl", 10.0, "", 10), ("bpl", 10.0, "", 15), ("heyoka", 10.0, "", None)]
    assert len(curves[("heyoka", 10.0, "", None)]) == 3 and len(curves[("bpl", 10.0, "", 15)]) == 2
    # the same tol at two set N: N does not follow tol, so the curves split
    both = [row("taylor-adaptive", t, n) for n in (8, 12) for t in (1e-6, 1e-9)]
    assert sorted(k[3] for k in sweeps(both)) == [8, 12]


def test_drift_figure_stays_legible_with_thirty_schemes(monkeypatch):
    """Thirty schemes on a problem of three invariants: three panels of a legible size (the
    legend below them, not beside), without matplotlib's 'tight layout not applied'."""
    import warnings

    import numpy as np

    from longtime.reporting.figures import results

    t = np.logspace(-2, 3, 40)
    curves = [{"invariant": n, "t": t.tolist(), "error": (1e-12 * t**k).tolist()} for k, n in enumerate("HLA")]
    rows = [{"problem": "kepler", "integrator": f"scheme-{i:02d}", "status": "ok", "cpu_s": 1e-3 * (i + 1),
             "dt": 0.01, "t_final": 1e3, "settings": "", "drift_curve": curves[0], "drift_curves": curves}
            for i in range(30)]
    drawn = {}
    monkeypatch.setattr(results, "svg", lambda fig: drawn.setdefault("fig", fig) and "<svg/>")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        figure, notes = results.drift_svg(rows, {r["integrator"]: {"color": "#000", "marker": "o"} for r in rows})
    fig = drawn["fig"]
    panels = [ax for ax in fig.axes if ax.get_visible()]
    widths = [ax.get_position().width * fig.get_figwidth() for ax in panels]
    assert len(panels) == 3 and min(widths) > 2.0, widths  # inches
    assert len(fig.legends) == 1 and len(fig.legends[0].get_texts()) == 30


def test_the_page_and_its_figures_are_replaced_together(tmp_path, monkeypatch):
    from longtime.core import files as files_module
    from longtime.reporting import page as page_module
    from longtime.reporting.page import figure_files, write_folder

    svg = '<svg width="72pt" height="36pt" viewBox="0 0 72 36"><path d="M0 0L1 1"/></svg>'
    first, files = figure_files(f'<figure class="plot">{svg}<figcaption>Winner map: a map.</figcaption></figure>')
    assert first.startswith('<figure class="plot"><img src="figures/') and 'alt="Winner map"' in first
    assert 'width="96" height="48"' in first and len(files) == 1
    write_folder(tmp_path, first, files)
    old = sorted((tmp_path / "figures").iterdir())
    # a write that fails at the page (a full disk) keeps the earlier page and its figures whole
    second, more = figure_files(f'<figure class="plot">{svg.replace("M0 0", "M0 1")}</figure>')
    real = files_module.write_atomic

    def full(path, data, *a):
        if Path(path).name == "index.html":
            raise files_module.NotWritten(28, "No space left on device", str(path))
        return real(path, data, *a)

    monkeypatch.setattr(page_module, "write_atomic", full)
    with pytest.raises(files_module.NotWritten):
        write_folder(tmp_path, second, more)
    assert (tmp_path / "index.html").read_text() == first and sorted((tmp_path / "figures").iterdir()) == old
    # a write that fails at a figure into a new folder leaves nothing, and names the page and the figure
    monkeypatch.setattr(page_module, "write_atomic", lambda path, data, *a: full(Path(path).with_name("index.html"),
                                                                                data))
    with pytest.raises(files_module.NotWritten) as caught:
        write_folder(tmp_path / "new", second, more)
    assert str(caught.value).startswith(f"cannot write {tmp_path / 'new' / 'index.html'}: No space left on device "
                                        f"(its figure figures/")
    assert [p.name for p in (tmp_path / "new").iterdir()] == []
    monkeypatch.setattr(page_module, "write_atomic", real)
    # a write that succeeds leaves the new page's figures only
    write_folder(tmp_path, second, more)
    assert sorted(f"figures/{f.name}" for f in (tmp_path / "figures").iterdir()) == sorted(more)


def test_figures_left_to_the_timed_rows_are_tasks_once_the_rows_are_timed():
    """With the cells timed again after the matrix, the work-precision figures wait for the
    timed rows (``timed``); the page then takes them, with the drift figures drawn before."""
    from longtime.execution.cells import Cell
    from longtime.reporting.figures.results import FIGURE_GROUPS
    from longtime.reporting.figures_ahead import FiguresAhead

    cells = [Cell("harmonic", "rk4", {}, {}, 10.0)]
    ahead = FiguresAhead(cells, run_id=3, timed_again=True)
    ahead.add(cells[0], {"problem": "harmonic", "integrator": "rk4", "status": "ok", "cpu_s": 0.1,
                         "drift_curve": [[0.0, 1.0], [0.0, 1e-9]]})  # a kept curve: what the drift figure reads
    fn, (rows, style, drift, groups), done = ahead.task()
    assert groups == ("drift",)
    done({f: f"<{f}>" for f in FIGURE_GROUPS["drift"]})
    assert ahead.task()[0].__name__ == "scheme_ahead" and ahead.task() is None
    timed = [{**rows[0], "cpu_s": 0.08}]  # the row as the timing processes left it
    assert set(ahead.figures("harmonic", timed, style, drift)) == set(FIGURE_GROUPS["drift"])
    ahead.timed(timed)
    fn, (later_rows, _, _, groups), done = ahead.task()
    assert fn.__name__ == "problem_figures" and later_rows == timed and groups == ("work_precision",)
    assert ahead.task() is None
    done({f: f"<{f}>" for f in FIGURE_GROUPS["work_precision"]})
    every = {f for fields in FIGURE_GROUPS.values() for f in fields}
    assert set(ahead.figures("harmonic", timed, style, drift)) == every
    # other rows than the timed ones: the work-precision figures are the page's to draw
    assert set(ahead.figures("harmonic", [{**timed[0], "cpu_s": 0.2}], style, drift)) == set(FIGURE_GROUPS["drift"])


def test_the_page_draws_on_the_main_jobs_workers_where_they_stay_up(monkeypatch):
    """A main job whose workers stay up for the page (``FiguresAhead.workers``): the page's
    figures go to them, and no figure process starts, however many figures there are."""
    from concurrent.futures import Future

    from longtime.reporting.figures import results

    class Workers:  # runs each task at once, as an idle worker would
        def __init__(self):
            self.ran = []

        def submit(self, fn, *args):
            self.ran.append(args[0].__name__ if fn is results.drawn_figure else fn.__name__)
            done = Future()
            done.set_result(fn(*args))
            return done

    class Ahead:
        workers = Workers()

        def figures(self, *args):
            return None

        def interval(self, *args):
            return None

    def started(processes):
        raise AssertionError(f"{processes} figure processes started beside the main job's workers")

    def winner_map(name):
        return f"<svg>{name}</svg>"

    monkeypatch.setattr(results, "_figure_pool", started)
    ahead = Ahead()
    with results.figures_drawing({}, {}, True, 2, {}, ahead, later=100) as (drawn, draw):
        assert draw(winner_map, "kepler")() == "<svg>kepler</svg>"
        assert drawn() == ({}, {})
    assert ahead.workers.ran == ["winner_map"]
