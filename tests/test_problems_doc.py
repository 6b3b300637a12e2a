"""The figures docs/problems.md quotes are recomputed from the code, as tests/test_api_docs.py
runs docs/api.md: each test computes a figure and asserts that the page quotes it as the
code gives it, so a figure and its code cannot drift apart. The page's whitespace (line
breaks) is normalised before the search."""
import contextlib
import io
import json
import math
from pathlib import Path

import numpy as np
import pytest

from longtime.core.registry import problem_class

DOC = Path(__file__).resolve().parents[1] / "docs" / "problems.md"
TEXT = " ".join(DOC.read_text().split())


def quoted(text: str) -> None:
    assert text in TEXT, f"docs/problems.md does not quote {text!r}, which the code gives"


def initial(name: str, invariant: str = "H", **settings) -> np.ndarray:
    problem = problem_class(name)(**settings)
    return np.asarray(problem.invariants(problem.t0, np.asarray(problem.u0, dtype=float)[None, :])[invariant])[0]


def sci(x: float, digits: int = 1) -> str:
    """1e-3, 9.4e-5, 1.89e-3: the page's way of writing a small number, to ``digits`` digits."""
    mantissa, exponent = f"{x:.{digits - 1}e}".split("e")
    return f"{mantissa}e{int(exponent)}"


def rows(*argv: str) -> list[dict]:
    from longtime.commands.cli import main

    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        assert main(["run", *argv, "--repeats", "1", "--min-time", "0", "--format", "json", "--no-store"]) == 0
    return json.loads(out.getvalue())


def test_initial_energies_and_invariants():
    quoted(f"H0 = {float(initial('toda'))!r}")  # the shortest repr (the page pads it with a 0)
    quoted("(**corrected** scaling: " + ", ".join(f"{initial('toda', f'eig{k}'):.9g}" for k in (1, 2, 3))
           + " initially)")
    quoted(f"H0 = {initial('figure-eight'):.16f}.")
    quoted(f"u[3m]); H0 = {initial('fpu'):.8f}.")
    quoted(f"H0 = {initial('lennard-jones'):,.2f} (")
    quoted(f"H0 = -(12/5 + 15/4 + 20/3) = {initial('pythagorean-three-body'):.6g}, L = P = 0.")
    quoted(f"H0 = {initial('charged-particle'):.4g}. Diagnostic")
    quoted(f"(absolute; |H0| = {abs(initial('charged-particle')):.4g})")
    quoted(f"H0 = 4 ln 2 - 6 = {initial('lotka-volterra'):.6g}.")
    assert initial("lotka-volterra") == pytest.approx(4 * math.log(2) - 6, rel=1e-15)
    quoted(f"(J0 = {initial('restricted-three-body', 'J'):.12g})")


def test_default_runs_and_sweeps():
    cls = problem_class("restricted-three-body")
    quoted(f"sweep dt = {', '.join(sci(x) for x in cls.sweep_dt)} over one period")
    assert cls.sweep_t_final == cls.default_t_final == pytest.approx(17.0652165601579625588917206249)
    lv = problem_class("lotka-volterra")
    quoted(f"`default_t_final` and sweep: {lv.default_t_final:g} (dt {', '.join(f'{x:g}' for x in lv.sweep_dt)})")


def test_lotka_volterra_rk4_drift():
    (row,) = rows("-p", "lotka-volterra", "-i", "rk4", "--dt", "0.05", "--t-final", "100")
    absolute = row["H.max"] * abs(initial("lotka-volterra"))
    quoted(f"rk4 at dt = 0.05 drifts by {sci(absolute, 2)} (absolute; its row's H.max, relative to |H0|, "
           f"is {sci(row['H.max'], 2)})")


@pytest.mark.slow
def test_charged_particle_boris_plateau():
    # 1e6 steps of boris, and the table's plateau at h = 0.1 to t = 1e5
    (row,) = rows("-p", "charged-particle", "-i", "boris", "--dt", "0.1", "--t-final", "1e5")
    absolute = row["H.max"] * abs(initial("charged-particle"))
    quoted(f"(H.max {sci(row['H.max'], 3)}, relative to |H0|, i.e. {sci(absolute, 3)} absolute; "
           f"H.growth_class `{row['H.growth_class']}`)")
    quoted(f"| 0.1 | {sci(absolute, 3)} | same to 3 digits | {sci(absolute, 3)} | |")


@pytest.mark.slow
def test_arenstorf_closure_in_long_double():
    from longtime.measure.reference import reference_states

    problem = problem_class("restricted-three-body")()
    end = reference_states(problem, np.array([0.0, problem.period]), "long double")[-1]
    quoted(f"heyoka in long double returns to {np.abs(end - problem.u0).max():.2g} of u0 after T")
