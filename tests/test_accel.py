"""The accelerator: Embree against a brute-force Möller–Trumbore reference, analytic shapes
against closed-form distances, empty batches, and no self-hits of spawned rays at extreme
scene scales and far from the origin (EMBREEX_NOTES.md, "Precision")."""

from __future__ import annotations

import zlib

import numpy as np
import pytest
import trimesh
from helpers import make_scene, moller_trumbore, unit

import raytrace
from raytrace.accel import SHADOW_SHORTEN, Accelerator, spawn_origins
from raytrace.rays import NO_SHAPE
from raytrace.tables import scene_arrays


def accelerator(scene: raytrace.Scene) -> Accelerator:
    return Accelerator(scene_arrays(scene))


def random_units(rng: np.random.Generator, n: int) -> np.ndarray:
    v = rng.normal(size=(n, 3))
    return v / np.linalg.norm(v, axis=1, keepdims=True)


# -- Embree against brute force ------------------------------------------------------------------

def _mesh_scene():
    ico = trimesh.creation.icosphere(subdivisions=2, radius=1.3)
    box = trimesh.creation.box(extents=[1.0, 2.0, 0.5])
    objects = [raytrace.Mesh(mesh=ico, translate=[0.2, -0.1, -3.0]),
               raytrace.Mesh(mesh=box, rotate=[20.0, 35.0, 5.0], translate=[-1.5, 0.5, -1.0])]
    return make_scene(objects)  # camera at the origin: accelerator coordinates are world ones


def test_embree_matches_brute_force_on_random_rays():
    scene = _mesh_scene()
    acc = accelerator(scene)
    verts = np.concatenate([m.vertices for m in scene.objects])
    offsets = np.cumsum([0] + [len(m.vertices) for m in scene.objects[:-1]])
    faces = np.concatenate([m.faces + k for m, k in zip(scene.objects, offsets, strict=True)])
    rng = np.random.default_rng(2024)
    n = 4000
    origins = rng.uniform([-4, -3, -6], [4, 3, 2], size=(n, 3))
    targets = rng.uniform([-2.5, -1.7, -4.5], [1.7, 1.7, -0.3], size=(n, 3))
    dirs = (targets - origins) / np.linalg.norm(targets - origins, axis=1, keepdims=True)
    hits = acc.intersect(origins, dirs, np.full(n, NO_SHAPE))
    ref = moller_trumbore(origins, dirs, verts, faces)

    clear = np.abs(ref["margin"]) > 1e-5            # not grazing an edge or a silhouette
    assert clear.mean() > 0.98
    ref_hit = np.isfinite(ref["t"])
    assert 0.3 < ref_hit.mean() < 0.9               # a real mix of hits and misses
    np.testing.assert_array_equal(hits.hit[clear], ref_hit[clear])
    both = clear & ref_hit
    np.testing.assert_allclose(hits.t[both], ref["t"][both], rtol=1e-4)
    with np.errstate(invalid="ignore"):  # inf − inf where the ray misses
        distinct = both & ((ref["t2"] - ref["t"]) > 1e-4 * ref["t"])
    assert distinct.sum() > 0.9 * both.sum()
    np.testing.assert_array_equal(hits.triangle[distinct], ref["tri"][distinct])
    assert np.all(hits.shape[hits.hit] == NO_SHAPE)


def test_embree_respects_tmax():
    scene = _mesh_scene()
    acc = accelerator(scene)
    rng = np.random.default_rng(5)
    n = 500
    dirs = random_units(rng, n)
    dirs[:, 2] = -np.abs(dirs[:, 2]) - 1.0
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    origins = np.zeros((n, 3))
    full = acc.intersect(origins, dirs, np.full(n, NO_SHAPE))
    h = full.hit
    assert h.sum() > 50
    tmax = np.where(h, full.t * 0.999, np.inf)
    short = acc.intersect(origins, dirs, np.full(n, NO_SHAPE), tmax)
    # Cut just before the first hit: nothing closer exists.
    assert not short.hit[h].any()
    blocked = acc.occluded(origins, dirs, np.full(n, NO_SHAPE), np.where(h, full.t * 1.001, 1e3))
    assert blocked[h].all()


# -- analytic shapes against closed form ----------------------------------------------------------

def _closed_form_t(o, d, spheres, planes):
    """Smallest positive t: spheres by the textbook quadratic t = −b ± √(b² − c),
    planes by t = (p − o)·n / (d·n)."""
    best = np.full(len(o), np.inf)
    for c, r in spheres:
        oc = o - c
        b = np.einsum("ij,ij->i", oc, d)
        cc = np.einsum("ij,ij->i", oc, oc) - r * r
        disc = b * b - cc
        sq = np.sqrt(np.maximum(disc, 0))
        for t in (-b - sq, -b + sq):
            ok = (disc >= 0) & (t > 0)
            best = np.where(ok & (t < best), t, best)
    for p, nrm in planes:
        nrm = unit(nrm)
        with np.errstate(divide="ignore", invalid="ignore"):
            t = ((p - o) @ nrm) / (d @ nrm)
        best = np.where((t > 0) & (t < best), t, best)
    return best


