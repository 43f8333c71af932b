"""Whitted's recursion as a wavefront (raytrace.integrator), against closed forms and against a
slow per-ray recursive reference (tests/reference_tracer.py).

The contract (SCENE_FORMAT.md): for a ray hitting a surface of opacity t,

    I = t·(ka·Ia + Σ_l S_l·f_l·I_l·[kd·max(N·L, 0) + ks·spec] + kr·I_r + kt·I_t)
        + (1 − t)·I_behind

children have depth parent + 1 and are traced while depth ≤ max_depth and while their path
weight (product of t·kr, t·kt, 1 − t; max over RGB) is ≥ min_weight; S_l is the product of
t·kt + (1 − t) over the surfaces a shadow ray crosses; TIR sends the kt share along the mirror
direction; entering/leaving is decided by the outward geometric normal.

Every expected value below is worked out by hand in the test (comments give the derivation).
"""

from __future__ import annotations

import json
import math
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest
import trimesh
from helpers import aimed_camera, make_scene, pixel
from reference_tracer import ReferenceTracer
from test_threads import scene as every_ray_scene

import raytrace
from raytrace import (
    Camera,
    Checker,
    DirectionalLight,
    Material,
    Mesh,
    Plane,
    PointLight,
    RenderSettings,
    Sphere,
)
from raytrace import integrator as integrator_module
from raytrace.cli import main
from raytrace.film import read_exr
from raytrace.integrator import (
    KERNEL_FEATURES,
    MIN_ROUND_PASS_SAMPLES,
    RenderOptions,
    Stop,
    WhittedIntegrator,
    chunks,
    round_pass_size,
)
from raytrace.kernels.kinds import CAMERA, NO_SHAPE, REFRACTION
from raytrace.kernels.rays import gather_chunks, sample_chunks
from raytrace.rays import RayBatch
from raytrace.rendering import render_options

RTOL = 1e-6  # float32 output: ~6e-8 relative rounding, so 1e-6 is tight but safe
IOR = 1.5
THETA_C = math.asin(1.0 / IOR)  # critical angle of glass, 41.81°


# -- helpers ---------------------------------------------------------------------------------
def glass(kt=1.0, ior=IOR, kr=0.0, opacity=1.0) -> Material:
    """A dielectric with no local terms: what comes through it is kt·(what is behind)."""
    return Material(ka=0.0, kd=0.0, ks=0.0, kr=kr, kt=kt, ior=ior, opacity=opacity)


def ambient_only(ka, kr=0.0) -> Material:
    """A surface whose local term is ka·Ia whatever the geometry."""
    return Material(ka=ka, kd=0.0, ks=0.0, kr=kr)


def integrator(scene, max_depth=10, min_weight=0.0, background=0.0) -> WhittedIntegrator:
    opts = RenderOptions(width=1, height=1, max_depth=max_depth, min_weight=min_weight,
                         background=background)
    return WhittedIntegrator(scene, opts)


def one_ray(origin, direction) -> RayBatch:
    """A depth-0 batch of one ray (camera-relative origin, unit direction)."""
    d = np.asarray(direction, np.float64)
    d = d / np.linalg.norm(d)
    return RayBatch(np.asarray(origin, np.float64)[None].copy(), d[None].copy(),
                    np.zeros(1, np.int64), np.ones((1, 3)), 0,
                    np.full(1, NO_SHAPE, np.int64), np.full(1, CAMERA, np.int8))


def follow(integ: WhittedIntegrator, rays: RayBatch, kind: int) -> RayBatch:
    """One wavefront step (integrator.trace), keeping only the children of ``kind``."""
    children = integ.trace(rays, np.zeros((1, 3)))
    return children.take(children.kind == kind)


def box(extents, translate=(0.0, 0.0, 0.0), material=None, rotate=(0.0, 0.0, 0.0)) -> Mesh:
    return Mesh(mesh=trimesh.creation.box(extents=extents), translate=translate,
                rotate=rotate, material=material)


def quad(z, half, material) -> Mesh:
    """A square in the plane z = const, counter-clockwise seen from +z."""
    v = [[-half, -half, z], [half, -half, z], [half, half, z], [-half, half, z]]
    return Mesh(vertices=v, faces=[[0, 1, 2], [0, 2, 3]], material=material)


# -- depth semantics -------------------------------------------------------------------------
KA = np.array([0.1, 0.2, 0.3])
KD = np.array([0.2, 0.1, 0.05])
KS = 0.25
KR = np.array([0.9, 0.6, 0.3])
IA = 0.5
BG = np.array([0.3, 0.6, 0.9])
IL = np.array([1.0, 0.8, 0.6])


def mirror_sphere_scene(lights=True):
    # Camera on the sphere's axis at distance 4 from the centre (0.3, -0.2, 0), radius 1.
    # The 1×1 ray hits the pole P = (0.3, -0.2, 1) head-on: N = V = (0, 0, 1).
    m = Material(ka=KA, kd=KD, ks=KS, shininess=40, kr=KR)
    cam = aimed_camera([0.3, -0.2, 4.0], [0.3, -0.2, 0.0])
    light = [PointLight([0.3, -0.2, 4.0], IL)] if lights else []
    return make_scene([Sphere([0.3, -0.2, 0.0], 1.0, m)], light, cam, ambient=IA,
                      background=BG)


@pytest.mark.parametrize("max_depth", [0, 1, 5])
def test_mirror_sphere_sees_uniform_background(max_depth):
    # Light at the camera, d = 3, attenuation [1, 0, 0] → f = 1; N·L = 1; Phong R = V so
    # (V·R)^40 = 1. Local = ka·Ia + Il·(kd·1 + ks·1). The reflected ray leaves along +z and
    # hits nothing (a lone convex sphere; lights are invisible): I_r = background.
    # max_depth 0: local only; max_depth ≥ 1: local + kr·background.
    local = KA * IA + IL * (KD + KS)
    expected = local + (KR * BG if max_depth >= 1 else 0.0)
    image = raytrace.render(mirror_sphere_scene(), width=1, height=1, max_depth=max_depth)
    np.testing.assert_allclose(image.rgb[0, 0], expected, rtol=RTOL)
    rays = image.stats["rays"]
    assert rays["reflection"] == min(max_depth, 1)
    assert rays["shadow"] == 1 and rays["refraction"] == 0
    assert image.stats["pruned"]["depth"] == (1 if max_depth == 0 else 0)


def test_mirror_sphere_every_pixel_is_ambient_plus_kr_background():
    # No lights: whatever point of a lone mirror sphere a pixel sees, its reflection escapes,
    # so a pixel is either background (a miss) or ka·Ia + kr·background (a hit). Both occur.
    image = raytrace.render(mirror_sphere_scene(lights=False), width=16, height=12,
                            max_depth=3)
    rgb = image.rgb.reshape(-1, 3).astype(np.float64)
    on = np.isclose(rgb, KA * IA + KR * BG, rtol=RTOL).all(axis=1)
    off = np.isclose(rgb, BG, rtol=RTOL).all(axis=1)
    assert (on | off).all() and on.sum() > 20 and off.sum() > 20
    assert image.stats["rays"]["reflection"] == on.sum()
    assert image.stats["rays"]["shadow"] == 0


