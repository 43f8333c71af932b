"""Per-corner tangent frames for tangent-space normal maps: MikkTSpace's per-vertex rule in
numpy (:func:`mikktspace`), and the frames a glTF ``TANGENT`` attribute gives.

The glTF 2.0 specification (§3.7.2.1) asks for MikkTSpace tangents where a primitive with a
normal map gives none (Mikkelsen, "Simulation of wrinkled surfaces revisited", MSc thesis,
University of Copenhagen, 2008; the reference implementation ``mikktspace.c``, as Blender
and the glTF exporters call it). There is no MikkTSpace package for Python, so its rule is
written here, for triangles, per face corner:

1. per face, the tangent and bitangent of the texture mapping, ``T_f = ∂P/∂s`` and
   ``B_f = ∂P/∂v`` (v = −t: OpenGL's texture v grows upwards, glTF's t downwards, and a
   normal map's +Y is "up", glTF §3.9.3), from the UV gradients of its edges
   (``T_f = (Δv₂·e₁ − Δv₁·e₂)/det``, ``det = Δs₁·Δv₂ − Δs₂·Δv₁``); its handedness is the
   sign of ``det`` (mikktspace.c's ``fSignedAreaSTx2``, which decides the "orientation
   preserving" flag);
2. per corner, ``T_f`` projected onto the plane of the corner's normal n (Gram–Schmidt,
   ``T_f − (n·T_f)·n``), normalised, and weighted by the corner's angle measured between its
   two edges projected onto that plane (mikktspace.c's ``fAngle``);
3. the weighted tangents summed over the corners that are one vertex (the same position,
   normal and texture coordinates) and of the same handedness, then normalised;
4. the sign ``w = ±1`` (glTF's ``TANGENT.w``) is the handedness: ``B = w·(n × T)`` lies on
   the side of ``∂P/∂v``.

Left out of the reference: its handling of degenerate triangles (zero area, or zero texture
area: mikktspace.c gives them the tangents of their neighbours sharing the vertex; here
they add nothing, and a corner left with no tangent takes any unit vector perpendicular
to its normal, ``w = +1``); its splitting of a vertex's faces into groups connected across
shared edges (here all faces of a welded vertex with one handedness form one group); the
tangent magnitudes ``fMagS``, ``fMagT`` and quads. On smooth, well-mapped meshes (a plane, a
UV sphere, tests/test_tangents.py) these parts are never reached and the rule gives the
analytic ``∂P/∂s`` direction.
"""

from __future__ import annotations

import numpy as np

#: Below this |det| (texture area × 2, in texture units²) a face's mapping is degenerate and
#: gives no tangent.
DEGENERATE_UV = 1e-20


