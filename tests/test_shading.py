"""Local shading against values worked out by hand (seed 000/001; SCENE_FORMAT.md):

    I = ka·Ia + Σ_l S_l · f_radial · f_angular · I_l · [ kd·max(N·L, 0) + ks·spec ]

Each test renders one pixel (1×1, spp = 1: the ray is the camera's forward direction, so it
hits exactly the aimed-at point) and compares it with the formula evaluated here in float64.
"""

from __future__ import annotations

import math
from decimal import Decimal, localcontext

import numpy as np
import pytest
from helpers import RTOL, aimed_camera, make_scene, pixel, unit

import raytrace
from raytrace.kernels.core import whole_power1
from raytrace.shading import blinn, cosine_power, direct, phong

FLOOR = dict(point=[0.0, 0.0, 0.0], normal=[0.0, 1.0, 0.0])


def test_diffuse_plane_under_attenuated_point_light():
    # Plane y = 0, N = (0, 1, 0); the pixel sees P = (0.3, 0, -0.2).
    # Light at (1.3, 3, 0.8): P→light = (1, 3, 1), d = √11, N·L = 3/√11.
    # f = 1/(a0 + a1·d + a2·d²) = 1/(0.5 + 0.25·√11 + 0.1·11).
    # I = ka·Ia + f·Il·kd·N·L, per channel.
    ka, kd = np.array([0.3, 0.2, 0.1]), np.array([0.6, 0.4, 0.2])
    ia, il = np.array([0.2, 0.25, 0.5]), np.array([1.0, 2.0, 0.5])
    p = np.array([0.3, 0.0, -0.2])
    d = math.sqrt(11.0)
    f = 1.0 / (0.5 + 0.25 * d + 0.1 * d * d)
    expected = ka * ia + f * il * kd * (3.0 / d)
    scene = make_scene(
        [raytrace.Plane(**FLOOR, material=raytrace.Material(kd=kd, ka=ka))],
        [raytrace.PointLight([1.3, 3.0, 0.8], color=il, attenuation=[0.5, 0.25, 0.1])],
        camera=aimed_camera([-1.0, 2.5, 3.0], p), ambient=ia)
    np.testing.assert_allclose(pixel(scene), expected, rtol=RTOL)


def test_omitted_ka_follows_kd():
    # No light: I = ka·Ia with ka = kd when ka is omitted.
    kd, ia = np.array([0.7, 0.5, 0.25]), 0.4
    scene = make_scene([raytrace.Plane(**FLOOR, material=raytrace.Material(kd=kd))],
                       camera=aimed_camera([0.0, 1.0, 2.0], [0.0, 0.0, 0.0]), ambient=ia)
    np.testing.assert_allclose(pixel(scene), kd * ia, rtol=RTOL)


def _highlight_scene(model: str, theta_l: float, theta_v: float, n: float):
    """Plane y = 0 at P = 0; light at angle θ_L from N towards +x, eye at θ_V towards −x,
    both in the xy plane, so R (the mirror of L) lies at θ_L on the eye's side."""
    tl, tv = math.radians(theta_l), math.radians(theta_v)
    light = 3.0 * np.array([math.sin(tl), math.cos(tl), 0.0])
    eye = 4.0 * np.array([-math.sin(tv), math.cos(tv), 0.0])
    mat = raytrace.Material(kd=[0.2, 0.3, 0.4], ka=0.1, ks=[0.5, 0.6, 0.7], shininess=n,
                            highlight=model)
    return make_scene([raytrace.Plane(**FLOOR, material=mat)],
                      [raytrace.PointLight(light, color=[1.0, 0.9, 0.8])],
                      camera=aimed_camera(eye, [0.0, 0.0, 0.0]), ambient=0.3), mat


