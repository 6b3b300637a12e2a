"""A card for every scheme: where it stands, from the stored rows and from its step map.

A card gathers, for one scheme: what it declares (order, symplectic, requirements); per
problem of the rows, its observed order (determined with its interval, flagged where it
misses the declared one, or undetermined with the local slopes: longtime.measure.orders),
the growth class of each invariant and of the solution error (its longest run), its rhs
evaluations and instructions per step, and where it sits on the problem's Pareto front
(per accuracy decade: fastest, or its CPU time over the fastest's); beside them its
stability interval on the imaginary axis (longtime.measure.stability) and its structure
measured from one step on a canonical problem (longtime.measure.structure). ``card``
builds it as a dict (the JSON of ``longtime card --format json``), ``card_text`` and
``card_markdown`` render it, ``cards_html`` gives the results page one folded card per
scheme.
"""
from __future__ import annotations

import statistics
from typing import Any, Iterable

from longtime.core.fmt import positive
from longtime.core.rowschema import formatted
from longtime.core.status import Status
from longtime.reporting.markup import escape, slug

NOT_MEASURED = "not measured"
# the cards' own style, carried by the fragment wherever it is placed
CARD_CSS = ("<style>details.card{border:1px solid #ddd;border-radius:4px;margin:.3em 0;padding:.2em .6em}"
            "details.card>summary{cursor:pointer}details.card[open]{background:#fafafa}"
            "details.card table{width:100%}details.card th{width:10em;white-space:nowrap}</style>")


def _declared(name: str, scheme: Any = None) -> dict[str, Any]:
    from longtime.core import registry

    cls = scheme if isinstance(scheme, type) else (type(scheme) if scheme is not None and not isinstance(scheme, str)
                                                    else None)
    if cls is None:
        cls = registry.integrator_class(name)
    return {"summary": cls.summary, "kind": cls.kind, "declared_order": cls.order,
            "declared_symplectic": bool(cls.symplectic), "requires": sorted(cls.requires),
            "family": next((b.__name__ for b in cls.__mro__[1:] if b.__module__.startswith("longtime.")),
                           cls.__mro__[1].__name__)}


def _orders(rows: list[dict], name: str) -> dict[str, list[dict[str, Any]]]:
    from longtime.measure.orders import fit_text, left_out, observed_orders

    mine = [r for r in rows if r.get("integrator") == name]
    out: dict[str, list[dict[str, Any]]] = {}
    for f in observed_orders(mine):
        out.setdefault(f["problem"], []).append(
            {"observed": f["observed_order"], "ci": f["observed_order_ci"], "flag": f["order_flag"],
             "points": len(f["order_points"]), "slopes": f["order_slopes"], "t_final": f["t_final"],
             "setting": _fixed(f), "reason": None, "text": fit_text(f)})
    for m in left_out(mine):
        out.setdefault(m["problem"], []).append(
            {"observed": None, "ci": None, "flag": False, "points": 0, "slopes": m["slopes"], "t_final": None,
             "setting": "", "reason": m["reason"], "text": None})
    return out


def _fixed(f: dict) -> str:
    parts = [f"N={f['order']}"] if f.get("order") is not None else []
    if f.get("settings"):
        parts.append(str(f["settings"]))
    return " ".join(parts)


def _growth(rows: list[dict]) -> dict[str, dict[str, Any]]:
    """name -> {"class", "reason", "setting", "t_final"} of the longest ok run with a class
    (the smallest step among equals)."""
    from longtime.reporting.report import growth_names, setting

    out = {}
    ok = [r for r in rows if r.get("status") == Status.OK]
    for name in growth_names(ok):
        have = [r for r in ok if r.get(f"{name}.growth_class")]
        if not have:
            continue
        r = max(have, key=lambda r: (r.get("t_final") or 0, -(r.get("mean_dt") or 0)))
        out[name] = {"class": r[f"{name}.growth_class"], "reason": r.get(f"{name}.growth_reason"),
                     "setting": setting(r), "t_final": r.get("t_final")}
    return out


