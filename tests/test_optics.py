"""raytrace.optics: the law of reflection and Snell's law on arrays of unit vectors.

Known numbers (Hecht, Optics): the critical angle of glass (n = 1.5) against air is
asin(1/1.5) = 41.81°; leaving glass at 30°, sin θt = 1.5·sin 30° = 0.75 (48.59°); entering
glass at grazing incidence, sin θt = 1/1.5 (θt is the critical angle).
Conventions under test: ``d`` the incoming unit direction, ``n`` the unit normal on the side
the ray comes from (d·n ≤ 0), ``eta = η₁/η₂``.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from raytrace.optics import critical_angle, dot, reflect, refract

UP = np.array([[0.0, 1.0, 0.0]])


def incoming(theta: np.ndarray) -> np.ndarray:
    """Unit directions in the xy-plane arriving at angle θ from the normal +y, (n, 3)."""
    theta = np.atleast_1d(theta)
    return np.column_stack([np.sin(theta), -np.cos(theta), np.zeros_like(theta)])


def random_pairs(n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """n random unit directions and unit normals facing them (d·n < 0)."""
    rng = np.random.default_rng(seed)
    d = rng.normal(size=(n, 3))
    nrm = rng.normal(size=(n, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
    nrm *= -np.sign(dot(d, nrm))[:, None]
    return d, nrm


def sin_to_normal(v: np.ndarray, n: np.ndarray) -> np.ndarray:
    """|v × n|: the sine of the angle between unit v and the normal line."""
    return np.linalg.norm(np.cross(v, n), axis=1)


# -- reflect ---------------------------------------------------------------------------------
def test_reflect_known_value():
    # (1, -1, 0) on the floor y = 0 comes back up as (1, 1, 0).
    np.testing.assert_array_equal(reflect(np.array([[1.0, -1.0, 0.0]]), UP), [[1, 1, 0]])


def test_reflect_obeys_the_law_of_reflection():
    # Angle out = angle in, the other side of the normal, in the plane of d and n, unit
    # length; reflecting twice gives d back.
    d, n = random_pairs(2000, seed=1)
    r = reflect(d, n)
    np.testing.assert_allclose(dot(r, n), -dot(d, n), atol=1e-14)
    np.testing.assert_allclose(np.linalg.norm(r, axis=1), 1.0, atol=1e-14)
    np.testing.assert_allclose(dot(np.cross(d, n), r), 0.0, atol=1e-14)
    np.testing.assert_allclose(reflect(r, n), d, atol=1e-14)


# -- refract ---------------------------------------------------------------------------------
@pytest.mark.parametrize("eta", [1 / 1.5, 1.5, 1 / 2.42, 1.33, 0.9, 1.1])
def test_refract_obeys_snells_law(eta):
    # η₁ sin θi = η₂ sin θt, i.e. sin θt = eta·sin θi; t is unit, on the far side of the
    # surface (t·n < 0) and in the plane of incidence. Where eta·sin θi > 1 it is TIR instead.
    d, n = random_pairs(4000, seed=2)
    t, tir = refract(d, n, np.full(len(d), eta))
    s_i = sin_to_normal(d, n)
    np.testing.assert_array_equal(tir, eta * s_i > 1.0)
    ok = ~tir
    assert ok.sum() > 1000
    np.testing.assert_allclose(sin_to_normal(t[ok], n[ok]), eta * s_i[ok], atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(t, axis=1), 1.0, atol=1e-12)
    assert np.all(dot(t[ok], n[ok]) < 0)
    np.testing.assert_allclose(dot(np.cross(d, n), t), 0.0, atol=1e-12)
    # Total internal reflection returns the mirror direction.
    np.testing.assert_array_equal(t[tir], reflect(d[tir], n[tir]))
    if eta > 1:
        assert tir.sum() > 100


def test_refract_known_angles():
    # Leaving glass (eta = 1.5) at 30°: sin θt = 0.75. Entering glass (eta = 1/1.5) at
    # grazing incidence (89.999999°): sin θt → 1/1.5, the critical angle. Normal incidence
    # never bends.
    t, tir = refract(incoming(math.radians(30.0)), UP, np.array([1.5]))
    np.testing.assert_allclose(t, [[0.75, -math.sqrt(1 - 0.75**2), 0.0]], atol=1e-15)
    assert not tir.any()
    t, _ = refract(incoming(math.radians(89.999999)), UP, np.array([1 / 1.5]))
    assert math.degrees(math.asin(t[0, 0])) == pytest.approx(41.8103149, abs=1e-6)
    etas = np.array([1 / 1.5, 1.5, 2.42, 1.0])
    d = np.repeat(incoming(0.0), 4, axis=0)
    t, tir = refract(d, np.repeat(UP, 4, axis=0), etas)
    np.testing.assert_array_equal(t, d)
    assert not tir.any()


def test_ior_one_is_bit_exactly_straight():
    # eta = 1 must give back d bit for bit, at every angle up to grazing: the radicand is
    # written cos²θ − (η² − 1)·sin²θ, exactly cos²θ at η = 1, and √(cos²θ) = cos θ exactly in
    # IEEE arithmetic, so t = d + (cos θ − cos θ)·n = d.
    d, n = random_pairs(20000, seed=4)
    t, tir = refract(d, n, np.ones(len(d)))
    assert np.array_equal(t, d) and not tir.any()
    grazing = incoming(np.linspace(0.0, math.pi / 2, 1001))
    t, tir = refract(grazing, np.repeat(UP, len(grazing), axis=0), np.ones(len(grazing)))
    assert np.array_equal(t, grazing) and not tir.any()


def test_critical_angle_of_glass():
    # asin(1/1.5) = 41.8103149°.
    assert math.degrees(critical_angle(1.5)) == pytest.approx(41.8103149, abs=1e-7)
    assert critical_angle(1.0) == pytest.approx(math.pi / 2)
    assert math.degrees(critical_angle(2.42)) == pytest.approx(24.4075, abs=1e-4)  # diamond


@pytest.mark.parametrize("ior", [1.33, 1.5, 2.42])
def test_tir_just_above_the_critical_angle_refraction_just_below(ior):
    # Leaving the denser medium (eta = ior): 1e-9 rad below θc the ray still leaves, skimming
    # the surface (sin θt = ior·sin θ just under 1); 1e-9 rad above, TIR.
    tc = critical_angle(ior)
    d = incoming(np.array([tc - 1e-9, tc + 1e-9]))
    t, tir = refract(d, np.repeat(UP, 2, axis=0), np.full(2, ior))
    assert tir.tolist() == [False, True]
    assert t[0, 0] == pytest.approx(ior * math.sin(tc - 1e-9), rel=1e-12)
    assert -1e-3 < t[0, 1] < 0  # grazing, on the far side
    np.testing.assert_array_equal(t[1], reflect(d[1:], UP)[0])
    # Entering the denser medium there is never TIR, even at grazing incidence.
    d = incoming(np.linspace(0, math.pi / 2, 101))
    _, tir = refract(d, np.repeat(UP, len(d), axis=0), np.full(len(d), 1 / ior))
    assert not tir.any()


def test_refraction_is_reversible():
    # Helmholtz reciprocity: sending −t back through the surface (normal −n, eta⁻¹) gives −d.
    d, n = random_pairs(3000, seed=5)
    eta = np.full(len(d), 1 / 1.5)
    t, tir = refract(d, n, eta)
    assert not tir.any()
    back, tir_back = refract(-t, -n, 1 / eta)
    assert not tir_back.any()
    np.testing.assert_allclose(back, -d, atol=1e-12)


def test_no_nan_at_the_edges():
    # Rounding can put d·n a hair outside [-1, 0]; grazing rays; empty batches.
    d = np.array([[0.0, -1.0000000000000002, 0.0], [1.0, 1e-17, 0.0], [1.0, 0.0, 0.0]])
    n = np.repeat(UP, 3, axis=0)
    for eta in (1 / 1.5, 1.0, 1.5):
        t, _ = refract(d, n, np.full(3, eta))
        assert np.isfinite(t).all()
    t, tir = refract(np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0))
    assert t.shape == (0, 3) and tir.shape == (0,)


@settings(max_examples=200, deadline=None)
@given(theta=st.floats(0.0, math.pi / 2), ior=st.floats(1.0001, 3.0))
def test_tir_exactly_where_sin_theta_exceeds_one_over_ior(theta, ior):
    # Leaving a medium of index ior: TIR ⇔ ior·sin θ > 1 (away from the boundary itself,
    # where rounding decides).
    margin = abs(ior * math.sin(theta) - 1.0)
    _, tir = refract(incoming(theta), UP, np.array([ior]))
    if margin > 1e-12:
        assert bool(tir[0]) == (ior * math.sin(theta) > 1.0)
