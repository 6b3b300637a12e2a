"""The verdict as text: one problem's verdict as report lines (``verdict_lines``), a
decision in words, and the stored checks of its predictions one per line."""
from __future__ import annotations

from typing import Any

from longtime.core.rowschema import formatted
from longtime.core.rowtext import setting
from longtime.predict.checks import CHECK_COST_FACTOR, check_holds, check_summary
from longtime.predict.decision import Decision, Verdict, deciding_run
from longtime.predict.settings import LOST, TRUST_FACTORS


def failed_first(checks: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """The checks in the order a reader needs them: failed, then not judged, then held."""
    order = {False: 0, None: 1, True: 2}
    return sorted(checks, key=lambda c: order[check_holds(c)])


def check_text(c: dict[str, Any]) -> str:
    """One check as a line: 'rk4 dt=0.01 to t = 1.260e+04 (best; ...): error 3.000e-06
    predicted, 2.500e-06 measured; CPU ...: held', each field as it formats (rowschema.formatted)."""
    holds = check_holds(c)
    verdict = {True: "held", False: "MISSED", None: "not judged"}[holds]
    me, pe = c.get("measured_error"), c.get("predicted_error")
    role = c.get("check_role")
    if role in ("chaos", "growth"):
        error = (f"error above {formatted('check_target', c['check_target'])} predicted, "
                 f"{formatted('measured_error', me)} measured")
    else:
        at_most = "at most " if c.get("predicted_bound") and pe is not None else ""
        error = (f"error {at_most}{formatted('predicted_error', pe)} predicted, "
                 f"{formatted('measured_error', me)} measured")
    rank = ""
    if c.get("rank_held") is not None:
        rank = f"; rank {'held' if c['rank_held'] else 'MISSED'} against {', '.join(c.get('rank_rivals') or [])}"
        if c.get("rank_lost_to"):
            rank += f" (cheaper by more than x{CHECK_COST_FACTOR:g}: {', '.join(c['rank_lost_to'])})"
    return (f"{c['integrator']} {setting(c)} to t = {formatted('t_final', c['t_final'])} "
            f"({role + '; ' if role else ''}{c.get('check_law')}): {error}; "
            f"CPU {formatted('predicted_cpu_s', c['predicted_cpu_s'])} s predicted, "
            f"{formatted('cpu_s', c.get('cpu_s'))} s measured{rank}: {verdict}")


def horizon_groups(v: Verdict, horizon: float) -> list[tuple[float, float, Decision]]:
    """The map's column at ``horizon`` folded: consecutive targets with the same decision
    (the same best setting, or the same state) as (loosest target, finest target, decision)."""
    out: list[tuple[float, float, Decision]] = []
    for t in v.targets:
        d = v.grid[(t, horizon)]
        key = (d.state, id(d.best) if d.best else None)
        if out and (out[-1][2].state, id(out[-1][2].best) if out[-1][2].best else None) == key:
            out[-1] = (out[-1][0], t, out[-1][2])
        else:
            out.append((t, t, d))
    return out


def _range(lo: float, hi: float) -> str:
    return f"{lo:.0e}" if lo == hi else f"{lo:.0e}..{hi:.0e}"


def decision_text(d: Decision) -> str:
    if d.limit is not None:
        kept = d.limit.kept_until
        if kept is None or d.limit.horizon < kept * (1 - 1e-9):  # the reference ends first
            return f"no pointwise answer past t = {d.limit.horizon:.3g} (the reference is trusted only up to there)"
        why = "chaos" if d.limit.lyapunov_time is not None else "an unstable flow"
        return f"no pointwise answer past t = {d.limit.horizon:.3g} ({why}; a finer target: sooner)"
    if d.best is not None:
        return d.best.text
    if d.open:
        return "undetermined (" + ", ".join(s.scheme for s in d.open[:3]) + ")"
    return "none measured"


def verdict_lines(v: Verdict, full: bool = False) -> list[str]:
    """The verdict of one problem as report lines: what is read, one line per horizon (the
    winners per target range), the open questions and the checks."""
    if v.measure is None or not v.candidates:
        return [f"  verdict: none (no ok row with an error, a growth class and a CPU time; "
                f"`longtime matrix -p {v.problem}` measures them)"]
    lines = [f"  verdict: the cheapest setting predicted to keep {v.measure.field} <= target up to T "
             f"({v.measure.text}; `longtime recommend -p {v.problem} --error E --horizon T`):"]
    for h in v.horizons:
        groups = [g for g in horizon_groups(v, h) if g[2].state != "none"]
        mark = "(run)" if h == v.t_main else ""
        text = "; ".join(f"{_range(lo, hi)} {decision_text(d)}" for lo, hi, d in groups) or "none predicted"
        lines.append(f"    T = {h:<9.3g}{mark:<6s}{text}")
    kinds = ("invariant",) if v.candidates[0].kind == "invariant" else ("solution", "drifting")
    chaotic = any(s.kind == "chaotic" for s in v.candidates)
    if chaotic:
        kinds = ("chaotic",)
    lines.append("  trusted: " + "; ".join(
        ("the energy drifting: " if kind == "drifting" else "a chaotic problem's solution error: "
         if kind == "chaotic" else f"{kind} error: ")
        + ", ".join(f"{k} x{f:g}" for k, f in TRUST_FACTORS[kind].items()) for kind in kinds)
        + f" its run's span; past it, and at a predicted error >= {LOST:g} (lost), nothing is predicted")
    far = max((s.reach for s in v.candidates), default=0.0)
    if chaotic:
        lines.append(f"  chaotic: past the predictability horizon no run decides a pointwise error; `longtime ensemble "
                     f"-p {v.problem}` measures which schemes keep the distribution the orbit visits")
    elif v.horizons and v.horizons[-1] > far * (1 + 1e-9):
        # of the settings reaching farthest, the most accurate there
        s = min((s for s in v.candidates if s.reach == far),
                key=lambda s: (s._law_at(far) if s.extrapolates else s.error, s.cpu_per_t, s.text))
        lines.append(f"  not determined past t = {far:.4g} (the farthest reach; the most accurate there, {s.text}): "
                     f"`{deciding_run(s, v.horizons[-1])}` would decide it")
    stuck = [s for s in v.candidates if not s.extrapolates]
    if stuck:
        first = sorted(stuck, key=lambda s: s.cpu_per_t)[0]
        lines.append(f"  not extrapolated: {len(stuck)} of {len(v.candidates)} settings (growth undetermined, faster, "
                     f"or a class not trusted past the run); the cheapest, {first.text} ({first.law_text()}), "
                     f"is decided by "
                     f"`{deciding_run(first, 10 * first.span)}`")
    if v.checks:
        lines.append(f"  checks: {check_summary(v.checks)}")
        shown = failed_first(v.checks if full else [c for c in v.checks if check_holds(c) is not True])
        lines += [f"    {check_text(c)}" for c in shown]
    return lines
