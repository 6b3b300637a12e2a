"""The results page: a static folder, index.html and its figures beside it as SVG files
(figures/<digest>.svg, each an <img> that loads lazily, with its size so that the page lays
out before any figure loads); no script or style from the network, no server. The page and
its figures are written together: the figures first, each whole, then index.html (renamed
into place), then the figures of the page it replaced; a failed write leaves the previous
page and its figures as they were.

Head: the run's metadata (command, commit, versions, machine) and the counts of each
status. Per problem: the work-precision figure (error against the minimum CPU time of the
repeats, a bar to the slowest repeat), the drift of every invariant against time for a
representative setting of each scheme (log-log, so growth laws read as slopes; one panel
per invariant), the change of the problem's diagnostics likewise, the Pareto front as a
table, the growth classes per scheme and setting, the fitted orders, and the stability
intervals of the schemes where they were measured. Then one capability matrix, schemes x
problems: ran / skipped and why / diverged / failed.

Colours: a colour and a marker per scheme, one look per scheme in every figure of the page
and no two schemes of a figure alike (longtime.reporting.figures.style.styles of the page's
schemes); legends sit outside the axes.

The figures are drawn by longtime.reporting.figures.results (ahead of the page, by idle
pool workers, with longtime.reporting.figures_ahead).
"""
from __future__ import annotations

import hashlib
import html
import json
import re
from datetime import datetime, timezone
from pathlib import Path
from typing import Any, Callable, Iterable

from longtime.core.files import NotWritten, write_atomic
from longtime.core.status import Status
from longtime.measure.orders import left_out, observed_orders
from longtime.predict.decision import Verdict
from longtime.reporting.figures.results import calibration_svg, figures_drawing
from longtime.reporting.figures.style import styles
from longtime.reporting.figures.verdict import checks_svg, winner_map_svg
from longtime.reporting.figures_ahead import FiguresAhead, stability_schemes
from longtime.reporting.markup import CSS, SCRIPT, escape, num, slug, table
from longtime.reporting.page_answers import (
    answers_section,
    example_answer,
    libraries_section,
    no_answer_text,
)
from longtime.reporting.page_tables import (
    capability_matrix,
    chaos_table,
    ensemble_table,
    growth_table,
    orders_table,
    pareto_table,
    stability_table,
)
from longtime.reporting.report import STOPPED, counts_text, not_ok

PAGE_NAME = "index.html"
FIGURES_DIR = "figures"  # the page's figures, beside index.html

_SVG = re.compile(r"<svg\b.*?</svg>", re.S)
_PT = re.compile(r'\b(width|height)="([0-9.]+)pt"')
_CAPTION = re.compile(r"\s*<figcaption>([^<]*)")


def provenance_text(run: dict) -> str:
    """longtime's commit (dirty marked) and the code under test of a stored run."""
    from longtime.execution import provenance

    versions = json.loads(run["versions"]) if run.get("versions") else {}
    own = versions.get("longtime_git") if isinstance(versions, dict) else None
    mine = ""
    if isinstance(own, dict) and own.get("commit"):
        mine = f"longtime {own['commit'][:10]}{'+dirty' if own.get('dirty') else ''}; "
    return mine + provenance.text(provenance.run_code(run))


def _meta(runs: list[dict]) -> str:
    body = []
    for r in runs:
        versions = json.loads(r["versions"]) if r.get("versions") else {}
        machine = json.loads(r["machine"]) if r.get("machine") else {}
        body += [["run", f"{r['id']} ({r.get('status')}; {r.get('done')} of {r.get('planned')} cells)"],
                 ["command", f"longtime {r.get('command') or ''}"],
                 ["started / finished", f"{r.get('started')} / {r.get('finished') or '-'}"],
                 ["commit", r.get("git_commit") or "-"],
                 ["code under test", provenance_text(r)],
                 ["versions", ", ".join(f"{k} {v}" for k, v in versions.items() if v and isinstance(v, str))],
                 ["machine", ", ".join(f"{k} {v}" for k, v in machine.items() if v)]]
        if "calibrations" in r:
            from longtime.execution.calibration import drift_text

            body.append(["calibration", drift_text(r["calibrations"])])
    rows = "".join(f"<tr><td>{escape(a)}</td><td>{escape(b)}</td></tr>" for a, b in body)
    return f'<table class="meta">{rows}</table>'


