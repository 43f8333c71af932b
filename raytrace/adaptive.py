"""Adaptive anti-aliasing: pixel corners, cells halved where their corners differ.

Whitted (1980, §4) and POV-Ray's ``+A0.3 +R3`` (its "method 2"): every pixel corner is
sampled, the four shared between neighbours; a cell whose four corners differ by the
threshold or more, in any RGB channel (``max − min``), is cut into four, its edge midpoints
and centre are sampled, and each quarter is judged the same way, down to ``aa_depth`` halvings.
A cell that is not cut counts the mean of its corners over its area: the pixel is the
area-weighted sum ``Σ 4^−ℓ · ¼(c₀ + c₁ + c₂ + c₃)`` over its uncut cells (ℓ their level). A
threshold of 0 cuts every cell to the deepest level (uniform refinement); on a flat frame
only the corners are traced.

**The lattice.** Every point ever sampled lies on the frame's finest lattice, ``2^D`` points
a pixel a side (D = ``aa_depth``): point (i, j) at ``(i, j)·2^−D`` pixels, numbered ``id = j·(W·2^D
+ 1) + i`` over the whole frame. A point is a function of its id only, so a corner shared by
two pixels, two passes or a crop and the full frame is the same sample: the pixel corners
(level 0) exactly at the corners, a point first needed at level ℓ ≥ 1 jittered by up to a
quarter of a level-ℓ cell each way (hashes of (seed, id),
:func:`raytrace.kernels.core.camera_uniform`),
its light samples keyed by its id. Each level of a pass is traced as one wavefront
(:func:`refine`'s ``trace``), and each pixel's cells are summed in one fixed order (level by
level, parents' order), so an image does not depend on threads, passes or crops.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from .camera import hash_uniform
from .kernels.adaptive import judge_cells
from .kernels.records import Cells, Level, SlotGrid

#: ``trace(x, y, ids)``: radiance (n, 3) float64 of the samples at image positions ``x, y``
#: (pixels, (n,) float64 each) with lattice ``ids`` (n,) int64.
Tracer = Callable[[np.ndarray, np.ndarray, np.ndarray], np.ndarray]


def lattice_ids(i: np.ndarray, j: np.ndarray, width: int, depth: int) -> np.ndarray:
    """The frame-wide number ``j·(W·2^D + 1) + i`` of lattice points (i, j) (int64)."""
    return np.asarray(j, np.int64) * ((width << depth) + 1) + np.asarray(i, np.int64)


def levels(i: np.ndarray, j: np.ndarray, depth: int) -> np.ndarray:
    """The level at which lattice point (i, j) is first needed: 0 for pixel corners, D −
    (the trailing zero bits of i and j, at most D) otherwise."""
    top = np.int64(1) << depth
    i, j = np.asarray(i, np.int64), np.asarray(j, np.int64)
    low_i = np.where(i == 0, top, i & -i)
    low_j = np.where(j == 0, top, j & -j)
    low = np.minimum(np.minimum(low_i, low_j), top)
    return depth - np.round(np.log2(low)).astype(np.int64)


def positions(i: np.ndarray, j: np.ndarray, width: int, depth: int,
              seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Image positions (x, y), pixels, and ids of lattice points (i, j): ``(i, j)·2^−D``,
    jittered by ``(ξ − ½)·2^−ℓ/2`` for a point of level ℓ ≥ 1 (ξ uniform, hashed from the id)."""
    ids = lattice_ids(i, j, width, depth)
    level = levels(i, j, depth)
    reach = np.where(level > 0, 0.5 * np.exp2(-level.astype(np.float64)), 0.0)
    h = 2.0**-depth
    x = np.asarray(i, np.float64) * h + (hash_uniform(seed, ids, 0) - 0.5) * reach
    y = np.asarray(j, np.float64) * h + (hash_uniform(seed, ids, 1) - 0.5) * reach
    return x, y, ids


