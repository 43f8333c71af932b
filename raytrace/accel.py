"""Ray queries: Embree's BVH for triangle meshes, float64 numpy for analytic shapes.

This is the only module that imports ``embreex``. Embree works in float32 with ``tnear = 0``
(EMBREEX_NOTES.md), so:

* the whole scene is recentred on the camera in float64 before anything is rounded to float32;
* a mesh hit point is rebuilt from Embree's barycentrics on the float64 triangle (on its plane);
* a ray spawned from a mesh hit starts off the surface along the geometric normal, on the side
  it leaves on, by :data:`OFFSET_ULPS` float32 ulps of the hit triangle's largest coordinate
  (scale-aware, unlike a fixed epsilon);
* Embree calls run on chunks of rays in a thread pool (embreex releases the GIL).
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import numpy as np

from .analytic import AnalyticShapes
from .rays import NO_SHAPE
from .scene import Mesh, Plane, Scene, Sphere

#: Spawned-ray offset in float32 ulps (2⁻²³ relative) of the triangle's largest coordinate.
OFFSET_ULPS = 3.0
#: Rays per Embree call in the thread pool (16k–64k is the measured sweet spot).
CHUNK = 32768
#: Shadow rays stop this relative fraction short of the light.
SHADOW_SHORTEN = 1e-7

SHADING_CODES = {"flat": 0, "smooth": 1, "gouraud": 2}


@dataclass
class Hits:
    """Closest hits of a batch of ``n`` rays.

    Attributes
    ----------
    t : (n,) float64
        Distance along the unit direction; inf on a miss.
    shape : (n,) int64
        Analytic shape index, or NO_SHAPE.
    triangle : (n,) int64
        Global triangle index, or −1.
    uv : (n, 2) float64
        Barycentrics of vertices 1 and 2 for triangle hits.
    """

    t: np.ndarray
    shape: np.ndarray
    triangle: np.ndarray
    uv: np.ndarray

    @property
    def hit(self) -> np.ndarray:
        return np.isfinite(self.t)


@dataclass
class Surface:
    """What the shading needs at ``n`` hit points (all float64, camera-relative).

    ``point`` (n, 3); ``geometric`` (n, 3) unit outward normal; ``shading`` (n, 3) unit shading
    normal on the same side as ``geometric``; ``material`` (n,) int64; ``offset`` (n,) the
    spawn offset (0 for analytic shapes); ``shape`` (n,) analytic shape or NO_SHAPE;
    ``triangle`` (n,) or −1; ``uv`` (n, 2) barycentrics; ``gouraud`` (n,) bool.
    """

    point: np.ndarray
    geometric: np.ndarray
    shading: np.ndarray
    material: np.ndarray
    offset: np.ndarray
    shape: np.ndarray
    triangle: np.ndarray
    uv: np.ndarray
    gouraud: np.ndarray



class Accelerator:
    """Closest-hit and occlusion queries for a scene, camera-relative.

    Parameters
    ----------
    scene : Scene
        Its objects' materials must be resolved (``Scene`` does so on construction).
    materials : list of Material
        The table that ``Surface.material`` indexes; objects' materials are looked up in it.
    threads : int
        Worker threads for Embree.
    """

    #: Benchmark hook (off by default): when set, ``recorder(query, origins, directions, tfar)``
    #: is called for every :meth:`intersect` ("INTERSECT") and :meth:`occluded` ("OCCLUDED")
    #: batch with fresh float32 arrays (n, 3), (n, 3), (n,), tfar = tmax or float32 max.
    #: ``benchmarks/bench.py`` replays them through embreex alone. None costs one test a batch.
    recorder = None

    def __init__(self, scene: Scene, materials: list, threads: int = 1):
        self.origin = np.asarray(scene.camera.position, dtype=np.float64)
        self.threads = max(1, int(threads))
        mat_index = {id(m): i for i, m in enumerate(materials)}
        spheres = [o for o in scene.objects if isinstance(o, Sphere)]
        planes = [o for o in scene.objects if isinstance(o, Plane)]
        meshes = [o for o in scene.objects if isinstance(o, Mesh)]
        self.shapes = AnalyticShapes(
            [s.center - self.origin for s in spheres], [s.radius for s in spheres],
            [p.point - self.origin for p in planes], [p.normal for p in planes])
        self.shape_material = np.array(
            [mat_index[id(o.material)] for o in (*spheres, *planes)], dtype=np.int64)
        self.degenerate = sum(m.degenerate for m in meshes)
        self._pool = ThreadPoolExecutor(self.threads) if self.threads > 1 else None
        self._build_meshes(meshes, mat_index)

    # -- construction --------------------------------------------------------------------
    def _build_meshes(self, meshes: list[Mesh], mat_index: dict) -> None:
        self.n_triangles = sum(len(m.faces) for m in meshes)
        self.embree = None
        if not meshes:
            return
        from embreex import rtcore_scene
        from embreex.mesh_construction import TriangleMesh

        self.embree = rtcore_scene.EmbreeScene()
        corners, vnormals, materials, shading, first = [], [], [], [], []
        count = 0
        for m in meshes:  # geomID is the attach order
            v = m.vertices - self.origin
            v32 = np.ascontiguousarray(v, dtype=np.float32)
            TriangleMesh(self.embree, v32, np.ascontiguousarray(m.faces, dtype=np.int32))
            first.append(count)
            count += len(m.faces)
            corners.append(v[m.faces])
            vnormals.append(vertex_normals(v, m.faces)[m.faces])
            materials.append(np.full(len(m.faces), mat_index[id(m.material)], np.int64))
            shading.append(np.full(len(m.faces), SHADING_CODES[m.shading], np.int8))
        self.geom_first = np.array(first, dtype=np.int64)
        self.tri_corners = np.concatenate(corners)             # (T, 3, 3) float64
        self.tri_vnormals = np.concatenate(vnormals)           # (T, 3, 3) unit vertex normals
        self.tri_material = np.concatenate(materials)
        self.tri_shading = np.concatenate(shading)
        a, b, c = (self.tri_corners[:, i] for i in range(3))
        ng = np.cross(b - a, c - a)
        self.tri_normal = ng / np.linalg.norm(ng, axis=1, keepdims=True)
        # A vertex whose face normals cancel (inconsistent winding) has no normal: its corners
        # use the face's own, so Gouraud shading does not go dark there.
        zero = ~self.tri_vnormals.any(axis=2)
        self.tri_vnormals[zero] = np.broadcast_to(self.tri_normal[:, None], zero.shape + (3,))[
            zero]
        extent = np.abs(self.tri_corners.astype(np.float32)).max(axis=(1, 2)).astype(np.float64)
        self.tri_offset = OFFSET_ULPS * 2.0**-23 * np.maximum(extent, np.finfo(np.float32).tiny)
        # The first run() commits the scene and is not thread-safe: do it once here.
        one = np.zeros((1, 3), np.float32)
        self.embree.run(one, np.array([[0, 0, 1]], np.float32), output=0)

    def close(self) -> None:
        if self._pool is not None:
            self._pool.shutdown()
            self._pool = None

    # -- queries -------------------------------------------------------------------------
    def _chunks(self, fn, n: int) -> None:
        """Run ``fn(slice)`` over chunks of ``n`` rays, in the pool when there is one.

        Without meshes a chunk is numpy work alone (analytic shapes), which measured slower
        on two threads than on one (many short GIL-releasing calls): then the chunks run here.
        """
        slices = [slice(i, min(i + CHUNK, n)) for i in range(0, n, CHUNK)]
        if self._pool is None or len(slices) == 1 or self.embree is None:
            for s in slices:
                fn(s)
        else:
            list(self._pool.map(fn, slices))

    def intersect(self, origin: np.ndarray, direction: np.ndarray, origin_shape: np.ndarray,
                  tmax: np.ndarray | None = None) -> Hits:
        """Closest hit of each ray with ``0 < t < tmax`` (mesh and analytic).

        Each chunk of :data:`CHUNK` rays runs the whole query in one worker: the analytic
        shapes, Embree bounded by the closest analytic hit, and the float64 refinement of
        Embree's hits. numpy and embreex release the GIL, so all of it runs in parallel; every
        step is row-wise, so the result does not depend on the number of threads.
        """
        n = len(origin)
        if self.recorder is not None:
            self._record("INTERSECT", origin, direction, tmax)
        t = np.empty(n)
        shape = np.empty(n, dtype=np.int64)
        triangle = np.full(n, -1, dtype=np.int64)
        uv = np.zeros((n, 2))

        def run(s: slice) -> None:
            lim = None if tmax is None else tmax[s]
            t[s], shape[s] = self.shapes.intersect(origin[s], direction[s], origin_shape[s], lim)
            if self.embree is not None:
                self._closest_triangles(origin[s], direction[s], lim, t[s], shape[s],
                                        triangle[s], uv[s])

        self._chunks(run, n)
        return Hits(t, shape, triangle, uv)

    def _closest_triangles(self, o: np.ndarray, d: np.ndarray, tmax: np.ndarray | None,
                           t: np.ndarray, shape: np.ndarray, triangle: np.ndarray,
                           uv: np.ndarray) -> None:
        """Embree's closest hits of one chunk, written into the views ``t``, ``shape``,
        ``triangle``, ``uv`` where a triangle comes before the analytic hit."""
        # Stop Embree at the closest analytic hit, or at tmax (the analytic query returns
        # inf, not tmax, where it finds nothing before tmax).
        bound = t if tmax is None else np.minimum(t, tmax)
        far = bound.astype(np.float32)  # a fresh array: Embree overwrites it
        far[~np.isfinite(far)] = np.float32(np.finfo(np.float32).max)
        out = self.embree.run(np.ascontiguousarray(o, dtype=np.float32),
                              np.ascontiguousarray(d, dtype=np.float32), dists=far, output=1)
        idx = np.flatnonzero(out["geomID"] >= 0)
        if not len(idx):
            return
        tri = self.geom_first[out["geomID"][idx]] + out["primID"][idx]
        corners = self.tri_corners[tri]
        om, dm = o[idx], d[idx]
        bary = _refine_uv(corners, om, dm, out["u"][idx], out["v"][idx])
        tm = np.einsum("ij,ij->i", _barycentric_point(corners, bary) - om, dm)
        closer = tm < bound[idx]
        hit = idx[closer]
        t[hit] = np.maximum(tm[closer], np.finfo(np.float64).tiny)
        shape[hit] = NO_SHAPE
        triangle[hit] = tri[closer]
        uv[hit] = bary[closer]

    def occluded(self, origin: np.ndarray, direction: np.ndarray, origin_shape: np.ndarray,
                 tmax: np.ndarray) -> np.ndarray:
        """True where something opaque or not lies in ``(0, tmax)`` (any-hit query).

        Chunked like :meth:`intersect`; Embree only sees the rays no analytic shape blocks.
        """
        n = len(origin)
        if self.recorder is not None:
            self._record("OCCLUDED", origin, direction, tmax)
        blocked = np.empty(n, dtype=bool)
        big = np.finfo(np.float32).max

        def run(s: slice) -> None:
            o, d, lim = origin[s], direction[s], tmax[s]
            t, _ = self.shapes.intersect(o, d, origin_shape[s], lim)
            b = np.isfinite(t)
            if self.embree is not None:
                todo = np.flatnonzero(~b)
                if 0 < len(todo) < len(b):
                    o, d, lim = o[todo], d[todo], lim[todo]
                if len(todo):
                    res = self.embree.run(np.ascontiguousarray(o, dtype=np.float32),
                                          np.ascontiguousarray(d, dtype=np.float32),
                                          dists=np.minimum(lim, big).astype(np.float32),
                                          query="OCCLUDED")
                    b[todo] = res == 0
            blocked[s] = b

        self._chunks(run, n)
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
    def surface(self, hits: Hits, origin: np.ndarray, direction: np.ndarray) -> Surface:
        """Points, normals and materials at the hits (every row of ``hits`` must be a hit).

        Computed chunk by chunk in the thread pool, like :meth:`intersect`.
        """
        n = len(hits.t)
        point = np.empty((n, 3))
        geometric = np.empty((n, 3))
        shading = np.empty((n, 3))
        material = np.empty(n, np.int64)
        offset = np.zeros(n)
        gouraud = np.zeros(n, bool)

        def run(s: slice) -> None:
            self._surface_chunk(hits.t[s], hits.shape[s], hits.triangle[s], hits.uv[s],
                                origin[s], direction[s], point[s], geometric[s], shading[s],
                                material[s], offset[s], gouraud[s])

        self._chunks(run, n)
        return Surface(point, geometric, shading, material, offset, hits.shape, hits.triangle,
                       hits.uv, gouraud)

    def _surface_chunk(self, t, shape, triangle, uv, origin, direction,
                       point, geometric, shading, material, offset, gouraud) -> None:
        """:meth:`surface` for one chunk, written into the output views."""
        an = shape != NO_SHAPE
        n_an = int(np.count_nonzero(an))
        if n_an:
            sel = slice(None) if n_an == len(an) else an
            s_an = shape[sel]
            p, nrm = self.shapes.surface(s_an, origin[sel] + t[sel, None] * direction[sel])
            point[sel], geometric[sel], shading[sel] = p, nrm, nrm
            material[sel] = self.shape_material[s_an]
        if n_an == len(an):
            return
        sel = slice(None) if not n_an else ~an
        tri, w = triangle[sel], uv[sel]
        corners = self.tri_corners[tri]
        point[sel] = _barycentric_point(corners, w)
        ng = self.tri_normal[tri]
        geometric[sel] = ng
        code = self.tri_shading[tri]
        smooth = code != 0
        n_smooth = int(np.count_nonzero(smooth))
        if n_smooth:
            every = n_smooth == len(smooth)
            ms = slice(None) if every else smooth
            vn = self.tri_vnormals[tri if every else tri[smooth]]
            ws = w[ms]
            ns = ((1 - ws[:, 0] - ws[:, 1])[:, None] * vn[:, 0] + ws[:, :1] * vn[:, 1]
                  + ws[:, 1:] * vn[:, 2])
            length = _norm(ns)
            good = length > 1e-12
            ns[good] /= length[good, None]
            ns[~good] = ng[ms][~good]
            if every:
                shading[sel] = ns
            else:
                ns_all = ng.copy()
                ns_all[smooth] = ns
                shading[sel] = ns_all
        else:
            shading[sel] = ng
        material[sel] = self.tri_material[tri]
        offset[sel] = self.tri_offset[tri]
        gouraud[sel] = code == 2


def _refine_uv(corners: np.ndarray, origin: np.ndarray, direction: np.ndarray,
               u32: np.ndarray, v32: np.ndarray) -> np.ndarray:
    """Barycentrics (n, 2) of Embree's hits recomputed in float64 (Möller & Trumbore 1997).

    Embree's float32 ``u, v`` are off by ~1e-5 (measured), enough to move smooth normals
    and hit points visibly between scales; solving ``o + t·d = a + u·e1 + v·e2`` again on
    the float64 triangle (``corners`` (n, 3, 3)) makes them exact to ~1e-15. The result is
    clamped onto the triangle (a float64 solve may land a hair outside an edge Embree hit);
    rays (nearly) parallel to the plane keep Embree's values.
    """
    c0 = corners[:, 0]
    e1, e2 = corners[:, 1] - c0, corners[:, 2] - c0
    p = _cross(direction, e2)
    det = np.einsum("ij,ij->i", e1, p)
    s = origin - c0
    q = _cross(s, e1)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        u = np.einsum("ij,ij->i", s, p) / det
        v = np.einsum("ij,ij->i", direction, q) / det
    ok = np.isfinite(u) & np.isfinite(v) & (det != 0)
    uv = np.empty((len(u), 2))
    uv[:, 0] = np.where(ok, np.maximum(u, 0.0), u32)
    uv[:, 1] = np.where(ok, np.maximum(v, 0.0), v32)
    total = uv[:, 0] + uv[:, 1]
    over = total > 1.0
    if over.any():
        uv[over] /= total[over, None]
    return uv


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``np.cross`` of (n, 3) float64 arrays: the same arithmetic, without its dtype and axis
    handling (a third of the cost on 32k-ray chunks)."""
    out = np.empty(a.shape)
    a0, a1, a2 = a[:, 0], a[:, 1], a[:, 2]
    b0, b1, b2 = b[:, 0], b[:, 1], b[:, 2]
    np.subtract(a1 * b2, a2 * b1, out=out[:, 0])
    np.subtract(a2 * b0, a0 * b2, out=out[:, 1])
    np.subtract(a0 * b1, a1 * b0, out=out[:, 2])
    return out


