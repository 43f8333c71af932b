"""Lights: spot cones, directional sources, attenuation and area-light sampling against the
seeds' formulas (seed 000: f_radial = 1/(a0 + a1·d + a2·d²); f_angular = 0 where
cos α < cos θ, else (cos α)^a)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from helpers import RTOL, aimed_camera, make_scene, pixel

import raytrace
from raytrace import shading
from raytrace.kernels import shading as K
from raytrace.lights import cos_cutoff, emitters, labels
from raytrace.shading import light_words

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


# -- KHR_lights_punctual's laws: the smooth spot (inner_cutoff) and the range window ----------
#: A smooth spot of inner cone 10° and outer cone 30° (KHR_lights_punctual's falloff).
INNER, OUTER = 10.0, 30.0
SPOT_COLOR = np.array([1.5, 1.0, 0.5])


def _smooth_spot_pixel(alpha_deg: float, **keys):
    """The floor lit by a spot at S = (0, 2, 0) pointing straight down, at 1/d²
    (attenuation (0, 0, 1), as glTF's candela), the pixel at P = (2·tan α, 0, 0): the
    light-to-point direction makes angle α with the axis, d = 2/cos α, N·L = cos α."""
    x = 2.0 * math.tan(math.radians(alpha_deg))
    spot = raytrace.SpotLight([0.0, 2.0, 0.0], [0.0, -1.0, 0.0], cutoff=OUTER,
                              inner_cutoff=INNER, color=SPOT_COLOR, attenuation=[0, 0, 1],
                              **keys)
    scene = make_scene([raytrace.Plane(**FLOOR, material=raytrace.Material(kd=KD, ka=KA))],
                       [spot], camera=aimed_camera([x, 3.0, 3.0], [x, 0.0, 0.0]), ambient=IA)
    return pixel(scene)


def _lit_floor(alpha_deg: float, t: float, window: float = 1.0) -> np.ndarray:
    """ka·Ia + t²·window·I·kd·cos α/d² with d = 2/cos α: the floor pixel by hand."""
    c = math.cos(math.radians(alpha_deg))
    return KA * IA + t * t * window * SPOT_COLOR * KD * c * (c / 2.0) ** 2


def test_smooth_spot_between_its_cones_falls_off_as_the_khr_spec():
    """KHR_lights_punctual's recommended falloff at α = 20°, between inner 10° and outer 30°:
    t = (cos 20° − cos 30°)/(cos 10° − cos 30°) = (0.9396926 − 0.8660254)/(0.9848078 −
    0.8660254) = 0.0736672/0.1187824 = 0.620184; the light is t² = 0.384628 of the cone's."""
    cos = [math.cos(math.radians(a)) for a in (20.0, 30.0, 10.0)]
    t = (cos[0] - cos[1]) / (cos[2] - cos[1])
    np.testing.assert_allclose(_smooth_spot_pixel(20.0), _lit_floor(20.0, t), rtol=1e-6)


@pytest.mark.parametrize("alpha", [0.0, 5.0, INNER])
def test_smooth_spot_inside_its_inner_cone_is_full(alpha):
    """At and inside the inner cone t = clamp(≥ 1) = 1: the whole light, 1/d² and N·L only."""
    np.testing.assert_allclose(_smooth_spot_pixel(alpha), _lit_floor(alpha, 1.0), rtol=RTOL)


@pytest.mark.parametrize("alpha", [30.5, 60.0])
def test_smooth_spot_beyond_its_outer_cone_is_dark(alpha):
    """t = clamp(< 0) = 0 beyond the outer cone: ambient only, exactly."""
    np.testing.assert_array_equal(_smooth_spot_pixel(alpha), (KA * IA).astype(np.float32))


def test_range_window_at_half_the_range():
    """A point light 2 above the floor with range 4: d = range/2, so the KHR window is
    1 − (1/2)⁴ = 15/16 and the pixel below it kd·I·(15/16)/d² (N·L = 1, ambient 0)."""
    light = raytrace.PointLight([0.0, 2.0, 0.0], color=SPOT_COLOR, attenuation=[0, 0, 1],
                                range=4.0)
    scene = make_scene([raytrace.Plane(**FLOOR, material=raytrace.Material(kd=KD, ka=0.0))],
                       [light], camera=aimed_camera([0.0, 3.0, 3.0], [0.0, 0.0, 0.0]))
    np.testing.assert_allclose(pixel(scene), KD * SPOT_COLOR * (1 - 1 / 16) / 4, rtol=1e-7)
    # the smooth spot's axis, d = 2 again
    np.testing.assert_allclose(_smooth_spot_pixel(0.0, range=4.0),
                               _lit_floor(0.0, 1.0, 15 / 16), rtol=1e-7)


@pytest.mark.parametrize("make", [
    lambda r: raytrace.PointLight([0.0, 2.0, 0.0], color=2.0, range=r),
    lambda r: raytrace.SpotLight([0.0, 2.0, 0.0], [0, -1, 0], color=2.0, range=r),
    lambda r: raytrace.AreaLight([0.0, 2.0, 0.0], [0.1, 0, 0], [0, 0, 0.1], color=2.0,
                                 range=r)])
def test_beyond_its_range_a_light_gives_nothing(make):
    """d = 2 > range 1.9: 1 − (d/r)⁴ < 0, the window is 0: ambient only."""
    scene = make_scene([raytrace.Plane(**FLOOR, material=raytrace.Material(kd=KD, ka=KA))],
                       [make(1.9)], camera=aimed_camera([0.0, 3.0, 3.0], [0.0, 0.0, 0.0]),
                       ambient=IA)
    np.testing.assert_array_equal(pixel(scene), (KA * IA).astype(np.float32))
    scene.lights[0].range = 2.5  # inside its range, it lights the floor
    assert np.all(pixel(scene) > KA * IA + 0.1)


@pytest.mark.parametrize("keys,key,problem", [
    (dict(inner_cutoff=31.0), "inner_cutoff", "must be <= 30"),
    (dict(inner_cutoff=-1.0), "inner_cutoff", "must be >= 0"),
    (dict(inner_cutoff=10.0, exponent=2.0), "inner_cutoff", "not both"),
    (dict(range=0.0), "range", "must be > 0"),
    (dict(range=-3.0), "range", "must be > 0"),
])
def test_bad_spot_keys_are_one_line(keys, key, problem):
    with pytest.raises(raytrace.SceneError, match=problem) as e:
        raytrace.SpotLight([0, 2, 0], [0, -1, 0], cutoff=30.0, **keys)
    assert e.value.key == key


def test_the_new_keys_are_opt_in_and_the_old_spot_law_stays_the_default():
    """Without inner_cutoff and range a spot's emitter is seed 000's SPOT with no window, as
    before (so existing scenes render bit for bit as they did)."""
    (old,) = emitters([raytrace.SpotLight([0, 2, 0], [0, -1, 0], exponent=3.0)], np.zeros(3), 0)
    assert old.record.kind == K.SPOT and old.record.range == 0.0
    (new,) = emitters([raytrace.SpotLight([0, 2, 0], [0, -1, 0], inner_cutoff=20.0,
                                          range=5.0)], np.zeros(3), 0)
    assert new.record.kind == K.SMOOTH_SPOT and new.record.range == 5.0
    assert new.record.cos_inner == pytest.approx(math.cos(math.radians(20.0)))


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
    to_light, dist, f = shading.incidence(em, pts)
    np.testing.assert_allclose(dist, [3.0, 5.0])
    np.testing.assert_allclose(to_light, [[0, 0, 1], [-0.6, -0.8, 0]], atol=1e-15)
    np.testing.assert_allclose(f, 1 / (0.5 + 0.2 * np.array([3, 5]) + 0.03 * np.array([9, 25])))


def test_emitters_are_camera_relative():
    light = raytrace.PointLight([10.0, 0.0, 0.0])
    (em,) = emitters([light], np.array([4.0, 0.0, 0.0]), seed=0)
    _, dist, _ = shading.incidence(em, np.zeros((1, 3)))      # the camera itself
    assert dist[0] == pytest.approx(6.0)


def test_spot_cos_cutoff_at_90_degrees_is_exactly_zero():
    assert cos_cutoff(90.0) == 0.0
    assert cos_cutoff(60.0) == pytest.approx(0.5)
    spot = raytrace.SpotLight([0, 0, 0], [0, -1, 0], cutoff=90.0)
    (em,) = emitters([spot], np.zeros(3), seed=0)
    # a point level with the spot (α = 90°): cos α = 0 >= cos θ = 0, (cos α)^0 = 1 inside.
    _, _, f = shading.incidence(em, np.array([[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 1.0, 0.0]]))
    np.testing.assert_allclose(f, [1.0, 1.0, 0.0])


def _jittered_cells(samples=9, seed=3):
    area = raytrace.AreaLight([0, 5, 0], [2, 0, 0], [0, 0, 2], samples=samples, jitter=True,
                              color=9.0)
    return emitters([area], np.zeros(3), seed=seed)


def _sample_point(em, key: int, depth: int = 0) -> np.ndarray:
    """Where a shading point at the origin samples the emitter: P + L·d."""
    word = light_words(np.array([key]), em.stream, depth)[0] if key >= 0 else -1
    lx, ly, lz, d, _ = K.incidence1((0.0, 0.0, 0.0), em.record, word)
    return np.array([lx, ly, lz]) * d


def test_jittered_area_light_draws_a_point_per_hit_inside_its_cell():
    ems = _jittered_cells()
    assert len(ems) == 9 and all(e.jittered for e in ems)
    np.testing.assert_allclose(sum(e.color for e in ems), np.full(3, 9.0))
    for em in ems:
        half = (em.cell_u + em.cell_v) / 2
        lo, hi = em.position - half, em.position + half
        pts = np.array([_sample_point(em, key) for key in range(200)])
        assert np.all(pts[:, [0, 2]] >= lo[[0, 2]] - 1e-12)      # inside its 2/3 × 2/3 cell
        assert np.all(pts[:, [0, 2]] <= hi[[0, 2]] + 1e-12)
        np.testing.assert_allclose(pts[:, 1], 5.0)
        # spread over the cell (uniform: mean near the centre, both halves used)
        assert len({tuple(p) for p in pts}) == 200
        np.testing.assert_allclose(pts.mean(0)[[0, 2]], em.position[[0, 2]], atol=0.06)
        # key < 0 (Python-side incidence, Gouraud vertices): the cell centre
        np.testing.assert_allclose(_sample_point(em, -1), em.position, atol=1e-12)
    em = ems[4]
    np.testing.assert_array_equal(_sample_point(em, 17), _sample_point(em, 17))  # reproducible
    assert not np.array_equal(_sample_point(em, 17, depth=0), _sample_point(em, 17, depth=1))
    # another seed draws other points; the cells (and centres) stay
    other = _jittered_cells(seed=4)[4]
    np.testing.assert_array_equal(other.position, em.position)
    assert not np.array_equal(_sample_point(other, 17), _sample_point(em, 17))


def test_jittered_cells_of_one_hit_are_n_rooks_over_the_light():
    # The rotated multi-jittered pattern (shading_kernels.incidence1): at every hit the k²
    # points put one in each cell and one in each of the k² columns and k² rows of the whole
    # 2 × 2 rectangle (centred on x = z = 0); independent jitter per cell would fill some
    # column twice (for k = 3, nearly always).
    ems = _jittered_cells(samples=9)
    for key in range(50):
        for depth in (0, 2):
            pts = np.array([_sample_point(em, key, depth) for em in ems])
            cols = np.floor((pts[:, 0] + 1.0) / 2.0 * 9).astype(int)
            rows = np.floor((pts[:, 2] + 1.0) / 2.0 * 9).astype(int)
            assert sorted(cols) == list(range(9)) and sorted(rows) == list(range(9))
            cells = {(c // 3, r // 3) for c, r in zip(cols, rows, strict=True)}
            assert len(cells) == 9


def test_unjittered_area_light_samples_the_cell_centres():
    area = raytrace.AreaLight([0, 5, 0], [2, 0, 0], [0, 0, 2], samples=9)
    ems = emitters([area], np.zeros(3), seed=3)
    assert not any(e.jittered for e in ems)
    centres = {(round(e.position[0], 12), round(e.position[2], 12)) for e in ems}
    third = round(2 / 3, 12)
    assert centres == {(x, z) for x in (-third, 0.0, third) for z in (-third, 0.0, third)}


def test_jittered_area_light_converges_to_the_rectangle_integral():
    # A white floor point straight below a w × w light at height h (no falloff, colour C,
    # kd): each hit's value is C·kd·mean over the k² cells of N·L to its drawn point, whose
    # expectation is C·kd·(1/w²)∫∫ h/√(x² + z² + h²) dx dz over the rectangle. With 4096
    # pixel samples, each drawing its own points, the pixel must approach that integral much
    # more closely than the 4 cell centres do (their midpoint rule is biased by ~3 %; the
    # jittered estimate's standard error here is ~8e-4, measured over seeds 0–3).
    w, h, C, kd, k = 2.0, 1.0, 2.0, 0.5, 2
    n = 2000  # midpoint rule on an n × n grid: error ~1e-8
    x = (np.arange(n) + 0.5) / n * w - w / 2
    xx, zz = np.meshgrid(x, x)
    exact = C * kd * np.mean(h / np.sqrt(xx**2 + zz**2 + h**2))

    def render(jitter: bool) -> float:
        area = raytrace.AreaLight([0.0, h, 0.0], [w, 0, 0], [0, 0, w], samples=k * k,
                                  jitter=jitter, color=C)
        scene = make_scene([raytrace.Plane(**FLOOR, material=raytrace.Material(kd=kd, ka=0.0))],
                           [area], camera=aimed_camera([0, 3, 0.5], [0, 0, 0], fov=0.001))
        image = raytrace.render(scene, width=1, height=1, spp=4096, seed=11)
        return float(image.rgb[0, 0, 0])

    centres, jittered = render(False), render(True)
    assert abs(centres - exact) > 5e-3                    # the grid's bias at k = 2 (~1 %)
    assert abs(jittered - exact) < 0.1 * abs(centres - exact)


def test_jittered_area_light_on_a_gouraud_floor_converges_to_the_vertex_integrals():
    # Gouraud shading evaluates the local model at the triangle's vertices V_k and
    # interpolates it with the hit's barycentrics b_k (seed 000). Under a jittered area light
    # each hit draws its own point in every cell, and its three vertices must see that same
    # point, the one the hit's shadow ray aims at. With N = +y, no falloff and ks = 0 the
    # pixel's expectation is then each vertex's own rectangle integral,
    #   C·kd·Σ_k b_k·(1/w²)∫∫ h/|(x, h, z) − V_k| dx dz,
    # while the cell centres c_j give the midpoint rule C·kd·Σ_k b_k·mean_j h/|c_j − V_k|.
    w, h, C, kd, k = 2.0, 1.0, 2.0, 0.5, 2
    corners = np.array([[-1.0, 0.0, -1.0], [1.0, 0.0, -1.0], [1.0, 0.0, 1.0], [-1.0, 0.0, 1.0]])
    target = np.array([0.3, 0.0, -0.2])  # inside face (V0, V2, V1): z < x
    tri = corners[[0, 2, 1]]
    bary = np.linalg.solve(np.vstack([tri[:, 0], tri[:, 2], np.ones(3)]),
                           [target[0], target[2], 1.0])
    assert np.all(bary > 0.05)

    def seen(xs, zs):  # Σ_k b_k · mean of h/|p − V_k| over the light points (xs, h, zs)
        return sum(b * np.mean(h / np.sqrt((xs - v[0]) ** 2 + h**2 + (zs - v[2]) ** 2))
                   for b, v in zip(bary, tri, strict=True))

    n = 1000  # midpoint rule on an n × n grid: error ~1e-7
    x = (np.arange(n) + 0.5) / n * w - w / 2
    exact = C * kd * seen(*np.meshgrid(x, x))
    half = np.array([-w / 4, w / 4])
    at_centres = C * kd * seen(*np.meshgrid(half, half))
    assert abs(at_centres - exact) > 5e-3

    def render(jitter: bool) -> float:
        area = raytrace.AreaLight([0.0, h, 0.0], [w, 0, 0], [0, 0, w], samples=k * k,
                                  jitter=jitter, color=C)
        floor = raytrace.Mesh(vertices=corners, faces=[[0, 2, 1], [0, 3, 2]],
                              shading="gouraud", material=raytrace.Material(kd=kd, ka=0.0))
        scene = make_scene([floor], [area],
                           camera=aimed_camera(target + [0.0, 3.0, 0.5], target, fov=0.001))
        return float(raytrace.render(scene, width=1, height=1, spp=4096, seed=11).rgb[0, 0, 0])

    centres, jittered = render(False), render(True)
    assert centres == pytest.approx(at_centres, rel=1e-5)
    assert abs(jittered - exact) < 0.1 * abs(at_centres - exact)


def test_jittered_area_light_is_noise_not_the_same_for_every_pixel():
    # Eight neighbouring floor pixels, 1e-5 apart, see the light almost identically: from
    # fixed sample points (the cell centres, or points drawn once per render) they would
    # differ by ~1e-6. Per-hit jitter gives each its own draw: a spread of percent.
    def row(jitter: bool, threads: int = 1) -> np.ndarray:
        area = raytrace.AreaLight([0.0, 1.0, 0.0], [2, 0, 0], [0, 0, 2], samples=4,
                                  jitter=jitter)
        scene = make_scene([raytrace.Plane(**FLOOR, material=raytrace.Material(kd=0.5, ka=0.0))],
                           [area], camera=aimed_camera([0, 3, 0.01], [0, 0, 0], fov=0.001))
        return raytrace.render(scene, width=8, height=1, spp=1, threads=threads).rgb[0, :, 0]

    fixed, jittered = np.ptp(row(False)), np.ptp(row(True))
    assert fixed < 1e-5 and jittered > 1e-3
    np.testing.assert_array_equal(row(True), row(True, threads=2))  # still deterministic


def test_area_light_samples_must_be_a_square():
    with pytest.raises(raytrace.SceneError, match="perfect square"):
        raytrace.AreaLight([0, 1, 0], [1, 0, 0], [0, 0, 1], samples=8)


# -- per-path keys: the children of one hit draw their own points (core.path_key1) -----------
def _splitter_scene(samples=4):
    """A camera ray straight down through a beam splitter at y = 1 (kr = kt = 0.5, ior 1: the
    reflected child goes straight up, the refracted one straight down) onto a matte ceiling at
    y = 2 and a matte floor at y = 0; a jittered area light in the plane y = 1, off to the
    side, so the two hits are mirror images about y = 1 and the same point of the light gives
    them bit-identical terms."""
    matte = raytrace.Material(kd=0.5, ka=0.0, ks=0.0)
    splitter = raytrace.Mesh(vertices=[[-0.5, 1, -0.5], [0.5, 1, -0.5], [0.5, 1, 0.5],
                                       [-0.5, 1, 0.5]], faces=[[0, 2, 1], [0, 3, 2]],
                             material=raytrace.Material(kd=0.0, ks=0.0, ka=0.0, kr=0.5, kt=0.5,
                                                        ior=1.0))
    area = raytrace.AreaLight([3.0, 1.0, 0.0], [1, 0, 0], [0, 0, 1], samples=samples,
                              jitter=True)
    return make_scene([raytrace.Plane(**FLOOR, material=matte),
                       raytrace.Plane(point=[0, 2, 0], normal=[0, -1, 0], material=matte),
                       splitter], [area],
                      camera=aimed_camera([0.0, 1.5, 0.0], [0.0, 0.0, 0.0], fov=10.0))


def test_children_of_one_hit_draw_their_own_light_points():
    """Before per-path keys both children of the splitter's hit took the points of their
    camera sample and depth: mirror-image hits, identical terms. Now each path has its own."""
    tree = raytrace.explain(_splitter_scene(), (0, 0), width=1, height=1, max_depth=1)
    hits = [r for r in tree["rays"] if r["depth"] == 1 and r["hit"] is not None]
    assert sorted(r["kind"] for r in hits) == ["reflection", "refraction"]
    (up,), (down,) = ([r for r in hits if r["kind"] == k] for k in ("reflection", "refraction"))
    assert up["hit"]["point"][1] == pytest.approx(2.0) and down["hit"]["point"][1] == 0.0
    terms = [np.array([lt["term"] for lt in r["lights"]]) for r in (up, down)]
    assert np.all(terms[0][:, 0] > 0.0) and np.all(terms[1][:, 0] > 0.0)
    assert not np.any(terms[0] == terms[1])  # no cell's point is shared
    # with cell centres (no jitter) the two are mirror images: the same terms
    unjittered = _splitter_scene()
    unjittered.lights[0].jitter = False
    tree = raytrace.explain(unjittered, (0, 0), width=1, height=1, max_depth=1)
    hits = [r for r in tree["rays"] if r["depth"] == 1 and r["hit"] is not None]
    same = [np.array([lt["term"] for lt in r["lights"]]) for r in hits]
    np.testing.assert_allclose(same[0], same[1], rtol=1e-12)


def test_children_of_one_hit_draw_uncorrelated_light_points():
    """20 000 camera samples, each hitting a beam splitter at a random point: the draws
    (:func:`raytrace.kernels.core.light_uniform`'s first number, the point's position along
    the light's first edge) of its reflected child (leaving up) and refracted child (leaving
    down) at depth 1. Their correlation is within 4/√n ≈ 0.028 of 0 (its standard deviation
    for independent draws is 1/√n); keyed by the camera sample alone, as before per-path
    keys, the two draws are the same number (correlation 1)."""
    from raytrace.shading import path_keys

    n = 20_000
    rng = np.random.default_rng(4)
    keys = np.arange(n, dtype=np.int64)
    origin = np.column_stack([rng.random(n), np.ones(n), rng.random(n)])
    up = np.tile([0.0, 1.0, 0.0], (n, 1))

    def first_draw(k: np.ndarray) -> np.ndarray:
        return (light_words(k, 3, 1) >> 32).astype(np.float64) * 2.0**-31

    reflected = first_draw(path_keys(keys, origin, up))
    refracted = first_draw(path_keys(keys, origin, -up))
    assert abs(np.corrcoef(reflected, refracted)[0, 1]) < 4 / math.sqrt(n)
    assert abs(reflected.mean() - 0.5) < 4 * math.sqrt(1 / 12 / n)
    assert np.corrcoef(first_draw(keys), first_draw(keys))[0, 1] == pytest.approx(1.0)


def test_path_keys_differ_by_path_and_keep_camera_keys():
    from raytrace.shading import path_keys

    origin = np.zeros((3, 3))
    direction = np.array([[0.0, 1.0, 0.0], [0.0, -1.0, 0.0], [0.0, 1.0, 0.0]])
    keys = path_keys(np.array([7, 7, 8]), origin, direction)
    assert len(set(keys.tolist())) == 3 and np.all(keys >= 0)
    np.testing.assert_array_equal(keys, path_keys(np.array([7, 7, 8]), origin, direction))
    assert path_keys(np.array([7]), origin[:1] + [0, 0, 1e-16], direction[:1])[0] != keys[0]


def test_per_path_jitter_is_the_same_for_any_threads_and_pass_size():
    """Secondary rays' light points follow their path, not the batch they are traced in."""
    scene = _splitter_scene(samples=9)
    scene.camera = raytrace.Camera(position=[0.0, 1.5, 0.0], look_at=[0.0, 0.0, 0.0],
                                   up=[1.0, 0.0, 0.0], fov=60.0)
    one = raytrace.render(scene, width=24, height=16, spp=4, max_depth=2, threads=1).rgb
    assert one.max() > 0.0
    np.testing.assert_array_equal(
        one, raytrace.render(scene, width=24, height=16, spp=4, max_depth=2, threads=2).rgb)
    np.testing.assert_array_equal(
        one, raytrace.render(scene, width=24, height=16, spp=4, max_depth=2, threads=2,
                             pass_samples=64).rgb)


@pytest.mark.parametrize("jitter", [False, True])
def test_every_emitter_has_a_label_naming_its_light_and_part(jitter):
    # explain's labels (raytrace.raytree): one per emitter, in emitters' order, each light
    # naming the parts of its own (an area light's cells).
    lights = [raytrace.AreaLight([0, 3, 0], [1, 0, 0], [0, 0, 1], samples=4, jitter=jitter),
              raytrace.PointLight([0, 2, 0]), raytrace.DirectionalLight([0, -1, 0]),
              raytrace.SpotLight([0, 2, 0], [0, -1, 0])]
    origin = np.array([0.5, 1.0, 2.0])
    assert labels(lights, origin, 7) == [
        *(f"lights[0] (area, cell {c})" for c in range(4)), "lights[1] (point)",
        "lights[2] (directional)", "lights[3] (spot)"]
    assert len(labels(lights, origin, 7)) == len(emitters(lights, origin, 7))


# -- bounds on light positions, edges and directions -----------------------------------------
@pytest.mark.parametrize("make,key", [
    (lambda: raytrace.PointLight([0, 1e200, 0]), "position[1]"),
    (lambda: raytrace.SpotLight([0, 0, -1e13], [0, -1, 0]), "position[2]"),
    (lambda: raytrace.AreaLight([1e308, 0, 0], [1, 0, 0], [0, 0, 1]), "position[0]"),
])
def test_a_light_beyond_the_coordinate_bound_is_refused(make, key):
    with pytest.raises(raytrace.SceneError) as e:
        make()
    assert e.value.key == key
    assert e.value.problem.startswith("must be within ±1e+12 (")


@pytest.mark.parametrize("edge,length", [([1e-300, 0, 0], "1e-300"),
                                         ([0, 0, 1e13], "10000000000000.0"),
                                         ([1e200, 1e200, 0], "1.414213562373095e+200")])
def test_an_area_light_edge_outside_the_length_bounds_says_so(edge, length):
    """An edge of 1e-300 was reported as parallel to the other (the cross product underflows)."""
    with pytest.raises(raytrace.SceneError) as e:
        raytrace.AreaLight([0, 1, 0], edge, [0, 1, 0])
    assert str(e.value) == (f"edge_u: its length must be within [1e-12, 1e+12] (the lengths at "
                            f"which a scene renders as it does at unit size), got {length}")


def test_a_light_direction_too_short_to_normalise_is_refused():
    with pytest.raises(raytrace.SceneError, match=r"^direction: is too short to normalise"):
        raytrace.DirectionalLight([1e-160, -1e-160, 0])
