"""The material at a hit: the one place a kernel looks up a surface's colours and opacity.

Every kernel that needs a hit's colour (the light pass's kd and ks, the hit's ka, ke, kr and
kt, a transparent shadow's kt, the albedo AOV), opacity or texture coordinates (the uv AOV)
asks :func:`surface_color1`, :func:`surface_opacity1` or :func:`surface_texcoords1`, inlined
in numba's IR into the caller (``raytrace.kernels.jit.inline``, so the material's arrays
cross no call), with

* ``palette``: a :class:`raytrace.kernels.records.Palette` (constant colours and checkers),
  :func:`palette1` of the scene;
  ``textures``, ``alphas``: the image and alpha textures' tables (:func:`texture_tables1`,
  :func:`alpha_tables1`, bound once a kernel), or None in a scene without image textures
  or vertex colours, whose kernels then compile no texture code;
* ``hit``: a :class:`raytrace.kernels.records.MaterialHit`, the hit's world point (a checker
  is a function of it), its triangle (−1 off a mesh) and barycentrics (where an image texture
  is read), its camera-relative point and geometric normal (a box-filtered checker's
  footprint).

A colour is its constant, or its checker at the world point (SCENE_FORMAT.md; box-filtered
over the sample's ray-cone footprint with ``filter = "box"``), or, where the
material's colour has an image texture, the texture's bilinear texel at the hit's texture
coordinates (:func:`raytrace.kernels.core.texture1`), read through the texture's mapping
(its uv set and affine transform, :func:`texture_st1`); KA times the material's occlusion
texture and the colours it tints times the vertex colour (:func:`modulate1`); the opacity is the
material's constant t, times the alpha texture's alpha (glTF BLEND) or cut at its cutoff
(MASK). The pieces below the two are used by them alone.

The shading normal at a triangle hit is perturbed by its material's normal or height map
where it has one (:func:`relief1`, called by ``kernels.accel.hit_surfaces``; ``reliefs`` None
in a scene without one, which compiles none of that code).
"""

from __future__ import annotations

import math

from numba.core import types
from numba.extending import overload

from .core import ALPHA, bilinear1, checker1, cross3, texture1
from .jit import helper, inline, kernel
from .kinds import KA, NORMAL_MAP
from .mip import cone_footprint1, cone_lod1, footprint_checker1, trilinear1
from .records import (
    CHECKER_COLOR0,
    CHECKER_COLOR1,
    CHECKER_FILTER,
    CHECKER_SCALE,
    MAP_AFFINE,
    MAP_MATRIX,
    MAP_SET,
    TEX_HEIGHT,
    TEX_WIDTH,
    AlphaTables,
    MaterialHit,
    Palette,
    TextureTables,
)


def _texture_record(scene):
    return TextureTables(
        scene.materials.textured, scene.materials.texture, scene.materials.texels,
        scene.materials.tex_info, scene.texcoords, scene.triangles.texcoords1,
        scene.materials.tex_map, scene.materials.occlusion, scene.materials.tinted,
        scene.triangles.colors, scene.mips)


def _alpha_record(scene):
    return AlphaTables(
        scene.materials.alpha, scene.materials.alpha_cutoff, scene.materials.texels,
        scene.materials.tex_info, scene.texcoords, scene.triangles.texcoords1,
        scene.materials.tex_map)


def texture_tables1(scene):
    """What :func:`surface_color1` reads of image textures, taken once at a kernel's top (each
    array a per-hit helper is handed costs reference counts on every hit), a
    :class:`raytrace.kernels.records.TextureTables` of ``scene`` (a
    :class:`raytrace.kernels.records.Scene`); None where ``scene.texcoords`` is None (a scene
    without image textures or vertex colours), and the lookup's texture code is then not
    compiled. Chosen by type when a kernel compiles (``numba.extending.overload``), so no
    kernel sees an optional value; the same in Python (``raytrace explain``)."""
    return None if scene.texcoords is None else _texture_record(scene)


