"""The machine's speed, measured with a fixed reference workload beside the cells.

The reference workload is ``STEPS`` classical RK4 steps on the harmonic oscillator
q' = p, p' = -q, a compiled loop on two scalars (no allocation, no memory traffic): the
kind of work a cell's kernel does. A *calibration* times it ``REPEATS`` times in a row
(process time, as a cell's ``cpu_s``) and keeps the minimum (``cpu_s``), the median, the
maximum and every sample, with the wall-clock time it was taken (``t``, seconds since
the epoch), the process and where in the run it was taken (``phase``: ``before`` the
cells, ``batch`` between them, ``after`` them).

A run calibrates in the process that starts it before its cells and after them; a process
that runs cells (this one for the serial executor, each pool or Dask worker) calibrates
before a batch of cells, after a cell and after a batch, whenever ``INTERVAL`` seconds
have passed since its last calibration (so between batches, at a small fixed share of the
time). Each row gets ``cpu_s_calibrated`` = ``cpu_s`` / the reference workload's
``cpu_s`` of the calibration of its own process nearest in time to the cell (in units of
the reference workload: a row of 2.0 took as long as two reference workloads), and
``calibration_cpu_s``, ``calibration_t`` saying which calibration that was. The
calibrations of a run are kept in the store (``Store.calibrations``), so its drift can be
read afterwards (``drift``).

A cell whose working set leaves the caches (a large state, its work arrays and samples:
``working_set_bytes`` of the row) runs at the speed of the memory, which a neighbour that
streams memory slows while the compute-bound reference workload does not move
(docs/performance.md, "Calibration and memory": measured). So each calibration also times a
*memory workload*, ``MEMORY_PASSES`` passes of a triad over ``MEMORY_BYTES`` (beyond a
core's own caches, within the shared one) timed ``MEMORY_REPEATS`` times, and keeps its
minimum (``memory_cpu_s``); a row whose ``working_set_bytes`` passes ``MEMORY_BOUND_BYTES`` is
calibrated by it (``cpu_s_calibrated`` in units of the memory workload,
``calibration_workload`` = ``memory``), every other row by the reference workload
(``compute``). compare divides calibrated times only where both rows used the same one.

Neither workload sees a neighbour that streams memory: the reference workload never leaves
its registers and the memory workload stays within the shared cache. So each calibration
also *streams* memory: ``STREAM_REPEATS`` passes of the same triad over arrays of
``stream_bytes()`` (beyond the last-level cache, so that every pass goes to memory and
shares its bandwidth with whatever else streams), each timed alone, and keeps the minimum
(``stream_cpu_s``). It calibrates no row: compare and history read a run's median of it
(``stream_median``) to tell whether two runs had the same memory bandwidth
(longtime.reporting.compare_machine), and give no time verdict where they did not.

The kernels are compiled once and cached on disk (numba's cache): a process loads them.
"""
from __future__ import annotations

import os
import platform
import statistics
import time
from typing import Any

import numba
import numpy as np

from longtime.core import phases

STEPS = 400_000  # a few milliseconds on a current core
REPEATS = 5
INTERVAL = 5.0  # seconds between the calibrations of one process while it runs cells
# rows carry the calibrations their process took under this key until run_matrix stores
# them in the run (it is never part of a stored row)
POINTS_KEY = "_calibrations"
MEMORY_BYTES = 8 * 2**20  # the memory workload's two arrays together (beyond L2, within L3)
MEMORY_PASSES = 64  # passes a timed call makes: tens of milliseconds, as a large cell runs
MEMORY_REPEATS = 2
# a row whose working set passes this (beyond a core's share of the last-level cache) is
# calibrated by the memory workload
MEMORY_BOUND_BYTES = 4 * 2**20
# the streaming workload's two arrays together: twice the last-level cache (a pass over
# twice the cache finds none of its data there, whatever the cache's replacement), at least
# STREAM_MIN_BYTES (above the last-level cache of a desktop or a server's core complex) where
# the cache's size is not known, at most STREAM_MAX_BYTES (allocated at each calibration)
STREAM_MIN_BYTES = 64 * 2**20
STREAM_MAX_BYTES = 512 * 2**20
STREAM_REPEATS = 5
CACHE_DIR = "/sys/devices/system/cpu/cpu0/cache"


