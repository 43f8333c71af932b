"""Compiled per-ray arithmetic of the shading stage, used by :mod:`raytrace.integrator` and
behind the array functions of :mod:`raytrace.optics` and :mod:`raytrace.shading`.

Two layers, in pipeline order:

* **one ray at a time**, a function per formula, on scalars: ``incidence1`` (a light's L,
  distance and ``f_radial·f_angular``, seed 000, and KHR_lights_punctual's cone and range),
  ``cosine_power1`` / ``phong1`` / ``blinn1`` / ``blinn_cosine1`` / ``direct1`` (the seeds'
  local model, Phong 1975, Blinn 1977; glTF's lobe with its cosine), ``bulge1``,
  ``gouraud1`` and ``fast_phong1`` (Bishop & Weimer 1986); the primitives they share with the
  other kernel modules (reflection, refraction, the spawn rule, the checker, the hashes) are
  :mod:`raytrace.kernels.core`'s, a hit's material :mod:`raytrace.kernels.material`'s;
* **one batch at a time**, the passes the integrator makes over its hits, each composed of the
  functions above: ``light_pass`` (one emitter's unshadowed term at every hit, Gouraud's
  included, and the shadow rays of the hits it lights), ``add_unblocked`` (opaque shadows),
  ``crossing_rays``, ``cross_surfaces`` (the walk of transparent shadows) and ``add_light``,
  ``hit_terms`` (what each hit adds to its sample; its reflected, refracted and see-through
  children's directions, weights and pruning status), ``count_keep`` and
  ``spawn_children`` (the next depth's batch from those); plus ``accumulate``, the
  fixed-order sum of the background into the pixel samples of the rays that miss.

All are serial ``nogil`` kernels (``raytrace.kernels.jit.kernel``): the integrator's threads
run them side by side, each on the batches of its own pass, and ``hit_terms`` and ``accumulate`` add
into a pixel sample in batch order, one fixed order, so no result depends on the number of
threads. Arguments are the named records of :mod:`raytrace.kernels.records` and C-contiguous
arrays of fixed dtypes, so each kernel compiles once, into numba's cache (which
:mod:`raytrace.kernels.jit` keeps true when :mod:`raytrace.kernels.core` changes).
"""

from __future__ import annotations

import math

import numpy as np

from .core import (
    FAST_PHONG,
    FLAT,
    GOURAUD,
    NO_FRESNEL,
    SHADOW_SHORTEN,
    facing1,
    fresnel_weights1,
    is_whole1,
    leave1,
    light_uniform,
    reflect3,
    refract3,
    taylor1,
    whole_power1,
)
from .jit import helper, kernel
from .kinds import (  # noqa: F401  (the codes, as this module's names)
    BLINN,
    BLINN_COSINE,
    DIRECTIONAL,
    KA,
    KD,
    KE,
    KEEP,
    KR,
    KS,
    KT,
    NONE,
    PHONG,
    POINT,
    PRUNED,
    SMOOTH_SPOT,
    SPOT,
)
from .material import (
    alpha_tables1,
    palette1,
    surface_color1,
    surface_opacity1,
    texture_tables1,
)
from .medium import arriving1, crossing1, thin_walled1
from .records import (
    FAST_DIFFUSE,
    FAST_SPECULAR,
    Finish,
    MaterialHit,
    MeshHit,
    SmoothTriangles,
    SpawnPoint,
)


# -- lights -----------------------------------------------------------------------------------
@kernel
def incidence1(p, em, word):
    """Unit vector to the light, distance and attenuation ``f_radial·f_angular`` at a point.

    ``p`` is the point (a 3-tuple), ``em`` a :class:`raytrace.kernels.records.Emitter`. A jittered
    area-light cell (stream ≥ 0), cell (i, j) of k × k, is sampled at
    ``position + (ξ_u − ½)·u + (ξ_v − ½)·v`` with ``ξ_u = frac(w₁ + j/k)``,
    ``ξ_v = frac(w₂ + i/k)`` and (w₁, w₂) = :func:`raytrace.kernels.core.light_uniform` of ``word``,
    the hit's :func:`raytrace.kernels.core.light_word` for the light, shared by its cells: a
    Cranley–Patterson rotation (1976) of the canonical multi-jittered pattern of Chiu,
    Shirley & Wang ("Multi-jittered sampling", Graphics Gems IV, 1994). Each hit puts one
    point in every cell (the k × k strata) and one in each of the k² columns and rows of the
    whole rectangle (n-rooks), each point uniform in its cell; points of their own for each
    shading point (the word hashes its camera sample, for a secondary ray hashed with its
    path, :func:`raytrace.kernels.core.path_key1`, and depth); with ``word`` < 0, at the cell
    centre. Seed 000:
    ``f_radial = 1/(a0 + a1·d + a2·d²)`` (0 where that is not finite, and at the light itself,
    where L is undefined; L stays a unit vector however near or far the light); a spot
    multiplies ``(cos α)^a`` inside its cone (``cos α >= cos θ``, edge included) and 0
    outside; a smooth spot (KHR_lights_punctual, "Inner and Outer Cone Angles", the spec's
    recommended implementation) multiplies ``t²``, ``t = clamp((cos α − cos θ_outer) /
    max(0.001, cos θ_inner − cos θ_outer), 0, 1)``. An emitter with a ``range`` r > 0 also
    multiplies the spec's window ``max(min(1 − (d/r)⁴, 1), 0)`` (KHR_lights_punctual, "Range
    Property"). A directional light has L = −direction, d = ∞, f = 1.
    """
    px, py, pz = p
    if em.kind == DIRECTIONAL:
        return -em.dx, -em.dy, -em.dz, math.inf, 1.0
    sx, sy, sz = em.px, em.py, em.pz
    if em.stream >= 0.0 and word >= 0:
        w1, w2 = light_uniform(word)
        u, v = w1 + em.ou, w2 + em.ov
        u, v = (u - 1.5 if u >= 1.0 else u - 0.5), (v - 1.5 if v >= 1.0 else v - 0.5)
        sx, sy, sz = (sx + u * em.ux + v * em.vx, sy + u * em.uy + v * em.vy,
                      sz + u * em.uz + v * em.vz)
    lx, ly, lz = sx - px, sy - py, sz - pz
    if lx == 0.0 and ly == 0.0 and lz == 0.0:
        return lx, ly, lz, 0.0, 0.0
    square = lx * lx + ly * ly + lz * lz
    if not 1e-290 < square < 1e290:  # |L|² under- or overflows: scale it first
        big = max(max(abs(lx), abs(ly)), abs(lz))
        lx, ly, lz = lx / big, ly / big, lz / big
        unit = math.sqrt(lx * lx + ly * ly + lz * lz)
        dist = big * unit
        lx, ly, lz = lx / unit, ly / unit, lz / unit
    else:
        dist = math.sqrt(square)
        lx, ly, lz = lx / dist, ly / dist, lz / dist
    f = 1.0 / (em.a0 + dist * (em.a1 + em.a2 * dist))
    if not math.isfinite(f):
        f = 0.0
    if em.kind == SPOT:
        cos_a = -(lx * em.dx + ly * em.dy + lz * em.dz)  # light-to-point against the axis
        f = f * (max(cos_a, 0.0) ** em.exponent if cos_a >= em.cos_cutoff else 0.0)
    elif em.kind == SMOOTH_SPOT:
        cos_a = -(lx * em.dx + ly * em.dy + lz * em.dz)
        t = (cos_a - em.cos_cutoff) / max(em.cos_inner - em.cos_cutoff, 0.001)
        t = min(max(t, 0.0), 1.0)
        f = f * (t * t)
    if em.range > 0.0:
        q = dist / em.range
        f = f * min(max(1.0 - (q * q) * (q * q), 0.0), 1.0)
    return lx, ly, lz, dist, f