def _fold(summary: str, body: str, open_: bool = False) -> str:
    """``body`` folded under ``summary`` (a <details>, closed unless ``open_``)."""
    return f'<details{" open" if open_ else ""}><summary>{summary}</summary>{body}</details>'


def _verdict_section(p: str, v, mine: list[dict], style: dict | None = None, fig: str | None = None) -> str:
    """One problem's verdict: an example answer, the winner map ``fig`` (winner_map_svg of
    ``v`` in the page's ``style``), the winners as a table (folded) and the settings whose
    law does not extrapolate, each with its deciding run."""
    from longtime.predict.checks import check_counts, check_summary
    from longtime.predict.decision import deciding_run
    from longtime.reporting.verdict import check_text, decision_text, failed_first, horizon_groups

    head = f'<h3 id="verdict-{slug(p)}">{escape(p)}</h3>'
    if v.measure is None or not v.candidates:
        return head + (f'<p class="note">No verdict: no ok row with an error, a growth class and a CPU time '
                       f'(<code>longtime matrix -p {escape(p)}</code> measures them).</p>')
    out = [head]
    example = example_answer(v)
    if example:
        t, h, d = example
        b, r = d.best, d.runner_up
        runner = (f"; runner-up {escape(r.text)}, x{r.cpu_at(h) / b.cpu_at(h):.3g} the CPU" if r else
                  "; no other scheme is predicted to keep it")
        out.append(f'<p class="answer">To keep {escape(v.measure.field)} &le; {t:.0e} up to T = {h:.3g} '
                   f'({h / v.t_main:.0f} times the runs\' t_final): <b>{escape(b.text)}</b>, predicted error '
                   f'{b.error_at(h):.2g} ({escape(b.law_text())}), CPU {b.cpu_at(h):.3g} s{runner}. '
                   f'<span class="note">Any other target and horizon: the map below, or <code>longtime recommend -p '
                   f'{escape(p)} --error E --horizon T</code>.</span></p>')
    else:
        out.append(f'<p class="answer">{escape(no_answer_text(v))}.</p>')
    if fig:
        out.append(f'<figure class="plot">{fig}<figcaption>Winner map: for each target ({escape(v.measure.text)}) '
                   f"and horizon T, the scheme of the cheapest setting predicted to keep it (its setting written "
                   f"in the cell), from each setting's measured CPU time per unit of simulated time and its growth "
                   f"class, each class trusted up to a stated multiple of its run's span; grey: undetermined "
                   f"(a cheaper setting's law is not determined that far); "
                   f"circles and crosses: predictions re-run and checked.</figcaption></figure>")
    body = []
    for h in v.horizons:
        for lo, hi, d in horizon_groups(v, h):
            if d.best is None:
                if d.state == "undetermined":
                    body.append([f"{h:.3g}", f"{lo:.0e}" + (f" .. {hi:.0e}" if hi != lo else ""),
                                 decision_text(d), "-", "-", "-", "-"])
                continue
            b, r = d.best, d.runner_up
            body.append([f"{h:.3g}", f"{lo:.0e}" + (f" .. {hi:.0e}" if hi != lo else ""), b.text,
                         num(b.error_at(h)), num(b.cpu_at(h)), b.law_text(),
                         f"{r.text} (x{r.cpu_at(h) / b.cpu_at(h):.3g})" if r else "none"])
    out.append(_fold(f"The winners as a table ({len(body)} rows: horizon, targets, predicted error and CPU, law, "
                     f"runner-up)", table(["T", f"{v.measure.field} <=", "cheapest setting", "predicted error at T",
                                           "predicted CPU s", "growth law", "runner-up (its CPU)"], body)))
    stuck = sorted((s_ for s_ in v.candidates if not s_.extrapolates), key=lambda s_: s_.cpu_per_t)
    if stuck:
        items = "".join(f"<li>{escape(s_.text)}: {escape(s_.law_text())}; "
                        f"<code>{escape(deciding_run(s_, 10 * s_.span))}</code></li>" for s_ in stuck[:12])
        more = f"<li>and {len(stuck) - 12} more</li>" if len(stuck) > 12 else ""
        out.append(_fold(f"Not extrapolated: {len(stuck)} of {len(v.candidates)} settings (growth undetermined, "
                         f"faster, or a class not trusted past the run), with the run that would decide each",
                         f"<ul>{items}{more}</ul>"))
    if v.checks:
        out.append(_fold(f"Checks: {escape(check_summary(v.checks))}",
                         "<ul>" + "".join(f"<li>{escape(check_text(c))}</li>" for c in failed_first(v.checks))
                         + "</ul>", open_=check_counts(v.checks)["failed"] > 0))
    return "".join(out)


