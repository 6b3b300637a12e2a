"""Exponentially long times, measured: the breakdown time T*(dt) of a bounded energy error
and the law it follows in the step.

Backward error analysis (Benettin and Giorgilli 1994; Hairer, Lubich and Wanner IX.8) says
that a symplectic scheme conserves a modified energy up to errors of size e^(-gamma/dt) per
unit time, so its energy error stays O(dt^r) for times up to about e^(gamma/dt): the claim
of the paper that longtime reproduces. A non-symplectic scheme's energy drifts like
C dt^p t, so its breakdown time grows only as a power of 1/dt.

Backward error analysis gives a LOWER bound on the time the energy stays close (the
modified energy is conserved up to e^(-gamma/dt) per unit time, so nothing can break down
sooner than about e^(gamma/dt)), not a law T* ~ e^(gamma/dt) for when it does: a measured
T*(dt) may grow faster. So the exponential law is fitted, but said to hold only where the
data can tell it from a constant (its slope's interval excludes 0) and from a power law
(the power law bends away from the points, or the steps outside the fitted range
contradict it), and where no step outside the fitted range contradicts it (a step without
breakdowns gives a lower bound on T*); else it is ``undetermined`` with the reason, beside
the local slopes d ln T* / d(1/dt) between successive steps.

Here a *breakdown* of one run is the first time its orbit escapes (the run diverged, while
the exact orbit is bounded) or, where a threshold is given, its energy error reaches it. Over an ensemble
of runs (members) breakdowns come at random times, as escapes from a chaotic sea do; the
members that have not broken down by t_final are censored. With exponentially distributed
breakdown times, the maximum-likelihood rate is r = k / S (k breakdowns over the exposure S,
the time all members ran before breaking down or being censored), and T* = 1/r with the
exact Poisson (Garwood) interval on k. ln T* is then fitted against 1/dt (the exponential
law) and against ln dt (a power law), each weighted by k (var ln r ~ 1/k).

"""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field
from typing import Any, Iterable

import numpy as np

# fewer observed breakdowns than this at a step: T* is too uncertain to enter a fit
MIN_EVENTS = 3
MIN_POINTS = 4


@dataclass
class Breakdown:
    """T*(dt) of one scheme at one step, from an ensemble of runs."""

    dt: float
    members: int
    events: int
    exposure: float  # summed time the members ran before breaking down or being censored
    t_final: float
    t_star: float | None  # 1 / rate; None where nothing broke down (a lower bound only)
    t_star_ci: tuple[float, float]  # 95 % (Garwood) interval; (lower bound, inf) when events == 0
    median_t: float | None  # median breakdown time, censored at t_final (None: under half broke)
    times: list[float | None] = field(default_factory=list)  # per member, None: censored
    # the largest |H - H0| of the members that held to t_final (None: none held, or not measured)
    held_swing: float | None = None

    def as_dict(self) -> dict[str, Any]:
        return asdict(self)


def breakdown_time(t: np.ndarray, energy_error: np.ndarray, threshold: float | None,
                   escaped_at: float | None) -> float | None:
    """The first time the orbit escaped (``escaped_at``: where the run diverged) or the energy
    error reached ``threshold`` (None: escapes only), whichever is first; None: neither."""
    first = None
    if threshold is not None:
        hit = np.flatnonzero(~(np.asarray(energy_error) < threshold))  # a NaN error counts
        first = float(t[hit[0]]) if hit.size else None
    candidates = [x for x in (first, escaped_at) if x is not None]
    return min(candidates) if candidates else None


def estimate(dt: float, times: Iterable[float | None], t_final: float, t0: float = 0.0,
             swings: Iterable[float] | None = None) -> Breakdown:
    """The breakdown rate's maximum-likelihood estimate over censored members, as T*;
    ``swings`` (per member, its largest |H - H0|) gives ``held_swing``."""
    from scipy.stats import chi2

    times = list(times)
    held = [w for t, w in zip(times, swings) if t is None] if swings is not None else []
    spans = [(t if t is not None else t_final) - t0 for t in times]
    k = sum(t is not None for t in times)
    exposure = float(sum(spans))
    if k:
        lo = chi2.ppf(0.025, 2 * k) / (2 * exposure)
        hi = chi2.ppf(0.975, 2 * k + 2) / (2 * exposure)
        t_star, ci = exposure / k, (1.0 / hi, 1.0 / lo)
    else:
        t_star, ci = None, (exposure / (chi2.ppf(0.95, 2) / 2), math.inf)
    ordered = sorted(spans)
    median = None
    if 2 * k > len(times):  # more than half broke down: the median is an observed time
        median = t0 + float(np.median(ordered))
    return Breakdown(dt=float(dt), members=len(times), events=k, exposure=exposure, t_final=float(t_final),
                     t_star=t_star, t_star_ci=(float(ci[0]), float(ci[1])), median_t=median, times=times,
                     held_swing=float(max(held)) if held else None)


