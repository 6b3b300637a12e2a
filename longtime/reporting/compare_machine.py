"""The machine in ``longtime compare``: each run's reference workload (the median of its
calibrations, longtime.execution.calibration) and whether the machine's speed differed; each
run's streaming workload and whether the memory bandwidth differed.

A neighbour that streams memory slows a cell while the reference workload, all in registers,
does not move: a calibrated time cannot tell the neighbour from the code. The streaming
workload moves with it. So where the streaming workload (the median over a run's
calibrations) took longer (or shorter) in one run than in the other by more than a cell's
time verdict can attribute (``compare_cells.compare_rows``: ``--factor`` and the spread
between processes), the cell's time gets no verdict ("not comparable"; its instruction
counts, where both runs have them, still judge its work). The run's median, not the
calibration nearest the cell: one calibration's streaming moves with every burst of a
neighbour's memory traffic, the cell's time (the minimum over its processes) does not.
"""
from __future__ import annotations

from typing import Any

MACHINE_FACTOR = 1.03  # reference workloads further apart than this: the machine's speed differed


def machine(cal_a: list[dict] | None, cal_b: list[dict] | None) -> dict[str, Any]:
    """The reference workload's CPU time in each run and whether the machine's speed differed;
    the streaming workload's CPU time in each run (None: not calibrated with it) and their
    ratio B / A (``bandwidth_ratio``; None unless both streamed the same size)."""
    from longtime.execution.calibration import drift

    da, db = drift(cal_a or []), drift(cal_b or [])
    out: dict[str, Any] = {"reference_cpu_s_a": da and da["reference_cpu_s"],
                           "reference_cpu_s_b": db and db["reference_cpu_s"], "ratio": None, "differed": None,
                           "stream_cpu_s_a": da and da["stream_cpu_s"], "stream_cpu_s_b": db and db["stream_cpu_s"],
                           "bandwidth_ratio": None}
    if da and db:
        ratio = db["reference_cpu_s"] / da["reference_cpu_s"]
        out.update(ratio=ratio, differed=bool(ratio > MACHINE_FACTOR or ratio < 1 / MACHINE_FACTOR))
        if da["stream_cpu_s"] and db["stream_cpu_s"] and da["stream_bytes"] == db["stream_bytes"]:
            out["bandwidth_ratio"] = db["stream_cpu_s"] / da["stream_cpu_s"]
    return out


def bandwidth_unchecked(m: dict[str, Any]) -> str | None:
    """Why the runs' memory bandwidths were not set against each other (``machine``'s record
    ``m``; None: they were): a run stored before calibrations, or before the streaming
    workload joined them, or two runs that streamed arrays of other sizes."""
    if m["bandwidth_ratio"] is not None:
        return None
    if m["ratio"] is None:
        missing = " and ".join(x for x, v in (("A", m["reference_cpu_s_a"]), ("B", m["reference_cpu_s_b"]))
                               if v is None)
        return f"no calibration in {missing}: stored before calibrations"
    missing = " and ".join(x for x, v in (("A", m.get("stream_cpu_s_a")), ("B", m.get("stream_cpu_s_b"))) if v is None)
    if missing:
        return f"no memory-bandwidth calibration in {missing}: stored before the bandwidth check"
    return "A and B streamed arrays of other sizes"


def unchecked_text(n: int, reason: str) -> str:
    """The line that says ``n`` time verdicts were given without the bandwidth check, and why."""
    return (f"time verdicts without the memory-bandwidth check: {n} cell(s) ({reason}): they rest on the older "
            f"measurement, which does not tell a neighbour that streams memory from the code")


def machine_text(m: dict[str, Any]) -> str:
    if m["ratio"] is None:
        missing = " and ".join(x for x, v in (("A", m["reference_cpu_s_a"]), ("B", m["reference_cpu_s_b"]))
                               if v is None)
        return f"machine: no calibration in {missing} (a run stored before calibrations): times compared raw"
    text = (f"machine: reference workload {1e3 * m['reference_cpu_s_a']:.3g} ms in A, "
            f"{1e3 * m['reference_cpu_s_b']:.3g} ms in B (x{m['ratio']:.3g})")
    if m["differed"]:
        text += f": its speed differed between the runs (beyond x{MACHINE_FACTOR:g}); calibrated times allow for it"
    else:
        text += f": the same speed (within x{MACHINE_FACTOR:g})"
    return f"{text}; {_bandwidth_text(m)}"


def _bandwidth_text(m: dict[str, Any]) -> str:
    a, b = m.get("stream_cpu_s_a"), m.get("stream_cpu_s_b")
    if a is None or b is None:
        missing = " and ".join(x for x, v in (("A", a), ("B", b)) if v is None)
        return (f"no memory-bandwidth calibration in {missing} (a run calibrated without the streaming workload): "
                f"its time verdicts do not see a neighbour that streams memory")
    if m["bandwidth_ratio"] is None:
        return "memory streamed over arrays of other sizes in A and B: the bandwidths are not compared"
    return (f"memory streaming {1e3 * a:.3g} ms in A, {1e3 * b:.3g} ms in B (x{m['bandwidth_ratio']:.3g}); "
            f"a cell's time is not judged where that passes its threshold")