@pytest.mark.parametrize("model", ["phong", "blinn", "blinn_cosine"])
def test_highlight_peak_at_mirror_direction(model):
    # Light and eye symmetric about N at 45°: V = R (so V·R = 1) and H = N (N·H = 1).
    # I = ka·Ia + Il·(kd·cos 45° + ks·1); blinn_cosine's highlight is times N·L = cos 45°.
    scene, m = _highlight_scene(model, 45.0, 45.0, 50.0)
    il = np.array([1.0, 0.9, 0.8])
    cos_l = math.cos(math.radians(45)) if model == "blinn_cosine" else 1.0
    expected = m.ka * 0.3 + il * (m.kd * math.cos(math.radians(45)) + m.ks * cos_l)
    np.testing.assert_allclose(pixel(scene), expected, rtol=RTOL)


@pytest.mark.parametrize("model", ["phong", "blinn", "blinn_cosine"])
def test_highlight_off_peak(model):
    # θ_L = 30°, θ_V = 55°: R is 25° away from V, so V·R = cos 25° (Phong), and H bisects L, V
    # at (55° − 30°)/2 = 12.5° from N, so N·H = cos 12.5° (Blinn; seed 001: α = φ/2);
    # blinn_cosine: (N·H)ⁿ·N·L = cos¹⁰ 12.5°·cos 30°.
    theta_l, theta_v, n = 30.0, 55.0, 10.0
    scene, m = _highlight_scene(model, theta_l, theta_v, n)
    phi = math.radians(theta_v - theta_l)
    spec = math.cos(phi) ** n if model == "phong" else math.cos(phi / 2) ** n
    if model == "blinn_cosine":
        spec *= math.cos(math.radians(theta_l))
    il = np.array([1.0, 0.9, 0.8])
    expected = m.ka * 0.3 + il * (m.kd * math.cos(math.radians(theta_l)) + m.ks * spec)
    np.testing.assert_allclose(pixel(scene), expected, rtol=RTOL)
    # The highlight really is there: it is more than 5 % of the pixel.
    assert np.all(il * m.ks * spec > 0.05 * expected)


def test_light_behind_the_surface_gives_ambient_only():
    # L below the plane, eye above: N (turned to the eye) · L < 0: no diffuse, no highlight.
    mat = raytrace.Material(kd=0.8, ka=0.5, ks=1.0, shininess=1)
    scene = make_scene([raytrace.Plane(**FLOOR, material=mat)],
                       [raytrace.PointLight([0.5, -2.0, 0.0], color=5.0)],
                       camera=aimed_camera([0.0, 2.0, 2.0], [0.0, 0.0, 0.0]), ambient=0.2)
    np.testing.assert_allclose(pixel(scene), np.full(3, 0.5 * 0.2), rtol=RTOL)


def test_two_sided_plane_seen_from_below():
    # The eye is below the plane whose normal points up: N turns to the viewer, (0, −1, 0);
    # a light below at P + (0, −2, 0) gives N·L = 1, d = 2, f = 1/(1 + d) = 1/3.
    mat = raytrace.Material(kd=0.6, ka=0.0)
    scene = make_scene([raytrace.Plane(**FLOOR, material=mat)],
                       [raytrace.PointLight([0.0, -2.0, 0.0], attenuation=[1.0, 1.0, 0.0])],
                       camera=aimed_camera([1.0, -1.0, 1.0], [0.0, 0.0, 0.0]))
    np.testing.assert_allclose(pixel(scene), np.full(3, 0.6 / 3.0), rtol=RTOL)


def _shadow_scene(with_blocker: bool):
    # Plane y = 0, light straight above P = 0 at (0, 4, 0); an opaque sphere of radius 0.5
    # at (0, 2, 0) sits on the segment P→light. The eye at (3, 1, 3) sees P: its ray passes
    # the sphere's centre at distance √(4 − 4/19) ≈ 1.95 > 0.5.
    objects = [raytrace.Plane(**FLOOR, material=raytrace.Material(kd=[0.8, 0.6, 0.4],
                                                                  ka=[0.5, 0.5, 0.25]))]
    if with_blocker:
        objects.append(raytrace.Sphere([0.0, 2.0, 0.0], 0.5, material="brass"))
    return make_scene(objects, [raytrace.PointLight([0.0, 4.0, 0.0], color=2.0)],
                      camera=aimed_camera([3.0, 1.0, 3.0], [0.0, 0.0, 0.0]), ambient=0.2)


