"""Argument types shared by every ``longtime`` command (argparse ``type=`` callables).

Each raises ``argparse.ArgumentTypeError`` naming the flag and what it takes, so a bad
value is reported by argparse with exit code 2 like every other input error; the --set
pairs are checked as a whole (``settings``), with an InputError.
"""
from __future__ import annotations

import argparse
import contextlib
import math
from typing import Callable, Iterator

from longtime.core.params import MAX_SECONDS, InputError


def names(text: str) -> list[str]:
    """A comma-separated list of names, each once: "toda, kepler" -> ["toda", "kepler"]."""
    found = list(dict.fromkeys(x.strip() for x in text.split(",") if x.strip()))  # a repeat runs once
    if not found:  # "-p ," must not mean "everything"
        raise argparse.ArgumentTypeError(f"expected comma-separated names, got {text!r}")
    return found


def floats(flag: str, finite: bool = True) -> Callable[[str], list[float]]:
    """A comma-separated list of numbers, at least one; finite ones unless ``finite`` is False
    (where the cells' own validation names the parameter and its value, ``dt=nan``)."""

    def parse(text: str) -> list[float]:
        try:
            values = [float(x) for x in text.split(",") if x.strip()]
        except ValueError:
            raise argparse.ArgumentTypeError(f"{flag} takes comma-separated numbers, got {text!r}") from None
        if not values:
            raise argparse.ArgumentTypeError(f"{flag} needs at least one value")
        if finite and not all(math.isfinite(v) for v in values):  # nan, inf: refused before any work
            raise argparse.ArgumentTypeError(f"{flag} takes finite numbers, got {text!r}")
        return values

    return parse


# the most values a range A..B may expand to
MAX_RANGE = 10_000


def ints(flag: str) -> Callable[[str], list[int]]:
    """A comma-separated list of integers; ``A..B`` is the range A to B inclusive (A <= B, at
    most MAX_RANGE values)."""

    def parse(text: str) -> list[int]:
        try:
            if ".." in text:
                a, b = (int(x) for x in text.split("..", 1))
            else:
                values = [int(x) for x in text.split(",") if x.strip()]
        except ValueError:
            raise argparse.ArgumentTypeError(f"{flag} takes comma-separated integers (or A..B), "
                                             f"got {text!r}") from None
        if ".." not in text:
            if not values:
                raise argparse.ArgumentTypeError(f"{flag} needs at least one value")
            return values
        if b < a:
            raise argparse.ArgumentTypeError(f"{flag} {text}: an empty range (A..B needs A <= B)")
        if b - a + 1 > MAX_RANGE:
            raise argparse.ArgumentTypeError(f"{flag} {text}: {b - a + 1} values, over the limit of "
                                             f"{MAX_RANGE} a range may expand to")
        return list(range(a, b + 1))

    return parse


def integer(flag: str, minimum: int, note: str = "", maximum: int | None = None) -> Callable[[str], int]:
    """One integer >= ``minimum`` and <= ``maximum`` (None: no bound) (``note`` says what the
    smallest means, e.g. 0: one per core)."""

    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            value = None
        if value is None or value < minimum or (maximum is not None and value > maximum):
            bound = f"from {minimum} to {maximum}" if maximum is not None else f">= {minimum}"
            raise argparse.ArgumentTypeError(f"{flag} takes an integer {bound}{note}, got {text!r}")
        return value

    return parse


# the largest seed taken (numpy's generators take any integer >= 0; a larger one is a typo)
MAX_SEED = 2**63 - 1
# the most members an ensemble (horizon, ensemble, roundoff) may have: each is a run of its own
MAX_MEMBERS = 10_000


def seed(flag: str = "--seed") -> Callable[[str], int]:
    """A random seed: an integer from 0 to MAX_SEED."""
    return integer(flag, 0, maximum=MAX_SEED)


def members(flag: str, minimum: int) -> Callable[[str], int]:
    """The members of an ensemble: an integer from ``minimum`` to MAX_MEMBERS."""
    return integer(flag, minimum, " (runs of their own each)", maximum=MAX_MEMBERS)


# the smallest relative perturbation taken: half the double's epsilon (a smaller one leaves the
# state as it is)
MIN_SIZE = 1.1e-16


def bounded(flag: str, low: float, high: float) -> Callable[[str], float]:
    """A number from ``low`` to ``high`` (finite)."""

    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            value = float("nan")
        if not low <= value <= high:
            raise argparse.ArgumentTypeError(f"{flag} takes a number from {low:g} to {high:g}, got {text!r}")
        return value

    return parse


def share(flag: str) -> Callable[[str], float]:
    """A share of a whole: a number from 1e-6 (not vanishingly small) to 1."""
    return bounded(flag, 1e-6, 1.0)


def jobs(text: str) -> int:
    """--jobs: worker processes, 0 for one per core (every command that has the flag)."""
    return integer("--jobs", 0, " (0: one per core)")(text)


def key_value(text: str) -> tuple[str, str]:
    """``--set key=value``: the pair of stripped strings (the parameter parses the value)."""
    if "=" not in text:
        raise argparse.ArgumentTypeError(f"--set takes key=value, got {text!r}")
    key, value = text.split("=", 1)
    return key.strip(), value.strip()


