"""Compiled per-ray kernels of the intersection stage, used by :mod:`raytrace.analytic` and
:mod:`raytrace.accel`.

In pipeline order: analytic shapes (closest hit with the self-hit rules) → the
float32 rays Embree takes → Embree's hits re-solved in float64 → the surfaces of all hits →
spawned rays' origins; and, at build time, the triangle tables and vertex normals.

Every kernel loops over rays and writes only that ray's rows, so no result depends on the
number of threads or on how a batch is split (tests/test_threads.py). All are serial
``nogil`` kernels (:data:`raytrace.kernels.jit.kernel`): the integrator's threads run them side by
side on batches of their own, beside Embree. Their arguments are the named records of
:mod:`raytrace.kernels.records` and C-contiguous arrays of fixed dtypes (Embree's own float32 /
int32 outputs among them), so each kernel compiles once, into numba's cache. Where a spawned ray
starts is :func:`raytrace.kernels.core.leave1`, shared with the shading kernels.
"""

from __future__ import annotations

import math

import numpy as np

from .core import FLAT
from .jit import helper, inline, kernel
from .kinds import NO_SHAPE
from .material import relief1
from .records import (
    Ray,
)

#: Rounding tolerance of analytic shapes, relative to the coordinates' magnitude.
TOL = 16.0 * float(np.finfo(np.float64).eps)
#: The far limit Embree gets where a ray has none.
F32_MAX = float(np.finfo(np.float32).max)
TINY = float(np.finfo(np.float64).tiny)
F32_TINY = float(np.finfo(np.float32).tiny)
#: A ray whose origin lies this close to a triangle's plane, relative to the coordinates'
#: magnitude (16 float64 ulps), starts on it: it cannot meet that triangle again.
PLANE_TOL = 16.0 * float(np.finfo(np.float64).eps)
#: Spawned rays start 3 float32 ulps (2⁻²³ relative) of their hit point's largest coordinate
#: off a triangle (``raytrace.accel``; docs/robustness.md).
SPAWN_OFFSET = 3.0 * 2.0**-23


# The columns of each kind's row of ``Shapes.rows``: its scene record's ``row`` method names
# the values (``raytrace.scene.Sphere.row``, …), :func:`pack_row` puts them at these columns,
# its intersection and surface functions read them (``sphere_t``, …). A vector takes three
# columns from its first.
#: A sphere: centre c (x, y, z), radius r, c's largest absolute coordinate (its rounding scale).
SPHERE_CENTRE, SPHERE_RADIUS, SPHERE_SCALE = 0, 3, 4
#: A plane: a point p on it (x, y, z), unit normal n (x, y, z), p's largest absolute coordinate.
PLANE_POINT, PLANE_NORMAL, PLANE_SCALE = 0, 3, 6
#: A disk: its plane's row (the centre c as the plane's point) and the radius r.
DISK_CENTRE, DISK_NORMAL, DISK_SCALE, DISK_RADIUS = PLANE_POINT, PLANE_NORMAL, PLANE_SCALE, 7

#: Each shape kind's columns by the names its record's ``row`` gives its values.
SHAPE_COLUMNS = {
    "sphere": {"centre": SPHERE_CENTRE, "radius": SPHERE_RADIUS, "scale": SPHERE_SCALE},
    "plane": {"point": PLANE_POINT, "normal": PLANE_NORMAL, "scale": PLANE_SCALE},
    "disk": {"centre": DISK_CENTRE, "normal": DISK_NORMAL, "scale": DISK_SCALE,
             "radius": DISK_RADIUS},
}


def pack_row(kind: str, values: dict) -> np.ndarray:
    """A ``kind`` shape's row of parameters (float64): each named value of its record's ``row``
    (a number, or a vector over three columns) at its column of :data:`SHAPE_COLUMNS`."""
    columns = SHAPE_COLUMNS[kind]
    packed = {columns[name]: np.atleast_1d(np.asarray(v, np.float64))
              for name, v in values.items()}
    row = np.zeros(max(c + len(v) for c, v in packed.items()))
    for c, v in packed.items():
        row[c:c + len(v)] = v
    return row


# -- analytic shapes ------------------------------------------------------------------------
# A shape kind is an intersection function and a surface function of one row of its
# parameters (``row``, an 8-tuple of floats: what the scene record's ``row`` method packs,
# camera-relative, zero-padded, at the columns of SHAPE_COLUMNS: SPHERE_CENTRE, …),
# registered by a kind code in SHAPE_KINDS and named once in
# each of the two dispatchers, :func:`shape_t` and :func:`shape_surface`. The shape loops
# number the shapes kind by kind, in SHAPE_KINDS' order (spheres, then planes, …), and in the
# scene's order within a kind (:func:`raytrace.tables.shape_tables`).

