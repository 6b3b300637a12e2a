"""What a run returns (``Trajectory``) and the bitwise comparison of two runs of one cell
(``same_run``, ``run_digest``): the timed repeats of a cell, and its timing processes, must
reproduce the first run bit for bit."""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np


@dataclass
class Trajectory:
    """What a scheme returns: samples of the state, the outcome and the cost."""

    status: str  # ok | diverged | failed | timeout
    message: str
    t: np.ndarray  # (n,)
    u: np.ndarray  # (n, dim)
    cpu_s: float
    wall_s: float
    counters: dict[str, int] = field(default_factory=dict)
    min_dt: float | None = None
    max_dt: float | None = None
    extra: dict[str, Any] = field(default_factory=dict)

    @property
    def t_reached(self) -> float:
        return float(self.t[-1])

    @property
    def steps(self) -> int:
        return int(self.counters.get("steps", 0))


def same_run(a: Trajectory, b: Trajectory) -> bool:
    """Bitwise equality of two runs of one cell: outcome, counters and every sample."""
    return (a.status == b.status and a.counters == b.counters and _same_bits(a.t, b.t)
            and _same_bits(a.u, b.u))


def run_digest(traj: Trajectory) -> str:
    """A hash of what ``same_run`` compares (outcome, counters, the bits of every sample):
    equal digests from two processes mean the same run, without sending the samples."""
    import hashlib
    import json

    # a counter JSON cannot write (a plugin's numpy integer) is hashed by its repr: the row's
    # check, not the digest, says what is wrong with it
    h = hashlib.sha1(json.dumps([traj.status, sorted(traj.counters.items())], default=repr).encode())
    for x in (traj.t, traj.u):
        x = np.ascontiguousarray(x)
        h.update(repr((x.shape, x.dtype.str)).encode())
        h.update(x.view(np.uint8).reshape(-1) if x.size else b"")
    return h.hexdigest()


def _same_bits(x: np.ndarray, y: np.ndarray) -> bool:
    """Bit-for-bit equality (NaN equals the same NaN, 0.0 differs from -0.0), comparing the
    float64 samples as 64-bit integers, a view: no copy of the samples is made
    (docs/performance.md)."""
    if x.shape != y.shape or x.dtype != y.dtype:
        return False
    x, y = np.ascontiguousarray(x), np.ascontiguousarray(y)
    if x.dtype.itemsize not in (1, 2, 4, 8):
        return x.tobytes() == y.tobytes()
    as_int = np.dtype(f"u{x.dtype.itemsize}")
    return bool(np.array_equal(x.view(as_int), y.view(as_int)))
