"""Compiled adaptive anti-aliasing (:mod:`raytrace.adaptive`): one level of corner refinement
over a pass's cells (:func:`judge_cells`), with its two inlined helpers, a cell's corner rows
(:func:`corners1`) and the mean it adds (:func:`add_mean1`)."""

from __future__ import annotations

import math

from .jit import inline, kernel


@inline
def corners1(slot, grid, ci, cj, s):
    """The rows in ``values`` of the four corners of the cell whose top-left lattice point is
    (ci, cj) and side ``s``, through the pass's ``slot`` table (laid out by ``grid``, a
    :class:`raytrace.kernels.records.SlotGrid`): top-left, top-right, bottom-left,
    bottom-right."""
    stride = grid.stride
    i, j = ci - grid.i0, cj - grid.j0
    return (slot[j * stride + i], slot[j * stride + i + s],
            slot[(j + s) * stride + i], slot[(j + s) * stride + i + s])


@inline
def add_mean1(out, p, values, r, weight):
    """``out[p] += ¼(c₀ + c₁ + c₂ + c₃)·weight`` for the corner rows ``r`` of ``values``."""
    r0, r1, r2, r3 = r
    for c in range(3):
        mean = (values[r0, c] + values[r1, c] + values[r2, c] + values[r3, c]) * 0.25
        out[p, c] += mean * weight


@kernel
def judge_cells(slot, values, grid, cells, level, out, cut):
    """One level of :func:`raytrace.adaptive.refine` over its ``cells`` (a
    :class:`raytrace.kernels.records.Cells`), in cell order: each cell's four corners
    (top-left lattice point (ci, cj), side ``s`` = ``level.size``) looked up through the
    pass's ``slot`` table (laid out by ``grid``, a :class:`raytrace.kernels.records.SlotGrid`)
    in ``values`` (n, 3) (:func:`corners1`); ``cut[k]`` where the cell is cut: not at the
    ``last`` level, and every cell of a level before the first judged one (``everywhere``), or
    its corners' spread ``max_c (max − min)`` ≥ ``threshold`` (never where a corner is NaN:
    the spread is NaN); an uncut cell adds ``¼(c₀ + c₁ + c₂ + c₃)·weight`` to its pixel's row
    of ``out`` (:func:`add_mean1`), one cell after another (the fixed order of the pixel's
    sum). ``level``: a :class:`raytrace.kernels.records.Level`. Returns the number cut."""
    ci, cj, pixel = cells.ci, cells.cj, cells.pixel
    s, threshold, everywhere = level.size, level.threshold, level.everywhere
    last, weight = level.last, level.weight
    n = 0
    for k in range(ci.shape[0]):
        r = corners1(slot, grid, ci[k], cj[k], s)
        r0, r1, r2, r3 = r
        split = False
        if not last:
            if everywhere:
                split = True
            else:
                finite, spread = True, -math.inf
                for c in range(3):
                    a, b, e, f = values[r0, c], values[r1, c], values[r2, c], values[r3, c]
                    d = max(max(a, b), max(e, f)) - min(min(a, b), min(e, f))
                    if a != a or b != b or e != e or f != f or d != d:
                        finite = False
                    elif d > spread:
                        spread = d
                split = finite and spread >= threshold
        cut[k] = split
        if split:
            n += 1
            continue
        add_mean1(out, pixel[k], values, r, weight)
    return n
