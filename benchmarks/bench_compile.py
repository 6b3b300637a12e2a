"""Compile time of each scheme family's kernel: cold (empty caches) and warm (a cache hit).

numba compilation, not integration, can dominate a cold main job's wall time (a fresh process
compiles every kernel it runs; docs/performance.md gives the figures). This script and
its asv twin (``CompileTime.track_cold_s`` / ``track_warm_s``, in seconds) keep that cost
in the history, so a compile regression shows like a speed regression.

Each measurement is a fresh Python process with its own empty ``NUMBA_CACHE_DIR`` and
``LONGTIME_CACHE_DIR``: the cold figure is the first ``integrate`` call (compilation plus a
ten-step run, whose integration is negligible), the warm figure the same call in a second
process over the caches the first one filled. With ``--events`` the cold run also lists
the functions numba spent longest compiling (numba's event API, ``numba:compile``), which
is where to look when a family's figure grows. With ``--stages`` it splits the cold run's
CPU seconds by compiler stage (numba's bytecode analysis and untyped passes, IR inlining,
type inference, lowering to LLVM IR; LLVM's function passes, module passes and object code;
the cache's writing), each stage's own time, the stages nested in it subtracted.

    python benchmarks/bench_compile.py                  # every family
    python benchmarks/bench_compile.py -f bpl --events  # one family, with the breakdown
    python benchmarks/bench_compile.py -f splitting --stages
    python benchmarks/bench_compile.py --pair pythagorean-three-body,bpl --events  # any pair
    python benchmarks/bench_compile.py --matrix -- -p kepler,toda   # longtime matrix's kernels

``--matrix`` compiles, in one fresh process with empty caches (as one worker of a cold main
job would), the kernel of every distinct cell of ``longtime matrix`` (its arguments after
``--``; none: the default matrix), each by a few steps of its scheme, and prints the CPU
seconds of numba's compiles (the outermost ones) in total and by pair.
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile

# one representative pair per scheme family (the family shares its driver and step shape)
FAMILIES = {
    "explicit-rk": ("toda", "rk4"),
    "implicit-rk": ("toda", "gauss6"),
    "splitting": ("figure-eight", "yoshida8"),
    "embedded-rk": ("kepler", "rk45"),
    "taylor": ("toda", "taylor-adaptive"),
    "bpl": ("toda", "bpl"),
    "exponential": ("kdv", "etdrk4"),
    "constrained": ("double-pendulum", "rattle"),
}

# run in the child: time the first integrate call, optionally recording compile events
_CHILD = r"""
import contextlib, json, sys, time
from numba.core import event
from longtime.core import registry
problem_name, scheme_name, events, stages = sys.argv[1], sys.argv[2], sys.argv[3] == "1", sys.argv[4] == "1"
own, open_stages = {}, []


def timed(owner, method, label):
    # owner.method adds its CPU seconds, less those of the stages nested in it, to own[label]
    original = getattr(owner, method)

    def wrapper(*args, **kwargs):
        c0 = time.process_time()
        open_stages.append(0.0)
        try:
            return original(*args, **kwargs)
        finally:
            spent, nested = time.process_time() - c0, open_stages.pop()
            own[label] = own.get(label, 0.0) + spent - nested
            if open_stages:
                open_stages[-1] += spent

    setattr(owner, method, wrapper)


if stages:
    from numba.core import base, caching, codegen, compiler_machinery, lowering, typed_passes, typeinfer, untyped_passes
    for owner, method, label in (
            (compiler_machinery.PassManager, "run", "numba: other passes (bytecode, rewrites, SSA, wrappers)"),
            (untyped_passes.InlineInlinables, "run_pass", "numba: IR inlining (inline='always')"),
            (typeinfer.TypeInferer, "propagate", "numba: type inference"),
            (typed_passes.NopythonRewrites, "run_pass", "numba: typed rewrites"),
            (lowering.Lower, "lower", "numba: lowering to LLVM IR"),
            (base.BaseContext, "refresh", "numba: target context set-up (once a process)"),
            (codegen.CPUCodeLibrary, "add_ir_module", "llvm: parsing the IR"),
            (codegen.CPUCodeLibrary, "_optimize_functions", "llvm: function passes"),
            (codegen.CPUCodeLibrary, "_optimize_final_module", "llvm: module passes (O3, after linking)"),
            (codegen.JITCodeLibrary, "_finalize_specific", "llvm: object code (MCJIT)"),
            (caching.Cache, "save_overload", "cache: writing (pickle, index)")):
        timed(owner, method, label)
problem = registry.problem_class(problem_name)()
scheme = registry.integrator_class(scheme_name)()
t_final = problem.t0 + 10 * problem.default_dt
with (event.install_recorder("numba:compile") if events else contextlib.nullcontext()) as recorder:
    start = time.perf_counter()
    scheme.integrate(problem, t_final, max_samples=16)
    seconds = time.perf_counter() - start
top, begun = [], {}
for ts, ev in (recorder.buffer if events else []):
    fn = getattr(ev.data.get("dispatcher"), "py_func", None)
    key = (id(ev.data.get("dispatcher")), str(ev.data.get("args")))
    if ev.is_start:
        begun[key] = ts
    elif key in begun and fn is not None:
        top.append((ts - begun.pop(key), f"{fn.__module__}.{fn.__qualname__}"))
top.sort(reverse=True)
print(json.dumps({"seconds": seconds, "top": top[:8], "stages": sorted(own.items(), key=lambda kv: -kv[1])}))
"""


_MATRIX_CHILD = r"""
import collections, json, sys, time
from numba.core import event
from longtime.commands.cli import build_parser
from longtime.commands.matrix import matrix_cells
from longtime.core.stepping import AdaptiveIntegrator, FixedStepIntegrator
from longtime.execution.cells import build
cells, _ = matrix_cells(build_parser().parse_args(["matrix"] + sys.argv[1:]))
by_pair, count, depth, start, pair = collections.Counter(), collections.Counter(), [0], [0.0], [None]


