"""A main job's results page and report (longtime.execution.main_job): what `longtime
matrix` prints after its cells and what ``longtime.api.main_job`` returns."""
from __future__ import annotations

import sys
from dataclasses import dataclass
from pathlib import Path

from longtime.core import phases
from longtime.core.progress import Progress
from longtime.execution.main_job import MainJobResult
from longtime.reporting.page import write_html
from longtime.reporting.screen import report_text


@dataclass(frozen=True)
class MainJobReport:
    """A main job's ``job`` (MainJobResult), its results ``page`` (None: not written; then
    ``page_error`` says why where it failed) and its report ``text`` (the first screen, or
    the full tables)."""
    job: MainJobResult
    page: Path | None
    page_error: str | None
    text: str


def page_and_report(job: MainJobResult, html: str | Path | None = None, *, page: bool = True, full: bool = False,
                    progress: Progress | None = None) -> MainJobReport:
    """The results page of ``job`` into ``html`` (default: longtime-report/run-RUN_ID beside
    the store) unless not ``page``, with the figures its main job drew ahead, then its report
    (``full``: the per-cell tables after the summary). A page that fails is a warning on
    stderr and ``page_error``: the rows are stored, `longtime report --html DIR` can retry."""
    from longtime.reporting.recommend import map_verdicts

    shown = progress or Progress(on=False)
    written, error = None, None
    # the verdicts the page and the report both show, found once
    with phases.phase("page"):
        found = map_verdicts(job.rows, job.checks)
    if page:  # the results page first, so that a long report ends with its path
        try:
            with phases.phase("page"), shown.phase("page", detail="figures and the results page"):
                written = write_html(html or job.store.path.parent / "longtime-report" / f"run-{job.run_id}",
                                     job.rows, job.store, [job.run_id], ahead=job.ahead, writer="matrix",
                                     verdicts=found)
        except Exception as exc:  # the rows are stored; `longtime report --html DIR` can retry
            error = f"results page not written: {type(exc).__name__}: {exc}"
            print(f"warning: {error}", file=sys.stderr)
    with phases.phase("report"), shown.phase("report"):
        text = report_text(job.rows, "table", full=full, checks=job.checks, ensembles=job.ensembles,
                           page=str(written) if written is not None else None, verdicts=found)
    return MainJobReport(job, written, error, text)
