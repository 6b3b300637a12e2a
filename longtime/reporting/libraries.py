"""Which library for this problem: per problem, the cheapest measured setting of each library
(the suite's own kernels, scipy, SUNDIALS, diffrax, heyoka, REBOUND, a plugin's) that keeps a
target error over the problem's main run. Measured rows only, at the one final time most of
the problem's rows ran to: no extrapolation, so that the libraries are compared on equal
terms (a library whose rows the budget moved to a shorter final time is said to be so)."""
from __future__ import annotations

from typing import Any

from longtime.core.fmt import positive
from longtime.core.rowtext import main_t_final, setting
from longtime.predict.settings import Measure, error_kept, solution_measure

# the error the table asks of each library's settings (the verdict's measure: max_error, the
# largest error of any block of the state over the run, relative to its motion)
TARGET = 1e-6


def library_of(scheme: str) -> str:
    """The library whose method ``scheme`` runs (its class's ``library``; "longtime" for the
    suite's own kernels, "unknown" for a scheme no longer installed)."""
    from longtime.core import registry

    try:
        return str(getattr(registry.integrator_class(scheme), "library", "longtime"))
    except Exception:  # a scheme of an old run that is no longer installed
        return "unknown"


def _cell(rows: list[dict[str, Any]], t_main: float, target: float, m: Measure | None) -> str:
    if not rows:
        return "-"
    ran = [r for r in rows if r.get("status") == "ok"]
    if not ran:
        if all(r.get("status") == "skipped" for r in rows):
            return "not installed" if any("pip install" in str(r.get("message")) for r in rows) else "does not apply"
        return "no ok row"
    main = [r for r in ran if r.get("t_final") == t_main]
    if not main:
        return f"only shorter runs (t_final {min(r['t_final'] for r in ran):.3g}: the budget)"
    errors = {id(r): error_kept(r, m) if m is not None else None for r in main}
    kept = [r for r in main if not r.get("solution_lost") and positive(r.get("cpu_s"))
            and errors[id(r)] is not None and errors[id(r)] <= target]
    if not kept:
        best = min((e for e in errors.values() if e is not None), default=None)
        return f"none keeps it (best {best:.2g})" if best is not None else "no error measured"
    r = min(kept, key=lambda r: r["cpu_s"])
    return f"{r['integrator']} {setting(r)}: {r['cpu_s']:.3g} s ({errors[id(r)]:.1g})".replace("  ", " ")


def library_table(rows: list[dict[str, Any]], target: float = TARGET) -> tuple[list[str], list[list[str]]]:
    """(header, body): a row per problem, a column per library present in ``rows``, each cell
    the cheapest ok setting of that library that keeps ``target`` (``error_kept`` of the
    problem's solution error, ``solution_measure``) at the
    problem's main final time (``main_t_final``), with its CPU seconds and error, or why
    there is none."""
    by_library: dict[str, set[str]] = {}
    for scheme in sorted({r["integrator"] for r in rows}):
        by_library.setdefault(library_of(scheme), set()).add(scheme)
    libraries = sorted(by_library, key=lambda lib: (lib != "longtime", lib))
    body = []
    for problem in sorted({r["problem"] for r in rows}):
        mine = [r for r in rows if r["problem"] == problem]
        t_main = main_t_final(mine)
        if t_main is None:
            continue
        m = solution_measure(mine)
        cells = [_cell([r for r in mine if r["integrator"] in by_library[lib]], t_main, target, m) for lib in libraries]
        body.append([problem, f"{t_main:.4g}", *cells])
    return ["problem", "T", *libraries], body
