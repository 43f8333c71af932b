"""Ray queries: Embree's BVH for triangle meshes, float64 kernels for analytic shapes.

Embree is the library the embreex wheel ships, called directly (:mod:`raytrace.embree` builds
the scene over shared arrays; :mod:`raytrace.kernels.embree` traverses it in packets). Embree
works in float32 with ``tnear = 0`` (EMBREEX_NOTES.md), so:

* the scene arrives recentred on the camera in float64 (:mod:`raytrace.tables`), before
  anything is rounded to float32;
* a mesh hit point is rebuilt from Embree's barycentrics, re-solved in float64, on the float64
  triangle (on its plane);
* a ray spawned from a mesh hit starts off the surface along the geometric normal, on the side
  it leaves on, by 3 float32 ulps of the hit point's own largest coordinate (scale-aware,
  unlike a fixed epsilon, and independent of the triangle's size);
* a query runs the analytic shapes on the batch (a compiled kernel), then Embree, bounded by
  the rays' closest analytic hits, then the float64 refinement of Embree's hits;
* a hit that the float64 solve puts behind the ray's origin (a ray leaving a large triangle
  whose float32 rounding exceeds that offset) is discarded and the ray traced on from beyond
  the triangle's error band, in a second pass over those few rays (an Embree filter
  callback could do it inside traversal: not tried, docs/decisions.md). docs/robustness.md
  gives the scheme and its measured bound.

A query runs on the calling thread. Embree and the kernels of :mod:`raytrace.kernels.accel`
release the GIL and the accelerator is read-only after construction, so the integrator's
threads query it concurrently, each with batches of its own.
"""

from __future__ import annotations

import numpy as np

from .analytic import NO_TMAX, AnalyticShapes, f64, i64
from .embree import Meshes
from .kernels import accel as ak  # the compiled passes of this stage
from .kernels import embree as ek
from .kernels import loop
from .kernels.core import SHADOW_SHORTEN, leave_rows
from .kernels.records import (
    EmbreeHits,
    EmbreeRays,
    Hits,
    Query,
    Redo,
    Reliefs,
    ShadowQuery,
    Surface,
)
from .rays import NO_SHAPE
from .tables import SceneArrays

#: Most second passes of a query over the rays whose hits were float32 artefacts (one value
#: for both loops).
MAX_RETRACES = loop.MAX_RETRACES

__all__ = ["SHADOW_SHORTEN", "Accelerator", "Hits", "Surface", "spawn_origins",
           "vertex_normals"]
#: The rays a first pass traces: every ray, from its origin (no rows).
_FIRST_PASS = Redo(np.zeros(0, np.int64), np.zeros(0))


