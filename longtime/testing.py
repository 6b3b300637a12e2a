"""Assertions for a scheme author's tests (pytest or any runner): each measures with
``longtime.sweep`` / ``longtime.solve`` and fails with an AssertionError that states what was
measured, what was expected and the points used. See docs/api.md.

    assert_order(scheme, problem, order, dts=None, slack=0.1, **settings)
    assert_bounded(scheme, problem, invariant, bound, t_final=..., **settings)
    assert_growth(scheme, problem, invariant, allowed_classes, t_final=..., **settings)
    assert_no_regression(store, baseline_run, run, ...)
    assert_symplectic(scheme, h=0.05, problem=None)    # ||M^T J M - J|| within its error
    assert_reversible(scheme, h=0.05, problem=None)    # a step of h then -h returns to u0
    benchmark_cell(benchmark, problem, scheme, **settings)   # pytest-benchmark's fixture

A scheme or a problem is a registered name, a class (registered for the session, no
install needed) or an instance.
"""
from __future__ import annotations

from typing import Any, Iterable, Sequence

from longtime.api import Order, Result, cells_for, convergence, resolve, solve, sweep
from longtime.core import registry
from longtime.core.params import check_number
from longtime.core.roles import row_columns, row_fields
from longtime.core.status import Status

# a fit needs points in the asymptotic range: the problem's sweep and this many halvings below it
EXTRA_HALVINGS = 2


def default_dts(problem: Any, scheme: Any = None, t_final: float | None = None) -> list[float]:
    """The steps ``assert_order`` sweeps by default: the problem's ``sweep_dt`` and two
    halvings of its smallest step; for a ``scheme`` of a high declared order, the larger
    steps of its default sweep too (longtime.execution.sizes.sweep_steps, over ``t_final``,
    default the problem's), where its error is above the round-off floor."""
    from longtime.execution.sizes import sweep_steps

    cls = registry.problem_class(resolve(problem, "problem")[0])
    dts = sorted({float(x) for x in cls.sweep_dt} or {float(cls.default_dt)}, reverse=True)
    larger = []
    if scheme is not None:
        icls = registry.integrator_class(resolve(scheme, "scheme")[0])
        span = cls.default_t_final if t_final is None else t_final
        larger = [h for h in sweep_steps(cls, icls, span) if h > dts[0]]
    return larger + dts + [dts[-1] / 2 ** k for k in range(1, EXTRA_HALVINGS + 1)]


def _label(scheme: Any, problem: Any) -> str:
    return f"{resolve(scheme, 'scheme')[0]} on {resolve(problem, 'problem')[0]}"


def _points(order: Order) -> str:
    var = order.variable or "dt"
    used = ", ".join(f"{var}={x:.4g}: {e:.3e}" for x, e in order.points)
    text = f"points used ({order.error_field or 'error'}): {used or 'none'}"
    if order.dropped:
        text += "; dropped: " + ", ".join(f"{var}={x:.4g}: {e:.3e} ({why})" for x, e, why in order.dropped)
    return text


def assert_order(scheme: Any, problem: Any, order: float, *, dts: Sequence[float] | None = None,
                 slack: float = 0.1, t_final: float | None = None, executor: str = "serial",
                 **settings: Any) -> Order:
    """The observed order of ``scheme`` on ``problem`` over the steps ``dts`` (default
    ``default_dts``) is within ``slack`` of ``order``. Returns the Order."""
    check_number("order", order, positive=True)
    check_number("slack", slack, minimum=0.0)
    dts = list(dts) if dts is not None else default_dts(problem, scheme, t_final)
    rows = sweep(problem, scheme, t_final=t_final, executor=executor, repeats=1, min_time=0.0, dt=dts,
                 progress=False, **settings)
    found = convergence(rows)
    if isinstance(found, list):
        raise AssertionError(f"assert_order: the settings give {len(found)} sweeps; give one value per "
                             f"parameter other than dts")
    expected = f"expected order {order:g} +- {slack:g}"
    if found.value is None:
        # an undetermined order confirms nothing: the sweep does not reach the asymptotic range
        raise AssertionError(f"{_label(scheme, problem)}: order undetermined ({found.reason}); {expected}; "
                             + _points(found) + _not_ok(rows) + _conditions(scheme, order))
    if abs(found.value - order) > slack:
        from longtime.measure.orders import local_slopes, order_text

        text = order_text(found.value, found.ci, len(found.points), local_slopes(found.points), 3)
        raise AssertionError(f"{_label(scheme, problem)}: observed order {text} (95 %), {expected}; "
                             + _points(found) + _conditions(scheme, order))
    return found


