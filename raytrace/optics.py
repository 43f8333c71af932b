"""Mirror reflection and Snell refraction on arrays of unit vectors.

Conventions: ``d`` is the incoming unit direction, ``n`` the unit normal on the side the ray
comes from (``d·n <= 0``). All arrays are (n, 3) float64.
"""

from __future__ import annotations

import numpy as np


def dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise dot product of (n, 3) arrays."""
    return np.einsum("ij,ij->i", a, b)


def reflect(d: np.ndarray, n: np.ndarray) -> np.ndarray:
    """Mirror direction ``r = d − 2(d·n)n`` (law of reflection).

    >>> reflect(np.array([[1.0, -1.0, 0.0]]), np.array([[0.0, 1.0, 0.0]]))
    array([[1., 1., 0.]])
    """
    return d - 2.0 * dot(d, n)[:, None] * n


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
    cos_i = np.clip(-dot(d, n), 0.0, 1.0)
    sin2 = np.maximum(0.0, (1.0 - cos_i) * (1.0 + cos_i))
    k = cos_i * cos_i - (eta - 1.0) * (eta + 1.0) * sin2
    tir = k < 0.0
    root = np.sqrt(np.where(tir, 0.0, k))
    t = eta[:, None] * d + (eta * cos_i - root)[:, None] * n
    if tir.any():
        t[tir] = reflect(d[tir], n[tir])
    return t, tir


def critical_angle(ior: float) -> float:
    """Critical angle (radians) leaving a medium of index ``ior`` into index 1: asin(1/ior).

    >>> round(float(np.degrees(critical_angle(1.5))), 2)
    41.81
    """
    return float(np.arcsin(1.0 / ior))
