"""Property-based tests (hypothesis) of the pure optics and shading functions.

reflect and refract keep unit length; refraction obeys Snell's law η₁ sin θ₁ = η₂ sin θ₂ in
the plane of incidence; total internal reflection happens exactly when η sin θᵢ > 1; the local
shading terms are finite, non-negative and bounded by (kd + ks)·I_l. Few examples each, so the
file runs in a few seconds.
"""

from __future__ import annotations

import math

import numpy as np
from hypothesis import assume, example, given, settings
from hypothesis import strategies as st

from raytrace import shading
from raytrace.kernels.core import is_whole1
from raytrace.lights import Emitter, cos_cutoff
from raytrace.optics import critical_angle, reflect, refract
from raytrace.shading import HIGHLIGHT_CODES, cosine_power, direct

FAST = settings(max_examples=150, deadline=None)


coord = st.floats(-1.0, 1.0, allow_nan=False)
vec3 = st.tuples(coord, coord, coord)
eta = st.floats(1e-3, 1e3, allow_nan=False)
colour = st.tuples(*(st.floats(0.0, 1.0),) * 3)


def unit(v) -> np.ndarray:
    a = np.asarray(v, dtype=np.float64)
    norm = np.linalg.norm(a)
    assume(norm > 1e-3)
    return (a / norm)[None, :]


def incident(d, n) -> tuple[np.ndarray, np.ndarray]:
    """A unit direction and a unit normal on the side it comes from (d·n <= 0)."""
    d, n = unit(d), unit(n)
    c = float(d[0] @ n[0])
    assume(abs(c) > 1e-6)
    return d, (n if c < 0 else -n)


@FAST
@given(vec3, vec3)
def test_reflect_keeps_unit_length_and_mirrors_the_angle(d, n):
    d, n = unit(d), unit(n)
    r = reflect(d, n)
    assert abs(np.linalg.norm(r) - 1.0) < 1e-12
    assert abs(float(r[0] @ n[0]) + float(d[0] @ n[0])) < 1e-12   # r·n = −d·n
    assert np.allclose(np.cross(r, n), np.cross(d, n), atol=1e-12)  # tangent part kept


@FAST
@given(vec3, vec3, eta)
def test_refract_keeps_unit_length_and_obeys_snell(d, n, e):
    d, n = incident(d, n)
    t, tir = refract(d, n, np.array([e]))
    assert np.isfinite(t).all()
    assert abs(np.linalg.norm(t) - 1.0) < 1e-9
    if tir[0]:
        np.testing.assert_allclose(t, reflect(d, n), atol=1e-12)
        return
    sin_i = np.linalg.norm(np.cross(d, n))
    sin_t = np.linalg.norm(np.cross(t, n))
    assert abs(sin_t - e * sin_i) < 1e-9 * max(1.0, e)        # η₁ sin θ₁ = η₂ sin θ₂
    assert float(t[0] @ n[0]) <= 1e-12                            # it crosses the surface
    # coplanar: the triple product d·(n × t) (numpy's det warns on the exactly singular
    # matrices coplanar vectors make)
    assert abs(float(d[0] @ np.cross(n[0], t[0]))) < 1e-9 * max(1.0, e)


@FAST
@given(vec3, vec3, eta)
def test_total_internal_reflection_exactly_when_predicted(d, n, e):
    d, n = incident(d, n)
    sin_i = math.sqrt(max(0.0, 1.0 - float(d[0] @ n[0]) ** 2))
    _, tir = refract(d, n, np.array([e]))
    if e * sin_i > 1.0 + 1e-9:
        assert tir[0]
    elif e * sin_i < 1.0 - 1e-9:
        assert not tir[0]


@FAST
@given(st.floats(1.0 + 1e-9, 1e3))
def test_critical_angle_is_where_snell_reaches_90_degrees(ior):
    th = critical_angle(ior)
    assert 0 < th <= math.pi / 2
    assert abs(ior * math.sin(th) - 1.0) < 1e-12


@FAST
@given(vec3, vec3, st.floats(0.0, 1e8), st.floats(1.0, 1e8))
@example((0.0, 0.0, 1.0), (0.0, 0.953125, 1.0), 4.0, 1.0000000000000002)
def test_cosine_power_is_a_bounded_decreasing_function_of_n(a, b, n, factor):
    # Decreasing exactly along each of its two forms; where n is whole (squaring) and n·factor
    # is not (exp/log1p), or the other way, the forms agree to the 1.5e-11 they promise
    # (kernels.shading.cosine_power1): n = 4 and n·(1 + 2⁻⁵²) with a·b = 0.72 give q one
    # ulp above p.
    a, b = unit(a), unit(b)
    p = float(cosine_power(a, b, np.array([n]))[0])
    q = float(cosine_power(a, b, np.array([n * factor]))[0])
    assert 0.0 <= q <= 1.0 and 0.0 <= p <= 1.0
    if is_whole1.py_func(n) == is_whole1.py_func(n * factor):  # the same form
        assert q <= p
    else:
        assert q <= p * (1.0 + 1.5e-11)
    if float(a[0] @ b[0]) <= 0:
        assert p == 0.0


