"""The paper's figures (Razafindralandy, Salnikov, Hamdouni, Deeb 2019), in one place.

Quoted from the paper (docs/paper.md), measured by its own code on its own machine: they
are printed beside ours by ``longtime match`` and ``longtime reproduce`` and never used in
a computation.
"""
from __future__ import annotations

# Toda, t_f = 5000: mean energy error E_mean and CPU seconds, by (scheme, dt)
TODA_EMEAN = {("rk4", 0.1): 3.7902e-1, ("rk4sym", 0.1): 2.261e-3, ("rk4", 0.0275): 2.4e-3}
TODA_CPU = {("rk4", 0.1): 107.44, ("rk4sym", 0.1): 128.74}
TODA_BPL = {0.125: (2.897e-3, None), 0.0983: (3.010e-4, 259.31)}  # mean step: (E_mean, CPU s)

# Duffing: BPL's mean step, case 1 (eps_res = 1e-4, over [0, 20]) and case 2
DUFFING1_BPL_STEP = 4.7e-4
DUFFING2_BPL_STEP = 0.106
# the forcing amplitudes of the forced Duffing phase portraits
DUFFING_C = (0.20, 0.28, 0.29, 0.37, 0.50, 0.65)

# KdV, d = 128, one period, matched L2 error about 1e-5: (CPU s, mean step, L2 error). The
# paper's RK4 row is its adaptive RK4 (it has a mean step)
KDV = {
    "bpl": (1.74, 0.153, 9.76e-6),
    "etdrk4": (1660.0, 6.41e-4, 1.10e-5),
    "adaptive-rk4": (59.8, 1.88e-3, 1.69e-5),
}
KDV_GROWTH_128_512 = {"bpl": 51.0, "etdrk4": 381.0}  # % CPU growth from d = 128 to 512
# the paper has one BPL: its variants are shown against it
KDV_ROW = {"bpl-exp": "bpl"}
# the schemes of the paper's KdV comparison (and bpl's variant), as run by both commands
KDV_SCHEMES = ("bpl", "bpl-exp", "etdrk4", "adaptive-rk4")


def kdv_row(scheme: str) -> tuple[float, float, float] | None:
    """The paper's (CPU s, mean step, L2 error) shown beside ``scheme`` on KdV at d = 128."""
    return KDV.get(KDV_ROW.get(scheme, scheme))
