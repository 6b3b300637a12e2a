"""``longtime reproduce``: the paper's tables and figures, regenerated, beside the paper's.

Every section of the report (docs/problems.md and docs/paper.md: Toda, figure-eight, the perturbed
figure-eight, the double pendulum, Duffing, KdV) runs the cells it needs through the
suite's own matrix runner (``longtime.execution.cells.run_cell``: same metrics as everywhere) and
writes a Markdown table with our numbers beside the paper's, the ratio ours / paper, and
the reasons for the differences. A section whose problems or schemes are not registered
(or fail to load) says "not available" and the others go on. Figures are drawn by
``longtime.plot`` (PNG and SVG next to the report). The sections are
longtime.commands.reproduce_sections; this module runs them and writes the report.

The paper's numbers are quoted from ``longtime.reporting.paper`` (its own code and machine); every
number of ours is measured in this run. ``--quick`` shortens the final times (stated in
the report) so that the whole report takes a couple of minutes: quick numbers of schemes
whose error grows with time are then not comparable with the paper's.
"""
from __future__ import annotations

import sys
import time
import traceback
from datetime import datetime, timezone
from pathlib import Path

from longtime.commands.reproduce_sections import SECTIONS, Context, Unavailable
from longtime.core import cli_args
from longtime.core.files import write_atomic
from longtime.core.params import InputError
from longtime.core.progress import Progress
from longtime.execution.lifecycle import command_line, recorded_run
from longtime.execution.matrix import EXECUTORS, ExecOptions
from longtime.execution.store import Store, environment


def reproduce(out: str | Path = "reproduction", quick: bool = False, figures: bool = True,
              executor: str = "process", options: ExecOptions | None = None, store: Store | None = None,
              sections: list[str] | None = None, command: str = "reproduce",
              progress: bool = True) -> tuple[Path, list[str]]:
    """Write out/report.md; return its path and the titles of the sections that failed.
    ``progress``: each section's title, the sections done and the time on stderr
    (longtime.core.progress)."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    ctx = Context(quick=quick, out=out, figures=figures, executor=executor, options=options or ExecOptions(),
                  store=store)
    env = environment()
    started = time.perf_counter()
    chosen = [(t, f) for t, f in SECTIONS if not sections or f.__name__.removeprefix("section_") in sections]
    parts = [
        "# longtime: reproduction of Razafindralandy, Salnikov, Hamdouni, Deeb (2019)", "",
        f"Generated {datetime.now(timezone.utc).isoformat(timespec='seconds')} by `longtime {command}`"
        f"{' (**quick**: shortened final times, stated per section)' if quick else ''}; git "
        f"{env['git_commit'] or 'unknown'}; "
        + ", ".join(f"{k} {v}" for k, v in env["versions"].items() if v and isinstance(v, str))
        + f"; {env['machine']['cpus']} CPUs.", "",
        "Paper's numbers: quoted from docs/paper.md (its own code and machine). Ours: measured in this run "
        "(CPU = process time of the compiled integration alone). 'ours / paper' is the ratio of the two.", ""]
    failed = []
    shown = Progress(on=progress)
    with recorded_run(store, command) as ctx.run_id, shown.phase("reproduce", total=len(chosen), unit="sections"):
        for title, build in chosen:
            shown.say(f"reproduce: {title} ...")
            t0 = time.perf_counter()
            try:
                body = build(ctx)
            except Unavailable as exc:
                body = f"Not available: {exc}."
            except Exception as exc:  # a failing section is reported; the others go on
                failed.append(title)
                body = ("**Section failed**:\n\n```\n" + "".join(traceback.format_exception(exc))[-3000:]
                        + "\n```")
            parts += [f"## {title}", "", body, "", f"*(section: {time.perf_counter() - t0:.1f} s wall)*", ""]
            shown.advance(last=title)
    parts.append(f"Total: {time.perf_counter() - started:.1f} s wall, {ctx.cells_run} cells.")
    report = out / "report.md"
    write_atomic(report, "\n".join(parts) + "\n")
    return report, failed


def cmd_reproduce(args) -> int:
    args.executor = args.executor or ("serial" if args.quick else "process")
    if args.executor not in EXECUTORS:
        raise InputError(f"--executor {args.executor!r}: valid: {', '.join(sorted(EXECUTORS))}")
    valid = [f.__name__.removeprefix("section_") for _, f in SECTIONS]
    for s in args.section or []:
        if s not in valid:
            raise InputError(f"--section {s!r} is not valid: expected one of {', '.join(valid)}")
    store = None if args.no_store else Store(args.db)
    options = ExecOptions(jobs=args.jobs, max_samples=args.max_samples)
    report, failed = reproduce(args.out, quick=args.quick, figures=not args.no_figures, executor=args.executor,
                               options=options, store=store, sections=args.section,
                               command=command_line(args))
    print(report)
    for title in failed:
        print(f"longtime reproduce: section failed: {title} (details in {report})", file=sys.stderr)
    return 1 if failed else 0


def add_parser(subparsers) -> None:
    p = subparsers.add_parser("reproduce", help="the paper's tables and figures beside ours, in one Markdown report",
                              description=__doc__.splitlines()[0])
    p.add_argument("--out", default="reproduction", type=cli_args.out_folder("--out"),
                   help="folder of report.md and its figures (default: reproduction)")
    p.add_argument("--quick", action="store_true",
                   help="shortened final times (a couple of minutes; stated in the report)")
    p.add_argument("--section", type=cli_args.names, default=None,
                   metavar="NAME[,..]", help="only these sections: " + ", ".join(
                       f.__name__.removeprefix("section_") for _, f in SECTIONS))
    p.add_argument("--no-figures", action="store_true", help="tables only")
    p.add_argument("--executor", default=None,
                   help="where the cells run (default: serial with --quick, which reuses the kernels the "
                        "figures compile; process otherwise)")
    p.add_argument("--jobs", type=cli_args.jobs, default=0, help="worker processes (default: one per core)")
    p.add_argument("--max-samples", type=int, default=100_001, help="states kept per run for the metrics")
    p.add_argument("--db", default=None, help="store the rows here (default: $LONGTIME_DB or longtime.sqlite)")
    p.add_argument("--no-store", action="store_true", help="do not keep the rows")
    p.set_defaults(func=cmd_reproduce)