#: Analytic shape kinds by scene-file type (``raytrace.scene.SHAPE_TYPES``' keys), in the
#: order the shapes are numbered: each is one intersection and one surface function below,
#: named in the dispatchers. Here, beside them, so a shape is its record and this file.
SHAPE_KINDS = {"sphere": 0, "plane": 1, "disk": 2}
SPHERE, PLANE, DISK = SHAPE_KINDS.values()
#: Floats in a shape's row of parameters (``Shapes.rows``: a record's ``row``, zero-padded).
ROW = 8


@helper
def sphere_t(ray, row, extent, on_it, spawned):
    """Ray parameter of the hit of one ray with one sphere (inf on a miss), float64.

    Haines et al. (Ray Tracing Gems, 2019, ch. 7): ``b = d·(o − c)``, the perpendicular offset
    ``f = (o − c) − b·d``, discriminant ``r² − |f|²``, roots ``q = −b − sign(b)·√disc`` and
    ``c/q``. ``ray``: a :class:`raytrace.kernels.records.Ray` (origin o, unit direction d);
    ``row``: the centre, the radius and the centre's largest absolute coordinate (the
    rounding scale) at ``SPHERE_CENTRE``, … (``Sphere.row``); ``on_it``: the ray starts on
    this sphere; ``extent``: the largest absolute coordinate of the origin.
    """
    ox, oy, oz = ray.origin
    dx, dy, dz = ray.direction
    cx, cy, cz = row[SPHERE_CENTRE], row[SPHERE_CENTRE + 1], row[SPHERE_CENTRE + 2]
    r, c_max = row[SPHERE_RADIUS], row[SPHERE_SCALE]
    ocx, ocy, ocz = ox - cx, oy - cy, oz - cz
    b = ocx * dx + ocy * dy + ocz * dz                    # d·(o − c), |d| = 1
    fx, fy, fz = ocx - b * dx, ocy - b * dy, ocz - b * dz
    disc = r * r - (fx * fx + fy * fy + fz * fz)          # r² − |f|² (no cancellation)
    inward = on_it and b < 0
    if not (disc >= 0 or inward):
        return math.inf
    if inward and disc < 0:
        disc = 0.0                                        # it starts on the sphere
    if not disc >= 0:
        return math.inf
    c = (ocx * ocx + ocy * ocy + ocz * ocz) - r * r
    q = -b - math.copysign(math.sqrt(disc), b)
    t1 = c / q
    if math.isnan(t1):
        near = far = math.nan
    else:
        near, far = min(q, t1), max(q, t1)
    t = near if near > 0 else far
    # A ray starting on this sphere (its small root t1 within the rounding of the coordinates)
    # though spawned from another one (touching spheres) is treated like one spawned here:
    # going in, it enters at t = 0; going out, it never hits. A rounding-sized root of either
    # sign would otherwise bounce the ray between the two surfaces until max_depth.
    touching = not on_it and abs(t1) <= TOL * ((extent + c_max) + r)
    enters = touching and b < 0
    if enters:
        t = max(t1, 0.0)
    elif touching:
        t = math.inf
    if inward:
        t = q                                             # from the surface inward: far root
    elif on_it:
        t = math.inf                                      # leaving a convex shape
    if (t > 0 or enters) and math.isfinite(t):
        return t
    return math.inf


@helper
def sphere_surface(row, p):
    """The point ``p`` (a 3-tuple) snapped onto the sphere of ``row``, ``c + r·n``, and its
    unit outward normal ``n``, the normalised radial vector, as a 6-tuple."""
    x, y, z = p
    cx, cy, cz = row[SPHERE_CENTRE], row[SPHERE_CENTRE + 1], row[SPHERE_CENTRE + 2]
    r = row[SPHERE_RADIUS]
    rx, ry, rz = x - cx, y - cy, z - cz
    length = math.sqrt(rx * rx + ry * ry + rz * rz)
    rx, ry, rz = rx / length, ry / length, rz / length
    return cx + r * rx, cy + r * ry, cz + r * rz, rx, ry, rz