def test_shadowed_point_gets_exactly_the_ambient_term():
    ambient = np.array([0.5, 0.5, 0.25]) * 0.2            # ka·Ia
    np.testing.assert_allclose(pixel(_shadow_scene(True)), ambient, rtol=RTOL)
    # Without the blocker the same point is lit: + Il·kd·N·L with N·L = 1 (f = 1).
    lit = ambient + 2.0 * np.array([0.8, 0.6, 0.4])
    np.testing.assert_allclose(pixel(_shadow_scene(False)), lit, rtol=RTOL)


def test_shadow_behind_a_mesh_occluder():
    # The same blocker as a 2-triangle square (Embree) at y = 2 across the light's path.
    square = raytrace.Mesh(vertices=[[-0.5, 2, -0.5], [0.5, 2, -0.5], [0.5, 2, 0.5],
                                     [-0.5, 2, 0.5]], faces=[[0, 1, 2], [0, 2, 3]],
                           material="black_plastic")
    scene = _shadow_scene(False)
    scene = make_scene([*scene.objects, square], scene.lights, camera=scene.camera,
                       ambient=0.2)
    np.testing.assert_allclose(pixel(scene), np.array([0.5, 0.5, 0.25]) * 0.2, rtol=RTOL)


def test_transparent_shadow_factor_is_kt_squared():
    # A glass sphere (kt = 0.6, opacity 1) in the light's path: the shadow ray crosses it
    # twice, S = kt² = 0.36 (SCENE_FORMAT.md: the product of t·kt + (1 − t) per crossing).
    glass = raytrace.Material(kd=0.0, ka=0.0, kt=0.6, ior=1.5)
    scene = _shadow_scene(False)
    scene = make_scene([scene.objects[0], raytrace.Sphere([0.0, 2.0, 0.0], 0.5, material=glass)],
                       scene.lights, camera=scene.camera, ambient=0.2)
    expected = np.array([0.5, 0.5, 0.25]) * 0.2 + 0.36 * 2.0 * np.array([0.8, 0.6, 0.4])
    np.testing.assert_allclose(pixel(scene), expected, rtol=RTOL)


def test_mirror_reflection_and_opacity_blend():
    # The eye looks straight down (0, −1, 0) at a mirror floor (kr = 0.5, kd = ks = ka = 0)
    # from (0, 1, 0); the reflected ray goes straight up and misses: it adds kr·background.
    # With opacity t = 0.75 the see-through ray continues down and misses too:
    # I = t·(kr·B) + (1 − t)·B.
    bg = np.array([0.2, 0.4, 0.8])
    mat = raytrace.Material(kd=0.0, ka=0.0, kr=0.5, opacity=0.75)
    scene = make_scene([raytrace.Plane(**FLOOR, material=mat)],
                       camera=aimed_camera([0.0, 1.0, 0.0], [0.0, 0.0, 0.0], up=[0, 0, -1]),
                       background=bg)
    np.testing.assert_allclose(pixel(scene), 0.75 * 0.5 * bg + 0.25 * bg, rtol=RTOL)
    # max_depth = 0: only local shading (zero here), no child rays.
    np.testing.assert_allclose(pixel(scene, max_depth=0), 0.0, atol=0)


# -- the shading functions on their own --------------------------------------------------------

def test_cosine_power_matches_the_plain_formula_and_is_stable():
    rng = np.random.default_rng(1)
    a = rng.normal(size=(500, 3))
    b = rng.normal(size=(500, 3))
    a /= np.linalg.norm(a, axis=1, keepdims=True)
    b /= np.linalg.norm(b, axis=1, keepdims=True)
    n = rng.uniform(0.5, 200, 500)
    plain = np.maximum(np.einsum("ij,ij->i", a, b), 0.0) ** n
    np.testing.assert_allclose(cosine_power(a, b, n), plain, rtol=1e-9, atol=1e-300)
    # A huge exponent: cos(1e-4)^1e8 = exp(1e8·ln cos 1e-4) ≈ exp(−0.5).
    x = np.array([[1.0, 0.0, 0.0]])
    y = np.array([[math.cos(1e-4), math.sin(1e-4), 0.0]])
    expected = math.exp(1e8 * math.log(math.cos(1e-4)))
    assert cosine_power(x, y, np.array([1e8]))[0] == pytest.approx(expected, rel=1e-6)