def test_analytic_shapes_match_closed_form():
    spheres = [(np.array([0.0, 0.0, -5.0]), 1.0), (np.array([2.0, 1.0, -3.0]), 0.5),
               (np.array([-1.5, -0.5, -2.0]), 0.75)]
    planes = [(np.array([0.0, -2.0, 0.0]), np.array([0.1, 1.0, 0.2]))]
    cam = np.array([2.0, 1.0, 7.0])       # not the origin: the accelerator recentres on it
    objects = [raytrace.Sphere(c, r) for c, r in spheres]
    objects += [raytrace.Plane(p, nrm) for p, nrm in planes]
    acc = accelerator(make_scene(objects, camera=raytrace.Camera(position=cam)))
    rng = np.random.default_rng(7)
    n = 3000
    o = rng.uniform(-4, 4, size=(n, 3)) + [0, 0, -3]     # some start inside spheres
    d = random_units(rng, n)
    hits = acc.intersect(o - cam, d, np.full(n, NO_SHAPE))
    ref = _closed_form_t(o, d, spheres, planes)
    np.testing.assert_array_equal(hits.hit, np.isfinite(ref))
    assert 0.2 < hits.hit.mean() < 0.95
    np.testing.assert_allclose(hits.t[hits.hit], ref[hits.hit], rtol=1e-9, atol=1e-12)
    # The shape index: the sphere or plane whose surface the hit point lies on.
    p = o + hits.t[:, None] * d
    for s, (c, r) in enumerate(spheres):
        m = hits.shape == s
        np.testing.assert_allclose(np.linalg.norm(p[m] - c, axis=1), r, rtol=1e-9)
    m = hits.shape == len(spheres)
    np.testing.assert_allclose((p[m] - planes[0][0]) @ unit(planes[0][1]), 0, atol=1e-9)


def test_analytic_surface_normals_and_points():
    acc = accelerator(make_scene([raytrace.Sphere([0, 0, -5], 2.0),
                                  raytrace.Plane([0, -3, 0], [0, 2, 0])]))
    o = np.zeros((2, 3))
    d = np.array([[0.0, 0.0, -1.0], [0.0, -0.6, -0.8]])
    hits = acc.intersect(o, d, np.full(2, NO_SHAPE))
    np.testing.assert_allclose(hits.t, [3.0, 5.0])
    s = acc.surface(hits, o, d)
    np.testing.assert_allclose(s.point, [[0, 0, -3], [0, -3, -4]], atol=1e-12)
    np.testing.assert_allclose(s.geometric, [[0, 0, 1], [0, 1, 0]])
    assert np.all(s.offset == 0)


@pytest.mark.parametrize("kind", ["mesh", "analytic", "both", "none"])
def test_empty_batches(kind):
    objects = []
    if kind in ("mesh", "both"):
        objects.append(raytrace.Mesh(mesh=trimesh.creation.box(), translate=[0, 0, -3]))
    if kind in ("analytic", "both"):
        objects += [raytrace.Sphere([0, 0, -3], 1.0), raytrace.Plane([0, -1, 0], [0, 1, 0])]
    acc = accelerator(make_scene(objects))
    z3, zi = np.zeros((0, 3)), np.zeros(0, np.int64)
    hits = acc.intersect(z3, z3, zi)
    assert hits.t.shape == (0,) and hits.triangle.shape == (0,) and hits.uv.shape == (0, 2)
    blocked = acc.occluded(z3, z3, zi, np.zeros(0))
    assert blocked.shape == (0,) and blocked.dtype == bool
    surf = acc.surface(hits, z3, z3)
    assert surf.point.shape == (0, 3)


def test_occluded_when_analytic_shapes_block_every_ray():
    # Every ray is stopped by the plane first, so no ray is left for Embree (an empty batch).
    objects = [raytrace.Plane([0, 0, -1], [0, 0, 1]),
               raytrace.Mesh(mesh=trimesh.creation.box(), translate=[0, 0, -3])]
    acc = accelerator(make_scene(objects))
    n = 10
    d = np.tile([0.0, 0.0, -1.0], (n, 1))
    blocked = acc.occluded(np.zeros((n, 3)), d, np.full(n, NO_SHAPE), np.full(n, 10.0))
    assert blocked.all()


# -- no self-hits ----------------------------------------------------------------------------------