def _conditions(scheme: Any, order: float) -> str:
    """The residuals of the order conditions up to ``order`` of a scheme with coefficients
    (a splitting or composition, a Runge-Kutta tableau), and the first that fails."""
    from longtime.numerics.order_conditions import describe, scheme_conditions

    cls = registry.integrator_class(resolve(scheme, "scheme")[0])
    found = scheme_conditions(cls, int(order))
    return "" if found is None else "; " + describe(*found)


def _structure(scheme: Any, h: float | None, problem: Any):
    from longtime.measure import structure

    if problem is not None and not hasattr(problem, "u0"):  # a name or a class: an instance of it
        problem = registry.problem_class(resolve(problem, "problem")[0])()
    found = structure.measure(scheme, h=structure.STEP if h is None else h, problem=problem)
    if found.reason is not None:
        raise AssertionError(str(found))
    return found


def assert_symplectic(scheme: Any, *, h: float | None = None, problem: Any = None) -> Any:
    """One step of ``scheme`` (default h: 0.05, on the first canonical problem it can step:
    kepler, henon-heiles, harmonic) is a symplectic map: its symplecticity defect
    ||M^T J M - J||_2 (M by extrapolated central differences) is at most
    ``structure.SAFETY`` times the stated error of that measurement. Returns the
    ``Structure`` (longtime.measure.structure)."""
    from longtime.measure.structure import SAFETY

    found = _structure(scheme, h, problem)
    if not found.symplectic:
        raise AssertionError(
            f"{found.scheme} on {found.problem}, one step h = {found.h:g}: symplecticity defect ||M^T J M - J|| = "
            f"{found.symplecticity_defect:.3e}, expected at most {SAFETY:g} x its finite-difference error "
            f"{found.symplecticity_error:.2e} = {SAFETY * found.symplecticity_error:.2e}")
    return found


def assert_reversible(scheme: Any, *, h: float | None = None, problem: Any = None) -> Any:
    """A step of h then one of -h returns ``scheme`` to its start within round-off
    (``structure.REVERSIBLE_ULPS`` eps of the state's largest component). Returns the
    ``Structure``."""
    found = _structure(scheme, h, problem)
    if not found.reversible:
        raise AssertionError(
            f"{found.scheme} on {found.problem}: a step of h = {found.h:g} then one of -h misses the start by "
            f"{found.reversibility_defect:.3e} (relative to the state's largest component), expected at most "
            f"round-off {found.reversibility_bound:.2e}")
    return found


def _not_ok(rows) -> str:
    bad = rows[rows["status"] != Status.OK]
    if bad.empty:
        return ""
    return "; not ok: " + ", ".join(f"dt={r['dt']:.4g} {r['status']} ({r['message']})" for _, r in bad.iterrows())


def _solve(scheme: Any, problem: Any, t_final: float, settings: dict) -> Result:
    result = solve(problem, scheme, t_final=t_final, repeats=1, min_time=0.0, **settings)
    if result.status != Status.OK:
        raise AssertionError(f"{_label(scheme, problem)} to t={t_final:g} ({_settings(result)}): "
                             f"status {result.status}: {result.row['message']}")
    return result


def _settings(result: Result) -> str:
    r = result.row
    parts = [f"{k}={r[k]:g}" for k in (*row_fields("step"), *row_fields("accuracy"))
             if isinstance(r.get(k), (int, float))]
    if r.get("settings"):
        parts.append(str(r["settings"]))
    return ", ".join(parts) or "default settings"


def assert_bounded(scheme: Any, problem: Any, invariant: str, bound: float, *, t_final: float,
                   **settings: Any) -> Result:
    """The largest relative error of ``invariant`` (``NAME.max``) over one run to ``t_final``
    is at most ``bound``. Returns the Result."""
    result = _solve(scheme, problem, t_final, settings)
    field = f"{invariant}.max"
    if field not in result.row or result.row[field] is None:
        have = sorted(k[:-4] for k, v in result.row.items() if k.endswith(".max") and v is not None)
        raise AssertionError(f"{_label(scheme, problem)}: no invariant {invariant!r}; measured: {', '.join(have)}")
    value = result.row[field]
    if not value <= bound:
        growth = result.row.get(f"{invariant}.growth_class")
        raise AssertionError(
            f"{_label(scheme, problem)} to t={t_final:g} ({_settings(result)}): max relative error of "
            f"{invariant} {value:.3e}, expected at most {bound:.3e} (x{value / bound:.3g} the bound); "
            f"final {_g(result.row.get(invariant + '.final'))}, growth {growth} "
            f"(alpha {_g(result.row.get(invariant + '.growth'))}); {result.row['steps']} steps")
    return result