# -- the precision budget: whole highlight exponents by squaring (docs/robustness.md) -----------
U = 2.0**-53  # float64's unit roundoff
WHOLE_N = [1, 2, 3, 7, 20, 80, 200, 1000, 4097, 65536]


def _exact_power(c: float, n: int) -> float:
    with localcontext() as ctx:
        ctx.prec = 60
        return float(Decimal(c) ** n)


def test_whole_power_is_within_its_bound():
    # whole_power1 squares and multiplies: c^(2^j) after j squarings carries at most
    # (2^j − 1)·u, each bit's factor one more rounding, so cⁿ is within (n − 1)·u of the exact
    # power of the float64 c (first order; the slack below covers the second). Checked against
    # 60-digit Decimal over bases spread over (0, 1], the highlight's range.
    rng = np.random.default_rng(7)
    bases = np.concatenate([1.0 - rng.uniform(0, 1e-3, 40), rng.uniform(0.0, 1.0, 40),
                            [1.0, 0.5, 1.0 - 2.0**-40]])
    for n in WHOLE_N:
        for c in bases:
            want = _exact_power(float(c), n)
            if want < 1e-290:  # underflowing powers: no relative precision to check
                continue
            got = whole_power1(float(c), float(n))
            err = abs(got - want) / want
            assert err <= (n - 1) * U * 1.001 + 1e-300, (c, n, err)
    assert whole_power1(0.5, 10.0) == 2.0**-10  # exact where every product is


def test_whole_exponent_highlight_stays_within_the_budget():
    # cosine_power at whole n takes (1 − h)ⁿ by squaring in place of exp(n·log1p(−h)).
    # Error analysis (u = 2⁻⁵³): h = |a − b|²/2 is within 4u·h of the exact h of the float64
    # vectors (the difference 1 − bx rounds once, its square and the sum once more each),
    # 1 − h rounds by at most u relative (exact for h >= 1/2, Sterbenz), and the
    # squaring adds (n − 1)·u (test above): cⁿ is within n·(2 + 4h/c)·u + u of the exact
    # (a·b)ⁿ, ≤ 1.5e-11 for the n ≤ 65 536 that take this path at the angles where the
    # highlight is above 1e-12. Every term of a pixel is a non-negative sum, so a term within
    # ε relative keeps the pixel within ε: far below the 1e-5 budget. A float32 c (error
    # 6e-8·n) breaks the bound at every n here.
    worst = 0.0
    for n in WHOLE_N:
        width = math.sqrt(2.0 / n)
        for k in (0.0, 0.05, 0.3, 1.0, 2.0, 3.0, 5.0):
            th = min(k * width, 1.5)
            a = np.array([[1.0, 0.0, 0.0]])
            b = np.array([[math.cos(th), math.sin(th), 0.0]])
            with localcontext() as ctx:
                ctx.prec = 60
                bx, by = Decimal(b[0, 0]), Decimal(b[0, 1])
                h = ((Decimal(1) - bx) ** 2 + by * by) / 2
                c = Decimal(1) - h
                want = float(c**n)
            if want < 1e-12:
                continue
            got = float(cosine_power(a, b, np.array([float(n)]))[0])
            err = abs(got - want) / want
            bound = (n * (2.0 + 4.0 * float(h) / float(c)) + 2.0) * U
            assert err <= bound, (n, th, err, bound)
            worst = max(worst, err)
    assert worst < 1.5e-11


