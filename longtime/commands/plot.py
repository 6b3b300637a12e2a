"""``longtime plot KIND``: the suite's figures, saved as PNG and SVG (matplotlib, Agg).

The kinds and the options each takes are longtime.plot's (``PLOT_KINDS``, ``draw``)."""
from __future__ import annotations

from typing import Any

from longtime.core import cli_args
from longtime.plot import PLOT_KINDS, draw
from longtime.reporting.figures.work_precision import DRIFT_METRICS


def cmd_plot(args) -> int:
    settings: dict[str, Any] = cli_args.single_settings(args.set)
    paths = draw(args.kind, args.out, problems=args.problem, schemes=args.integrator, dt=args.dt,
                 t_final=args.t_final, problem_settings=settings or None, db=args.db, run=args.run,
                 metric=args.metric, invariant=args.invariant, formats=tuple(args.format))
    for p in paths:
        print(p)
    return 0


def add_parser(subparsers) -> None:
    p = subparsers.add_parser("plot", help="figures: work-precision, drift, Toda eigenvalues, Duffing phase, ...",
                              description=__doc__.splitlines()[0])
    p.add_argument("kind", choices=sorted(PLOT_KINDS), help="what to draw")
    p.add_argument("--out", default="figures", type=cli_args.out_folder("--out"),
                   help="folder for the files (default: figures)")
    p.add_argument("-p", "--problem", type=cli_args.names, default=None, metavar="PROBLEM[,..]")
    p.add_argument("-i", "--integrator", type=cli_args.names, default=None, metavar="SCHEME[,..]")
    p.add_argument("--dt", type=float, default=None, help="time step of the integrations")
    p.add_argument("--t-final", type=float, default=None, metavar="T")
    p.add_argument("--set", type=cli_args.key_value, action="append", default=[], metavar="KEY=VALUE",
                   help="a problem parameter (repeatable)")
    p.add_argument("--db", default=None, help="store to read (work-precision)")
    p.add_argument("--run", default=None, help="run id, 'latest' (default) or 'all' (work-precision)")
    p.add_argument("--metric", choices=DRIFT_METRICS, default=None, help="drift metric of work-precision")
    p.add_argument("--invariant", default=None, metavar="NAME",
                   help="drift: the invariant (or diagnostic) to draw, e.g. L (default: H, else the first)")
    p.add_argument("--format", type=cli_args.names, default=["png", "svg"], metavar="FMT[,..]",
                   help="png, svg, pdf (default: png,svg)")
    p.set_defaults(func=cmd_plot)
