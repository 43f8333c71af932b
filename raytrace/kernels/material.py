"""The material at a hit: the one place a kernel looks up a surface's colours and opacity.

Every kernel that needs a hit's colour (the light pass's kd and ks, the hit's ka, ke, kr and
kt, a transparent shadow's kt, the albedo AOV) and opacity asks :func:`surface_color1` and
:func:`surface_opacity1`, inlined in numba's IR into the caller (``raytrace.kernels.jit.inline``,
so the material's arrays cross no call), with

* ``materials``: the :class:`raytrace.kernels.records.Materials` record; ``texcoords``: the
  triangles' per-corner texture coordinates (T, 3, 2), or None in a kernel variant compiled
  for a scene without image textures (numba prunes the texture code before typing; a separate
  argument, not a tuple's element, for that);
* ``hit``: a :class:`raytrace.kernels.records.MaterialHit`, the hit's world point (a checker
  is a function of it), its triangle (−1 off a mesh) and barycentrics (where an image texture
  is read).

A colour is its constant, or its checker at the world point (SCENE_FORMAT.md), or, where the
material's colour has an image texture, the texture's bilinear texel at the hit's texture
coordinates (:func:`raytrace.kernels.core.texture1`); the opacity is the material's constant t,
times the alpha texture's alpha (glTF BLEND) or cut at its cutoff (MASK). The pieces below the
two are used by them alone.
"""

from __future__ import annotations

from .core import ALPHA, bilinear1, checker1, texture1
from .jit import inline, kernel
from .records import CHECKER_COLOR0, CHECKER_COLOR1, CHECKER_SCALE, Palette


@inline
def surface_color1(materials, texcoords, m, slot, hit):
    """Colour ``slot`` (:data:`raytrace.kernels.kinds.KA` … ``KE``) of material ``m`` at
    ``hit`` (module docstring): its image texture where it has one, else its checker or
    constant (a 3-tuple)."""
    x, y, z = hit.world
    c = color1(Palette(materials.colors, materials.pattern, materials.checkers), m, slot, x,
               y, z)
    if texcoords is not None and materials.textured[m]:
        c = texel1(materials, m, slot, texcoord1(texcoords, hit.triangle, hit.u, hit.v), c)
    return c


@inline
def surface_opacity1(materials, texcoords, m, hit):
    """Opacity t of material ``m`` at ``hit``: its constant, or with an alpha texture
    (:func:`opacity1`) the texture's alpha there."""
    if texcoords is not None and materials.alpha[m] >= 0:
        return opacity1(materials, m, texcoord1(texcoords, hit.triangle, hit.u, hit.v))
    return materials.opacity[m]


@kernel
def color1(palette, m, slot, x, y, z):
    """Colour ``slot`` (KA … KE) of material ``m`` at the world point (x, y, z): its constant
    or its checker pattern there, colour 0 or colour 1 by :func:`checker1`'s parity
    (``palette``: a :class:`raytrace.kernels.records.Palette`, the materials' colours,
    patterns and checkers). A material with an image texture then takes :func:`texel1`
    instead."""
    colors, pattern, checkers = palette.colors, palette.pattern, palette.checkers
    p = pattern[m, slot // 3]
    if p < 0:
        return colors[m, slot], colors[m, slot + 1], colors[m, slot + 2]
    c = CHECKER_COLOR1 if checker1(x, y, z, checkers[p, CHECKER_SCALE]) else CHECKER_COLOR0
    return checkers[p, c], checkers[p, c + 1], checkers[p, c + 2]


@kernel
def texel1(materials, m, slot, st, other):
    """Colour ``slot`` of a textured material ``m`` at texture coordinates ``st``: its image
    texture (:func:`raytrace.kernels.core.texture1`) where that colour has one, else ``other``.
    Called
    only for materials with ``textured[m]``, so scenes without textures never pay for it (a
    per-hit helper that takes arrays costs reference counts on every call)."""
    q = materials.texture[m, slot // 3]
    if q < 0:
        return other
    return texture1(materials.texels, materials.tex_info, q, st[0], st[1])


@kernel
def opacity1(materials, m, st):
    """Opacity t of a material ``m`` with an alpha texture (``materials.alpha[m] >= 0``) at
    texture coordinates ``st``: its constant times the texture's alpha (glTF BLEND), or 1 / 0
    by the alpha cutoff (MASK). Others take ``materials.opacity[m]`` without this call."""
    a = materials.opacity[m] * bilinear1(materials.texels, materials.tex_info,
                                         materials.alpha[m], st[0], st[1], ALPHA)
    cutoff = materials.alpha_cutoff[m]
    if cutoff >= 0.0:
        return 1.0 if a >= cutoff else 0.0
    return a


@kernel
def texcoord1(tc, tri, u, v):
    """The texture coordinates (s, t) at barycentrics (u, v) of triangle ``tri``,
    ``(1 − u − v)·st₀ + u·st₁ + v·st₂`` from its corners' ``tc`` (T, 3, 2); (0, 0) off a
    triangle. Called only for textured materials."""
    if tri < 0:
        return 0.0, 0.0
    w = 1.0 - u - v
    return (w * tc[tri, 0, 0] + u * tc[tri, 1, 0] + v * tc[tri, 2, 0],
            w * tc[tri, 0, 1] + u * tc[tri, 1, 1] + v * tc[tri, 2, 1])