@pytest.mark.parametrize("model", ["phong", "blinn"])
@pytest.mark.parametrize("n", [20, 80, 200])
def test_whole_exponent_highlight_renders_its_closed_form(model, n):
    # A camera looking straight down at a plane (kd = 0, ks = 1) lit straight down: each
    # pixel is the highlight alone. Pixel (x, y) at unit depth has V·R = 1/s, s = √(1 + ρ²),
    # so Phong's (V·R)ⁿ = exp(−(n/2)·log1p(ρ²)); Blinn's N·H = √((1 + 1/s)/2), so (N·H)ⁿ =
    # exp((n/2)·log1p(−ρ²/(2s(1 + s)))). The image is float32 (rounding 6e-8): the squaring's
    # 1.5e-11 must not show, so the pixels stay within 1e-6 relative of the float64 formula.
    w, h = 15, 11
    aspect = w / h
    spread = 10.0 if model == "phong" else 40.0
    tan_half = math.sqrt(spread / (n * (1 + aspect**2)))
    fov = math.degrees(2 * math.atan(tan_half))
    mat = raytrace.Material(kd=0.0, ks=1.0, shininess=n, highlight=model)
    scene = make_scene([raytrace.Plane(**FLOOR, material=mat)],
                       [raytrace.DirectionalLight([0, -1, 0], 1.0)],
                       camera=raytrace.Camera([0, 1, 0], [0, 0, 0], [0, 0, -1], fov))
    img = raytrace.render(scene, width=w, height=h).rgb.astype(np.float64)
    col, row = np.meshgrid(np.arange(w), np.arange(h))
    x = (2 * (col + 0.5) / w - 1) * tan_half * aspect
    y = (1 - 2 * (row + 0.5) / h) * tan_half
    rho2 = x * x + y * y
    s = np.sqrt(1.0 + rho2)
    if model == "phong":
        want = np.exp(-0.5 * n * np.log1p(rho2))
    else:
        want = np.exp(0.5 * n * np.log1p(-0.5 * rho2 / (s * (1.0 + s))))
    assert want.min() < 0.2, "the falloff is inside the frame"
    np.testing.assert_allclose(img, np.repeat(want[..., None], 3, axis=2), rtol=1e-6, atol=0)

def test_phong_and_blinn_functions_at_known_angles():
    n_ = np.array([[0.0, 1.0, 0.0]])
    to_l = unit([math.sin(math.radians(20)), math.cos(math.radians(20)), 0.0])[None]
    to_v = unit([-math.sin(math.radians(50)), math.cos(math.radians(50)), 0.0])[None]
    e = np.array([7.0])
    assert phong(n_, to_l, to_v, e)[0] == pytest.approx(math.cos(math.radians(30)) ** 7)
    assert blinn(n_, to_l, to_v, e)[0] == pytest.approx(math.cos(math.radians(15)) ** 7)
    # direct(): zero where N·L <= 0, even with ks > 0.
    below = np.array([[0.0, -1.0, 0.0]])
    out = direct(n_, below, to_v, np.ones((1, 3)), np.ones((1, 3)), e, np.array([0]))
    assert np.all(out == 0)


def test_occluder_beyond_the_light_casts_no_shadow_in_a_scene_with_glass():
    # A mesh ceiling at y = 6 lies beyond the light at y = 4: the shadow ray stops at the light,
    # so P stays lit (I = kd·Il·N·L = 0.5). A glass sphere elsewhere makes the renderer walk
    # transparent shadows (closest-hit queries with tmax) instead of the occlusion query.
    # (Regression: the closest-hit query ignored tmax for meshes, so P came out black.)
    ceiling = raytrace.Mesh(vertices=[[-5, 6, -5], [5, 6, -5], [5, 6, 5], [-5, 6, 5]],
                            faces=[[0, 1, 2], [0, 2, 3]])
    glass = raytrace.Material(kd=0.0, ka=0.0, kt=0.6)
    for extra in ([], [raytrace.Sphere([10, 0, 0], 0.5, material=glass)]):
        scene = make_scene([raytrace.Plane(**FLOOR, material=raytrace.Material(kd=0.5, ka=0)),
                            ceiling, *extra], [raytrace.PointLight([0, 4, 0])],
                           camera=aimed_camera([3, 1, 3], [0, 0, 0]))
        np.testing.assert_allclose(pixel(scene), np.full(3, 0.5), rtol=RTOL)