def _self_hit_objects(kind: str, s: float, shift: np.ndarray):
    if kind == "sphere":
        return raytrace.Sphere(shift, 1.0 * s)
    if kind == "plane":
        return raytrace.Plane(shift, [0.3, 1.0, 0.2])
    if kind == "disk":
        return raytrace.Disk(shift, [0.3, 1.0, 0.2], 1.5 * s)
    if kind == "icosphere":
        return raytrace.Mesh(mesh=trimesh.creation.icosphere(subdivisions=3), scale=s,
                             translate=shift)
    # A large flat quad of two triangles (half-size 50, or 1e5 and 1e7 for the floors users
    # model: their float32 rounding far exceeds a spawned ray's offset near the camera),
    # tilted so nothing is axis-aligned.
    half = {"quad": 50.0, "floor1e5": 1e5, "floor1e7": 1e7}[kind]
    quad = np.array([[-half, 0, -half], [half, 0, -half], [half, 0, half], [-half, 0, half]])
    return raytrace.Mesh(vertices=quad, faces=[[0, 2, 1], [0, 3, 2]], scale=s,
                         rotate=[17.0, 5.0, -11.0], translate=shift)


@pytest.mark.parametrize("kind", ["sphere", "plane", "disk", "icosphere", "quad", "floor1e5",
                                  "floor1e7"])
@pytest.mark.parametrize("scale,shift", [(1e-4, 0.0), (1.0, 0.0), (1e4, 0.0), (1.0, 1e5),
                                         (1e-4, 1e5)])
def test_no_self_hits(kind, scale, shift):
    """Seeded rays spawned from hits never re-hit their own (convex or flat) surface.

    Shadow rays towards lights on the side the normal faces (turned to the viewer) must be
    unoccluded: the object lies in the half-space behind its tangent plane, so nothing can
    block them. The same rays traced for a closest hit must miss, and rays going into the
    surface must leave a sphere at the far side of its chord and miss a flat surface.
    """
    rng = np.random.default_rng(zlib.crc32(f"{kind} {scale} {shift}".encode()))
    shift_v = np.full(3, shift)
    obj = _self_hit_objects(kind, scale, shift_v)
    cam_world = shift_v + scale * np.array([0.3, 2.0, 5.0])
    scene = make_scene([obj], camera=raytrace.Camera(position=cam_world, look_at=shift_v))
    acc = accelerator(scene)
    n = 6000
    target = rng.uniform(-1.2, 1.2, size=(n, 3)) * scale
    d = target + (shift_v - cam_world)         # camera-relative, float64
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    hits = acc.intersect(np.zeros((n, 3)), d, np.full(n, NO_SHAPE))
    h = hits.hit
    assert h.sum() > 2000                    # thousands of spawned rays per case
    hits = type(hits)(*(column[h] for column in hits))
    d = d[h]
    surf = acc.surface(hits, np.zeros((len(d), 3)), d)
    facing = surf.geometric * np.where(np.einsum("ij,ij->i", surf.geometric, d) < 0, 1.0,
                                       -1.0)[:, None]
    m = len(d)

    # Lights in the hemisphere the facing normal points into, at 0.5..10 scene units.
    out = random_units(rng, m)
    out *= np.sign(np.einsum("ij,ij->i", out, facing))[:, None]
    light = surf.point + out * rng.uniform(0.5, 10.0, size=(m, 1)) * scale
    delta = light - surf.point
    dist = np.linalg.norm(delta, axis=1)
    to_light = delta / dist[:, None]
    origin = spawn_origins(surf.point, surf.geometric, surf.offset, to_light)
    blocked = acc.occluded(origin, to_light, surf.shape, dist * (1.0 - SHADOW_SHORTEN))
    assert int(blocked.sum()) == 0, f"{int(blocked.sum())} of {m} wrongly shadowed"
    again = acc.intersect(origin, to_light, surf.shape)
    assert int(again.hit.sum()) == 0, f"{int(again.hit.sum())} of {m} self-hits"

    # Into the surface.
    inward = -out
    origin = spawn_origins(surf.point, surf.geometric, surf.offset, inward)
    through = acc.intersect(origin, inward, surf.shape)
    if kind in ("plane", "disk", "quad", "floor1e5", "floor1e7"):
        assert int(through.hit.sum()) == 0, "a ray leaving a flat surface re-hit it"
    elif kind == "sphere":
        assert through.hit.all()
        chord = 2.0 * scale * np.einsum("ij,ij->i", out, facing)   # 2r·cos θ
        np.testing.assert_allclose(through.t, chord, rtol=1e-6, atol=1e-9 * scale)
    else:
        ok = through.hit & (through.triangle != surf.triangle)
        assert ok.all(), f"{int((~ok).sum())} inward rays re-hit their own triangle or escaped"