class Accelerator:
    """Closest-hit and occlusion queries for a scene, camera-relative.

    Parameters
    ----------
    arrays : SceneArrays
        The scene as arrays (:func:`raytrace.tables.scene_arrays`): its analytic shapes, its
        triangle tables and the camera-relative meshes Embree builds its BVH of.
    threads : int
        Threads Embree builds the BVH on.
    """

    #: Benchmark hook (off by default): when set, ``recorder(query, origins, directions, tfar)``
    #: is called for every :meth:`intersect` ("INTERSECT") and :meth:`occluded` ("OCCLUDED")
    #: batch of the integrator's Python loop (the compiled loop's queries are the same) with
    #: fresh float32 arrays (n, 3), (n, 3), (n,), tfar = tmax or float32 max.
    #: ``benchmarks/bench.py`` replays them through embreex alone. None costs one test a batch.
    recorder = None

    def __init__(self, arrays: SceneArrays, threads: int = 1):
        self.shapes = AnalyticShapes(arrays.shapes)
        self._none_columns = (np.zeros(0, np.int64), np.zeros((0, 2)))
        self._build_meshes(arrays, threads)

    # -- construction --------------------------------------------------------------------
    def _build_meshes(self, arrays: SceneArrays, threads: int) -> None:
        """Embree's scene of the camera-relative meshes (vertices, faces), rounded to float32,
        attached in order (their geomIDs), and the triangle tables its hits index."""
        #: The triangle tables, as every kernel takes them.
        self.triangles = arrays.triangles
        #: Embree's scene (:class:`raytrace.embree.Meshes`), or None without meshes.
        self.embree = Meshes(arrays.meshes, threads) if arrays.meshes else None

    # -- queries -------------------------------------------------------------------------
    def intersect(self, origin: np.ndarray, direction: np.ndarray, origin_shape: np.ndarray,
                  tmax: np.ndarray | None = None, packets: np.ndarray = ek.PLAIN) -> Hits:
        """Closest hit of each ray with ``0 < t < tmax`` (mesh and analytic).

        The analytic shapes first; then Embree, bounded by the closest analytic hit, and the
        float64 refinement of Embree's hits. Embree traces the rays in plain packets,
        answering each ray as its single-ray call would; ``packets``, where not empty: where
        each packet of neighbouring rays starts (camera rays in blocks of the frame,
        :func:`raytrace.kernels.camera.frame_packets`, or a noise-driven round's samples of
        one pixel, :func:`raytrace.kernels.camera.pixel_packets`), traced with the COHERENT
        flag, the hits that may tie at a shared edge traced again without it
        (:func:`raytrace.kernels.embree.closest_hits`).
        """
        origin, direction, origin_shape = f64(origin), f64(direction), i64(origin_shape)
        tmax = None if tmax is None else f64(tmax)
        n = len(origin)
        if self.recorder is not None:
            self._record("INTERSECT", origin, direction, tmax)
        t, shape = self.shapes.intersect(origin, direction, origin_shape, tmax)
        if self.embree is None:  # no triangle hits: shared columns, never written to
            triangle, uv = self._no_triangles(n)
            return Hits(t, shape, triangle, uv)
        triangle = np.full(n, -1, dtype=np.int64)
        uv = np.zeros((n, 2))
        if n:
            has_tmax, lim = (False, NO_TMAX) if tmax is None else (True, tmax)
            self._closest_triangles(Query(origin, direction, lim, has_tmax),
                                    Hits(t, shape, triangle, uv), packets)
        return Hits(t, shape, triangle, uv)

    def _no_triangles(self, n: int) -> tuple[np.ndarray, np.ndarray]:
        """Views of ``n`` rows of a −1 triangle column and a zero uv column, kept between
        calls (a scene without meshes filled the two anew for every query: 19 ms of a
        1280×960 Whitted frame). Nothing writes into a ``Hits`` it is handed. Safe with
        threads: a thread that needs more rows makes bigger ones and returns its own,
        whatever another thread stores meanwhile."""
        triangle, uv = self._none_columns
        if len(triangle) < n:
            triangle, uv = np.full(n, -1, np.int64), np.zeros((n, 2))
            self._none_columns = (triangle, uv)
        return triangle[:n], uv[:n]

    def _closest_triangles(self, query: Query, hits: Hits, packets: np.ndarray = ek.PLAIN) -> None:
        """Embree's closest hits of ``query``'s rays, written into ``hits`` where a triangle
        comes before the analytic hit (and ``tmax``); ``packets``: the first pass's COHERENT
        packets (:meth:`intersect`).

        Hits that the float64 solve finds behind the origin are float32 artefacts
        (:func:`raytrace.kernels.accel.refine_hits`): those rays are traced again from
        beyond the artefact's error band, at most :data:`MAX_RETRACES` times."""
        n = len(query.origin)
        rays = _embree_rays(n)  # far: a fresh array, Embree overwrites it
        ak.embree_rays(query, hits.t, rays)
        redo = Redo(np.empty(n, np.int64), np.empty(n))
        traced = _FIRST_PASS
        for _ in range(MAX_RETRACES + 1):
            out = _embree_hits(len(rays.far))
            ek.closest_hits(self.embree.record, rays, packets, out)
            packets = ek.PLAIN  # the rays traced again are a scattered few
            k = ak.refine_hits(out, traced, self.triangles, query, hits, redo)
            if not k:
                return
            traced, rays = Redo(np.empty(k, np.int64), np.empty(k)), _embree_rays(k)
            k = ak.retrace_rays(Redo(redo.rows[:k], redo.adv[:k]), query, hits.t, rays,
                                traced)
            if not k:
                return
            traced = Redo(traced.rows[:k], traced.adv[:k])
            rays = EmbreeRays(rays.origin[:k], rays.direction[:k], rays.far[:k])

    def occluded(self, origin: np.ndarray, direction: np.ndarray, origin_shape: np.ndarray,
                 tmax: np.ndarray, coherent: bool = False) -> np.ndarray:
        """True where something opaque or not lies in ``(0, tmax)`` (any-hit query);
        ``coherent``: neighbouring rays travel together (shadow rays of neighbouring hits to
        one point), so Embree traverses their packets as frusta (an any-hit answer does not
        depend on the order it meets the triangles in).

        The analytic shapes first (any hit, :func:`raytrace.kernels.accel.shadow_prepass`);
        Embree only sees the rays they do not block. Embree's any-hit answer does not say
        what it hit, so the rays it finds blocked that start on a triangle (no analytic
        ``origin_shape``), where the blocker may be a float32 artefact of that triangle or of
        a neighbour meeting it at an edge, are asked again as closest-hit queries, which
        discard artefacts (:meth:`_closest_triangles`). Where no blocker is an artefact, that
        costs one closest-hit query per such ray (measured: 4 % of the Embree rays of
        benchmarks/bench.py's mesh frame).
        """
        origin, direction, origin_shape = f64(origin), f64(direction), i64(origin_shape)
        tmax = f64(tmax)
        if self.recorder is not None:
            self._record("OCCLUDED", origin, direction, tmax)
        n, meshes = len(origin), self.embree is not None
        blocked = np.empty(n, dtype=bool)
        m = n if meshes else 0
        idx, rays = np.empty(m, np.int64), _embree_rays(m)
        k = ak.shadow_prepass(ShadowQuery(origin, direction, origin_shape, tmax),
                              self.shapes.table, meshes, blocked, idx, rays)
        if k:
            res = np.empty(k, np.int32)
            ek.any_hits(self.embree.record, EmbreeRays(rays.origin[:k], rays.direction[:k],
                                                       rays.far[:k]), coherent, res)
            recheck = np.empty(k, np.int64)
            j = ak.occlusion(idx[:k], res, origin_shape, blocked, recheck)
            if j:
                rows = recheck[:j]
                o, d, lim = origin[rows], direction[rows], tmax[rows]
                t = np.full(j, np.inf)
                self._closest_triangles(Query(o, d, lim, True), Hits(
                    t, np.full(j, NO_SHAPE, np.int64), np.empty(j, np.int64), np.empty((j, 2))))
                blocked[rows] = np.isfinite(t)
        return blocked

    def _record(self, query: str, origin: np.ndarray, direction: np.ndarray,
                tmax: np.ndarray | None) -> None:
        """Hand a batch, as Embree would take it, to :attr:`recorder`."""
        big = np.finfo(np.float32).max
        far = (np.full(len(origin), big, np.float32) if tmax is None
               else np.minimum(tmax, big).astype(np.float32))
        self.recorder(query, np.ascontiguousarray(origin, dtype=np.float32),
                      np.ascontiguousarray(direction, dtype=np.float32), far)

    # -- surfaces ------------------------------------------------------------------------
    def surface(self, hits: Hits, origin: np.ndarray, direction: np.ndarray,
                reliefs: Reliefs | None = None) -> Surface:
        """Points, normals and materials at the hits (every row of ``hits`` must be a hit);
        ``reliefs``: the scene's normal and height maps (``Scene.reliefs``), or None.

        One kernel over the hits: :func:`raytrace.kernels.accel.hit_surfaces`.
        """
        n = len(hits.t)
        point, geometric, shading = np.empty((n, 3)), np.empty((n, 3)), np.empty((n, 3))
        material, offset = np.empty(n, np.int64), np.empty(n)
        surface = Surface(point, geometric, shading, material, offset, hits.shape,
                          hits.triangle, hits.uv)
        hits = Hits(f64(hits.t), i64(hits.shape), i64(hits.triangle), f64(hits.uv))
        ak.hit_surfaces(hits, f64(origin), f64(direction), self.shapes.table, self.triangles,
                        reliefs, surface)
        return surface