def fit_law(points: list[Breakdown], law: str) -> dict[str, Any]:
    """ln T* against 1/dt (``law="exponential"``: ln T* = a + gamma/dt) or against ln dt
    (``law="power"``: ln T* = a - p ln dt), weighted by the breakdown counts, with the
    interval of the slope (gamma or p) from the residuals (an ensemble of chaotic orbits
    scatters more than Poisson counts do). The line *holds* where its slope's 95 % interval
    excludes 0 and a quadratic term, fitted beside it, is not significant (its 95 % interval
    contains 0): the points do not bend away from the line more than they scatter about it.
    Returns the fit, the points used and dropped, and the verdict (``holds``, ``does not
    hold``, ``undetermined``) with its reason."""
    from scipy.stats import t as student

    used = [p for p in points if p.events >= MIN_EVENTS and p.t_star]
    out: dict[str, Any] = {"law": law, "points": len(used), "dropped": [
        {"dt": p.dt, "reason": (f"{p.events} breakdowns (fewer than {MIN_EVENTS})" if p.events else
                                f"none of {p.members} broke down by t = {p.t_final:g}")}
        for p in points if p not in used]}
    if len(used) < MIN_POINTS:
        out.update(slope=None, slope_ci=None, verdict="undetermined",
                   reason=f"{len(used)} steps with at least {MIN_EVENTS} breakdowns; a fit needs {MIN_POINTS} "
                          "(a longer t_final or more members decides it)")
        return out
    x = np.array([1.0 / p.dt if law == "exponential" else -math.log(p.dt) for p in used])
    y = np.log([p.t_star for p in used])
    w = np.array([float(p.events) for p in used])
    line, line_se, line_rss = _weighted_fit(x, y, w, degree=1)
    curve, curve_se, _ = _weighted_fit(x, y, w, degree=2)
    dof = len(used) - 2
    half = float(student.ppf(0.975, dof) * line_se[1])
    slope = float(line[1])
    out.update(slope=slope, slope_ci=(slope - half, slope + half), intercept=float(line[0]),
               residual=float(math.sqrt(line_rss / w.sum())))
    bend, bend_half = float(curve[2]), float(student.ppf(0.975, dof - 1) * curve_se[2]) if dof > 1 else math.inf
    out["curvature"] = bend
    out["curvature_ci"] = (bend - bend_half, bend + bend_half)
    lo_x, hi_x = sorted((float(x.min()), float(x.max())))
    span = (f"1/dt {1 / used[0].dt:.3g} to {1 / used[-1].dt:.3g}" if law == "exponential" else
            f"dt {used[-1].dt:.3g} to {used[0].dt:.3g}")
    contradicted = []
    for p in points:
        if p in used:
            continue
        px = 1.0 / p.dt if law == "exponential" else -math.log(p.dt)
        predicted = math.exp(line[0] + slope * px)
        lo, hi = p.t_star_ci
        if not lo <= predicted <= hi:
            measured = (f"T* in [{lo:.3g}, {hi:.3g}]" if p.events else
                        f"no breakdown of {p.members} to t = {p.t_final:g}: T* >= {lo:.3g}")
            contradicted.append(f"dt {p.dt:g}: {measured}, where the fit predicts {predicted:.3g}")
    out["contradicted"] = contradicted
    if contradicted:
        out.update(verdict="does not hold", reason=f"fitted over {span}, it is contradicted outside that range: "
                                                   + "; ".join(contradicted))
    elif slope - half <= 0:
        out.update(verdict="undetermined", reason=f"the slope's 95 % interval [{slope - half:.3g}, "
                                                  f"{slope + half:.3g}] contains 0: not told from a constant")
    elif not bend - bend_half <= 0 <= bend + bend_half:
        out.update(verdict="does not hold", reason=f"the points bend away from a line: a quadratic term "
                                                   f"{bend:.3g} [{bend - bend_half:.3g}, {bend + bend_half:.3g}]")
    else:
        out.update(verdict="holds", reason=f"no significant bend (quadratic term {bend:.3g} [{bend - bend_half:.3g}, "
                                           f"{bend + bend_half:.3g}]), rms residual {out['residual']:.2g} in ln T*, "
                                           f"over {span}")
    out["span"] = (lo_x, hi_x)
    return out


