"""The results page's first screen (longtime.reporting.page): the Answers table (per problem,
the cheapest setting predicted to keep a target up to a hundred times the runs' final time)
and "Which library" (per problem and library, the cheapest setting measured to keep 1e-6 at
the runs' final time). The two ask different questions (a horizon past the runs, predicted
by growth laws, against the runs' own final time, measured), so where they name different
settings the Answers table says why, from the setting "Which library" names."""
from __future__ import annotations

from typing import Any

from longtime.core.rowtext import setting
from longtime.reporting.markup import escape, slug, table


def example_answer(v):
    """(target, horizon, decision) of a verdict's example answer: at a hundred times the
    runs' final time, 1e-6 where predicted (else the middle of the targets predicted there);
    None where no target is predicted there."""
    h = v.horizons[min(2, len(v.horizons) - 1)]
    met = [t for t in v.targets if v.grid[(t, h)].best is not None]
    if not met:
        return None
    t = 1e-6 if 1e-6 in met else met[len(met) // 2]
    return t, h, v.grid[(t, h)]


def no_answer_text(v) -> str:
    """Why a verdict has no example answer: past the predictability horizon, or no setting."""
    h = v.horizons[min(2, len(v.horizons) - 1)]
    chaotic = next((d for (_, h_), d in v.grid.items() if h_ == h and d.limit is not None), None)
    if chaotic is not None:  # past the predictability horizon: no pointwise answer, and why
        return f"No pointwise answer up to T = {h:.3g}: {chaotic.limit.text()}"
    return f"No setting is predicted to keep any target up to T = {h:.3g}"


def why_not_library_best(v, t: float, h: float, best, rows: list[dict[str, Any]]) -> str | None:
    """Why the answer (``best``, for target ``t`` up to ``h``) is not the setting "Which
    library" names cheapest for this problem (measured at the runs' final time, at its own
    target): that setting's predicted error or CPU up to ``h``, its law's reach, or the
    other target or measure; None where the two name the same setting or the table names none."""
    from longtime.reporting.libraries import TARGET, cheapest_kept

    row = cheapest_kept(rows, TARGET)
    if row is None:
        return None
    text = " ".join(x for x in (row["integrator"], setting(row)) if x)
    if text == best.text:
        return None
    asked = [f"{TARGET:g} measured at T = {v.t_main:.4g}"]
    if t != TARGET:
        asked.append(f"the answer's target is {t:.0e}")
    if v.measure is not None and v.measure.field != "max_error":
        asked.append(f"the answer's error is {v.measure.field}")
    s = next((c for c in v.candidates if c.text == text), None)
    if s is None:
        why = "it is no candidate for a prediction (no growth law of its error)"
    else:
        state = s.state_at(h)
        e = s.error_at(h)
        if state == "lost":
            why = f"its error is predicted O(1) by T = {h:.3g}"
        elif state == "undetermined":
            why = f"its error is not predicted up to T = {h:.3g} ({s.law_text()})"
        elif e is not None and e > t:
            why = f"its error is predicted {e:.2g} at T = {h:.3g} ({s.law}), past {t:.0e}"
        else:
            why = f"up to T = {h:.3g} it is predicted {s.cpu_at(h):.3g} s, dearer than {best.cpu_at(h):.3g} s"
    return (f"Which library's cheapest, {text} ({'; '.join(asked)}), is not the answer: {why}")


def answers_section(problems: list[str], found: dict, rows: list[dict[str, Any]]) -> str:
    """The first screen's answer: one row per problem, its example answer (the verdict's
    first line) with its CPU and the runner-up's ratio, and why it is not the setting "Which
    library" names where they differ; the verdict below says more."""
    body, notes = [], []
    for p in problems:
        v = found[p]
        link = f'<a href="#verdict-{slug(p)}">{escape(p)}</a>'
        if v.measure is None or not v.candidates:
            body.append([link, '<td colspan="5">no verdict: no ok row with an error, a growth class and a CPU '
                               "time</td>"])
            continue
        example = example_answer(v)
        if example is None:
            body.append([link, f'<td colspan="5">{escape(no_answer_text(v))}</td>'])
            continue
        t, h, d = example
        b, r = d.best, d.runner_up
        body.append([link, f"<td>{escape(v.measure.field)} &le; {t:.0e} up to T = {h:.3g}</td>",
                     f"<td><b>{escape(b.text)}</b></td>", f'<td class="num">{b.cpu_at(h):.3g}</td>',
                     f'<td class="num">{b.error_at(h):.2g}</td>',
                     f"<td>{escape(r.text)} (x{r.cpu_at(h) / b.cpu_at(h):.3g})</td>" if r else "<td>none</td>"])
        why = why_not_library_best(v, t, h, b, [x for x in rows if x.get("problem") == p])
        if why:
            notes.append(f"<li>{escape(p)}: {escape(why)}.</li>")
    lines = "".join("<tr>" + (f"<td>{c[0]}</td>" + "".join(c[1:])) + "</tr>" for c in body)
    head = "".join(f"<th>{h}</th>" for h in ("problem", "target", "cheapest setting", "CPU s", "predicted error",
                                             "runner-up (its CPU)"))
    differ = (f'<ul class="note">{"".join(notes)}</ul>' if notes else "")
    return (f'<h2 id="answers">Answers</h2><table class="answers"><tr>{head}</tr>{lines}</table>'
            '<p class="note">Per problem, the cheapest stored setting predicted to keep the target up to T '
            '(a hundred times the runs\' final time, by each setting\'s growth law); any other target and horizon: '
            '<a href="#verdict">the verdicts</a> below. <a href="#libraries">Which library</a> measures at the '
            "runs' final time itself: where it names another setting, the line below says why.</p>" + differ)


def libraries_section(rows: list[dict]) -> str:
    """Which library for each problem: its cheapest measured setting that keeps the target."""
    from longtime.reporting.libraries import TARGET, library_table

    header, body = library_table(rows)
    return (f'<h2 id="libraries">Which library</h2><p class="note">Per problem and library, the cheapest ok '
            f"setting measured to keep its solution error (max_error: the largest error of any block of the "
            f"state over [0, T], relative to its motion) &le; {TARGET:g} over the problem's main run (T: the "
            f"final time most of its rows ran to), its CPU seconds, its error and its CPU as a multiple of the "
            f"cheapest library's; or why the library has none (too slow: a run stopped at the time limit, the "
            f"seconds it ran and how far it got, or its cheapest setting estimated past a cell's budget). "
            f"Measured rows only, no extrapolation: the Answers above are predicted a hundred times further.</p>"
            + table(header, body))
