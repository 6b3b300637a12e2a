"""Adaptive and external schemes (embedded RK, Taylor, BPL, heyoka, scipy) at their
default tolerance: cost on the Toda lattice, accuracy on Toda and Kepler."""
from ._common import _PairAccuracy, _PairFamily, problem_names, scheme_names

SCHEMES = scheme_names(lambda c: c.kind in ("adaptive", "external"))


class Adaptive(_PairFamily):
    params = [problem_names(("toda",)), SCHEMES]


class AdaptiveAccuracy(_PairAccuracy):
    params = [problem_names(("toda", "kepler")), SCHEMES]
