"""Torture suite: stiff and extreme cases, one test per case, each with an oracle.

Every render here goes through :func:`render_checked`, which asserts that no non-finite pixel
was produced (``stats["nonfinite_pixels"] == 0``) and none reached the image. Oracles are
closed forms worked out in the tests (pinhole rays are recomputed here from SCENE_FORMAT.md's
definition, not taken from raytrace.camera), invariants (scale, translation) or exact
identities (ior 1 is no sphere at all). docs/robustness.md tabulates the cases and the
measured errors; run ``python3 -m pytest tests/test_torture.py -q -s`` to see them printed.
"""

from __future__ import annotations

import math
from decimal import Decimal, getcontext
from pathlib import Path

import numpy as np
import pytest
import trimesh

import raytrace
from raytrace import (
    Camera,
    DirectionalLight,
    Material,
    Mesh,
    Plane,
    PointLight,
    RenderSettings,
    Scene,
    Sphere,
    SpotLight,
)
from raytrace.camera import camera_rays
from raytrace.integrator import RenderOptions, WhittedIntegrator
from raytrace.lights import Emitter, cos_cutoff
from raytrace.material import Checker
from raytrace.optics import critical_angle, reflect, refract
from raytrace.rays import REFLECTION, REFRACTION
from raytrace.shading import cosine_power, direct, incidence

ROOT = Path(__file__).resolve().parents[1]


# -- helpers ----------------------------------------------------------------------------------
def render_checked(scene: Scene, **kw) -> tuple[np.ndarray, dict]:
    """Render; assert that no non-finite pixel was produced or written. (H, W, 3) float64."""
    image = raytrace.render(scene, **kw)
    assert image.stats["nonfinite_pixels"] == 0
    assert np.isfinite(image.rgb).all()
    return image.rgb.astype(np.float64), image.stats


def pinhole(position, look_at, up, fov: float, width: int, height: int) -> np.ndarray:
    """Unit directions (H, W, 3) of pixel-centre rays, from SCENE_FORMAT.md alone.

    Pixel (0, 0) is top-left; the centre of pixel (row, col) sits at
    x = (2(col + ½)/W − 1)·tan(fov/2)·W/H, y = (1 − 2(row + ½)/H)·tan(fov/2) on the image
    plane one unit in front; right = forward × up, true up = right × forward.
    """
    position, look_at, up = (np.asarray(v, dtype=np.float64) for v in (position, look_at, up))
    f = look_at - position
    f /= np.linalg.norm(f)
    r = np.cross(f, up)
    r /= np.linalg.norm(r)
    u = np.cross(r, f)
    th = math.tan(math.radians(fov) / 2)
    col, row = np.meshgrid(np.arange(width), np.arange(height))
    x = (2 * (col + 0.5) / width - 1) * th * width / height
    y = (1 - 2 * (row + 0.5) / height) * th
    d = x[..., None] * r + y[..., None] * u + f
    return d / np.linalg.norm(d, axis=-1, keepdims=True)


