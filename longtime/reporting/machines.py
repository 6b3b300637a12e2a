"""Results from several machines side by side (a store that ``longtime merge`` filled from
the stores of several machines, or one whose runs moved between machines).

A run's machine is its recorded ``machine`` (longtime.execution.store.environment): the
host name, the CPU model and the core count tell one machine from another (``machine_key``);
two stores of one machine are one machine. Each machine is listed with its calibration (its
runs' reference workload, longtime.execution.calibration.drift), the versions that
can move an instruction count (Python, numba, llvmlite, numpy) and the targets its counts
were compiled for.

The cross-machine table has one line per cell (the cell identity ``longtime compare``
matches: longtime.reporting.compare.cross_machine_table passes them in) and, for each machine, the cell's instruction
count, its calibrated time (the row's ``cpu_s_calibrated``: its CPU time over its own
process's reference workload; else ``cpu_s`` over the machine's calibration) and its own CPU
seconds; the row of a machine's latest run of the cell is shown. What compares across
machines:

- instruction counts, where both were counted for the same target by the same Valgrind with
  the same versions (``instructions_tool``, ``instructions_versions``): the count does not
  depend on the host CPU (``agree`` gives the largest ratio between machines);
- calibrated times, roughly: the calibration takes out the clock, not the caches, the memory
  or the vector units, and each machine times kernels compiled for its own CPU;
- CPU seconds: only on their own machine.
"""
from __future__ import annotations

import json
from html import escape
from typing import Any, Callable

from longtime.core.status import Status
from longtime.execution.calibration import drift
from longtime.execution.run_environment import machine_key

# what the table says about each kind of figure
COMPARABLE = (
    ("instructions", "compare across machines where counted for the same target by the same Valgrind with the same "
                     "Python, numba, llvmlite and numpy (the count does not depend on the host CPU)"),
    ("calibrated time", "compares roughly: the row's CPU time over its machine's reference workload takes out the "
                        "clock speed, not the caches, memory or vector units, and each machine times kernels "
                        "compiled for its own CPU"),
    ("CPU seconds", "do not compare across machines: each is its own machine's"),
)
VERSION_KEYS = ("python", "numba", "llvmlite", "numpy")


def _json(text: Any) -> Any:
    if not isinstance(text, str):
        return text
    try:
        return json.loads(text)
    except ValueError:
        return None


def machines(runs: list[dict[str, Any]], calibrations: Callable[[int], list[dict]]) -> dict[int, dict[str, Any]]:
    """Each run's machine by run id: ``label`` (M1, M2, ... in order of first run), ``node``,
    ``cpu_model``, ``cpus``, ``versions`` (of VERSION_KEYS), ``calibration_cpu_s`` (the
    reference workload over the machine's runs, as calibration.drift reads it; None without
    calibrations) and ``runs``.
    ``calibrations(run_id)`` gives a run's calibration points."""
    found: dict[tuple, dict[str, Any]] = {}
    by_run: dict[int, dict[str, Any]] = {}
    for run in sorted(runs, key=lambda r: r["id"]):
        machine = _json(run.get("machine")) or {}
        versions = _json(run.get("versions")) or {}
        key = machine_key(machine) if isinstance(machine, dict) else (None, None, None)
        entry = found.get(key)
        if entry is None:
            entry = found[key] = {"label": f"M{len(found) + 1}", "node": key[0], "cpu_model": key[1],
                                  "cpus": key[2], "runs": [], "points": [],
                                  "versions": {k: versions.get(k) for k in VERSION_KEYS}
                                  if isinstance(versions, dict) else {}}
        entry["runs"].append(run["id"])
        entry["points"] += calibrations(run["id"])
        by_run[run["id"]] = entry
    for entry in found.values():
        summary = drift(entry.pop("points"))
        entry["calibration_cpu_s"] = summary["reference_cpu_s"] if summary else None
    return by_run


def cross_machine(rows: list[dict[str, Any]], runs: list[dict[str, Any]], calibrations: Callable[[int], list[dict]],
                  key: Callable[[dict], Any], name: Callable[[dict], str]) -> dict[str, Any] | None:
    """The cross-machine table of ``rows`` (each with its ``run_id``; ``runs``: the store's
    runs), or None when they come from fewer than two machines. ``key``/``name``: a row's
    cell identity and its header."""
    by_run = machines([r for r in runs if r["id"] in {row.get("run_id") for row in rows}], calibrations)
    listed = {m["label"]: m for m in by_run.values()}
    if len(listed) < 2:
        return None
    cells: dict[Any, dict[str, Any]] = {}
    for row in sorted(rows, key=lambda r: r.get("run_id") or 0):  # a machine's latest run last: it stays
        machine = by_run.get(row.get("run_id"))
        if machine is None or row.get("status") != Status.OK:
            continue
        cell = cells.setdefault(key(row), {"cell": name(row), "machines": {}})
        cell["machines"][machine["label"]] = _figures(row, machine)
    for cell in cells.values():
        cell["instructions_agree"] = _agreement(cell["machines"])
    for m in listed.values():
        m["targets"] = sorted({f["instructions_target"] for c in cells.values()
                               for label, f in c["machines"].items() if label == m["label"]
                               and f["instructions_target"]})
    return {"machines": list(listed.values()), "cells": list(cells.values()),
            "comparable": [{"figure": f, "says": s} for f, s in COMPARABLE]}