def _checks_section(checks: list[dict], figure: Callable[[], str | None]) -> str:
    """The checked predictions: their summary, the failed ones, ``figure()`` (their figure,
    ``checks_svg``, drawn beside the page)."""
    from longtime.predict.checks import check_holds, check_summary
    from longtime.reporting.verdict import check_text

    out = ['<h2 id="checks">Checked predictions</h2>']
    if not checks:
        out.append('<p class="note">No prediction of these rows was re-run: <code>longtime matrix</code> checks a few '
                   'at the longest horizon its budget affords (<code>--checks N</code>).</p>')
        return "".join(out)
    out.append(f'<p class="answer">{escape(check_summary(checks))}.</p>')
    failed = [c for c in checks if check_holds(c) is False]
    if failed:  # the checks that failed first, each in a line
        out.append('<p>Failed:</p><ul>' + "".join(f"<li>{escape(check_text(c))}</li>" for c in failed) + "</ul>")
    fig = figure()
    if fig:
        out.append(f'<figure class="plot">{fig}<figcaption>Each check: a winner of a map re-run at a horizon past its '
                   f"run, its predicted error against the measured one (filled: its CPU time within the predicted "
                   f"x1.5; the band: within a factor 3).</figcaption></figure>")
    return "".join(out)


def _cards_section(rows: list[dict]) -> str | None:
    """The scheme cards (longtime.reporting.card), where that module is installed."""
    import importlib.util

    if importlib.util.find_spec("longtime.reporting.card") is None:
        return None
    from longtime.reporting.card import cards_html

    return '<h2 id="cards">Scheme cards</h2>' + cards_html(rows)


