"""Mip-maps for ``texture_filter = "trilinear"``: what the trilinear lookup
(:mod:`raytrace.kernels.mip`) reads besides the textures themselves, built on the host.

* :func:`downsample`: one level of a box-filtered pyramid (Williams 1983; pbrt-v4
  ``MIPMap``): each texel the mean of the 2 × 2 texels below it, a side of odd length n
  halving to ⌈n/2⌉ with its last pair's missing texel taken by the texture's wrap mode;
* :func:`pyramid`: every level above 0, down to 1 × 1;
* :func:`triangle_lods`: each triangle's Δ = ½·log₂(t_a/p_a), the ratio of its area in
  texture space to its area in the world (Akenine-Möller et al., Ray Tracing Gems ch. 20,
  2019, eq. 34; JCGT 10(1) 2021: without the texture's size, which the lookup adds);
* :func:`spread_angle`: the cone's spread per camera sample, γ = arctan(2·tan(ψ/2)/H)
  (Ray Tracing Gems ch. 20, eq. 30; ψ the vertical field of view, H the image height in
  pixels), divided by √spp for ``aa = "uniform"`` (a sample's stratum is 1/√spp of a
  pixel's side);
* :func:`with_mips`: a scene record with its :class:`raytrace.kernels.records.Mips`;
* :func:`with_spread`: a scene record with the spread its box-filtered checkers' footprints
  take (``raytrace.kernels.mip.cone_footprint1``).
"""

from __future__ import annotations

import math
import weakref

import numpy as np

from .kernels.records import (
    CHECKER_FILTER,
    TEX_COLUMNS,
    TEX_HEIGHT,
    TEX_OFFSET,
    TEX_WIDTH,
    TEX_WRAP_S,
    TEX_WRAP_T,
    Mips,
)
from .kernels.records import Scene as SceneRecord
from .readers.texture import WRAPS, Texture
from .scene import Camera, RenderSettings
from .tables import MaterialTable

#: Each texture's pyramid (levels 1 … L), built on its first trilinear render.
_PYRAMIDS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def wrapped(i: np.ndarray, n: int, mode: int) -> np.ndarray:
    """Texel indices ``i`` of a row of ``n`` wrapped as ``raytrace.kernels.core.wrap1``: 0
    repeat, 1 clamp, 2 mirrored repeat."""
    if mode == 1:
        return np.clip(i, 0, n - 1)
    if mode == 2:
        k = i % (2 * n)
        return np.where(k < n, k, 2 * n - 1 - k)
    return i % n


