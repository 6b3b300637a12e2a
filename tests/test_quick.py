"""`longtime matrix --quick`: the stated small matrix, and what it leaves out of a run's fixed
work where no flag asks for it (the fresh timing processes, the results page, the checks, the
ensembles); a flag that asks keeps it. Its run itself is the tour's first command
(tests/test_tour.py)."""
import pytest

from longtime.commands.cli import build_parser
from longtime.commands.matrix import QUICK_PROBLEMS, QUICK_SCHEMES, quick, quick_text
from longtime.core.params import InputError


def _quick(*argv: str):
    args = build_parser().parse_args(["matrix", "--quick", *argv])
    quick(args)
    return args


def test_quick_runs_its_stated_matrix_without_the_fixed_work_no_flag_asks_for():
    args = _quick()
    assert args.problem == list(QUICK_PROBLEMS) and args.integrator == list(QUICK_SCHEMES)
    assert args.processes == 1 and args.no_html and args.checks == 0 and args.no_ensemble
    said = quick_text(args)  # its first line on stderr: what it leaves out and where the rest is
    assert "no timing processes (--processes N), no results page (--html DIR), no checks" in said
    assert said.endswith("`longtime matrix` runs the full one")


def test_a_flag_keeps_what_it_asks_for():
    args = _quick("--processes", "3", "--html", "page", "--checks", "2", "-p", "toda", "-i", "rk4")
    assert args.processes == 3 and not args.no_html and args.checks == 2
    assert args.problem == ["toda"] and args.integrator == ["rk4"]
    assert quick_text(args).startswith("quick matrix: toda x rk4; `longtime matrix`")


def test_quick_does_not_resume():
    with pytest.raises(InputError, match="--resume"):
        _quick("--resume")