@pytest.mark.parametrize("kind", ["planes", "quads"])
@pytest.mark.parametrize("depth", [1, 5, 50])
def test_facing_mirrors_sum_the_geometric_series(kind, depth):
    # Mirrors at z = -1 and z = 2, the camera between them looking down -z along their common
    # normal. Every bounce sees the local term L = ka·Ia (ambient only: constant) and passes
    # kr on: I = L·(1 + kr + … + kr^D) = L·(1 − kr^(D+1))/(1 − kr); the ray never escapes, so
    # the (absurd) background must not show. Exactly D reflection rays are traced, and the
    # depth-(D+1) child is the one ray pruned by depth.
    kr, ka, ia = 0.9, np.array([0.2, 0.1, 0.05]), np.array([1.0, 0.5, 0.25])
    m = ambient_only(ka, kr=kr)
    if kind == "planes":
        objects = [Plane([0, 0, -1.0], [0, 0, 1.0], m), Plane([0, 0, 2.0], [0, 0, -1.0], m)]
    else:
        objects = [quad(-1.0, 50.0, m), quad(2.0, 50.0, m)]
    cam = aimed_camera([0.25, 0.5, 0.5], [0.25, 0.5, -1.0])
    scene = make_scene(objects, [], cam, ambient=ia, background=7.0)
    image = raytrace.render(scene, width=1, height=1, max_depth=depth)
    expected = ka * ia * (1.0 - kr ** (depth + 1)) / (1.0 - kr)
    np.testing.assert_allclose(image.rgb[0, 0], expected, rtol=RTOL)
    assert image.stats["rays"]["reflection"] == depth
    assert image.stats["rays"]["camera"] == 1
    assert image.stats["pruned"] == {"depth": 1, "weight": 0}


# -- refraction ------------------------------------------------------------------------------
SLAB_TOP, SLAB_H = -0.75, 0.5  # box of extents (8, 0.5, 8) centred at y = -1


@pytest.mark.parametrize("theta_deg", [10.0, 30.0, 60.0, 80.0])
def test_glass_slab_displaces_a_ray_by_h_tan_theta_t(theta_deg):
    # A ray from (-4, 0, 0) at θi from the vertical hits the slab top y = -0.75 at
    # x0 = -4 + 0.75·tan θi, refracts to sin θt = sin θi / 1.5, crosses the thickness h = 0.5
    # and leaves the bottom y = -1.25 at x1 = x0 + h·tan θt, parallel to the incoming ray.
    # (The lateral shift from the undeviated line is h·sin(θi − θt)/cos θt.)
    # Mesh hit points come from Embree's float32 barycentrics on the float64 triangle: on the
    # face's plane, but up to ~2⁻²⁴ × the 10-unit face off along it, hence atol 1e-6.
    ti = math.radians(theta_deg)
    tt = math.asin(math.sin(ti) / IOR)
    d = np.array([math.sin(ti), -math.cos(ti), 0.0])
    scene = make_scene([box((10.0, SLAB_H, 10.0), (0, -1.0, 0), glass())], [],
                       Camera([0, 0, 0], [0, -1, 0], up=[0, 0, 1]))
    integ = integrator(scene)
    inside = follow(integ, one_ray([-4.0, 0, 0], d), REFRACTION)
    out = follow(integ, inside, REFRACTION)
    assert len(inside) == 1 and len(out) == 1
    # Inside: Snell's direction; outside again: the incoming direction.
    np.testing.assert_allclose(inside.direction[0], [math.sin(tt), -math.cos(tt), 0.0],
                               atol=1e-12)
    np.testing.assert_allclose(out.direction[0], d, atol=1e-12)

    # A ray spawned from a mesh hit starts a few float32 ulps off the face along its normal
    # (here y), so its x is the hit point's x.
    x0, x1 = inside.origin[0, 0], out.origin[0, 0]
    assert x0 == pytest.approx(-4.0 + 0.75 * math.tan(ti), abs=1e-6)
    assert x1 - x0 == pytest.approx(SLAB_H * math.tan(tt), abs=2e-6)
    shift = (x1 - (-4.0 + 1.25 * math.tan(ti))) * math.cos(ti)  # perpendicular to the ray
    assert -shift == pytest.approx(SLAB_H * math.sin(ti - tt) / math.cos(tt), abs=2e-6)


@pytest.mark.parametrize("side", [+1, -1])
def test_slab_shift_seen_end_to_end_on_a_checker_edge(side):
    # The same slab, kt = 1, in front of a floor y = -2 with an ambient-only checker of scale
    # 10: its x cell changes where floor(x/10 + 1e-4) steps, at x = -1e-3 (near z = 0 the z
    # cell is 0; at y = -2 the y cell is floor(-0.1999) = -1). The refracted ray lands at
    #   x_f = c + 0.75·tan θi (to the slab) + 0.5·tan θt (through) + 0.75·tan θi (to the floor)
    # for a camera at x = c. Put the predicted landing 2e-5 to one side of the edge: x ≥ edge
    # gives cells (0, -1, 0), sum odd → colors[1]; x < edge gives sum even → colors[0]. The
    # undeviated ray would land 0.5·(tan θi − tan θt) ≈ 0.19 away, in the same cell both times.
    ti = math.radians(40.0)
    tt = math.asin(math.sin(ti) / IOR)
    x_f = 1.5 * math.tan(ti) + SLAB_H * math.tan(tt)
    c = -1e-3 - x_f + side * 2e-5
    a, b = np.array([0.9, 0.8, 0.7]), np.array([0.1, 0.2, 0.3])
    floor = Material(ka=Checker((a, b), 10.0), kd=0.0)
    cam = Camera([c, 0, 0], [c + math.sin(ti), -math.cos(ti), 0], up=[0, 0, 1])
    scene = make_scene([box((40.0, SLAB_H, 40.0), (0, -1.0, 0), glass()),
                        Plane([0, -2.0, 0], [0, 1, 0], floor)], [], cam, ambient=1.0)
    got = pixel(scene, max_depth=3)
    np.testing.assert_allclose(got, b if side > 0 else a, rtol=RTOL)


def test_ior_one_refracts_bit_exactly_straight():
    # η = 1: the refraction must hand back the incoming direction bit for bit, entering and
    # leaving (raytrace.optics.refract's radicand is cos²θ exactly then), at any angle.
    scene = make_scene([box((16.0, SLAB_H, 16.0), (0, -1.0, 0), glass(ior=1.0))], [],
                       Camera([0, 0, 0], [0, -1, 0], up=[0, 0, 1]))
    integ = integrator(scene)
    rng = np.random.default_rng(3)
    for _ in range(8):
        d = rng.normal(size=3)
        d[1] = -abs(d[1]) - 0.3  # downwards, to the slab
        ray = one_ray([0, 0, 0], d)
        inside = follow(integ, ray, REFRACTION)
        out = follow(integ, inside, REFRACTION)
        assert len(out) == 1
        assert np.array_equal(inside.direction, ray.direction)
        assert np.array_equal(out.direction, ray.direction)


def _lit_scene(extra=()):
    """A lit checker floor and a diffuse sphere, seen from z = 6; light at (5, 5, 0)."""
    floor = Material(kd=Checker((np.array([0.8, 0.8, 0.7]), np.array([0.2, 0.3, 0.2])), 0.7),
                     ks=0.3, shininess=20)
    ball = Material(kd=[0.7, 0.3, 0.2], ks=0.5, shininess=50, highlight="blinn")
    objects = [Plane([0, 0, 0], [0, 1, 0], floor), Sphere([0.3, 0.8, -1.0], 0.8, ball),
               *extra]
    return make_scene(objects, [PointLight([5, 5, 0], 1.5, [1, 0.02, 0.01])],
                      Camera([0, 1.2, 6], [0, 0.6, 0], fov=45), ambient=0.1,
                      background=[0.2, 0.3, 0.4])