def _figures(row: dict[str, Any], machine: dict[str, Any]) -> dict[str, Any]:
    cpu_s, calibrated = row.get("cpu_s"), row.get("cpu_s_calibrated")
    if calibrated is None and cpu_s is not None and machine["calibration_cpu_s"]:
        calibrated = cpu_s / machine["calibration_cpu_s"]
    return {"instructions": row.get("instructions"), "cpu_s_calibrated": calibrated, "cpu_s": cpu_s,
            "run_id": row.get("run_id"), "instructions_target": row.get("instructions_target"),
            "counted_by": json.dumps([row.get("instructions_tool"), row.get("instructions_versions")], sort_keys=True)}


def _agreement(per_machine: dict[str, dict[str, Any]]) -> dict[str, Any]:
    """The largest ratio between the machines' counts of a cell where they can be compared,
    else why not."""
    counted = {label: f for label, f in per_machine.items() if f["instructions"]}
    if len(counted) < 2:
        return {"ratio": None, "why": "counted on fewer than two machines"}
    if len({f["counted_by"] for f in counted.values()}) > 1:
        return {"ratio": None, "why": "counted for another target, Valgrind or versions"}
    values = [f["instructions"] for f in counted.values()]
    return {"ratio": max(values) / min(values), "why": None}


def _number(value: float | None, unit: str = "") -> str:
    return "-" if value is None else f"{value:.4g}{unit}"


def machine_line(m: dict[str, Any]) -> str:
    versions = " ".join(f"{k} {v}" for k, v in m["versions"].items() if v)
    calibration = (f"calibration {1e3 * m['calibration_cpu_s']:.3g} ms" if m["calibration_cpu_s"]
                   else "no calibration")
    targets = f"counted for {', '.join(m['targets'])}" if m.get("targets") else "no instruction count"
    return (f"{m['label']}: {m['cpu_model'] or 'CPU unknown'}, {m['cpus'] or '?'} cores "
            f"({m['node'] or 'host unknown'}); {calibration}; {versions or 'versions unknown'}; {targets}; "
            f"runs {', '.join(map(str, m['runs']))}")


def _agree_text(agree: dict[str, Any]) -> str:
    return f"x{agree['ratio']:.5f}" if agree["ratio"] is not None else agree["why"]


def _grid(table: dict[str, Any]) -> tuple[list[str], list[list[str]]]:
    """The cell table's header and lines, as text: each machine's counts, the agreement,
    each machine's calibrated times and CPU seconds."""
    labels = [m["label"] for m in table["machines"]]
    head = (["cell"] + [f"{x} instructions" for x in labels] + ["instructions agree"]
            + [f"{x} calibrated" for x in labels] + [f"{x} cpu_s" for x in labels])
    body = []
    for cell in table["cells"]:
        figs = [cell["machines"].get(x, {}) for x in labels]
        body.append([cell["cell"], *(_number(f.get("instructions")) for f in figs),
                     _agree_text(cell["instructions_agree"]), *(_number(f.get("cpu_s_calibrated")) for f in figs),
                     *(_number(f.get("cpu_s"), " s") for f in figs)])
    return head, body


def text(table: dict[str, Any] | None) -> str:
    """The table as text: the machines, what compares, one line per cell."""
    if not table:
        return ""
    lines = ["results from several machines:", *(f"  {machine_line(m)}" for m in table["machines"])]
    lines += [f"  {c['figure']}: {c['says']}" for c in table["comparable"]]
    head, body = _grid(table)
    widths = [max(len(r[i]) for r in [head, *body]) for i in range(len(head))]
    for r in [head, *body]:
        lines.append("  " + "  ".join(v.ljust(w) if i == 0 else v.rjust(w) for i, (v, w) in enumerate(zip(r, widths))))
    return "\n".join(lines)


def html(table: dict[str, Any] | None) -> str:
    """The table as an HTML section (empty when the rows come from one machine)."""
    if not table:
        return ""
    items = "".join(f"<li>{escape(machine_line(m))}</li>" for m in table["machines"])
    says = "".join(f"<li><b>{escape(c['figure'])}</b> {escape(c['says'])}</li>" for c in table["comparable"])
    head, body = _grid(table)
    cells = "".join("<tr>" + "".join(f"<td>{escape(v)}</td>" for v in r) + "</tr>" for r in body)
    return (f'<section id="machines"><h2>Results from several machines</h2><ul>{items}</ul>'
            f"<p>Which figures compare across machines:</p><ul>{says}</ul>"
            f"<table><thead><tr>{''.join(f'<th>{escape(h)}</th>' for h in head)}</tr></thead>"
            f"<tbody>{cells}</tbody></table></section>")
