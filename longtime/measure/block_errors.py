"""The solution error per block of the state, each block relative to the size of its own
motion (docs/metrics.md, longtime.measure.metrics): the partition of the state into blocks
(``Blocks``), the reference's motion over the samples (``Motion``) and the errors
(``BlockErrors``).

A row reads the pointwise error at every sample but the running l2_error (the l2_error of
the samples up to each one) only at its error curve's times and at the last sample, so the
running l2_error is evaluated at the samples asked for (``BlockErrors.l2_at``): its
cumulative sums run sample after sample from the first, whichever samples are asked for, so
each value asked for has the same bits as in the whole array.

The passes over every sample are compiled loops (numba), each written by hand where numpy
would make several passes and temporaries of the whole arrays: ``Motion`` centres the states
and takes their five cumulative sums in one pass, and each block's squared size and squared
error are summed per sample in one pass. Each loop adds in numpy's order (a cumulative sum
sample after sample, as np.cumsum; a block's components as np.add.reduceat,
``_block_squares``), so every value has the bits numpy's arrays would hold.
"""
from __future__ import annotations

import math
from typing import Any

import numba
import numpy as np

# a motion smaller than this fraction of the state's size is rounding: nothing moves
STILL = 1e-8


@numba.njit(cache=True)
def _running_sums(t, x, centre, t_mean, x_mean, t_out, x_out, rows, slots, st, stt, sx, sxx, stx):
    """The cumulative sums of t, t^2, x, x^2 and t x over the samples (x: samples x
    components) up to each of ``rows`` (ascending), written to row ``slots[k]`` of the
    outputs for ``rows[k]``. With ``centre`` each sample is first centred on ``t_mean``,
    ``x_mean`` (as numpy subtracts) and written to ``t_out``, ``x_out``. As np.cumsum adds:
    the first sample as it is, then sample after sample, so the same bits. One pass instead
    of numpy's centring, five cumulative sums and their temporaries."""
    d = x.shape[1]
    a_x, a_xx, a_tx = np.empty(d), np.empty(d), np.empty(d)
    a_t = a_tt = 0.0
    k = 0
    for i in range(rows[-1] + 1 if rows.size else 0):
        ti = t[i]
        if centre:
            ti -= t_mean
            t_out[i] = ti
        a_t = ti if i == 0 else a_t + ti
        a_tt = ti * ti if i == 0 else a_tt + ti * ti
        for j in range(d):
            v = x[i, j]
            if centre:
                v -= x_mean[j]
                x_out[i, j] = v
            if i == 0:
                a_x[j], a_xx[j], a_tx[j] = v, v * v, ti * v
            else:
                a_x[j] += v
                a_xx[j] += v * v
                a_tx[j] += ti * v
        while k < rows.size and rows[k] == i:
            s = slots[k]
            st[s], stt[s] = a_t, a_tt
            sx[s], sxx[s], stx[s] = a_x, a_xx, a_tx
            k += 1


@numba.njit(cache=True)
def _pairwise_sum(a, lo, n):
    """numpy's pairwise sum of a[lo:lo + n], the order of its add reductions: one
    accumulator below 8 terms, eight up to 128, two halves (at a multiple of 8) above."""
    if n < 8:
        res = 0.0
        for i in range(lo, lo + n):
            res += a[i]
        return res
    if n <= 128:
        r0, r1, r2, r3 = a[lo], a[lo + 1], a[lo + 2], a[lo + 3]
        r4, r5, r6, r7 = a[lo + 4], a[lo + 5], a[lo + 6], a[lo + 7]
        i = 8
        while i < n - n % 8:
            r0 += a[lo + i]
            r1 += a[lo + i + 1]
            r2 += a[lo + i + 2]
            r3 += a[lo + i + 3]
            r4 += a[lo + i + 4]
            r5 += a[lo + i + 5]
            r6 += a[lo + i + 6]
            r7 += a[lo + i + 7]
            i += 8
        res = ((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7))
        while i < n:
            res += a[lo + i]
            i += 1
        return res
    half = n // 2
    half -= half % 8
    return _pairwise_sum(a, lo, half) + _pairwise_sum(a, lo + half, n - half)