def _evidence(p: str, mine: list[dict], figs: dict, fits: list[dict], missing: list[dict], drift: bool,
              ensembles: list[dict] = ()) -> str:
    """One problem's evidence, each piece folded: the Pareto front, work-precision, orders,
    growth classes, drift and diagnostics; what did not run to the end stays open."""
    out = [f'<h3 id="{slug(p)}">{escape(p)}</h3><p>{escape(counts_text(mine))}</p>']
    folded = not_ok(mine)
    if folded:  # open where something failed, diverged or lost the solution; skips alone stay folded
        failed = sorted(k for k in folded if not k.startswith("skipped") and k != STOPPED)
        skipped = sum(len(v) for k, v in folded.items() if k.startswith("skipped"))
        stopped = len(folded.get(STOPPED, []))  # no failure: folded like the skips
        what = "; ".join([f"{k.split(' (')[0].split(',')[0]}: {len(folded[k])} schemes" for k in failed]
                         + ([f"skipped: {skipped} schemes"] if skipped else [])
                         + ([f"stopped at their library's bound: {stopped} schemes"] if stopped else []))
        out.append(_fold(f"Not run to the end, or the solution lost ({escape(what)})", "<ul>" + "".join(
            f"<li>{escape(why)}: {escape(', '.join(s))}</li>"
            for why, s in sorted(folded.items(), key=lambda kv: kv[0].startswith("skipped")))
            + "</ul>", bool(failed)))
    out.append(_fold("Fastest scheme per accuracy at the runs' t_final (Pareto front)", pareto_table(mine)))
    fig = figs["work_precision"]
    if fig:
        out.append(_fold("Work-precision figure", f'<figure class="plot">{fig}<figcaption>{escape(figs["field"])} '
                                                  f"against CPU seconds, one point per setting; a colour and a marker "
                                                  f"per scheme.</figcaption></figure>"))
    fig = figs.get("work_precision_instructions")
    if fig:
        out.append(_fold("Work-precision in instructions", f'<figure class="plot">{fig}<figcaption>'
                         f"{escape(figs['field'])} against the instructions of the integration, counted under "
                         f"Valgrind (--cost instructions): a deterministic cost, blind to cache misses and "
                         f"memory stalls; cells without a count are left out.</figcaption></figure>"))
    orders = orders_table([f for f in fits if f["problem"] == p])
    mine_missing = [m for m in missing if m["problem"] == p]
    if orders or mine_missing:
        body = ('<p class="note">Least-squares slope of log error against log step over the asymptotic range '
                '(floors and pre-asymptotic points dropped), with its 95 % interval; only where at least two '
                'local slopes agree within 0.1 (otherwise the order is undetermined, listed below with its '
                'slopes, and never flagged).</p>' + orders if orders else "")
        if mine_missing:
            body += "<p>Left out of the order table:</p><ul>" + "".join(
                f"<li>{escape(m['integrator'])}: {escape(m['reason'])}</li>" for m in mine_missing) + "</ul>"
        out.append(_fold("Observed order", body))
    growth = growth_table(mine)
    if growth:
        out.append(_fold("Growth classes", growth))
    chaos = chaos_table(mine)
    if chaos:
        out.append(_fold("Chaos: Lyapunov time and predictability horizons", chaos))
    spread = ensemble_table([e for e in ensembles if e.get("problem") == p])
    if spread:
        ok = [e for e in ensembles if e.get("problem") == p and e.get("status") == Status.OK]
        told = sum(1 for e in ok if e.get("distinguishable"))
        out.append(_fold(f"Chaos: ensemble distance to heyoka's distribution ({len(ok) - told} of {len(ok)} "
                         f"measured schemes as heyoka)", spread, open_=True))
    if drift:
        fig, notes = figs["drift"], figs["drift_notes"]
        if fig:
            out.append(_fold("Invariant drift against time", f'<figure class="plot">{fig}<figcaption>'
                             f"Relative error of each invariant (absolute where it starts at 0), log-log (a "
                             f"slope is a growth law), for each scheme's setting of median steps (the upper "
                             f"envelope each row keeps); one panel per invariant."
                             f"{escape(' ' + '; '.join(notes)) if notes else ''}</figcaption></figure>"))
        fig, notes = figs.get("diagnostics"), figs.get("diagnostics_notes") or []
        if fig:
            out.append(_fold("Diagnostics against time", f'<figure class="plot">{fig}<figcaption>'
                             f"Change of each diagnostic from its initial value, relative (absolute where it "
                             f"starts at 0), log-log: quantities the problem watches but the flow does not "
                             f"conserve, so never a drift and never classed."
                             f"{escape(' ' + '; '.join(notes)) if notes else ''}</figcaption></figure>"))
    return "".join(out)