def plane_hits(origin, dirs: np.ndarray, height: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Hit points (H, W, 3) of rays with the plane y = height, and where they hit (t > 0)."""
    origin = np.asarray(origin, dtype=np.float64)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (height - origin[1]) / dirs[..., 1]
    hit = np.isfinite(t) & (t > 0)
    return origin + np.where(hit, t, 0.0)[..., None] * dirs, hit


def rel_err(a: np.ndarray, b: np.ndarray, floor: float = 1e-12) -> np.ndarray:
    return np.abs(a - b) / np.maximum(np.abs(b), floor)


def measured(label: str, value: float) -> None:
    """Print a measured number (shown with ``pytest -s``; quoted in docs/robustness.md)."""
    print(f"\n[measured] {label}: {value:.3g}")


def quad(size: float, y: float = 0.0, flip_second: bool = False) -> tuple[list, list]:
    """A square [−size, size]² at height y, two CCW (upward) triangles."""
    v = [[-size, y, -size], [size, y, -size], [size, y, size], [-size, y, size]]
    f = [[0, 3, 2], [0, 2, 1]]
    if flip_second:
        f[1] = [0, 1, 2]
    return v, f


# -- scale and translation invariance -------------------------------------------------------
def invariance_scene(s: float, shift: float) -> Scene:
    """The same scene scaled by ``s`` and moved by ``shift`` along (1, 1, 1).

    Lengths scale; so do the checker cell and the attenuation (1/(a0 + a1·d + a2·d²) is
    invariant under d → s·d when a1 → a1/s and a2 → a2/s²); directions and angles do not.
    """
    t = np.full(3, shift)

    def p(x):
        return (s * np.asarray(x, dtype=np.float64) + t).tolist()

    att = [1.0, 0.05 / s, 0.01 / s**2]
    ico = trimesh.creation.icosphere(subdivisions=2, radius=0.6)
    floor = Material(kd=Checker((np.array([0.8, 0.8, 0.8]), np.array([0.2, 0.3, 0.4])), s),
                     ks=0.3, shininess=20)
    materials = {
        "red": Material(kd=[0.8, 0.1, 0.1], ks=0.5, shininess=50, highlight="blinn"),
        "mirror": Material(kd=0.1, ks=0.2, kr=0.7),
        "glass": Material(kd=0.0, ks=0.4, kr=0.1, kt=0.85, ior=1.5, shininess=200,
                          highlight="blinn"),
        "green": Material(kd=[0.2, 0.6, 0.2], ks=0.3),
        "floor": floor,
    }
    return Scene(
        camera=Camera(p([0, 1.2, 5]), p([0, 0.6, 0]), [0, 1, 0], 45),
        objects=[Sphere(p([-1.4, 0.8, -0.8]), 0.8 * s, "red"),
                 Sphere(p([0.1, 0.7, -1.8]), 0.7 * s, "mirror"),
                 Sphere(p([-0.1, 0.5, 1.0]), 0.5 * s, "glass"),
                 Plane(p([0, 0, 0]), [0, 1, 0], "floor"),
                 Mesh(vertices=s * (ico.vertices + [1.6, 0.6, -0.5]) + t, faces=ico.faces,
                      shading="smooth", material="green")],
        lights=[DirectionalLight([-1, -2, -1], 0.6), PointLight(p([3, 5, 4]), 0.8, att),
                SpotLight(p([-2, 4, 2]), [0.4, -1, -0.4], 30, 4, 0.7, att)],
        materials=materials, ambient=0.1, render=RenderSettings(background=[0.1, 0.2, 0.3]))


def hit_ids(scene: Scene, width: int, height: int) -> np.ndarray:
    """(H, W) id of the object each camera ray hits first: analytic shape, mesh (1000), or −1."""
    integ = WhittedIntegrator(scene, RenderOptions(width=width, height=height, max_depth=0))
    rays = camera_rays(scene.camera, RenderSettings(width=width, height=height), 0,
                       width * height)
    hits = integ.accel.intersect(rays.origin, rays.direction, rays.origin_shape)
    ids = np.where(hits.triangle >= 0, 1000, hits.shape)
    return np.where(hits.hit, ids, -1).reshape(height, width)


def edge_mask(ids: np.ndarray, rgb: np.ndarray, radius: int = 2, contrast: float = 0.1
              ) -> np.ndarray:
    """Pixels within ``radius`` px of a silhouette (a change of hit id), or next to a jump of
    more than ``contrast`` (relative) in the image (shadow, checker and reflected edges)."""
    h, w = ids.shape
    pad = np.pad(ids, radius, mode="edge")
    mask = np.zeros((h, w), bool)
    for dy in range(-radius, radius + 1):
        for dx in range(-radius, radius + 1):
            mask |= pad[radius + dy: radius + dy + h, radius + dx: radius + dx + w] != ids
    lum = rgb.max(axis=2)
    pad = np.pad(lum, 1, mode="edge")
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            nb = pad[1 + dy: 1 + dy + h, 1 + dx: 1 + dx + w]
            mask |= np.abs(nb - lum) > contrast * np.maximum(lum, 0.01)
    return mask


@pytest.mark.parametrize("scale,shift", [(1e-6, 0.0), (1e6, 0.0), (1.0, 1e5)],
                         ids=["scale 1e-6", "scale 1e6", "moved 1e5"])
def test_scale_and_translation_invariance(scale, shift):
    w, h = 96, 72
    ref, _ = render_checked(invariance_scene(1.0, 0.0), width=w, height=h)
    img, stats = render_checked(invariance_scene(scale, shift), width=w, height=h)
    ids = hit_ids(invariance_scene(1.0, 0.0), w, h)
    assert (ids == hit_ids(invariance_scene(scale, shift), w, h)).mean() > 0.99
    keep = ~edge_mask(ids, ref, radius=1, contrast=0.25)
    assert keep.mean() > 0.55, "the mask must leave most of the image to compare"
    assert {0, 1, 2, 3, 1000} <= set(np.unique(ids[keep])), "every object is compared"
    err = rel_err(img, ref, 1e-3).max(axis=2)
    measured(f"scale {scale:g}, shift {shift:g}: max relative error over "
             f"{keep.mean():.0%} of pixels", err[keep].max())
    measured(f"scale {scale:g}, shift {shift:g}: pixels of {w * h} over 1e-5 anywhere "
             f"(max {err.max():.2g})", (err > 1e-5).sum())
    assert err[keep].max() < 1e-5


# -- grazing light and grazing camera rays: no acne -----------------------------------------
def lit_plane_value(points, normal_y, light_pos, ka_ia, kd, intensity, att=(1.0, 0.0, 0.0)):
    """ka·Ia + kd·max(N·L, 0)·I/(a0 + a1·d + a2·d²) for points on a plane with N = ±y."""
    delta = np.asarray(light_pos, dtype=np.float64) - points
    dist = np.linalg.norm(delta, axis=-1)
    ndl = np.maximum(normal_y * delta[..., 1] / dist, 0.0)
    return ka_ia + kd * ndl * intensity / (att[0] + att[1] * dist + att[2] * dist**2)


def ground(kind: str, size: float, material) -> object:
    if kind == "plane":
        return Plane([0, 0, 0], [0, 1, 0], material)
    v, f = quad(size)
    return Mesh(vertices=v, faces=f, material=material)


@pytest.mark.parametrize("kind", ["plane", "mesh"])
def test_grazing_light_no_acne(kind):
    # A point light 1e-3 above the ground, ~5 units away from what the camera sees: N·L is
    # 2e-4 or less. Unshadowed, I = ka·Ia + kd·N·L·I_l per pixel; acne would darken pixels
    # to ka·Ia.
    cam, look, fov, w, h = [0, 2, 6], [0, 0, 0], 50, 48, 36
    light = [0.3, 1e-3, -4.0]
    mat = Material(kd=0.8, ka=0.5)
    scene = Scene(camera=Camera(cam, look, fov=fov), objects=[ground(kind, 100.0, mat)],
                  lights=[PointLight(light, 200.0)], ambient=0.05)
    img, _ = render_checked(scene, width=w, height=h)
    pts, hit = plane_hits(cam, pinhole(cam, look, [0, 1, 0], fov, w, h))
    want = lit_plane_value(pts, 1.0, light, 0.05 * 0.5, 0.8, 200.0)
    inside = hit & (np.abs(pts[..., [0, 2]]).max(axis=-1) < 99.0)
    assert inside.mean() > 0.5
    assert (want[inside] > 0.05 * 0.5 * 1.01).mean() > 0.9, "most pixels are lit"
    err = rel_err(img[inside], want[inside, None])
    measured(f"grazing light on a {kind}: max relative error", err.max())
    assert err.max() < 1e-5


@pytest.mark.parametrize("kind", ["plane", "mesh"])
def test_grazing_camera_rays_no_acne(kind):
    # The camera 1e-3 above the ground looks along it with a 2° field: the rays meet the
    # ground at 1e-3 rad and less. A light straight above: I = ka·Ia + kd·N·L·I_l per pixel;
    # above the horizon the background. The mesh ground is 1000 units wide; the band of pixels
    # whose analytic hit falls near its far edge is left out.
    cam, look, fov, w, h = [0.0, 1e-3, 0.0], [0.0, 1e-3, -1.0], 2.0, 32, 33
    light = [0.0, 10.0, -5.0]
    mat = Material(kd=0.7, ka=0.0)
    scene = Scene(camera=Camera(cam, look, fov=fov), objects=[ground(kind, 1000.0, mat)],
                  lights=[PointLight(light, 1.0)], ambient=0.0,
                  render=RenderSettings(background=0.25))
    img, _ = render_checked(scene, width=w, height=h)
    dirs = pinhole(cam, look, [0, 1, 0], fov, w, h)
    pts, hit = plane_hits(cam, dirs)
    reach = np.abs(pts[..., [0, 2]]).max(axis=-1)
    if kind == "mesh":
        hit &= reach < 1000.0
        compare = ~((reach > 900.0) & (reach < 1100.0))
    else:
        compare = np.ones_like(hit)
    want = np.where(hit, lit_plane_value(pts, 1.0, light, 0.0, 0.7, 1.0), 0.25)
    grazing = hit & (dirs[..., 1] > -2e-3)
    assert (grazing & compare).sum() >= 10, "some rays really graze"
    err = rel_err(img[compare], want[compare, None])
    measured(f"grazing camera rays on a {kind}: max relative error", err.max())
    assert err.max() < 1e-5


# -- N·L = 0, V·R < 0, L = −V, huge exponents ------------------------------------------------
def test_normal_dot_light_exactly_zero_gives_ambient_only():
    # A directional light travelling along the floor and a point light in its plane: N·L is
    # exactly 0 at every hit, so I = ka·Ia even with shininess 0 (spec would be 1 if it were
    # not gated by N·L > 0).
    mat = Material(kd=0.6, ka=0.4, ks=0.9, shininess=0)
    cam, look, fov, w, h = [0, 2, 3], [0, 0, 0], 60, 24, 18
    scene = Scene(camera=Camera(cam, look, fov=fov), objects=[Plane([0, 0, 0], [0, 1, 0], mat)],
                  lights=[DirectionalLight([1, 0, 0], 5.0), PointLight([3, 0, -2], 5.0)],
                  ambient=0.5, render=RenderSettings(background=0.125))
    img, _ = render_checked(scene, width=w, height=h)
    _, hit = plane_hits(cam, pinhole(cam, look, [0, 1, 0], fov, w, h))
    want = np.where(hit, 0.5 * 0.4, 0.125)
    np.testing.assert_array_equal(img, np.repeat(want[..., None], 3, axis=2).astype(np.float32))


def test_shading_terms_at_the_degenerate_angles():
    n = np.array([[0.0, 1.0, 0.0]])
    one = np.ones((1, 3))
    for model in (0, 1):  # phong, blinn
        # N·L = 0 exactly: nothing, even with exponent 0 (0^0 would be 1).
        out = direct(n, np.array([[1.0, 0.0, 0.0]]), n, one, one, np.array([0.0]),
                     np.array([model]))
        assert out.tolist() == [[0.0, 0.0, 0.0]]
    # a·b = 0 exactly where |a − b|² rounds below 2 (found by hypothesis): 0, not 0^0 = 1.
    a, b = np.array([[0.0, 0.0, 1.0]]), np.array([[0.625, 0.1875, 0.0]])
    b /= np.linalg.norm(b)
    assert 0.5 * ((a - b) ** 2).sum() < 1.0 and float(a[0] @ b[0]) == 0.0
    assert cosine_power(a, b, np.array([0.0])).tolist() == [0.0]
    # V·R < 0: L at 45°, V opposite to R = (−L_x, L_y): Phong's highlight is 0, diffuse stays.
    s = math.sqrt(0.5)
    out = direct(n, np.array([[s, s, 0.0]]), np.array([[s, -s, 0.0]]), one, one,
                 np.array([1.0]), np.array([0]))
    np.testing.assert_allclose(out, [[s, s, s]], rtol=1e-15)
    # Blinn with L = −V (the viewer below the surface): L + V = 0 has no direction: spec 0.
    out = direct(n, np.array([[0.0, 1.0, 0.0]]), np.array([[0.0, -1.0, 0.0]]), one, one,
                 np.array([0.0]), np.array([1]))
    assert out.tolist() == [[1.0, 1.0, 1.0]]  # kd·N·L = 1 and no NaN from normalising 0


@pytest.mark.parametrize("n", [0, 1, 1e4, 1e6, 1e8])
def test_cosine_power_against_high_precision(n):
    # (a·b)^n for unit a, b at angles around the highlight width sqrt(2/n), against Python's
    # Decimal with 60 digits: cos θ = a·b/(|a||b|) exactly from the float64 components, then
    # exp(n·ln cos θ). The naive float64 pow loses n·1e-16 relative; the stable form keeps it.
    getcontext().prec = 60
    width = math.sqrt(2.0 / n) if n > 1 else 0.5
    worst = 0.0
    for k in (0.0, 0.1, 0.5, 1.0, 2.0, 3.0):
        th = k * width
        a = np.array([[1.0, 0.0, 0.0]])
        b = np.array([[math.cos(th), math.sin(th), 0.0]])
        got = float(cosine_power(a, b, np.array([float(n)]))[0])
        bx, by = Decimal(b[0, 0]), Decimal(b[0, 1])
        cos = bx / (bx * bx + by * by).sqrt()
        want = Decimal(1) if n == 0 else (Decimal(n) * cos.ln()).exp()
        worst = max(worst, abs(got - float(want)) / float(want))
    measured(f"cosine_power n={n:g}: max relative error", worst)
    assert worst < 1e-9


def highlight_closed_form(model: str, n: float, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """The highlight of a camera looking straight down at a floor lit straight down.

    With L = N = +y, R = N and the pixel ray through (x, y) at unit depth, V·R = 1/s with
    s = sqrt(1 + ρ²), ρ² = x² + y²; so Phong's (V·R)^n = exp(−(n/2)·log1p(ρ²)). Blinn's
    N·H = sqrt((1 + c)/2), c = 1/s, so (N·H)^n = exp((n/2)·log1p(−(1 − c)/2)) with
    1 − c = ρ²/(s(1 + s)) (no cancellation).
    """
    rho2 = x * x + y * y
    if model == "phong":
        return np.exp(-0.5 * n * np.log1p(rho2))
    s = np.sqrt(1.0 + rho2)
    return np.exp(0.5 * n * np.log1p(-0.5 * rho2 / (s * (1.0 + s))))


@pytest.mark.parametrize("model", ["phong", "blinn"])
@pytest.mark.parametrize("n", [0, 1, 1e4, 1e6, 1e8])
def test_highlight_exponents_render_closed_form(model, n):
    w, h = 15, 11
    aspect = w / h
    # The field of view makes the highlight fill the frame: n·ρ²/2 ≈ 5 (Phong), n·ρ²/8 ≈ 5
    # (Blinn: the half-vector turns half as far) in the corners.
    spread = 10.0 if model == "phong" else 40.0
    tan_half = 1.0 if n <= 1 else math.sqrt(spread / (n * (1 + aspect**2)))
    fov = math.degrees(2 * math.atan(tan_half))
    mat = Material(kd=0.0, ks=1.0, shininess=n, highlight=model)
    scene = Scene(camera=Camera([0, 1, 0], [0, 0, 0], [0, 0, -1], fov),
                  objects=[Plane([0, 0, 0], [0, 1, 0], mat)],
                  lights=[DirectionalLight([0, -1, 0], 1.0)])
    img, _ = render_checked(scene, width=w, height=h)
    th = math.tan(math.radians(fov) / 2)
    col, row = np.meshgrid(np.arange(w), np.arange(h))
    x = (2 * (col + 0.5) / w - 1) * th * aspect
    y = (1 - 2 * (row + 0.5) / h) * th
    want = highlight_closed_form(model, n, x, y)
    assert want.min() < 0.2 or n <= 1, "the falloff is inside the frame"
    err = rel_err(img, want[..., None])
    measured(f"{model} n={n:g}: max relative error of the rendered highlight", err.max())
    assert err.max() < 1e-6


# -- light distance 0 and 1e8; spot cone edge -----------------------------------------------
def test_point_light_on_the_surface():
    # The camera looks straight down at the floor; the centre ray hits (0, 0, 0) exactly.
    # A light there (distance 0) has no direction: factor 0; a light in the floor's plane
    # has N·L = 0 elsewhere: everything is ka·Ia. A second scene puts the light 2⁻³⁰ above
    # the hit with f = 1/d²: the centre pixel gets kd·2⁶⁰, the rest the closed form. (2⁻³⁰ is
    # exact also camera-relative, −3 + 2⁻³⁰; 1e-12 would round there to 4e-4 relative.)
    cam, look, up, fov, w, h = [0, 3, 0], [0, 0, 0], [0, 0, -1], 60, 9, 9
    mat = Material(kd=0.5, ka=0.3)
    floor = [Plane([0, 0, 0], [0, 1, 0], mat)]
    img, _ = render_checked(Scene(camera=Camera(cam, look, up, fov), objects=floor,
                                  lights=[PointLight([0, 0, 0], 7.0)], ambient=0.2),
                            width=w, height=h)
    assert np.all(img == np.float32(0.2 * 0.3))
    img, _ = render_checked(Scene(camera=Camera(cam, look, up, fov), objects=floor,
                                  lights=[PointLight([0, 2**-30, 0], 1.0, [0, 0, 1])]),
                            width=w, height=h)
    pts, _ = plane_hits(cam, pinhole(cam, look, up, fov, w, h))
    want = lit_plane_value(pts, 1.0, [0, 2**-30, 0], 0.0, 0.5, 1.0, (0, 0, 1))
    assert img[4, 4, 0] == np.float32(0.5 * 2.0**60)
    assert rel_err(img, want[..., None]).max() < 1e-6


@pytest.mark.parametrize("att,color", [((1, 0, 0), 1.0), ((0, 0, 1), 1e16)],
                         ids=["no falloff", "1/d^2"])
def test_point_light_1e8_away(att, color):
    light = [3e7, 1e8, -2e7]
    cam, look, fov, w, h = [0, 2, 4], [0, 0, 0], 50, 20, 16
    scene = Scene(camera=Camera(cam, look, fov=fov),
                  objects=[Plane([0, 0, 0], [0, 1, 0], Material(kd=0.7, ka=0.0))],
                  lights=[PointLight(light, color, att)])
    img, _ = render_checked(scene, width=w, height=h)
    pts, hit = plane_hits(cam, pinhole(cam, look, [0, 1, 0], fov, w, h))
    want = np.where(hit, lit_plane_value(pts, 1.0, light, 0.0, 0.7, color, att), 0.0)
    assert want.max() > 0.3
    assert rel_err(img, want[..., None]).max() < 1e-6


def test_spot_cone_edge_is_inclusive_in_a_render():
    # A wall x = 2 facing a spot at the origin that points down with cutoff 90°: the cone is
    # the half-space y <= 0. The camera sits at the light and looks along +x; with an odd
    # height the middle row's rays have d_y = 0 exactly and hit the wall at y = 0, where
    # cos α = 0 = cos 90°: on the edge, inside (inclusive), f_angular = 0^0 = 1.
    w, h = 9, 9
    wall = Plane([2, 0, 0], [-1, 0, 0], Material(kd=0.5, ka=1.0))
    scene = Scene(camera=Camera([0, 0, 0], [1, 0, 0], fov=60), objects=[wall],
                  lights=[SpotLight([0, 0, 0], [0, -1, 0], 90.0, 0.0, 1.0)], ambient=0.1)
    img, _ = render_checked(scene, width=w, height=h)
    dirs = pinhole([0, 0, 0], [1, 0, 0], [0, 1, 0], 60, w, h)
    pts = 2.0 * dirs / dirs[..., :1]
    dist = np.linalg.norm(pts, axis=-1)
    ndl = 2.0 / dist                                 # N = (−1, 0, 0), L = −p/|p|
    want = 0.1 + np.where(pts[..., 1] <= 0, 0.5 * ndl, 0.0)
    assert (pts[4, :, 1] == 0).all()
    np.testing.assert_allclose(img[..., 0], want, rtol=1e-6)
    assert (img[4, :, 0] > 0.1 + 0.25).all(), "the edge row is lit"
    assert (img[3, :, 0] == np.float32(0.1)).all(), "the row above is outside"


def test_spot_cone_edge_exactly_at_a_general_angle():
    # A 3-4-5 triangle puts a point at cos α = 4/5 exactly, and this cutoff (found by
    # stepping through neighbouring doubles) has math.cos(radians(θ)) == 0.8 exactly.
    cutoff = 36.86989764584401
    assert cos_cutoff(cutoff) == 0.8
    em = Emitter(np.ones(3), np.zeros(3), np.array([0.0, -1.0, 0.0]), np.array([1.0, 0, 0]),
                 cos_cutoff(cutoff), 2.0)
    pts = np.array([[3.0, -4.0, 0.0], [3.0 + 1e-9, -4.0, 0.0], [0.0, -5.0, 0.0]])
    _, dist, f = incidence(em, pts)
    assert dist[0] == 5.0
    assert f[0] == 0.8**2  # on the edge: inside, (cos α)^a
    assert f[1] == 0.0      # just outside
    assert f[2] == 1.0      # on the axis


# -- dielectrics ------------------------------------------------------------------------------
def checker_floor_scene(obj_material, ambient=1.0, lights=()) -> Scene:
    floor = Material(ka=Checker((np.array([0.9, 0.6, 0.2]), np.array([0.1, 0.2, 0.5])), 0.5),
                     kd=0.0)
    objects = [Plane([0, -1, 0], [0, 1, 0], floor)]
    if obj_material is not None:
        objects.append(Sphere([0, 0, 0], 1.0, obj_material))
    return Scene(camera=Camera([0, 1.5, 4], [0, 0, 0], fov=45), objects=objects,
                 lights=list(lights), ambient=ambient,
                 render=RenderSettings(background=[0.3, 0.5, 0.7], max_depth=8))


def test_ior_one_is_exactly_undeviated():
    # kt = 1, ior = 1: the sphere must vanish, shadows included (t·kt + 1 − t = 1).
    glass = Material(kd=0.0, ks=0.0, kt=1.0, ior=1.0)
    light = [PointLight([3, 5, 2], 1.0)]
    floor_lit = Material(kd=Checker((np.array([0.9, 0.6, 0.2]), np.array([0.1, 0.2, 0.5])),
                                    0.5))
    with_sphere = checker_floor_scene(glass, 0.2, light)
    without = checker_floor_scene(None, 0.2, light)
    for s in (with_sphere, without):
        s.objects[0].material = floor_lit
    a, stats = render_checked(with_sphere, width=48, height=36)
    b, _ = render_checked(without, width=48, height=36)
    assert stats["rays"]["refraction"] > 0
    err = rel_err(a, b, 1e-3)
    measured("ior 1 sphere against no sphere: max relative error", err.max())
    assert err.max() < 1e-6


def test_ior_1e3_behaves_as_a_mirror():
    # Entering with η = 1/ior = 1000, Snell has no solution unless sin θ < 1e-3: the kt share
    # goes along the mirror direction (TIR), so a kt = 1 sphere looks exactly like a kr = 1
    # mirror except in the pixels hit within sin θ < 1e-3 of normal incidence.
    w, h = 48, 36
    tir, stats = render_checked(checker_floor_scene(Material(kd=0, ks=0, kt=1.0, ior=1e-3)),
                                width=w, height=h)
    mirror, _ = render_checked(checker_floor_scene(Material(kd=0, ks=0, kr=1.0)),
                               width=w, height=h)
    assert stats["total_internal_reflections"] > 0.9 * stats["rays"]["refraction"] > 0
    cam = np.array([0, 1.5, 4.0])
    dirs = pinhole(cam, [0, 0, 0], [0, 1, 0], 45, w, h)
    b = dirs @ cam
    disc = b * b - (cam @ cam - 1.0)
    tnear = -b - np.sqrt(np.maximum(disc, 0))
    normal = cam + tnear[..., None] * dirs
    cos_i = -(dirs * normal).sum(-1)
    near_normal = (disc > 0) & (np.sqrt(np.maximum(0, 1 - cos_i**2)) < 2e-3)
    assert (disc > 0).sum() > 100
    np.testing.assert_allclose(tir[~near_normal], mirror[~near_normal], rtol=1e-6)


def test_ior_10_sphere_is_invisible_with_kt_1():
    # kt = 1, kr = 0, background 1, no lights. By the sphere's symmetry a ray entering at θ
    # meets the far side at its refraction angle θt and leaves at θ again (no TIR is possible
    # from outside), with weight kt·kt = 1: every pixel is exactly the background, however
    # strongly ior 10 bends the rays inside.
    scene = Scene(camera=Camera([0, 0, 4], [0, 0, 0], fov=40),
                  objects=[Sphere([0, 0, 0], 1.0, Material(kd=0, ks=0, kt=1.0, ior=10.0))],
                  render=RenderSettings(background=1.0, max_depth=2))
    img, stats = render_checked(scene, width=31, height=31)
    assert stats["rays"]["refraction"] > 300
    assert stats["total_internal_reflections"] == 0
    np.testing.assert_allclose(img, 1.0, rtol=1e-6)


def test_critical_angle_exactly():
    # Leaving glass (η = 1.5) at θc = asin(1/1.5): the refracted ray grazes the surface
    # (sin θt = 1) or, within rounding, is totally reflected; either way a unit vector on the
    # right side. One part in 1e9 either side decides clearly.
    eta = 1.5
    n = np.array([[0.0, 1.0, 0.0]])
    for th, expect in ((critical_angle(eta), None), (critical_angle(eta) * (1 + 1e-9), True),
                       (critical_angle(eta) * (1 - 1e-9), False)):
        d = np.array([[math.sin(th), -math.cos(th), 0.0]])
        t, tir = refract(d, n, np.array([eta]))
        assert np.isfinite(t).all() and abs(np.linalg.norm(t) - 1) < 1e-12
        if expect is None:
            assert tir[0] or abs(t[0, 1]) < 1e-4
        else:
            assert bool(tir[0]) is expect
        if not tir[0]:
            assert t[0, 1] <= 0 and abs(eta * math.sin(th) - math.hypot(t[0, 0], t[0, 2])) < 1e-9


@pytest.mark.parametrize("max_depth", [0, 1, 5, 50])
@pytest.mark.filterwarnings("ignore:render.max_depth. 50 with min_weight 0:"
                            "raytrace.errors.RenderWarning")  # the tree's bound: 2^51 rays
def test_camera_inside_a_glass_sphere(max_depth):
    # From the centre every ray meets the sphere at normal incidence: kt leaves undeviated to
    # the background b, kr comes back through the centre to the opposite side, and so on.
    # Reflection j (j = 0, 1, ...) sends kr^j·kt out at depth j + 1 <= max_depth:
    # I = b·kt·Σ_{j=0}^{D−1} kr^j.
    kr, kt, b = 0.5, 0.4, 0.8
    scene = Scene(camera=Camera([0.3, -0.2, 0.1], [0.3, -0.2, -1.0], fov=70),
                  objects=[Sphere([0.3, -0.2, 0.1], 2.0, Material(kd=0, ks=0, kr=kr, kt=kt))],
                  render=RenderSettings(background=b, max_depth=max_depth))
    img, _ = render_checked(scene, width=7, height=5)
    want = b * kt * sum(kr**j for j in range(max_depth))
    np.testing.assert_allclose(img, want, rtol=1e-6, atol=1e-12)


def test_touching_dielectrics():
    # Two glass spheres touching at one point and a glass slab under a third sphere resting
    # on it, looked at along the line through the contact: the centre ray crosses four
    # surfaces, two of them at the same point, so I = kt⁴·b (never kt³, nor a ray bouncing
    # between the two surfaces until max_depth, which was black before the fix).
    kt = 0.9
    g = Material(kd=0.0, ks=0.0, kt=kt, ior=1.5)
    for a, ra, b, rb in ((0.3, 0.3, -1.1, 1.1), (0.1, 0.1, -0.7, 0.7), (1.0, 1.0, -1.0, 1.0)):
        scene = Scene(camera=Camera([0, 0, 5], [0, 0, 0], fov=20),
                      objects=[Sphere([0, 0, a], ra, g), Sphere([0, 0, b], rb, g)],
                      render=RenderSettings(background=1.0, max_depth=10))
        img, _ = render_checked(scene, width=5, height=5)
        assert img[2, 2, 0] == pytest.approx(kt**4, rel=1e-6)
        assert img.min() >= 0 and img.max() <= 1.0
    # The slab is the glass between y0 − 1 and y0 (two planes, outward normals ∓y).
    for y0, r in ((0.0, 1.0), (1e3, 0.01)):
        objs = [Sphere([0, y0 + r, 0], r, g), Plane([0, y0, 0], [0, 1, 0], g),
                Plane([0, y0 - 1, 0], [0, -1, 0], g)]
        scene = Scene(camera=Camera([0, y0 + r + 3, 0], [0, y0, 0], [0, 0, -1], fov=60),
                      objects=objs, render=RenderSettings(background=1.0, max_depth=10))
        img, _ = render_checked(scene, width=5, height=5)
        assert img[2, 2, 0] == pytest.approx(kt**4, rel=1e-6)   # sphere 2 + slab 2
        assert img[0, 0, 0] == pytest.approx(kt**2, rel=1e-6)   # slab only


# -- meshes: coincident, degenerate, needle, winding, back-facing normals -------------------
def overhead_view(objects, light=(0.5, 4.0, 0.3), w=40, h=30, ambient=0.1):
    cam, look = [0.3, 2.2, 1.0], [0.0, 0.0, 0.0]
    scene = Scene(camera=Camera(cam, look, fov=50), objects=objects,
                  lights=[PointLight(list(light), 2.0)], ambient=ambient,
                  render=RenderSettings(background=0.0))
    img, stats = render_checked(scene, width=w, height=h)
    pts, hit = plane_hits(cam, pinhole(cam, look, [0, 1, 0], 50, w, h))
    return img, stats, pts, hit


def test_coincident_triangles_no_acne():
    # Two copies of the same quad (the second wound the other way) with different kd: every
    # pixel shows one of them fully lit, I = ka·Ia + kd_i·N·L·I_l; a copy shadowing the other
    # would leave ka·Ia.
    v, f = quad(1.0)
    a = Mesh(vertices=v, faces=f, material=Material(kd=0.3, ka=0.3))
    b = Mesh(vertices=v, faces=[face[::-1] for face in f], material=Material(kd=0.7, ka=0.3))
    img, _, pts, hit = overhead_view([a, b])
    inside = hit & (np.abs(pts[..., [0, 2]]).max(-1) < 0.97)
    light = [0.5, 4.0, 0.3]
    ok = np.zeros(inside.shape, bool)
    for kd in (0.3, 0.7):
        want = lit_plane_value(pts, 1.0, light, 0.1 * 0.3, kd, 2.0)
        ok |= (rel_err(img, want[..., None]) < 1e-5).all(-1)
    assert inside.sum() > 200
    assert ok[inside].all()


def test_degenerate_triangles_are_dropped_and_counted():
    # A quad plus three zero-area faces (a repeated index, three collinear points, three
    # identical points): the stats count 3, the quad renders to its closed form.
    v, f = quad(1.0)
    v = [*v, [0.0, 0.0, 0.0], [0.5, 0.0, 0.0], [1.0, 0.0, 0.0], [0.2, 0.0, 0.2], [0.2, 0.0, 0.2]]
    f = [*f, [0, 0, 1], [4, 5, 6], [7, 8, 8]]
    mesh = Mesh(vertices=v, faces=f, material=Material(kd=0.6, ka=0.6))
    assert mesh.degenerate == 3
    img, stats, pts, hit = overhead_view([mesh])
    assert stats["degenerate_triangles"] == 3 and stats["triangles"] == 2
    inside = hit & (np.abs(pts[..., [0, 2]]).max(-1) < 0.97)
    want = lit_plane_value(pts, 1.0, [0.5, 4.0, 0.3], 0.1 * 0.6, 0.6, 2.0)
    assert rel_err(img[inside], want[inside, None]).max() < 1e-5


def test_needle_triangles_leave_no_cracks():
    # A fan of 20 000 needles (base 1e-4, height 2: aspect 2e4) from an apex to the far edge
    # covers a triangle; every pixel inside shows the lit floor (no background through a
    # crack, no stray normal), flat and smooth alike.
    k = 20000
    xs = np.linspace(-1.0, 1.0, k + 1)
    v = np.vstack([[[0.0, 0.0, 1.0]], np.column_stack([xs, np.zeros(k + 1), -np.ones(k + 1)])])
    f = np.column_stack([np.zeros(k, int), np.arange(2, k + 2), np.arange(1, k + 1)])
    for shading in ("flat", "smooth"):
        mesh = Mesh(vertices=v, faces=f, shading=shading, material=Material(kd=0.6, ka=0.6))
        img, stats, pts, hit = overhead_view([mesh])
        assert stats["degenerate_triangles"] == 0
        # Inside the fan's outline |x| < (1 − z)/2 for −1 < z < 1, 2 % in from its edges.
        x, z = pts[..., 0], pts[..., 2]
        inside = hit & (np.abs(x) < 0.98 * (1 - z) / 2 - 0.02) & (z > -0.98) & (z < 0.98)
        want = lit_plane_value(pts, 1.0, [0.5, 4.0, 0.3], 0.1 * 0.6, 0.6, 2.0)
        assert inside.sum() > 100
        assert rel_err(img[inside], want[inside, None]).max() < 1e-5


def test_inconsistent_winding_shades_as_two_sided():
    # One triangle of the quad wound clockwise: its face normal points down. The vertex
    # normals (sums of face normals) cancel at the two shared vertices, whose corners then
    # take their face's normal. Surfaces are two-sided, so under a directional light
    # (N·L = L_y/|L| everywhere, so Gouraud's interpolation is exact too) every pixel is
    # ka·Ia + kd·N·L·I_l; before the fix Gouraud went dark towards the shared edge.
    v, f = quad(1.0, flip_second=True)
    light = np.array([-0.3, -1.0, -0.2])
    want = 0.1 * 0.6 + 0.6 * 2.0 * (-light[1] / np.linalg.norm(light))
    cam, look = [0.3, 2.2, 1.0], [0.0, 0.0, 0.0]
    pts, hit = plane_hits(cam, pinhole(cam, look, [0, 1, 0], 50, 40, 30))
    inside = hit & (np.abs(pts[..., [0, 2]]).max(-1) < 0.97)
    assert inside.sum() > 200
    for shading in ("flat", "smooth", "gouraud"):
        mesh = Mesh(vertices=v, faces=f, shading=shading, material=Material(kd=0.6, ka=0.6))
        scene = Scene(camera=Camera(cam, look, fov=50), objects=[mesh],
                      lights=[DirectionalLight(light, 2.0)], ambient=0.1)
        img, _ = render_checked(scene, width=40, height=30)
        err = rel_err(img[inside], want).max()
        assert err < 1e-6, shading


def test_shading_normals_never_send_rays_into_the_surface(monkeypatch):
    # A coarse smooth mirror-and-glass icosphere: near the silhouette the interpolated normal
    # faces away from the viewer and reflect(d, N_s) points into the surface. Every reflected
    # ray must leave on the viewer's side of the geometric normal, every refracted ray (not
    # TIR) on the other side.
    ico = trimesh.creation.icosphere(subdivisions=0, radius=1.0)
    mat = Material(kd=0.0, ks=0.0, kr=0.5, kt=0.5, ior=1.5)
    scene = Scene(camera=Camera([0, 0, 4], [0, 0, 0], fov=35),
                  objects=[Mesh(mesh=ico, shading="smooth", material=mat)],
                  render=RenderSettings(background=1.0, max_depth=1))
    seen = []

    class Spy(SpawnObserver):
        def spawned(self, children, parent):
            parents, surf = self.batch
            if parents.depth == 0:  # children of camera rays
                for kind in (REFLECTION, REFRACTION):
                    mine = children.kind == kind
                    m = parent[mine]
                    seen.append((kind, parents.direction[m].copy(), surf.geometric[m].copy(),
                                 surf.shading[m].copy(), children.direction[mine].copy()))

    monkeypatch.setattr(WhittedIntegrator, "observer", Spy())
    render_checked(scene, width=64, height=64, threads=1)
    refl = [s for s in seen if s[0] == REFLECTION]
    refr = [s for s in seen if s[0] == REFRACTION]
    d, ng, ns, r = (np.concatenate([s[i] for s in refl]) for i in range(1, 5))
    side = np.sign(-(d * ng).sum(1))[:, None]  # turns N_g (and N_s) towards the viewer
    naive = reflect(d, ns * side)
    assert ((naive * ng * side).sum(1) <= 0).sum() > 0, "the case occurs"
    assert ((r * ng * side).sum(1) > 0).all()
    # Camera rays enter from outside (η = 1/1.5 < 1: no TIR): all refracted rays go inside.
    d, ng, ns, t = (np.concatenate([s[i] for s in refr]) for i in range(1, 5))
    side = np.sign(-(d * ng).sum(1))[:, None]
    assert len(t) == len(d) > 1000
    assert ((t * ng * side).sum(1) < 0).all()


# -- recursion limits --------------------------------------------------------------------------
@pytest.mark.parametrize("kr,max_depth", [(0.5, 0), (0.5, 50), (1.0, 50)])
def test_facing_mirrors_geometric_series(kr, max_depth):
    # Parallel mirrors z = ±1 facing each other, the camera between them: every ray bounces
    # forever. Each hit adds ka·Ia·(kr)^depth for depth 0..D:
    # I = ka·Ia·Σ_{k=0}^{D} kr^k = ka·Ia·(1 − kr^{D+1})/(1 − kr), or ka·Ia·(D + 1) at kr = 1.
    mat = Material(kd=0.0, ka=0.2, kr=kr)
    scene = Scene(camera=Camera([0, 0, 0], [0, 0, -1], fov=60),
                  objects=[Plane([0, 0, -1], [0, 0, 1], mat), Plane([0, 0, 1], [0, 0, -1], mat)],
                  ambient=1.0, render=RenderSettings(max_depth=max_depth))
    w, h = 8, 6
    img, stats = render_checked(scene, width=w, height=h)
    series = 0.2 * sum(kr**k for k in range(max_depth + 1))
    np.testing.assert_allclose(img, series, rtol=1e-6)
    assert stats["rays"]["reflection"] == max_depth * w * h
    bound = 0.2 * (max_depth + 1 if kr == 1 else 1 / (1 - kr))
    assert img.max() <= bound * (1 + 1e-6)


# -- HDR ----------------------------------------------------------------------------------------
def test_hdr_light_keeps_its_value_in_exr_and_png_stays_in_range(tmp_path):
    # A 1e6 light straight above a floor seen from above: I = kd·N·L·1e6 ≈ 5e5 per pixel,
    # kept as a float in the EXR; the PNG preview saturates to 255 (never wraps around), the
    # background (0.5 → sRGB 188) is unchanged.
    cam, look, up, fov, w, h = [0, 2, 0], [0, 0, 0], [0, 0, -1], 40, 12, 10
    scene = Scene(camera=Camera(cam, look, up, fov),
                  objects=[Mesh(vertices=quad(0.5)[0], faces=quad(0.5)[1],
                                material=Material(kd=0.5, ka=0.0))],
                  lights=[DirectionalLight([0, -1, 0], 1e6)],
                  render=RenderSettings(background=0.5))
    image = raytrace.render(scene, width=w, height=h)
    assert image.stats["nonfinite_pixels"] == 0
    exr, png = tmp_path / "hdr.exr", tmp_path / "hdr.png"
    image.save(exr)
    image.save(png)
    rgb, _ = raytrace.read_exr(exr)
    np.testing.assert_array_equal(rgb, image.rgb)
    pts, _ = plane_hits(cam, pinhole(cam, look, up, fov, w, h))
    on = np.abs(pts[..., [0, 2]]).max(-1) < 0.48
    off = np.abs(pts[..., [0, 2]]).max(-1) > 0.52
    assert on.sum() > 10 and off.sum() > 10
    np.testing.assert_allclose(rgb[on], 0.5e6, rtol=1e-6)
    pixels = decode_png(png.read_bytes())
    assert pixels.dtype == np.uint8 and pixels.shape == (h, w, 3)
    assert (pixels[on] == 255).all()
    assert (pixels[off] == 188).all()  # sRGB(0.5) = 1.055·0.5^(1/2.4) − 0.055 = 0.7354


def decode_png(data: bytes) -> np.ndarray:
    """Pixels (H, W, 3) of an 8-bit RGB PNG with filter type 0 (what film.write_png makes)."""
    import struct
    import zlib

    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    pos, idat, size = 8, b"", None
    while pos < len(data):
        (length,) = struct.unpack(">I", data[pos:pos + 4])
        kind, body = data[pos + 4:pos + 8], data[pos + 8:pos + 8 + length]
        if kind == b"IHDR":
            size = struct.unpack(">II", body[:8])
            assert body[8:10] == b"\x08\x02"
        elif kind == b"IDAT":
            idat += body
        pos += 12 + length
    w, h = size
    raw = np.frombuffer(zlib.decompress(idat), np.uint8).reshape(h, 1 + 3 * w)
    assert (raw[:, 0] == 0).all()
    return raw[:, 1:].reshape(h, w, 3)


def test_overflowing_pixels_are_counted_and_zeroed():
    # A 1e39 light (finite in float64, beyond float32's 3.4e38) straight above a floor with
    # kd = 1: every floor pixel is 1e39 and cannot be stored; the stats count exactly those
    # pixels and the image holds 0 there, never inf. The background stays 0.25.
    cam, look, up, fov, w, h = [0, 1, 3], [0, 0, 0], [0, 1, 0], 60, 16, 12
    scene = Scene(camera=Camera(cam, look, up, fov),
                  objects=[Plane([0, 0, 0], [0, 1, 0], Material(kd=1.0, ka=0.0))],
                  lights=[DirectionalLight([0, -1, 0], 1e39)],
                  render=RenderSettings(background=0.25))
    with pytest.warns(raytrace.errors.RenderWarning, match="overflowed to inf or NaN"):
        image = raytrace.render(scene, width=w, height=h)
    _, hit = plane_hits(cam, pinhole(cam, look, up, fov, w, h))
    assert 0 < hit.sum() < w * h
    assert image.stats["nonfinite_pixels"] == hit.sum()
    assert np.isfinite(image.rgb).all()
    assert (image.rgb[hit] == 0).all() and (image.rgb[~hit] == np.float32(0.25)).all()


# -- tiny and odd image sizes -------------------------------------------------------------------
def test_one_pixel_image_sees_along_the_forward_direction():
    # 1×1: the only ray is the camera's forward direction. A sphere of radius 1e-3 on it, 6.5
    # away (1.5e-4 rad), lit along the same direction: the ray meets its nearest point, where
    # N·L = 1: I = ka·Ia + kd·I_l.
    pos, look = np.array([1.0, 2.0, 3.0]), np.array([-4.0, 0.5, 7.0])
    fwd = (look - pos) / np.linalg.norm(look - pos)
    scene = Scene(camera=Camera(pos, look, fov=30),
                  objects=[Sphere(look, 1e-3, Material(kd=0.6, ka=0.5))],
                  lights=[DirectionalLight(fwd, 1.0)], ambient=0.2,
                  render=RenderSettings(background=0.0))
    img, _ = render_checked(scene, width=1, height=1)
    assert img.shape == (1, 1, 3)
    assert img[0, 0, 0] == pytest.approx(0.2 * 0.5 + 0.6, rel=1e-6)


@pytest.mark.parametrize("w,h,fov", [(1, 1000, 35), (1000, 1, 0.1), (7, 3, 35), (3, 7, 35)])
def test_sphere_footprint_matches_the_analytic_projection(w, h, fov):
    # A pixel shows the sphere iff its centre ray passes within r of the sphere's centre
    # (distance from c to the ray = |(c − o) − ((c − o)·d)d| < r). Unlit, ka·Ia = 0.5 on the
    # sphere, background 0; pixels whose ray passes within 1e-9·r of the rim are not judged.
    pos, look = [0.0, 0.0, 6.0], [0.0, 0.0, 0.0]
    center, r = np.array([0.25, 0.4, 0.0]), 0.9
    scene = Scene(camera=Camera(pos, look, fov=fov),
                  objects=[Sphere(center, r, Material(kd=0.5, ka=0.5))], ambient=1.0)
    img, _ = render_checked(scene, width=w, height=h)
    dirs = pinhole(pos, look, [0, 1, 0], fov, w, h)
    oc = center - np.array(pos)
    along = dirs @ oc
    dist = np.linalg.norm(oc - along[..., None] * dirs, axis=-1)
    clear = np.abs(dist - r) > 1e-9 * r
    inside = dist < r
    assert inside.any() and (~inside).any()
    np.testing.assert_array_equal((img[..., 0] > 0)[clear], inside[clear])
    assert np.all(img[inside & clear] == np.float32(0.5))


# -- every shipped scene ------------------------------------------------------------------------
@pytest.mark.parametrize("path", sorted((ROOT / "scenes").glob("*.toml"))
                         + sorted((ROOT / "scenes").glob("*.json")), ids=lambda p: p.name)
def test_shipped_scene_renders_without_nonfinite_pixels(path):
    img, stats = render_checked(raytrace.load_scene(path), width=32, height=24, spp=1)
    assert stats["nonfinite_pixels"] == 0
    assert img.min() >= 0


# -- smooth-mesh refraction and spawned directions (issue 19) --------------------------------
class SpawnObserver:
    """An integrator observer (``WhittedIntegrator.observer``, the hook ``raytrace explain``
    uses) that keeps the batch being shaded and ignores everything else; subclasses look at
    the children in :meth:`spawned`. One thread only: render with ``threads=1``."""

    batch = None

    def traced(self, rays, found, missed, background):
        pass

    def hits(self, rays, hits, surf):
        self.batch = (rays, surf)

    def light(self, emitter, term, rows):
        pass

    def shadow(self, factor):
        pass

    def shaded(self, terms, status, weights, tir, last):
        pass

    def spawned(self, children, parent):
        pass


def spawned_directions(monkeypatch, scene: Scene, **kw) -> list[np.ndarray]:
    """Render ``scene`` and return the directions of every batch of spawned children."""
    seen = []

    class Spy(SpawnObserver):
        def spawned(self, children, parent):
            seen.append(children.direction.copy())

    monkeypatch.setattr(WhittedIntegrator, "observer", Spy())
    render_checked(scene, threads=1, **kw)
    return seen


def test_refraction_at_smooth_silhouettes_is_a_unit_vector(monkeypatch):
    # A 20-face smooth glass icosahedron over a checker plane: near its silhouettes the
    # interpolated normal faces away from the ray while the face faces it. Snell's formula
    # with the cosine clamped to 0 returned η·d − √(1 − η²)·N there, of length 0.87–0.91.
    ico = trimesh.creation.icosphere(subdivisions=0, radius=1.0)
    glass = Material(kd=0.0, ks=0.0, kr=0.1, kt=0.9, ior=1.5)
    floor = Material(kd=Checker([[0.9, 0.9, 0.9], [0.1, 0.1, 0.1]], 0.5))
    scene = Scene(camera=Camera([0, 0.6, 4], [0, 0, 0], fov=40),
                  objects=[Mesh(mesh=ico, shading="smooth", material=glass),
                           Plane([0, -1, 0], [0, 1, 0], material=floor)],
                  lights=[PointLight([3, 4, 5])], ambient=0.1,
                  render=RenderSettings(max_depth=6))
    batches = spawned_directions(monkeypatch, scene, width=96, height=72)
    lengths = np.concatenate([np.linalg.norm(b, axis=1) for b in batches])
    assert len(lengths) > 5000
    np.testing.assert_allclose(lengths, 1.0, rtol=0, atol=1e-12)


def test_refract_is_unit_where_the_normal_faces_away():
    # refract(d, N, η) with d·N > 0 (the shading normal turned away from the ray): Snell's
    # formula with the signed cosine, a unit vector for every such direction and η.
    rng = np.random.default_rng(19)
    d = rng.normal(size=(2000, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    n = np.array([[0.0, 1.0, 0.0]])
    d[:, 1] = np.abs(d[:, 1])  # d·N >= 0
    for eta in (1 / 1.5, 1.0, 1.5):
        t, tir = refract(d, n, np.full(len(d), eta))
        np.testing.assert_allclose(np.linalg.norm(t, axis=1), 1.0, rtol=0, atol=1e-12)


# -- spawn offsets on large triangles (issue 19) ---------------------------------------------
def _floor_scene(floor, sphere: str) -> Scene:
    """A radius-0.5 sphere resting on a reflective floor (``floor``: a Plane or a Mesh), lit
    by a point light, the camera 2.5 units away looking down at the contact point."""
    ball = Material(kd=[0.8, 0.2, 0.2], ks=0.5, shininess=50)
    if sphere == "analytic":
        obj = Sphere([0.3, 0.5, 0.1], 0.5, material=ball)
    else:
        obj = Mesh(mesh=trimesh.creation.icosphere(4, 0.5), shading="smooth",
                   translate=[0.3, 0.5, 0.1], material=ball)
    return Scene(camera=Camera([0.1, 2.5, 2.0], [0.3, 0.2, 0.1], fov=40),
                 objects=[floor, obj], lights=[PointLight([2.3, 5.1, 3.7])], ambient=0.1)


@pytest.mark.parametrize("sphere", ["analytic", "mesh"])
@pytest.mark.parametrize("half", [1e5, 1e7])
@pytest.mark.parametrize("rotate", [0.0, 33.3])
def test_huge_two_triangle_floor_equals_the_analytic_plane(half, rotate, sphere):
    # A floor of two triangles ±half wide renders as the infinite analytic plane (float64,
    # no offset) does: no false shadow around the sphere, no shifted reflection. The spawn
    # offset used to be 3 ulps of the triangle's largest coordinate, 0.036 at ±1e5, and the
    # clamp of the re-solved hit onto Embree's triangle moved points across the float32
    # diagonal by up to 0.1 at ±1e7: 684 and 7460 pixels of this frame were wrong.
    mat = Material(kd=0.7, ka=0.7, kr=0.2)
    v = np.array([[-half, 0, -half], [half, 0, -half], [half, 0, half], [-half, 0, half]])
    mesh = Mesh(vertices=v, faces=[[0, 2, 1], [0, 3, 2]], material=mat, rotate=[0, rotate, 0])
    want, _ = render_checked(_floor_scene(Plane([0, 0, 0], [0, 1, 0], material=mat), sphere),
                             width=160, height=120)
    got, _ = render_checked(_floor_scene(mesh, sphere), width=160, height=120)
    err = np.abs(got - want).max(axis=2) / np.maximum(want.max(axis=2), 1e-3)
    print(f"measured: floor ±{half:g} rotated {rotate}°, {sphere} sphere: max rel. error "
          f"{err.max():.2g} against the analytic plane")
    assert int((err > 1e-5).sum()) == 0


def test_concave_edges_are_not_shadowed_by_their_neighbour():
    # A wall (x = −1) meeting a floor (y = 0), each two triangles, lit by a directional light
    # travelling towards −x and slightly down: nothing shadows anything. The camera sits on
    # the corner's plane of symmetry, so the middle column of rays meets the corner line
    # within float64 rounding. A shadow ray from the wall there starts within float32
    # rounding of the floor's plane and leaves it behind; Embree still reported the floor
    # as a blocker (a float32 artefact), which left a dark line along the corner (also 28
    # pixels of scenes/cornell_box.toml at 48×48).
    white = Material(kd=0.6, ka=0.6)
    floor = Mesh(vertices=[[-1, 0, -3], [1, 0, -3], [1, 0, 3], [-1, 0, 3]],
                 faces=[[0, 2, 1], [0, 3, 2]], material=white)
    wall = Mesh(vertices=[[-1, 0, -3], [-1, 0, 3], [-1, 2, 3], [-1, 2, -3]],
                faces=[[0, 2, 1], [0, 3, 2]], material=white)
    light = np.array([-1.0, -0.2, 0.0])
    scene = Scene(camera=Camera([0.0, 1.0, 3.0], [-1.0, 0.0, -1.0], up=[1, 1, 0], fov=50),
                  objects=[floor, wall], lights=[DirectionalLight(light, 1.0)], ambient=0.1)
    img, _ = render_checked(scene, width=101, height=75)
    to_light = -light / np.linalg.norm(light)
    lit = {"wall": 0.06 + 0.6 * to_light[0], "floor": 0.06 + 0.6 * to_light[1], "none": 0.0}
    err = np.min([np.abs(img - v).max(axis=2) for v in lit.values()], axis=0)
    dark = np.abs(img - 0.06).max(axis=2) < 1e-6
    assert (img[:, 50].max(axis=1) > 0).sum() > 40             # the corner column is seen
    assert int(dark.sum()) == 0, f"{int(dark.sum())} pixels falsely shadowed"
    assert err.max() < 1e-6


def test_debug_checks_pass_on_smooth_glass_and_catch_a_bad_direction(monkeypatch):
    # RAYTRACE_DEBUG=1 checks every spawned batch: unit directions and finite origins.
    from raytrace import integrator
    from raytrace.rays import RayBatch

    monkeypatch.setattr(integrator, "DEBUG", True)
    checked, check = [], integrator.check_spawned
    monkeypatch.setattr(integrator, "check_spawned", lambda rays: (checked.append(len(rays)),
                                                                   check(rays)))
    ico = trimesh.creation.icosphere(subdivisions=0, radius=1.0)
    scene = Scene(camera=Camera([0, 0.6, 4], [0, 0, 0], fov=40),
                  objects=[Mesh(mesh=ico, shading="smooth",
                                material=Material(kd=0.0, kr=0.1, kt=0.9, ior=1.5))],
                  render=RenderSettings(max_depth=4))
    render_checked(scene, width=48, height=36)
    assert sum(checked) > 1000  # the render ran the debug check on its spawned batches
    bad = RayBatch(np.zeros((2, 3)), np.array([[0.0, 0.0, 1.0], [0.0, 0.6, 0.6]]),
                   np.zeros(2, np.int64), np.ones((2, 3)), 1, np.full(2, -1), np.zeros(2, np.int8))
    with pytest.raises(AssertionError, match="not a unit vector"):
        integrator.check_spawned(bad)
