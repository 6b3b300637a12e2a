"""The ``longtime`` command: list | run | matrix | report (and commands added by modules).

Exit codes: 0 done; 1 a requested cell failed (``run``) or a failure that changing the
command does not fix; 2 bad input; 3 ``run --cost instructions`` counted no row (stderr
says why); 130, 143, 129 stopped by SIGINT, SIGTERM, SIGHUP (longtime.commands.guard).
"""
from __future__ import annotations

import argparse
import importlib
import sys

from longtime.commands import guard, listing, matrix, report, run_cmd

# modules that add subcommands: each defines add_parser(subparsers) and sets func
COMMAND_MODULES: tuple[str, ...] = (
    "longtime.commands.asv_init", "longtime.commands.cache_cmd", "longtime.commands.card",
    "longtime.commands.compare", "longtime.commands.history", "longtime.commands.horizon",
    "longtime.commands.ensemble", "longtime.commands.matched", "longtime.commands.plot",
    "longtime.commands.recommend", "longtime.commands.reproduce", "longtime.commands.roundoff",
    "longtime.commands.warmup", "longtime.commands.merge")


def build_parser() -> argparse.ArgumentParser:
    parser = guard.Parser(prog="longtime", description=__doc__.splitlines()[0])  # errors in one line
    parser.add_argument("--debug", action="store_true",
                        help="an error's traceback too, not only its one-line message")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for module in (listing, run_cmd, matrix, report):
        module.add_parser(sub)
    for name in COMMAND_MODULES:
        importlib.import_module(name).add_parser(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    argv = list(sys.argv[1:] if argv is None else argv)
    args = parser.parse_args(argv)
    args.argv = argv  # the command a run records (lifecycle.command_line)
    return guard.run_command(args)  # every failure caught there: one line, its exit code


if __name__ == "__main__":
    sys.exit(main())
