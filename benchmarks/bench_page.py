"""What does the results page cost, figure by figure?

``longtime matrix`` and ``longtime report --html`` end with the results page
(longtime.reporting.page): per problem a winner map, a work-precision figure and the drift
figures (some drawn ahead by the matrix's idle workers), then the checks, the cards and the
history. This script writes the page of a stored run again, in this one process (no pool,
nothing drawn ahead: every figure drawn here), and prints the CPU seconds of each kind of
figure, of the rest of the page and in all:

    python benchmarks/bench_page.py --db longtime.sqlite --run RUN_ID --out /tmp/page

CPU seconds, not wall: the figures are all Python, so their CPU time is their cost on any
number of cores. The first figure of the process also pays matplotlib's start (its font
list): it is counted with its kind. Nothing is stored.
"""
from __future__ import annotations

import argparse
import collections
import functools
import tempfile
import time

# (module, function): the figure functions the page calls, each counted as its kind
FIGURES = (("longtime.reporting.figures.results", "work_precision_svg"),
           ("longtime.reporting.figures.results", "drift_svg"),
           ("longtime.reporting.figures.results", "calibration_svg"),
           ("longtime.reporting.figures.verdict", "winner_map_svg"),
           ("longtime.reporting.figures.verdict", "checks_svg"))


def main() -> None:
    import importlib

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--db", default="longtime.sqlite")
    parser.add_argument("--run", type=int, default=None, help="run id (default: the newest)")
    parser.add_argument("--out", default=None, help="the page's folder (default: a temporary one)")
    args = parser.parse_args()
    from longtime.execution.store import Store
    from longtime.reporting import page

    spent: collections.Counter = collections.Counter()
    calls: collections.Counter = collections.Counter()

    def counted(kind, fn):
        @functools.wraps(fn)
        def wrapper(*a, **k):
            start = time.process_time()
            try:
                return fn(*a, **k)
            finally:
                spent[kind] += time.process_time() - start
                calls[kind] += 1
        return wrapper

    for module, name in FIGURES:
        mod = importlib.import_module(module)
        fn = getattr(mod, name)
        if name == "drift_svg":  # the invariants' and the diagnostics' figures apart
            def drift(rows, style, kind="invariant", _fn=fn):
                return counted(f"drift_svg ({kind})", _fn)(rows, style, kind)
            setattr(mod, name, drift)
        else:
            setattr(mod, name, counted(name, fn))
    store = Store(args.db, readonly=True)
    run_id = args.run or store.latest_run()
    rows = store.rows(run_id)
    out = args.out or tempfile.mkdtemp(prefix="bench-page-")
    cpu, wall = time.process_time(), time.perf_counter()
    path = page.write_html(out, rows, store, [run_id], jobs=1)
    cpu, wall = time.process_time() - cpu, time.perf_counter() - wall
    figures = sum(spent.values())
    print(f"run {run_id}: {len(rows)} rows; page {path}")
    print(f"{'':32s} {'calls':>5s} {'CPU s':>7s}")
    for kind in sorted(spent):
        print(f"{kind:32s} {calls[kind]:5d} {spent[kind]:7.2f}")
    print(f"{'figures':32s} {'':5s} {figures:7.2f}")
    print(f"{'the page besides its figures':32s} {'':5s} {cpu - figures:7.2f}")
    print(f"{'in all':32s} {'':5s} {cpu:7.2f}   (wall {wall:.1f} s)")


if __name__ == "__main__":
    main()
