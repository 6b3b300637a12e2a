"""The results page's figures drawn ahead: while the matrix runs, a pool worker that has no
cell left draws the figures of each problem whose cells are all stored, and measures the
stability interval and the step map's structure (its card's) of each scheme whose cells
are; the page takes what was drawn from the rows it shows, and finds the rest in the
caches."""
from __future__ import annotations

from typing import Any, Sequence

from longtime.core.status import Status
from longtime.execution.store import as_read
from longtime.reporting.figures.results import FIGURE_GROUPS, figure_inputs, problem_figures
from longtime.reporting.figures.style import styles


def stability_schemes(rows: list[dict]) -> tuple[dict[str, list | None], dict[str, list | None]]:
    """The schemes of ``rows`` whose stability intervals the page shows, each with the N its
    rows ran with (a series scheme; its default N where the row has none): (built-in ones,
    measured here where not cached: their solves are capped; plugins', read from the cache
    only, since a plugin's step that never returns would hang the page: `longtime list
    --stability` measures them)."""
    from longtime.core import registry
    from longtime.measure.stability import SERIES_ORDERS

    wanted: dict[str, set | None] = {}
    for r in rows:
        if r.get("status") == Status.SKIPPED:
            wanted.setdefault(r["integrator"], None)
            continue
        n = r.get("order")
        orders = wanted.get(r["integrator"]) or set()
        orders.add(int(n) if isinstance(n, (int, float)) and n == n else None)
        wanted[r["integrator"]] = orders
    schemes = {}
    for s, orders in wanted.items():
        param = registry.integrator_class(s).parameters.get("order") if s in registry.integrators() else None
        if param is None:
            schemes[s] = None
        else:
            schemes[s] = sorted({param.default if n is None else n for n in (orders or {None})}) or [SERIES_ORDERS[0]]
    builtin = {s: o for s, o in schemes.items()
               if s in registry.integrators() and registry.integrator_class(s).__module__.startswith("longtime.")}
    return builtin, {s: o for s, o in schemes.items() if s not in builtin}


def scheme_ahead(name: str, orders) -> dict[str, str]:
    """A built-in scheme's stability interval at ``orders`` (its text by name) and its
    structure on the canonical problem, each measured into its cache: on a cold machine each
    compiles a step loop, which the page's card would otherwise compile in the main process
    after the matrix."""
    from longtime.measure import structure
    from longtime.measure.stability import interval_texts

    texts = interval_texts({name: orders}, True)
    try:
        structure.measure(name)
    except Exception:  # the page's card measures it again and says why it could not
        pass
    return texts


