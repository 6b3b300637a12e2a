"""Numbers that would fail later are refused or named: a time limit past what a clock counts, a
step larger than the span in an ensemble, a horizon no run reaches, a setting whose square
passes double precision, an API argument of the wrong type. Each is refused up front, in
one line naming the argument, or is a failed row that says what overflowed."""
import pytest

import longtime
from longtime import InputError
from longtime.commands.cli import main
from longtime.execution.cells import Cell, run_cell


def _refused(capsys, argv) -> str:
    try:
        code = main(argv)
    except SystemExit as exc:  # argparse's refusal
        code = exc.code
    err = capsys.readouterr().err
    assert code == 2, err
    assert "Traceback" not in err and len(err.strip().splitlines()) == 1, err
    return err


@pytest.mark.parametrize("argv", [
    ["card", "rk4", "--time-limit", "1e308"],
    ["run", "-p", "harmonic", "-i", "rk4", "--time-limit", "1e308", "--no-store"],
    ["ensemble", "-p", "henon-heiles", "-i", "verlet", "--time-limit", "1e308"],
    ["run", "-p", "harmonic", "-i", "rk4", "--min-time", "1e308", "--no-store"],
])
def test_a_time_limit_past_what_a_clock_counts_is_refused(capsys, argv):
    flag = argv[argv.index("1e308") - 1]
    assert f"{flag} takes a number of seconds" in _refused(capsys, argv)


def test_the_api_bounds_a_time_limit_too():
    expected = r"time_limit=1e\+308 is not valid: expected a finite number >= 0 and <= 1e\+09"
    with pytest.raises(InputError, match=expected):
        longtime.sweep("harmonic", "rk4", dt=0.1, time_limit=1e308, executor="serial")


def test_an_ensemble_step_larger_than_the_span_is_refused_as_run_refuses_it(capsys):
    err = _refused(capsys, ["ensemble", "-p", "henon-heiles", "-i", "verlet", "--dt", "1e308", "--t-final", "20"])
    assert "--dt 1e+308: larger than the span" in err


def test_a_horizon_no_run_reaches_is_refused(capsys):
    err = _refused(capsys, ["recommend", "-p", "harmonic", "--error", "0.01", "--horizon", "1e308"])
    assert "--horizon 1e+308:" in err and "no run reaches it" in err
    with pytest.raises(InputError, match=r"^horizon=1e\+308: .*no run reaches it"):
        longtime.recommend("harmonic", 0.01, 1e308)


def test_the_api_names_its_parameter_and_the_type_it_got():
    with pytest.raises(InputError) as info:
        longtime.recommend("harmonic", "0.01", 100)
    assert str(info.value) == "error='0.01' is not valid: expected a finite number > 0 (got a str)"
    with pytest.raises(InputError, match=r"^horizon=-1 is not valid"):
        longtime.recommend("harmonic", 0.01, -1)


def test_a_setting_that_overflows_is_a_failed_row_saying_so():
    row = run_cell(Cell("harmonic", "rk4", {"omega": 1e308}, {}, 2.0))
    assert row["status"] == "failed"
    assert row["message"].startswith("OverflowError: ")
    assert '{"omega": 1e+308}' in row["message"] and "pass the range of double precision" in row["message"]