def build_page(rows: list[dict[str, Any]], runs: list[dict[str, Any]], drift: bool = True,
               stability: bool = True, jobs: int = 1, ahead: FiguresAhead | None = None,
               history: str | Callable[[], str | None] | None = None, checks: Iterable[dict[str, Any]] = (),
               writer: str = "report --html", ensembles: Iterable[dict[str, Any]] = (),
               verdicts: dict[str, Verdict] | None = None) -> str:
    """The page's HTML for ``rows`` (of the ``runs`` whose metadata closes it), led by the
    verdict of each problem (``checks``: the stored checks of its predictions), then the
    scheme cards, then the evidence (folded), the history, the capability matrix, the
    stability intervals and the run and machine; the figures are drawn on ``jobs``
    processes, but for those ``ahead`` drew from the same rows. ``history``: the history
    section (longtime.reporting.history_page), or the function that makes it. ``writer``: the command that wrote
    the page, named in its footer. ``ensembles``: the stored ensemble distances of the
    chaotic problems (each in its problem's evidence). ``verdicts``: ``map_verdicts`` of the
    rows and checks, where the caller has them."""
    from longtime.reporting.recommend import map_verdicts

    ensembles = list(ensembles)
    problems = sorted({r["problem"] for r in rows})
    checks = list(checks)
    style = styles(sorted({r["integrator"] for r in rows}))
    # the heaviest problems first, so the processes finish together
    by_problem = dict(sorted(((p, [r for r in rows if r["problem"] == p]) for p in problems),
                             key=lambda item: -len(item[1])))
    from longtime.measure.stability import interval_texts

    builtin, plugins = stability_schemes(rows) if stability else ({}, {})
    # the figures drawn on other processes while this one does the rest
    later = len(problems) + 1 + len(runs)  # the winner maps, the checks' figure, the calibrations'
    with figures_drawing(by_problem, style, drift, jobs, builtin, ahead, later=later) as (drawn, draw):
        found = map_verdicts(rows, checks) if verdicts is None else verdicts
        # the checks' figure, the winner maps and the run's calibrations drawn beside the rest
        # (each costs what a work-precision figure does), in the order the page reads them
        checks_figure = draw(checks_svg, checks) if checks else (lambda: None)
        maps = {p: draw(winner_map_svg, found[p], style) for p in problems}
        calibrations = [draw(calibration_svg, r.get("calibrations") or []) for r in runs]
        fits = observed_orders(rows)
        missing = left_out(rows)
        cards = _cards_section(rows)
        checked = _checks_section(checks, checks_figure)
        history = history() if callable(history) else history
        verdict_sections = [_verdict_section(p, found[p], by_problem[p], style, maps[p]()) for p in problems]
        figures, intervals = drawn()
        calibration_figures = [(r, figure()) for r, figure in zip(runs, calibrations)]
    ids = ", ".join(str(r["id"]) for r in runs) or "-"
    out = ["<!DOCTYPE html>", '<html lang="en"><head><meta charset="utf-8">',
           '<meta name="viewport" content="width=device-width, initial-scale=1">',
           "<title>longtime results</title>", f"<style>{CSS}</style>", "</head><body>",
           "<h1>longtime: which scheme for this problem, horizon and accuracy</h1>",
           f'<p class="lead"><b>{len(rows)} cells</b> ({escape(counts_text(rows))}) '
           f'of run{"s" if len(runs) != 1 else ""} '
           f'{escape(ids)}. <a href="#about">The run, the machine and its calibration</a> are at the end.</p>',
           '<nav><b>Contents:</b> <a href="#answers">answers</a><a href="#libraries">which library</a>'
           + "<b>verdict:</b> " + "".join(f'<a href="#verdict-{slug(p)}">{escape(p)}</a>' for p in problems)
           + '<br><a href="#checks">checked predictions</a>'
           + ('<a href="#cards">scheme cards</a>' if cards else "")
           + '<a href="#evidence">evidence</a>' + ('<a href="#history">history</a>' if history else "")
           + '<a href="#capabilities">capability matrix</a><a href="#about">run and machine</a></nav>',
           answers_section(problems, found, rows), libraries_section(rows),
           '<h2 id="verdict">Verdict</h2>'
           '<p class="note">Per problem, the cheapest stored setting predicted to keep a target error '
           'up to a horizon T: '
           "its error at T from its measured error and growth class (bounded: flat; sqrt, linear, quadratic: "
           "t^(1/2, 1, 2) from its run's final time), its CPU time from its measured CPU time per unit of simulated "
           "time. A class predicts only as far as it was measured to hold (its reach: a solution error classed "
           "bounded or sqrt not past its run, a linear one up to 100 times it, a quadratic one or an invariant's "
           "error up to 1000 times, less where the energy drifts, the slopes still steepen or the run is short "
           "against the problem's horizon); past its reach, or where its growth is undetermined, a "
           "setting predicts nothing. docs/metrics.md says how a prediction is made and checked.</p>"]
    out += verdict_sections
    out.append(checked)
    if cards:
        out.append(cards)
    out.append('<h2 id="evidence">Evidence</h2><p class="note">What the verdicts rest on, per problem, folded: '
               "click a line to open it.</p>")
    for p in problems:
        out.append(_evidence(p, by_problem[p], figures[p], fits, missing, drift, ensembles))
    if history:
        out.append(history)
    out.append('<h2 id="capabilities">Capability matrix</h2>' + capability_matrix(rows))
    stab = stability_table({**interval_texts(plugins), **intervals}) if stability else None
    if stab:
        out.append('<h2 id="stability">Linear stability</h2>' + stab)
    out.append('<h2 id="about">The run and the machine</h2>' + _meta(runs))
    out += _calibration_figures(calibration_figures)
    out.append(f'<p class="note footer">Written {datetime.now(timezone.utc).isoformat(timespec="seconds")} by '
               f"<code>longtime {escape(writer)}</code>.</p>")
    out.append(f"<script>{SCRIPT}</script></body></html>")
    return "\n".join(out)