# -- highlights and the local model -----------------------------------------------------------
@helper
def cosine_power1(a, b, n):
    """``max(a·b, 0)^n`` for unit vectors as ``exp(n·log1p(−h))`` with ``h = 1 − a·b`` taken
    as ``|a − b|²/2`` (no cancellation near a·b = 1, so n = 1e8 still falls off right);
    0 where ``a·b <= 0`` (0^0 counts as 0), 1 where n = 0 otherwise. ``a``, ``b``: 3-tuples.
    A whole n up to 65 536 (shininess 20, 80, 200) takes ``(1 − h)ⁿ`` by squaring instead
    (:func:`raytrace.kernels.core.whole_power1`, within (2n − 1)·2⁻⁵³ relative, the exp/log1p form
    within about (|n·log1p(−h)| + 1)·2⁻⁵²): the same value to 1.5e-11 without the two
    library calls (docs/robustness.md, "Precision budget")."""
    ax, ay, az = a
    bx, by, bz = b
    ex, ey, ez = ax - bx, ay - by, az - bz
    h = 0.5 * (ex * ex + ey * ey + ez * ez)
    # h < 1 alone lets a·b = 0 through where |a − b|² rounds just below 2 (0^0 would give 1).
    if not (h < 1.0 and ax * bx + ay * by + az * bz > 0.0):
        return 0.0
    if n == 0.0:
        return 1.0
    if is_whole1(n):  # (1 − h)ⁿ by squaring, within (2n − 1)·2⁻⁵³: the precision budget
        return whole_power1(1.0 - h, n)
    return math.exp(n * math.log1p(-h))


@helper
def phong1(normal, light, view, n):
    """Phong's ``(V·R)^n``, ``R = 2(N·L)N − L`` normalised (Phong 1975); N, L, V unit
    3-tuples."""
    nx, ny, nz = normal
    lx, ly, lz = light
    k = 2.0 * (nx * lx + ny * ly + nz * lz)
    rx, ry, rz = k * nx - lx, k * ny - ly, k * nz - lz
    length = max(math.sqrt(rx * rx + ry * ry + rz * rz), 1e-300)
    return cosine_power1(view, (rx / length, ry / length, rz / length), n)


@helper
def blinn1(normal, light, view, n):
    """Blinn's ``(N·H)^n``, ``H = (L + V)/|L + V|`` (Blinn 1977); 0 where L = −V. N, L, V
    unit 3-tuples."""
    lx, ly, lz = light
    vx, vy, vz = view
    hx, hy, hz = lx + vx, ly + vy, lz + vz
    length = math.sqrt(hx * hx + hy * hy + hz * hz)
    if not length > 1e-12:
        return 0.0
    return cosine_power1(normal, (hx / length, hy / length, hz / length), n)


@helper
def blinn_cosine1(normal, light, view, n):
    """Blinn's lobe weighted by the reflectance equation's cosine, ``(N·H)^n·max(N·L, 0)``
    (Akenine-Möller et al., Real-Time Rendering, 4th ed., §9.3: every BRDF lobe is weighted by
    N·L), the highlight glTF materials map to: at n = 0 a Lambertian term, not a constant
    one. N, L, V unit 3-tuples."""
    nx, ny, nz = normal
    lx, ly, lz = light
    cos_l = nx * lx + ny * ly + nz * lz
    return blinn1(normal, light, view, n) * cos_l if cos_l > 0.0 else 0.0


