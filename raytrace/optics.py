"""Mirror reflection and Snell refraction on arrays of unit vectors.

Conventions: ``d`` is the incoming unit direction, ``n`` the unit normal on the side the ray
comes from (``d·n <= 0``). All arrays are (n, 3) float64 (a single row broadcasts). The per-ray
arithmetic is :func:`raytrace.kernels.core.reflect3` and ``refract3``, which the
integrator's compiled passes call directly.
"""

from __future__ import annotations

import numpy as np

from .kernels import shading as sk  # the compiled passes of this stage


def dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise dot product of (n, 3) arrays."""
    return np.einsum("ij,ij->i", a, b)


def rows3(*arrays, n: int = 1) -> list[np.ndarray]:
    """The arguments as C-contiguous float64 (k, 3) arrays, broadcast to a common k (with n)."""
    arrays = [np.asarray(a, np.float64).reshape(-1, 3) for a in arrays]
    k = np.broadcast_shapes((n,), *((len(a),) for a in arrays))[0]
    return [np.ascontiguousarray(np.broadcast_to(a, (k, 3))) for a in arrays]


def reflect(d: np.ndarray, n: np.ndarray) -> np.ndarray:
    """Mirror direction ``r = d − 2(d·n)n`` (law of reflection).

    >>> reflect(np.array([[1.0, -1.0, 0.0]]), np.array([[0.0, 1.0, 0.0]]))
    array([[1., 1., 0.]])
    """
    d, n = rows3(d, n)
    out = np.empty(d.shape)
    sk.reflect_rows(d, n, out)
    return out


def refract(d: np.ndarray, n: np.ndarray, eta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Snell refraction ``η₁ sin θ₁ = η₂ sin θ₂`` with ``eta = η₁/η₂``.

    Returns the refracted unit directions and a mask of total internal reflection (where the
    returned direction is the mirror direction instead). The radicand is written
    ``k = cos²θᵢ − (η² − 1)·sin²θᵢ`` (equal to ``1 − η²(1 − cos²θᵢ)``) so that ``eta = 1``
    gives ``k = cos²θᵢ`` and the ray leaves exactly undeviated; no square root ever sees a
    negative number: ``k < 0`` is TIR.

    >>> t, tir = refract(np.array([[0.6, -0.8, 0.0]]), np.array([[0.0, 1.0, 0.0]]),
    ...                  np.array([1.0]))
    >>> t.tolist(), tir.tolist()
    ([[0.6, -0.8, 0.0]], [False])
    """
    eta = np.asarray(eta, np.float64).reshape(-1)
    d, n = rows3(d, n, n=len(eta))
    eta = np.ascontiguousarray(np.broadcast_to(eta, len(d)))
    out, tir = np.empty(d.shape), np.empty(len(d), bool)
    sk.refract_rows(d, n, eta, out, tir)
    return out, tir


def critical_angle(ior: float) -> float:
    """Critical angle (radians) leaving a medium of index ``ior`` into index 1: asin(1/ior).

    >>> round(float(np.degrees(critical_angle(1.5))), 2)
    41.81
    """
    return float(np.arcsin(1.0 / ior))