def _embree_hits(n: int) -> EmbreeHits:
    """Room for Embree's closest hits of ``n`` rays."""
    return EmbreeHits(np.empty(n, np.int32), np.empty(n, np.int32), np.empty(n, np.float32),
                      np.empty(n, np.float32))


def _embree_rays(n: int) -> EmbreeRays:
    """Room for ``n`` rays as Embree takes them (float32)."""
    return EmbreeRays(np.empty((n, 3), np.float32), np.empty((n, 3), np.float32),
                      np.empty(n, np.float32))


def spawn_origins(point: np.ndarray, geometric: np.ndarray, offset: np.ndarray,
                  direction: np.ndarray) -> np.ndarray:
    """Start points (n, 3) of rays leaving surface points along ``direction``.

    The one spawn rule of every kernel, :func:`raytrace.kernels.core.leave1`: mesh hits move
    ``offset`` off the plane along the geometric normal, to the side the ray leaves on;
    analytic hits have offset 0 and stay put (their ray carries its shape instead, see
    :mod:`raytrace.analytic`).
    """
    point = f64(point)
    out = np.empty_like(point)
    leave_rows(point, f64(geometric), f64(offset), f64(direction), out)
    return out


def vertex_normals(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Unit vertex normals: the normalised sum of the unit normals of the faces sharing
    each vertex (seed 000, Gouraud: N_V = Σ N_k / |Σ N_k|). (V, 3) float64; 0 where the face
    normals cancel (shading then falls back to the face's normal).
    """
    vertices = f64(vertices)
    out = np.empty_like(vertices)
    ak.vertex_normals(vertices, i64(faces), out)
    return out
