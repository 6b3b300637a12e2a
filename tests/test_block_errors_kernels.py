"""The compiled passes of the solution error per block (longtime.measure.block_errors) give the
bits of the plain numpy formulation they replace: the motion's centring and cumulative sums,
the blocks' squared sizes and errors (np.add.reduceat's order, also past 128 components),
the pointwise errors and their largest block, the running l2_error at samples in any order."""
from __future__ import annotations

import numpy as np
import pytest

from longtime.measure.block_errors import STILL, BlockErrors, Blocks, Motion
from longtime.measure.metrics import drifting_components


def _numpy_motion(t, x):
    """(centred t, centred x, residuals at every sample): the numpy formulation."""
    t = t - t.mean()
    x = x - x.mean(axis=0)
    n = np.arange(1, t.size + 1, dtype=float)
    st, stt = np.cumsum(t), np.cumsum(t * t)
    sx, sxx, stx = np.cumsum(x, axis=0), np.cumsum(x * x, axis=0), np.cumsum(t[:, None] * x, axis=0)
    ctt = stt - st**2 / n
    cxx = sxx - sx**2 / n[:, None]
    ctx = stx - st[:, None] * sx / n[:, None]
    with np.errstate(divide="ignore", invalid="ignore"):
        trend = np.where(ctt[:, None] > 0, ctx**2 / ctt[:, None], 0.0)
    return t, x, np.maximum(cxx - trend, 0.0)


def _numpy_errors(t, U, ref, window, blocks):
    """(scales, pointwise, l2 at every sample, final l2) of BlockErrors, in numpy."""
    def bsum(a):
        return np.add.reduceat(a[..., blocks.order], blocks.starts, axis=-1)

    samples = len(t)
    resid = _numpy_motion(t, ref)[2]
    n = np.arange(1, samples + 1, dtype=float)[:, None]
    floor = bsum(_numpy_motion(*window)[2][-1] / len(window[0]))
    variance = np.maximum(bsum(resid[-1]) / samples, floor)
    size = np.cumsum(bsum(ref**2), axis=0)
    still = ~(variance > STILL**2 * size[-1] / samples)
    variance = np.where(still, size[-1] / samples, variance)
    scales = np.where(variance > 0, np.sqrt(variance), 1.0)
    diff = bsum((U - ref) ** 2)
    motion = np.maximum(bsum(resid), n * floor)
    motion = np.where(motion > STILL**2 * size, motion, np.where(size > 0, size, n))
    l2 = np.sqrt(np.cumsum(diff, axis=0) / motion)
    final = np.sqrt(diff.sum(axis=0) / samples) / scales
    l2[-1] = final
    return scales, np.sqrt(diff) / scales, l2, final


def _states(rng, samples, dim):
    t = np.sort(rng.uniform(0.0, 50.0, samples))
    scale = 10.0 ** rng.uniform(-4, 4, dim)
    ref = np.cos(np.outer(t, rng.uniform(0.1, 3.0, dim)) + rng.uniform(0, 6, dim)) * scale + 0.3 * t[:, None]
    U = ref + 1e-5 * scale * rng.standard_normal(ref.shape).cumsum(axis=0)
    return t, U, ref


@pytest.mark.parametrize("dim", [1, 2, 5, 12, 130, 300])
def test_motion_pass_has_the_bits_of_numpy(dim):
    rng = np.random.default_rng(dim)
    t, _, ref = _states(rng, 700, dim)
    motion = Motion(t, ref)
    t_c, x_c, resid = _numpy_motion(t, ref)
    assert np.array_equal(motion.t, t_c) and np.array_equal(motion.x, x_c)
    assert np.array_equal(motion.at(), resid)
    assert np.array_equal(motion.last(), resid[-1:])
    rows = np.array([699, 3, 3, 0, 450, 698, 17])  # out of order, repeated, both ends
    assert np.array_equal(motion.at(rows), resid[rows])
    assert np.array_equal(motion.at(slice(10, 20)), resid[10:20])
    assert np.array_equal(motion.sum_of_squares(), np.cumsum(x_c * x_c, axis=0)[-1])
    with pytest.raises(IndexError):
        motion.at(np.array([700]))