# -- Hanika's lifted shadow-ray origin (shading_kernels.bulge1) ----------------------------------
def _patch(bend: float):
    """One triangle of a patch whose vertex normals lean outward by ``bend`` (convex, > 0) or
    inward (concave, < 0): corners on z = 0, normals (±bend·x̂, ±bend·ŷ) + ẑ, normalised."""
    corners = np.array([[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]])
    centre = corners[0].mean(0)
    normals = np.array([[np.r_[bend * (c - centre)[:2], 1.0] for c in corners[0]]])
    normals /= np.linalg.norm(normals, axis=2, keepdims=True)
    return corners, normals


def _triangles(corners: np.ndarray, vnormals: np.ndarray):
    """One triangle's corners and vertex normals, as :func:`bulge1` takes them."""
    from raytrace.kernels.records import SmoothTriangles

    return SmoothTriangles(corners, vnormals)


def test_lifted_origin_rises_on_a_convex_patch_and_stays_on_a_concave_one():
    from raytrace.kernels.records import MeshHit
    from raytrace.kernels.shading import bulge1

    u, v = 0.3, 0.3
    corners, normals = _patch(0.5)
    # P = (0.3, 0.3, 0) lies below each vertex's tangent plane (n_k·(P − V_k) < 0 where n_k
    # leans away from P): P_k = P − (n_k·(P − V_k))·n_k, blended with (0.4, 0.3, 0.3).
    p = np.array([u, v, 0.0])
    w = np.array([1 - u - v, u, v])
    expected = sum(w[k] * (p - min(0.0, normals[0, k] @ (p - corners[0, k])) * normals[0, k])
                   for k in range(3))
    p3 = tuple(p)
    got = np.array(bulge1(p3, MeshHit(0, u, v, 1.0), _triangles(corners, normals)))
    np.testing.assert_allclose(got, expected, rtol=1e-12, atol=1e-15)
    assert got[2] > 1e-3                                   # lifted off the flat facet
    # seen from the other side (side −1) the same patch is concave: no lift
    np.testing.assert_array_equal(
        bulge1(p3, MeshHit(0, u, v, -1.0), _triangles(corners, normals)), p)
    # a concave patch (normals leaning inward) seen from the front: no lift either
    corners, inward = _patch(-0.5)
    np.testing.assert_array_equal(bulge1(p3, MeshHit(0, u, v, 1.0), _triangles(corners, inward)), p)
    # flat normals: nothing to lift
    corners, flat = _patch(0.0)
    np.testing.assert_allclose(bulge1(p3, MeshHit(0, u, v, 1.0), _triangles(corners, flat)), p,
                               atol=1e-15)
    # at a vertex the point is that vertex (its own tangent plane passes through it)
    corners, normals = _patch(0.5)
    np.testing.assert_allclose(bulge1(tuple(corners[0, 1]), MeshHit(0, 1.0, 0.0, 1.0),
                                      _triangles(corners, normals)), corners[0, 1], atol=1e-15)


