"""The planar circular restricted three-body problem in the rotating frame (Hairer, Norsett,
Wanner, Solving ODEs I, section II.0, eq. (0.1)): a body of negligible mass moves under two
masses mu' = 1 - mu and mu at (-mu, 0) and (mu', 0), which circle their centre of mass with
angular velocity 1,

    y1'' = y1 + 2 y2' - mu' (y1 + mu) / D1 - mu (y1 - mu') / D2,
    y2'' = y2 - 2 y1' - mu' y2 / D1 - mu y2 / D2,
    D1 = ((y1 + mu)^2 + y2^2)^(3/2),   D2 = ((y1 - mu')^2 + y2^2)^(3/2).

State u = (y1, y2, y1', y2'). Invariant: the Jacobi constant
J = 2 Omega(y) - |y'|^2, Omega = (y1^2 + y2^2)/2 + mu'/r1 + mu/r2 (named ``J``).
Default data: Arenstorf's periodic orbit, mu = 0.012277471, u0 = (0.994, 0, 0,
-2.00158510637908252240537862224), period 17.0652165601579625588917206249 (HNW's digits).
"""
from __future__ import annotations

import math

import numba
import numpy as np

from longtime.core.params import Param
from longtime.core.problem import Problem, qp_blocks

ARENSTORF_MU = 0.012277471
ARENSTORF_STATE = (0.994, 0.0, 0.0, -2.00158510637908252240537862224)
ARENSTORF_PERIOD = 17.0652165601579625588917206249


@numba.njit(cache=True)
def _rhs(t, u, params, out):
    mu = params[0]
    mup = 1.0 - mu
    a = u[0] + mu
    b = u[0] - mup
    y2 = u[1] * u[1]
    r1 = a * a + y2
    r2 = b * b + y2
    d1 = r1 * math.sqrt(r1)
    d2 = r2 * math.sqrt(r2)
    out[0] = u[2]
    out[1] = u[3]
    out[2] = u[0] + 2.0 * u[3] - mup * a / d1 - mu * b / d2
    out[3] = u[1] - 2.0 * u[2] - mup * u[1] / d1 - mu * u[1] / d2


class RestrictedThreeBody(Problem):
    name = "restricted-three-body"
    summary = ("planar circular restricted three-body problem (rotating frame), Arenstorf's periodic orbit; "
               "Jacobi constant J")
    check_class = "unstable orbit"
    parameters = {"mu": Param(ARENSTORF_MU, "mass ratio of the smaller primary", float, minimum=0.0,
                              maximum=0.5, role="physical")}
    period = ARENSTORF_PERIOD
    default_t_final = ARENSTORF_PERIOD
    default_dt = 1e-3
    # fixed steps pass close to the moon: 2e-3 leaves rk4 off the orbit, 5e-4 is asymptotic
    sweep_dt = (1e-3, 5e-4)
    sweep_t_final = ARENSTORF_PERIOD

    rhs = staticmethod(_rhs)

    def blocks(self):
        return qp_blocks(["satellite"], 2)  # its position and velocity in the rotating frame

    def initial_state(self):
        return list(ARENSTORF_STATE)

    def kernel_params(self):
        return np.array([self.settings["mu"]])

    def invariants(self, t, U):
        mu = self.settings["mu"]
        r1 = np.hypot(U[:, 0] + mu, U[:, 1])
        r2 = np.hypot(U[:, 0] - (1 - mu), U[:, 1])
        omega = 0.5 * (U[:, 0] ** 2 + U[:, 1] ** 2) + (1 - mu) / r1 + mu / r2
        return {"J": 2 * omega - (U[:, 2] ** 2 + U[:, 3] ** 2)}

    def heyoka_system(self):
        import heyoka as hy

        y1, y2, v1, v2 = hy.make_vars("y1", "y2", "v1", "v2")
        mu = self.settings["mu"]
        mup = 1.0 - mu
        d1 = ((y1 + mu) ** 2 + y2 * y2) ** 1.5
        d2 = ((y1 - mup) ** 2 + y2 * y2) ** 1.5
        return [y1, y2, v1, v2], [v1, v2,
                                  y1 + 2.0 * v2 - mup * (y1 + mu) / d1 - mu * (y1 - mup) / d2,
                                  y2 - 2.0 * v1 - mup * y2 / d1 - mu * y2 / d2]
