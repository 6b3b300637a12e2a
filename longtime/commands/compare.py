"""``longtime compare RUN_A RUN_B``: regressions in accuracy as well as speed, cell by cell.

The comparison and its rules: longtime.reporting.compare.
"""
from __future__ import annotations

from longtime.measure.instructions import COUNT_NOISE
from longtime.reporting.compare import report, run_compare
from longtime.reporting.compare_cells import CELL_FACTOR, INSTRUCTION_FACTOR, TIME_FACTOR


def cmd_compare(args) -> int:
    from longtime.core.progress import Progress

    with Progress().phase("compare", detail=f"runs {args.run_a} and {args.run_b}, cell by cell", announce=False):
        result = run_compare(args.db, args.run_a, args.db_b or args.db, args.run_b, args.factor, args.error_factor,
                             args.alpha, args.raw_time, args.cell_factor, args.instruction_factor)
    return report(result, args.format, args.all)


def add_time_flags(p) -> None:
    """The flags that judge times and errors."""
    p.add_argument("--factor", type=float, default=TIME_FACTOR,
                   help=f"time ratio of a scheme or a problem (median over its batches) that counts as slower "
                        f"(default {TIME_FACTOR:g}: beyond the measured spread of identical runs)")
    p.add_argument("--cell-factor", type=float, default=CELL_FACTOR,
                   help=f"time ratio of a single cell timed in one process that counts as slower (default "
                        f"{CELL_FACTOR:g}); a cell timed in several processes is judged against the spread "
                        f"between them and --factor")
    p.add_argument("--error-factor", type=float, default=2.0,
                   help="error ratio that counts as less accurate (default 2)")
    p.add_argument("--raw-time", action="store_true",
                   help="compare raw CPU seconds instead of calibrated times")


def add_instruction_flag(p) -> None:
    p.add_argument("--instruction-factor", type=float, default=INSTRUCTION_FACTOR,
                   help=f"ratio of a cell's instruction count (--cost instructions in both runs) that counts as "
                        f"more work (default {INSTRUCTION_FACTOR:g}; more for a count so small that the counts' noise, "
                        f"{COUNT_NOISE} instructions a call, passes it)")


def add_parser(subparsers) -> None:
    p = subparsers.add_parser("compare", help="two runs cell by cell: time and accuracy regressions (exit 1)",
                              description=__doc__.split("\n\n")[0])
    p.add_argument("run_a", metavar="RUN_A", help="the baseline run id")
    p.add_argument("run_b", metavar="RUN_B", help="the run compared with it")
    p.add_argument("--db", default=None, help="the store of RUN_A (and RUN_B unless --db-b)")
    p.add_argument("--db-b", default=None, help="the store of RUN_B")
    add_time_flags(p)
    add_instruction_flag(p)
    p.add_argument("--alpha", type=float, default=0.05,
                   help="kept for scripts that pass it: the repeats' p-value is reported (p_slower), not judged")
    p.add_argument("--all", action="store_true", help="list every common cell, not only the changed ones")
    p.add_argument("--format", choices=["table", "json"], default="table")
    p.set_defaults(func=cmd_compare)