def _per_step(rows: list[dict]) -> dict[str, Any]:
    ok = [r for r in rows if r.get("status") == Status.OK and isinstance(r.get("steps"), int) and r["steps"] > 0]
    rhs = [r["rhs_evals"] / r["steps"] for r in ok if isinstance(r.get("rhs_evals"), (int, float))]
    ins = [r["instructions_per_step"] for r in ok if positive(r.get("instructions_per_step"))]
    return {"rhs_evals_per_step": statistics.median(rhs) if rhs else None,
            "instructions_per_step": statistics.median(ins) if ins else None}


def _pareto(rows: list[dict], name: str, fronts: dict[str, tuple] | None = None) -> list[dict[str, Any]]:
    """Per accuracy decade of the problem's front: the fastest scheme and this scheme's best
    CPU time over the fastest's (None where no row of it meets the target). ``fronts``: each
    problem's (field, main final time, front) as found for another card of the same rows,
    and where this one's is found."""
    from longtime.reporting.report import main_t_final, pareto, pareto_field

    problem = rows[0]["problem"]
    found = fronts.get(problem) if fronts is not None else None
    if found is None:
        field = pareto_field(rows)
        found = (field, main_t_final(rows), pareto(rows, field) if field else [])
        if fronts is not None:
            fronts[problem] = found
    field, t_main, front = found
    if not field:
        return []
    mine = [r for r in rows if r.get("integrator") == name and r.get("status") == Status.OK and positive(r.get("cpu_s"))
            and positive(r.get(field)) and r.get("t_final") == t_main]
    out = []
    for p in front:
        meets = [r["cpu_s"] for r in mine if r[field] <= p["target"]]
        out.append({"target": p["target"], "field": field, "fastest": p["best"]["integrator"],
                    "is_fastest": p["best"]["integrator"] == name,
                    "ratio": min(meets) / p["best"]["cpu_s"] if meets else None})
    return out


def card(scheme: Any, rows: Iterable[dict] | None = None, *, structure: bool = True,
         stability: bool = True, fronts: dict[str, tuple] | None = None) -> dict[str, Any]:
    """The card of ``scheme`` (a registered name, a class or an instance) from ``rows``
    (row dicts; None: the scheme alone). ``structure``/``stability``: measure the step map
    and the stability interval (each takes a few compiled steps; the interval is cached).
    ``fronts``: the problems' fronts shared between the cards of the same rows (``_pareto``)."""
    from longtime.measure import structure as structure_mod
    from longtime.measure.stability import interval_texts

    name = scheme if isinstance(scheme, str) else scheme.name
    rows = [r for r in (rows or [])]
    out: dict[str, Any] = {"scheme": name, **_declared(name, scheme)}
    out["stability_interval"] = (interval_texts({name: None}, compute=True).get(name, NOT_MEASURED)
                                 if stability else NOT_MEASURED)
    out["structure"] = structure_mod.measure(scheme).as_dict() if structure else None
    orders = _orders(rows, name)
    by_problem: dict[str, list[dict]] = {}
    for r in rows:
        by_problem.setdefault(r["problem"], []).append(r)
    problems = []
    for problem in sorted({r["problem"] for r in rows if r.get("integrator") == name}):
        all_rows = by_problem[problem]
        mine = [r for r in all_rows if r.get("integrator") == name]
        if all(r.get("status") == Status.SKIPPED for r in mine):  # the scheme cannot treat the problem
            problems.append({"problem": problem, "cells": len(mine), "ok": 0, "statuses": ["skipped"],
                             "does_not_apply": _skip_reason(mine), "orders": [], "growth": {},
                             "rhs_evals_per_step": None, "instructions_per_step": None, "pareto": []})
            continue
        problems.append({"problem": problem, "cells": len(mine), "does_not_apply": None,
                         "ok": sum(r.get("status") == Status.OK for r in mine),
                         "statuses": sorted({str(r.get("status")) for r in mine}),
                         "orders": orders.get(problem, []), "growth": _growth(mine), **_per_step(mine),
                         "pareto": _pareto(all_rows, name, fronts)})
    out["problems"] = problems
    return out


def _skip_reason(rows: list[dict]) -> str:
    reasons = sorted({str(r.get("message") or "skipped") for r in rows})
    return "; ".join(reasons)