@pytest.mark.parametrize("kt,opacity", [(1.0, 1.0), ([0.9, 0.7, 0.5], 1.0),
                                         ([0.8, 0.6, 0.4], 0.5), (0.0, 0.25)])
def test_ior_one_slab_only_scales_by_kt_and_opacity(kt, opacity):
    # An ior-1 slab (z in [4.8, 5.2]) covers the whole view in front of the camera; the
    # light at z = 0 lights the scene from behind it, so no shadow ray crosses it. Each of the
    # two crossings passes the ray on straight (ior 1) with weight t·kt (refraction) plus
    # 1 − t (see-through), so every pixel is (t·kt + 1 − t)² × the slab-less pixel.
    # max_depth 2 is just enough: the floor and ball are neither reflective nor transparent.
    # Only the spawn offsets (3 float32 ulps of the slab's ~3-unit camera-relative extent,
    # ~1e-6 along its normal) move the rays sideways; the steepest pixels (the ball's
    # highlight) change by ~1e-5 relative for that, hence rtol 3e-5.
    slab = box((6.0, 6.0, 0.4), (0, 0, 5.0), glass(kt=kt, ior=1.0, opacity=opacity))
    with_slab = raytrace.render(_lit_scene([slab]), width=32, height=24, max_depth=2)
    without = raytrace.render(_lit_scene(), width=32, height=24, max_depth=2)
    factor = (opacity * np.asarray(kt, np.float64) + 1.0 - opacity) ** 2
    np.testing.assert_allclose(with_slab.rgb, factor * without.rgb.astype(np.float64),
                               rtol=3e-5, atol=1e-7)
    assert without.rgb.std() > 0.05  # the picture has content
    # Every pixel crosses the slab: c children per crossing (refraction if kt > 0, see-through
    # if t < 1), so c + c² secondary rays per pixel.
    c = int(np.any(np.asarray(kt) > 0)) + int(opacity < 1)
    rays = with_slab.stats["rays"]
    assert rays["refraction"] + rays["see_through"] == 32 * 24 * (c + c * c)


@pytest.mark.parametrize("delta_deg,tir", [(-0.01, False), (+0.01, True)])
def test_critical_angle_inside_a_glass_block(delta_deg, tir):
    # The camera sits inside a glass cube (ior 1.5, kt = 1, nothing else) and looks at the top
    # face at θ from its normal. Leaving glass, sin θ_out = 1.5·sin θ: below the critical
    # angle asin(1/1.5) = 41.81° the ray leaves and sees the background (weight kt = 1); just
    # above it, TIR sends it down to the bottom face, where (max_depth 1) the depth-1 hit adds
    # its local term 0 and stops.
    theta = THETA_C + math.radians(delta_deg)
    d = [math.sin(theta), math.cos(theta), 0.0]
    cube = box((2.0, 2.0, 2.0), material=glass())
    scene = make_scene([cube], [], aimed_camera([0, 0, 0], d, up=[0, 0, 1]), background=BG)
    image = raytrace.render(scene, width=1, height=1, max_depth=1)
    np.testing.assert_allclose(image.rgb[0, 0], np.zeros(3) if tir else BG, rtol=RTOL)
    assert image.stats["total_internal_reflections"] == int(tir)
    assert image.stats["rays"]["refraction"] == 1
    if not tir:  # the leaving direction obeys Snell's law, grazing at 88.6°
        integ = integrator(scene)
        out = follow(integ, one_ray([0, 0, 0], d), REFRACTION)
        sin_out = IOR * math.sin(theta)
        np.testing.assert_allclose(out.direction[0],
                                   [sin_out, math.sqrt(1 - sin_out**2), 0.0], rtol=1e-9)


# -- shadows ---------------------------------------------------------------------------------
SH_KA, SH_IA = np.array([0.3, 0.2, 0.1]), 0.25
SH_KD, SH_IL = np.array([0.6, 0.5, 0.4]), np.array([1.0, 0.9, 0.8])


def _shadow_pixel(blocker_material, mesh=False, blockers=((0.0, 2.0, 0.0),)) -> np.ndarray:
    # Floor y = 0, seen at P = (0, 0, 0) from (0, 3, 3); light straight above at (0, 4, 0).
    # The blockers (r = 0.5) sit on the vertical shadow ray, away from the camera ray (the
    # camera line passes (0, 1, 1) at 1.41 from (0, 2, 0)).
    floor = Material(ka=SH_KA, kd=SH_KD, ks=0.0)
    objects = [Plane([0, 0, 0], [0, 1, 0], floor)]
    for c in blockers:
        if mesh:  # a rotated icosphere, so the vertical ray meets no edge or vertex
            objects.append(Mesh(mesh=trimesh.creation.icosphere(2, 0.5), rotate=[17, 31, 7],
                                translate=c, material=blocker_material))
        else:
            objects.append(Sphere(c, 0.5, blocker_material))
    light = PointLight([0, 4, 0], SH_IL, [0.5, 0.1, 0.05])
    scene = make_scene(objects, [light], aimed_camera([0, 3, 3], [0, 0, 0]), ambient=SH_IA)
    return pixel(scene, max_depth=3)


# Unshadowed: N·L = 1, d = 4, f = 1/(0.5 + 0.1·4 + 0.05·16) = 1/1.7; lit = kd·Il·f.
LIT = SH_KD * SH_IL / 1.7
AMB = SH_KA * SH_IA


def test_shadow_setup_unblocked():
    np.testing.assert_allclose(_shadow_pixel(None, blockers=()), AMB + LIT, rtol=RTOL)


@pytest.mark.parametrize("mesh", [False, True])
@pytest.mark.parametrize("kt,opacity,factor", [
    # glass, coloured kt: two crossings → kt² per channel
    ([0.9, 0.6, 0.3], 1.0, np.array([0.9, 0.6, 0.3]) ** 2),
    # opaque: nothing gets through → ambient only
    (0.0, 1.0, np.zeros(3)),
    # opacity t = 0.5 with kt: (t·kt + 1 − t)² = (0.5·kt + 0.5)²
    ([0.8, 0.6, 0.4], 0.5, np.array([0.9, 0.8, 0.7]) ** 2),
    # opacity 0.25, no kt: (1 − t)² = 0.75²
    (0.0, 0.25, np.full(3, 0.75**2)),
])
def test_shadow_through_a_sphere(mesh, kt, opacity, factor):
    # A sphere's shadow ray crosses two surfaces, each passing t·kt + (1 − t).
    m = Material(kd=0.4, kt=kt, opacity=opacity)
    np.testing.assert_allclose(_shadow_pixel(m, mesh), AMB + factor * LIT, rtol=RTOL,
                               atol=1e-9)


def test_shadow_through_two_glass_spheres_multiplies_four_crossings():
    kt = np.array([0.9, 0.8, 0.7])
    got = _shadow_pixel(glass(kt=kt), blockers=((0.0, 1.2, 0.0), (0.0, 2.6, 0.0)))
    np.testing.assert_allclose(got, AMB + kt**4 * LIT, rtol=RTOL)


