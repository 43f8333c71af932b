"""Compiled AOVs (:mod:`raytrace.film.aov`): what each camera ray first hit, per sample, and each
pixel's value from its samples.

The AOVs asked for share one float64 table per pass, a row per camera sample: column
``AOV_DISTANCE`` (0) holds the distance t of the sample's hit (+inf on a miss), which picks a
pixel's nearest sample; each AOV has the columns :class:`raytrace.kernels.records.AOVLayout`
gives it. An AOV is a kind code of
:data:`AOV_KINDS` and its branch in :func:`aov_value1`; :mod:`raytrace.film.aov` names its
channels, its miss value and how a pixel's samples combine.
"""

from __future__ import annotations

import numpy as np

from .core import facing1
from .jit import inline, kernel
from .kinds import KD
from .material import palette1, surface_color1, surface_texcoords1, texture_tables1
from .records import (
    AOV_COMBINE,
    AOV_COUNT,
    AOV_DISTANCE,
    AOV_FIRST,
    AOV_KIND,
    FirstHits,
    MaterialHit,
)

#: The AOVs' kernel codes, by their name in :data:`raytrace.film.aov.AOVS`.
AOV_KINDS = {"depth": 0, "normal": 1, "albedo": 2, "id": 3, "uv": 4, "position": 5}
DEPTH, NORMAL, ALBEDO, ID, UV, POSITION = AOV_KINDS.values()
#: A pixel's value of an AOV (``AOVLayout.table``'s ``combine``): its nearest sample's, or
#: the mean of its samples.
NEAREST, MEAN = 0, 1


@inline
def aov_value1(kind, i, hits, scene, objects, out, row, col):
    """Write AOV ``kind``'s value at hit ``i`` into ``out[row, col …]``: the distance t
    (``depth``), the shading normal turned to face the ray (``normal``, as the shading uses it:
    :func:`facing1`), kd at the hit (``albedo``, the material lookup), the object's index in
    the scene (``id``: an analytic shape's ``shape_object``, a triangle's mesh the last
    ``geom_first`` at or before it, ``geom_object`` of that), the hit's texture coordinates
    (``uv``: a mesh's (s, t) where its file gives them, else (0, 0), as Blender's UV pass)
    or its world point (``position``). ``hits``: the camera rays' first hits (a
    :class:`raytrace.kernels.records.FirstHits`); ``scene``: a
    :class:`raytrace.kernels.records.Scene`, ``objects`` an
    :class:`raytrace.kernels.records.Objects`."""
    surf = hits.surface
    if kind == DEPTH:
        out[row, col] = hits.t[i]
    elif kind == NORMAL:
        d, g = hits.direction, surf.geometric
        f = facing1(g[i, 0], g[i, 1], g[i, 2], d[i, 0], d[i, 1], d[i, 2])
        for c in range(3):
            out[row, col + c] = f * surf.shading[i, c]
    elif kind == ALBEDO or kind == POSITION:
        p, o = surf.point, scene.origin
        x, y, z = p[i, 0] + o[0], p[i, 1] + o[1], p[i, 2] + o[2]
        if kind == POSITION:
            out[row, col], out[row, col + 1], out[row, col + 2] = x, y, z
        else:
            g = surf.geometric
            at = MaterialHit(world=(x, y, z), triangle=surf.triangle[i], u=surf.uv[i, 0],
                             v=surf.uv[i, 1], axis=(p[i, 0], p[i, 1], p[i, 2]),
                             normal=(g[i, 0], g[i, 1], g[i, 2]))
            kd = surface_color1(palette1(scene), texture_tables1(scene), surf.material[i], KD,
                                at)
            for c in range(3):
                out[row, col + c] = kd[c]
    elif kind == ID:
        triangle = surf.triangle[i]
        if triangle >= 0:
            mesh = np.searchsorted(scene.triangles.geom_first, triangle, side="right") - 1
            out[row, col] = objects.geom_object[mesh]
        else:
            out[row, col] = objects.shape_object[surf.shape[i]]
    elif kind == UV:
        at = MaterialHit(world=(0.0, 0.0, 0.0), triangle=surf.triangle[i], u=surf.uv[i, 0],
                         v=surf.uv[i, 1], axis=(0.0, 0.0, 0.0), normal=(0.0, 0.0, 0.0))
        out[row, col], out[row, col + 1] = surface_texcoords1(scene.triangles.texcoords, at)


@kernel
def aov_hits(rays, t, surf, scene, objects, layout, out):
    """The AOVs of camera-ray hits (``rays``, their distances ``t`` and ``surf``) into their
    samples' rows (``rays.sample``) of ``out`` (samples, columns): column ``AOV_DISTANCE`` the
    distance, then each AOV of ``layout`` (a :class:`raytrace.kernels.records.AOVLayout`) by
    :func:`aov_value1`."""
    sample, table = rays.sample, layout.table
    hits = FirstHits(direction=rays.direction, t=t, surface=surf)
    for i in range(sample.shape[0]):
        s = sample[i]
        out[s, AOV_DISTANCE] = t[i]
        for k in range(table.shape[0]):
            aov_value1(table[k, AOV_KIND], i, hits, scene, objects, out, s, table[k, AOV_FIRST])


@kernel
def aov_pixels(pixels, spp, samples, layout, out):
    """``pixels`` pixels of ``out`` (pixels, columns), pixel j from samples ``j·spp … j·spp +
    spp − 1`` of ``samples`` (the per-sample table of :func:`aov_hits`): each AOV of ``layout``
    its nearest sample's value (the smallest distance, the first on ties: a Z buffer) or the
    mean of its samples (misses counting as their miss value), channel by channel, summed in
    sample order."""
    table = layout.table
    for j in range(pixels):
        first = j * spp
        best = first
        for k in range(first + 1, first + spp):
            if samples[k, AOV_DISTANCE] < samples[best, AOV_DISTANCE]:
                best = k
        out[j, AOV_DISTANCE] = samples[best, AOV_DISTANCE]
        for a in range(table.shape[0]):
            col, count, combine = table[a, AOV_FIRST], table[a, AOV_COUNT], table[a, AOV_COMBINE]
            for c in range(col, col + count):
                if combine == NEAREST:
                    out[j, c] = samples[best, c]
                else:
                    total = 0.0
                    for k in range(first, first + spp):
                        total += samples[k, c]
                    out[j, c] = total / spp