class Lattice:
    """The lattice points of one pass traced so far, with their radiance: a dense table of
    slots over the pass's window (``(rows·2^D + 1)·(cols·2^D + 1)`` int64, −1 where not yet
    traced), so that looking up or adding points is an index, not a search."""

    def __init__(self, window: tuple[int, int, int, int], width: int, depth: int, seed: int,
                 trace: Tracer):
        x0, y0, x1, y1 = window
        self.width, self.depth, self.seed, self.trace = width, depth, seed, trace
        top = 1 << depth
        self.i0, self.j0, self.stride = x0 * top, y0 * top, (x1 - x0) * top + 1
        self.slot = np.full(((y1 - y0) * top + 1) * self.stride, -1, np.int64)
        self.values = np.zeros((0, 3))
        self.traced = 0

    def _local(self, i: np.ndarray, j: np.ndarray) -> np.ndarray:
        return (np.asarray(j, np.int64) - self.j0) * self.stride + (np.asarray(i, np.int64)
                                                                    - self.i0)

    def add(self, i: np.ndarray, j: np.ndarray) -> None:
        """Trace, as one batch, the points (i, j) not traced yet (duplicates once: the
        first of each, in the order given)."""
        i, j = np.asarray(i, np.int64), np.asarray(j, np.int64)
        local = self._local(i, j)
        new = np.flatnonzero(self.slot[local] < 0)
        order = np.arange(len(new))
        self.slot[local[new[::-1]]] = order[::-1]  # the first occurrence's number wins
        first = new[self.slot[local[new]] == order]
        if not len(first):
            return
        x, y, ids = positions(i[first], j[first], self.width, self.depth, self.seed)
        values = self.trace(x, y, ids)
        self.slot[local[first]] = len(self.values) + np.arange(len(first))
        self.values = np.concatenate([self.values, values])
        self.traced += len(first)

    def __call__(self, i: np.ndarray, j: np.ndarray) -> np.ndarray:
        """Radiance (n, 3) of traced points (i, j)."""
        return self.values[self.slot[self._local(i, j)]]


def refine(window: tuple[int, int, int, int], width: int, depth: int, threshold: float,
           seed: int, trace: Tracer, first: int = 0) -> tuple[np.ndarray, np.ndarray, int]:
    """The pixels of ``window`` = (x0, y0, x1, y1) of a ``width``-wide frame by adaptive
    refinement (module docstring): ``(pixels (n, 3) float64 in row order, level (n,) int8 the
    deepest level each pixel was cut to, samples traced)``. ``trace`` shades a batch of
    points (:data:`Tracer`); it is called once per level with every point that level needs.
    The first ``first`` levels (at most ``depth``) cut every cell, whatever its corners: with
    1, every pixel starts as 2×2 cells (POV-Ray's ``+AM2`` judges its sub-samples the same
    way), so detail between a pixel's corners is seen.
    """
    x0, y0, x1, y1 = window
    cols, rows = x1 - x0, y1 - y0
    top = 1 << depth
    lattice = Lattice(window, width, depth, seed, trace)
    ci, cj = np.meshgrid(np.arange(x0, x1 + 1) * top, np.arange(y0, y1 + 1) * top)
    lattice.add(ci.ravel(), cj.ravel())  # level 0: every pixel corner, once
    pixel = np.arange(cols * rows)
    row, col = np.divmod(pixel, cols)
    ci, cj = (col + x0) * top, (row + y0) * top  # each cell's top-left lattice point
    out = np.zeros((cols * rows, 3))
    deepest = np.zeros(cols * rows, np.int8)
    for level in range(depth + 1):
        s = top >> level
        cut = np.empty(len(ci), bool)
        rule = Level(size=s, threshold=float(threshold), everywhere=level < first,
                     last=level == depth, weight=0.25**level)
        if not judge_cells(lattice.slot, lattice.values,
                           SlotGrid(lattice.stride, lattice.i0, lattice.j0),
                           Cells(ci, cj, pixel), rule, out, cut):
            break
        ci, cj, pixel, h = ci[cut], cj[cut], pixel[cut], s >> 1
        deepest[pixel] = level + 1
        lattice.add(*(np.concatenate(v) for v in zip(
            *((ci + a, cj + b) for a, b in ((h, 0), (0, h), (h, h), (s, h), (h, s))),
            strict=True)))
        quarter = ((0, 0), (h, 0), (0, h), (h, h))  # each parent's four, in parent order
        ci = (ci[:, None] + np.array([a for a, _ in quarter])).ravel()
        cj = (cj[:, None] + np.array([b for _, b in quarter])).ravel()
        pixel = np.repeat(pixel, 4)
    return out, deepest, lattice.traced
