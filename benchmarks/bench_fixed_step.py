"""Fixed-step schemes on the paper's Hamiltonian problems: cost and accuracy.

Every registered fixed-step scheme that needs neither constraints nor a linear part
(those have families of their own). Timed on the Toda lattice; accuracy tracked on the
Toda lattice and the figure-eight (the two tables of the paper). The hand-written
baselines of the kernels are in bench_kernels.
"""
from ._common import _PairAccuracy, _PairFamily, needs, problem_names, scheme_names

SCHEMES = scheme_names(lambda c: c.kind == "fixed" and not needs(c) & {"constraints", "linear_part"})


class FixedStep(_PairFamily):
    params = [problem_names(("toda",)), SCHEMES]


class FixedStepAccuracy(_PairAccuracy):
    params = [problem_names(("toda", "figure-eight")), SCHEMES]
