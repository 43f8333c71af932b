"""``threads=N`` changes speed, never pixels: renders are bit-identical for any thread count.

Every query in raytrace.accel runs chunk by chunk (analytic shapes, Embree, float64
refinement, surfaces), each step row-wise, and the integrator accumulates in a fixed order;
so the image cannot depend on which worker took which chunk. The chunk size is shrunk here so
that a small image is split into many chunks that really do run concurrently.
"""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

import raytrace
from raytrace import accel

W, H = 48, 36


def scene() -> raytrace.Scene:
    """Meshes (a smooth glass icosphere, a flat box), a mirror sphere, a reflective checker
    floor, a point and a spot light: every kind of ray, transparent shadows."""
    glass = raytrace.Material(kd=0.0, ks=0.5, shininess=200, highlight="blinn", kr=0.1, kt=0.9,
                              ior=1.5)
    floor = raytrace.Material(
        kd=raytrace.Checker((np.array([0.9, 0.9, 0.9]), np.array([0.2, 0.3, 0.6])), 0.5),
        ks=0.2, kr=0.2)
    return raytrace.Scene(
        camera=raytrace.Camera(position=[0.0, 1.5, 5.0], look_at=[0.0, 0.8, 0.0], fov=45.0),
        objects=[
            raytrace.Mesh(mesh=trimesh.creation.icosphere(subdivisions=2), shading="smooth",
                          translate=[0.6, 0.8, 0.5], scale=0.8, material=glass),
            raytrace.Mesh(mesh=trimesh.creation.box(extents=[0.8, 0.8, 0.8]),
                          translate=[-1.2, 0.4, 0.8], rotate=[0.0, 30.0, 0.0],
                          material="red_plastic"),
            raytrace.Sphere([-0.5, 1.0, -1.2], 1.0, material="mirror"),
            raytrace.Plane([0.0, 0.0, 0.0], [0.0, 1.0, 0.0], material=floor),
        ],
        lights=[raytrace.PointLight([4.0, 6.0, 4.0]),
                raytrace.SpotLight([0.0, 4.0, 2.0], [0.0, -1.0, -0.3], cutoff=40.0,
                                   exponent=4.0, color=0.5)],
        ambient=0.1, render=raytrace.RenderSettings(background=[0.2, 0.3, 0.5]))


@pytest.fixture(scope="module")
def renders() -> dict:
    s = scene()
    mp = pytest.MonkeyPatch()
    mp.setattr(accel, "CHUNK", 97)  # 1728 camera rays → 18 chunks per query
    try:
        out = {t: raytrace.render(s, width=W, height=H, threads=t) for t in (1, 2, 3)}
        out["passes"] = raytrace.render(s, width=W, height=H, threads=2, pass_samples=500)
    finally:
        mp.undo()
    return out


def test_the_scene_exercises_every_kind_of_ray(renders):
    stats = renders[1].stats
    assert stats["rays"]["reflection"] > 0
    assert stats["rays"]["refraction"] > 0
    assert stats["rays"]["shadow"] > 0
    rgb = renders[1].rgb
    assert np.isfinite(rgb).all() and rgb.std() > 0.01


@pytest.mark.parametrize("threads", [2, 3])
def test_bit_identical_for_any_thread_count(renders, threads):
    a, b = renders[1], renders[threads]
    assert np.array_equal(a.rgb.view(np.uint32), b.rgb.view(np.uint32))
    assert a.stats["rays"] == b.stats["rays"]
    assert a.stats["pruned"] == b.stats["pruned"]


def test_bit_identical_when_rendered_in_passes(renders):
    # 500 samples per pass: the 1728-pixel image in 4 passes, split mid-row.
    assert np.array_equal(renders[1].rgb.view(np.uint32), renders["passes"].rgb.view(np.uint32))


def test_default_chunking_matches_small_chunks(renders):
    # The chunk size is a performance knob too: it must not change a pixel either.
    default = raytrace.render(scene(), width=W, height=H, threads=2)
    assert np.array_equal(default.rgb.view(np.uint32), renders[1].rgb.view(np.uint32))