@helper
def highlight1(model, normal, light, view, n):
    """The highlight ``spec`` of model code ``model`` (PHONG, BLINN or BLINN_COSINE)."""
    if model == BLINN:
        return blinn1(normal, light, view, n)
    if model == BLINN_COSINE:
        return blinn_cosine1(normal, light, view, n)
    return phong1(normal, light, view, n)


@helper
def direct1(normal, light, view, finish):
    """``kd·max(N·L, 0) + ks·spec`` per channel for the colours ``kd``, ``ks`` of ``finish``
    (a :class:`raytrace.kernels.records.Finish`, with the highlight's model and exponent n);
    N, L, V unit 3-tuples; all zero where ``N·L <= 0`` (the highlight too, whatever the
    exponent)."""
    nx, ny, nz = normal
    lx, ly, lz = light
    kd, ks = finish.kd, finish.ks
    ndl = nx * lx + ny * ly + nz * lz
    if not ndl > 0.0:
        return 0.0, 0.0, 0.0
    if ks[0] == 0.0 and ks[1] == 0.0 and ks[2] == 0.0:  # no highlight: skip its exp and log
        return kd[0] * ndl, kd[1] * ndl, kd[2] * ndl
    spec = highlight1(finish.highlight, normal, light, view, finish.shininess)
    return kd[0] * ndl + ks[0] * spec, kd[1] * ndl + ks[1] * spec, kd[2] * ndl + ks[2] * spec


# -- surfaces ---------------------------------------------------------------------------------
# -- batch kernels of the integrator ----------------------------------------------------------
@kernel
def bulge1(p, hit, smooth):
    """Hanika's shading point for a ray leaving a smooth-shaded triangle ("Hacking the Shadow
    Terminator", Ray Tracing Gems II, 2021, ch. 4): ``P' = Σ_k b_k·P_k`` with ``P_k`` the hit
    point ``P`` lifted onto the tangent plane of vertex k where it lies below it, ``P_k = P −
    min(0, (P − V_k)·n_k)·n_k``, for barycentrics ``b = (1 − u − v, u, v)`` and the vertex
    normals turned to ``side`` (+1 outward, −1 inward). On a convex patch P' rises to about
    the smooth surface the normals describe, so a shadow ray near the terminator does not
    start inside the neighbouring facets; where P is above every tangent plane (concave), P'
    = P. ``p`` is a 3-tuple; ``hit`` a :class:`raytrace.kernels.records.MeshHit` (triangle
    ``tri``, u, v, side); ``smooth`` a :class:`raytrace.kernels.records.SmoothTriangles`."""
    px, py, pz = p
    tri, u, v, side = hit.triangle, hit.u, hit.v, hit.side
    corners, vnormals = smooth.corners, smooth.vnormals
    w = 1.0 - u - v
    dx = dy = dz = 0.0  # Σ_k b_k·(P_k − P): exactly P where nothing lifts
    for k in range(3):
        b = w if k == 0 else (u if k == 1 else v)
        nx, ny, nz = side * vnormals[tri, k, 0], side * vnormals[tri, k, 1], side * vnormals[
            tri, k, 2]
        lift = min(0.0, (px - corners[tri, k, 0]) * nx + (py - corners[tri, k, 1]) * ny
                   + (pz - corners[tri, k, 2]) * nz)
        dx -= b * lift * nx
        dy -= b * lift * ny
        dz -= b * lift * nz
    return px + dx, py + dy, pz + dz


@helper
def gouraud1(hit, eye, smooth, em, word, finish):
    """Seed 000's Gouraud shading at a hit on triangle ``tri`` (barycentrics ``1 − (u + v)``,
    ``u``, ``v``): the unshadowed ``f·[kd·max(N·L, 0) + ks·spec]`` of one emitter ``em``
    evaluated at the three corners, with their vertex normals turned by ``s`` (+1 outward,
    −1 inward) and V towards the ``eye`` (a 3-tuple), then interpolated; ``hit`` = a
    :class:`raytrace.kernels.records.MeshHit` (tri, u, v, side s). Every corner sees a
    jittered area light at the one point drawn for this hit (its ``word``,
    :func:`incidence1`): the point its shadow ray aims at. ``finish``: the material at the
    hit (:class:`raytrace.kernels.records.Finish`); ``smooth``: a
    :class:`raytrace.kernels.records.SmoothTriangles`."""
    tri, u, v, s = hit.triangle, hit.u, hit.v, hit.side
    ex, ey, ez = eye
    corners, vnormals = smooth.corners, smooth.vnormals
    r = g = b = 0.0
    for k in range(3):
        w = 1.0 - (u + v) if k == 0 else (u if k == 1 else v)
        px, py, pz = corners[tri, k, 0], corners[tri, k, 1], corners[tri, k, 2]
        nx, ny, nz = vnormals[tri, k, 0] * s, vnormals[tri, k, 1] * s, vnormals[tri, k, 2] * s
        vx, vy, vz = ex - px, ey - py, ez - pz
        length = max(math.sqrt(vx * vx + vy * vy + vz * vz), 1e-300)
        vx, vy, vz = vx / length, vy / length, vz / length
        lx, ly, lz, _, f = incidence1((px, py, pz), em, word)
        dr, dg, db = direct1((nx, ny, nz), (lx, ly, lz), (vx, vy, vz), finish)
        r += w * dr * f
        g += w * dg * f
        b += w * db * f
    return r, g, b


