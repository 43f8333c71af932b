"""Lights: spot cones, directional sources, attenuation and area-light sampling against the
seeds' formulas (seed 000: f_radial = 1/(a0 + a1·d + a2·d²); f_angular = 0 where
cos α < cos θ, else (cos α)^a)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from helpers import RTOL, aimed_camera, make_scene, pixel

import raytrace
from raytrace.lights import cos_cutoff, emitters

FLOOR = dict(point=[0.0, 0.0, 0.0], normal=[0.0, 1.0, 0.0])
KD, KA, IA = np.array([0.9, 0.6, 0.3]), np.array([0.4, 0.2, 0.1]), 0.25


def _spot_pixel(alpha_deg: float, cutoff: float = 30.0, exponent: float = 8.0):
    """A spot at S = (0, 2, 0) pointing straight down onto the plane y = 0; the pixel sees
    P = (2·tan α, 0, 0), so the light-to-point direction makes angle α with the axis."""
    x = 2.0 * math.tan(math.radians(alpha_deg))
    spot = raytrace.SpotLight([0.0, 2.0, 0.0], [0.0, -1.0, 0.0], cutoff=cutoff,
                              exponent=exponent, color=[1.5, 1.0, 0.5],
                              attenuation=[1.0, 0.0, 0.05])
    scene = make_scene([raytrace.Plane(**FLOOR, material=raytrace.Material(kd=KD, ka=KA))],
                       [spot], camera=aimed_camera([x, 3.0, 3.0], [x, 0.0, 0.0]), ambient=IA)
    return pixel(scene), x


def test_spot_just_inside_the_cone():
    # α = 29.9° < θ = 30°: d = 2/cos α, N·L = cos α (L points from P up to S),
    # I = ka·Ia + f_radial·(cos α)^a·Il·kd·cos α with f_radial = 1/(1 + 0.05·d²).
    alpha = math.radians(29.9)
    value, _ = _spot_pixel(29.9)
    d = 2.0 / math.cos(alpha)
    f = 1.0 / (1.0 + 0.05 * d * d)
    expected = KA * IA + f * math.cos(alpha) ** 8 * np.array([1.5, 1.0, 0.5]) * KD * math.cos(
        alpha)
    np.testing.assert_allclose(value, expected, rtol=RTOL)


def test_spot_just_outside_the_cone_is_exactly_ambient():
    value, _ = _spot_pixel(30.1)
    np.testing.assert_allclose(value, KA * IA, rtol=RTOL)


def test_spot_exponent_zero_is_a_hard_edged_cone():
    # a = 0: (cos α)^0 = 1 inside, so only f_radial and N·L remain.
    alpha = math.radians(10.0)
    value, _ = _spot_pixel(10.0, exponent=0.0)
    d = 2.0 / math.cos(alpha)
    expected = KA * IA + np.array([1.5, 1.0, 0.5]) * KD * math.cos(alpha) / (1 + 0.05 * d * d)
    np.testing.assert_allclose(value, expected, rtol=RTOL)


def test_directional_light_on_a_sphere():
    # Unit sphere at C = (1, -0.5, 0.25); the pixel aims at Q = C + N with the outward normal
    # N = (sin 40°, 0, cos 40°) from the eye at C + (0, 0, 5). The light travels along
    # (−1, −1, −1)/√3, so L = (1, 1, 1)/√3 and N·L = (sin 40° + cos 40°)/√3; no attenuation.
    c = np.array([1.0, -0.5, 0.25])
    nrm = np.array([math.sin(math.radians(40)), 0.0, math.cos(math.radians(40))])
    il = np.array([0.8, 0.9, 1.0])
    scene = make_scene(
        [raytrace.Sphere(c, 1.0, material=raytrace.Material(kd=KD, ka=KA))],
        [raytrace.DirectionalLight([-1.0, -1.0, -1.0], color=il)],
        camera=aimed_camera(c + [0.0, 0.0, 5.0], c + nrm), ambient=IA)
    ndl = (math.sin(math.radians(40)) + math.cos(math.radians(40))) / math.sqrt(3)
    np.testing.assert_allclose(pixel(scene), KA * IA + il * KD * ndl, rtol=RTOL)


def test_directional_light_from_behind_the_sphere_leaves_ambient():
    # L = (0, 0, −1) while the visible point's normal is (0, 0, 1): N·L = −1.
    scene = make_scene([raytrace.Sphere([0, 0, 0], 1.0, material=raytrace.Material(kd=KD, ka=KA))],
                       [raytrace.DirectionalLight([0.0, 0.0, 1.0], color=3.0)],
                       camera=aimed_camera([0, 0, 5], [0, 0, 0]), ambient=IA)
    np.testing.assert_allclose(pixel(scene), KA * IA, rtol=RTOL)


def test_area_light_grid_sums_to_its_colour():
    # A 2×2 area light straight above a point, far away compared with its size: the four cell
    # centres sit at (±0.25·w, h, ±0.25·w). Each sample carries colour/4 and
    # N·L = h/|(±w/4, h, ±w/4)|, so the total is colour·h/√(h² + w²/8).
    w, h = 1.0, 3.0
    area = raytrace.AreaLight([0.0, h, 0.0], [w, 0, 0], [0, 0, w], samples=4, color=2.0)
    scene = make_scene([raytrace.Plane(**FLOOR, material=raytrace.Material(kd=0.5, ka=0.0))],
                       [area], camera=aimed_camera([0, 1, 2], [0, 0, 0]))
    expected = 2.0 * 0.5 * h / math.sqrt(h * h + w * w / 8)
    np.testing.assert_allclose(pixel(scene), np.full(3, expected), rtol=RTOL)


# -- Emitter.incidence on its own ---------------------------------------------------------------

def test_point_emitter_direction_distance_attenuation():
    light = raytrace.PointLight([1.0, 2.0, 3.0], attenuation=[0.5, 0.2, 0.03])
    (em,) = emitters([light], np.zeros(3), seed=0)
    pts = np.array([[1.0, 2.0, 0.0], [4.0, 6.0, 3.0]])
    to_light, dist, f = em.incidence(pts)
    np.testing.assert_allclose(dist, [3.0, 5.0])
    np.testing.assert_allclose(to_light, [[0, 0, 1], [-0.6, -0.8, 0]], atol=1e-15)
    np.testing.assert_allclose(f, 1 / (0.5 + 0.2 * np.array([3, 5]) + 0.03 * np.array([9, 25])))


def test_emitters_are_camera_relative():
    light = raytrace.PointLight([10.0, 0.0, 0.0])
    (em,) = emitters([light], np.array([4.0, 0.0, 0.0]), seed=0)
    _, dist, _ = em.incidence(np.zeros((1, 3)))      # the camera itself
    assert dist[0] == pytest.approx(6.0)


def test_spot_cos_cutoff_at_90_degrees_is_exactly_zero():
    assert cos_cutoff(90.0) == 0.0
    assert cos_cutoff(60.0) == pytest.approx(0.5)
    spot = raytrace.SpotLight([0, 0, 0], [0, -1, 0], cutoff=90.0)
    (em,) = emitters([spot], np.zeros(3), seed=0)
    # a point level with the spot (α = 90°): cos α = 0 >= cos θ = 0, (cos α)^0 = 1 inside.
    _, _, f = em.incidence(np.array([[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 1.0, 0.0]]))
    np.testing.assert_allclose(f, [1.0, 1.0, 0.0])


def test_area_light_samples_jittered_stay_in_their_cells():
    area = raytrace.AreaLight([0, 5, 0], [2, 0, 0], [0, 0, 2], samples=9, jitter=True, color=9.0)
    ems = emitters([area], np.zeros(3), seed=3)
    assert len(ems) == 9
    pos = np.array([e.position for e in ems])
    np.testing.assert_allclose(sum(e.color for e in ems), np.full(3, 9.0))
    assert np.all(np.abs(pos[:, [0, 2]]) <= 1.0) and np.all(pos[:, 1] == 5.0)
    cells = np.floor((pos[:, [0, 2]] + 1.0) / (2.0 / 3.0)).astype(int)
    assert len({tuple(c) for c in cells}) == 9            # one sample per cell (stratified)
    again = np.array([e.position for e in emitters([area], np.zeros(3), seed=3)])
    np.testing.assert_array_equal(pos, again)             # seeded: reproducible


def test_area_light_samples_must_be_a_square():
    with pytest.raises(raytrace.SceneError, match="perfect square"):
        raytrace.AreaLight([0, 1, 0], [1, 0, 0], [0, 0, 1], samples=8)
