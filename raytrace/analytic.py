"""Analytic shapes (spheres, planes, …), intersected in float64 by compiled per-ray kernels.

Self-intersection is avoided without an epsilon (EMBREEX_NOTES.md, "Precision"): a ray that
starts on a convex primitive and leaves it cannot hit it again, so that primitive is skipped;
a ray that starts on a sphere and goes inward (refraction) can only hit its far side, so only
the far root counts. Where two shapes touch (spheres resting on each other or on a plane), a
ray spawned on one starts on the other within rounding (16 float64 ulps of the coordinates'
magnitude): it crosses there at t = 0 instead of bouncing between the two surfaces.

The quadratic is solved in the numerically stable form of Haines et al., "Precision
Improvements for Ray/Sphere Intersection" (Ray Tracing Gems, 2019, ch. 7): the discriminant
``r² − |f|²`` uses the ray's perpendicular offset ``f``, and the second root comes from
``c/q`` (Vieta), so neither cancels catastrophically.

The per-ray arithmetic is in :mod:`raytrace.kernels.accel` (one intersection and one surface
function per kind behind ``shape_t`` and ``shape_surface``, the loops ``closest_analytic`` and
``analytic_surface``); the tables are :func:`raytrace.tables.shape_tables`'.
"""

from __future__ import annotations

import numpy as np

from .kernels import accel as ak  # the compiled passes of this stage
from .kernels.records import Shapes
from .rays import NO_SHAPE

#: Stands for "no tmax" in the kernels' float64 tmax argument.
NO_TMAX = np.empty(0)


class AnalyticShapes:
    """Queries over the analytic shapes of a :class:`raytrace.kernels.records.Shapes`
    (camera-relative, numbered as :func:`raytrace.tables.shape_tables` numbers them)."""

    def __init__(self, shapes: Shapes):
        #: The tables as the kernels take them.
        self.table = shapes

    def __len__(self) -> int:
        return len(self.table.kind)

    def intersect(self, origin: np.ndarray, direction: np.ndarray, origin_shape: np.ndarray,
                  tmax: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Closest hit of each ray: ``t`` (n,) float64 (inf on a miss) and the shape (n,) int64
        (NO_SHAPE on a miss).

        ``direction`` must be unit length. Only hits with ``0 < t < tmax`` count.
        """
        n = len(origin)
        t, shape = np.empty(n), np.empty(n, np.int64)
        if not len(self):  # a mesh-only scene
            t.fill(np.inf)
            shape.fill(NO_SHAPE)
        else:
            lim = NO_TMAX if tmax is None else f64(tmax)
            ak.closest_analytic(f64(origin), f64(direction), i64(origin_shape), lim,
                               tmax is not None, self.table, t, shape)
        return t, shape

    def surface(self, shape: np.ndarray, point: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Hit points snapped onto their surfaces, and unit outward normals, (n, 3) each
        (rows whose shape is NO_SHAPE: the point as it is, normal 0)."""
        point = f64(point)
        snapped, normal = point.copy(), np.zeros_like(point)
        ak.analytic_surface(i64(shape), point, self.table, snapped, normal)
        return snapped, normal


def f64(a) -> np.ndarray:
    """``a`` as a C-contiguous float64 array (no copy when it is one): the kernels' type."""
    return np.ascontiguousarray(a, dtype=np.float64)


def i64(a) -> np.ndarray:
    """``a`` as a C-contiguous int64 array (no copy when it is one)."""
    return np.ascontiguousarray(a, dtype=np.int64)