def _norm(a: np.ndarray) -> np.ndarray:
    """Row lengths (n,) of (n, 3): ``np.linalg.norm(a, axis=1)``'s sum, in its order."""
    return np.sqrt(a[:, 0] * a[:, 0] + a[:, 1] * a[:, 1] + a[:, 2] * a[:, 2])


def _barycentric_point(corners: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """Points (n, 3) at barycentrics ``uv`` (n, 2) of triangles ``corners`` (n, 3, 3)."""
    c = corners
    w0 = 1.0 - uv[:, 0] - uv[:, 1]
    return w0[:, None] * c[:, 0] + uv[:, :1] * c[:, 1] + uv[:, 1:] * c[:, 2]


def spawn_origins(point: np.ndarray, geometric: np.ndarray, offset: np.ndarray,
                  direction: np.ndarray) -> np.ndarray:
    """Start points (n, 3) of rays leaving surface points along ``direction``.

    Mesh hits move ``offset`` off the plane along the geometric normal, to the side the ray
    leaves on; analytic hits have offset 0 and stay put (their ray carries its shape instead,
    see :mod:`raytrace.analytic`).
    """
    side = np.sign(np.einsum("ij,ij->i", direction, geometric))
    side[side == 0] = 1.0
    return point + (side * offset)[:, None] * geometric


def vertex_normals(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Unit vertex normals: the normalised sum of the unit normals of the faces sharing
    each vertex (seed 000, Gouraud: N_V = Σ N_k / |Σ N_k|). (V, 3) float64.
    """
    a, b, c = vertices[faces[:, 0]], vertices[faces[:, 1]], vertices[faces[:, 2]]
    fn = np.cross(b - a, c - a)
    fn /= np.linalg.norm(fn, axis=1, keepdims=True)
    acc = np.zeros_like(vertices)
    for k in range(3):
        np.add.at(acc, faces[:, k], fn)
    length = np.linalg.norm(acc, axis=1, keepdims=True)
    with np.errstate(invalid="ignore", divide="ignore"):
        out = acc / length
    out[length[:, 0] < 1e-12] = 0.0  # cancelling normals: shading falls back to the face
    return out
