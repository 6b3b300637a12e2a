"""The solution error per block of the state, each block relative to the size of its own
motion (docs/metrics.md, longtime.measure.metrics): the partition of the state into blocks
(``Blocks``), the reference's motion over the samples (``Motion``) and the errors
(``BlockErrors``).

A row reads the pointwise error at every sample but the running l2_error (the l2_error of
the samples up to each one) only at its error curve's times and at the last sample, so the
running l2_error is evaluated at the samples asked for (``BlockErrors.l2_at``): its
cumulative sums run over every sample as before, so each value asked for has the same bits
as in the whole array.
"""
from __future__ import annotations

from typing import Any

import numpy as np

# a motion smaller than this fraction of the state's size is rounding: nothing moves
STILL = 1e-8


class Motion:
    """The motion of ``states`` (samples x components) at times ``t`` about each component's
    least-squares line in t: the cumulative sums behind it, and at the samples asked for
    (``at``) the sum of the squared residuals of the samples up to each one (the mean and
    the drift taken out). ``t`` and ``x`` keep the times and the states centred on their
    means."""

    def __init__(self, t: np.ndarray, states: np.ndarray) -> None:
        t = np.asarray(t, dtype=float)
        x = np.asarray(states, dtype=float)
        self.t = t = t - t.mean()
        self.x = x = x - x.mean(axis=0)  # centred first: the cumulative sums keep their digits
        self.n = np.arange(1, t.size + 1, dtype=float)
        self.st, self.stt = np.cumsum(t), np.cumsum(t * t)
        self.sx, self.sxx = np.cumsum(x, axis=0), np.cumsum(x * x, axis=0)
        self.stx = np.cumsum(t[:, None] * x, axis=0)

    def at(self, rows: Any = slice(None)) -> np.ndarray:
        """The detrended squared residuals per component at the samples ``rows`` (an index
        array, or a slice), (len(rows), components)."""
        n, st, stt = self.n[rows], self.st[rows], self.stt[rows]
        sx, sxx, stx = self.sx[rows], self.sxx[rows], self.stx[rows]
        ctt = stt - st**2 / n
        cxx = sxx - sx**2 / n[:, None]
        ctx = stx - st[:, None] * sx / n[:, None]
        with np.errstate(divide="ignore", invalid="ignore"):
            trend = np.where(ctt[:, None] > 0, ctx**2 / ctt[:, None], 0.0)
        return np.maximum(cxx - trend, 0.0)

    def last(self) -> np.ndarray:
        """``at`` the last sample alone, (1, components)."""
        return self.at(np.array([self.n.size - 1]))


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
        (the reference's motion, the squared differences; a partition of the same shape as
        an earlier one is that one under its own names)."""
        reference = np.asarray(reference, dtype=float)
        motion = Motion(t, reference)
        early = None
        if window is not None and len(window[0]) >= 3 and np.isfinite(window[1]).all():
            early = Motion(*window).last()[0] / len(window[0])
        squared, diff2 = reference**2, (np.asarray(U, dtype=float) - reference) ** 2
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
            size = np.cumsum(blocks.sum(squared), axis=0)  # nothing moved yet: the block's size
            still = ~(variance > STILL**2 * size[-1] / samples)  # a motion below its rounding: nothing moves
            variance = np.where(still, size[-1] / samples, variance)
            scales = np.where(variance > 0, np.sqrt(variance), 1.0)
            diff = blocks.sum(diff2)
            parts = {"blocks": blocks, "motion": motion, "floor": floor, "size": size, "diff": diff,
                     "reference": reference, "samples": samples}
            done[blocks.shape] = errors = cls(blocks.names, scales, np.sqrt(diff) / scales, parts)
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
        if "cumulative" not in p:
            p["cumulative"] = np.cumsum(p["diff"], axis=0)
        size = p["size"][rows]
        motion = np.where(motion > STILL**2 * size, motion, np.where(size > 0, size, n))
        l2 = np.sqrt(p["cumulative"][rows] / motion)
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
        diff = p["blocks"].sum((np.asarray(U, dtype=float) - p["reference"]) ** 2)
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
    def largest(self) -> tuple[np.ndarray, np.ndarray]:
        """(e, l2) of the largest block at each sample: the solution error."""
        return self.pointwise.max(axis=1), self.l2.max(axis=1)

    @property
    def worst(self) -> str:
        """The name of the block with the largest l2_error over the run."""
        last = self.final_l2()
        return self.names[int(np.argmax(np.where(np.isfinite(last), last, np.inf)))]