# -- the wavefront equals the recursion --------------------------------------------------------
def reference_scene() -> raytrace.Scene:
    """Mirror sphere, glass sphere holding an air bubble (TIR at the bubble), a half-opaque
    transmitting sphere, a glass cube mesh (TIR between faces), a checker plane, two lights."""
    floor = Material(kd=Checker((np.array([0.9, 0.9, 0.9]), np.array([0.2, 0.3, 0.2])), 1.0),
                     ks=0.2, kr=0.1)
    mirror = Material(kd=0.05, ks=0.5, shininess=60, kr=[0.9, 0.8, 0.7])
    glass_m = Material(kd=0.0, ks=0.5, shininess=200, highlight="blinn", kr=0.05,
                       kt=[0.9, 0.95, 0.85], ior=1.5)
    bubble = Material(kd=0.0, ks=0.0, kr=0.05, kt=0.95, ior=1 / 1.5)
    veil = Material(kd=[0.8, 0.2, 0.2], ks=0.3, kt=0.4, ior=1.3, opacity=0.5)
    cube = Material(kd=0.02, ks=0.4, kr=0.04, kt=[0.85, 0.9, 0.95], ior=1.5)
    return make_scene(
        [Plane([0, 0, 0], [0, 1, 0], floor), Sphere([-1.3, 0.8, -0.5], 0.8, mirror),
         Sphere([0.9, 0.9, 0.6], 0.9, glass_m), Sphere([1.05, 1.0, 0.75], 0.45, bubble),
         Sphere([-0.2, 0.5, 1.2], 0.5, veil),
         box((0.8, 0.8, 0.8), (1.6, 0.45, -1.6), cube, rotate=(0, 30, 0))],
        [PointLight([3, 5, 4], 1.0, [1, 0.05, 0.01]), DirectionalLight([-1, -2, -1], 0.5)],
        Camera([0, 1.5, 6], [0, 0.8, 0], fov=45), ambient=0.1, max_depth=4,
        background=[0.2, 0.3, 0.5])


@pytest.mark.parametrize("min_weight", [0.0, 0.08])
def test_wavefront_equals_recursive_reference(min_weight):
    # The reference shares nothing with the renderer but the scene description (its own
    # float64 intersection, camera and shading; tests/test_reference_tracer.py). On this
    # scene the two agree to the float32 rounding of the output: at most 2.3e-7 relative,
    # measured at 24×18 and 96×72 with both min_weights; the cube's flat faces move spawned
    # rays by ~1e-7 of the scene (the renderer's offset) without moving a pixel by more.
    # Hence rtol 1e-6, and the ray counts of every kind must be equal.
    scene = reference_scene()
    image = raytrace.render(scene, width=24, height=18, min_weight=min_weight)
    ref = ReferenceTracer(scene, min_weight=min_weight)
    expected = ref.render(24, 18)
    np.testing.assert_allclose(image.rgb, expected, rtol=1e-6, atol=1e-9)
    st, c = image.stats, ref.counts
    assert st["rays"]["camera"] == c.camera == 24 * 18
    assert st["rays"]["reflection"] == c.reflection
    assert st["rays"]["refraction"] == c.refraction
    assert st["rays"]["see_through"] == c.see_through
    assert st["rays"]["shadow"] == c.shadow
    assert st["total_internal_reflections"] == c.tir > 0
    assert st["pruned"] == {"depth": c.pruned_depth, "weight": c.pruned_weight}
    assert (c.pruned_weight > 0) == (min_weight > 0)


def test_image_does_not_depend_on_pass_size_or_threads():
    # Per-depth compaction and the pass split must not change a pixel: it is a sum of the
    # same terms. 37 samples a pass does not divide the 432 pixels.
    scene = reference_scene()
    a = raytrace.render(scene, width=24, height=18)
    b = raytrace.render(scene, width=24, height=18, pass_samples=37, threads=2)
    np.testing.assert_array_equal(a.rgb, b.rgb)
    assert a.stats["rays"] == b.stats["rays"]


def test_no_batch_outgrows_the_pass():
    # Glass doubles the rays at every hit; a batch larger than the pass is split and its
    # chunks finished one after another (depth first), so no trace() call sees more rays
    # than a pass holds, and the image is the same sum (up to the order of float additions).
    sizes = []

    class Recording(WhittedIntegrator):
        compiled = False  # the Python loop, which calls trace() a batch at a time

        def trace(self, rays, samples):
            sizes.append(len(rays))
            return super().trace(rays, samples)

    scene = reference_scene()
    opts = RenderOptions(width=24, height=18, max_depth=6, background=[0.2, 0.3, 0.5],
                         pass_samples=16)
    small = Recording(scene, opts).render()
    assert max(sizes) <= 16 and len(sizes) > 27 * 6
    whole = raytrace.render(scene, width=24, height=18, max_depth=6)
    np.testing.assert_allclose(small.rgb, whole.rgb, rtol=1e-6, atol=1e-9)
    assert small.stats["rays"] == whole.stats["rays"]


def test_chunks_are_each_chunks_rays_in_batch_order():
    # The compiled regrouping (a stable counting sort) gives every chunk exactly the rays
    # numpy's stable argsort of the chunk ids gives, column by column, bounds included.
    rng = np.random.default_rng(14)
    n, samples, most = 700, 90, 37
    rays = RayBatch(rng.normal(size=(n, 3)), rng.normal(size=(n, 3)),
                    rng.integers(0, samples, n), rng.random((n, 3)), 3,
                    rng.integers(-1, 6, n), rng.integers(0, 4, n).astype(np.int8))
    chunk = np.empty(n, np.int64)
    count = sample_chunks(rays.sample, samples, most, chunk)
    order = np.argsort(chunk, kind="stable")
    out = RayBatch(np.empty((n, 3)), np.empty((n, 3)), np.empty(n, np.int64),
                   np.empty((n, 3)), 3, np.empty(n, np.int64), np.empty(n, np.int8))
    bounds = gather_chunks(chunk, count, rays.record, out.record)
    np.testing.assert_array_equal(bounds, np.searchsorted(chunk[order], np.arange(count + 1)))
    for name in ("origin", "direction", "sample", "weight", "origin_shape", "kind"):
        np.testing.assert_array_equal(getattr(out, name), getattr(rays, name)[order])
    parts = chunks(rays, samples, most)
    assert len(parts) == count > 10
    for c, part in enumerate(parts):
        rows = np.flatnonzero(chunk == c)
        assert part.depth == 3 and 0 < len(part) <= most
        for name in ("origin", "direction", "sample", "weight", "origin_shape", "kind"):
            np.testing.assert_array_equal(getattr(part, name), getattr(rays, name)[rows])


# -- statistics ------------------------------------------------------------------------------
def test_no_reflective_or_transparent_material_means_no_secondary_rays():
    image = raytrace.render(_lit_scene(), width=16, height=12, max_depth=5)
    rays = image.stats["rays"]
    assert rays["reflection"] == rays["refraction"] == rays["see_through"] == 0
    assert rays["shadow"] > 0
    assert rays["total"] == rays["camera"] + rays["shadow"] == 16 * 12 + rays["shadow"]
    assert image.stats["pruned"] == {"depth": 0, "weight": 0}


def test_no_lights_means_no_shadow_rays():
    scene = reference_scene()
    scene.lights = []
    image = raytrace.render(scene, width=16, height=12)
    assert image.stats["rays"]["shadow"] == 0
    assert image.stats["rays"]["reflection"] > 0 and image.stats["rays"]["refraction"] > 0