def local_slopes(points: list[Breakdown]) -> list[dict[str, Any]]:
    """d ln T* / d(1/dt) between successive steps (by increasing 1/dt): {"from", "to" (the
    dt), "slope", "bound"}; toward a step without breakdowns the slope is a lower bound
    (``bound`` "at least", from that step's lower bound on T*), between two such steps none."""
    ordered = sorted(points, key=lambda p: -p.dt)
    out = []
    for a, b in zip(ordered, ordered[1:]):
        if a.t_star is None:
            continue
        dx = 1.0 / b.dt - 1.0 / a.dt
        if b.t_star is not None:
            out.append({"from": a.dt, "to": b.dt, "slope": math.log(b.t_star / a.t_star) / dx, "bound": None})
        else:
            out.append({"from": a.dt, "to": b.dt, "slope": math.log(b.t_star_ci[0] / a.t_star) / dx,
                        "bound": "at least"})
    return out


def local_slopes_text(slopes: list[dict[str, Any]]) -> str:
    """'dt 0.9 -> 0.85: 0.01; 0.7 -> 0.65: >= 27.3' (d ln T* / d(1/dt))."""
    return "; ".join(f"{s['from']:g} -> {s['to']:g}: {'>= ' if s['bound'] else ''}{s['slope']:.3g}" for s in slopes)


def judge(exp_fit: dict[str, Any], power_fit: dict[str, Any], swing: float | None = None,
          gap: float | None = None) -> dict[str, Any]:
    """The exponential law's verdict against the alternatives: it *holds* only where its own
    fit holds and the power law's does not (the data tell the two apart); an escape counts as
    a breakdown of the O(dt^r) energy bound only where the orbits that never escape swing in
    energy (``swing``, the largest |H - H0| of the members that held) by less than the
    ``gap`` to the escape energy. Returns {"verdict", "reason"}."""
    if swing is not None and gap is not None and swing >= gap:
        return {"verdict": "undetermined",
                "reason": f"an escape is not a breakdown of the O(dt^r) energy bound here: orbits that never escape "
                          f"already swing by |H - H0| = {swing:.3g}, as much as the gap {gap:g} to the escape energy; "
                          f"the escape times' own fit {exp_fit['verdict']} ({exp_fit['reason']})"}
    if exp_fit["verdict"] != "holds":
        return {"verdict": exp_fit["verdict"], "reason": exp_fit["reason"]}
    if power_fit.get("verdict") == "holds":
        return {"verdict": "undetermined",
                "reason": f"not told apart from a power law: T* ~ dt^-{power_fit['slope']:.3g} holds as well over "
                          f"the same steps ({exp_fit['reason']}); a wider span of 1/dt, whose steps break down "
                          f"within t_final, decides"}
    return {"verdict": "holds", "reason": f"{exp_fit['reason']}; the power law {power_fit['verdict']}"
                                          + (f" ({power_fit['reason']})" if power_fit.get("reason") else "")}


def _weighted_fit(x: np.ndarray, y: np.ndarray, w: np.ndarray, degree: int):
    """Coefficients (constant first) of the weighted least-squares polynomial, their standard
    errors scaled by the residuals, and the weighted residual sum of squares."""
    A = np.vander(x, degree + 1, increasing=True)
    sw = np.sqrt(w)
    coef, *_ = np.linalg.lstsq(A * sw[:, None], y * sw, rcond=None)
    resid = y - A @ coef
    rss = float(w @ resid**2)
    dof = len(x) - degree - 1
    sigma2 = rss / dof if dof > 0 else math.inf
    cov = np.linalg.inv((A * w[:, None]).T @ A) * sigma2
    return coef, np.sqrt(np.diag(cov)), rss


def verdict_text(scheme: str, exp_fit: dict[str, Any], power_fit: dict[str, Any],
                 judged: dict[str, Any] | None = None, slopes: list[dict[str, Any]] | None = None) -> str:
    """One sentence: whether the exponential law holds for ``scheme`` (``judged``: its verdict
    against the alternatives, ``judge``), with what gamma, and the local slopes."""
    judged = judged or {"verdict": exp_fit["verdict"], "reason": exp_fit["reason"]}
    local = f"; local slopes d ln T*/d(1/dt), dt {local_slopes_text(slopes)}" if slopes else ""
    if judged["verdict"] == "undetermined" or exp_fit.get("slope") is None:
        return f"{scheme}: ln T* = a + gamma/dt undetermined ({judged['reason']}){local}"
    lo, hi = exp_fit["slope_ci"]
    text = (f"{scheme}: ln T* = a + gamma/dt {judged['verdict']}, gamma = {exp_fit['slope']:.3g} "
            f"[{lo:.3g}, {hi:.3g}] ({judged['reason']}){local}")
    if power_fit.get("slope") is not None:
        plo, phi = power_fit["slope_ci"]
        better = "the exponential law" if exp_fit["residual"] < power_fit["residual"] else "the power law"
        text += (f"; as a power law T* ~ dt^-p, p = {power_fit['slope']:.3g} [{plo:.3g}, {phi:.3g}] "
                 f"({power_fit['verdict']}); {better} leaves the smaller residual")
    return text
