"""Fast Phong shading (raytrace.fast_phong, shading_kernels.fast_phong1; Bishop & Weimer 1986).

The polynomials against the exact cosines written out here (N̂·L, N̂·H, V·R with R = 2(N̂·L)N̂ −
L): equal on a flat triangle, within θ³/6 on curved meshes (θ the largest angle between a
triangle's vertex normals; (2θ)³/6 for V·R; docs/shading.md#fast-phong) and third-order
convergent; renders against ``smooth``: equal on a flat mesh, bounded on a sphere, identical
where the assumptions fail (point lights, rays not from the camera).
"""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

import raytrace
from raytrace import fast_phong

RNG = np.random.default_rng(16)


def _barycentrics(n: int) -> np.ndarray:
    uv = RNG.random((n, 2))
    out = uv.sum(axis=1) > 1.0
    uv[out] = 1.0 - uv[out]
    return uv


def _exact(corners, vnormals, to_light, rows, uv):
    """N̂·L, N̂·H and V·R at barycentrics ``uv`` of triangles ``rows``, V from the centroid to
    the camera at the origin (the distant viewer), written out from the definitions."""
    w = 1.0 - uv.sum(axis=1)
    n = (w[:, None] * vnormals[rows, 0] + uv[:, :1] * vnormals[rows, 1]
         + uv[:, 1:] * vnormals[rows, 2])
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    view = -corners[rows].mean(axis=1)
    view /= np.linalg.norm(view, axis=1, keepdims=True)
    half = to_light + view
    half /= np.linalg.norm(half, axis=1, keepdims=True)
    n_l = n @ to_light
    return n_l, (n * half).sum(axis=1), 2.0 * n_l * (n * view).sum(axis=1) - view @ to_light


def _polynomials(corners, vnormals, to_light, rows, uv):
    t = len(corners)
    d, s_blinn = fast_phong.evaluate(
        fast_phong.coefficients(corners, vnormals, to_light, np.ones(t, bool)), rows, uv)
    _, s_phong = fast_phong.evaluate(
        fast_phong.coefficients(corners, vnormals, to_light, np.zeros(t, bool)), rows, uv)
    return d, s_blinn, s_phong


def test_poly_mul_truncates_at_second_order():
    """(1 + du + dv)·(2 − dv + du²) = 2 + 2du + dv + du² − du·dv − dv² + O(3)."""
    p = np.array([1.0, 1.0, 1.0, 0.0, 0.0, 0.0])
    q = np.array([2.0, 0.0, -1.0, 1.0, 0.0, 0.0])
    np.testing.assert_array_equal(fast_phong.poly_mul(p, q), [2.0, 2.0, 1.0, 1.0, -1.0, -1.0])


def test_flat_triangle_polynomials_are_the_exact_cosines():
    """All three vertex normals equal: |n| = 1 everywhere, so every polynomial is a constant
    equal to the exact cosine, for any barycentrics."""
    corners = np.array([[[-1.0, -0.5, -4.0], [1.5, -0.25, -5.0], [0.0, 1.0, -4.5]]])
    normal = np.array([0.2, 0.3, 1.0]) / np.linalg.norm([0.2, 0.3, 1.0])
    vnormals = np.tile(normal, (1, 3, 1))
    to_light = np.array([0.5, 1.0, 2.0]) / np.linalg.norm([0.5, 1.0, 2.0])
    uv = _barycentrics(200)
    rows = np.zeros(len(uv), np.int64)
    for got, want in zip(_polynomials(corners, vnormals, to_light, rows, uv),
                         _exact(corners, vnormals, to_light, rows, uv), strict=True):
        np.testing.assert_allclose(got, want, rtol=0, atol=1e-14)


@pytest.mark.parametrize("subdivisions", [1, 2, 3])
def test_curved_mesh_stays_within_the_stated_bound(subdivisions):
    """An icosphere 4 units in front of the camera, its vertex normals perturbed, a random
    light: each triangle's |polynomial − exact| ≤ θ³/6 for N̂·L and N̂·H, (2θ)³/6 for V·R
    (measured: 0.11·θ³ and 0.37·θ³)."""
    sphere = trimesh.creation.icosphere(subdivisions)
    normals = sphere.vertices + RNG.normal(0.0, 0.1 * 2.0**-subdivisions, sphere.vertices.shape)
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    corners, vnormals = sphere.vertices[sphere.faces] + [0.0, 0.0, -4.0], normals[sphere.faces]
    to_light = RNG.normal(size=3)
    to_light /= np.linalg.norm(to_light)
    t, per = len(corners), 32
    rows = np.repeat(np.arange(t), per)
    uv = _barycentrics(t * per)
    theta = np.max([np.arccos(np.clip((vnormals[:, i] * vnormals[:, j]).sum(axis=1), -1, 1))
                    for i, j in ((0, 1), (1, 2), (0, 2))], axis=0)
    # R turns twice as fast as N: Phong's V·R has the bound of twice the angle
    for got, want, scale in zip(_polynomials(corners, vnormals, to_light, rows, uv),
                                _exact(corners, vnormals, to_light, rows, uv), (1, 1, 2),
                                strict=True):
        assert np.all(np.abs(got - want) <= (scale * theta[rows]) ** 3 / 6.0)


