"""Fast Phong shading: per-triangle Taylor polynomials of the diffuse and specular cosines.

Bishop & Weimer, "Fast Phong Shading", SIGGRAPH 1986 (seed 000's last slides): on a triangle
whose normal is interpolated linearly, ``n(u, v) = N₀ + u·(N₁ − N₀) + v·(N₂ − N₀)``, the
diffuse cosine of a directional light

    D(u, v) = L·n / |n| = (a·u + b·v + c) / √(d·u² + e·uv + f·v² + g·u + h·v + i)

is a smooth function of the barycentrics (u, v), and so is the specular cosine for a distant
viewer. Its second-order Taylor polynomial about the triangle's centroid (u, v) = (⅓, ⅓),

    D ≈ T₀ + T₁·du + T₂·dv + T₃·du² + T₄·du·dv + T₅·dv²,   du = u − ⅓, dv = v − ⅓,

is evaluated per hit with five multiply-adds instead of blending, normalising and dotting the
normal. The coefficients are computed here, once per (triangle, directional light), with
truncated polynomial arithmetic on the exact quadratic ``|n|²``:

* diffuse ``D = (L·n)·|n|⁻¹``, with ``|n|⁻¹ = q₀^(−½)·(1 − δ/2 + 3δ²/8)``, ``δ = (|n|² − q₀)/q₀``
  (the binomial series to second order, q₀ = |n|² at the centroid);
* specular, Blinn (the paper's): ``N̂·H = (H·n)·|n|⁻¹`` with ``H = (L + V)/|L + V|``;
* specular, Phong: ``V·R = 2·(L·n)·(V·n)·|n|⁻² − L·V`` (``R = 2(N̂·L)N̂ − L``), with
  ``|n|⁻² = q₀⁻¹·(1 − δ + δ²)``;

V is the unit vector from the triangle's centroid to the camera: the distant-viewer
assumption, V constant over the triangle. The highlight power ``max(S, 0)ⁿ`` is taken of the
polynomial per hit (:func:`raytrace.kernels.shading.fast_phong1`).

Where the assumptions do not hold, the renderer does not use the polynomials: hits lit by a
point, spot or area light, and hits of rays that do not start at the camera (reflected,
refracted, see-through: their viewer is another surface point) get exact Phong shading, the
same numbers as ``shading = "smooth"`` (docs/shading.md#fast-phong).

Functions: :func:`coefficients` (the table of one light), :func:`tables` (every light's, for
the integrator), :func:`evaluate` (the polynomials at barycentrics, for tests and
measurements), :func:`poly_mul` (truncated product).
"""

from __future__ import annotations

import numpy as np

from .kernels.core import FAST_PHONG, taylor_rows
from .kernels.records import FAST_COLUMNS, FAST_DIFFUSE, FAST_SPECULAR, FAST_TERMS
from .kernels.shading import PHONG

#: No table: the light pass shades every hit exactly (``raytrace.kernels.records.Scene.fast``).
NONE = np.zeros((0, FAST_COLUMNS))
#: The expansion point in barycentrics (u, v): the centroid.
CENTRE = 1.0 / 3.0