def _calibration_figures(drawn: list[tuple[dict[str, Any], str | None]]) -> list[str]:
    """Per run with calibrations (``drawn``: each run and its ``calibration_svg``): how the
    machine's speed drifted during it."""
    out = []
    for r, fig in drawn:
        if fig:
            out.append(f'<figure class="plot">{fig}<figcaption>Run {r["id"]}: the reference workload\'s CPU time '
                       f"(the fastest of its repeats, a bar to the slowest) at each calibration; each row's "
                       f"<code>cpu_s_calibrated</code> is its <code>cpu_s</code> over the calibration of its "
                       f"process nearest in time.</figcaption></figure>")
    return out


def figure_files(page: str) -> tuple[str, dict[str, bytes]]:
    """(the page with each inline SVG figure replaced by an <img> of its file, {file name
    relative to the page: its bytes}). A file is named by a digest of its content; the <img>
    carries the figure's size in CSS pixels and, as its text, the start of its caption."""
    files: dict[str, bytes] = {}

    def to_file(m: re.Match) -> str:
        figure = m.group(0)
        name = f"{FIGURES_DIR}/{hashlib.md5(figure.encode()).hexdigest()[:16]}.svg"
        files[name] = ('<?xml version="1.0" encoding="utf-8" standalone="no"?>\n' + figure).encode()
        root = figure[:figure.index(">")]
        size = "".join(f' {k}="{round(float(v) * 4 / 3)}"' for k, v in _PT.findall(root))  # 1 pt = 4/3 px
        caption = _CAPTION.match(page, m.end())
        alt = re.split(r"[:;.(]", html.unescape(caption.group(1)))[0].strip() if caption else ""
        return f'<img src="{name}" loading="lazy" alt="{escape(alt or "figure")}"{size}>'

    return _SVG.sub(to_file, page), files


