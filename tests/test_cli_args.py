"""Argument types of the command line (longtime.core.cli_args): ranges and --set pairs."""
import argparse

import pytest

from longtime.core import cli_args
from longtime.core.params import InputError


def test_ranges():
    order = cli_args.ints("--order")
    assert order("4..6") == [4, 5, 6]
    assert order("4,8") == [4, 8]
    assert order("7..7") == [7]
    with pytest.raises(argparse.ArgumentTypeError, match="--order 5..1: an empty range"):
        order("5..1")
    with pytest.raises(argparse.ArgumentTypeError, match="over the limit of 10000"):
        order("1..1000000000000")
    assert len(order(f"1..{cli_args.MAX_RANGE}")) == cli_args.MAX_RANGE
    with pytest.raises(argparse.ArgumentTypeError, match="comma-separated integers"):
        order("1..x")


def test_set_pairs_sweep_or_set():
    sets, sweeps = cli_args.settings([("e", "0.5,0.9, 0.99"), ("d", "4")])
    assert sets == {"d": "4"} and sweeps == {"e": ["0.5", "0.9", "0.99"]}


def test_repeated_set_key_is_an_error():
    with pytest.raises(InputError, match=r"--set d is given twice \(3, 4\)"):
        cli_args.settings([("d", "3"), ("d", "4")])
    with pytest.raises(InputError, match="given twice"):
        cli_args.single_settings([("d", "3"), ("d", "3")])
    with pytest.raises(InputError, match="an empty value"):
        cli_args.settings([("e", "0.5,")])