@helper
def plane_t(ray, row, extent, on_it, spawned):
    """Ray parameter of the hit of one ray with one plane (inf on a miss): ``(p − o)·n / d·n``.

    ``ray``: a :class:`raytrace.kernels.records.Ray`; ``row``: the plane's point p, unit
    normal n and p's largest absolute coordinate at ``PLANE_POINT``, … (``Plane.row``). A ray
    leaving the plane (``on_it``) never re-hits it. A ray spawned on another analytic shape
    that touches this plane (a sphere resting on it) starts on the plane within rounding: it
    crosses here, at t = 0.
    """
    if on_it:
        return math.inf
    ox, oy, oz = ray.origin
    dx, dy, dz = ray.direction
    px, py, pz = row[PLANE_POINT], row[PLANE_POINT + 1], row[PLANE_POINT + 2]
    nx, ny, nz = row[PLANE_NORMAL], row[PLANE_NORMAL + 1], row[PLANE_NORMAL + 2]
    p_max = row[PLANE_SCALE]
    denom = dx * nx + dy * ny + dz * nz
    dist = (px - ox) * nx + (py - oy) * ny + (pz - oz) * nz
    t = dist / denom
    if spawned and abs(dist) <= TOL * (extent + p_max) and denom != 0:
        t = 0.0
    if (t > 0 or (t == 0 and spawned)) and math.isfinite(t):
        return t
    return math.inf


@helper
def plane_surface(row, p):
    """The point ``p`` moved onto the plane of ``row`` along its normal by its signed
    distance, and the plane's unit normal, as a 6-tuple."""
    x, y, z = p
    px, py, pz = row[PLANE_POINT], row[PLANE_POINT + 1], row[PLANE_POINT + 2]
    nx, ny, nz = row[PLANE_NORMAL], row[PLANE_NORMAL + 1], row[PLANE_NORMAL + 2]
    off = (x - px) * nx + (y - py) * ny + (z - pz) * nz
    return x - off * nx, y - off * ny, z - off * nz, nx, ny, nz


@helper
def disk_t(ray, row, extent, on_it, spawned):
    """Ray parameter of the hit of one ray with one disk (inf on a miss): its plane's hit
    (:func:`plane_t`, with its rules for a ray leaving it or starting on it) where that point
    ``o + t·d`` lies within the radius of the centre, ``|o + t·d − c|² ≤ r²``.

    ``row``: the centre c, the unit normal, c's largest absolute coordinate and the radius r
    at ``DISK_CENTRE``, … (``Disk.row``), a plane's row and the radius.
    """
    t = plane_t(ray, row, extent, on_it, spawned)
    if t == math.inf:
        return t
    r = row[DISK_RADIUS]
    o, d = ray.origin, ray.direction
    qx, qy, qz = (o[0] + t * d[0] - row[DISK_CENTRE], o[1] + t * d[1] - row[DISK_CENTRE + 1],
                  o[2] + t * d[2] - row[DISK_CENTRE + 2])
    if qx * qx + qy * qy + qz * qz <= r * r:
        return t
    return math.inf


@helper
def disk_surface(row, p):
    """The point ``p`` snapped onto the disk of ``row`` and its unit normal, as a 6-tuple:
    its plane's (:func:`plane_surface`; a disk's row begins with its plane's)."""
    return plane_surface(row, p)


@inline
def shape_t(kind, row, ray, extent, on_it, spawned):
    """The one dispatch of the intersections: the ray parameter of shape kind ``kind``
    (SHAPE_KINDS) with parameters ``row`` for the ray ``ray`` (a
    :class:`raytrace.kernels.records.Ray`; inf on a miss); ``on_it``: the ray starts on this
    shape, ``spawned``: on some analytic shape."""
    if kind == SPHERE:
        return sphere_t(ray, row, extent, on_it, spawned)
    if kind == PLANE:
        return plane_t(ray, row, extent, on_it, spawned)
    if kind == DISK:
        return disk_t(ray, row, extent, on_it, spawned)
    return math.inf


@inline
def shape_surface(kind, row, p):
    """The one dispatch of the surfaces: hit point ``p`` snapped onto shape kind ``kind``
    and its unit outward normal, as a 6-tuple (scalars, not array views: a view per ray
    costs reference counting)."""
    if kind == SPHERE:
        return sphere_surface(row, p)
    if kind == DISK:
        return disk_surface(row, p)
    return plane_surface(row, p)


@inline
def shape_row(rows, s):
    """Row ``s`` of the shapes' parameters as an 8-tuple (:data:`ROW`)."""
    return (rows[s, 0], rows[s, 1], rows[s, 2], rows[s, 3], rows[s, 4], rows[s, 5],
            rows[s, 6], rows[s, 7])