def test_min_weight_prunes_the_mirror_series_where_max_kr_to_the_k_drops_below():
    # Facing mirrors, kr = (0.9, 0.5, 0.1): a depth-k ray's weight is max(kr^k) = 0.9^k.
    # With min_weight 0.5: 0.9^6 = 0.531 is traced, 0.9^7 = 0.478 is not. So per pixel 6
    # reflection rays and 1 pruned by weight, none by depth (max_depth 10); every pixel (the
    # planes are parallel, so each ray zig-zags forever) is L·Σ_{k=0..6} kr^k per channel.
    kr = np.array([0.9, 0.5, 0.1])
    ka, ia = 0.3, 0.5
    m = ambient_only(ka, kr=kr)
    scene = make_scene([Plane([0, 0, -1.0], [0, 0, 1.0], m), Plane([0, 0, 2.0], [0, 0, -1.0], m)],
                       [], Camera([0, 0, 0.5], [0, 0, -1.0], fov=30), ambient=ia)
    image = raytrace.render(scene, width=4, height=3, max_depth=10, min_weight=0.5)
    expected = ka * ia * (1 - kr**7) / (1 - kr)
    np.testing.assert_allclose(image.rgb, np.broadcast_to(expected, (3, 4, 3)), rtol=RTOL)
    assert image.stats["rays"]["reflection"] == 12 * 6
    assert image.stats["pruned"] == {"depth": 0, "weight": 12}
    # max_depth 3 stops it first: 3 rays traced, the depth-4 one pruned by depth.
    image = raytrace.render(scene, width=4, height=3, max_depth=3, min_weight=0.5)
    assert image.stats["rays"]["reflection"] == 12 * 3
    assert image.stats["pruned"] == {"depth": 12, "weight": 0}


def test_min_weight_prunes_see_through_rays_of_stacked_veils():
    # Five parallel veils (opacity t = 0.5, no kr/kt) at z = -1 … -5, ambient only. The ray
    # through k veils has weight 0.5^k; min_weight 0.2 keeps 0.5 and 0.25, prunes 0.125: two
    # see-through rays traced, one pruned by weight. Pixel = Σ_{k=0..2} 0.5^k · t·ka·Ia.
    ka, ia = np.array([0.4, 0.2, 0.1]), 1.0
    veil = Material(ka=ka, kd=0.0, opacity=0.5)
    veils = [Plane([0, 0, -z], [0, 0, 1.0], veil) for z in range(1, 6)]
    scene = make_scene(veils, [], Camera([0, 0, 0], [0, 0, -1]), ambient=ia, background=5.0)
    image = raytrace.render(scene, width=1, height=1, max_depth=10, min_weight=0.2)
    np.testing.assert_allclose(image.rgb[0, 0], 0.5 * ka * ia * (1 + 0.5 + 0.25), rtol=RTOL)
    assert image.stats["rays"]["see_through"] == 2
    assert image.stats["pruned"] == {"depth": 0, "weight": 1}
    # Without pruning all five are crossed and the background shows with weight 0.5^5.
    image = raytrace.render(scene, width=1, height=1, max_depth=10)
    expected = 0.5 * ka * ia * (1 - 0.5**5) / 0.5 + 0.5**5 * 5.0
    np.testing.assert_allclose(image.rgb[0, 0], expected, rtol=RTOL)
    assert image.stats["rays"]["see_through"] == 5


@pytest.mark.parametrize("depth", [1, 2, 7])
def test_tir_count_of_a_ray_trapped_in_a_glass_cube(depth):
    # The camera inside a glass cube (half-size 1) at (0.2, -0.1, 0) looks along (1, 1, 0):
    # every wall is met at 45° > 41.81°, so every hit is a TIR and the ray rattles around the
    # xy-plane without escaping. Hits at depth 0 … D−1 each spawn a TIR ray within max_depth D:
    # D TIRs, D refraction-kind rays; the depth-D hit's child is pruned. No local term → 0.
    cube = box((2.0, 2.0, 2.0), material=glass())
    cam = aimed_camera([0.2, -0.1, 0.0], [1.2, 0.9, 0.0], up=[0, 0, 1])
    image = raytrace.render(make_scene([cube], [], cam, background=1.0), width=1, height=1,
                            max_depth=depth)
    assert image.stats["total_internal_reflections"] == depth
    assert image.stats["rays"]["refraction"] == depth
    assert image.stats["pruned"]["depth"] == 1
    np.testing.assert_array_equal(image.rgb, 0.0)


def _trapped_in_glowing_glass(kr, kt, ka, ia, depth, min_weight):
    """The one-pixel render of the trapped ray of the test above, in glass that reflects
    (kr), transmits (kt, ior 1.5) and glows (ka under ambient Ia)."""
    mat = Material(kd=0.0, ka=ka, ks=0.0, kr=kr, kt=kt, ior=1.5)
    cube = box((2.0, 2.0, 2.0), material=mat)
    cam = aimed_camera([0.2, -0.1, 0.0], [1.2, 0.9, 0.0], up=[0, 0, 1])
    return raytrace.render(make_scene([cube], [], cam, ambient=ia), width=1, height=1,
                           max_depth=depth, min_weight=min_weight)


@pytest.mark.parametrize("depth", [1, 3, 6])
def test_tir_and_reflection_on_one_path_are_one_ray(depth):
    # The same trapped ray, now in glass that also reflects (kr = 0.1, kt = 0.8) and glows
    # (ka = 0.5 under Ia = 0.2). At every wall the reflection and the TIR share leave along
    # the same mirror direction: the recursion I_k = ka·Ia + kr·I_{k+1} + kt·I_{k+1} traced as
    # one ray of weight (kr + kt)^k per depth (not 2^k rays), so
    #   pixel = ka·Ia·Σ_{k=0..D} (kr + kt)^k,
    # D reflection-kind rays, no refraction-kind ray, still D TIRs, and the depth-D hit's one
    # child pruned.
    kr, kt, ka, ia = 0.1, 0.8, 0.5, 0.2
    image = _trapped_in_glowing_glass(kr, kt, ka, ia, depth, 0.0)
    expected = ka * ia * sum((kr + kt) ** k for k in range(depth + 1))
    np.testing.assert_allclose(image.rgb[0, 0], np.full(3, expected), rtol=RTOL)
    st = image.stats
    assert st["rays"]["reflection"] == depth and st["rays"]["refraction"] == 0
    assert st["total_internal_reflections"] == depth
    assert st["pruned"]["depth"] == 1
    # With min_weight 0.5 the contract prunes each path by its own weight, so the two shares
    # are two rays again. The depth-k hit has weight 0.8^k (only TIR shares reach it); its
    # reflection share 0.1·0.8^k < 0.5 is pruned by weight at every hit, its TIR share 0.8^(k+1)
    # is traced while ≥ 0.5: 0.8, 0.64, 0.512 are, 0.4096 is not. So hits at depths
    # 0 … M = min(D, 3), and
    #   pixel = ka·Ia·Σ_{k=0..M} 0.8^k,
    # M refraction-kind rays, no reflection-kind ray. The hits at depths 0 … min(D − 1, 3) have
    # their children within max_depth: min(D, 4) TIRs, and each prunes its reflection by weight,
    # the depth-3 one (if D ≥ 4) its TIR share too: min(D, 4) + [D ≥ 4] pruned by weight. If
    # D ≤ 3 the depth-D hit's two children (0.1·0.8^D and 0.8^(D+1), both > 0) are pruned by
    # depth; else none.
    pruned = _trapped_in_glowing_glass(kr, kt, ka, ia, depth, 0.5)
    m = min(depth, 3)
    expected = ka * ia * sum(kt**k for k in range(m + 1))
    np.testing.assert_allclose(pruned.rgb[0, 0], np.full(3, expected), rtol=RTOL)
    st = pruned.stats
    assert st["rays"]["reflection"] == 0 and st["rays"]["refraction"] == m
    assert st["total_internal_reflections"] == min(depth, 4)
    assert st["pruned"] == {"depth": 2 if depth <= 3 else 0,
                            "weight": min(depth, 4) + (depth >= 4)}