# -- one emitter's pass over the hits (shading_kernels.light_pass) ---------------------------
def test_light_pass_terms_and_the_shadow_rays_of_the_lit_hits_only():
    """Four hits on the plane y = 0 (N = ŷ, V from above), a point light at (0, 4, 0) with
    f = 1/(1 + 0.5·d²): a lit matte hit, an unlit material, a hit on a Gouraud triangle whose
    corners see the light at their own angles, and a hit seen from below (the light is then
    behind the surface the viewer sees). Only the lit ones get a shadow ray, in hit order."""
    from raytrace.kernels.records import Rays, Scene, Shadows, Surface, Triangles
    from raytrace.kernels.shading import light_pass
    from raytrace.lights import Emitter
    from raytrace.tables import MaterialTable

    kd = np.array([0.5, 0.25, 1.0])
    table = MaterialTable([raytrace.Material(kd=kd, ks=0.0),
                           raytrace.Material(ka=0.3, kd=0.0, ks=0.0)])  # unlit
    em = Emitter(np.ones(3), position=np.array([0.0, 4.0, 0.0]),
                 attenuation=np.array([1.0, 0.0, 0.5]))
    corners = np.array([[[-1.0, 0.0, 1.0], [1.0, 0.0, 1.0], [0.0, 0.0, -1.0]]])
    vnormals = np.array([[[0.0, 1.0, 0.0]] * 3])
    triangles = Triangles(np.zeros(1, np.int64), corners, np.array([[0.0, 1.0, 0.0]]), vnormals,
                          np.array([2], np.int8), np.zeros(1, np.int64), np.zeros(1))  # Gouraud
    point = np.array([[1.0, 0.0, 0.0], [2.0, 0.0, 0.0], [0.0, 0.0, 1.0 / 3.0],
                      [0.5, 0.0, 0.5]])
    up = np.tile([0.0, 1.0, 0.0], (4, 1))
    eye = np.array([[1.0, 3.0, 0.0], [2.0, 3.0, 0.0], [0.0, 3.0, 1.0 / 3.0],
                    [0.5, -3.0, 0.5]])
    direction = (point - eye) / 3.0
    material = np.array([0, 1, 0, 0])
    offset, shape = np.full(4, 1e-6), np.full(4, -1, np.int64)
    triangle, uv = np.array([-1, -1, 0, -1]), np.zeros((4, 2))
    uv[2] = [1.0 / 3.0, 1.0 / 3.0]                               # the centroid
    n = len(point)
    term, rows = np.empty((n, 3)), np.empty(n, np.int64)
    s_origin, s_direction = np.empty((n, 3)), np.empty((n, 3))
    s_tmax, s_shape = np.empty(n), np.empty(n, np.int64)
    from raytrace.kernels.core import SHADOW_SHORTEN

    shorten = 1e-7  # the documented value (docs/architecture.md), not read from the code
    assert SHADOW_SHORTEN == shorten
    rays = Rays(eye, direction, np.arange(n), np.ones((n, 3)), shape, np.zeros(n, np.int8))
    surf = Surface(point, up, up, material, offset, shape, triangle, uv)
    k = light_pass(rays, surf, Scene(np.zeros(3), table.record, triangles), em.record,
                   np.zeros(0, np.int64), 0, term, Shadows(rows, s_origin, s_direction, s_tmax,
                                                           s_shape))

    def lambert(p, normal):
        to_light = np.array([0.0, 4.0, 0.0]) - p
        d = np.linalg.norm(to_light)
        return kd * max(normal @ to_light / d, 0.0) / (1.0 + 0.5 * d * d)

    # hit 0: kd·N·L·f at the hit; hit 1: unlit; hit 3: from below N turns to −ŷ, N·L < 0
    np.testing.assert_allclose(term[0], lambert(point[0], up[0]), rtol=1e-14)
    np.testing.assert_array_equal(term[1], 0.0)
    np.testing.assert_array_equal(term[3], 0.0)
    # hit 2: Gouraud, the corners' terms (each with its own L and d) averaged at the centroid
    gouraud = sum(lambert(c, up[0]) for c in corners[0]) / 3.0
    np.testing.assert_allclose(term[2], gouraud, rtol=1e-14)
    assert abs(term[2] - lambert(point[2], up[0])).max() > 1e-3   # not the hit's own term
    # shadow rays: hits 0 and 2, in that order, leaving on the lit side towards the light
    assert k == 2
    np.testing.assert_array_equal(rows[:k], [0, 2])
    for j, i in enumerate(rows[:k]):
        to_light = np.array([0.0, 4.0, 0.0]) - point[i]
        d = np.linalg.norm(to_light)
        np.testing.assert_allclose(s_direction[j], to_light / d, rtol=1e-15)
        np.testing.assert_allclose(s_tmax[j], d * (1 - shorten), rtol=1e-15)
        np.testing.assert_allclose(s_origin[j], point[i] + [0.0, 1e-6, 0.0], rtol=1e-15,
                                   atol=1e-15)
        assert s_shape[j] == -1