@helper
def fast_phong1(table, hit, finish):
    """Bishop & Weimer's fast Phong shading (1986) at barycentrics (u, v) of triangle ``tri``
    seen from side ``s`` (``hit``: a :class:`raytrace.kernels.records.MeshHit`):
    ``kd·D + ks·max(S, 0)ⁿ`` with D and S the diffuse and specular Taylor polynomials of row
    ``tri`` of ``table`` (columns ``FAST_DIFFUSE`` and ``FAST_SPECULAR``;
    :mod:`raytrace.fast_phong`, :func:`raytrace.kernels.core.taylor1`) in place of ``N̂·L``
    and ``N̂·H`` (``finish.highlight`` BLINN; BLINN_COSINE also times D) or ``V·R`` (PHONG);
    all zero where ``D <= 0``,
    as :func:`direct1`. The side turns N: it negates D and ``N̂·H``, and ``V·R`` is even in
    N. ``finish``: a :class:`raytrace.kernels.records.Finish`."""
    tri, u, v, s = hit.triangle, hit.u, hit.v, hit.side
    kd, ks, n, model = finish.kd, finish.ks, finish.shininess, finish.highlight
    ndl = s * taylor1(table, tri, FAST_DIFFUSE, u, v)
    if not ndl > 0.0:
        return 0.0, 0.0, 0.0
    if ks[0] == 0.0 and ks[1] == 0.0 and ks[2] == 0.0:
        return kd[0] * ndl, kd[1] * ndl, kd[2] * ndl
    cos = taylor1(table, tri, FAST_SPECULAR, u, v) * (1.0 if model == PHONG else s)
    spec = 0.0
    if cos > 0.0:  # as cosine_power1: 0 where the cosine is not positive, 1 for n = 0
        spec = 1.0 if n == 0.0 else math.exp(n * math.log(min(cos, 1.0)))
    if model == BLINN_COSINE:
        spec = spec * ndl
    return kd[0] * ndl + ks[0] * spec, kd[1] * ndl + ks[1] * spec, kd[2] * ndl + ks[2] * spec


@kernel
def light_pass(rays, surf, scene, em, words, depth, term, shadow):
    """One emitter ``em`` (a :class:`raytrace.kernels.records.Emitter`) at every hit of ``rays`` on
    ``surf`` (:class:`raytrace.kernels.records.Rays`, :class:`raytrace.kernels.records.Surface`),
    in one pass:
    its unshadowed term and the shadow rays that must decide it. Returns k, the number of
    shadow rays.

    ``term = f·[kd·max(N·L, 0) + ks·spec]`` (n, 3) with N the shading normal turned to the
    viewer and V = −d (a Gouraud triangle's, :func:`gouraud1`, is interpolated from its
    corners, V towards the ray's origin; a fast-Phong triangle's, :func:`fast_phong1`, is
    its Taylor polynomials where ``scene.fast`` has this light's table and the rays are camera
    rays, ``depth`` 0, else exact); 0 for unlit materials. Only hits where some channel
    of term is > 0 need a shadow ray: the first k rows of ``shadow`` (a
    :class:`raytrace.kernels.records.Shadows`) hold them, in hit order. A shadow ray leaves the hit
    towards the light (:func:`leave1`) and stops :data:`raytrace.kernels.core.SHADOW_SHORTEN`
    (relative) short of it; from a smooth or Gouraud triangle it goes from :func:`bulge1`'s
    lifted point P′ (on the side the viewer sees) to the same point of the light the shading
    used (SCENE_FORMAT.md's smooth-mesh rule 2; Blender Cycles aims from P′ as well).
    ``words`` (n,): each hit's :func:`raytrace.kernels.core.light_word` for this emitter's light,
    read only for a jittered emitter (:func:`incidence1`). ``depth``: the rays' depth, or
    None in a scene without triangles and image textures: numba then prunes their branches
    (``if depth is not None``) before typing, so such a scene compiles and loads a kernel
    without Gouraud, fast Phong, Hanika's lift or texture lookups (the same arithmetic on
    every hit it has)."""
    direction, eye = rays.direction, rays.origin
    point, geometric, shading, material = surf.point, surf.geometric, surf.shading, surf.material
    materials, triangles, origin = scene.materials, scene.triangles, scene.origin
    palette = palette1(scene)
    # None: no texture code compiled; scene.mips: trilinear lookups (kernels.mip)
    textures = texture_tables1(scene)
    code = triangles.shading
    smooth_tables = SmoothTriangles(triangles.corners, triangles.vnormals)
    rows, s_origin, s_direction = shadow.rows, shadow.origin, shadow.direction
    s_tmax, s_shape = shadow.tmax, shadow.shape
    jittered = em.stream >= 0.0 and words.shape[0] > 0
    shininess, highlight, lit = materials.shininess, materials.highlight, materials.lit
    keep = 1.0 - SHADOW_SHORTEN
    # a directional light, seen from the camera (depth None: no triangles, no textures, and
    # none of the code under `depth is not None` is compiled)
    fast = depth is not None and scene.fast.shape[0] > 0 and depth == 0
    k = 0
    for i in range(point.shape[0]):
        m = material[i]
        if not lit[m]:
            term[i, 0] = term[i, 1] = term[i, 2] = 0.0
            continue
        dx, dy, dz = direction[i, 0], direction[i, 1], direction[i, 2]
        gx, gy, gz = geometric[i, 0], geometric[i, 1], geometric[i, 2]
        s = facing1(gx, gy, gz, dx, dy, dz)
        px, py, pz = point[i, 0], point[i, 1], point[i, 2]
        word = words[i] if jittered else -1
        lx, ly, lz, d, f = incidence1((px, py, pz), em, word)
        wx, wy, wz = px + origin[0], py + origin[1], pz + origin[2]
        tri = surf.triangle[i]
        u, v = surf.uv[i, 0], surf.uv[i, 1]
        at = MaterialHit(world=(wx, wy, wz), triangle=tri, u=u, v=v, axis=(px, py, pz),
                         normal=(gx, gy, gz))
        finish = Finish(kd=surface_color1(palette, textures, m, KD, at),
                        ks=surface_color1(palette, textures, m, KS, at),
                        shininess=shininess[m], highlight=highlight[m])
        on_mesh = MeshHit(triangle=tri, u=u, v=v, side=s)
        smooth = tri >= 0 and code[tri] != FLAT
        if depth is not None and smooth and code[tri] == GOURAUD:
            r, g, b = gouraud1(on_mesh, (eye[i, 0], eye[i, 1], eye[i, 2]), smooth_tables, em,
                               word, finish)
        elif depth is not None and fast and smooth and code[tri] == FAST_PHONG:  # f = 1
            r, g, b = fast_phong1(scene.fast, on_mesh, finish)
        else:
            normal = (shading[i, 0] * s, shading[i, 1] * s, shading[i, 2] * s)
            r, g, b = direct1(normal, (lx, ly, lz), (-dx, -dy, -dz), finish)
            r, g, b = r * f, g * f, b * f
        term[i, 0], term[i, 1], term[i, 2] = r, g, b
        if not (r > 0.0 or g > 0.0 or b > 0.0):
            continue
        if depth is not None and smooth:  # from Hanika's lifted P′ to the light's same point
            qx, qy, qz = bulge1((px, py, pz), on_mesh, smooth_tables)
            if math.isfinite(d) and (qx != px or qy != py or qz != pz):
                lx, ly, lz = px + d * lx - qx, py + d * ly - qy, pz + d * lz - qz
                d = math.sqrt(lx * lx + ly * ly + lz * lz)
                lx, ly, lz = lx / d, ly / d, lz / d
            px, py, pz = qx, qy, qz
        s_origin[k, 0], s_origin[k, 1], s_origin[k, 2] = leave1(
            SpawnPoint(point=(px, py, pz), geometric=(gx, gy, gz), offset=surf.offset[i]),
            (lx, ly, lz))
        s_direction[k, 0], s_direction[k, 1], s_direction[k, 2] = lx, ly, lz
        s_tmax[k] = d * keep
        s_shape[k] = surf.shape[i]
        rows[k] = i
        k += 1
    return k