@kernel
def closest_analytic(o, d, origin_shape, tmax, has_tmax, shapes, t_out, shape_out):
    """Closest analytic hit of each ray with ``0 < t < tmax`` into ``t_out`` (inf on a miss)
    and ``shape_out`` (NO_SHAPE on a miss).

    ``shapes`` is a :class:`raytrace.kernels.records.Shapes`; ``tmax`` is read only when
    ``has_tmax``. The first shape in the shapes' order wins a tie. See :func:`sphere_t` and
    :func:`plane_t` for the self-hit rules.
    """
    kinds, rows = shapes.kind, shapes.rows
    for i in range(o.shape[0]):
        ox, oy, oz = o[i, 0], o[i, 1], o[i, 2]
        dx, dy, dz = d[i, 0], d[i, 1], d[i, 2]
        ray = Ray(origin=(ox, oy, oz), direction=(dx, dy, dz))
        own = origin_shape[i]
        extent = max(max(abs(ox), abs(oy)), abs(oz))     # scale of the rounding tolerances
        best_t = tmax[i] if has_tmax else math.inf
        best = NO_SHAPE
        own_t = math.inf                                  # where it leaves its own shape
        for s in range(kinds.shape[0]):
            t = shape_t(kinds[s], shape_row(rows, s), ray, extent, own == s, own != NO_SHAPE)
            if own == s:
                own_t = t
            if t < best_t:
                best_t, best = t, s
        # Touching solids: leaving the ray's own sphere where another shape begins (equal t
        # within rounding), the exit comes first, so the contact counts both crossings.
        if best != NO_SHAPE and best != own and own_t <= best_t + TOL * (extent + best_t):
            best_t, best = own_t, own
        t_out[i] = best_t if best != NO_SHAPE else math.inf
        shape_out[i] = best


@kernel
def analytic_surface(shape, point, shapes, point_out, normal_out):
    """Rows with an analytic ``shape``: ``point`` snapped onto the surface into
    ``point_out`` and the unit outward normal into ``normal_out`` (:func:`shape_surface`);
    other rows are left as they are. ``shapes``: a :class:`raytrace.kernels.records.Shapes`."""
    kinds, rows = shapes.kind, shapes.rows
    for i in range(shape.shape[0]):
        s = shape[i]
        if s == NO_SHAPE:
            continue
        (point_out[i, 0], point_out[i, 1], point_out[i, 2], normal_out[i, 0], normal_out[i, 1],
         normal_out[i, 2]) = shape_surface(kinds[s], shape_row(rows, s),
                                           (point[i, 0], point[i, 1], point[i, 2]))


# -- Embree's rays ------------------------------------------------------------------------
@kernel
def embree_rays(query, t, out):
    """The rays of ``query`` (a :class:`raytrace.kernels.records.Query`) as Embree takes them,
    into ``out`` (an :class:`raytrace.kernels.records.EmbreeRays`): float32 origins and
    directions, and ``far`` = the closest analytic hit ``t`` or ``tmax`` (float32 max where
    neither is finite)."""
    o, d, tmax, has_tmax = query.origin, query.direction, query.tmax, query.has_tmax
    o32, d32, far = out.origin, out.direction, out.far
    for i in range(o.shape[0]):
        for k in range(3):
            o32[i, k] = np.float32(o[i, k])
            d32[i, k] = np.float32(d[i, k])
        bound = t[i]
        if has_tmax and tmax[i] < bound:
            bound = tmax[i]
        f = np.float32(bound)
        far[i] = f if math.isfinite(f) else np.float32(F32_MAX)


@kernel
def shadow_prepass(query, shapes, to_embree, blocked, idx, embree):
    """The first half of an occlusion query of the rays of ``query`` (a
    :class:`raytrace.kernels.records.ShadowQuery`): ``blocked[i]`` where an analytic shape
    lies in ``(0, tmax[i])``, found as any hit (the first one ends the search), with
    :func:`closest_analytic`'s self-hit rules, so ``blocked`` is exactly "its closest
    analytic hit is finite". With ``to_embree``, the rays it does not block are written, as
    Embree takes them, into the first rows of ``embree`` (an
    :class:`raytrace.kernels.records.EmbreeRays`: float32 origins and directions, ``far`` =
    ``min(tmax, f32 max)``), and their indices into ``idx``; returns how many.
    One pass where a closest-hit pass, a column of t and a gathering pass were. ``shapes``: a
    :class:`raytrace.kernels.records.Shapes`."""
    o, d, origin_shape, tmax = query.origin, query.direction, query.origin_shape, query.tmax
    o32, d32, far = embree.origin, embree.direction, embree.far
    kinds, rows = shapes.kind, shapes.rows
    k = 0
    for i in range(o.shape[0]):
        ox, oy, oz = o[i, 0], o[i, 1], o[i, 2]
        dx, dy, dz = d[i, 0], d[i, 1], d[i, 2]
        ray = Ray(origin=(ox, oy, oz), direction=(dx, dy, dz))
        own, limit = origin_shape[i], tmax[i]
        extent = max(max(abs(ox), abs(oy)), abs(oz))
        hit = False
        for s in range(kinds.shape[0]):
            if shape_t(kinds[s], shape_row(rows, s), ray, extent, own == s,
                       own != NO_SHAPE) < limit:
                hit = True
                break
        blocked[i] = hit
        if hit or not to_embree:
            continue
        idx[k] = i
        for c in range(3):
            o32[k, c] = np.float32(o[i, c])
            d32[k, c] = np.float32(d[i, c])
        far[k] = np.float32(min(limit, F32_MAX))
        k += 1
    return k