@FAST
@given(vec3, vec3, vec3, colour, colour, st.floats(0.0, 1e8),
       st.sampled_from(sorted(HIGHLIGHT_CODES)), st.floats(0.0, 1e6))
def test_direct_is_finite_non_negative_and_bounded(nrm, light, eye, kd, ks, shininess, model,
                                                   intensity):
    n, ldir, v = unit(nrm), unit(light), unit(eye)
    kd, ks = np.array([kd]), np.array([ks])
    out = direct(n, ldir, v, kd, ks, np.array([shininess]), np.array([HIGHLIGHT_CODES[model]]))
    lit = out * intensity
    assert np.isfinite(lit).all()
    assert (lit >= 0).all()
    assert (lit <= (kd + ks) * intensity * (1 + 1e-12)).all()
    if float(n[0] @ ldir[0]) <= 0:
        assert (out == 0).all()


@FAST
@given(vec3, st.floats(1.0, 1e3), st.floats(0.0, 10.0), st.floats(0.0, 10.0),
       st.floats(1e-6, 90.0), st.floats(0.0, 1e3), st.floats(-1e4, 1e4))
def test_light_factor_is_finite_and_at_most_one_over_a0(p, a0, a1, a2, cutoff, exponent,
                                                        offset):
    # f_radial·f_angular <= 1/a0: the shading is bounded by (kd + ks)·I_l/a0 (<= with a0 >= 1).
    point = np.asarray(p, dtype=np.float64)[None, :] * abs(offset)
    em = Emitter(np.ones(3), np.zeros(3), np.array([0.0, -1.0, 0.0]), np.array([a0, a1, a2]),
                 cos_cutoff(cutoff), exponent)
    to_light, dist, f = shading.incidence(em, point)
    assert np.isfinite(to_light).all() and np.isfinite(f).all()
    assert 0.0 <= f[0] <= 1.0 / a0
    if dist[0] > 0:
        assert abs(np.linalg.norm(to_light) - 1.0) < 1e-12


@settings(max_examples=12, deadline=None, derandomize=True)
@given(seed=st.integers(0, 2**32 - 1), subdivisions=st.integers(0, 1),
       ior=st.floats(0.4, 3.0), kr=st.floats(0.0, 0.5), jitter=st.floats(0.0, 0.3))
def test_every_spawned_direction_is_a_unit_vector_on_random_smooth_meshes(
        seed, subdivisions, ior, kr, jitter):
    # Random lumpy smooth glass (an icosphere with its vertices moved along random
    # directions), seen from a random side: interpolated normals face away from the rays
    # at many silhouette hits. The debug path asserts that every spawned direction is a unit
    # vector (raytrace.integrator.check_spawned).
    import trimesh

    import raytrace
    from raytrace import integrator

    rng = np.random.default_rng(seed)
    ico = trimesh.creation.icosphere(subdivisions=subdivisions)
    v = ico.vertices * (1.0 + jitter * rng.uniform(-1, 1, size=(len(ico.vertices), 1)))
    eye = rng.normal(size=3)
    eye = 4.0 * eye / np.linalg.norm(eye)
    glass = raytrace.Material(kd=0.0, kr=kr, kt=1.0 - kr, ior=ior)
    scene = raytrace.Scene(camera=raytrace.Camera(eye, [0, 0, 0], fov=40),
                           objects=[raytrace.Mesh(vertices=v, faces=ico.faces, shading="smooth",
                                                  material=glass)],
                           render=raytrace.RenderSettings(max_depth=5, background=1.0))
    checked, check = [], integrator.check_spawned

    def counting(rays):
        checked.append(len(rays))
        check(rays)

    before = integrator.DEBUG, integrator.check_spawned
    integrator.DEBUG, integrator.check_spawned = True, counting
    try:
        image = raytrace.render(scene, width=32, height=24, threads=1)
    finally:
        integrator.DEBUG, integrator.check_spawned = before
    assert checked, "the debug path checked the spawned batches"
    assert np.isfinite(image.rgb).all()