def alpha_tables1(scene):
    """What :func:`surface_opacity1` reads of alpha textures, taken once at a kernel's top:
    a :class:`raytrace.kernels.records.AlphaTables`; None where ``scene.texcoords`` is None."""
    return None if scene.texcoords is None else _alpha_record(scene)


def _field(record, name):
    """The numba type of field ``name`` of a named-tuple type ``record``."""
    return record.types[record.fields.index(name)]


def _when_textured(record):
    """The overload of a ``*_tables1(scene)``: ``record(scene)``, or None where the scene's
    ``texcoords`` are None (typed so, when a kernel compiles)."""
    def typed(scene):
        if isinstance(_field(scene, "texcoords"), types.NoneType):
            return lambda scene: None
        return record
    return typed


overload(texture_tables1, inline="always")(_when_textured(_texture_record))
overload(alpha_tables1, inline="always")(_when_textured(_alpha_record))


@inline
def surface_color1(palette, textures, m, slot, hit):
    """Colour ``slot`` (:data:`raytrace.kernels.kinds.KA` … ``KE``) of material ``m`` at
    ``hit`` (module docstring): its image texture where it has one (``textures``, from
    :func:`texture_tables1`), else its checker or constant (``palette`` = the materials'
    colours, patterns and checkers); a 3-tuple."""
    x, y, z = hit.world
    color = box_filtered1(palette, m, slot, hit, color1(palette, m, slot, x, y, z))
    return modulate1(textures, m, slot, hit, texel1(textures, m, slot, hit, color))


@inline
def surface_texcoords1(texcoords, hit):
    """The texture coordinates (s, t) at ``hit`` where its triangle has them (a mesh whose file
    gives them), else (0, 0): where an image texture, and the ``uv`` AOV, read."""
    if 0 <= hit.triangle < texcoords.shape[0]:
        return texcoord1(texcoords, hit.triangle, hit.u, hit.v)
    return 0.0, 0.0


@inline
def surface_opacity1(opacity, alphas, m, hit):
    """Opacity t of material ``m`` at ``hit``: its constant, or with an alpha texture
    (``alphas``, from :func:`alpha_tables1`) the texture's alpha there (:func:`opacity1`)."""
    return alpha1(alphas, m, hit, opacity[m])


def texel1(textures, m, slot, hit, other):
    """Colour ``slot`` of material ``m`` at ``hit`` from its image texture where the material
    has one for that slot (:func:`raytrace.kernels.core.texture1` at the hit's texture
    coordinates), else ``other``; ``other`` itself where ``textures`` is None (no code).
    The lookup is bilinear, or trilinear with ``texture_filter = "trilinear"``
    (:func:`filtered1`)."""


