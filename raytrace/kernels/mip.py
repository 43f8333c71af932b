"""Trilinear (mip-mapped) texture lookups with a ray-cone footprint: the minification filter
of ``texture_filter = "trilinear"`` (``raytrace.mipmap`` builds the tables, a
:class:`raytrace.kernels.records.Mips`).

* :func:`cone_lod1`: the texture-independent part of the level of detail at a hit, by ray
  cones (Akenine-Möller, Nilsson, Andersson, Barré-Brisebois, Toth & Karras, "Texture Level
  of Detail Strategies for Real-Time Ray Tracing", Ray Tracing Gems, ch. 20, 2019, eq. 34,
  with the texture's size split off as in Akenine-Möller et al., "Improved Shader and Texture
  Level of Detail Using Ray Cones", JCGT 10(1), 2021, and Falcor's ``TexLODHelpers``):
  ``λ₀ = Δ + log₂|W| − log₂|n̂·d̂|``, Δ = ½·log₂(t_a/p_a) the triangle's UV-to-world area
  ratio, W the cone's width at the hit, n̂ the face normal, d̂ the ray's direction;
* :func:`trilinear1`: the RGB of texture q at (s, t) and level ``λ = λ₀ + ½·log₂(w·h)``
  (w × h: its level 0), bilinear in each of the two nearest levels of its box-filtered
  pyramid and linear between them (Williams, "Pyramidal Parametrics", SIGGRAPH 1983; pbrt-v4
  ``MIPMap::Filter`` with ``FilterFunction::Trilinear``); λ ≤ 0 is level 0, bilinear
  (:func:`raytrace.kernels.core.texture1`) bit for bit.

Array version for numpy callers and tests: :func:`lod_rows` (λ at given hits).

The cone (a simpler rule than the paper's propagation, docs/shading.md): every hit takes the
cone of a camera ray to it, W = γ·|P| and d̂ = P/|P| with P the hit point relative to the
camera; exact for camera rays, and for a reflected or refracted ray's hit the footprint that
point has seen directly (the paper grows W along the path and widens γ by the curvature).
"""

from __future__ import annotations

import math

from .core import texture1
from .jit import helper, inline, kernel


@helper
def cone_lod1(mips, tri, world):
    """``Δ + log₂(W/|n̂·d̂|)`` at the world point ``world`` (a 3-tuple) of triangle ``tri`` (≥ 0):
    with P = world − camera, W = γ·|P| and |n̂·d̂| = |n̂·P|/|P|, that is
    ``Δ + log₂(γ·|P|²/|n̂·P|)`` (``mips``: a :class:`raytrace.kernels.records.Mips`); +inf
    where the cone grazes the triangle (n̂·P = 0), −inf where it has no UV area."""
    px, py, pz = (world[0] - mips.origin[0], world[1] - mips.origin[1],
                  world[2] - mips.origin[2])
    n = mips.normal
    c = abs(n[tri, 0] * px + n[tri, 1] * py + n[tri, 2] * pz)
    if not c > 0.0:
        return math.inf
    return mips.delta[tri] + math.log2(mips.spread * (px * px + py * py + pz * pz) / c)


@inline
def level1(texels, info, mips, q, level, s, t):
    """The RGB of texture ``q`` at (s, t), bilinear in its mip level ``level``: level 0 from
    the material table's ``texels``/``info``, level l ≥ 1 from ``mips`` (row
    ``first[q] + l − 1`` of its ``levels``)."""
    image, rows, row = ((texels, info, q) if level == 0
                        else (mips.texels, mips.levels, mips.first[q] + level - 1))
    return texture1(image, rows, row, s, t)


@inline
def trilinear1(texels, info, mips, q, s, t, lod):
    """The RGB of texture ``q`` at (s, t) filtered for the footprint ``lod`` (λ₀, from
    :func:`cone_lod1`): level ``λ = λ₀ + ½·log₂(w·h)`` (``mips.size_lod[q]``) clamped to
    [0, L] (L the pyramid's top), ``(1 − f)·level k + f·level k+1`` with k = ⌊λ⌋,
    f = λ − k, each level bilinear (:func:`level1`). λ ≤ 0 (magnified, one texel a pixel or
    less, no UV area: −inf; NaN) is level 0 alone, :func:`raytrace.kernels.core.texture1`
    bit for bit. Inlined in numba's IR: the tables cross no call."""
    lam = lod + mips.size_lod[q]
    top = mips.count[q]
    k, f = 0, 0.0
    if lam >= top:
        k = top
    elif lam > 0.0:
        k = int(math.floor(lam))
        f = lam - k
    r, g, b = level1(texels, info, mips, q, k, s, t)
    if f > 0.0:
        r1, g1, b1 = level1(texels, info, mips, q, k + 1, s, t)
        e = 1.0 - f
        r, g, b = e * r + f * r1, e * g + f * g1, e * b + f * b1
    return r, g, b


@kernel
def lod_rows(mips, q, triangle, world, out):
    """λ of texture ``q`` at each hit: :func:`cone_lod1` of triangle ``triangle[i]`` (n,) at
    the world point ``world[i]`` (n, 3), plus ½·log₂(w·h), into ``out`` (n,) (tests,
    docs/shading.md's worked example)."""
    for i in range(triangle.shape[0]):
        out[i] = cone_lod1(mips, triangle[i], (world[i, 0], world[i, 1], world[i, 2])) + \
            mips.size_lod[q]
