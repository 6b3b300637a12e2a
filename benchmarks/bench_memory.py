"""Peak memory of one benchmark run per problem (RK4; the stored samples and the problem's
size dominate, not the scheme)."""
from ._common import _PairMemory, problem_names, scheme_names


class PeakMemory(_PairMemory):
    params = [problem_names(("toda", "kdv")),
              scheme_names(lambda c: c.name == "rk4")]
