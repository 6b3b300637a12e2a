"""Fixed-step schemes on the paper's Hamiltonian problems: cost and accuracy.

Every registered fixed-step scheme that needs neither constraints nor a linear part
(those have families of their own), on the Toda lattice (the paper's table; one problem
keeps `asv run --quick` within a few minutes: every pair costs a kernel compilation per
benchmark). The hand-written baselines of the kernels are in bench_kernels.
"""
from ._common import _PairAccuracy, _PairFamily, needs, problem_names, scheme_names

SCHEMES = scheme_names(lambda c: c.kind == "fixed" and not needs(c) & {"constraints", "linear_part"})


class FixedStep(_PairFamily):
    params = [problem_names(("toda",)), SCHEMES]


class FixedStepAccuracy(_PairAccuracy):
    params = [problem_names(("toda",)), SCHEMES]

    def setup_cache(self):  # a cache per family: asv keys caches by the method's source line
        return self.rows()