def _unit(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``x`` (…, 3) normalised where its length is above 0, and where it is."""
    length = np.linalg.norm(x, axis=-1, keepdims=True)
    ok = length[..., 0] > 1e-300
    return np.where(ok[..., None], x / np.where(length > 0, length, 1.0), 0.0), ok


def perpendicular(n: np.ndarray) -> np.ndarray:
    """A unit vector perpendicular to each unit ``n`` (k, 3): n × the axis least along it."""
    axis = np.zeros_like(n)
    axis[np.arange(len(n)), np.argmin(np.abs(n), axis=1)] = 1.0
    return _unit(np.cross(n, axis))[0]


def mikktspace(corners: np.ndarray, normals: np.ndarray, texcoords: np.ndarray) -> np.ndarray:
    """Unit tangents and handedness (F, 3, 4) at each face corner (xyz, w = ±1) by
    MikkTSpace's per-vertex rule (module docstring). ``corners`` (F, 3, 3) the faces' vertex
    positions, ``normals`` (F, 3, 3) the unit normals each corner is shaded with, ``texcoords``
    (F, 3, 2) its (s, t), t = 0 at the image's top (glTF's, and OBJ's once read).

    >>> import numpy as np
    >>> quad = np.array([[[0, 0, 0], [2, 0, 0], [0, 2, 0]]], float)  # s along x, t along −y
    >>> st = np.array([[[0, 1], [1, 1], [0, 0]]], float)
    >>> mikktspace(quad, np.tile([0, 0, 1.0], (1, 3, 1)), st)[0, 0].tolist()
    [1.0, 0.0, 0.0, 1.0]
    """
    f = len(corners)
    p, n = np.asarray(corners, np.float64), np.asarray(normals, np.float64)
    s, v = texcoords[..., 0].astype(np.float64), -texcoords[..., 1].astype(np.float64)
    e1, e2 = p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]
    ds1, ds2 = s[:, 1] - s[:, 0], s[:, 2] - s[:, 0]
    dv1, dv2 = v[:, 1] - v[:, 0], v[:, 2] - v[:, 0]
    det = ds1 * dv2 - ds2 * dv1
    mapped = np.abs(det) > DEGENERATE_UV
    tf = (dv2[:, None] * e1 - dv1[:, None] * e2) / np.where(mapped, det, 1.0)[:, None]
    handed = np.where(det < 0.0, -1.0, 1.0)  # (F,)
    # per corner: T_f in the plane of the corner's normal, weighted by the corner's angle there
    t = tf[:, None, :] - np.einsum("fkj,fj->fk", n, tf)[..., None] * n
    t, ok = _unit(t)
    a = np.roll(p, -1, axis=1) - p  # edge to the next corner
    b = np.roll(p, 1, axis=1) - p   # edge to the previous one
    a = _unit(a - np.einsum("fkj,fkj->fk", a, n)[..., None] * n)[0]
    b = _unit(b - np.einsum("fkj,fkj->fk", b, n)[..., None] * n)[0]
    angle = np.arccos(np.clip(np.einsum("fkj,fkj->fk", a, b), -1.0, 1.0))
    weight = np.where(ok & mapped[:, None], angle, 0.0)
    # one vertex: the same position, normal and (s, t), and the same handedness
    key = np.concatenate([p, n, texcoords.astype(np.float64),
                          np.repeat(handed[:, None, None], 3, axis=1)], axis=2).reshape(3 * f, -1)
    _, group = np.unique(key, axis=0, return_inverse=True)
    group = group.reshape(-1)
    summed = np.zeros((group.max() + 1 if len(group) else 0, 3))
    np.add.at(summed, group, (weight[..., None] * t).reshape(-1, 3))
    out = np.empty((f, 3, 4))
    tangent, found = _unit(summed[group])
    flat_n = n.reshape(-1, 3)
    tangent[~found] = perpendicular(flat_n[~found])
    out[..., :3] = tangent.reshape(f, 3, 3)
    out[..., 3] = np.where(found.reshape(f, 3), handed[:, None], 1.0)
    return out


def given_tangents(tangents: np.ndarray, linear: np.ndarray) -> np.ndarray:
    """A file's tangents (…, 4) (glTF ``TANGENT``: unit xyz along ∂P/∂s, w = ±1) taken through
    the linear part ``linear`` (3×3) of a transform: ``M·t`` normalised (a tangent is a
    direction along the surface, not a normal), and w times the sign of det M (a mirroring
    transform swaps the frame's handedness: ``B = w·(n × T)`` must still be ``M·B``); a zero
    row (a corner the file gives no tangent) stays zero."""
    t = np.array(tangents, np.float64)
    t[..., :3], ok = _unit(t[..., :3] @ np.asarray(linear, np.float64).T)
    mirror = -1.0 if np.linalg.det(linear) < 0 else 1.0
    t[..., 3] = np.where(ok, np.where(t[..., 3] < 0.0, -mirror, mirror), 0.0)  # none: zeros
    return t


def mapped_tangents(tangents: np.ndarray, normals: np.ndarray, linear: np.ndarray
                    ) -> np.ndarray:
    """A file's tangent frames (F, 3, 4) (glTF ``TANGENT``: unit T along ∂P/∂s, w the sign of
    B = w·(N × T), along ∂P/∂v with v = −t), given for the coordinates (s, t), turned into the
    frames of the coordinates a normal map reads, ``(s', t') = L·(s, t) + c`` (its
    KHR_texture_transform or MTL ``-o``/``-s``; ``linear`` (F, 2, 2) the L of each face):
    ``T' ∝ ∂P/∂s'``, ``w' = w·sign(det L)``. ``normals`` (F, 3, 3) are the unit normals N the
    corners are shaded with. In (s, v), L is ``L_v = [[a, −b], [−d, e]]`` for ``L = [[a, b],
    [d, e]]``, and ``∂P/∂s' = P_s·M₀₀ + P_v·M₁₀`` with ``M = L_v⁻¹``; a file gives only the
    directions of P_s and P_v, taken as T and B (a conformal mapping, which a tangent-space
    normal map assumes: its frame is orthonormal). The Khronos glTF Sample Renderer turns its
    TBN frame by the texture transform the same way (KhronosGroup/glTF-Sample-Renderer#16,
    fixing glTF-Sample-Viewer#592). A zero row (a corner without a tangent) stays zero.

    >>> quarter = np.array([[[0.0, 1.0], [-1.0, 0.0]]])  # KHR rotation 90°: s' = t, t' = −s
    >>> t = mapped_tangents(np.array([[[1.0, 0, 0, 1]] * 3]), np.array([[[0, 0, 1.0]] * 3]),
    ...                     quarter)
    >>> t[0, 0].round(12).tolist()  # ∂P/∂s' = ∂P/∂t = −B = −y
    [0.0, -1.0, 0.0, 1.0]
    """
    t = np.asarray(tangents, np.float64)
    n = np.asarray(normals, np.float64)
    lin = np.asarray(linear, np.float64)
    a, b, d, e = lin[:, 0, 0], lin[:, 0, 1], lin[:, 1, 0], lin[:, 1, 1]
    det = a * e - b * d
    safe = np.where(det != 0.0, det, 1.0)
    m00, m10 = e / safe, d / safe  # first column of [[a, −b], [−d, e]]⁻¹
    bitangent = np.where(t[..., 3:] < 0.0, -1.0, 1.0) * np.cross(n, t[..., :3])
    out = np.zeros_like(t)
    out[..., :3], ok = _unit(m00[:, None, None] * t[..., :3] + m10[:, None, None] * bitangent)
    flip = np.where(det < 0.0, -1.0, 1.0)[:, None]
    given = np.any(t != 0.0, axis=2) & ok & (det != 0.0)[:, None]
    out[..., 3] = np.where(t[..., 3] < 0.0, -1.0, 1.0) * flip
    out[~given] = 0.0
    return out
