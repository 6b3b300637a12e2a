"""Which library for this problem: per problem, the cheapest measured setting of each library
(the suite's own kernels, scipy, SUNDIALS, diffrax, heyoka, REBOUND, a plugin's) that keeps a
target error over the problem's main run, with its CPU seconds as a multiple of the cheapest
library's. Measured rows only, at the one final time most of the problem's rows ran to: no
extrapolation, so that the libraries are compared on equal terms. A library without an entry
says why: not installed, does not apply, too slow (a ``timeout`` row at that final time: the
seconds it ran and how far it got), none of its settings keeps the target (its best error),
or only shorter runs (the budget moved its rows). A run stopped at its chain's CPU bound (the
main job's library peers: ``status.bounded``) is neither an entry nor too slow: a cheaper
setting of its library keeps the target, and that one is the library's entry."""
from __future__ import annotations

from typing import Any

from longtime.core.fmt import positive
from longtime.core.rowschema import formatted
from longtime.core.rowtext import main_t_final, setting
from longtime.core.status import TOO_SLOW, Status, bounded
from longtime.predict.need import TARGET, kept_error, library_of  # noqa: F401 (read from here too)
from longtime.predict.settings import Measure, error_kept, solution_measure

# a too-slow row's wall seconds are shown beside its CPU seconds past this many times them
WALL_SHOWN = 1.5


def _cell(rows: list[dict[str, Any]], t_main: float, target: float, m: Measure | None) -> tuple[str, float | None]:
    """(the library's cell, the CPU seconds of its entry or None where it has none)."""
    if not rows:
        return "not run on this problem", None
    ran = [r for r in rows if r.get("status") == Status.OK]
    # a run stopped at its chain's CPU bound is no answer and not too slow: a cheaper setting of
    # the library keeps the target (longtime.execution.batches)
    slow = [r for r in rows if r.get("status") == Status.TIMEOUT and r.get("t_final") == t_main and not bounded(r)]
    if not ran and not slow:
        if all(r.get("status") == Status.SKIPPED for r in rows):
            if any("pip install" in str(r.get("message")) for r in rows):
                return "not installed", None
            estimated = next((str(r["message"]) for r in rows if str(r.get("message")).startswith(TOO_SLOW)), None)
            if estimated is not None:  # "too slow: about 43 s a run estimated for t_final 1000 ..."
                return "too slow:" + estimated[len(TOO_SLOW):].split(", over the")[0], None
            return "does not apply", None
        return "no ok row", None
    main = [r for r in ran if r.get("t_final") == t_main]
    if not main and slow:
        return _too_slow(slow, t_main), None
    if not main:
        return f"only shorter runs (t_final {formatted('t_final', min(r['t_final'] for r in ran))}: the budget)", None
    errors = {id(r): error_kept(r, m) if m is not None else None for r in main}
    kept = _kept(main, target, m) if m is not None else []
    if not kept:
        measured = [r for r in main if errors[id(r)] is not None]
        if not measured:
            return "no error measured", None
        r = min(measured, key=lambda r: errors[id(r)])
        text = f"none keeps it (best {errors[id(r)]:.2g}: {r['integrator']} {setting(r)})".replace("  ", " ")
        return (f"{text}; {_too_slow(slow, t_main)}" if slow else text), None
    r = min(kept, key=lambda r: r["cpu_s"])
    cpu = formatted("cpu_s", r["cpu_s"])
    text = f"{r['integrator']} {setting(r)}: {cpu} s ({errors[id(r)]:.1g})".replace("  ", " ")
    return text, float(r["cpu_s"])


def _kept(main: list[dict[str, Any]], target: float, m: Measure) -> list[dict[str, Any]]:
    """The rows of ``main`` that keep the solution and ``target`` (``kept_error``) and have a CPU time."""
    return [r for r in main if kept_error(r, m, target) is not None]


def cheapest_kept(rows: list[dict[str, Any]], target: float = TARGET) -> dict[str, Any] | None:
    """The cheapest row of one problem's ``rows``, of any library, that keeps ``target`` at the
    problem's main final time: the "best" entry of its row in ``library_table`` (None: none)."""
    t_main = main_t_final(rows)
    m = solution_measure(rows)
    if t_main is None or m is None:
        return None
    main = [r for r in rows if r.get("status") == Status.OK and r.get("t_final") == t_main]
    kept = _kept(main, target, m)
    return min(kept, key=lambda r: r["cpu_s"]) if kept else None


def _too_slow(slow: list[dict[str, Any]], t_main: float) -> str:
    """'too slow: cvode-bdf tol=1e-13 ran 3.1 s for t=250 of 500' from the timeout rows at T
    (the one that got furthest): its CPU seconds, and its wall seconds beside them where they
    are more than WALL_SHOWN times as many (a loaded machine: the time limit is on the wall);
    for a run stopped on its pace, where its pace put T ('pace_cpu_s')."""
    r = max(slow, key=lambda r: r.get("t_reached") or 0.0)
    cpu, wall = r.get("cpu_s"), r.get("wall_s")
    spent = "cpu_s" if positive(cpu) else "wall_s" if positive(wall) else None
    spent_text = f"{formatted(spent, r[spent])} s" if spent else "its time limit"
    if positive(cpu) and positive(wall) and wall > WALL_SHOWN * cpu:
        spent_text = f"{formatted('cpu_s', cpu)} s CPU in {formatted('wall_s', wall)} s wall"
    reached, t_text = r.get("t_reached"), formatted("t_final", t_main)
    reached_text = f"t={formatted('t_reached', reached)} of {t_text}" if reached is not None else f"less than {t_text}"
    if positive(r.get("pace_cpu_s")):
        reached_text += f" (about {formatted('cpu_s', r['pace_cpu_s'])} s to T at its pace)"
    return f"too slow: {r['integrator']} {setting(r)} ran {spent_text} for {reached_text}".replace("  ", " ")


def library_table(rows: list[dict[str, Any]], target: float = TARGET) -> tuple[list[str], list[list[str]]]:
    """(header, body): a row per problem, a column per library present in ``rows``, each cell
    the cheapest ok setting of that library that keeps ``target`` (``error_kept`` of the
    problem's solution error, ``solution_measure``) at the problem's main final time
    (``main_t_final``), with its CPU seconds, its error and its CPU as a multiple of the
    cheapest library's entry ("best" for that one), or why there is none."""
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
        found = [_cell([r for r in mine if r["integrator"] in by_library[lib]], t_main, target, m)
                 for lib in libraries]
        best = min((cpu for _, cpu in found if cpu is not None), default=None)
        cells = [text if cpu is None else f"{text} {_ratio(cpu, best)}" for text, cpu in found]
        body.append([problem, formatted("t_final", t_main), *cells])
    return ["problem", "T", *libraries], body


def best_of_library(rows: list[dict[str, Any]], library: str, target: float = TARGET) -> dict[str, str]:
    """problem -> the cell of ``library`` in ``library_table`` (its cheapest setting that keeps
    ``target``, or why it has none), for the problems ``rows`` cover."""
    header, body = library_table(rows, target)
    if library not in header:
        return {}
    column = header.index(library)
    return {line[0]: line[column] for line in body}


def _ratio(cpu: float, best: float | None) -> str:
    if best is None or cpu <= best:
        return "best"
    return f"x{cpu / best:.3g}"
