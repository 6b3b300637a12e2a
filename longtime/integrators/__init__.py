"""Built-in schemes, and the families a plugin builds on (docs/plugins.md).

Each built-in registers through the ``longtime.integrators`` entry-point group. The
families are exported here, imported on first use (so that loading one scheme does not
import heyoka or scipy's solvers):

    ExplicitRungeKutta    Butcher tableau A, b, c as class attributes (explicit_rk)
    ImplicitRungeKutta    A, b, c of an implicit tableau, fixed-point stages (implicit_rk)
    EmbeddedRungeKutta    A, b, c, error weights e, error_order, fsal (embedded_rk)
    Splitting, compose    kicks / drifts of a separable H; compose(gammas) builds them
                          from Verlet steps of sizes gamma_k h (splitting)
    ConstrainedIntegrator Dirac / RATTLE schemes on constraints (dirac)
    Taylor, AdaptiveTaylor, BorelPadeLaplace   series schemes over ``taylor``
    Trigonometric         filter functions psi, psi0, psi1, phi of h Omega over
                          ``oscillatory`` (trigonometric)
"""
from __future__ import annotations

import importlib

_EXPORTS = {
    "ExplicitRungeKutta": "explicit_rk",
    "ImplicitRungeKutta": "implicit_rk",
    "EmbeddedRungeKutta": "embedded_rk",
    "Splitting": "splitting",
    "compose": "splitting",
    "ConstrainedIntegrator": "dirac",
    "Taylor": "taylor",
    "AdaptiveTaylor": "taylor",
    "BorelPadeLaplace": "bpl",
    "Trigonometric": "trigonometric",
    "check_tableau": "tableau",
    "TableauError": "tableau",
}
__all__ = sorted(_EXPORTS)


def __getattr__(name: str):
    if name in _EXPORTS:
        return getattr(importlib.import_module(f"{__name__}.{_EXPORTS[name]}"), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__():
    return sorted(set(globals()) | set(__all__))