@kernel
def occlusion(idx, embree_result, origin_shape, blocked, recheck):
    """``blocked[idx[j]]``: Embree's OCCLUDED answer (0) for the rays it was asked about.
    The blocked ones that start on a triangle (no analytic ``origin_shape``), where the
    blocker may be a float32 artefact (:func:`refine_hits`), go to ``recheck``; returns how
    many."""
    k = 0
    for j in range(idx.shape[0]):
        i = idx[j]
        hit = embree_result[j] == 0
        blocked[i] = hit
        if hit and origin_shape[i] == NO_SHAPE:
            recheck[k] = i
            k += 1
    return k


# -- Embree's hits ------------------------------------------------------------------------
@kernel
def refine_hits(embree, traced, tables, query, hits, redo):
    """Embree's hits re-solved in float64, written where they come before the analytic hit;
    the hits that float64 shows to be float32 artefacts are set aside for a second pass.
    Returns how many were set aside.

    ``embree``: Embree's answer (an :class:`raytrace.kernels.records.EmbreeHits`), at row j
    for ray ``traced.rows[j]`` of ``query`` started ``traced.adv[j]`` along it (``traced``: a
    :class:`raytrace.kernels.records.Redo`, :func:`retrace_rays`' kept rays; no rows: ray j
    from its origin); ``tables`` a :class:`raytrace.kernels.records.Triangles`; ``query`` a
    :class:`raytrace.kernels.records.Query`; ``hits`` a
    :class:`raytrace.kernels.records.Hits`, updated in place; ``redo`` a
    :class:`raytrace.kernels.records.Redo`, the rays set aside in its first rows.

    Embree's float32 ``u, v`` are off by ~1e-5 (measured), enough to move smooth normals and
    hit points visibly between scales; solving ``o + t·d = a + u·e1 + v·e2`` again on the
    float64 triangle (Möller & Trumbore 1997) makes them exact to ~1e-15. The result is
    clamped onto a smooth or Gouraud triangle, whose barycentrics interpolate normals and
    colours (a float64 solve may land a hair outside an edge Embree hit). A flat triangle
    keeps them unclamped: the point stays where the ray meets its plane, which matters where
    the float32 vertices of a huge triangle move its edges (a ±1e7 floor's diagonal moves
    0.1 units, and clamping moved hit points across it by as much). Rays (nearly) parallel
    to the plane keep Embree's values. ``t`` is then the distance to the hit point rebuilt on
    the triangle's plane, and the hit counts if it is below the analytic hit ``t`` and
    ``tmax``.

    **Artefacts.** Where the float64 solve puts the crossing of the ray's line with the
    triangle's plane at or behind the origin (its ``t ≤ 0``), or the origin lies on that
    plane within the float64 rounding of the coordinates (:data:`PLANE_TOL`), the ray cannot
    meet that triangle: a straight ray leaving a plane never meets it again (a wall hit
    rounded 2e-16 past the ceiling's plane at a room's corner would otherwise shadow
    itself). Embree reported it only
    because its float32 arithmetic puts the origin within the triangle's error band (spawned
    rays start a few ulps of their own hit point off the surface, which can be less than the
    rounding of a large triangle's vertices). Such a ray is written to ``redo`` with ``adv``,
    how far along it the second pass starts: past the triangle's band ``h`` (its float32
    rounding scale, :func:`triangle_tables`), ``2·adv + h/|d·n|``. Embree's answer beyond
    that point is the ray's answer (:meth:`raytrace.accel.Accelerator.intersect`).
    """
    geom_id, prim_id, u32, v32 = embree.geom_id, embree.prim_id, embree.u, embree.v
    rows, adv = traced.rows, traced.adv
    geom_first, corners, face_normal = tables.geom_first, tables.corners, tables.normal
    band, code = tables.band, tables.shading
    o, d, tmax, has_tmax = query.origin, query.direction, query.tmax, query.has_tmax
    t, shape, triangle, uv = hits.t, hits.shape, hits.triangle, hits.uv
    redo_rows, redo_adv = redo.rows, redo.adv
    mapped = rows.shape[0] > 0
    k = 0
    for j in range(geom_id.shape[0]):
        g = geom_id[j]
        if g < 0:
            continue
        i = rows[j] if mapped else j
        tri = geom_first[g] + prim_id[j]
        ax, ay, az = corners[tri, 0, 0], corners[tri, 0, 1], corners[tri, 0, 2]
        bx, by, bz = corners[tri, 1, 0], corners[tri, 1, 1], corners[tri, 1, 2]
        cx, cy, cz = corners[tri, 2, 0], corners[tri, 2, 1], corners[tri, 2, 2]
        ox, oy, oz = o[i, 0], o[i, 1], o[i, 2]
        dx, dy, dz = d[i, 0], d[i, 1], d[i, 2]
        e1x, e1y, e1z = bx - ax, by - ay, bz - az
        e2x, e2y, e2z = cx - ax, cy - ay, cz - az
        px, py, pz = dy * e2z - dz * e2y, dz * e2x - dx * e2z, dx * e2y - dy * e2x  # d × e2
        det = e1x * px + e1y * py + e1z * pz
        sx, sy, sz = ox - ax, oy - ay, oz - az
        qx, qy, qz = sy * e1z - sz * e1y, sz * e1x - sx * e1z, sx * e1y - sy * e1x  # s × e1
        u = (sx * px + sy * py + sz * pz) / det
        v = (dx * qx + dy * qy + dz * qz) / det
        t_plane = (e2x * qx + e2y * qy + e2z * qz) / det
        nx, ny, nz = face_normal[tri, 0], face_normal[tri, 1], face_normal[tri, 2]
        gap = abs(sx * nx + sy * ny + sz * nz)  # the origin's distance from the plane
        scale = (max(max(abs(ox), abs(oy)), abs(oz)) + max(max(abs(ax), abs(ay)), abs(az)))
        if math.isfinite(u) and math.isfinite(v) and det != 0:
            if t_plane <= 0.0 or gap <= PLANE_TOL * scale:  # an artefact: traced on
                cos = abs(dx * nx + dy * ny + dz * nz)
                redo_rows[k] = i
                redo_adv[k] = 2.0 * (adv[j] if mapped else 0.0) + band[tri] / max(cos, TINY)
                k += 1
                continue
            if code[tri] != FLAT:  # smooth, Gouraud: barycentrics interpolate, keep them inside
                u, v = max(u, 0.0), max(v, 0.0)
                total = u + v
                if total > 1.0:
                    u, v = u / total, v / total
        else:
            u, v = np.float64(u32[j]), np.float64(v32[j])
            total = u + v
            if total > 1.0:
                u, v = u / total, v / total
        w = 1.0 - u - v
        tm = ((((w * ax + u * bx) + v * cx) - ox) * dx + (((w * ay + u * by) + v * cy) - oy) * dy
              + (((w * az + u * bz) + v * cz) - oz) * dz)    # (hit point − o)·d
        bound = t[i]
        if has_tmax and tmax[i] < bound:
            bound = tmax[i]
        if tm < bound:
            t[i] = max(tm, TINY)
            shape[i] = NO_SHAPE
            triangle[i] = tri
            uv[i, 0], uv[i, 1] = u, v
    return k