@numba.njit(cache=True)
def _block_squares(reference, U, order, starts, ends, size, diff):
    """Per sample i and block b (components ``order[starts[b]:ends[b]]``): ``diff[i, b]``,
    the block's sum of (u - u_ref)^2, and ``size[i, b]``, the cumulative sum over the
    samples up to i of the block's sum of u_ref^2. Squared as numpy's ``**2``, summed over
    the samples as np.cumsum and over a block as np.add.reduceat (its first term plus
    numpy's pairwise sum of the others): the same bits. One pass over the states instead of
    numpy's squares, gathers, reductions and cumulative sum."""
    d = reference.shape[1]
    ref2, diff2 = np.empty(d), np.empty(d)  # one sample's squares, block by block
    for i in range(reference.shape[0]):
        for c in range(d):
            j = order[c]
            r = reference[i, j]
            e = U[i, j] - r
            ref2[c] = r * r
            diff2[c] = e * e
        for b in range(starts.size):
            first, lo, hi = starts[b], starts[b] + 1, ends[b]
            if hi - lo < 8:  # the pairwise sum's one accumulator, inline: no call in the loop
                rest_r = rest_d = 0.0
                for c in range(lo, hi):
                    rest_r += ref2[c]
                    rest_d += diff2[c]
            else:
                rest_r, rest_d = _pairwise_sum(ref2, lo, hi - lo), _pairwise_sum(diff2, lo, hi - lo)
            s_r = ref2[first] if hi == lo else ref2[first] + rest_r
            size[i, b] = s_r if i == 0 else size[i - 1, b] + s_r
            diff[i, b] = diff2[first] if hi == lo else diff2[first] + rest_d


@numba.njit(cache=True)
def _cumsum_at(a, rows, slots, out):
    """The cumulative sums over the rows of ``a`` (samples x columns) up to each of ``rows``
    (ascending), written to row ``slots[k]`` of ``out`` for ``rows[k]``: np.cumsum(a,
    axis=0)[rows], the same bits (the first row as it is, then row after row), read in one
    pass without the whole array of sums."""
    acc = np.empty(a.shape[1])
    k = 0
    for i in range(rows[-1] + 1 if rows.size else 0):
        for j in range(a.shape[1]):
            acc[j] = a[i, j] if i == 0 else acc[j] + a[i, j]
        while k < rows.size and rows[k] == i:
            out[slots[k]] = acc
            k += 1


@numba.njit(cache=True, error_model="numpy")
def _relative(diff, scales, pointwise, peak):
    """pointwise[i, b] = sqrt(diff[i, b]) / scales[b] (numpy's sqrt and division: the same
    bits) and peak[i] its largest over the blocks (np.max: NaN where one is NaN). One pass
    instead of numpy's three (its max over the few blocks reduces sample by sample)."""
    for i in range(diff.shape[0]):
        m = 0.0
        for b in range(diff.shape[1]):
            v = math.sqrt(diff[i, b]) / scales[b]
            pointwise[i, b] = v
            if b == 0 or (m == m and (v > m or v != v)):  # the first, a larger one or a NaN, which stays
                m = v
        peak[i] = m


def _indices(rows: Any, size: int) -> np.ndarray:
    """The samples ``rows`` (an index array, a boolean mask or a slice of ``size`` samples)
    as indices from 0, for the passes above."""
    rows = np.arange(size)[rows] if isinstance(rows, slice) else np.asarray(rows)
    if rows.dtype == bool:
        rows = np.flatnonzero(rows)
    rows = np.where(rows < 0, rows + size, rows).astype(np.int64)
    if rows.size and not (rows.min() >= 0 and rows.max() < size):
        raise IndexError(f"samples {rows.min()}..{rows.max()} out of {size}")
    return rows