@kernel
def add_light(out, rows, term, shadow, color):
    """``out[rows[j]] += term[rows[j]]·S[j]·I_l``: the emitter's share where the shadow
    factor S (k, 3) lets it through (rows are distinct)."""
    for j in range(rows.shape[0]):
        i = rows[j]
        for c in range(3):
            out[i, c] += term[i, c] * shadow[j, c] * color[c]


@kernel
def add_unblocked(out, rows, term, blocked, color):
    """``out[rows[j]] += term[rows[j]]·I_l`` where shadow ray j is not ``blocked`` (opaque
    scenes: S is 0 or 1, and ``x·1`` is exact)."""
    for j in range(rows.shape[0]):
        if blocked[j]:
            continue
        i = rows[j]
        for c in range(3):
            out[i, c] += term[i, c] * color[c]


@kernel
def crossing_rays(hits, origin, direction, tmax, live):
    """The walking shadow rays that hit a surface before the light (finite ``t``), in row
    order: their hits (``t``, ``shape``, ``triangle``, ``uv``), ``origin``, ``direction``,
    ``tmax`` and ``live`` (the row of the shadow factor each one multiplies), as a tuple of
    new arrays (one pass for what was eight numpy gathers). ``hits``: a
    :class:`raytrace.kernels.records.Hits`."""
    t, shape, triangle, uv = hits.t, hits.shape, hits.triangle, hits.uv
    n = 0
    for i in range(t.shape[0]):
        if math.isfinite(t[i]):
            n += 1
    t_out, shape_out, triangle_out = np.empty(n), np.empty(n, np.int64), np.empty(n, np.int64)
    uv_out, origin_out, direction_out = np.empty((n, 2)), np.empty((n, 3)), np.empty((n, 3))
    tmax_out, live_out = np.empty(n), np.empty(n, np.int64)
    j = 0
    for i in range(t.shape[0]):
        if not math.isfinite(t[i]):
            continue
        t_out[j], shape_out[j], triangle_out[j] = t[i], shape[i], triangle[i]
        uv_out[j, 0], uv_out[j, 1] = uv[i, 0], uv[i, 1]
        for c in range(3):
            origin_out[j, c], direction_out[j, c] = origin[i, c], direction[i, c]
        tmax_out[j], live_out[j] = tmax[i], live[i]
        j += 1
    return t_out, shape_out, triangle_out, uv_out, origin_out, direction_out, tmax_out, live_out


