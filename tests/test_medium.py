"""What lies behind a surface (raytrace/kernels/medium.py): Beer's-law absorption inside a
closed volume and thin walls, against hand-worked values.

Beer's law: light crossing a length L of a material with ``attenuation_color`` c and
``attenuation_distance`` D keeps ``c^(L/D) = exp(−σ·L)``, σ = −ln(c)/D, per channel
(KHR_materials_volume, "Attenuation"). A thin wall passes light without bending.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import trimesh
from helpers import make_scene, pixel, write_gltf

import raytrace
from raytrace import Camera, Checker, DirectionalLight, Material, Mesh, Plane, Sphere
from raytrace.integrator import WhittedIntegrator
from raytrace.rendering import render_options
from raytrace.tables import scene_arrays

C = np.array([0.8, 0.5, 0.2])  # attenuation colour
D = 2.0                        # attenuation distance
BG = np.array([0.3, 0.6, 0.9])
SIGMA = -np.log(C) / D


def tinted(ior=1.0, fresnel="none", kr=0.0, **kw) -> Material:
    """Clear glass (kt = 1, nothing lit or emitted) with an absorbing interior."""
    return Material(kd=0.0, ks=0.0, kr=kr, kt=1.0, ior=ior, fresnel=fresnel,
                    attenuation_color=C, attenuation_distance=D, **kw)


def box(extents, translate, material) -> Mesh:
    return Mesh(mesh=trimesh.creation.box(extents=extents), translate=translate,
                material=material)


@pytest.mark.parametrize("offset", [0.0, 0.6])
def test_an_ior_one_sphere_absorbs_along_its_chord(offset):
    # ior 1, no Fresnel: the ray along −z at distance b from the centre of a sphere of radius
    # r = 1 crosses the chord L = 2·sqrt(r² − b²) (b = 0: 2; b = 0.6: 1.6) inside and goes on
    # straight: the pixel is BG·c^(L/D) (c^1 = (0.8, 0.5, 0.2); c^0.8 = (0.8365, 0.5743,
    # 0.2759)). Without absorption it would be BG.
    chord = 2.0 * math.sqrt(1.0 - offset**2)
    cam = Camera([offset, 0, 5], [offset, 0, 0])
    got = pixel(make_scene([Sphere([0, 0, 0], 1.0, tinted())], [], cam, background=BG,
                           max_depth=3))
    np.testing.assert_allclose(got, BG * C ** (chord / D), rtol=1e-6)


@pytest.mark.parametrize("theta_deg", [0.0, 35.0])
def test_a_tilted_ray_through_an_ior_one_slab_absorbs_over_h_over_cos_theta(theta_deg):
    # A mesh slab of thickness h = 0.5 (y in [−1.25, −0.75]), ior 1: a ray at θ from the
    # vertical crosses L = h/cos θ inside (0.5 and 0.6104), so the pixel is BG·c^(L/D).
    # The spawn offsets (a few float32 ulps of the 40-unit slab) change L by ~1e-5.
    t = math.radians(theta_deg)
    cam = Camera([0, 0, 0], [math.sin(t), -math.cos(t), 0], up=[0, 0, 1])
    scene = make_scene([box((40.0, 0.5, 40.0), (0, -1.0, 0), tinted())], [], cam,
                       background=BG, max_depth=3)
    np.testing.assert_allclose(pixel(scene), BG * C ** (0.5 / math.cos(t) / D), rtol=2e-5)


def test_normal_incidence_through_a_glass_ball_centre():
    # ior 1.5, dielectric Fresnel, kr = 0 (no reflected child): head on, each crossing passes
    # 1 − R, R = ((n − 1)/(n + 1))² = 0.04, and the ray crosses 2r = 2 inside:
    # BG·(1 − R)²·exp(−σ·2r) = BG·0.9216·c^(2/2).
    r = 1.0
    expected = BG * (1 - 0.04) ** 2 * np.exp(-SIGMA * 2 * r)
    cam = Camera([0, 0, 5], [0, 0, 0])
    got = pixel(make_scene([Sphere([0, 0, 0], r, tinted(ior=1.5, fresnel="dielectric"))], [],
                           cam, background=BG, max_depth=3))
    np.testing.assert_allclose(got, expected, rtol=1e-6)  # the image is float32


def test_a_camera_inside_absorbing_glass_sees_through_the_distance_to_the_wall():
    # The camera at the centre of a sphere of radius 2 (ior 1.5, no Fresnel): every camera ray
    # starts inside and leaves the wall head on (no bending), after 2 units inside:
    # BG·c^(2/D) in every pixel.
    c = np.array([1.0, 2.0, 3.0])
    scene = make_scene([Sphere(c, 2.0, tinted(ior=1.5))], [], Camera(c, c + [0, 0, -1], fov=90),
                       background=BG, max_depth=2)
    image = raytrace.render(scene, width=8, height=6)
    np.testing.assert_allclose(image.rgb, np.broadcast_to(BG * C ** (2 / D), (6, 8, 3)),
                               rtol=1e-6)


def test_nested_media_absorb_only_where_a_ray_leaves_them():
    # Whitted has no medium stack: a segment is absorbed by the material it leaves at its far
    # end. Through the centre of a tinted sphere (r = 2) holding a clear one (r = 1), both
    # ior 1: camera → outer wall (enters: nothing), → inner wall (enters: nothing), → inner
    # wall (leaves the clear one: σ = 0), → outer wall (leaves the tinted one after 1 unit):
    # BG·c^(1/D) (docs/shading.md states the rule; a medium stack would give c^(2/D)).
    clear = Material(kd=0.0, ks=0.0, kt=1.0, ior=1.0)
    scene = make_scene([Sphere([0, 0, 0], 2.0, tinted()), Sphere([0, 0, 0], 1.0, clear)], [],
                       Camera([0, 0, 6], [0, 0, 0]), background=BG, max_depth=5)
    np.testing.assert_allclose(pixel(scene), BG * C ** (1 / D), rtol=1e-6)


def test_a_shadow_through_absorbing_glass_is_tinted_by_its_thickness():
    # A directional light straight down through an ior-1 slab of thickness 0.5 (y in [1, 1.5])
    # onto a floor y = 0 (kd 0.6, ambient 0); the camera sits under the slab, so only the
    # shadow ray crosses it: kd·(N·L = 1)·I·kt·c^(0.5/D).
    floor = Plane([0, 0, 0], [0, 1, 0], Material(kd=0.6, ks=0.0))
    scene = make_scene([floor, box((40.0, 0.5, 40.0), (0, 1.25, 0), tinted())],
                       [DirectionalLight([0, -1, 0], 1.0)],
                       Camera([0, 0.5, 3], [0, 0, 0]), max_depth=1)
    np.testing.assert_allclose(pixel(scene), 0.6 * C ** (0.5 / D), rtol=1e-6)


# -- thin walls against volumes, read from glTF ----------------------------------------------
THETA = math.radians(40.0)
THETA_T = math.asin(math.sin(THETA) / 1.5)
EDGE = -1e-3  # the checker's x edge on the floor y = −2 (scale 10: floor(x/10 + 1e-4))
A, B = np.array([0.9, 0.8, 0.7]), np.array([0.1, 0.2, 0.3])  # x < EDGE: A; x ≥ EDGE: B


def fresnel(cos_i: float, n1: float, n2: float) -> float:
    """The unpolarised Fresnel reflectance (Hecht, Optics, §4.6), written out here."""
    sin_t = n1 / n2 * math.sqrt(1 - cos_i * cos_i)
    cos_t = math.sqrt(1 - sin_t * sin_t)
    rs = (n1 * cos_i - n2 * cos_t) / (n1 * cos_i + n2 * cos_t)
    rp = (n2 * cos_i - n1 * cos_t) / (n2 * cos_i + n1 * cos_t)
    return (rs * rs + rp * rp) / 2


def gltf_pane(tmp_path, volume: dict | None) -> Mesh:
    """A 40 × 0.5 × 40 glTF box centred at y = −1 (top −0.75, bottom −1.25) of clear glass
    (KHR_materials_transmission 1, ior 1.5), with ``volume`` as its KHR_materials_volume."""
    m = trimesh.creation.box(extents=(40.0, 0.5, 40.0))
    ext = {"KHR_materials_transmission": {"transmissionFactor": 1.0},
           "KHR_materials_ior": {"ior": 1.5}}
    if volume is not None:
        ext["KHR_materials_volume"] = volume
    material = {"pbrMetallicRoughness": {"baseColorFactor": [1, 1, 1, 1],
                                         "metallicFactor": 0.0, "roughnessFactor": 0.0},
                "extensions": ext}
    path = write_gltf(tmp_path / "pane.gltf", [{"mesh": 0, "translation": [0, -1, 0]}],
                      [{"positions": m.vertices.tolist(), "indices": m.faces.tolist(),
                        "material": 0}], [material])
    return Mesh(file=path, material="from_file")


def edge_pixel(c: float, pane: Mesh | None, toward: int = 1) -> np.ndarray:
    """The one pixel of a camera at (c, 0, 0) looking down at θ = 40° from the vertical
    (towards +x, or −x with ``toward`` −1) through ``pane`` at the ambient-only checker floor
    y = −2."""
    floor = Material(ka=Checker((A, B), 10.0), kd=0.0)
    cam = Camera([c, 0, 0], [c + toward * math.sin(THETA), -math.cos(THETA), 0], up=[0, 0, 1])
    objects = [Plane([0, -2.0, 0], [0, 1, 0], floor), *([pane] if pane else [])]
    return pixel(make_scene(objects, [], cam, ambient=1.0, max_depth=3))


@pytest.mark.parametrize("volume", [None, {"thicknessFactor": 0.0}])
@pytest.mark.parametrize("toward", [+1, -1])
def test_a_thin_walled_pane_does_not_displace_what_is_behind_it(tmp_path, volume, toward):
    # Without a volume (or with thickness 0) glTF transmission is a thin wall: the ray goes
    # straight on, landing on the floor at x = c ± 2·tan θ (looking towards ±x) as without the
    # pane. Put that 2e-5 beyond the checker edge: the pane must show the same cell as no
    # pane, times (1 − F)² (Fresnel at θ on both faces; max_depth 3 keeps the light reflected
    # between the faces (depth ≥ 4) out, and the reflection off the top sees a black
    # background). A refracting pane would pull the landing back towards the camera by
    # 0.5·(tan θ − tan θt) = 0.19, across the edge, into the other cell.
    c = EDGE - toward * (2 * math.tan(THETA) - 2e-5)
    bare = edge_pixel(c, None, toward)
    np.testing.assert_allclose(bare, B if toward > 0 else A, rtol=1e-6)
    got = edge_pixel(c, gltf_pane(tmp_path, volume), toward)
    np.testing.assert_allclose(got, (1 - fresnel(math.cos(THETA), 1, 1.5)) ** 2 * bare,
                               rtol=1e-6)


@pytest.mark.parametrize("side", [+1, -1])
def test_a_volume_pane_displaces_by_t_sin_theta_minus_theta_t_over_cos_theta_t(tmp_path, side):
    # With KHR_materials_volume (thickness > 0) the pane refracts: the ray leaves it parallel
    # to itself, displaced sideways by Δ = t·sin(θ − θt)/cos θt (t = 0.5, θ = 40°, sin θt =
    # sin θ/1.5), which moves its landing on the floor by Δ/cos θ towards −x: from
    # c + 2·tan θ to c + 2·tan θ − Δ/cos θ. Put the displaced landing 2e-5 to one side of the
    # edge: the cell is that side's, while the undisplaced landing (0.19 to +x) is B's on both.
    # Transmission: (1 − F(θ))·(1 − F(θt, leaving)) = (1 − F(θ))² (Stokes: F is reciprocal).
    delta = 0.5 * math.sin(THETA - THETA_T) / math.cos(THETA_T)
    c = EDGE - (2 * math.tan(THETA) - delta / math.cos(THETA)) + side * 2e-5
    got = edge_pixel(c, gltf_pane(tmp_path, {"thicknessFactor": 0.5}))
    expected = (1 - fresnel(math.cos(THETA), 1, 1.5)) ** 2 * (B if side > 0 else A)
    np.testing.assert_allclose(got, expected, rtol=1e-6)
    np.testing.assert_allclose(edge_pixel(c, None), B, rtol=1e-6)  # the landing without it


# -- what a scene compiles -------------------------------------------------------------------
def test_only_a_scene_with_absorbing_or_thin_walled_materials_has_media():
    plain = make_scene([Sphere([0, 0, 0], 1.0, Material(kt=1.0, ior=1.5))], [],
                       Camera([0, 0, 5], [0, 0, 0]))
    assert scene_arrays(plain).record.media is None
    assert "media" not in WhittedIntegrator(plain, render_options(plain)).features
    for m in (tinted(), Material(kt=1.0, thin_walled=True)):
        scene = make_scene([Sphere([0, 0, 0], 1.0, m)], [], Camera([0, 0, 5], [0, 0, 0]))
        media = scene_arrays(scene).record.media
        assert media is not None
        np.testing.assert_allclose(media.sigma[0], SIGMA if m.absorbs else 0.0, rtol=1e-15)
        assert media.thin[0] == m.thin_walled
        assert "media" in WhittedIntegrator(scene, render_options(scene)).features