@pytest.mark.parametrize("depth", [2, 3, 5])
def test_min_weight_keeps_tir_and_reflection_as_two_rays(depth):
    # The trapped ray again, in glass with kr = 0.7, kt = 0.75 (ka = 0.5, Ia = 0.2), and
    # min_weight 0.33. Every hit is a TIR: both shares leave along the mirror direction, as
    # two rays (a reflection-kind one of weight w·0.7 and a refraction-kind one of w·0.75),
    # so depth k holds 2^k rays of weights 0.7^a·0.75^(k−a). At depth 3 the smallest is
    # 0.7^3 = 0.343 ≥ 0.33: all 8 traced; at depth 4 the largest is 0.75^4 = 0.316 < 0.33: all
    # 16 pruned by weight. With M = min(D, 3):
    #   pixel = ka·Ia·Σ_{k=0..M} Σ_a C(k, a)·0.7^a·0.75^(k−a) = ka·Ia·Σ_{k=0..M} 1.45^k,
    #   reflection = refraction = Σ_{k=1..M} 2^(k−1) = 2^M − 1 rays,
    #   TIRs = hits at depths 0 … min(D − 1, 3) = Σ 2^k = 2^min(D, 4) − 1,
    #   pruned: by depth 2·2^D (the depth-D hits' children) if D ≤ 3, else 16 by weight.
    # One merged ray per depth (weight 1.45^k, never under 0.33) would give D rays and
    # ka·Ia·Σ_{k=0..D} 1.45^k instead.
    kr, kt, ka, ia = 0.7, 0.75, 0.5, 0.2
    image = _trapped_in_glowing_glass(kr, kt, ka, ia, depth, 0.33)
    m = min(depth, 3)
    expected = ka * ia * sum((kr + kt) ** k for k in range(m + 1))
    np.testing.assert_allclose(image.rgb[0, 0], np.full(3, expected), rtol=RTOL)
    st = image.stats
    assert st["rays"]["reflection"] == st["rays"]["refraction"] == 2**m - 1
    assert st["total_internal_reflections"] == 2 ** min(depth, 4) - 1
    assert st["pruned"] == ({"depth": 2 * 2**depth, "weight": 0} if depth <= 3
                            else {"depth": 0, "weight": 16})


# -- analytic spheres without an epsilon ------------------------------------------------------
@pytest.mark.parametrize("scale", [1e-4, 1.0, 1e4])
def test_refracted_ray_finds_the_far_side_of_a_sphere(scale):
    # Sphere of radius r = scale around c = scale·(0.3, 0.1, -5), camera at scale·(0, 0, 2.5)
    # (not the origin: the scene is recentred on it). A ray with impact parameter 0.6·r hits
    # at sin θi = 0.6, refracts to sin θt = 0.4 and must meet the far side after the chord
    # 2·r·cos θt, leave at the symmetric point with sin θ = 0.6 again, and see the background.
    r = scale
    c = scale * np.array([0.3, 0.1, -5.0])
    eye = scale * np.array([0.0, 0.0, 2.5])
    axis = np.array([0.0, 0.0, -1.0])
    side = np.array([1.0, 0.0, 0.0])
    start = c - 3 * r * axis + 0.6 * r * side  # ray parallel to the axis, offset 0.6 r
    m = glass(kt=[0.9, 0.8, 0.7])
    scene = make_scene([Sphere(c, r, m)], [], Camera(eye, c), background=BG)
    integ = integrator(scene)
    inside = follow(integ, one_ray(start - eye, axis), REFRACTION)
    out = follow(integ, inside, REFRACTION)
    assert len(inside) == 1 and len(out) == 1  # not a TIR, no self-hit, no miss
    entry, exit_ = inside.origin[0] + eye, out.origin[0] + eye
    cos_t = math.sqrt(1 - 0.4**2)
    assert np.linalg.norm(exit_ - entry) == pytest.approx(2 * r * cos_t, rel=1e-12)
    assert np.linalg.norm(exit_ - c) == pytest.approx(r, rel=1e-14)
    # Deviation by a sphere: the ray turns by 2(θi − θt) towards the centre.
    dev = 2 * (math.asin(0.6) - math.asin(0.4))
    np.testing.assert_allclose(out.direction[0], [-math.sin(dev), 0, -math.cos(dev)],
                               atol=1e-12)
    # End to end: every pixel on the sphere sees kt²·background (no local terms, no kr).
    image = raytrace.render(scene, width=12, height=9, max_depth=2)
    rgb = image.rgb.reshape(-1, 3).astype(np.float64)
    through = np.isclose(rgb, m.kt**2 * BG, rtol=RTOL).all(axis=1)
    assert (through | np.isclose(rgb, BG, rtol=RTOL).all(axis=1)).all()
    assert through.sum() >= 4
    assert image.stats["rays"]["refraction"] == 2 * through.sum()


def test_camera_inside_a_glass_sphere():
    # The camera at the centre of a glass sphere (radius 2) sees its inside wall head-on in
    # every direction: normal incidence never bends or TIRs, so each pixel is the wall's local
    # term plus kt·background. A point light at the centre (attenuation 1/(1 + 0.5·d)) lights
    # the wall from inside: the two-sided N faces the camera, N·L = 1, d = 2 → f = 1/2;
    # its shadow ray runs inward from the wall and must not hit the sphere's far side before
    # the light. Local = ka·Ia + kd·Il·f.
    kt, ka, kd = np.array([0.9, 0.8, 0.7]), np.array([0.1, 0.1, 0.2]), np.array([0.3, 0.2, 0.1])
    m = Material(ka=ka, kd=kd, ks=0.0, kt=kt, ior=IOR)
    c = np.array([1.0, 2.0, 3.0])
    scene = make_scene([Sphere(c, 2.0, m)], [PointLight(c, 1.0, [1, 0.5, 0])],
                       Camera(c, c + [0, 0, -1], fov=90), ambient=0.5, background=BG)
    image = raytrace.render(scene, width=8, height=6, max_depth=1)
    expected = ka * 0.5 + kd * 0.5 + kt * BG
    np.testing.assert_allclose(image.rgb, np.broadcast_to(expected, (6, 8, 3)), rtol=RTOL)
    assert image.stats["total_internal_reflections"] == 0
    assert image.stats["rays"]["refraction"] == 48


def test_facing_mirrors_through_the_command_line(tmp_path):
    # The same series from a scene file via `raytrace render --stats`: D = 5 on a 3×2 image
    # (the planes are parallel, so every pixel zig-zags the same way): 5 reflection rays per
    # pixel, and the EXR pixel is L·(1 − 0.9⁶)/(1 − 0.9) with L = ka·Ia = 0.2·0.5.
    scene = tmp_path / "mirrors.toml"
    scene.write_text("""
[render]
width = 3
height = 2
max_depth = 5
background = 9.0
[camera]
position = [0.0, 0.0, 0.5]
look_at = [0.0, 0.0, -1.0]
fov = 20.0
[ambient]
color = 0.5
[materials.m]
ka = 0.2
kd = 0.0
kr = 0.9
[[objects]]
type = "plane"
point = [0.0, 0.0, -1.0]
normal = [0.0, 0.0, 1.0]
material = "m"
[[objects]]
type = "plane"
point = [0.0, 0.0, 2.0]
normal = [0.0, 0.0, -1.0]
material = "m"
""")
    out, stats = tmp_path / "m.exr", tmp_path / "m.json"
    assert main(["render", str(scene), "-o", str(out), "--stats", str(stats), "-q"]) == 0
    s = json.loads(stats.read_text())
    assert s["rays"]["reflection"] == 5 * 6 and s["rays"]["camera"] == 6
    assert s["rays"]["shadow"] == s["rays"]["refraction"] == s["rays"]["see_through"] == 0
    assert s["rays"]["total"] == 6 + 30
    assert s["pruned"] == {"depth": 6, "weight": 0}
    rgb = read_exr(out)[0]
    np.testing.assert_allclose(rgb, 0.1 * (1 - 0.9**6) / 0.1, rtol=RTOL)


