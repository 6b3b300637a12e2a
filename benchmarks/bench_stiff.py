"""The stiff spectral KdV soliton (d = 128): exponential integrators and the paper's
competitors (RK4, adaptive RK4, BPL), plus every scheme that needs a linear part."""
from ._common import _PairAccuracy, _PairFamily, needs, problem_names, scheme_names

PROBLEMS = problem_names(("kdv",))
SCHEMES = scheme_names(lambda c: "linear_part" in needs(c) or c.name in ("rk4", "adaptive-rk4", "bpl"))


class Stiff(_PairFamily):
    params = [PROBLEMS, SCHEMES]


class StiffAccuracy(_PairAccuracy):
    params = [PROBLEMS, SCHEMES]

    def setup_cache(self):  # a cache per family: asv keys caches by the method's source line
        return self.rows()