def run_hint(name: str) -> str:
    """A ``longtime run`` command that measures some rows of scheme ``name``: on a problem
    it can treat (kepler or harmonic where it can, else the first by name), sweeping the
    parameter its accuracy is set by (its step or accuracy role: --dt for a fixed-step
    scheme, --eps-res for bpl, --tol for an adaptive one), three values from its default
    (a fixed step from the problem's default step, halved; an accuracy tightened tenfold, or
    loosened from a default near round-off); no flag where it declares none."""
    from longtime.core import registry, roles

    cls = registry.integrator_class(name)
    problems = registry.problems()
    fits = [p for p in ("kepler", "harmonic", *sorted(problems)) if p in problems
            and not set(cls.requires) - problems[p].capabilities()]
    problem = fits[0] if fits else "PROBLEM"
    command = f"longtime run -i {name} -p {problem}"
    params = roles.declared([cls])
    for param_name in roles.with_role([cls], *roles.ACCURACY_ROLES):
        default = params[param_name].default
        if default is None and params[param_name].role == "step" and problem in problems:
            default = getattr(problems[problem], "default_dt", None)
        if isinstance(default, (int, float)) and default > 0:
            # a step halves; an accuracy tightens tenfold, or loosens from a default near round-off
            scale = 2.0 if params[param_name].role == "step" else (10.0 if default >= 1e-12 else 0.01)
            values = ",".join(f"{default / scale ** k:.3g}" for k in range(3))
            return f"{command} {roles.flag(param_name)} {values}"
    return command


# ------------------------------------------------------------------ rendering
def _order_text(o: dict) -> str:
    if o["observed"] is None:
        return f"undetermined ({o['reason']})"
    flag = " MISSES the declared order" if o["flag"] else ""
    at = f" [{o['setting']}]" if o["setting"] else ""
    return f"{o['text']}{at}{flag}"


def _pareto_text(entries: list[dict]) -> str:
    """'(l2_error) fastest at 1e-01..1e-03; x1.86 at 1e-04 (rk4 fastest); not met at 1e-05..1e-10'."""
    if not entries:
        return "no front (no ok row with an error and a CPU time)"
    groups: list[list] = []  # [kind, first target, last target, ratio, fastest scheme]
    for e in entries:
        kind = "fastest" if e["is_fastest"] else ("not met" if e["ratio"] is None else "ratio")
        last = groups[-1] if groups else None
        same = ((kind != "ratio" or (f"{last[3]:.3g}" == f"{e['ratio']:.3g}" and last[4] == e["fastest"]))
                if last else False)
        if last and last[0] == kind and same:
            last[2] = e["target"]
        else:
            groups.append([kind, e["target"], e["target"], e["ratio"], e["fastest"]])
    parts = []
    for kind, first, last, ratio, fastest in groups:
        at = f"{first:.0e}" if first == last else f"{first:.0e}..{last:.0e}"
        parts.append(f"fastest at {at}" if kind == "fastest" else f"not met at {at}" if kind == "not met"
                     else f"x{ratio:.3g} at {at} ({fastest} fastest)")
    return f"({entries[0]['field']}) " + "; ".join(parts)


def _per_step_text(p: dict) -> str:
    rhs = p["rhs_evals_per_step"]
    ins = p["instructions_per_step"]
    return (f"rhs evaluations per step {rhs:.3g}" if rhs is not None
            else f"rhs evaluations per step {NOT_MEASURED}") + \
        (f", instructions per step {formatted('instructions_per_step', ins)}" if ins is not None
         else f", instructions per step {NOT_MEASURED}")


def _structure_text(s: dict | None) -> str:
    from longtime.measure.structure import reversibility_text

    if s is None:
        return NOT_MEASURED
    if s["reason"]:
        return f"{NOT_MEASURED} ({s['reason']})"
    kept = ", ".join(s["kept"]) or "none"
    return (f"on {s['problem']}, one step h = {s['h']:g}: symplecticity defect ||M^T J M - J|| "
            f"{s['symplecticity_defect']:.2e} (finite-difference error <= {s['symplecticity_error']:.1e}: "
            f"{'symplectic' if s['symplectic'] else 'NOT symplectic'}); {reversibility_text(s)}; "
            f"invariants kept to round-off: {kept}")


