"""heyoka's ``taylor_adaptive`` for a problem: the one place where the reference
(longtime.measure.reference) and the ``heyoka`` scheme build it.

Two choices live here:

- **Compact mode for large systems.** heyoka's default straight-line code compiles in a
  time that grows much faster than the system (docs/performance.md has the figures).
  Above COMPACT_ABOVE state variables the build uses compact mode (heyoka's own advice for
  large systems), and extended precisions always do.
  The reference (tolerance at double's epsilon, Taylor order 19) switches sooner, above
  REFERENCE_COMPACT_ABOVE: its straight-line code is about twice the default tolerance's, and
  a reference is computed once and then read from its cache, so only its compile is paid on
  every new setting. The ``heyoka`` scheme keeps straight-line code up to COMPACT_ABOVE: its
  runs are the timed figures, and compact mode runs about twice as long.
- **A compile that can be interrupted.** LLVM runs in a thread (heyoka releases the GIL
  while it compiles), and the caller's thread waits on it in short slices: Ctrl-C reaches the
  waiting thread at once, and a time limit turns a compile that takes too long into
  ``CompileTimeout`` instead of a hang. A compile given up this way finishes in its daemon
  thread and is dropped.
"""
from __future__ import annotations

import threading
import time
from typing import Any

import numpy as np

from longtime.core import phases
from longtime.core.problem import Problem

COMPACT_ABOVE = 40  # state variables (toda d = 20)
REFERENCE_COMPACT_ABOVE = 24  # state variables, for the high-accuracy reference
_WAIT_SLICE_S = 0.1


class CompileTimeout(RuntimeError):
    """heyoka's compile did not finish within the time given."""


def compact_mode(problem: Problem, fp_type: Any = np.float64, reference: bool = False) -> bool:
    """Whether ``problem``'s integrator in ``fp_type`` is built in compact mode (``reference``:
    the high-accuracy reference's, which switches at REFERENCE_COMPACT_ABOVE)."""
    limit = REFERENCE_COMPACT_ABOVE if reference else COMPACT_ABOVE
    return problem.dim > limit or fp_type is not np.float64


def taylor_adaptive(problem: Problem, state: np.ndarray, timeout_s: float | None = None, **kwargs: Any):
    """heyoka.taylor_adaptive for ``problem``'s heyoka system from ``state`` (keyword
    arguments go to heyoka; ``compact_mode`` defaults to ``compact_mode(problem, fp_type)``).
    Raises CompileTimeout after ``timeout_s`` seconds (None: no limit; 0 or less: at once,
    the caller's deadline having passed); KeyboardInterrupt
    reaches the caller while it waits."""
    if timeout_s is not None and timeout_s <= 0:  # a deadline already past: no compile to give up on
        raise CompileTimeout(f"the time limit was reached before heyoka's compile of {problem.name} (dimension "
                             f"{problem.dim}) began")
    import heyoka as hy

    variables, rhs = problem.heyoka_system()
    kwargs.setdefault("compact_mode", compact_mode(problem, kwargs.get("fp_type", np.float64)))
    built: dict[str, Any] = {}

    def build() -> None:
        try:
            built["ta"] = hy.taylor_adaptive(list(zip(variables, rhs)), state, **kwargs)
        except BaseException as exc:  # handed to the waiting thread
            built["error"] = exc

    worker = threading.Thread(target=build, name=f"heyoka-compile-{problem.name}", daemon=True)
    start = time.perf_counter()
    with phases.compiling():
        worker.start()
        while worker.is_alive():
            worker.join(_WAIT_SLICE_S)
            if worker.is_alive() and timeout_s is not None and time.perf_counter() - start > timeout_s:
                raise CompileTimeout(f"heyoka's compile of {problem.name} (dimension {problem.dim}) took "
                                     f"more than {timeout_s:.3g} s")
    if "error" in built:
        raise built["error"]
    return built["ta"]