def poly_mul(p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """The product of two second-order polynomials in (du, dv), truncated to second order.

    ``p``, ``q``: (..., 6) coefficients of ``1, du, dv, du², du·dv, dv²``.

    >>> poly_mul(np.array([1.0, 1, 0, 0, 0, 0]), np.array([1.0, 1, 0, 0, 0, 0])).tolist()
    [1.0, 2.0, 0.0, 1.0, 0.0, 0.0]
    """
    p0, p1, p2, p3, p4, p5 = np.moveaxis(p, -1, 0)
    q0, q1, q2, q3, q4, q5 = np.moveaxis(q, -1, 0)
    return np.stack([p0 * q0, p0 * q1 + p1 * q0, p0 * q2 + p2 * q0,
                     p0 * q3 + p1 * q1 + p3 * q0,
                     p0 * q4 + p1 * q2 + p2 * q1 + p4 * q0,
                     p0 * q5 + p2 * q2 + p5 * q0], axis=-1)


def _dot(x: np.ndarray, centre: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``x·n`` as a polynomial in (du, dv): ``x·n_c + du·x·A + dv·x·B`` (exact, linear)."""
    zero = np.zeros(len(centre))
    return np.stack([np.einsum("ij,ij->i", x, centre), np.einsum("ij,ij->i", x, a),
                     np.einsum("ij,ij->i", x, b), zero, zero, zero], axis=-1)


def _inverse_powers(centre: np.ndarray, a: np.ndarray,
                    b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``|n|⁻¹`` and ``|n|⁻²`` to second order about the centroid: the binomial series of
    ``q₀^(−k)·(1 + δ)^(−k)`` in ``δ = (|n|² − q₀)/q₀``, where
    ``|n|² = q₀ + 2n_c·A·du + 2n_c·B·dv + A·A·du² + 2A·B·du·dv + B·B·dv²`` (exact)."""
    dot = lambda x, y: np.einsum("ij,ij->i", x, y)  # noqa: E731
    q0 = dot(centre, centre)
    delta = np.stack([np.zeros_like(q0), 2 * dot(centre, a), 2 * dot(centre, b), dot(a, a),
                      2 * dot(a, b), dot(b, b)], axis=-1) / q0[:, None]
    delta2 = poly_mul(delta, delta)
    one = np.zeros_like(delta)
    one[:, 0] = 1.0
    inv1 = (one - 0.5 * delta + 0.375 * delta2) / np.sqrt(q0)[:, None]
    inv2 = (one - delta + delta2) / q0[:, None]
    return inv1, inv2


def coefficients(corners: np.ndarray, vnormals: np.ndarray, to_light: np.ndarray,
                 blinn: np.ndarray) -> np.ndarray:
    """The fast-Phong table of one directional light: (T, FAST_COLUMNS) float64, per triangle
    the diffuse polynomial of ``L·n/|n|`` and the specular polynomial (Blinn's ``N̂·H`` where
    ``blinn`` (T,) is true, Phong's ``V·R`` elsewhere), in ``du = u − ⅓``, ``dv = v − ⅓``, from
    the columns ``FAST_DIFFUSE`` and ``FAST_SPECULAR`` of ``kernels.records``.

    ``corners`` (T, 3, 3) camera-relative (the camera at the origin), ``vnormals`` (T, 3, 3)
    unit vertex normals, ``to_light`` (3,) the unit vector L towards the light. Both
    polynomials are for the vertex normals as given (outward); a hit seen from the other
    side turns the normal, which negates ``L·n`` and ``H·n`` and leaves Phong's ``V·R``
    (even in n).
    """
    n0, n1, n2 = vnormals[:, 0], vnormals[:, 1], vnormals[:, 2]
    a, b = n1 - n0, n2 - n0
    centre = n0 + CENTRE * (a + b)                    # n at the centroid (unnormalised)
    view = -corners.mean(axis=1)                      # centroid → camera
    view /= np.linalg.norm(view, axis=1, keepdims=True)
    light = np.broadcast_to(np.asarray(to_light, np.float64), view.shape)
    inv1, inv2 = _inverse_powers(centre, a, b)
    l_n = _dot(light, centre, a, b)
    diffuse = poly_mul(l_n, inv1)
    half = light + view
    half /= np.maximum(np.linalg.norm(half, axis=1, keepdims=True), 1e-300)
    blinn_s = poly_mul(_dot(half, centre, a, b), inv1)
    phong_s = 2.0 * poly_mul(poly_mul(l_n, _dot(view, centre, a, b)), inv2)
    phong_s[:, 0] -= np.einsum("ij,ij->i", light, view)
    specular = np.where(np.asarray(blinn, bool)[:, None], blinn_s, phong_s)
    table = np.zeros((len(corners), FAST_COLUMNS))
    table[:, FAST_DIFFUSE:FAST_DIFFUSE + FAST_TERMS] = diffuse
    table[:, FAST_SPECULAR:FAST_SPECULAR + FAST_TERMS] = specular
    return table


def tables(triangles, highlight: np.ndarray, emitters: list) -> list[np.ndarray]:
    """The table of each emitter (a :class:`raytrace.lights.Emitter`) for the triangles of a
    :class:`raytrace.kernels.records.Triangles`: :func:`coefficients` for a directional light where
    some triangle is ``fast_phong`` (rows of other triangles are computed too and never
    read), else :data:`NONE` (exact Phong). ``highlight`` (M,): each material's highlight
    code (``raytrace.kernels.records.Materials.highlight``)."""
    if not np.any(triangles.shading == FAST_PHONG):
        return [NONE] * len(emitters)
    blinn = np.asarray(highlight)[triangles.material] != PHONG  # N̂·H for both Blinn models
    return [NONE if em.position is not None else
            coefficients(triangles.corners, triangles.vnormals, -np.asarray(em.direction), blinn)
            for em in emitters]


def evaluate(table: np.ndarray, rows: np.ndarray,
             uv: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The diffuse and specular polynomials of triangles ``rows`` (n,) of ``table`` (T,
    FAST_COLUMNS) at barycentrics ``uv`` (n, 2), as the kernels evaluate them
    (:func:`raytrace.kernels.core.taylor1`)."""
    table = np.ascontiguousarray(table, np.float64)
    rows = np.ascontiguousarray(rows, np.int64)
    uv = np.ascontiguousarray(uv, np.float64).reshape(-1, 2)
    diffuse, specular = np.empty(len(rows)), np.empty(len(rows))
    taylor_rows(table, rows, FAST_DIFFUSE, uv, diffuse)
    taylor_rows(table, rows, FAST_SPECULAR, uv, specular)
    return diffuse, specular