def _lines(c: dict) -> list[tuple[str, str]]:
    """(label, text) lines of a card, in order."""
    out = [("declared", f"order {c['declared_order'] if c['declared_order'] is not None else '-'}, "
                        f"{'symplectic' if c['declared_symplectic'] else 'not declared symplectic'}, {c['kind']}"
                        + (f", needs {', '.join(c['requires'])}" if c["requires"] else "")),
           ("stability", f"on the imaginary axis {c['stability_interval']}"),
           ("structure", _structure_text(c["structure"]))]
    return out


def _undetermined(p: dict) -> bool:
    """Every order of problem entry ``p`` is undetermined."""
    return bool(p["orders"]) and all(o["observed"] is None for o in p["orders"])


def _why_kind(reason: str) -> str:
    """An undetermined order's reason in brief: '2 points only', 'every point above 0.1',
    'pre-asymptotic', ..."""
    import re

    return re.split(r" \(|: |; ", str(reason))[0]


def _problem_lines(p: dict, full: bool = True) -> list[tuple[str, str]]:
    if not full and _undetermined(p):  # counted in the card's one line about them
        orders = "undetermined (below)"
    else:
        orders = "; ".join(_order_text(o) for o in p["orders"]) or "no sweep"
    growth = ", ".join(f"{'solution error' if n == 'error' else n} {formatted(f'{n}.growth_class', g['class'])}"
                       for n, g in p["growth"].items()) or "no growth law"
    return [("observed order", orders), ("growth (longest run)", growth), ("cost", _per_step_text(p)),
            ("Pareto front", _pareto_text(p["pareto"]))]


def card_text(c: dict, full: bool = True) -> str:
    """The plain-text card (``longtime card``). ``full=False``: the problems it does not
    apply to, and the reasons of the orders left undetermined, each summarised in one line
    (``longtime card --full`` gives each)."""
    lines = [f"{c['scheme']}: {c['summary']}".rstrip(": ")]
    lines += [f"  {label}: {text}" for label, text in _lines(c)]
    if not c["problems"]:
        lines.append(f"  no stored rows of {c['scheme']} in {c.get('rows_from') or 'the rows'}: "
                     f"`{run_hint(c['scheme'])}` measures some")
    not_applied: dict[str, list[str]] = {}
    undetermined: dict[str, list[str]] = {}
    for p in c["problems"]:
        if p.get("does_not_apply"):
            if full:
                lines.append(f"  == {p['problem']}: does not apply ({p['does_not_apply']}) ==")
            else:
                not_applied.setdefault(str(p["does_not_apply"]).split(", which")[0], []).append(p["problem"])
            continue
        lines.append(f"  == {p['problem']}: {p['ok']} of {p['cells']} cells ok ==")
        lines += [f"    {label}: {text}" for label, text in _problem_lines(p, full)]
        if not full and _undetermined(p):
            for o in p["orders"]:
                undetermined.setdefault(_why_kind(o["reason"]), []).append(p["problem"])
    if undetermined:
        lines.append(f"  order undetermined on {len({q for ps in undetermined.values() for q in ps})} problems: "
                     + "; ".join(f"{why} ({', '.join(sorted(set(ps)))})" for why, ps in
                                 sorted(undetermined.items(), key=lambda kv: -len(kv[1])))
                     + " (`--full`: each with its slopes)")
    if not_applied:
        lines.append("  does not apply: " + "; ".join(f"{why} ({', '.join(ps)})" for why, ps in not_applied.items()))
    return "\n".join(lines)


def card_markdown(c: dict) -> str:
    lines = [f"### {c['scheme']}", "", c["summary"] or "", ""]
    lines += [f"- **{label}**: {text}" for label, text in _lines(c)]
    if c["problems"]:
        lines += ["", "| problem | " + " | ".join(label for label, _ in _problem_lines(c["problems"][0])) + " |",
                  "|---" * 5 + "|"]
        for p in c["problems"]:
            texts = [f"does not apply ({p['does_not_apply']})"] + [""] * 3 if p.get("does_not_apply") else [
                t for _, t in _problem_lines(p)]
            lines.append(f"| {p['problem']} | " + " | ".join(t.replace("|", "/") for t in texts) + " |")
    return "\n".join(lines) + "\n"