@kernel
def retrace_rays(redo, query, t, out, kept):
    """The second pass's rays as Embree takes them: ray ``redo.rows[j]`` of ``query`` (a
    :class:`raytrace.kernels.records.Query`) restarted ``redo.adv[j]`` along itself
    (``redo``: a :class:`raytrace.kernels.records.Redo`), ``o + adv·d`` in float32, and
    ``far`` = what is left of its bound (the analytic hit ``t`` or ``tmax``) beyond that, into
    ``out`` (an :class:`raytrace.kernels.records.EmbreeRays`). Rays with nothing left are
    dropped; the kept ones' rows and advances go to ``kept`` (a ``Redo``: the next
    :func:`refine_hits`' ``traced``). Returns how many were kept."""
    rows, adv = redo.rows, redo.adv
    o, d, tmax, has_tmax = query.origin, query.direction, query.tmax, query.has_tmax
    o32, d32, far = out.origin, out.direction, out.far
    keep, keep_adv = kept.rows, kept.adv
    k = 0
    for j in range(rows.shape[0]):
        i, a = rows[j], adv[j]
        bound = t[i]
        if has_tmax and tmax[i] < bound:
            bound = tmax[i]
        rest = bound - a
        if not rest > 0.0:
            continue
        for c in range(3):
            o32[k, c] = np.float32(o[i, c] + a * d[i, c])
            d32[k, c] = np.float32(d[i, c])
        far[k] = np.float32(min(rest, F32_MAX))
        keep[k], keep_adv[k] = i, a
        k += 1
    return k