@kernel
def cross_surfaces(factor, live, surf, walk, scene):
    """Transparent shadow rays ``walk`` (a :class:`raytrace.kernels.records.ShadowWalk`)
    crossing the surfaces they hit (``surf``, a :class:`raytrace.kernels.records.Surface`):
    ``S *= t·kt + (1 − t)`` (seed 003, t the opacity) on row ``live[j]`` of ``factor``, and
    where the ray leaves an absorbing material, by Beer's law over the segment it crossed
    inside (:func:`raytrace.kernels.medium.crossing1`: no code in a scene without media). Those
    that still let some channel through go on from the far side (:func:`leave1` along their
    ``direction``) for the rest of their ``tmax`` (minus the hit's ``t``): returns their
    (origin, direction, start shape, tmax, live) as new arrays. A scene without image
    textures (``scene.texcoords`` None) compiles it without the texture lookups."""
    direction, t, tmax = walk.direction, walk.t, walk.tmax
    material, point, geometric = surf.material, surf.point, surf.geometric
    origin, materials = scene.origin, scene.materials
    palette = palette1(scene)
    opacity = materials.opacity
    # None without image textures: the lookup's texture code is then not compiled
    textures = texture_tables1(scene)
    alphas = alpha_tables1(scene)
    n, on = live.shape[0], 0
    through = np.empty(n, np.bool_)
    for j in range(n):
        mj = material[j]
        hit = MaterialHit(world=(point[j, 0] + origin[0], point[j, 1] + origin[1],
                                 point[j, 2] + origin[2]),
                          triangle=surf.triangle[j], u=surf.uv[j, 0], v=surf.uv[j, 1],
                          axis=(point[j, 0], point[j, 1], point[j, 2]),
                          normal=(geometric[j, 0], geometric[j, 1], geometric[j, 2]))
        kt = surface_color1(palette, textures, mj, KT, hit)
        op = surface_opacity1(opacity, alphas, mj, hit)
        r = live[j]
        beer = crossing1(scene.media, mj, walk, surf, j)  # (1, 1, 1) in a scene without media
        for c in range(3):
            factor[r, c] *= op * kt[c] + (1.0 - op)
            factor[r, c] *= beer[c]
        through[j] = factor[r, 0] > 0.0 or factor[r, 1] > 0.0 or factor[r, 2] > 0.0
        on += through[j]
    origin_out, direction_out = np.empty((on, 3)), np.empty((on, 3))
    shape_out, tmax_out, live_out = np.empty(on, np.int64), np.empty(on), np.empty(on, np.int64)
    k = 0
    for j in range(n):
        if not through[j]:
            continue
        dx, dy, dz = direction[j, 0], direction[j, 1], direction[j, 2]
        at = SpawnPoint(point=(point[j, 0], point[j, 1], point[j, 2]),
                        geometric=(geometric[j, 0], geometric[j, 1], geometric[j, 2]),
                        offset=surf.offset[j])
        origin_out[k, 0], origin_out[k, 1], origin_out[k, 2] = leave1(at, (dx, dy, dz))
        direction_out[k, 0], direction_out[k, 1], direction_out[k, 2] = dx, dy, dz
        shape_out[k], tmax_out[k], live_out[k] = surf.shape[j], tmax[j] - t[j], live[j]
        k += 1
    return origin_out, direction_out, shape_out, tmax_out, live_out