def single_settings(pairs: list[tuple[str, str]]) -> dict[str, str]:
    """The --set pairs as a dict; a key given twice is an error, not the last one winning."""
    out: dict[str, str] = {}
    for key, value in pairs:
        if key in out:
            raise InputError(f"--set {key} is given twice ({out[key]}, {value}): give it once "
                             f"(several values: --set {key}=V1,V2)")
        out[key] = value
    return out


def settings(pairs: list[tuple[str, str]]) -> tuple[dict[str, str], dict[str, list[str]]]:
    """(single values, sweeps) of the --set pairs: ``KEY=V1,V2,..`` sweeps KEY over the values
    (one cell each), ``KEY=V`` sets it; a key given twice is an error."""
    sets, sweeps = {}, {}
    for key, value in single_settings(pairs).items():
        values = [v.strip() for v in value.split(",")]
        if len(values) > 1:
            if not all(values):
                raise InputError(f"--set {key}={value}: an empty value in the list")
            sweeps[key] = values
        else:
            sets[key] = value
    return sets, sweeps


def seconds(flag: str, allow_zero: bool = False) -> Callable[[str], float]:
    """A number of seconds, > 0 (or >= 0 with ``allow_zero``), up to MAX_SECONDS."""

    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            value = float("nan")
        ok = (0 <= value if allow_zero else 0 < value) and value <= MAX_SECONDS
        if not ok:
            raise argparse.ArgumentTypeError(f"{flag} takes a number of seconds {'>= 0' if allow_zero else '> 0'} "
                                             f"and <= {MAX_SECONDS:g}, got {text!r}")
        return value

    return parse


def positive_number(flag: str) -> Callable[[str], float]:
    """A finite number > 0 (a target error, a horizon)."""

    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            value = float("nan")
        if not 0 < value < float("inf"):
            raise argparse.ArgumentTypeError(f"{flag} takes a finite number > 0, got {text!r}")
        return value

    return parse


def out_folder(flag: str) -> Callable[[str], str]:
    """A folder to write into: an existing regular file (or one on its path) is an error
    before anything runs, not a traceback after."""

    def parse(text: str) -> str:
        from pathlib import Path

        path = Path(text)
        for p in (path, *path.parents):
            if p.exists() and not p.is_dir():
                raise argparse.ArgumentTypeError(f"{flag} {text}: {p} is a file, not a folder")
        return text

    return parse


def out_file(flag: str) -> Callable[[str], str]:
    """A file to write: a folder, a regular file on its path, or a folder that exists and
    cannot be written is an error before anything runs (``writing`` catches the rest)."""

    def parse(text: str) -> str:
        import os
        from pathlib import Path

        path = Path(text)
        if not text.strip() or path.is_dir():
            raise argparse.ArgumentTypeError(f"{flag} {text!r}: a folder, not a file name")
        for p in path.parents:
            if p.exists():
                if not p.is_dir():
                    raise argparse.ArgumentTypeError(f"{flag} {text}: {p} is a file, not a folder")
                if not os.access(p, os.W_OK | os.X_OK):
                    raise argparse.ArgumentTypeError(f"{flag} {text}: the folder {p} cannot be written")
                break
        return text

    return parse


@contextlib.contextmanager
def writing(flag: str, path) -> Iterator[None]:
    """An OSError while writing the file of ``flag`` as an InputError naming it (one line,
    exit 2): the user picks another path."""
    from longtime.core.params import InputError

    try:
        yield
    except OSError as exc:
        raise InputError(f"{flag} {path}: cannot write it: {exc.strerror or exc}") from None


def writable_folder(flag: str, path) -> None:
    """Refuse, before any work, a folder ``flag`` is to write into that cannot be written (read
    only, under a file, on a full disk): tried by creating it and a file in it
    (cache.probe_folder). A folder it creates is left (empty) for the write that follows."""
    from pathlib import Path

    from longtime.core.cache import probe_folder

    try:
        probe_folder(Path(path))
    except OSError as exc:
        raise InputError(f"{flag} {path}: cannot write there: {exc.strerror or exc}") from None


def scheduler(text: str) -> str:
    """--scheduler: a Dask scheduler address, ``[PROTOCOL://]HOST:PORT`` (checked by Dask's
    own parser when dask.distributed is installed; without it the executor says so)."""
    try:
        from distributed.comm.addressing import parse_address, parse_host_port
        from distributed.comm.registry import backends
    except ImportError:
        return text
    try:
        protocol, location = parse_address(text)
        if protocol not in backends:
            raise ValueError(f"unknown protocol {protocol!r} (known: {', '.join(sorted(backends))})")
        if protocol in ("tcp", "tls", "ws", "wss"):
            host, _ = parse_host_port(location)
            if not host or any(c.isspace() for c in host):
                raise ValueError(f"no host name in {location!r}")
    except ValueError as exc:
        raise argparse.ArgumentTypeError(f"--scheduler {text!r}: not a Dask scheduler address "
                                         f"(expected tcp://HOST:PORT): {exc}") from None
    return text