def assert_growth(scheme: Any, problem: Any, invariant: str, allowed_classes: Iterable[str] | str, *,
                  t_final: float, **settings: Any) -> Result:
    """The growth class of ``invariant``'s error over one run to ``t_final`` (``NAME.growth_class``:
    bounded, sqrt, linear, quadratic, faster, saturated, diverged; ``error`` for the solution
    error) is one of ``allowed_classes``. Returns the Result."""
    allowed = [allowed_classes] if isinstance(allowed_classes, str) else list(allowed_classes)
    result = _solve(scheme, problem, t_final, settings)
    got = result.row.get(f"{invariant}.growth_class")
    if got is None:
        have = sorted(k[:-13] for k, v in result.row.items() if k.endswith(".growth_class") and v is not None)
        raise AssertionError(f"{_label(scheme, problem)}: no growth law of {invariant!r}; measured: {', '.join(have)}")
    if got not in allowed:
        alpha, ci = result.row.get(f"{invariant}.growth"), result.row.get(f"{invariant}.growth_ci")
        raise AssertionError(
            f"{_label(scheme, problem)} to t={t_final:g} ({_settings(result)}): error of {invariant} grows as "
            f"t^{_g(alpha)} (95 % interval {_interval(ci)}), class {got!r}; "
            f"expected {' or '.join(map(repr, allowed))}; "
            f"max {_g(result.row.get(invariant + '.max'))}, fitted over the last two decades of t")
    return result


def assert_no_regression(store: Any, baseline_run: int, run: int | None = None, *, factor: float | None = None,
                         error_factor: float = 2.0, timing: bool = True, raw_time: bool = False,
                         store_b: Any = None) -> dict[str, Any]:
    """``longtime compare``'s verdict on ``run`` (default: the store's latest) against
    ``baseline_run``: no common cell slower (with ``timing``; calibrated times unless
    ``raw_time``, a scheme's median beyond ``factor``, default compare's), less accurate or
    no longer ok, no observed order changed and no scheme newly left out of the order table.
    ``store_b`` holds ``run`` when it is another store. Returns compare's result."""
    from longtime.execution.store import Store
    from longtime.reporting.compare import compare
    from longtime.reporting.compare_cells import TIME_FACTOR

    factor = TIME_FACTOR if factor is None else factor
    a = store if isinstance(store, Store) else Store(store, readonly=True)
    b = a if store_b is None else (store_b if isinstance(store_b, Store) else Store(store_b, readonly=True))
    run = b.latest_run() if run is None else run
    rows_a, rows_b = a.rows(int(baseline_run)), b.rows(int(run))
    result = compare(rows_a, rows_b, factor, error_factor, raw=raw_time,
                     calibrations=(a.calibrations(int(baseline_run)), b.calibrations(int(run))))
    if not result["cells"]:
        raise AssertionError(f"runs {baseline_run} and {run} have no cell in common")
    problems = []
    for c in result["cells"]:
        regressions = [x for x in c["regressions"] if timing or not x.startswith(("cpu", "time"))]
        if regressions:
            problems.append(f"{c['problem']} {c['integrator']} ({_cell(c)}): " + "; ".join(regressions))
    for pair in result["pairs"]:
        for o in pair["orders"]:
            if o["order_changed"]:
                problems.append(f"{o['problem']} {o['integrator']}: observed order "
                                f"{o['observed_order_a']:.3f} -> {o['observed_order_b']:.3f}")
    lost = {(m["problem"], m["integrator"]) for m in result["left_out_b"]} - \
        {(m["problem"], m["integrator"]) for m in result["left_out_a"]}
    for m in result["left_out_b"]:
        if (m["problem"], m["integrator"]) in lost:
            problems.append(f"{m['problem']} {m['integrator']}: no observed order any more ({m['reason']})")
    if problems:
        raise AssertionError(f"run {run} against run {baseline_run} ({len(result['cells'])} common cells; "
                             f"slower beyond x{factor:g} (a scheme's median) or x{result['cell_factor']:g} "
                             f"(a cell), errors beyond x{error_factor:g}): " + " | ".join(problems))
    return result


def _interval(ci: Any) -> str:
    return f"[{_g(ci[0])}, {_g(ci[1])}]" if isinstance(ci, (list, tuple)) and len(ci) == 2 else str(ci)


def _g(x: Any) -> str:
    return f"{x:.3g}" if isinstance(x, (int, float)) and not isinstance(x, bool) else str(x)


def _cell(c: dict) -> str:
    from longtime.reporting.report import setting

    return setting(c) or "default settings"