@kernel
def hit_terms(rays, surf, scene, local, min_weight, into, children):
    """What every hit of ``rays`` on ``surf`` adds to its sample and the children it spawns
    (Whitted 1980; seed 003's opacity blend), with t the opacity and N_s, N_g the shading and
    geometric normals turned to the viewer:

    * ``w·t·(ka·Ia + lights)`` added to row ``into.row[i]`` of ``into.sums`` (``into``: a
      :class:`raytrace.kernels.records.SampleSums`), one hit after another in batch order (as
      :func:`accumulate` adds); ``local`` (a :class:`raytrace.kernels.records.Local`) holds Ia
      and ``lights`` (n, 3), Σ_l S_l·f_l·I_l·[…], which has no rows in a scene without lights;
    * reflected: ``reflect(d, N_s)`` with weight ``w·t·kr``; where the interpolated normal
      sends it into the surface (``r·N_g <= 0``) it is mirrored about N_g instead;
    * refracted: ``refract(d, N_s, η)`` with η = 1/ior entering (``d·N_g < 0`` for the outward
      normal), ior leaving, weight ``w·t·kt``; TIR sends the kt share along the mirror
      direction; where the direction lands on the wrong side of the face (a refracted ray
      not crossing it, a TIR ray crossing it) it is refracted about N_g instead;
    * see-through: straight on with weight ``w·(1 − t)``.

    A ray that leaves a material with an absorbing interior reaches its hit with ``w`` times
    Beer's ``exp(−σ·t)`` over the distance t it travelled inside, before any term of the hit
    (:func:`raytrace.kernels.medium.arriving1`); on a thin-walled material the refracted ray
    goes straight on (``d``) and Fresnel takes the hit as entering from either side. With
    ``scene.media`` None (no such material) none of that code is compiled.

    Under TIR the kt share and the reflection leave along the same mirror direction from the
    same point: the two rays would trace the same path. With ``min_weight`` 0, where there is
    a reflected child and the directions are equal (bit for bit), they become one reflected
    ray of weight ``w·t·(kr + kt)``, so a glass scene does not trace its trapped light twice.
    That is exact: the recursion is linear in a child's weight, both children have the same
    depth, and with no weight pruning only ``max_depth``, which treats them alike, stops a
    path. With ``min_weight`` > 0 they stay two rays, the reflected one (``w·t·kr``) and the
    TIR one (``w·t·kt``, refracted column, along the mirror direction), each kept or pruned by
    its own path weight as the contract says: a merged ray would be pruned by the sum.

    A scene without image textures (``scene.texcoords`` None) compiles this kernel without
    the material lookup's texture code (which, compiled, costs every hit the reference counts
    of the texture tables it is handed).

    ``children`` None: a scene none of whose materials reflects, transmits or is see-through
    (no hit has a child); numba prunes the children's code (``if children is None``) before
    typing, so such a scene compiles and loads a kernel without reflection, refraction or
    Fresnel (the same additions into the samples).

    The children's directions, weights, status and TIR flags are written into ``children``
    (a :class:`raytrace.kernels.records.Children`): ``status`` (n, 3), columns reflected, refracted,
    see-through: NONE where the material has no such child or its weight is 0, PRUNED where
    its largest channel is under ``min_weight`` (Hall & Greenberg 1983), else KEEP. ``tir`` is
    set on transmitting hits only.
    """
    direction = rays.direction
    geometric, shading, material, point = surf.geometric, surf.shading, surf.material, surf.point
    origin, materials = scene.origin, scene.materials
    palette = palette1(scene)
    opacity = materials.opacity
    # None without image textures: the lookup's texture code is then not compiled
    textures = texture_tables1(scene)
    alphas = alpha_tables1(scene)
    ambient, lights = local.ambient, local.lights
    samples, sample = into.sums, into.row
    if children is not None:
        r_dir, t_dir, w_r, w_t, w_s = (children.r_dir, children.t_dir, children.w_r,
                                       children.w_t, children.w_s)
        status, tir = children.status, children.tir
    ior = materials.ior
    reflects, transmits = materials.reflects, materials.transmits
    emits, fresnel = materials.emits, materials.fresnel
    lit = lights.shape[0] > 0
    media = scene.media  # None: no absorption or thin-wall code compiled
    for i in range(direction.shape[0]):
        m = material[i]
        w = arriving1(media, m, rays, surf, i)  # Beer's law inside the material it leaves
        hit = MaterialHit(world=(point[i, 0] + origin[0], point[i, 1] + origin[1],
                                 point[i, 2] + origin[2]),
                          triangle=surf.triangle[i], u=surf.uv[i, 0], v=surf.uv[i, 1],
                          axis=(point[i, 0], point[i, 1], point[i, 2]),
                          normal=(geometric[i, 0], geometric[i, 1], geometric[i, 2]))
        op = surface_opacity1(opacity, alphas, m, hit)
        ka = surface_color1(palette, textures, m, KA, hit)
        ke = surface_color1(palette, textures, m, KE, hit) if emits[m] else (0.0, 0.0, 0.0)
        for c in range(3):
            here = ambient[c] * ka[c]
            if lit:
                here += lights[i, c]
            if emits[m]:
                here += ke[c]
            samples[sample[i], c] += w[c] * (op * here)
        if children is None:  # compiled only for scenes with reflective or transparent ones
            continue
        status[i, 0] = status[i, 1] = status[i, 2] = NONE
        tir[i] = False
        dx, dy, dz = direction[i, 0], direction[i, 1], direction[i, 2]
        gx, gy, gz = geometric[i, 0], geometric[i, 1], geometric[i, 2]
        s = facing1(gx, gy, gz, dx, dy, dz)
        nx, ny, nz = shading[i, 0] * s, shading[i, 1] * s, shading[i, 2] * s
        fx, fy, fz = gx * s, gy * s, gz * s
        kr, kt = (0.0, 0.0, 0.0), (0.0, 0.0, 0.0)
        if reflects[m]:
            kr = surface_color1(palette, textures, m, KR, hit)
        if transmits[m]:
            kt = surface_color1(palette, textures, m, KT, hit)
        if fresnel[m] != NO_FRESNEL:  # kr, kt for this angle (V = −d, N facing the viewer)
            entering = dx * gx + dy * gy + dz * gz < 0.0 or thin_walled1(media, m)
            kr, kt = fresnel_weights1(fresnel[m], -(dx * nx + dy * ny + dz * nz),
                                      1.0 / ior[m] if entering else ior[m], kr, kt)
        if reflects[m]:
            rx, ry, rz = reflect3(dx, dy, dz, nx, ny, nz)
            if rx * fx + ry * fy + rz * fz <= 0.0:
                rx, ry, rz = reflect3(dx, dy, dz, fx, fy, fz)
            r_dir[i, 0], r_dir[i, 1], r_dir[i, 2] = rx, ry, rz
            for c in range(3):
                w_r[i, c] = w[c] * op * kr[c]
            status[i, 0] = _status((w_r[i, 0], w_r[i, 1], w_r[i, 2]), min_weight)
        if transmits[m]:
            eta = 1.0 / ior[m] if dx * gx + dy * gy + dz * gz < 0.0 else ior[m]
            if thin_walled1(media, m):  # a thin wall: straight through, no TIR
                tx, ty, tz, total = dx, dy, dz, False
            else:
                tx, ty, tz, total = refract3(dx, dy, dz, nx, ny, nz, eta)
                side = tx * fx + ty * fy + tz * fz
                if (side <= 0.0) if total else (side >= 0.0):
                    tx, ty, tz, total = refract3(dx, dy, dz, fx, fy, fz, eta)
            t_dir[i, 0], t_dir[i, 1], t_dir[i, 2] = tx, ty, tz
            tir[i] = total
            for c in range(3):
                w_t[i, c] = w[c] * op * kt[c]
            if (total and not min_weight > 0.0 and reflects[m] and status[i, 0] != NONE
                    and tx == r_dir[i, 0] and ty == r_dir[i, 1]
                    and tz == r_dir[i, 2]):  # one path, one ray (no weight pruning)
                for c in range(3):
                    w_r[i, c] = w[c] * op * (kr[c] + kt[c])
                    w_t[i, c] = 0.0
                status[i, 0] = _status((w_r[i, 0], w_r[i, 1], w_r[i, 2]), min_weight)
            status[i, 1] = _status((w_t[i, 0], w_t[i, 1], w_t[i, 2]), min_weight)
        if op < 1.0:
            for c in range(3):
                w_s[i, c] = w[c] * (1.0 - op)
            status[i, 2] = _status((w_s[i, 0], w_s[i, 1], w_s[i, 2]), min_weight)


@helper
def _status(w, min_weight):
    """NONE, PRUNED or KEEP for a child of weight ``w`` (3,) (its largest channel, NaN
    propagating like numpy's max). ``w`` is a tuple: a row of an array would cost a
    reference count per call."""
    big = w[0]
    for c in (1, 2):
        if not (big >= w[c] or big != big):
            big = w[c]
    if not big > 0.0:
        return NONE
    return PRUNED if big < min_weight else KEEP


