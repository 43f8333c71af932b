"""Analytic spheres and planes, intersected in float64 numpy.

Self-intersection is avoided without an epsilon (EMBREEX_NOTES.md, "Precision"): a ray that
starts on a convex primitive and leaves it cannot hit it again, so that primitive is skipped;
a ray that starts on a sphere and goes inward (refraction) can only hit its far side, so only
the far root counts.

The quadratic is solved in the numerically stable form of Haines et al., "Precision
Improvements for Ray/Sphere Intersection" (Ray Tracing Gems, 2019, ch. 7): the discriminant
``r² − |f|²`` uses the ray's perpendicular offset ``f``, and the second root comes from
``c/q`` (Vieta), so neither cancels catastrophically.
"""

from __future__ import annotations

import numpy as np

from .rays import NO_SHAPE


class AnalyticShapes:
    """Spheres then planes, numbered 0..S−1 then S..S+P−1, in camera-relative coordinates.

    Parameters
    ----------
    centers : (S, 3) float64
    radii : (S,) float64
    points : (P, 3) float64
        A point on each plane.
    normals : (P, 3) float64
        Unit outward normals of the planes.
    """

    def __init__(self, centers, radii, points, normals):
        self.centers = np.asarray(centers, dtype=np.float64).reshape(-1, 3)
        self.radii = np.asarray(radii, dtype=np.float64).reshape(-1)
        self.points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        self.normals = np.asarray(normals, dtype=np.float64).reshape(-1, 3)
        self.n_spheres = len(self.radii)

    def __len__(self) -> int:
        return self.n_spheres + len(self.points)

    def intersect(self, origin: np.ndarray, direction: np.ndarray, origin_shape: np.ndarray,
                  tmax: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Closest hit of each ray: ``t`` (n,) float64 (inf on a miss) and the shape (n,) int64.

        ``direction`` must be unit length. Only hits with ``0 < t < tmax`` count.
        """
        n = len(origin)
        best = np.full(n, NO_SHAPE, dtype=np.int64)
        if not len(self):  # a mesh-only scene
            return np.full(n, np.inf), best
        best_t = np.full(n, np.inf) if tmax is None else np.asarray(tmax, np.float64).copy()
        extent = row_abs_max(origin)  # scale of the rounding tolerances below
        own_t = np.full(n, np.inf)  # where a ray leaves the sphere it started on
        for s in range(self.n_spheres):
            own = origin_shape == s
            t = self._sphere(s, origin, direction, own, extent)
            own_t[own] = t[own]
            closer = t < best_t
            best_t[closer], best[closer] = t[closer], s
        for p in range(len(self.points)):
            sid = self.n_spheres + p
            t = self._plane(p, origin, direction, origin_shape != NO_SHAPE, extent)
            t[origin_shape == sid] = np.inf  # a ray leaving a plane never re-hits it
            closer = t < best_t
            best_t[closer], best[closer] = t[closer], sid
        # Touching solids: leaving the ray's own sphere where another shape begins (equal t
        # within rounding), the exit comes first, so the contact counts both crossings.
        tol = 16.0 * np.finfo(np.float64).eps * (extent + best_t)
        tie = (best != NO_SHAPE) & (best != origin_shape) & (own_t <= best_t + tol)
        best_t[tie], best[tie] = own_t[tie], origin_shape[tie]
        best_t[best == NO_SHAPE] = np.inf
        return best_t, best

    def _sphere(self, s: int, o: np.ndarray, d: np.ndarray, on_it: np.ndarray,
                extent: np.ndarray) -> np.ndarray:
        """Ray parameter of the sphere hit (inf on a miss); ``extent`` = :func:`row_abs_max`
        of ``o``."""
        oc = o - self.centers[s]
        r = self.radii[s]
        b = np.einsum("ij,ij->i", oc, d)                 # d·(o − c), |d| = 1
        f = oc - b[:, None] * d                          # perpendicular offset of the ray
        disc = r * r - np.einsum("ij,ij->i", f, f)       # r² − |f|² (no cancellation)
        inward = on_it & (b < 0)
        # Only a ray whose line meets the sphere, or that starts on it going in, can hit it;
        # most rays miss any one sphere, so the rest is computed for those rays alone.
        out = np.full(len(o), np.inf)
        cand = (disc >= 0) | inward
        k = int(np.count_nonzero(cand))
        if not k:
            return out
        sel = slice(None) if 2 * k > len(o) else np.flatnonzero(cand)
        oc, b, disc, on_it, inward = oc[sel], b[sel], disc[sel], on_it[sel], inward[sel]
        c = np.einsum("ij,ij->i", oc, oc) - r * r
        disc = np.where(inward, np.maximum(disc, 0.0), disc)  # it starts on the sphere
        hit = disc >= 0
        sq = np.sqrt(np.where(hit, disc, 0.0))
        q = -b - np.copysign(sq, b)
        with np.errstate(divide="ignore", invalid="ignore"):
            t0, t1 = q, c / q
        near, far = np.minimum(t0, t1), np.maximum(t0, t1)
        t = np.where(near > 0, near, far)
        # A ray starting on this sphere (its small root t1 within the rounding of the
        # coordinates) though spawned from another one (touching spheres) is treated like one
        # spawned here: going in, it enters at t = 0; going out, it never hits. A
        # rounding-sized root of either sign would otherwise bounce the ray between the two
        # surfaces until max_depth (a black pixel).
        scale = extent[sel] + np.abs(self.centers[s]).max() + r
        touching = ~on_it & hit & (np.abs(t1) <= 16.0 * np.finfo(np.float64).eps * scale)
        enters = touching & (b < 0)
        t = np.where(enters, np.maximum(t1, 0.0), t)
        t = np.where(touching & ~enters, np.inf, t)
        t = np.where(inward, np.where(b < 0, q, np.inf), t)  # from the surface inward: far root
        t = np.where(on_it & ~inward, np.inf, t)             # leaving a convex shape
        ok = hit & ((t > 0) | enters) & np.isfinite(t)
        out[sel] = np.where(ok, t, np.inf)
        return out

    def _plane(self, p: int, o: np.ndarray, d: np.ndarray, spawned: np.ndarray,
               extent: np.ndarray) -> np.ndarray:
        """Ray parameter of the plane hit (inf on a miss)."""
        n = self.normals[p]
        denom = d @ n
        dist = (self.points[p] - o) @ n
        with np.errstate(divide="ignore", invalid="ignore"):
            t = dist / denom
        # A ray spawned on another analytic shape that touches this plane (a sphere resting on
        # it) starts on the plane within rounding: it crosses here, at t = 0.
        tol = 16.0 * np.finfo(np.float64).eps * (extent + np.abs(self.points[p]).max())
        t = np.where(spawned & (np.abs(dist) <= tol) & (denom != 0), 0.0, t)
        return np.where(((t > 0) | (t == 0) & spawned) & np.isfinite(t), t, np.inf)

    def surface(self, shape: np.ndarray, point: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Hit points snapped onto their surfaces, and unit outward normals, (n, 3) each."""
        normal = np.empty_like(point)
        point = point.copy()
        sph = shape < self.n_spheres
        if sph.any():
            c = self.centers[shape[sph]]
            r = self.radii[shape[sph]]
            radial = point[sph] - c
            radial /= np.sqrt(radial[:, 0] * radial[:, 0] + radial[:, 1] * radial[:, 1]
                              + radial[:, 2] * radial[:, 2])[:, None]  # = np.linalg.norm's
            normal[sph] = radial
            point[sph] = c + r[:, None] * radial
        pl = ~sph
        if pl.any():
            k = shape[pl] - self.n_spheres
            nrm = self.normals[k]
            normal[pl] = nrm
            off = np.einsum("ij,ij->i", point[pl] - self.points[k], nrm)
            point[pl] -= off[:, None] * nrm
        return point, normal


def row_abs_max(a: np.ndarray) -> np.ndarray:
    """``np.abs(a).max(axis=1)`` of an (n, 3) array, (n,), as two elementwise maxima: the same
    values, several times faster than a reduction along a length-3 axis.
    """
    return np.maximum(np.maximum(np.abs(a[:, 0]), np.abs(a[:, 1])), np.abs(a[:, 2]))