def test_error_falls_as_the_cube_of_the_triangle_size():
    """Second order in (u, v) leaves a third-order remainder: each icosphere subdivision
    halves the triangles' size and divides the largest error by about 8 (more than 6 here;
    a first-order expansion would give 4)."""
    to_light = np.array([1.0, 2.0, 3.0]) / np.linalg.norm([1.0, 2.0, 3.0])
    worst = []
    for k in (2, 3, 4):
        sphere = trimesh.creation.icosphere(k)
        corners = sphere.vertices[sphere.faces] + [0.0, 0.0, -4.0]
        vnormals = sphere.vertices[sphere.faces]
        rows = np.repeat(np.arange(len(corners)), 16)
        uv = _barycentrics(len(rows))
        got = _polynomials(corners, vnormals, to_light, rows, uv)
        want = _exact(corners, vnormals, to_light, rows, uv)
        worst.append([np.abs(g - w).max() for g, w in zip(got, want, strict=True)])
    worst = np.array(worst)
    assert np.all(worst[:-1] / worst[1:] > 6.0), worst


def _scene(shading, mesh, light, mirror=False, ks=0.5, highlight="phong"):
    objects = [raytrace.Mesh(mesh=mesh, shading=shading,
                             material=raytrace.Material(kd=[0.6, 0.5, 0.4], ks=ks,
                                                        shininess=30, highlight=highlight))]
    if mirror:  # the mesh behind the camera, seen only in a mirror ahead of it
        objects.append(raytrace.Plane(point=[0, 0, -3], normal=[0, 0, 1],
                                      material=raytrace.Material(kd=0.0, ks=0.0, kr=0.9)))
    return raytrace.Scene(camera=raytrace.Camera(position=[0, 0, 4], look_at=[0, 0, 0]),
                          objects=objects, lights=[light], ambient=0.05)


SUN = raytrace.DirectionalLight(direction=[-1.0, -1.0, -1.0])


def _render(scene):
    return raytrace.render(scene, width=80, height=60).rgb.astype(np.float64)


def test_flat_mesh_renders_as_smooth_under_a_directional_light():
    """A quad whose vertex normals all equal its face normal, diffuse only (the highlight's V
    is the centroid's, not the hit's): fast Phong's image is smooth's to rounding."""
    quad = trimesh.Trimesh([[-1.5, -1, 0], [1.5, -1, 0], [1.5, 1, 0], [-1.5, 1, 0]],
                           [[0, 1, 2], [0, 2, 3]], process=False)
    fast = _render(_scene("fast_phong", quad, SUN, ks=0.0))
    exact = _render(_scene("smooth", quad, SUN, ks=0.0))
    assert fast.max() > 0.3  # the quad fills the frame, lit
    np.testing.assert_allclose(fast, exact, rtol=1e-6, atol=0)


def test_sphere_render_within_its_bound_of_smooth():
    """An 1280-face icosphere under a directional light: diffuse only, the polynomials'
    error (≤ θ³/6 ≈ 6e-4 here, times kd ≤ 0.6); with a highlight, the distant viewer's
    error too (measured 0.032, bound 0.05). But not equal: the approximation is used."""
    sphere = trimesh.creation.icosphere(3)
    for ks, bound in ((0.0, 0.6 * 0.17**3 / 6.0), (0.5, 0.05)):
        fast = _render(_scene("fast_phong", sphere, SUN, ks=ks))
        exact = _render(_scene("smooth", sphere, SUN, ks=ks))
        error = np.abs(fast - exact).max()
        assert 0.0 < error <= bound, (ks, error)


def test_blinn_cosine_fast_phong_within_its_bound_of_smooth():
    """The glTF highlight (Blinn's lobe times N·L) through the fast-Phong polynomials: the
    same sphere within the same bound as Phong's highlight (measured 0.017); and not the
    plain Blinn render (the N·L factor is applied: measured differences up to 0.082)."""
    sphere = trimesh.creation.icosphere(3)
    fast = _render(_scene("fast_phong", sphere, SUN, highlight="blinn_cosine"))
    exact = _render(_scene("smooth", sphere, SUN, highlight="blinn_cosine"))
    assert 0.0 < np.abs(fast - exact).max() <= 0.05
    plain = _render(_scene("fast_phong", sphere, SUN, highlight="blinn"))
    assert np.abs(fast - plain).max() > 0.01


def test_point_lights_and_secondary_rays_shade_exactly():
    """Where the assumptions fail the light pass shades as ``smooth`` does, bit for bit: a
    point light; a directional light seen only in a mirror (reflected rays' viewer is the
    mirror, not the camera)."""
    sphere = trimesh.creation.icosphere(2)
    point = raytrace.PointLight(position=[3.0, 4.0, 5.0])
    np.testing.assert_array_equal(_render(_scene("fast_phong", sphere, point)),
                                  _render(_scene("smooth", sphere, point)))
    behind = sphere.copy()
    behind.apply_translation([0.0, 0.0, 7.0])  # behind the camera at z = 4
    mirrored = _render(_scene("fast_phong", behind, SUN, mirror=True))
    assert mirrored.max() > 0.2  # the sphere shows in the mirror
    np.testing.assert_array_equal(mirrored, _render(_scene("smooth", behind, SUN, mirror=True)))


def test_scene_file_accepts_fast_phong(tmp_path):
    (tmp_path / "s.toml").write_text(
        '[camera]\nposition = [0, 0, 4]\nlook_at = [0, 0, 0]\n'
        '[[objects]]\ntype = "mesh"\nvertices = [[-1, -1, 0], [1, -1, 0], [0, 1, 0]]\n'
        'faces = [[0, 1, 2]]\nshading = "fast_phong"\n'
        '[[lights]]\ntype = "directional"\ndirection = [0, 0, -1]\n')
    scene = raytrace.load_scene(tmp_path / "s.toml")
    assert scene.objects[0].shading == "fast_phong"
    image = raytrace.render(scene, width=16, height=12)
    assert image.rgb.max() > 0.0