@kernel
def count_keep(status):
    """How many rows of ``status`` (n, 3) are KEEP, per column (3,)."""
    count = np.zeros(3, np.int64)
    for i in range(status.shape[0]):
        for c in range(3):
            if status[i, c] == KEEP:
                count[c] += 1
    return count


@kernel
def spawn_children(children, parents, surf, first, kinds, out):
    """The children of a batch of hits: every child whose ``status`` (n, 3) is KEEP, column
    c's (reflected, refracted, see-through: directions ``r_dir``, ``t_dir`` and the parent's
    own, weights ``w_r``, ``w_t``, ``w_s`` of ``children``, a
    :class:`raytrace.kernels.records.Children`; kind ``kinds[c]``) in hit order from row
    ``first[c]``
    of ``out`` (a :class:`raytrace.kernels.records.Spawned`) on; the integrator sets ``first`` from
    :func:`count_keep`'s prefix sums, so the batch is allocated once, all reflected children
    first. Writes origin (:func:`leave1` from the hit of ``surf`` along the child's
    direction), direction, weight, sample (the parent's, of ``parents``, a
    :class:`raytrace.kernels.records.Rays`), start shape, kind and the row of each child's parent
    hit."""
    r_dir, t_dir, w_r, w_t, w_s, status = (children.r_dir, children.t_dir, children.w_r,
                                           children.w_t, children.w_s, children.status)
    s_dir, sample = parents.direction, parents.sample
    point, geometric, offset, shape = surf.point, surf.geometric, surf.offset, surf.shape
    origin, direction, weight = out.origin, out.direction, out.weight
    child_sample, child_shape, kind, parent = out.sample, out.shape, out.kind, out.parent
    for c in range(3):
        d = r_dir if c == 0 else (t_dir if c == 1 else s_dir)
        w = w_r if c == 0 else (w_t if c == 1 else w_s)
        j = first[c]
        for i in range(status.shape[0]):
            if status[i, c] != KEEP:
                continue
            dx, dy, dz = d[i, 0], d[i, 1], d[i, 2]
            direction[j, 0], direction[j, 1], direction[j, 2] = dx, dy, dz
            weight[j, 0], weight[j, 1], weight[j, 2] = w[i, 0], w[i, 1], w[i, 2]
            at = SpawnPoint(point=(point[i, 0], point[i, 1], point[i, 2]),
                            geometric=(geometric[i, 0], geometric[i, 1], geometric[i, 2]),
                            offset=offset[i])
            origin[j, 0], origin[j, 1], origin[j, 2] = leave1(at, (dx, dy, dz))
            child_sample[j], child_shape[j], kind[j] = sample[i], shape[i], kinds[c]
            parent[j] = i
            j += 1


@kernel
def accumulate(samples, sample, weight, factor, rows):
    """``samples[sample[r]] += weight[r]·factor[r]`` for r in ``rows``, one after another in
    the order of ``rows`` (``factor`` of one row applies to all). The order of the additions
    is the batch's, so the sums depend on nothing but how the pass is cut into batches, never
    on the threads."""
    one = factor.shape[0] == 1
    for j in range(rows.shape[0]):
        r = rows[j]
        s = sample[r]
        f = 0 if one else r
        for c in range(3):
            samples[s, c] += weight[r, c] * factor[f, c]


# -- array versions of the per-ray functions (the public numpy-facing API) -----------------------
@kernel
def reflect_rows(d, n, out):
    for i in range(d.shape[0]):
        out[i, 0], out[i, 1], out[i, 2] = reflect3(d[i, 0], d[i, 1], d[i, 2], n[i, 0], n[i, 1],
                                                   n[i, 2])


@kernel
def refract_rows(d, n, eta, out, tir):
    for i in range(d.shape[0]):
        out[i, 0], out[i, 1], out[i, 2], tir[i] = refract3(d[i, 0], d[i, 1], d[i, 2], n[i, 0],
                                                           n[i, 1], n[i, 2], eta[i])


@kernel
def incidence_rows(points, em, words, to_light, dist, factor):
    """:func:`incidence1` at each point; ``words`` (n,) the :func:`raytrace.kernels.core.light_word`
    of each (or no rows: the cell centre)."""
    keyed = words.shape[0] > 0
    for i in range(points.shape[0]):
        lx, ly, lz, dist[i], factor[i] = incidence1((points[i, 0], points[i, 1], points[i, 2]),
                                                    em, words[i] if keyed else -1)
        to_light[i, 0], to_light[i, 1], to_light[i, 2] = lx, ly, lz


@kernel
def cosine_power_rows(a, b, n, out):
    for i in range(a.shape[0]):
        out[i] = cosine_power1((a[i, 0], a[i, 1], a[i, 2]), (b[i, 0], b[i, 1], b[i, 2]), n[i])


@kernel
def highlight_rows(model, normal, to_light, to_eye, n, out):
    for i in range(normal.shape[0]):
        out[i] = highlight1(model, (normal[i, 0], normal[i, 1], normal[i, 2]),
                            (to_light[i, 0], to_light[i, 1], to_light[i, 2]),
                            (to_eye[i, 0], to_eye[i, 1], to_eye[i, 2]), n[i])


@kernel
def direct_rows(normal, to_light, to_eye, kd, ks, n, model, out):
    for i in range(normal.shape[0]):
        finish = Finish(kd=(kd[i, 0], kd[i, 1], kd[i, 2]), ks=(ks[i, 0], ks[i, 1], ks[i, 2]),
                        shininess=n[i], highlight=model[i])
        out[i, 0], out[i, 1], out[i, 2] = direct1(
            (normal[i, 0], normal[i, 1], normal[i, 2]),
            (to_light[i, 0], to_light[i, 1], to_light[i, 2]),
            (to_eye[i, 0], to_eye[i, 1], to_eye[i, 2]), finish)