def downsample(texels: np.ndarray, wrap: tuple[int, int]) -> np.ndarray:
    """The next level of ``texels`` (H, W, 4): (⌈H/2⌉, ⌈W/2⌉, 4), texel (j, i) the mean of
    texels (2j, 2i), (2j, 2i + 1), (2j + 1, 2i), (2j + 1, 2i + 1), an index past an odd side
    wrapped by ``wrap`` (the codes along s and t); a side of 1 stays 1 (its texel twice).
    Summed in float64, rounded to float32 once."""
    h, w = texels.shape[:2]
    a = texels.astype(np.float64)
    if w % 2 or h % 2:  # odd sides: the missing texels by the wrap modes
        cols = wrapped(np.arange(2 * ((w + 1) // 2)), w, wrap[0]) if w > 1 else np.zeros(2, int)
        rows = wrapped(np.arange(2 * ((h + 1) // 2)), h, wrap[1]) if h > 1 else np.zeros(2, int)
        a = a[rows][:, cols]
    h2, w2 = a.shape[0] // 2, a.shape[1] // 2
    return (0.25 * a.reshape(h2, 2, w2, 2, 4).sum(axis=(1, 3))).astype(np.float32)


def pyramid(texels: np.ndarray, wrap: tuple[int, int]) -> list[np.ndarray]:
    """Levels 1 … L of ``texels`` (H, W, 4) by :func:`downsample`, the last one 1 × 1
    (L = ⌈log₂ max(H, W)⌉); none for a 1 × 1 texture."""
    levels = []
    while texels.shape[0] > 1 or texels.shape[1] > 1:
        texels = downsample(texels, wrap)
        levels.append(texels)
    return levels


def texture_pyramid(texture: Texture) -> list[np.ndarray]:
    """:func:`pyramid` of ``texture`` (a ``raytrace.readers.texture.Texture``), built once a
    texture and kept while it lives."""
    if texture not in _PYRAMIDS:
        codes = tuple(WRAPS[w] for w in texture.wrap)
        _PYRAMIDS[texture] = pyramid(texture.texels, (codes[0], codes[1]))
    return _PYRAMIDS[texture]


def pyramids(table: MaterialTable) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Every texture's :func:`texture_pyramid` in ``table`` (a
    :class:`raytrace.tables.MaterialTable`), in one table: (texels (N,) float32, levels
    (R, TEX_COLUMNS), first (K,), count (K,)), the fields of
    :class:`raytrace.kernels.records.Mips` of those names."""
    chunks, rows, first, count, offset = [], [], [], [], 0
    for info, texture in zip(table.tex_info, table.textures, strict=True):
        levels = texture_pyramid(texture)
        first.append(len(rows))
        count.append(len(levels))
        for lv in levels:
            row = np.zeros(TEX_COLUMNS, np.int64)
            row[TEX_OFFSET], row[TEX_WIDTH], row[TEX_HEIGHT] = offset, lv.shape[1], lv.shape[0]
            row[TEX_WRAP_S], row[TEX_WRAP_T] = info[TEX_WRAP_S], info[TEX_WRAP_T]
            rows.append(row)
            chunks.append(lv.reshape(-1))
            offset += lv.size
    return (np.concatenate(chunks) if chunks else np.zeros(0, np.float32),
            np.array(rows, np.int64).reshape(-1, TEX_COLUMNS),
            np.array(first, np.int64), np.array(count, np.int64))


def triangle_lods(corners: np.ndarray, texcoords: np.ndarray) -> np.ndarray:
    """Δ = ½·log₂(t_a/p_a) of each triangle: ``corners`` (T, 3, 3) world (or camera-relative)
    positions, ``texcoords`` (T, 3, 2); t_a = |(t₁ − t₀) × (t₂ − t₀)|, p_a =
    |(P₁ − P₀) × (P₂ − P₀)| (twice the areas: the ratio is the areas'). −inf where the
    triangle has no area in texture space."""
    e1, e2 = corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]
    p_a = np.linalg.norm(np.cross(e1, e2), axis=1)
    u1, u2 = texcoords[:, 1] - texcoords[:, 0], texcoords[:, 2] - texcoords[:, 0]
    t_a = np.abs(u1[:, 0] * u2[:, 1] - u1[:, 1] * u2[:, 0])
    with np.errstate(divide="ignore", invalid="ignore"):
        return 0.5 * np.log2(t_a / p_a)


def spread_angle(fov: float, height: int, spp: int, aa: str) -> float:
    """γ, the spread of a camera sample's cone (radians): arctan(2·tan(ψ/2)/H) for the
    vertical field of view ``fov`` (degrees) and ``height`` pixels (Ray Tracing Gems ch. 20,
    eq. 30), over √spp with ``aa = "uniform"`` (spp stratified samples a pixel)."""
    gamma = math.atan(2.0 * math.tan(math.radians(fov) / 2.0) / height)
    return gamma / math.sqrt(spp) if aa == "uniform" else gamma


def point_sampled(options: RenderSettings) -> bool:
    """Whether the render's texture lookups take no footprint: a noise-driven render
    (``aa = "noise"``) counts its samples only as it goes, so no footprint would shrink with
    them, and a footprint-wide blur would stay however long it ran, an error the two streams'
    difference does not see (its estimate of the relative RMSE would no longer hold). So it
    reads box-filtered checkers as plain ones (:func:`with_spread`) and image textures at
    level 0 (:func:`with_mips`; ``raytrace.render`` warns where trilinear was asked for)."""
    return options.aa == "noise"


def with_mips(record: SceneRecord, table: MaterialTable, camera: Camera,
              options: RenderSettings) -> SceneRecord:
    """``record`` (the scene's :class:`raytrace.kernels.records.Scene`) with its ``mips`` where
    ``options.texture_filter`` is "trilinear" and the scene has image textures (``record``
    itself otherwise, so a bilinear render is the same record bit for bit): the pyramids of
    ``table``'s textures (:func:`pyramids`), each triangle's Δ (:func:`triangle_lods`), its
    face normal, the camera's position and the spread (:func:`spread_angle` of ``camera`` and
    ``options``); ``record`` itself where the render is :func:`point_sampled`."""
    if options.texture_filter != "trilinear" or point_sampled(options) \
            or record.texcoords is None:
        return record
    texels, levels, first, count = pyramids(table)
    size_lod = 0.5 * np.log2(table.tex_info[:, TEX_WIDTH] * table.tex_info[:, TEX_HEIGHT])
    tri = record.triangles
    mips = Mips(texels, levels, first, count, size_lod, triangle_lods(tri.corners, tri.texcoords),
                tri.normal, tuple(float(x) for x in record.origin),
                spread_angle(camera.fov, options.height, options.spp, options.aa))
    return record._replace(mips=mips)


def with_spread(record: SceneRecord, table: MaterialTable, camera: Camera,
                options: RenderSettings) -> SceneRecord:
    """``record`` with its ``spread`` (:func:`spread_angle` of ``camera`` and ``options``)
    where some checker of ``table`` is box-filtered (``filter = "box"``); ``record`` itself
    otherwise, spread None, so an unfiltered scene is the same record and compiles no filter
    code; ``record`` itself too where the render is :func:`point_sampled`."""
    if point_sampled(options) or not (table.checkers[:, CHECKER_FILTER] > 0.0).any():
        return record
    return record._replace(spread=spread_angle(camera.fov, options.height, options.spp,
                                               options.aa))
