"""Declared parameters: roles, and how a value is parsed and checked (longtime.core.params)."""
import pytest

from longtime.core.params import INT64_MAX, INT64_MIN, InputError, Param


def test_role_decides_whether_it_sweeps():
    assert Param(0.1, "step", role="step").sweeps
    assert Param(1e-6, "tolerance", role="accuracy").sweeps
    assert Param(10, "order", int, role="order").sweeps
    assert not Param(0.5, "eccentricity", role="physical").sweeps
    assert not Param(50, "sweeps allowed", int).sweeps  # an option by default
    assert Param(50, "sweeps allowed", int, sweeps=True).sweeps  # declared explicitly
    assert not Param(1e-6, "tolerance", role="accuracy", sweeps=False).sweeps


def test_unknown_role_fails_when_declared():
    with pytest.raises(ValueError, match="role 'speed'"):
        Param(1.0, "x", role="speed")


@pytest.mark.parametrize("text, value", [("3", 3), ("3.0", 3), ("1e3", 1000), (" 12 ", 12),
                                         (str(INT64_MAX), INT64_MAX), (str(INT64_MIN), INT64_MIN)])
def test_int_parse_exact(text, value):
    got = Param(1, "n", int).parse("n", text)
    assert got == value and type(got) is int


@pytest.mark.parametrize("text", ["1e19", "99999999999999999999", str(INT64_MAX + 1), str(INT64_MIN - 1)])
def test_int_outside_int64_refused(text):
    with pytest.raises(InputError, match="64-bit"):
        Param(1, "n", int).parse("max_iter", text)


def test_int_refuses_fractions_and_words():
    for text in ("2.5", "ten", "nan", "inf"):
        with pytest.raises(InputError, match="max_iter"):
            Param(1, "n", int, positive=True).parse("max_iter", text)


def test_bounds_named_in_the_message():
    p = Param(50, "n", int, positive=True, maximum=10**6)
    assert p.parse("max_iter", "1000000") == 10**6
    with pytest.raises(InputError, match=r"max_iter='1000001' is not valid: expected int > 0 <= 1000000"):
        p.parse("max_iter", "1000001")


def test_float_parse_unchanged():
    p = Param(0.6, "e", minimum=0.0, maximum=0.99, role="physical")
    assert p.parse("e", "0.9") == 0.9
    with pytest.raises(InputError, match="e='1e400'.*finite"):
        p.parse("e", "1e400")