# -- the shadow terminator on smooth meshes (Hanika 2021) ----------------------------------------
def _terminator_scene() -> raytrace.Scene:
    """A coarse smooth icosphere (80 faces) alone, lit from the side by a directional light:
    nothing else can shadow it, and a convex body does not shadow itself where its (smooth)
    normal faces the light."""
    ball = Mesh(mesh=trimesh.creation.icosphere(subdivisions=1), shading="smooth",
                material=Material(kd=1.0, ka=0.0, ks=0.0))
    return make_scene([ball], [DirectionalLight([-1.0, -0.2, 0.3])],
                      camera=Camera(position=[0.3, 0.2, 4.0], look_at=[0, 0, 0], fov=35.0))


def _smooth_n_dot_l(scene: raytrace.Scene, width: int, height: int) -> np.ndarray:
    """N_s·L per pixel, worked out independently of the renderer: the camera rays
    (raytrace.camera) against the mesh by brute force (Möller–Trumbore), the barycentrics of
    each hit solved in float64, the vertex normals (normalised sums of the unit face normals,
    the seeds' formula) interpolated and normalised; NaN off the mesh."""
    from helpers import moller_trumbore

    from raytrace.camera import camera_rays

    mesh = scene.objects[0]
    v, f = np.asarray(mesh.vertices, np.float64), np.asarray(mesh.faces)
    rays = camera_rays(scene.camera, RenderSettings(width=width, height=height), 0,
                       width * height)
    o = rays.origin + scene.camera.position
    hits = moller_trumbore(o, rays.direction, v, f)
    fn = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    fn /= np.linalg.norm(fn, axis=1, keepdims=True)
    vn = np.zeros_like(v)
    for k in range(3):
        np.add.at(vn, f[:, k], fn)
    vn /= np.linalg.norm(vn, axis=1, keepdims=True)
    light = -np.asarray(scene.lights[0].direction, np.float64)
    light /= np.linalg.norm(light)
    out = np.full(len(o), np.nan)
    for i in np.flatnonzero(hits["tri"] >= 0):
        a, b, c = v[f[hits["tri"][i]]]
        p = o[i] + hits["t"][i] * rays.direction[i]
        bary = np.linalg.solve(np.column_stack([a - c, b - c]).T @ np.column_stack(
            [a - c, b - c]), np.column_stack([a - c, b - c]).T @ (p - c))
        w = np.array([bary[0], bary[1], 1 - bary.sum()])
        n = w @ vn[f[hits["tri"][i]]]
        out[i] = n @ light / np.linalg.norm(n)
    return out.reshape(height, width)


def test_smooth_mesh_terminator_is_not_self_shadowed():
    # Near the terminator, facets turned (geometrically) away from the light still carry
    # smooth normals that face it; a shadow ray from the flat facet runs into the body, and
    # the smooth shading ends in a staircase of dark facets. Starting the shadow ray from
    # Hanika's lifted point removes those false shadows. Pixels with N_s·L > 0.1 must be lit:
    # value = kd·N_s·L (no ambient, no highlight), so a shadowed one reads 0.
    scene, w, h = _terminator_scene(), 64, 64
    n_dot_l = _smooth_n_dot_l(scene, w, h)
    lit = n_dot_l > 0.1
    assert lit.sum() > 500

    integ = WhittedIntegrator(scene, RenderOptions(width=w, height=h, max_depth=0))
    image = integ.render().rgb[..., 0]
    dark = lit & (image < 0.02)
    assert dark.sum() == 0, f"{dark.sum()} pixels with N_s·L > 0.1 are self-shadowed"
    # Where lit, the pixel is kd·N_s·L (float32 image; the interpolation is the same formula).
    np.testing.assert_allclose(image[lit], n_dot_l[lit], rtol=1e-4, atol=1e-5)

    # Control: the same render starting shadow rays from the flat facet shows the artefact,
    # so the test above can fail.
    flat = WhittedIntegrator(scene, RenderOptions(width=w, height=h, max_depth=0))
    tri = flat.tables.triangles
    flat.tables = flat.tables._replace(triangles=tri._replace(shading=np.zeros_like(tri.shading)))
    assert (lit & (flat.render().rgb[..., 0] < 0.02)).sum() > 10


# -- kernel variants: a scene compiles only the code it can run --------------------------------
SCENES = Path(__file__).resolve().parents[1] / "scenes"


@pytest.mark.parametrize("name,features", [
    ("spotlights.toml", set()),                        # matte spheres and planes
    ("whitted.toml", {"children"}),                    # a mirror, glass, a reflective floor
    ("flat_vs_smooth.toml", {"meshes"}),               # meshes, nothing reflective
    ("mesh_model.toml", {"meshes", "children"}),
    ("obj_mtl.toml", {"meshes", "children", "textures"}),  # an image-textured OBJ
])
def test_a_scene_has_the_kernel_features_of_what_it_holds(name, features):
    scene = raytrace.load_scene(SCENES / name)
    integrator = WhittedIntegrator(scene, render_options(scene))
    assert integrator.features == features


def _see_through_only() -> raytrace.Scene:
    """Matte spheres on a plane, one of them half see-through (opacity 0.5, no kr or kt):
    its children come from the opacity alone."""
    return raytrace.Scene(
        camera=raytrace.Camera(position=[0, 1, 4], look_at=[0, 0.5, 0], fov=50),
        lights=[raytrace.PointLight(position=[2, 4, 3], color=[1, 1, 1])],
        objects=[raytrace.Plane(point=[0, 0, 0], normal=[0, 1, 0],
                                material=raytrace.Material(kd=0.6)),
                 raytrace.Sphere(center=[-0.6, 0.5, 0], radius=0.5,
                                 material=raytrace.Material(kd=[0.8, 0.2, 0.2], opacity=0.5)),
                 raytrace.Sphere(center=[0.7, 0.5, -1], radius=0.5,
                                 material=raytrace.Material(kd=[0.2, 0.3, 0.8]))])


def test_a_see_through_material_alone_has_children():
    scene = _see_through_only()
    assert WhittedIntegrator(scene, render_options(scene)).features == {"children"}


@pytest.mark.parametrize("name", ["spotlights.toml", "whitted.toml", "flat_vs_smooth.toml",
                                  "area_light.toml", "tir.toml", "materials_showcase.toml",
                                  "see-through only"])
def test_each_kernel_variant_renders_the_general_kernels_image_bit_for_bit(name, monkeypatch):
    # The variant a scene picks against the general kernels (every feature on), on the scene
    # that exercises it: bit-identical (the variants prune code no hit of the scene runs).
    scene = _see_through_only() if name == "see-through only" else raytrace.load_scene(
        SCENES / name)
    picked = raytrace.render(scene, width=32, height=24, spp=2, threads=1)
    monkeypatch.setattr("raytrace.integrator.kernel_features",
                        lambda table, triangles: frozenset(KERNEL_FEATURES))
    general = raytrace.render(scene, width=32, height=24, spp=2, threads=1)
    assert WhittedIntegrator(scene, render_options(scene)).features == set(KERNEL_FEATURES)
    assert picked.rgb.tobytes() == general.rgb.tobytes()
    assert picked.stats["rays"] == general.stats["rays"]
    assert picked.stats["pruned"] == general.stats["pruned"]


