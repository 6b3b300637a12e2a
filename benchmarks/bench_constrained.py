"""Constrained mechanics: the schemes that need constraints (Dirac, RATTLE) and the naive
unconstrained baselines (explicit Euler, RK4 on the index-1 ODE) on the double pendulum."""
from ._common import _PairAccuracy, _PairFamily, needs, problem_names, scheme_names

PROBLEMS = problem_names(("double-pendulum",))
SCHEMES = scheme_names(lambda c: "constraints" in needs(c) or c.name in ("euler", "rk4"))


class Constrained(_PairFamily):
    params = [PROBLEMS, SCHEMES]


class ConstrainedAccuracy(_PairAccuracy):
    params = [PROBLEMS, SCHEMES]

    def setup_cache(self):  # a cache per family: asv keys caches by the method's source line
        return self.rows()

    def track_constraint_violation(self, rows, problem, scheme):
        """max |phi| over the benchmark run."""
        from ._common import tracked

        return tracked(rows, problem, scheme, "constraint.max")

    track_constraint_violation.unit = "length^2"
