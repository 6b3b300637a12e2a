"""The text of ``longtime compare``: a cell's label, the verdicts' counts, the machine, the
provenance of each run and the cells that changed."""
from __future__ import annotations

from typing import Any

from longtime.reporting import machines
from longtime.reporting.compare_cells import MATCH_KEYS
from longtime.reporting.compare_machine import machine_text, unchecked_text


def label(cell: dict, digits: int | None = None, problem: bool = True) -> str:
    """Every setting that tells two cells apart (``compare.MATCH_KEYS``), t_final included,
    each value to full precision: two cells never share a header. ``digits``: numbers to that
    many digits instead (a table or a panel title, where the full label is a command away);
    ``problem``: False leaves the problem out (a table under the problem's heading)."""
    parts = [str(cell.get("problem"))] if problem else []
    parts.append(str(cell.get("integrator")))
    for k in MATCH_KEYS[2:]:
        v = cell.get(k)
        if v is None or v == "":
            continue
        if k == "settings":
            parts.append(str(v))
        elif isinstance(v, float) and digits is not None:
            parts.append(f"{k}={v:.{digits}g}")
        elif isinstance(v, float):
            parts.append(f"{k}={v:.17g}" if float(f"{v:.6g}") != v else f"{k}={v:g}")
        else:
            parts.append(f"{k}={v}")
    return " ".join(parts)


def _counts_text(counts: dict[str, dict[str, int]], result: dict) -> str:
    t, acc = counts["time"], counts["accuracy"]
    basis = result["time_basis"] or "not timed"
    return (f"time ({basis}): {t['slower']} slower, {t['faster']} faster, {t['within']} within the spread, "
            f"{t['too short']} too short to time (< {1e6 * result['short_cpu_s']:g} us)"
            f"{_not_comparable_text(t)}; "
            f"accuracy: {acc['less accurate']} less accurate, {acc['more accurate']} more accurate, "
            f"{acc['same']} within x{result['error_factor']:g}; "
            f"status: {counts['status']['no longer ok']} no longer ok; "
            f"growth class: {counts['growth class']['changed']} changed; observed order: "
            f"{counts['observed order']['changed']} of {counts['observed order']['compared']} changed")


def _not_comparable_text(time_counts: dict[str, int]) -> str:
    """The cells without a time verdict because the memory bandwidth differed (none: nothing)."""
    n = time_counts.get("not comparable", 0)
    return f", {n} not comparable (the memory bandwidth beside them differed between the runs)" if n else ""


def _instructions_text(result: dict) -> list[str]:
    """The instruction counts' verdict line (none when no cell was counted in both runs)."""
    n = result["counts"].get("instructions")
    if not n or n["not compared"] == len(result["cells"]):
        return []
    other = f", {n['other tool']} counted by another tool (Valgrind or CPU)" if n["other tool"] else ""
    return [f"instructions (beyond x{result['instruction_factor']:g}): {n['more']} more, {n['fewer']} fewer, "
            f"{n['within']} within{other}, {n['not compared']} not counted in both runs"]


def render(result: dict[str, Any], show_all: bool = False) -> str:
    cells = result["cells"]
    lines = [f"{len(cells)} common cells ({result['only_a']} only in A, {result['only_b']} only in B): "
             f"{result['regressed']} regressed, {result['improved']} improved",
             _counts_text(result["counts"], result), machine_text(result["machine"])]
    if result.get("time_unchecked"):
        lines.append(unchecked_text(result["time_unchecked"], result["bandwidth_unchecked"]))
    lines += _instructions_text(result)
    if result.get("provenance"):
        lines += provenance_lines(result["provenance"])
    for kind, over in (("schemes", "problems"), ("problems", "schemes")):
        judged = [f"{name} x{g['median_ratio']:.3g} ({g['verdict']}, {g['batches']} {over})"
                  for name, g in result[kind].items() if g["verdict"] is not None
                  and (show_all or g["verdict"] != "within")]
        if judged:
            lines.append(f"time per {kind[:-1]} (median over its {over}, beyond x{result['factor']:g}): "
                         + "; ".join(judged))
    pair_lines = []
    for p in result["pairs"]:
        notes = [f"{o['integrator']} order {o['observed_order_a']:.2f} -> {o['observed_order_b']:.2f}"
                 + (" CHANGED" if o["order_changed"] else "") for o in p["orders"]
                 if show_all or o["order_changed"]]
        notes += [f"{k} ({n} cell{'s' if n > 1 else ''})" for k, n in p["growth_class_changes"].items()]
        if notes or show_all:
            time = f"time x{p['time_ratio']:.3g}" if p["time_ratio"] is not None else "time -"
            ef = result["error_factor"]
            errs = ", ".join(f"{f} x{r:.3g}" for f, r in p["error_ratios"].items()
                             if show_all or not 1 / ef <= r <= ef) or f"errors within x{ef:g}"
            pair_lines.append(f"  {p['problem']} {p['integrator']} ({p['cells']} cells): {time}; {errs}; "
                              + "; ".join(notes))
    if pair_lines:
        lines.append("per problem x scheme (observed order, growth class):")
        lines += pair_lines
    for c in cells:
        if c["regressions"] or c["improvements"] or c["growth_class_changes"] or show_all:
            if c.get("time_ratio") is not None:
                cpu = f"{'time' if c['time_basis'] == 'calibrated' else 'cpu'} x{c['time_ratio']:.3g}"
                if c["time_verdict"] == "too short":
                    cpu += " (too short to time)"
                elif c["time_verdict"] == "not comparable":
                    cpu += f" (not comparable: {c['not_comparable']})"
            else:
                cpu = f"cpu x{c['cpu_ratio']:.3g}" if c.get("cpu_ratio") is not None else "cpu -"
            text = f"  {'REGRESSED' if c['regressions'] else 'ok':9s} {label(c)}"
            if c["time_verdict"] not in ("slower", "faster"):  # those say it below
                text += f": {cpu}"
            if c["regressions"]:
                text += ("; " if c["time_verdict"] not in ("slower", "faster") else ": ") + "; ".join(c["regressions"])
            if c["improvements"]:
                text += "; better: " + ", ".join(c["improvements"])
            for k, (x, y) in c["growth_class_changes"].items():
                text += f"; {k} {x} -> {y}"
            lines.append(text)
    for side in ("a", "b"):
        for m in result.get(f"left_out_{side}", []):
            lines.append(f"  left out of {side.upper()}'s order table: {m['problem']} {m['integrator']} "
                         f"({m['reason']})")
    if result.get("cross_machine"):
        lines.append("runs A and B ran on different machines: their times compare only calibrated and roughly; "
                     "their instruction counts where the table says they agree")
        lines.append(machines.text(result["cross_machine"]))
    return "\n".join(lines)


def provenance_lines(prov: dict[str, Any]) -> list[str]:
    from longtime.execution.provenance import text

    lines = []
    for side in ("a", "b"):
        p = prov[side]
        own = p.get("longtime_git") or {}
        mine = f"{(own.get('commit') or '-')[:10]}{'+dirty' if own.get('dirty') else ''}"
        # the run's commit is longtime's own, or that of the code under test (a plugin's
        # repository, $LONGTIME_GIT_COMMIT): named as such, never as longtime's
        measured = p.get("git_commit")
        whose = "" if not measured or measured == own.get("commit") else \
            f"commit of the code measured {measured[:10]}; "
        lines.append(f"run {side.upper()}: {whose}longtime {p.get('longtime') or '-'} "
                     f"(commit {mine}); code under test: {text(p.get('code') or [])}")
    return lines