def benchmark_cell(benchmark: Any, problem: Any, scheme: Any, *, t_final: float | None = None,
                   processes: int | None = None, cost: str = "time", **settings: Any) -> dict[str, Any]:
    """Time one cell with pytest-benchmark's ``benchmark`` fixture: the cell runs once
    first (compiling its kernel, measuring its accuracy against the reference), then the
    fixture times its integration alone, which must reproduce that run bitwise. The row's
    accuracy fields (``l2_error``, ``final_error``, each invariant's ``.max``/``.mean``/
    ``.final``/``.growth``/``.growth_class``, ``status``, ``steps``, ``rhs_evals``) go into
    ``benchmark.extra_info``, so ``pytest --benchmark-json`` carries them beside the time.
    The fixture's times come from this process only; so with ``processes`` (default
    ``$LONGTIME_PROCESSES`` or 3) above 1, ``processes - 1`` fresh processes also time the
    integration (longtime.execution.processes), each reproducing the run bitwise, and
    ``extra_info`` gets each process's minimum CPU time (``cpu_s_processes``, this
    process's measured run first) and their spread (``cpu_s_process_spread``, max / min):
    a verdict on this benchmark judges that spread. ``cost="instructions"`` also counts the
    integration under Valgrind (``--cost instructions``) and puts ``instructions``,
    ``instructions_per_step`` (or ``instructions_skipped``, the reason) there too: a
    deterministic cost, which a loaded CI machine does not move. Returns the row."""
    from longtime.core.timing import Timing
    from longtime.core.trajectory import run_digest, same_run
    from longtime.execution.cells import run_cell
    from longtime.execution.child import RunSpec
    from longtime.execution.matrix import check_cost
    from longtime.execution.processes import check_processes, default_processes, run_children
    from longtime.reporting.report import complete

    check_cost(cost)
    processes = default_processes() if processes is None else check_processes(processes, "processes")

    cells = cells_for([problem], [scheme], t_final, settings, strict=True)
    if len(cells) != 1:
        raise AssertionError(f"benchmark_cell times one cell; the settings give {len(cells)}")
    keep: dict[str, Any] = {}
    row = complete(run_cell(cells[0], timing=Timing(repeats=1), keep=keep))
    if "trajectory" not in keep or row["status"] != Status.OK:
        raise AssertionError(f"{cells[0].integrator} on {cells[0].problem}: status {row['status']}: {row['message']}")
    prob, integ, first = keep["problem"], keep["integrator"], keep["trajectory"]
    t_end = prob.default_t_final if cells[0].t_final is None else cells[0].t_final
    timed = benchmark(integ.integrate, prob, t_end)
    if not same_run(first, timed):
        raise AssertionError(f"{integ.name} on {prob.name}: the timed integration did not reproduce the measured one")
    benchmark.extra_info.update(accuracy_fields(row))
    if processes > 1:
        digest = run_digest(first)
        minima = [row["cpu_s"]]
        spec = RunSpec(100_001, Timing().per_process(processes), time_limit=None)
        for results, why in run_children(cells, processes - 1, spec, 1, 600.0):
            if results is None:
                raise AssertionError(f"{integ.name} on {prob.name}: a timing process gave no result: {why}")
            (res,) = results
            if res.get("status") != Status.OK or res.get("samples_digest") != digest:
                raise AssertionError(f"{integ.name} on {prob.name}: the run timed in another process did not "
                                     f"reproduce the measured one ({res.get('status')}: {res.get('message')})")
            minima.append(res["cpu_s"])
        benchmark.extra_info.update(cpu_s_processes=minima,
                                    cpu_s_process_spread=max(minima) / min(minima) if min(minima) > 0 else None)
    if cost == "instructions":
        from longtime.execution.cells import DEFAULT_MAX_SAMPLES
        from longtime.execution.valgrind import FIELDS, instruction_fields

        row.update(instruction_fields([(cells[0], row)], DEFAULT_MAX_SAMPLES, None)[cells[0].key])
        benchmark.extra_info.update({k: row.get(k) for k in FIELDS})
    return row


def accuracy_fields(row: dict[str, Any]) -> dict[str, Any]:
    """The fields of a row that say how accurate it was (and what it ran)."""
    keep = ("problem", "integrator", "status", *row_columns(), "t_final", "settings", "steps",
            "rhs_evals", "l2_error", "final_error", "reference", "reference_error", "error_horizon",
            "error_floor", "error_below_floor", "discretisation_error")
    suffixes = (".max", ".mean", ".final", ".growth", ".growth_class")
    return {k: v for k, v in row.items()
            if (k in keep or k.endswith(suffixes)) and (v is None or isinstance(v, (str, int, float, bool)))}
