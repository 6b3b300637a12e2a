"""The compiled loop each (scheme, problem) pair runs, found once per pair in a process:
from the loops already built in the process (by the fingerprint of their closure), else from
numba's disk cache through ``jitcache.cacheable``."""
from __future__ import annotations

import weakref
from typing import TYPE_CHECKING, Callable

from longtime.core.jitcache import Unfreezable, cacheable, fingerprint

if TYPE_CHECKING:
    from longtime.core.integrator import Integrator
    from longtime.core.problem import Problem

# compiled loops by the fingerprint of their closure: whatever a make_step closes over (a
# dimension, a tableau, the problem's rhs) is part of the key, so a loop built for one
# setting never runs another, and equal settings share one compilation
LOOPS: dict[str, Callable] = {}
# loops over values that have no fingerprint (an arbitrary object): never shared, one per
# scheme instance (weak key) and problem instance
UNSHARED: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()
# the loop each (scheme instance, problem instance) pair runs, found once: the timed repeats of
# a cell (and the chunks of a run) reuse it without building and fingerprinting the closure
# again (docs/performance.md)
PAIRS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def cached_kernel(integrator: Integrator, problem: Problem, build: Callable[[], Callable]) -> Callable:
    """The jitted function ``build()`` returns (a loop, or a problem's closure rhs that a Python
    loop calls), from numba's disk cache through ``jitcache.cacheable``, found once per
    (scheme, problem) pair: a closure compiled anew in every process costs up to a second."""
    pairs = PAIRS.setdefault(integrator, {})
    found = pairs.get(id(problem))
    if found is not None and found[0] is problem:
        return found[1]
    closure = build()  # cheap: numba compiles on the first call, not here
    try:
        key = fingerprint(closure)
    except Unfreezable:
        own = UNSHARED.setdefault(integrator, {})
        if id(problem) not in own:  # the entry holds the problem, so its id stays its own
            own[id(problem)] = (problem, closure)
        loop = own[id(problem)][1]
    else:
        if key not in LOOPS:
            LOOPS[key] = cacheable(closure)
        loop = LOOPS[key]
    pairs[id(problem)] = (problem, loop)  # the entry holds the problem: its id stays its own
    return loop
