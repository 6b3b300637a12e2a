"""Burrau's Pythagorean three-body problem: masses 3, 4 and 5 start at rest at the vertices
of a right triangle with sides 3, 4 and 5, each opposite the side of its own length, G = 1
(Burrau 1913; Szebehely and Peters 1967 followed it to the escape):

    m = (3, 4, 5),   q1 = (1, 3),   q2 = (-2, -1),   q3 = (1, -1),   p = 0.

The bodies pass through close encounters (the closest, a pair distance of 4.1e-4 at
t = 15.83), then the lightest body escapes and the other two leave the other way as a
binary: by t = 70 the motion is a regular escape. A subclass of the n-body family
(``longtime.problems.nbody.NBody``): invariants H, L and P; diagnostic: the minimum pair
distance ``r_min`` (its curve shows every close encounter).
"""
from __future__ import annotations

import numpy as np

from longtime.problems.nbody import NBody


class PythagoreanThreeBody(NBody):
    name = "pythagorean-three-body"
    summary = "Burrau's three bodies (masses 3, 4, 5 at rest on a 3-4-5 triangle): close encounters, escape"
    check_class = "close encounters"
    default_t_final = 70.0
    # no fixed step resolves the closest encounters (r = 4e-4 passed at speed ~ 300), so no
    # fixed step is in the asymptotic range and a sweep of steps would fit no order: one
    # step shows what each fixed-step scheme makes of them (MERCURIUS, which hands every
    # encounter to IAS15, is the costly cell)
    default_dt = 1e-3
    sweep_dt = (1e-3,)
    sweep_t_final = 70.0

    def masses(self):
        return np.array([3.0, 4.0, 5.0])

    def initial_state(self):
        return [1.0, 3.0, -2.0, -1.0, 1.0, -1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]

    def diagnostics(self, t, U):
        _, q, _ = self.split_state(U)
        d = [np.hypot(*(q[:, k] - q[:, l]).T) for k, l in ((0, 1), (0, 2), (1, 2))]
        return {"r_min": np.minimum(np.minimum(d[0], d[1]), d[2])}
