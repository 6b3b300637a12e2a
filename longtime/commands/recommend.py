"""``longtime recommend``: the cheapest stored setting predicted to keep an error up to a
horizon on a problem, with the runner-up and the evidence (longtime.reporting.recommend).

Exit codes: 0 an answer; 3 (``NO_ANSWER_EXIT``) no answer the store determines (no setting
predicted to keep the target, or a horizon past a chaotic problem's predictability horizon):
the lines on stdout say why and name the command that would decide it; 2 bad input.
Where the answer lies beyond the stored runs, its candidates run to the horizon within
--budget seconds and the answer says "measured at T" (else "predicted, not run")."""
from __future__ import annotations

from longtime.core import cli_args
from longtime.execution.answers import DEFAULT_BUDGET_S
from longtime.execution.store import default_path


def cmd_recommend(args) -> int:
    from longtime.api import recommend
    from longtime.core import registry
    from longtime.execution.sizes import check_span
    from longtime.reporting.recommend import NO_ANSWER_EXIT

    if args.problem in registry.problems():  # an unknown one is named by recommend, as -p
        check_span(args.problem, args.horizon, f"--horizon {args.horizon:g}")  # a horizon a run accepts
    answer = recommend(args.problem, args.error, args.horizon, db=args.db, run=args.run, budget=args.budget,
                       library=args.library)
    print(answer)
    return 0 if answer.answered else NO_ANSWER_EXIT


def add_parser(subparsers) -> None:
    p = subparsers.add_parser("recommend", help="which scheme and setting keep an error up to a horizon, cheapest",
                              epilog="exit status: 0 an answer; 3 no answer the store determines (stdout says why "
                                     "and names the run that would decide it); 2 bad input")
    p.add_argument("-p", "--problem", required=True, metavar="PROBLEM", help="a problem name (see `longtime list`)")
    p.add_argument("--error", type=cli_args.positive_number("--error"), required=True, metavar="E",
                   help="the target error (the solution error relative to the motion where the problem has a "
                        "reference, docs/metrics.md; else the relative energy error)")
    p.add_argument("--horizon", type=cli_args.positive_number("--horizon"), required=True, metavar="T",
                   help="the final time the error must hold to")
    p.add_argument("--db", default=None, help=f"SQLite store (default: $LONGTIME_DB or {default_path()})")
    p.add_argument("--run", default=None, help="run id, or 'all' (default: every run of the store)")
    p.add_argument("--budget", type=cli_args.seconds("--budget", allow_zero=True), default=DEFAULT_BUDGET_S,
                   metavar="SECONDS",
                   help="wall seconds for running the best predicted candidates to the horizon where the answer "
                        "lies beyond the stored runs: the answer is then the cheapest measured, 'measured at T' "
                        f"(default {DEFAULT_BUDGET_S:g}; 0 runs nothing: 'predicted, not run')")
    p.add_argument("--library", default=None, metavar="LIBRARY",
                   help="only the schemes of this library (longtime, scipy, sundials, diffrax, heyoka, rebound): "
                        "its cheapest setting")
    p.set_defaults(func=cmd_recommend)