def write_page(out_dir: str | Path, rows: list[dict[str, Any]], runs: list[dict[str, Any]],
               drift: bool = True, jobs: int = 1, ahead: FiguresAhead | None = None,
               history: str | Callable[[], str | None] | None = None, checks: Iterable[dict[str, Any]] = (),
               writer: str = "report --html", ensembles: Iterable[dict[str, Any]] = (),
               verdicts: dict[str, Verdict] | None = None) -> Path:
    """Write ``out_dir``/index.html and its figures (drawn on ``jobs`` processes, or
    ``ahead``) in ``out_dir``/figures; return the page's path."""
    page, files = figure_files(build_page(rows, runs, drift=drift, jobs=jobs, ahead=ahead, history=history,
                                          checks=checks, writer=writer, ensembles=ensembles, verdicts=verdicts))
    return write_folder(out_dir, page, files)


def write_folder(out_dir: str | Path, page: str, files: dict[str, bytes]) -> Path:
    """``page`` as ``out_dir``/index.html with ``files`` beside it, replacing an earlier page
    and its figures at once (the rename of index.html): the files first, then the page, then
    the earlier page's figures that this one does not use. On a failed write the files
    written so far are removed, the earlier page keeps its own, and ``NotWritten`` names the
    page (and the figure that failed)."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    page_path = out / PAGE_NAME
    folder = out / FIGURES_DIR
    made = not folder.exists()
    written, name = [], None
    try:
        for name, data in files.items():
            path = out / name
            if path.is_file() and not path.is_symlink() and path.read_bytes() == data:
                continue  # the same figure, already there (its name is its digest)
            path.parent.mkdir(parents=True, exist_ok=True)
            written.append(write_atomic(path, data))
        name = None
        write_atomic(page_path, page)
    except OSError as exc:  # NotWritten, or a folder that cannot be made
        for path in written:
            path.unlink(missing_ok=True)
        if made and folder.is_dir() and not any(folder.iterdir()):
            folder.rmdir()
        if name is None and isinstance(exc, NotWritten):
            raise
        what = f" (its figure {name})" if name else ""
        raise NotWritten(exc.errno, f"{exc.strerror or exc}{what}", str(page_path)) from exc
    for old in folder.glob("*.svg") if folder.is_dir() else ():
        if f"{FIGURES_DIR}/{old.name}" not in files:
            old.unlink(missing_ok=True)
    return page_path


def write_html(out_dir, rows: list[dict[str, Any]], store, run_ids: Iterable[int] | None = None,
               jobs: int | None = None, ahead=None, writer: str = "report --html",
               verdicts: dict[str, Verdict] | None = None):
    """The results page of ``rows`` into ``out_dir``/index.html, with the checks the store
    keeps of ``run_ids``' predictions, its metadata at the end (default: every run the rows
    come from), its figures drawn on ``jobs`` processes (default: one per core) but for those
    drawn ``ahead`` (an figures_ahead.FiguresAhead); ``writer``: the command that writes it
    (the footer names it); ``verdicts``: ``map_verdicts`` of the rows and the checks the
    store keeps of ``run_ids``, where the caller has them; returns its path."""
    from longtime.reporting.history import machines_section
    from longtime.reporting.history_page import page_section

    ids = sorted(set(run_ids) if run_ids is not None else {r.get("run_id") for r in rows if r.get("run_id")})
    runs = [{**r, "calibrations": store.calibrations(r["id"])} for r in store.runs() if r["id"] in ids]
    checks = [c for i in ids for c in store.checks(i)]
    problems = {r["problem"] for r in rows}
    ensembles = [e for i in ids for e in store.ensembles(i) if e["problem"] in problems]

    def history() -> str | None:  # the page writes it while its figure processes draw
        section = page_section(store, rows, styles(sorted({r["integrator"] for r in rows})))
        return "\n".join(filter(None, (section, machines_section(store, rows)))) or None  # several machines

    from longtime.execution.pool import workers

    return write_page(out_dir, rows, runs, jobs=workers(jobs or 0), ahead=ahead, history=history, checks=checks,
                      writer=writer, ensembles=ensembles, verdicts=verdicts)