@numba.njit(cache=True, nogil=True)
def reference_workload(steps: int, h: float) -> float:
    """``steps`` RK4 steps of size ``h`` on q' = p, p' = -q from (1, 0); returns the
    energy error (so the loop cannot be optimised away)."""
    q, p = 1.0, 0.0
    for _ in range(steps):
        k1q, k1p = p, -q
        k2q, k2p = p + 0.5 * h * k1p, -(q + 0.5 * h * k1q)
        k3q, k3p = p + 0.5 * h * k2p, -(q + 0.5 * h * k2q)
        k4q, k4p = p + h * k3p, -(q + h * k3q)
        q += h / 6.0 * (k1q + 2.0 * k2q + 2.0 * k3q + k4q)
        p += h / 6.0 * (k1p + 2.0 * k2p + 2.0 * k3p + k4p)
    return 0.5 * (q * q + p * p) - 0.5


@numba.njit(cache=True, nogil=True)
def memory_workload(a: np.ndarray, b: np.ndarray, passes: int) -> float:
    """``passes`` passes of b = a + b / 2 over two arrays beyond the private caches, reused
    pass after pass as a large cell reuses its state, work and samples: what a neighbour
    that evicts the shared cache slows."""
    for _ in range(passes):
        for i in range(a.size):
            b[i] = a[i] + 0.5 * b[i]
    return b[0]


def reference_seconds(steps: int = STEPS) -> float:
    """CPU seconds of this process for one call of the reference workload over ``steps``
    steps (loaded or compiled by an earlier call: ``measure`` makes one)."""
    c0 = time.process_time()
    reference_workload(steps, 0.01)
    return time.process_time() - c0


_ARRAYS: list[np.ndarray] = []


def _memory_arrays(nbytes: int) -> tuple[np.ndarray, np.ndarray]:
    """The memory workload's arrays, allocated once per process and size."""
    n = nbytes // 16
    if not _ARRAYS or _ARRAYS[0].size != n:
        _ARRAYS[:] = [np.ones(n), np.zeros(n)]
    return _ARRAYS[0], _ARRAYS[1]


def last_level_cache_bytes(cache_dir: str = CACHE_DIR) -> int | None:
    """The size of the last level of cache of the first CPU (as Linux's /sys reports it), None
    where it is not known."""
    from pathlib import Path

    sizes = {}
    for index in Path(cache_dir).glob("index*"):
        try:
            level = int((index / "level").read_text())
            text = (index / "size").read_text().strip().upper()
            unit = {"K": 2**10, "M": 2**20, "G": 2**30}.get(text[-1:], 1)
            sizes[level] = int(text.rstrip("KMG")) * unit
        except (OSError, ValueError):
            continue
    return sizes[max(sizes)] if sizes else None


def stream_bytes() -> int:
    """The streaming workload's two arrays together: twice the last-level cache, within
    STREAM_MIN_BYTES .. STREAM_MAX_BYTES."""
    cache = last_level_cache_bytes() or 0
    return int(min(STREAM_MAX_BYTES, max(STREAM_MIN_BYTES, 2 * cache)))


