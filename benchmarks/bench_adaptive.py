"""Adaptive and external schemes (embedded RK, Taylor, BPL, heyoka, scipy) at their
default tolerance on the Toda lattice: cost and accuracy."""
from ._common import _PairAccuracy, _PairFamily, problem_names, scheme_names

SCHEMES = scheme_names(lambda c: c.kind in ("adaptive", "external"))


class Adaptive(_PairFamily):
    params = [problem_names(("toda",)), SCHEMES]


class AdaptiveAccuracy(_PairAccuracy):
    params = [problem_names(("toda",)), SCHEMES]

    def setup_cache(self):  # a cache per family: asv keys caches by the method's source line
        return self.rows()