@pytest.mark.parametrize("dim", [3, 9, 10, 17, 129, 130, 140, 300])
def test_block_squares_add_in_reduceats_order(dim):
    """The whole state (pairwise past 8 and past 128 terms), blocks out of order of every
    size, and one component each."""
    rng = np.random.default_rng(dim)
    _, U, ref = _states(rng, 300, dim)
    perm = rng.permutation(dim)
    cuts = np.sort(rng.choice(np.arange(1, dim), size=min(dim - 1, 4), replace=False))
    shuffled = Blocks({f"g{i}": g for i, g in enumerate(np.split(perm, cuts))}, dim)
    assert not shuffled.in_order
    for blocks in (Blocks.whole(dim), shuffled, Blocks({f"c{i}": [i] for i in range(dim)}, dim)):
        size, diff = blocks.squares(ref, U)
        assert np.array_equal(size, np.cumsum(blocks.sum(ref**2), axis=0))
        assert np.array_equal(diff, blocks.sum((U - ref) ** 2))


def test_block_errors_have_the_bits_of_numpy():
    """Blocks out of order, a block that stands still and one that is zero throughout, with
    a window; each partition against the numpy formulation."""
    rng = np.random.default_rng(7)
    t, U, ref = _states(rng, 1500, 7)
    ref[:, 4] = 2.5  # still: measured against its size
    ref[:, 6] = 0.0  # zero: an absolute error
    window = (np.logspace(-3, 0, 101) * 0.5, ref[:101] * 1.01)
    blocks = Blocks({"q": [5, 0, 2], "still": [4], "p": [1, 3], "zero": [6]}, 7)
    whole = Blocks.whole(7)
    per_block, state = BlockErrors.each(t, U, ref, window, [blocks, whole])
    for errors, partition in ((per_block, blocks), (state, whole)):
        scales, pointwise, l2, final = _numpy_errors(t, U, ref, window, partition)
        assert np.array_equal(errors.scales, scales)
        assert np.array_equal(errors.pointwise, pointwise)
        assert np.array_equal(errors.peak, pointwise.max(axis=1))
        assert np.array_equal(errors.final_l2(), final)
        assert np.array_equal(errors.l2, l2)
        rows = np.array([1499, 0, 700, 700, 3])
        assert np.array_equal(BlockErrors.each(t, U, ref, window, [partition])[0].l2_at(rows), l2[rows])
    other = U * (1 + 1e-6)
    assert np.array_equal(per_block.final_l2(other), _numpy_errors(t, other, ref, window, blocks)[3])


def test_the_largest_block_is_nan_where_a_block_is():
    t = np.linspace(0.0, 1.0, 50)
    ref = np.column_stack([np.cos(t), np.sin(t), t])
    U = ref + 1e-3
    U[10, 1] = np.inf  # inf - finite: an infinite error; with a scale of inf a NaN
    errors = BlockErrors.of(t, U, ref, blocks=Blocks({f"c{i}": [i] for i in range(3)}, 3))
    assert np.array_equal(errors.peak, errors.pointwise.max(axis=1), equal_nan=True)
    errors.pointwise[:] = np.nan  # the stored peak is not recomputed from it
    assert np.isinf(errors.peak[10]) and np.isfinite(errors.peak[:10]).all()


@pytest.mark.parametrize("dim", [1, 2, 6])
def test_drifting_components_read_from_the_motion_as_from_numpy(dim):
    rng = np.random.default_rng(dim)
    t, _, ref = _states(rng, 2000, dim)
    motion = Motion(t, ref)
    y = ref - ref.mean(axis=0)
    assert np.array_equal(motion.sum_of_squares(), (y**2).sum(axis=0)) or dim == 1  # numpy's pairwise
    assert drifting_components(t, ref, motion) == drifting_components(t, ref)