# -- surfaces -------------------------------------------------------------------------------
@kernel
def hit_surfaces(hits, o, d, shapes, tables, reliefs, out):
    """Everything the shading needs at each of ``hits`` (:class:`raytrace.kernels.records.Hits`) of
    rays ``o``, ``d``, written into the point, geometric, shading, material and offset
    columns of ``out`` (:class:`raytrace.kernels.records.Surface`).

    Analytic hits: the point ``o + t·d`` snapped onto the shape (:func:`shape_surface`), its normal
    for both normals, offset 0. Triangle hits: the point at the barycentrics ``uv`` on the
    float64 triangle, its unit face normal, and for smooth and Gouraud triangles the
    interpolated vertex normals, normalised (the face normal where they cancel); the spawn
    offset: the rounding scale of the point itself, :data:`SPAWN_OFFSET` × the hit point's
    largest absolute (camera-relative) coordinate, not of its triangle (a hit next to the
    camera on a floor ±1e5 wide gets an offset of ~1e-6, not 0.036). Where the triangle's
    error band (:func:`triangle_tables`) is at most twice that, the offset is the band itself
    (a small triangle: Embree never reports it again to such a ray). Elsewhere a ray leaving
    the hit may meet its own triangle as a float32 artefact, which the queries discard
    (:func:`refine_hits`). ``shapes``: the :class:`raytrace.kernels.records.Shapes`; ``tables`` the
    :class:`raytrace.kernels.records.Triangles`; ``reliefs``: the
    :class:`raytrace.kernels.records.Reliefs` whose normal and height maps then perturb a
    triangle's shading normal (:func:`raytrace.kernels.material.relief1`), or None (a scene
    without any: none of that code is compiled).
    """
    kinds, rows, shape_material = shapes.kind, shapes.rows, shapes.material
    t, shape, triangle, uv = hits.t, hits.shape, hits.triangle, hits.uv
    point, geometric, shading, material, offset = (out.point, out.geometric, out.shading,
                                                   out.material, out.offset)
    corners, face_normal, vnormals = tables.corners, tables.normal, tables.vnormals
    code, tri_material, band = tables.shading, tables.material, tables.band
    for i in range(t.shape[0]):
        s = shape[i]
        if s != NO_SHAPE:
            px, py, pz, nx, ny, nz = shape_surface(
                kinds[s], shape_row(rows, s), (o[i, 0] + t[i] * d[i, 0],
                                               o[i, 1] + t[i] * d[i, 1], o[i, 2] + t[i] * d[i, 2]))
            point[i, 0], point[i, 1], point[i, 2] = px, py, pz
            geometric[i, 0], geometric[i, 1], geometric[i, 2] = nx, ny, nz
            shading[i, 0], shading[i, 1], shading[i, 2] = nx, ny, nz
            material[i] = shape_material[s]
            offset[i] = 0.0
            continue
        tri = triangle[i]
        u, v = uv[i, 0], uv[i, 1]
        w = 1.0 - u - v
        for k in range(3):
            point[i, k] = (w * corners[tri, 0, k] + u * corners[tri, 1, k]) + v * corners[tri, 2, k]
            geometric[i, k] = face_normal[tri, k]
            shading[i, k] = face_normal[tri, k]
        if code[tri] != FLAT:  # smooth or Gouraud: interpolated vertex normals
            nx = (w * vnormals[tri, 0, 0] + u * vnormals[tri, 1, 0]) + v * vnormals[tri, 2, 0]
            ny = (w * vnormals[tri, 0, 1] + u * vnormals[tri, 1, 1]) + v * vnormals[tri, 2, 1]
            nz = (w * vnormals[tri, 0, 2] + u * vnormals[tri, 1, 2]) + v * vnormals[tri, 2, 2]
            length = math.sqrt(nx * nx + ny * ny + nz * nz)
            if length > 1e-12:
                shading[i, 0], shading[i, 1], shading[i, 2] = (nx / length, ny / length,
                                                               nz / length)
        material[i] = tri_material[tri]
        shading[i, 0], shading[i, 1], shading[i, 2] = relief1(
            reliefs, material[i], tri, u, v, (shading[i, 0], shading[i, 1], shading[i, 2]),
            (face_normal[tri, 0], face_normal[tri, 1], face_normal[tri, 2]))
        own = SPAWN_OFFSET * max(max(max(abs(point[i, 0]), abs(point[i, 1])),
                                     abs(point[i, 2])), F32_TINY)
        offset[i] = band[tri] if band[tri] <= 2.0 * own else own


