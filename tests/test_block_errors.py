"""The solution error per block of the state (docs/metrics.md, "Solution error"): a body lost
among others that move more is lost, whatever the whole state's norm says."""
from __future__ import annotations

import numpy as np
import pytest

from longtime.core import registry
from longtime.core.trajectory import Trajectory
from longtime.measure.block_errors import BlockErrors, Blocks
from longtime.measure.metrics import evaluate, solution_errors, solution_lost

# the outer solar system's bodies on circular orbits of their mean radii (AU) about the Sun,
# G M = 2.959e-4 AU^3/day^2 (a synthetic reference: the per-block error reads its shape)
RADII = (5.2, 9.55, 19.2, 30.1, 39.5)
GM = 2.95912208286e-4


def _solar_system(t: np.ndarray, jupiter_shift: float = 0.0) -> np.ndarray:
    """States (samples, 36) in outer-solar-system's layout: q (6 bodies x 3), then p = m v;
    Jupiter ``jupiter_shift`` radians along its orbit from where it is."""
    p = registry.problem_class("outer-solar-system")()
    m = p.masses()
    q = np.zeros((t.size, 6, 3))
    v = np.zeros((t.size, 6, 3))
    for k, r in enumerate(RADII, start=1):
        w = np.sqrt(GM / r**3)
        phase = w * t + k + (jupiter_shift if k == 1 else 0.0)
        q[:, k, 0], q[:, k, 1] = r * np.cos(phase), r * np.sin(phase)
        v[:, k, 0], v[:, k, 1] = -r * w * np.sin(phase), r * w * np.cos(phase)
    q[:, 0] = -np.einsum("k,tkd->td", m[1:], q[:, 1:]) / m[0]  # the Sun balances the planets
    v[:, 0] = -np.einsum("k,tkd->td", m[1:], v[:, 1:]) / m[0]
    return np.hstack([q.reshape(t.size, -1), (m[None, :, None] * v).reshape(t.size, -1)])


def _row(problem_name: str, t: np.ndarray, U: np.ndarray, ref: np.ndarray) -> dict:
    p = registry.problem_class(problem_name)()
    traj = Trajectory("ok", "", t, U, 0.0, 0.0, {"steps": t.size - 1})
    return evaluate(p, traj, ref)


def test_jupiter_half_an_orbit_off_is_lost_though_the_whole_state_hides_it():
    t = np.linspace(0.0, 1e6, 4001)
    ref = _solar_system(t)
    row = _row("outer-solar-system", t, _solar_system(t, np.pi), ref)
    assert row["l2_error"] >= 0.5 and row["final_error"] >= 0.5  # 2 R over R: about 2
    assert row["l2_error"] == pytest.approx(2.0, rel=0.05)
    assert row["error_block"] in ("q Jupiter", "p Jupiter")
    assert row["l2_error_state"] < 0.5 and row["final_error_state"] < 0.5  # 2 R_J over the state's ~53 AU
    assert row["max_error"] >= row["final_error"]
    assert solution_lost(row)[0] is True
    whole = {**row, "l2_error": row["l2_error_state"], "final_error": row["final_error_state"]}
    assert solution_lost(whole)[0] is False


def test_every_momentum_reversed_is_lost():
    """Momenta m v are 1e-5 of the positions in AU and solar masses: against the whole state
    a reversed momentum reads nothing; each body's momentum against its own motion reads 2."""
    t = np.linspace(0.0, 1e6, 4001)
    ref = _solar_system(t)
    U = ref.copy()
    U[:, 18:] *= -1
    row = _row("outer-solar-system", t, U, ref)
    assert row["l2_error"] >= 1.5 and row["error_block"].startswith("p ")
    assert row["l2_error_state"] < 1e-3
    assert solution_lost(row)[0] is True


def test_one_block_is_the_whole_state_figure():
    """rigid-body's blocks are one (the angular momentum): the figures are the whole state's."""
    t = np.linspace(0.0, 50.0, 2001)
    ref = np.column_stack([np.cos(t), np.sin(t), 0.3 + 0.0 * t])
    U = np.column_stack([np.cos(1.01 * t), np.sin(1.01 * t), 0.3 + 1e-3 * t])
    row = _row("rigid-body", t, U, ref)
    assert row["error_block"] == "u"
    assert row["l2_error"] == pytest.approx(row["l2_error_state"], rel=1e-12)
    assert row["final_error"] == pytest.approx(row["final_error_state"], rel=1e-12)
    e, l2, scale = solution_errors(t, U, ref)  # the whole state taken as one block
    assert row["l2_error"] == pytest.approx(l2[-1], rel=1e-12)


def test_default_blocks_are_each_component_against_its_own_motion():
    """lotka-volterra declares no blocks: u and v each a block; the row's error is the larger
    of each component measured alone as a one-component state."""
    p = registry.problem_class("lotka-volterra")()
    assert p.blocks() == {"u[0]": [0], "u[1]": [1]}
    t = np.linspace(0.0, 30.0, 3001)
    ref = np.column_stack([1 + 0.5 * np.cos(t), 2 + 0.01 * np.sin(t)])  # v moves 50 times less
    U = ref + np.column_stack([0.0 * t, 0.005 * np.sin(t)])  # v off by half its motion
    row = _row("lotka-volterra", t, U, ref)
    alone = [solution_errors(t, U[:, [j]], ref[:, [j]])[1][-1] for j in range(2)]
    assert row["l2_error"] == pytest.approx(max(alone), rel=1e-12) and row["error_block"] == "u[1]"
    assert row["l2_error"] == pytest.approx(0.5, rel=0.01)
    assert row["l2_error_state"] < 0.02  # v's error beside u's motion