class Compiles(event.Listener):
    def on_start(self, ev):
        if depth[0] == 0:
            start[0] = time.process_time()
        depth[0] += 1

    def on_end(self, ev):
        depth[0] -= 1
        if depth[0] == 0:
            by_pair[pair[0]] += time.process_time() - start[0]
            count[pair[0]] += 1


event.register("numba:compile", Compiles())
seen = set()
for cell in cells:
    key = json.dumps(cell.to_dict(), sort_keys=True, default=str)
    if cell.skip_reason or key in seen:
        continue
    seen.add(key)
    pair[0] = f"{cell.problem} x {cell.integrator}"
    problem, scheme = build(cell)
    if isinstance(scheme, FixedStepIntegrator):
        scheme.integrate(problem, problem.t0 + 3 * scheme.dt_for(problem), max_samples=16)
    elif isinstance(scheme, AdaptiveIntegrator):
        scheme.integrate(problem, problem.t0 + 3 * problem.default_dt, max_samples=16)
print(json.dumps({"cells": len(seen), "compiles": sum(count.values()), "cpu_s": sum(by_pair.values()),
                  "pairs": by_pair.most_common()}))
"""


def measure_matrix(matrix_args: list[str]) -> dict:
    """CPU seconds of the compiles of a matrix's kernels, in one process with empty caches."""
    with tempfile.TemporaryDirectory() as numba_dir, tempfile.TemporaryDirectory() as lt_dir:
        env = {**os.environ, "NUMBA_CACHE_DIR": numba_dir, "LONGTIME_CACHE_DIR": lt_dir}
        env.pop("LONGTIME_NO_KERNEL_CACHE", None)
        out = subprocess.run([sys.executable, "-c", _MATRIX_CHILD, *matrix_args], env=env,
                             capture_output=True, text=True, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def measure(family: str, events: bool = False, stages: bool = False) -> dict:
    """Cold and warm first-call seconds of ``family``'s pair, each in a fresh process."""
    problem, scheme = FAMILIES[family]
    with tempfile.TemporaryDirectory() as numba_dir, tempfile.TemporaryDirectory() as lt_dir:
        env = {**os.environ, "NUMBA_CACHE_DIR": numba_dir, "LONGTIME_CACHE_DIR": lt_dir}
        env.pop("LONGTIME_NO_KERNEL_CACHE", None)
        figures = {}
        for label, record in (("cold", events), ("warm", False)):
            split = stages and label == "cold"
            out = subprocess.run([sys.executable, "-c", _CHILD, problem, scheme, "1" if record else "0",
                                  "1" if split else "0"],
                                 env=env, capture_output=True, text=True, check=True)
            result = json.loads(out.stdout.strip().splitlines()[-1])
            figures[f"{label}_s"] = result["seconds"]
            if record:
                figures["top"] = result["top"]
            if split:
                figures["stages"] = result["stages"]
    return figures


class CompileTime:
    """asv: seconds of a family's first integrate call in a fresh process."""

    params = [list(FAMILIES)]
    param_names = ["family"]
    timeout = 600
    number = 1
    repeat = 1

    def setup_cache(self):
        return {family: measure(family) for family in FAMILIES}

    def track_cold_s(self, figures, family):
        """First call with empty numba and kernel caches: compilation (and a 10-step run)."""
        return figures[family]["cold_s"]

    track_cold_s.unit = "seconds"

    def track_warm_s(self, figures, family):
        """First call in a new process over a filled cache: loading the cached kernel."""
        return figures[family]["warm_s"]

    track_warm_s.unit = "seconds"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("-f", "--family", action="append", choices=sorted(FAMILIES),
                        help="families to measure (default: all)")
    parser.add_argument("--pair", action="append", metavar="PROBLEM,SCHEME", default=[],
                        help="also (or, without -f, only) this problem and scheme, measured as a family")
    parser.add_argument("--events", action="store_true",
                        help="list the functions that took longest to compile (cold run)")
    parser.add_argument("--stages", action="store_true",
                        help="split the cold run's CPU seconds by compiler stage")
    parser.add_argument("--matrix", action="store_true",
                        help="compile CPU seconds of longtime matrix's kernels (its arguments after --)")
    parser.add_argument("matrix_args", nargs="*", help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.matrix:
        figures = measure_matrix(args.matrix_args)
        print(f"{figures['cells']} distinct cells, {figures['compiles']} compiles, "
              f"{figures['cpu_s']:.1f} CPU s of compiling")
        for pair, seconds in figures["pairs"]:
            print(f"{seconds:8.2f} s  {pair}")
        return 0
    pairs = []
    for pair in args.pair:
        problem, _, scheme = pair.partition(",")
        if not problem or not scheme:
            parser.error(f"--pair: expected PROBLEM,SCHEME, got {pair!r}")
        FAMILIES[pair] = (problem, scheme)
        pairs.append(pair)
    print(f"{'family':14s} {'pair':28s} {'cold s':>8s} {'warm s':>8s}")
    for family in (args.family or ([] if pairs else list(FAMILIES))) + pairs:
        figures = measure(family, args.events, args.stages)
        pair = " x ".join(FAMILIES[family])
        print(f"{family:14s} {pair:28s} {figures['cold_s']:8.2f} {figures['warm_s']:8.2f}")
        for seconds, label in figures.get("top", []):
            print(f"{'':16s}{seconds:7.2f} s  {label}")
        for label, seconds in figures.get("stages", []):
            print(f"{'':16s}{seconds:7.2f} s  {label}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