def _ascending(rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(rows ascending, slots): for a pass over the samples, ``rows`` sorted and where each
    of them goes in the output (its place in ``rows``)."""
    slots = np.argsort(rows, kind="stable")
    return rows[slots], slots


def _residuals(n: np.ndarray, st: np.ndarray, stt: np.ndarray, sx: np.ndarray, sxx: np.ndarray,
               stx: np.ndarray) -> np.ndarray:
    """The squared residuals about the least-squares lines from the cumulative sums of ``n``
    samples (the mean and the drift taken out), per component, never below 0."""
    ctt = stt - st**2 / n
    cxx = sxx - sx**2 / n[:, None]
    ctx = stx - st[:, None] * sx / n[:, None]
    with np.errstate(divide="ignore", invalid="ignore"):
        trend = np.where(ctt[:, None] > 0, ctx**2 / ctt[:, None], 0.0)
    return np.maximum(cxx - trend, 0.0)


class Motion:
    """The motion of ``states`` (samples x components) at times ``t`` about each component's
    least-squares line in t: at the samples asked for (``at``) the sum of the squared
    residuals of the samples up to each one (the mean and the drift taken out), from the
    cumulative sums of the centred times and states. ``t`` and ``x`` keep the times and the
    states centred on their means (centred first: the cumulative sums keep their digits)."""

    def __init__(self, t: np.ndarray, states: np.ndarray) -> None:
        t = np.ascontiguousarray(t, dtype=float)
        x = np.ascontiguousarray(states, dtype=float)
        self.n = np.arange(1, t.size + 1, dtype=float)
        self.t, self.x = np.empty_like(t), np.empty_like(x)
        # one pass centres the samples into t and x and keeps the sums at the last one
        self._last = self._sums(np.arange(t.size)[-1:], (t, x, t.mean(), x.mean(axis=0)))

    def _sums(self, rows: np.ndarray, centre: tuple | None = None) -> tuple[np.ndarray, ...]:
        """(st, stt, sx, sxx, stx) at the samples ``rows`` (indices in any order) of the
        centred samples; with ``centre`` (t, x, their means), of those samples, which the
        pass centres into ``self.t``, ``self.x``."""
        m, d = rows.size, self.x.shape[1]
        st, stt = np.empty(m), np.empty(m)
        sx, sxx, stx = np.empty((m, d)), np.empty((m, d)), np.empty((m, d))
        t, x, t_mean, x_mean = centre or (self.t, self.x, 0.0, np.zeros(d))
        _running_sums(t, x, centre is not None, float(t_mean), x_mean, self.t, self.x, *_ascending(rows),
                      st, stt, sx, sxx, stx)
        return st, stt, sx, sxx, stx

    def at(self, rows: Any = slice(None)) -> np.ndarray:
        """The detrended squared residuals per component at the samples ``rows`` (an index
        array, or a slice), (len(rows), components)."""
        rows = _indices(rows, self.n.size)
        return _residuals(self.n[rows], *self._sums(rows))

    def last(self) -> np.ndarray:
        """``at`` the last sample alone, (1, components)."""
        if not self.n.size:
            raise IndexError("no samples")
        return _residuals(self.n[-1:], *self._last)

    def sum_of_squares(self) -> np.ndarray:
        """Per component, the sum over the samples of the centred states squared (added
        sample after sample)."""
        if not self.n.size:
            raise IndexError("no samples")
        return self._last[3][0]


def detrended_components(t: np.ndarray, states: np.ndarray) -> np.ndarray:
    """``detrended_ss`` per component (samples x components), before the sum."""
    return Motion(t, states).at()


def detrended_ss(t: np.ndarray, states: np.ndarray) -> np.ndarray:
    """The motion of ``states`` (samples x components) at times ``t``: at each sample k, the
    sum over components of the squared residuals of the samples up to k about each
    component's least-squares line in t (its mean and its drift taken out)."""
    return detrended_components(t, states).sum(axis=1)


class Blocks:
    """A partition of the state's components into named blocks (``Problem.blocks``), and
    per-block sums of per-component arrays. ``Blocks.whole(dim)``: one block."""

    def __init__(self, blocks: dict[str, Any], dim: int) -> None:
        self.names = list(blocks)
        groups = [np.asarray(list(v), dtype=np.int64).reshape(-1) for v in blocks.values()]
        seen = np.concatenate(groups) if groups else np.empty(0, dtype=np.int64)
        if not groups or any(g.size == 0 for g in groups) or seen.size != dim \
                or not np.array_equal(np.sort(seen), np.arange(dim)):
            raise ValueError(f"blocks {dict(zip(self.names, (g.tolist() for g in groups)))} are not a partition of "
                             f"the state's {dim} components (each in exactly one non-empty block)")
        self.order = seen  # the components, block by block
        self.starts = np.cumsum([0] + [g.size for g in groups[:-1]])
        self.ends = np.append(self.starts[1:], dim)
        # the components already in block order: the sums read them where they are
        self.in_order = bool(np.array_equal(seen, np.arange(dim)))

    @classmethod
    def whole(cls, dim: int) -> "Blocks":
        return cls({"u": range(dim)}, dim)

    @classmethod
    def of(cls, problem) -> "Blocks":
        return cls(problem.blocks(), problem.dim)

    def __len__(self) -> int:
        return len(self.names)

    @property
    def shape(self) -> tuple[bytes, bytes]:
        """What the sums depend on (the components' order and the blocks' starts): two
        partitions of the same shape sum alike, whatever their names."""
        return self.order.tobytes(), self.starts.tobytes()

    def sum(self, x: np.ndarray) -> np.ndarray:
        """Per-block sums over the last axis of ``x`` (..., components) -> (..., blocks)."""
        x = np.asarray(x, dtype=float)
        return np.add.reduceat(x if self.in_order else x[..., self.order], self.starts, axis=-1)

    def squares(self, reference: np.ndarray, U: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(size, diff), (samples, blocks): ``size``, the cumulative sum over the samples of
        each block's sum of u_ref^2, and ``diff``, each block's sum of (u - u_ref)^2 at each
        sample: np.cumsum(self.sum(reference**2), axis=0) and self.sum((U - reference)**2),
        bit for bit, in one pass (``_block_squares``)."""
        reference = np.ascontiguousarray(reference, dtype=float)
        U = np.asarray(U, dtype=float)
        if U.shape != reference.shape:  # numpy's broadcasting of U against the reference
            U = np.broadcast_to(U, reference.shape).copy()
        U = np.ascontiguousarray(U)
        size, diff = np.empty((reference.shape[0], len(self))), np.empty((reference.shape[0], len(self)))
        _block_squares(reference, U, self.order, self.starts, self.ends, size, diff)
        return size, diff


class BlockErrors:
    """The solution error of states ``U`` against ``reference`` at times ``t`` per block of
    the state (``Blocks``; default one, the whole state), each relative to its own motion:

    - ``scales`` (blocks,): S_b, ``motion_scale`` of the block's reference;
    - ``pointwise`` (samples, blocks): |u_b - u_ref,b| / S_b;
    - ``l2`` (samples, blocks): at each sample the l2_error of the samples up to it,
      sqrt(sum |u_b - u_ref,b|^2 / the block's motion over those samples); at the last one
      sqrt(mean |u_b - u_ref,b|^2) / S_b, the whole run's (``l2_at`` some samples only).

    A block that does not move (a motion below STILL of its size) is measured against its
    size, one whose reference is zero throughout as an absolute error."""

    def __init__(self, names: list[str], scales: np.ndarray, pointwise: np.ndarray,
                 parts: dict[str, Any]) -> None:
        self.names, self.scales, self.pointwise = names, scales, pointwise
        self._parts = parts  # what l2_at and final_l2 read
        self._l2: np.ndarray | None = None
        self._last: np.ndarray | None = None

    @classmethod
    def of(cls, t: np.ndarray, U: np.ndarray, reference: np.ndarray,
           window: tuple[np.ndarray, np.ndarray] | None = None, blocks: Blocks | None = None) -> "BlockErrors":
        return cls.each(t, U, reference, window, [blocks or Blocks.whole(np.shape(reference)[1])])[0]

    @classmethod
    def each(cls, t: np.ndarray, U: np.ndarray, reference: np.ndarray,
             window: tuple[np.ndarray, np.ndarray] | None, partitions: list[Blocks]) -> list["BlockErrors"]:
        """``of`` for each partition of the state, what the partitions share computed once
        (the reference's motion; a partition of the same shape as an earlier one is that one
        under its own names)."""
        reference = np.ascontiguousarray(reference, dtype=float)
        U = np.ascontiguousarray(U, dtype=float)
        motion = Motion(t, reference)
        early = None
        if window is not None and len(window[0]) >= 3 and np.isfinite(window[1]).all():
            early = Motion(*window).last()[0] / len(window[0])
        last = motion.last()
        done: dict[tuple, BlockErrors] = {}
        out = []
        for blocks in partitions:  # per-block sums first: arrays of (samples, blocks) from here
            same = done.get(blocks.shape)
            if same is not None:
                out.append(cls(blocks.names, same.scales, same.pointwise, same._parts))
                continue
            samples = len(t)
            variance = blocks.sum(last)[0] / samples
            floor = None if early is None else blocks.sum(early)
            if floor is not None:
                variance = np.maximum(variance, floor)
            size, diff = blocks.squares(reference, U)  # size: nothing moved yet, the block's size
            still = ~(variance > STILL**2 * size[-1] / samples)  # a motion below its rounding: nothing moves
            variance = np.where(still, size[-1] / samples, variance)
            scales = np.where(variance > 0, np.sqrt(variance), 1.0)
            pointwise, peak = np.empty_like(diff), np.empty(samples)
            _relative(diff, scales, pointwise, peak)
            parts = {"blocks": blocks, "motion": motion, "floor": floor, "size": size, "diff": diff,
                     "reference": reference, "samples": samples, "peak": peak}
            done[blocks.shape] = errors = cls(blocks.names, scales, pointwise, parts)
            out.append(errors)
        return out

    def l2_at(self, rows: np.ndarray) -> np.ndarray:
        """``l2`` at the samples ``rows`` (indices), (len(rows), blocks)."""
        p = self._parts
        rows = np.asarray(rows, dtype=np.int64)
        n = p["motion"].n[rows][:, None]
        motion = p["blocks"].sum(p["motion"].at(rows))
        if p["floor"] is not None:
            motion = np.maximum(motion, n * p["floor"])
        cumulative = np.empty((rows.size, len(p["blocks"])))
        _cumsum_at(p["diff"], *_ascending(_indices(rows, p["samples"])), cumulative)
        size = p["size"][rows]
        motion = np.where(motion > STILL**2 * size, motion, np.where(size > 0, size, n))
        l2 = np.sqrt(cumulative / motion)
        l2[rows == p["samples"] - 1] = self.final_l2()  # the whole run's, with its motion scale
        return l2

    def final_l2(self, U: np.ndarray | None = None) -> np.ndarray:
        """The whole run's l2_error per block, sqrt(mean |u_b - u_ref,b|^2) / S_b: of these
        states, or of other states ``U`` against the same reference and scales."""
        p = self._parts
        if U is None:
            if self._last is None:
                self._last = np.sqrt(p["diff"].sum(axis=0) / p["samples"]) / self.scales
            return self._last
        diff = p["blocks"].squares(p["reference"], U)[1]
        return np.sqrt(diff.sum(axis=0) / p["samples"]) / self.scales

    @property
    def motion(self) -> Motion:
        """The reference's motion the scales come from."""
        return self._parts["motion"]

    @property
    def l2(self) -> np.ndarray:
        if self._l2 is None:
            self._l2 = self.l2_at(np.arange(self._parts["samples"]))
        return self._l2

    @property
    def peak(self) -> np.ndarray:
        """The largest block's pointwise error at each sample, pointwise.max(axis=1)."""
        return self._parts["peak"]

    @property
    def largest(self) -> tuple[np.ndarray, np.ndarray]:
        """(e, l2) of the largest block at each sample: the solution error."""
        return self.peak, self.l2.max(axis=1)

    @property
    def worst(self) -> str:
        """The name of the block with the largest l2_error over the run."""
        last = self.final_l2()
        return self.names[int(np.argmax(np.where(np.isfinite(last), last, np.inf)))]