def test_blocks_of_the_built_in_problems_partition_their_states():
    for name in registry.problems():
        cls = registry.problem_class(name)
        p = cls()
        Blocks.of(p)  # raises unless every component is in exactly one block


def test_blocks_that_are_not_a_partition_are_refused():
    with pytest.raises(ValueError, match="not a partition"):
        Blocks({"a": [0, 1], "b": [1]}, 3)
    with pytest.raises(ValueError, match="not a partition"):
        Blocks({"a": [0], "b": [2]}, 3)


def test_a_block_at_rest_is_measured_against_its_size():
    t = np.linspace(0.0, 10.0, 101)
    ref = np.column_stack([np.cos(t), np.full(t.size, 4.0), np.zeros(t.size)])
    U = ref + 0.1
    err = BlockErrors.of(t, U, ref, blocks=Blocks({"moving": [0], "still": [1], "zero": [2]}, 3))
    assert err.scales[1] == pytest.approx(4.0) and err.scales[2] == 1.0  # its size; zero: absolute
    assert err.pointwise[-1, 1] == pytest.approx(0.1 / 4.0) and err.pointwise[-1, 2] == pytest.approx(0.1)


def test_a_plugin_whose_blocks_miss_a_component_is_refused():
    from longtime.core import contract
    from longtime.core.params import InputError

    class Halves(registry.problem_class("harmonic")):
        name = "halves"

        def blocks(self):
            return {"q": [0]}  # p in no block

    with pytest.raises(InputError, match="blocks"):
        contract.check_problem_outputs(Halves(), 1.0)


def test_keeping_E_up_to_T_reads_the_largest_error_up_to_T():
    """longtime.predict.settings.error_kept: the running maximum of the error envelope up to T
    (never the RMS), the whole run's max_error at or past its end; a store without max_error
    is read by its l2_error, and the verdict names it."""
    from longtime.predict import settings as S

    curve = {"t": [1.0, 10.0, 50.0, 100.0], "error": [1e-7, 3e-6, 2e-6, 4e-6], "l2": [1e-7, 1e-6, 1.2e-6, 1.5e-6]}
    row = {"status": "ok", "problem": "harmonic", "integrator": "rk4", "dt": 0.1, "settings": "", "t_final": 100.0,
           "cpu_s": 1.0, "max_error": 4e-6, "l2_error": 1.5e-6, "error.growth_class": "linear",
           "reference": "exact", "error_curve": curve}
    m = S.measure([row])
    assert m.field == "max_error" and m.solution and "largest error" in m.text
    assert S.error_kept(row, m) == 4e-6 and S.error_kept(row, m, 200.0) == 4e-6
    assert S.error_kept(row, m, 10.0) == 3e-6
    assert S.error_kept(row, m, 50.0) == 3e-6  # the largest up to 50, not the envelope's 2e-6 there
    (s,) = S.settings([row], m)
    assert s.error == 4e-6 and s.error_reached(50.0) == S.error_kept(row, m, 50.0)
    old = {k: v for k, v in row.items() if k != "max_error"}
    m_old = S.measure([old])
    assert m_old.field == "l2_error" and "RMS" in m_old.text
    assert S.error_kept(old, m_old, 50.0) == 1.2e-6


def test_l2_at_some_samples_has_the_bits_of_the_whole_running_l2():
    """A row reads the running l2_error only at its error curve's samples and the last one:
    evaluated there alone, each value is the one the whole array holds, bit for bit, and
    another run's whole l2 against the same reference and scales likewise."""
    rng = np.random.default_rng(3)
    t = np.linspace(0.0, 50.0, 2001)
    ref = np.column_stack([np.cos(t), np.sin(t), 0.1 + 0.2 * t, np.cos(3 * t) * 1e-3])
    U = ref + 1e-6 * rng.standard_normal(ref.shape).cumsum(axis=0)
    window = (np.logspace(-3, 0, 101) * 0.5, ref[:101] + 0.0)
    blocks = Blocks({"q": [0, 2], "p": [1], "r": [3]}, 4)  # out of order: the sums gather
    whole = BlockErrors.of(t, U, ref, window, blocks)
    full = whole.l2.copy()
    rows = np.array([0, 5, 5, 700, 1999, 2000])
    fresh = BlockErrors.of(t, U, ref, window, blocks)  # nothing evaluated at every sample yet
    assert np.array_equal(fresh.l2_at(rows), full[rows])
    other = U + 1e-7
    assert np.array_equal(fresh.final_l2(other), BlockErrors.of(t, other, ref, window, blocks).l2[-1])
    a, b = BlockErrors.each(t, U, ref, window, [Blocks.whole(4), Blocks({"all": range(4)}, 4)])
    assert b.names == ["all"] and np.array_equal(a.l2, b.l2) and np.array_equal(a.pointwise, b.pointwise)