class FiguresAhead:
    """A page's figures drawn while the matrix still runs: each problem's as soon as its last
    cell is stored, by a pool worker that has no cell left to run (``task`` is the process
    pool's ``ExecOptions.idle_work``; ``add`` sees each row as it is stored), and likewise a
    built-in scheme's stability interval and structure once its last cell is stored (measured
    into their caches on a cold machine: a second or two a scheme). The figures of a main job's last
    problems are then drawn beside its last cells instead of after them. The page takes a
    group of figures only if it was drawn from the very inputs it would draw it from
    (``figure_inputs``: a resumed run's page has older rows too), an interval only for the
    same N; it does the others itself. ``timed_again``: the rows' cells are timed again in
    other processes after the matrix (``--processes`` above 1), which changes their CPU
    times, so the work-precision figures wait for ``timed``: given the rows as stored once
    the timing processes timed them, it makes them tasks too (the main job hands them to
    the workers that run its checks); the drift figures, which read the kept curves, are
    drawn ahead."""

    def __init__(self, cells: Sequence, run_id: int | None, drift: bool = True, timed_again: bool = False):
        self.run_id, self.drift = run_id, drift
        self.groups = tuple(g for g in FIGURE_GROUPS if not (timed_again and g == "work_precision"))
        self.left: dict[str, int] = {}  # cells not stored yet, per problem and per scheme
        for c in cells:
            for name in (("problem", c.problem), ("scheme", c.integrator)):
                self.left[name] = self.left.get(name, 0) + 1
        self.style = styles(sorted({c.integrator for c in cells}))
        self.rows: dict[str, list[dict]] = {}
        self.outcomes: dict[str, list[dict]] = {}  # per scheme: what stability_schemes reads
        self.ready: list[tuple[str, str]] = []
        # problem -> (the inputs of each group drawn, its figures)
        self.drawn: dict[str, tuple[dict[str, str], dict]] = {}
        self.later: list[tuple[str, list[dict], tuple[str, ...]]] = []  # (problem, its rows, groups): ``timed``'s
        self.intervals: dict[str, tuple[Any, str | None]] = {}  # scheme -> (its N, its text)
        # the main job's workers, where they stay up for the page (run_main_job's keep_workers):
        # they draw its last figures, with matplotlib loaded already
        self.workers: Any = None

    def add(self, cell, row: dict) -> None:
        """A stored row (kept as the store gives it back: JSON and its run id)."""
        self.rows.setdefault(cell.problem, []).append(as_read(row, self.run_id))
        self.outcomes.setdefault(cell.integrator, []).append(
            {k: row.get(k) for k in ("integrator", "status", "order")})
        for name in (("problem", cell.problem), ("scheme", cell.integrator)):
            self.left[name] = self.left.get(name, 1) - 1
            if self.left[name] == 0:
                self.ready.append(name)

    def task(self):
        """(a function, its arguments, where its result goes): the figures of a problem whose
        rows are all in, or the stability interval and structure of such a scheme; None when
        there is none."""
        while self.ready:
            kind, name = self.ready.pop(0)
            if kind == "problem":
                return self._figures_task(name, self.rows.pop(name), self.groups)
            builtin, _ = stability_schemes(self.outcomes.pop(name))
            if name in builtin:  # a plugin's is read from the cache only (see stability_schemes)
                orders = builtin[name]
                return scheme_ahead, (name, orders), \
                    lambda texts: self.intervals.__setitem__(name, (orders, texts.get(name)))
        if self.later:
            return self._figures_task(*self.later.pop(0))
        return None

    def timed(self, rows: list[dict]) -> None:
        """The rows as the store gives them back once the timing processes timed them again:
        the groups of figures left to this moment (the work-precision figures, when
        ``timed_again``) become tasks, each problem's drawn from its rows here, the most
        rows first."""
        left = tuple(g for g in FIGURE_GROUPS if g not in self.groups)
        if not left:
            return
        by_problem: dict[str, list[dict]] = {}
        for r in rows:
            by_problem.setdefault(r["problem"], []).append(r)
        self.later = [(p, mine, left) for p, mine in sorted(by_problem.items(), key=lambda kv: -len(kv[1]))]

    def _figures_task(self, name: str, rows: list[dict], groups: tuple[str, ...]):
        inputs = figure_inputs(rows, self.style, self.drift)

        def done(figs: dict) -> None:
            had, drawn = self.drawn.get(name, ({}, {}))
            self.drawn[name] = ({**had, **{g: inputs[g] for g in groups}}, {**drawn, **figs})

        return problem_figures, (rows, self.style, self.drift, groups), done

    def figures(self, problem: str, rows: list[dict], style: dict, drift: bool) -> dict | None:
        """The figures drawn ahead for ``problem``, of each group drawn from the inputs these
        rows and styles give (None: no such group)."""
        inputs, figs = self.drawn.get(problem, (None, None))
        if inputs is None:
            return None
        now = figure_inputs(rows, style, drift)
        found = {f: figs[f] for g, fields in FIGURE_GROUPS.items()
                 if inputs.get(g) == now[g] and all(f in figs for f in fields) for f in fields}
        return found or None

    def interval(self, scheme: str, orders) -> str | None:
        """``scheme``'s interval text if it was found ahead at these N (None: a scheme without N)."""
        if scheme not in self.intervals:
            return None
        found_orders, text = self.intervals[scheme]
        return text if found_orders == orders else None
