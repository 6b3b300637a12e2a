"""Three schemes, one per way of writing one: a tableau family, a splitting family, and a
compiled step written out by hand."""
import numba
import numpy as np

from longtime import FixedStepIntegrator
from longtime.core.drivers import OK, RHS_EVALS
from longtime.integrators import ExplicitRungeKutta, Splitting, compose


class Heun(ExplicitRungeKutta):
    """A Butcher tableau is all an explicit Runge-Kutta scheme needs (checked on definition)."""
    name = "example-heun"
    summary = "Heun's method (order 2) from the example plugin"
    order = 2
    A = np.array([[0.0, 0.0], [1.0, 0.0]])
    b = np.array([0.5, 0.5])
    c = np.array([0.0, 1.0])


_G = 1.0 / (2.0 - 2.0 ** (1.0 / 3.0))


class ForestRuth(Splitting):
    """Forest-Ruth: three Verlet steps of sizes g h, (1 - 2g) h, g h (order 4, symplectic);
    a splitting needs a problem with the separable capability (the family says so)."""
    name = "example-forest-ruth"
    summary = "Forest-Ruth splitting (order 4, symplectic) from the example plugin"
    order = 4
    kicks, drifts = compose([_G, 1.0 - 2.0 * _G, _G])


class ExplicitMidpoint(FixedStepIntegrator):
    """The low-level way: build a compiled step; the shared driver runs the loop."""
    name = "example-midpoint"
    summary = "explicit midpoint rule (order 2), a hand-written step, from the example plugin"
    order = 2

    def work_shape(self, problem):
        return (2, problem.dim)  # scratch handed to every step: a slope and a stage state

    def make_step(self, problem):
        rhs = problem.rhs  # the step closes over the problem's compiled functions

        @numba.njit
        def step(t, u, h, params, work, counters, first):
            k, y = work[0], work[1]
            rhs(t, u, params, k)
            for i in range(u.size):
                y[i] = u[i] + 0.5 * h * k[i]
            rhs(t + 0.5 * h, y, params, k)
            for i in range(u.size):
                u[i] += h * k[i]  # advance u in place
            counters[RHS_EVALS] += 2
            return OK  # or FAILED (a solve that did not converge); the driver tests blow-up

        return step