@overload(texel1, inline="always")
def _texel1(textures, m, slot, hit, other):
    if isinstance(textures, types.NoneType):
        return lambda textures, m, slot, hit, other: other

    def texel(textures, m, slot, hit, other):
        if not textures.textured[m]:
            return other
        q = textures.texture[m, slot // 3]
        if q < 0:
            return other
        s, t = mapped_st1(textures, q, hit)
        return filtered1(textures, q, s, t, hit)
    return texel


def filtered1(textures, q, s, t, hit):
    """The RGB of texture ``q`` at (s, t): bilinear (:func:`raytrace.kernels.core.texture1`)
    where ``textures.mips`` is None, else trilinear for the ray-cone footprint at ``hit``
    (:func:`raytrace.kernels.mip.trilinear1` at :func:`raytrace.kernels.mip.cone_lod1`; off a
    triangle, level 0). Chosen by type when a kernel compiles."""


@overload(filtered1, inline="always")
def _filtered1(textures, q, s, t, hit):
    if isinstance(textures.types[textures.fields.index("mips")], types.NoneType):
        return lambda textures, q, s, t, hit: texture1(textures.texels, textures.tex_info, q,
                                                       s, t)

    def trilinear(textures, q, s, t, hit):
        lod = cone_lod1(textures.mips, hit.triangle, hit.world) if hit.triangle >= 0 \
            else -math.inf
        return trilinear1(textures.texels, textures.tex_info, textures.mips, q, s, t, lod)
    return trilinear


def modulate1(textures, m, slot, hit, c):
    """Colour ``c`` of slot ``slot`` of material ``m`` at ``hit`` times what varies over a
    surface besides its colour's texture: for KA, the material's occlusion texture where it
    has one (glTF 2.0 §3.9.3: ambient × (1 + strength·(occlusion − 1)), baked into the
    texture's RGB when it is read); for the slots the material's vertex colours tint
    (``textures.tinted``: KA and KD, and a glTF metal's KS and KR), the hit's vertex colour
    (glTF COLOR_0, which multiplies the base colour, :func:`vertex_color1`). ``c`` itself
    where ``textures`` is None, and no vertex-colour code where the scene has none
    (``textures.colors`` None)."""


@overload(modulate1, inline="always")
def _modulate1(textures, m, slot, hit, c):
    if isinstance(textures, types.NoneType) or (
            isinstance(_field(textures, "occlusion"), types.NoneType)
            and isinstance(_field(textures, "colors"), types.NoneType)):
        return lambda textures, m, slot, hit, c: c
    if isinstance(_field(textures, "occlusion"), types.NoneType):
        return lambda textures, m, slot, hit, c: tint1(textures.colors, textures.tinted, m,
                                                       slot, hit, c)

    def modulate(textures, m, slot, hit, c):
        q = textures.occlusion[m]
        if slot == KA and q >= 0:
            s, t = mapped_st1(textures, q, hit)
            o = texture1(textures.texels, textures.tex_info, q, s, t)
            return tint1(textures.colors, textures.tinted, m, slot, hit,
                         (c[0] * o[0], c[1] * o[1], c[2] * o[2]))
        return tint1(textures.colors, textures.tinted, m, slot, hit, c)
    return modulate


def tint1(colors, tinted, m, slot, hit, c):
    """``c`` times the vertex colour at ``hit`` (:func:`vertex_color1`) where material ``m``
    tints ``slot`` (``tinted``); ``c`` itself where ``colors`` is None (no code)."""


@overload(tint1, inline="always")
def _tint1(colors, tinted, m, slot, hit, c):
    if isinstance(colors, types.NoneType):
        return lambda colors, tinted, m, slot, hit, c: c

    def tint(colors, tinted, m, slot, hit, c):
        if not tinted[m, slot // 3]:
            return c
        w = vertex_color1(colors, hit.triangle, hit.u, hit.v)
        return c[0] * w[0], c[1] * w[1], c[2] * w[2]
    return tint


def mapped_st1(tables, q, hit):
    """The coordinates (s, t) at which texture ``q`` is read at ``hit`` (``tables``: a
    :class:`raytrace.kernels.records.TextureTables` or ``AlphaTables``): the first set's
    (:func:`texcoord1`) where no texture has a mapping (``tables.tex_map`` None: no mapping
    code), else :func:`texture_st1`'s."""


@overload(mapped_st1, inline="always")
def _mapped_st1(tables, q, hit):
    if isinstance(_field(tables, "tex_map"), types.NoneType):
        return lambda tables, q, hit: texcoord1(tables.texcoords, hit.triangle, hit.u, hit.v)
    if isinstance(_field(tables, "texcoords1"), types.NoneType):  # no mesh has a second set
        return lambda tables, q, hit: texture_st1(
            (tables.tex_map, tables.texcoords, tables.texcoords), q, hit)
    return lambda tables, q, hit: texture_st1(
        (tables.tex_map, tables.texcoords, tables.texcoords1), q, hit)


@helper
def texture_st1(maps, q, hit):
    """The coordinates (s, t) at which texture ``q`` is read at ``hit`` where some texture
    has a mapping; ``maps`` = (the textures' ``tex_map``, the first set's ``texcoords``, the
    second set's, or the first's where no mesh has a second): its row of ``tex_map``
    (:data:`raytrace.kernels.records.MAP_SET`, …) picks the set and, where it has one, the
    affine map ``(s', t') = (a·s + b·t + c, d·s + e·t + f)`` (glTF KHR_texture_transform's
    T·R·S, MTL ``-o``/``-s``); an identity mapping does no arithmetic."""
    row, texcoords, texcoords1 = maps
    s, t = texcoord1(texcoords1 if row[q, MAP_SET] == 1.0 else texcoords, hit.triangle, hit.u,
                     hit.v)
    if row[q, MAP_AFFINE] == 0.0:
        return s, t
    a = MAP_MATRIX
    return (row[q, a] * s + row[q, a + 1] * t + row[q, a + 2],
            row[q, a + 3] * s + row[q, a + 4] * t + row[q, a + 5])


def alpha1(alphas, m, hit, constant):
    """Opacity of material ``m`` at ``hit``: ``constant`` times its alpha texture's alpha
    there (glTF BLEND), or 1 / 0 by the alpha cutoff (MASK); ``constant`` where it has no alpha
    texture, or ``alphas`` is None (no code)."""


@overload(alpha1, inline="always")
def _alpha1(alphas, m, hit, constant):
    if isinstance(alphas, types.NoneType):
        return lambda alphas, m, hit, constant: constant

    def alpha(alphas, m, hit, constant):
        if alphas.alpha[m] < 0:
            return constant
        return opacity1(constant, (alphas.alpha[m], alphas.alpha_cutoff[m]),
                        (alphas.texels, alphas.tex_info),
                        mapped_st1(alphas, alphas.alpha[m], hit))
    return alpha


@inline
def palette1(scene):
    """What :func:`color1` reads of ``scene`` (a :class:`raytrace.kernels.records.Scene`): a
    :class:`raytrace.kernels.records.Palette` of its materials' colours, patterns and
    checkers and its cone spread."""
    materials = scene.materials
    return Palette(materials.colors, materials.pattern, materials.checkers, scene.spread)


def box_filtered1(palette, m, slot, hit, color):
    """``color``, colour ``slot`` of material ``m`` by :func:`color1`, or where that colour
    is a box-filtered checker (``filter = "box"``) whose footprint at ``hit``
    (:func:`raytrace.kernels.mip.cone_footprint1` of the palette's spread) crosses cell
    boundaries, ``(1 − f)·colour 0 + f·colour 1``, f the share of odd cells in it
    (:func:`raytrace.kernels.mip.footprint_checker1`); where it crosses none, ``color``, the
    parity's colour, bit for bit. ``color`` itself where ``palette.spread`` is None (no
    checker of the scene is filtered): chosen by type when a kernel compiles
    (``numba.extending.overload``), so such a scene compiles none of the filter's code. A
    step of its own, not inside :func:`color1`: a larger :func:`color1` is no longer inlined
    into its callers (docs/shading.md, "Box-filtered checkers")."""
    if palette.spread is None:
        return color
    return _mixed(palette, m, slot, hit, color)


def _mixed(palette, m, slot, hit, color):
    """:func:`box_filtered1` where ``palette.spread`` is a number: which checker, if any, is
    read here (inlined into the caller); the footprint in :func:`box_color1`."""
    p = palette.pattern[m, slot // 3]
    checkers = palette.checkers
    if p < 0 or not checkers[p, CHECKER_FILTER] > 0.0:
        return color
    pair = ((checkers[p, CHECKER_COLOR0], checkers[p, CHECKER_COLOR0 + 1],
             checkers[p, CHECKER_COLOR0 + 2]),
            (checkers[p, CHECKER_COLOR1], checkers[p, CHECKER_COLOR1 + 1],
             checkers[p, CHECKER_COLOR1 + 2]))
    return box_color1(hit, palette.spread, checkers[p, CHECKER_SCALE], pair, color)


@helper
def box_color1(hit, spread, scale, pair, color):
    """The colour of a box-filtered checker of cell size ``scale`` and colours ``pair`` at
    ``hit`` seen by a cone of spread ``spread``: ``(1 − f)·pair[0] + f·pair[1]``, f the
    share of odd cells over the footprint
    (:func:`raytrace.kernels.mip.footprint_checker1` of
    :func:`raytrace.kernels.mip.cone_footprint1`), or ``color`` (the parity's colour)
    where f is 0 or 1. Numbers in, numbers out: a call that takes the palette's arrays pays
    their reference counts on every lookup (docs/shading.md, "Box-filtered checkers")."""
    f = footprint_checker1(hit.world, cone_footprint1(hit.axis, hit.normal, spread), scale)
    if not 0.0 < f < 1.0:
        return color
    e = 1.0 - f
    c0, c1 = pair
    return e * c0[0] + f * c1[0], e * c0[1] + f * c1[1], e * c0[2] + f * c1[2]


@kernel
def box_color_rows(points, view, normal, spread, scale, pair, out):
    """:func:`box_color1` at each world point ``points`` (n, 3), seen at the camera-relative
    point ``view`` (n, 3) on a surface of normal ``normal`` (n, 3), into ``out`` (n, 3),
    which holds each point's parity colour on entry (``raytrace.shading.filtered_checker``,
    tests)."""
    for i in range(points.shape[0]):
        hit = MaterialHit(world=(points[i, 0], points[i, 1], points[i, 2]), triangle=-1,
                          u=0.0, v=0.0, axis=(view[i, 0], view[i, 1], view[i, 2]),
                          normal=(normal[i, 0], normal[i, 1], normal[i, 2]))
        out[i, 0], out[i, 1], out[i, 2] = box_color1(hit, spread, scale, pair,
                                                     (out[i, 0], out[i, 1], out[i, 2]))


def _box_filtered(palette, m, slot, hit, color):
    if isinstance(_field(palette, "spread"), types.NoneType):
        return lambda palette, m, slot, hit, color: color
    return _mixed


overload(box_filtered1, inline="always")(_box_filtered)


@helper
def color1(palette, m, slot, x, y, z):
    """Colour ``slot`` (KA … KE) of material ``m`` at the world point (x, y, z): its constant
    or its checker pattern there, colour 0 or colour 1 by :func:`checker1`'s parity
    (``palette``: a :class:`raytrace.kernels.records.Palette`, the materials' colours,
    patterns and checkers). A box-filtered checker then takes :func:`box_filtered1`, a
    material with an image texture :func:`texel1`."""
    colors, pattern, checkers = palette.colors, palette.pattern, palette.checkers
    p = pattern[m, slot // 3]
    if p < 0:
        return colors[m, slot], colors[m, slot + 1], colors[m, slot + 2]
    c = CHECKER_COLOR1 if checker1(x, y, z, checkers[p, CHECKER_SCALE]) else CHECKER_COLOR0
    return checkers[p, c], checkers[p, c + 1], checkers[p, c + 2]


@helper
def opacity1(constant, cut, image, st):
    """Opacity of a material with an alpha texture at texture coordinates ``st``: its
    ``constant`` times the texture's alpha (glTF BLEND), or 1 / 0 by the alpha cutoff (MASK;
    −1: blend); ``cut`` = (its texture's row of ``image`` = (texels, tex_info), cutoff)."""
    q, cutoff = cut
    texels, tex_info = image
    a = constant * bilinear1(texels, tex_info, q, st[0], st[1], ALPHA)
    if cutoff >= 0.0:
        return 1.0 if a >= cutoff else 0.0
    return a


@helper
def texcoord1(tc, tri, u, v):
    """The texture coordinates (s, t) at barycentrics (u, v) of triangle ``tri``,
    ``(1 − u − v)·st₀ + u·st₁ + v·st₂`` from its corners' ``tc`` (T, 3, 2); (0, 0) off a
    triangle, and on every triangle where no mesh of the scene has texture coordinates
    (``tc`` has no rows: a texture is then read at (0, 0)). Called only for textured
    materials."""
    if tri < 0 or tri >= tc.shape[0]:
        return 0.0, 0.0
    w = 1.0 - u - v
    return (w * tc[tri, 0, 0] + u * tc[tri, 1, 0] + v * tc[tri, 2, 0],
            w * tc[tri, 0, 1] + u * tc[tri, 1, 1] + v * tc[tri, 2, 1])


def relief1(reliefs, m, tri, u, v, n, g):
    """The shading normal (a unit 3-tuple) of material ``m`` at barycentrics (u, v) of
    triangle ``tri``: ``n``, the interpolated one, perturbed by the material's normal map
    (:func:`normal_map1`) or height map (:func:`bump1`) where it has one, turned over where it
    points below the face ``g`` (the rule of file normals, docs/shading.md); ``n`` itself
    off a mesh, without a map, or where ``reliefs`` is None (no code compiled)."""


@overload(relief1, inline="always")
def _relief1(reliefs, m, tri, u, v, n, g):
    if isinstance(reliefs, types.NoneType):
        return lambda reliefs, m, tri, u, v, n, g: n

    def relief(reliefs, m, tri, u, v, n, g):
        q = reliefs.texture[m]
        if tri < 0 or q < 0:
            return n
        st = texcoord1(reliefs.texcoords, tri, u, v)
        image = (reliefs.texels, reliefs.tex_info, q)
        if reliefs.kind[m] == NORMAL_MAP:
            x, y, z = normal_map1(image, st, reliefs.scale[m], reliefs.tangents, (tri, u, v), n)
        else:
            x, y, z = bump1(image, st, reliefs.scale[m], reliefs.corners[tri],
                            reliefs.texcoords[tri], n)
        length = math.sqrt(x * x + y * y + z * z)
        if not length > 1e-300:
            return n
        if x * g[0] + y * g[1] + z * g[2] < 0.0:  # below its face: turned over
            length = -length
        return x / length, y / length, z / length
    return relief


@helper
def normal_map1(image, st, scale, tangents, at, n):
    """A tangent-space normal map's normal, unnormalised (glTF 2.0 §3.9.3): the texel's
    ``n_t = (2·rgb − 1)·(scale, scale, 1)`` (linear texels, bilinear at ``st``) in the frame
    ``n_t.x·T + n_t.y·B + n_t.z·N``, with T the corners' tangents interpolated by the
    barycentrics ``at`` = (tri, u, v) like the normals, w their interpolated sign and
    ``B = w·(N × T)`` (glTF's bitangent; mikktspace.h's pixel-shader rule, T not
    renormalised); ``image`` = (texels, tex_info, texture row), ``n`` the unit normal N."""
    texels, info, q = image
    tri, u, v = at
    r, gr, b = texture1(texels, info, q, st[0], st[1])
    x, y, z = (2.0 * r - 1.0) * scale, (2.0 * gr - 1.0) * scale, 2.0 * b - 1.0
    w0 = 1.0 - u - v
    tx = w0 * tangents[tri, 0, 0] + u * tangents[tri, 1, 0] + v * tangents[tri, 2, 0]
    ty = w0 * tangents[tri, 0, 1] + u * tangents[tri, 1, 1] + v * tangents[tri, 2, 1]
    tz = w0 * tangents[tri, 0, 2] + u * tangents[tri, 1, 2] + v * tangents[tri, 2, 2]
    sign = w0 * tangents[tri, 0, 3] + u * tangents[tri, 1, 3] + v * tangents[tri, 2, 3]
    sign = -1.0 if sign < 0.0 else 1.0
    nx, ny, nz = n
    bx, by, bz = cross3(n, (tx, ty, tz))
    y *= sign  # B = w·(N × T)
    return (x * tx + y * bx + z * nx, x * ty + y * by + z * ny, x * tz + y * bz + z * nz)


@helper
def bump1(image, st, scale, corners, st3, n):
    """A height map's normal, unnormalised (Blinn, "Simulation of wrinkled surfaces",
    SIGGRAPH 1978, eq. for N′): the surface displaced by ``h = scale·H(s, t)`` along N (H the
    texel's mean of R, G, B, linear), so ``N′ = N + σ·(h_t·(P_s × N) + h_s·(N × P_t))/|P_s × P_t|``
    with ``P_s``, ``P_t`` the triangle's ∂P/∂s, ∂P/∂t (from its ``corners`` and their
    texture coordinates ``st3``), σ the sign of ``(P_s × P_t)·N`` (a mirrored mapping), and
    ``h_s``, ``h_t`` central differences one texel apart in texture space; N itself where the
    mapping is degenerate. ``image`` = (texels, tex_info, texture row), ``n`` the unit N."""
    texels, info, q = image
    s, t = st
    ds, dt = 1.0 / info[q, TEX_WIDTH], 1.0 / info[q, TEX_HEIGHT]
    hs = scale * (height1(texels, info, q, s + ds, t) - height1(texels, info, q, s - ds, t)) / (
        2.0 * ds)
    ht = scale * (height1(texels, info, q, s, t + dt) - height1(texels, info, q, s, t - dt)) / (
        2.0 * dt)
    e1s, e1t = st3[1, 0] - st3[0, 0], st3[1, 1] - st3[0, 1]
    e2s, e2t = st3[2, 0] - st3[0, 0], st3[2, 1] - st3[0, 1]
    det = e1s * e2t - e2s * e1t
    nx, ny, nz = n
    if det == 0.0:
        return nx, ny, nz
    ax, ay, az = corners[1, 0] - corners[0, 0], corners[1, 1] - corners[0, 1], corners[1, 2] - \
        corners[0, 2]
    bx, by, bz = corners[2, 0] - corners[0, 0], corners[2, 1] - corners[0, 1], corners[2, 2] - \
        corners[0, 2]
    ps = ((e2t * ax - e1t * bx) / det, (e2t * ay - e1t * by) / det, (e2t * az - e1t * bz) / det)
    pt = ((e1s * bx - e2s * ax) / det, (e1s * by - e2s * ay) / det, (e1s * bz - e2s * az) / det)
    cx, cy, cz = cross3(ps, pt)
    area = math.sqrt(cx * cx + cy * cy + cz * cz)
    if not area > 0.0:
        return nx, ny, nz
    f = (1.0 if cx * nx + cy * ny + cz * nz >= 0.0 else -1.0) / area
    ax, ay, az = cross3(ps, n)  # h_t·(P_s × N) + h_s·(N × P_t)
    bx, by, bz = cross3(n, pt)
    return (nx + f * (ht * ax + hs * bx), ny + f * (ht * ay + hs * by),
            nz + f * (ht * az + hs * bz))


@helper
def height1(texels, info, q, s, t):
    """A height map's value at (s, t): the mean of its bilinear R, G and B (grey maps have
    the three equal)."""
    r, g, b = texture1(texels, info, q, s, t)
    return (r + g + b) / 3.0


@helper
def vertex_color1(colors, tri, u, v):
    """The RGB vertex colour at barycentrics (u, v) of triangle ``tri``,
    ``(1 − u − v)·c₀ + u·c₁ + v·c₂`` from its corners' ``colors`` (T, 3, 4) (as
    :func:`texcoord1`); white off a triangle."""
    if tri < 0 or tri >= colors.shape[0]:
        return 1.0, 1.0, 1.0
    w = 1.0 - u - v
    return (w * colors[tri, 0, 0] + u * colors[tri, 1, 0] + v * colors[tri, 2, 0],
            w * colors[tri, 0, 1] + u * colors[tri, 1, 1] + v * colors[tri, 2, 1],
            w * colors[tri, 0, 2] + u * colors[tri, 1, 2] + v * colors[tri, 2, 2])