LOADED = """
import json, sys
import raytrace
from raytrace.integrator import WhittedIntegrator
from raytrace.kernels import shading as sk
WhittedIntegrator.compiled = False  # the Python loop, kernel by kernel (tests/test_loop.py
raytrace.render(raytrace.load_scene(sys.argv[1]), width=8, height=6, threads=1)  # : the other)
print(json.dumps({name: [str(t) for sig in getattr(sk, name).signatures for t in sig]
                  for name in ("light_pass", "hit_terms", "count_keep", "spawn_children",
                               "cross_surfaces", "add_light")}))
"""


def test_a_diffuse_scene_loads_no_reflection_refraction_or_mesh_kernels():
    # scenes/spotlights.toml: spheres and planes of matte and plastic materials, spot lights,
    # max_depth 2. Its render (loading from numba's cache or compiling) must leave the spawn
    # and transparent-shadow kernels untouched, and take the variants of light_pass without
    # the triangle/texture code (depth None) and of hit_terms without children (None).
    out = subprocess.run([sys.executable, "-c", LOADED, str(SCENES / "spotlights.toml")],
                         capture_output=True, text=True, check=True).stdout
    loaded = json.loads(out)
    assert loaded["count_keep"] == loaded["spawn_children"] == []
    assert loaded["cross_surfaces"] == loaded["add_light"] == []
    assert loaded["light_pass"][5] == "none"  # depth
    assert loaded["hit_terms"][6] == "none"  # children
    assert len(loaded["light_pass"]) == 8 and len(loaded["hit_terms"]) == 7


# -- stopping early (Ctrl-C, the memory ceiling) ------------------------------------------------
@pytest.mark.parametrize("compiled", [False, pytest.param(True, id="compiled")])
def test_a_stop_ends_the_pass_in_progress_before_its_next_batch(compiled):
    # The stop is asked for once a pass has started: that pass adds nothing more (the
    # compiled loop reads the flag itself, in one nogil call), and no other pass starts.
    # whitted.toml's variant of the compiled loop is the one tests/test_loop.py compiles.
    scene = raytrace.load_scene(SCENES / "whitted.toml")
    integ = WhittedIntegrator(scene, render_options(scene, width=32, height=24, threads=2))
    integ.compiled = compiled
    stop, passes = Stop(), []
    trace_batch = integ._trace_batch

    def stopped_then_traced(rays, n, samples):
        stop.request(KeyboardInterrupt())
        trace_batch(rays, n, samples)
        passes.append(samples.copy())

    integ._trace_batch = stopped_then_traced
    with pytest.raises(KeyboardInterrupt):
        integ.render(stop=stop)
    assert 1 <= len(passes) <= 2 and not any(p.any() for p in passes)  # one per thread at most
    assert integ.render().rgb.any()  # without a stop, the same passes see the scene
    later = Stop()
    later.request(MemoryError("first"))
    later.request(KeyboardInterrupt())  # the first request wins
    with pytest.raises(MemoryError, match="first"):
        integ.render(stop=later)


def test_a_ctrl_c_while_the_passes_run_stops_them_all(monkeypatch):
    # The calling thread only waits for the passes, so a Ctrl-C reaches it at once (a SIGINT
    # to the main thread, where a terminal's goes on Linux); it stops every thread at its
    # next batch. A signal that lands between Python's last check and the lock wait is seen
    # at the wait's next look (integrator.WAKE_SECONDS, 1 s on Linux): 0.1 s here, as on
    # macOS and Windows, so that such a signal too stops the render within some 20 passes.
    monkeypatch.setattr(integrator_module, "WAKE_SECONDS", 0.1)
    handler = signal.signal(signal.SIGINT, signal.default_int_handler)
    calls = []

    def progress(done: int, total: int) -> None:
        calls.append(done)
        if len(calls) == 1:
            signal.pthread_kill(threading.main_thread().ident, signal.SIGINT)

    # 16 lights: a pass of 4096 samples is some 10 ms; the waiting thread wakes at the signal
    # on Linux, and elsewhere looks for it every 0.1 s.
    lights = [PointLight([2, 2, 5 + k]) for k in range(16)]
    scene = make_scene([Sphere([0, 0, -3], 1.0)], lights)
    try:
        with pytest.raises(KeyboardInterrupt):
            raytrace.render(scene, width=400, height=300, spp=4, threads=2, pass_samples=4096,
                            progress=progress)
    finally:
        signal.signal(signal.SIGINT, handler)
    assert 1 <= len(calls) < 59, calls  # of 118 passes
    stopped_at = len(calls)
    time.sleep(0.3)
    assert len(calls) == stopped_at  # no pass went on
    assert raytrace.render(scene, width=40, height=30, threads=2).rgb.any()  # threads serve on


@pytest.mark.parametrize("threads", [1, 2])
def test_an_error_in_the_progress_callback_stops_the_render_and_is_raised(threads):
    calls = []

    def progress(done: int, total: int) -> None:
        calls.append(done)
        raise ValueError("the bar broke")

    scene = make_scene([Sphere([0, 0, -3], 1.0)], [PointLight([2, 2, 5])])
    with pytest.raises(ValueError, match="the bar broke"):
        raytrace.render(scene, width=400, height=300, threads=threads, pass_samples=4096,
                        progress=progress)
    assert 1 <= len(calls) <= threads  # the first call stops every thread


# -- a noise-driven round's passes ------------------------------------------------------------
@pytest.mark.parametrize(("samples", "threads", "size"), [
    (76800, 2, 38400),  # 160×120 at 4 a pixel: one pass a thread
    (307200, 2, 51200),  # over 2 × 65 536: six passes, three a thread
    (5000, 2, MIN_ROUND_PASS_SAMPLES),  # no pass under the least
    (76800, 16, 4800),  # one pass for each of 16 threads
    (76800, 1, 38400)])  # two passes, as one would pass 65 536
def test_a_noise_round_goes_in_the_fewest_passes_a_thread(samples, threads, size):
    assert round_pass_size(samples, threads, 65536) == size
    passes = -(-samples // size)
    assert passes % threads == 0 or size == MIN_ROUND_PASS_SAMPLES


def test_a_noise_round_s_pass_keeps_within_pass_samples():
    """``pass_samples`` bounds a pass's memory, below the least pass too."""
    assert round_pass_size(76800, 2, 50) == 50
    assert round_pass_size(76800, 2, 4096) == 4096  # the least pass, not an even 3 840


def test_a_render_by_target_cuts_each_round_into_one_pass_a_thread(monkeypatch):
    """Each pass pays its depths' Python once, so a round on 2 threads goes in 2 passes
    (64×48 at 4 samples a pixel: 12 288 samples, two of 6 144), not more."""
    run, cuts = WhittedIntegrator._run, []

    def noted(self, passes, *args, **kw):
        cuts.append(len(passes))
        return run(self, passes, *args, **kw)

    monkeypatch.setattr(WhittedIntegrator, "_run", noted)
    image = raytrace.render(every_ray_scene(), width=64, height=48, threads=2,
                            target_error=1e-6, max_spp=16)
    assert image.stats["aa"]["rounds"] == len(cuts) >= 2
    assert cuts[0] == 2 and max(cuts) == 2
