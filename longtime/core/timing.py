"""How one process times a run (``Timing``) and the timing loop (``timed_runs``): the repeats
of a run after the first, each of which must reproduce it bitwise."""
from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Any, Callable, ClassVar

import numpy as np

from longtime.core.params import InputError
from longtime.core.status import Status
from longtime.core.trajectory import Trajectory, same_run


@dataclass(frozen=True)
class Timing:
    """How one process times a run, timeit-style: after the warm-up the integration runs at
    least ``min_runs`` times (default ``MIN_RUNS``, or ``repeats`` if fewer), then again
    while its timing is not settled and the timed wall total is below ``min_time`` seconds,
    at most ``repeats`` times. Settled: the two fastest runs agree within ``SETTLED`` (the
    minimum has been seen twice, so more runs would not move it), which a long run reaches
    at once and a short one on a quiet core after a few. The minimum is the figure (noise
    only ever adds time); the median and the maximum show the spread within the process.
    The spread between processes is measured by running the cell in several
    (longtime.execution.processes); ``per_process`` splits the repeats among them."""

    repeats: int = 7
    min_time: float = 0.2
    min_runs: int | None = None  # None: MIN_RUNS
    MIN_RUNS: ClassVar[int] = 3
    # the two fastest runs within this (relative) of each other: the minimum is known
    SETTLED: ClassVar[float] = 0.02
    # a run longer than this (wall seconds, 5x timeit's whole autorange budget) is timed
    # once: repeating a 10^8-step cell would cost minutes for a spread that is small at that
    # length (the row says so)
    ONCE_ABOVE: ClassVar[float] = 1.0
    # a screening timing (``screening``) repeats a run only while the timed total is below this
    # (wall seconds): a run of a few milliseconds, which one disturbance can double, is timed
    # a few times; a longer one once
    SCREEN_TIME: ClassVar[float] = 0.01
    # and at most this many times
    SCREEN_RUNS: ClassVar[int] = 3

    def __post_init__(self) -> None:
        if isinstance(self.repeats, bool) or not isinstance(self.repeats, (int, np.integer)) \
                or self.repeats < 1:
            raise InputError(f"repeats={self.repeats!r} is not valid: expected an integer >= 1")
        if not (isinstance(self.min_time, (int, float)) and math.isfinite(self.min_time)
                and self.min_time >= 0):
            raise InputError(f"min_time={self.min_time!r} is not valid: expected a finite number "
                             f"of seconds >= 0")
        if self.min_runs is not None and (isinstance(self.min_runs, bool) or not isinstance(
                self.min_runs, (int, np.integer)) or self.min_runs < 1):
            raise InputError(f"min_runs={self.min_runs!r} is not valid: expected an integer >= 1")

    @property
    def least_runs(self) -> int:
        """The runs a process times at least: ``min_runs`` (default ``MIN_RUNS``), at most
        ``repeats``."""
        return min(self.repeats, self.MIN_RUNS if self.min_runs is None else self.min_runs)

    def wants_another(self, wall_times: list[float]) -> bool:
        n = len(wall_times)
        if n and wall_times[0] > self.ONCE_ABOVE:
            return False
        if n >= self.repeats:
            return False
        if n < self.least_runs:
            return True
        return not self.settled(wall_times) and sum(wall_times) < self.min_time

    @classmethod
    def settled(cls, times: list[float]) -> bool:
        """The two fastest of ``times`` agree within ``SETTLED``."""
        if len(times) < 2:
            return False
        a, b = sorted(times)[:2]
        return b <= a * (1 + cls.SETTLED)

    def per_process(self, processes: int) -> "Timing":
        """The timing of each of ``processes`` processes that time one cell: the repeats, the
        minimum runs and the time budget split among them (rounded up), so that timing a cell
        in several processes costs about what timing it in one did."""
        if processes <= 1:
            return self
        runs = self.MIN_RUNS if self.min_runs is None else self.min_runs
        return Timing(repeats=max(1, math.ceil(self.repeats / processes)), min_time=self.min_time / processes,
                      min_runs=max(1, math.ceil(runs / processes)))

    def screening(self) -> "Timing":
        """The timing of a run whose time only has to decide by a factor of 2 whether it is
        timed again (the process that measures a cell's row, where the fresh processes time
        again only the cells whose time could change an answer: longtime.predict.need): one
        run, repeated while the timed total is below ``SCREEN_TIME``, at most ``SCREEN_RUNS``
        runs, and never more, or longer, than this timing asks."""
        return Timing(repeats=min(self.repeats, self.SCREEN_RUNS), min_time=min(self.min_time, self.SCREEN_TIME),
                      min_runs=1)

    def to_dict(self) -> dict[str, Any]:
        """The timing as JSON for a child process (``from_dict`` reads it back whole)."""
        return {"repeats": int(self.repeats), "min_time": float(self.min_time),
                "min_runs": None if self.min_runs is None else int(self.min_runs)}

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> "Timing":
        return cls(repeats=data["repeats"], min_time=data["min_time"], min_runs=data.get("min_runs"))


def timed_runs(run: Callable[[], Trajectory], timing: Timing,
               deadline: float | None) -> tuple[Trajectory, list[float], list[float]]:
    """The first run of ``run()``, then repeats while ``timing`` wants another and the
    ``deadline`` (a time.monotonic() value) is not past: the first run with the CPU and wall
    seconds of every run that counts. A repeat that does not reproduce the first run bitwise
    turns the first into a ``failed`` run ("non-deterministic") and ends the repeats; a repeat
    the deadline cuts short ends them too (the first run stands)."""
    first = run()
    cpu, wall = [first.cpu_s], [first.wall_s]
    while first.status != Status.TIMEOUT and timing.wants_another(wall) and not (
            deadline is not None and time.monotonic() > deadline):
        again = run()
        if again.status == Status.TIMEOUT:
            break  # the deadline cut a repeat short: the first run stands
        if not same_run(first, again):
            first.status = Status.FAILED
            first.message = (f"non-deterministic: timed run {len(cpu) + 1} did not reproduce "
                             f"the first run's states bitwise")
            break
        cpu.append(again.cpu_s)
        wall.append(again.wall_s)
    return first, cpu, wall