def card_html(c: dict, notes: Iterable[tuple[str, str]] = ()) -> str:
    """One card: a folded <details> whose summary line says the declared and the measured
    structure and the problems where the scheme is fastest; ``notes`` are (label, text)
    lines added after the card's own (the verdicts that name the scheme, say)."""
    fastest = [p["problem"] for p in c["problems"] if any(e["is_fastest"] for e in p["pareto"])]
    s = c["structure"]
    struct = "" if not s or s["reason"] else (
        f"; measured {'symplectic' if s['symplectic'] else 'not symplectic'}"
        + ("" if s["reversible"] is None else f", {'reversible' if s['reversible'] else 'not reversible'}"))
    flagged = [p["problem"] for p in c["problems"] if any(o["flag"] for o in p["orders"])]
    declared = c['declared_order'] if c['declared_order'] is not None else '-'
    head = (f"<b>{escape(c['scheme'])}</b> order {escape(declared)}"
            + escape(struct)
            + (f"; fastest somewhere on {escape(', '.join(fastest))}" if fastest else "")
            + (f' <span class="flag">misses its order on {escape(", ".join(flagged))}</span>' if flagged else ""))
    body = "".join(f"<tr><th>{escape(label)}</th><td>{escape(text)}</td></tr>"
                   for label, text in [*_lines(c), *notes])
    rows = []
    for p in c["problems"]:
        if p.get("does_not_apply"):
            rows.append(f"<tr><td>{escape(p['problem'])}</td><td colspan=\"4\">does not apply "
                        f"({escape(p['does_not_apply'])})</td></tr>")
            continue
        rows.append("<tr>" + f"<td>{escape(p['problem'])}</td>"
                    + "".join(f"<td>{escape(t)}</td>" for _, t in _problem_lines(p)) + "</tr>")
    table = ("<table><tr><th>problem</th>" + "".join(f"<th>{escape(label)}</th>" for label, _ in
                                                      _problem_lines(c["problems"][0])) + "</tr>" + "".join(rows)
             + "</table>") if c["problems"] else '<p class="note">no stored rows</p>'
    return (f'<details class="card" id="card-{slug(c["scheme"])}"><summary>{head}</summary>'
            f"<p>{escape(c['summary'])}</p><table>{body}</table>{table}</details>")


def cards_html(rows: list[dict], schemes: Iterable[str] | None = None, *, structure: bool = True,
               stability: bool = False, notes: dict[str, list[tuple[str, str]]] | None = None) -> str:
    """The results page's scheme cards: an HTML fragment, one folded card per scheme of
    ``rows`` (or ``schemes``), by name. ``stability``: measure intervals not in the cache
    (cached ones are shown either way). ``notes``: scheme -> (label, text) lines each card
    adds (plain text, escaped here)."""
    names = sorted(set(schemes) if schemes is not None else {r["integrator"] for r in rows})
    parts = []
    fronts: dict[str, tuple] = {}  # each problem's front, found for the first card that reads it
    for name in names:
        try:
            c = card(name, rows, structure=structure, stability=True, fronts=fronts) if stability else \
                _cached_card(name, rows, structure, fronts)
        except Exception as exc:  # a scheme no longer installed: its rows still say what they say
            parts.append(f'<p class="note">{escape(name)}: no card ({escape(type(exc).__name__)}: '
                         f'{escape(exc)})</p>')
            continue
        parts.append(card_html(c, (notes or {}).get(name, ())))
    note = ('<p class="note">One card per scheme (click to unfold): declared and observed order per problem '
            '(undetermined where the local slopes still move), growth class of each invariant and of the '
            'solution error on its longest run, cost per step, its place on each Pareto front, its stability '
            'interval and the structure measured from one step on a canonical problem (docs/metrics.md).</p>')
    return '<section id="scheme-cards">' + CARD_CSS + note + "".join(parts) + "</section>"


def _cached_card(name: str, rows: list[dict], structure: bool, fronts: dict[str, tuple]) -> dict[str, Any]:
    from longtime.measure.stability import cached_texts

    c = card(name, rows, structure=structure, stability=False, fronts=fronts)
    texts, _ = cached_texts({name: None})
    c["stability_interval"] = texts.get(name, NOT_MEASURED)
    return c