# -- build ----------------------------------------------------------------------------------
@kernel
def vertex_normals(vertices, faces, out):
    """Unit vertex normals ``N_V = Σ N_k / |Σ N_k|`` (seed 000, Gouraud) into ``out`` (V, 3);
    0 where the face normals cancel. Sums face by face in face order, each face's unit normal
    ``(b − a) × (c − a) / |…|`` added to its corners 0, then 1, then 2."""
    nf = faces.shape[0]
    fn = np.empty((nf, 3))
    for f in range(nf):
        a, b, c = faces[f, 0], faces[f, 1], faces[f, 2]
        e1x, e1y, e1z = (vertices[b, 0] - vertices[a, 0], vertices[b, 1] - vertices[a, 1],
                         vertices[b, 2] - vertices[a, 2])
        e2x, e2y, e2z = (vertices[c, 0] - vertices[a, 0], vertices[c, 1] - vertices[a, 1],
                         vertices[c, 2] - vertices[a, 2])
        x, y, z = e1y * e2z - e1z * e2y, e1z * e2x - e1x * e2z, e1x * e2y - e1y * e2x
        length = math.sqrt(x * x + y * y + z * z)
        fn[f, 0], fn[f, 1], fn[f, 2] = x / length, y / length, z / length
    out[:] = 0.0
    for k in range(3):
        for f in range(nf):
            for j in range(3):
                out[faces[f, k], j] += fn[f, j]
    for i in range(out.shape[0]):
        length = math.sqrt(out[i, 0] * out[i, 0] + out[i, 1] * out[i, 1] + out[i, 2] * out[i, 2])
        for j in range(3):  # cancelling normals: shading falls back to the face's
            out[i, j] = 0.0 if length < 1e-12 else out[i, j] / length


@kernel
def triangle_tables(vertices, faces, vnormal, band_scale, corners, face_normal, vnormals,
                    band):
    """The per-triangle tables of one mesh, written into (F, …) views of the scene's tables:
    float64 ``corners`` (F, 3, 3); unit ``face_normal`` ``(b − a) × (c − a) / |…|``; the
    unit vertex normals ``vnormal`` at the ``vnormals`` corners, the face normal at a vertex
    whose face normals cancel (so Gouraud shading does not go dark there); and the error
    ``band``: ``band_scale`` × the largest absolute float32 coordinate of the corners (at
    least float32's smallest normal number), the distance from the triangle beyond which
    Embree's float32 arithmetic never reports a hit on it for a ray leaving it (measured:
    3 ulps gave 0 self-hits at scales 1e-6…1e6, EMBREEX_NOTES.md)."""
    for f in range(faces.shape[0]):
        extent = 0.0
        for k in range(3):
            for j in range(3):
                x = vertices[faces[f, k], j]
                corners[f, k, j] = x
                extent = max(extent, abs(np.float64(np.float32(x))))
        e1x, e1y, e1z = (corners[f, 1, 0] - corners[f, 0, 0], corners[f, 1, 1] - corners[f, 0, 1],
                         corners[f, 1, 2] - corners[f, 0, 2])
        e2x, e2y, e2z = (corners[f, 2, 0] - corners[f, 0, 0], corners[f, 2, 1] - corners[f, 0, 1],
                         corners[f, 2, 2] - corners[f, 0, 2])
        x, y, z = e1y * e2z - e1z * e2y, e1z * e2x - e1x * e2z, e1x * e2y - e1y * e2x
        length = math.sqrt(x * x + y * y + z * z)
        face_normal[f, 0], face_normal[f, 1], face_normal[f, 2] = x / length, y / length, z / length
        for k in range(3):
            v = faces[f, k]
            cancel = vnormal[v, 0] == 0 and vnormal[v, 1] == 0 and vnormal[v, 2] == 0
            for j in range(3):
                vnormals[f, k, j] = face_normal[f, j] if cancel else vnormal[v, j]
        band[f] = band_scale * max(extent, F32_TINY)