def stream_seconds(nbytes: int, repeats: int = STREAM_REPEATS) -> list[float] | None:
    """CPU seconds of ``repeats`` passes of the memory workload's triad over two arrays of
    ``nbytes`` together, each pass timed alone, after an untimed pass that maps every page
    (None where this process may not allocate them: a memory limit)."""
    try:
        a, b = np.ones(nbytes // 16), np.zeros(nbytes // 16)
    except MemoryError:
        return None
    memory_workload(a, b, 1)
    passes = []
    for _ in range(repeats):
        c0 = time.process_time()
        memory_workload(a, b, 1)
        passes.append(time.process_time() - c0)
    return passes


def measure(phase: str = "batch", repeats: int = REPEATS, steps: int = STEPS,
            memory_bytes: int = MEMORY_BYTES, memory_repeats: int = MEMORY_REPEATS,
            streamed_bytes: int | None = None, stream_repeats: int = STREAM_REPEATS) -> dict[str, Any]:
    """One calibration: the reference workload timed ``repeats`` times (after a call that
    loads or compiles it), then the memory workload ``memory_repeats`` times over
    ``memory_bytes`` (0: not timed), then the streaming workload ``stream_repeats`` times over
    ``streamed_bytes`` (default ``stream_bytes()``; 0: not timed)."""
    reference_workload(10, 0.01)
    t = time.time()
    samples = [reference_seconds(steps) for _ in range(repeats)]
    point = {"t": t, "phase": phase, "pid": os.getpid(), "host": platform.node(), "steps": steps,
             "cpu_s": min(samples), "cpu_s_median": statistics.median(samples), "cpu_s_max": max(samples),
             "cpu_s_samples": samples}
    if memory_bytes and memory_repeats:
        a, b = _memory_arrays(memory_bytes)
        memory_workload(a, b, 1)  # loads or compiles it, and touches every page
        passes = []
        for _ in range(memory_repeats):
            c0 = time.process_time()
            memory_workload(a, b, MEMORY_PASSES)
            passes.append(time.process_time() - c0)
        point.update(memory_bytes=memory_bytes, memory_cpu_s=min(passes), memory_cpu_s_samples=passes)
    streamed_bytes = stream_bytes() if streamed_bytes is None else streamed_bytes
    streamed = stream_seconds(streamed_bytes, stream_repeats) if streamed_bytes and stream_repeats else None
    if streamed:
        point.update(stream_bytes=streamed_bytes, stream_cpu_s=min(streamed), stream_cpu_s_samples=streamed)
    return point


class Calibrator:
    """The calibrations of one process that runs cells, and the rows they calibrate.

    ``start()`` before a batch of cells, ``cell(row, t0, t1)`` after each cell (which ran
    from wall time ``t0`` to ``t1``: the row gets the calibration nearest in time to its
    middle), ``finish()`` after the batch (re-annotates the batch's rows, which a batch
    returns together, with a calibration taken then). Each of them calibrates only once
    ``interval`` seconds have passed since this process's last calibration (or before its
    first), so calibrating costs a fixed small share of the time. A new calibration rides
    on the next row handed back (``POINTS_KEY``) until the run stores it."""

    def __init__(self, interval: float = INTERVAL) -> None:
        self.interval = interval
        self.points: list[dict[str, Any]] = []
        self._rows: list[tuple[dict, float]] = []  # the batch's rows and their mid times
        self._new: list[dict[str, Any]] = []  # calibrations not yet handed to a row

    def take(self, phase: str) -> dict[str, Any]:
        point = self._measured(phase)
        self._new.append(point)
        return point

    def _measured(self, phase: str) -> dict[str, Any]:
        """A calibration taken now, kept as this process's latest."""
        with phases.phase("calibration"):
            point = measure(phase)
        self.points.append(point)
        return point

    def due(self) -> bool:
        return not self.points or time.time() - self.points[-1]["t"] >= self.interval

    def recent(self, phase: str) -> dict[str, Any]:
        """This process's latest calibration where it is recent (``due`` not yet), else one
        taken now and kept for the next caller; it rides on no row (the caller annotates its
        own record with it)."""
        return self._measured(phase) if self.due() else self.points[-1]

    def start(self) -> None:
        self._rows = []
        if self.due():
            self.take("batch")

    def cell(self, row: dict[str, Any], t0: float, t1: float) -> dict[str, Any]:
        if self.due():
            self.take("batch")
        mid = 0.5 * (t0 + t1)
        self._rows.append((row, mid))
        annotate(row, self.points, mid)
        self._hand_over(row)
        return row

    def finish(self) -> None:
        if self._rows and self.due():
            self.take("batch")
            for row, mid in self._rows:
                annotate(row, self.points, mid)
            self._hand_over(self._rows[-1][0])
        self._rows = []

    def handed(self) -> None:
        """The run has stored the calibrations taken so far (they ride on no row)."""
        self._new = []

    def _hand_over(self, row: dict[str, Any]) -> None:
        if self._new:
            row.setdefault(POINTS_KEY, []).extend(self._new)
            self._new = []


_HERE: Calibrator | None = None


def here(reset: bool = False) -> Calibrator:
    """This process's calibrator (a pool worker keeps it across batches); ``reset`` starts
    a new run's (the calibrations of an earlier run in the same process are not its own)."""
    global _HERE
    if _HERE is None or reset:
        _HERE = Calibrator()
    return _HERE


def nearest(points: list[dict[str, Any]], t: float) -> dict[str, Any] | None:
    return min(points, key=lambda p: abs(p["t"] - t)) if points else None


def workload_for(row: dict[str, Any]) -> str:
    """The workload that calibrates ``row``: ``memory`` where its working set passes
    ``MEMORY_BOUND_BYTES``, else ``compute`` (the reference workload)."""
    size = row.get("working_set_bytes")
    return "memory" if isinstance(size, (int, float)) and size > MEMORY_BOUND_BYTES else "compute"


def annotate(row: dict[str, Any], points: list[dict[str, Any]], t: float) -> None:
    """``cpu_s_calibrated``, ``calibration_cpu_s``, ``calibration_workload`` and
    ``calibration_t`` of ``row`` from the calibration of ``points`` nearest to ``t``, by the
    workload that fits the row (``workload_for``; the reference workload where the point has
    no memory part) (nothing for a row without a CPU time)."""
    point = nearest(points, t)
    cpu = row.get("cpu_s")
    if point is None or not isinstance(cpu, (int, float)) or isinstance(cpu, bool) or not point["cpu_s"] > 0:
        return
    workload = workload_for(row)
    if workload == "memory" and isinstance(point.get("memory_cpu_s"), (int, float)) and point["memory_cpu_s"] > 0:
        unit = point["memory_cpu_s"]
    else:
        workload, unit = "compute", point["cpu_s"]
    row.update(cpu_s_calibrated=cpu / unit, calibration_cpu_s=unit, calibration_workload=workload,
               calibration_t=point["t"])


def take_points(row: dict[str, Any]) -> list[dict[str, Any]]:
    """The calibrations a row carries (removed from it: they belong to the run, not the row)."""
    return row.pop(POINTS_KEY, None) or []


def drift(points: list[dict[str, Any]]) -> dict[str, Any] | None:
    """A run's calibration in brief: the reference workload's CPU seconds (median over the
    calibrations of their minima), its range and its change from the first to the last
    calibration, the spread within a calibration (median of max / min - 1), and the
    streaming workload's CPU seconds (``stream_cpu_s``: ``stream_median``; None for a run
    calibrated without it) and the bytes it streamed."""
    if not points:
        return None
    ordered = sorted(points, key=lambda p: p["t"])
    values = [p["cpu_s"] for p in ordered]
    within = [p["cpu_s_max"] / p["cpu_s"] - 1 for p in ordered if p["cpu_s"] > 0]
    streamed = stream_median(ordered)
    return {"calibrations": len(values), "reference_cpu_s": float(np.median(values)),
            "min": min(values), "max": max(values), "range": max(values) / min(values) - 1 if min(values) > 0 else None,
            "first_to_last": values[-1] / values[0] if values[0] > 0 else None,
            "within": float(np.median(within)) if within else None,
            "span_s": ordered[-1]["t"] - ordered[0]["t"],
            "stream_cpu_s": streamed and streamed[0], "stream_bytes": streamed and streamed[1]}


def stream_median(points: list[dict[str, Any]]) -> tuple[float, int] | None:
    """The streaming workload's CPU seconds over a run's calibrations (the median of their
    minima, over those that streamed the most common size) and that size; None where no
    calibration streamed."""
    sizes = [p["stream_bytes"] for p in points if _positive(p.get("stream_cpu_s")) and p.get("stream_bytes")]
    if not sizes:
        return None
    size = max(set(sizes), key=sizes.count)
    return float(np.median([p["stream_cpu_s"] for p in points if p.get("stream_bytes") == size
                            and _positive(p.get("stream_cpu_s"))])), size


def _positive(x) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool) and x > 0


def drift_text(points: list[dict[str, Any]]) -> str:
    """'reference workload 2.01 ms (12 calibrations over 40 s: 1.98 .. 2.15 ms, last/first
    x1.03; within one calibration +2.1 %)'."""
    d = drift(points)
    if d is None:
        return "no calibration (the run's executor does not calibrate, or it was stored before calibrations)"
    text = f"reference workload {1e3 * d['reference_cpu_s']:.3g} ms ({d['calibrations']} calibration"
    text += "s" if d["calibrations"] != 1 else ""
    if d["calibrations"] > 1:
        text += (f" over {d['span_s']:.0f} s: {1e3 * d['min']:.3g} .. {1e3 * d['max']:.3g} ms, "
                 f"last/first x{d['first_to_last']:.3g}")
    if d["within"] is not None:
        text += f"; slowest repeat +{100 * d['within']:.1f} % over the fastest"
    if d["stream_cpu_s"] is not None:
        text += f"; memory streamed {d['stream_bytes'] / 2**20:.0f} MiB in {1e3 * d['stream_cpu_s']:.3g} ms"
    return text + ")"
