"""What lies behind a surface: Beer's-law absorption inside a closed volume, and thin walls.

A material's interior (``Scene.media``, a :class:`raytrace.kernels.records.Media`) has an
absorption coefficient σ per channel, ``σ = −ln(attenuation_color)/attenuation_distance``
(KHR_materials_volume, "Attenuation"; pbrt-v4's ``HomogeneousMedium``; Shirley & Marschner,
Fundamentals of Computer Graphics, 3rd ed., §13.1, Beer's law): light that travels a distance
d inside keeps ``T = exp(−σ·d) = attenuation_color^(d/attenuation_distance)`` of itself. A
thin wall (KHR_materials_transmission without a volume) has no inside: a transmitted ray goes
straight on, and nothing is absorbed.

Whitted's tracer keeps no stack of media, so a segment's medium is read at its far end: a ray
(or a transparent shadow ray) that **leaves** a surface (``d·N_g > 0``, N_g outward) has
crossed that surface's material, and is attenuated over its whole length; a segment that
ends entering a surface is not (docs/shading.md states the consequences: a camera inside
glass, nested media).

The helpers are chosen by type when a kernel compiles (``numba.extending.overload``, as
:mod:`raytrace.kernels.material`'s texture tables): with ``media`` None (no material absorbs
or is thin-walled) each is the identity, and a kernel compiles none of the code below.
"""

from __future__ import annotations

import math

from numba.core import types
from numba.extending import overload

from .jit import helper


@helper
def beer1(sigma, m, leaving, distance):
    """Beer's-law transmittance ``exp(−σ_m·distance)`` per channel (3-tuple) of a segment of
    ``distance`` ending at a hit on material ``m`` that it ``leaves``; (1, 1, 1) where it
    enters or the material's σ (row ``m`` of ``sigma`` (M, 3)) is 0."""
    s0, s1, s2 = sigma[m, 0], sigma[m, 1], sigma[m, 2]
    if not leaving or (s0 == 0.0 and s1 == 0.0 and s2 == 0.0):
        return 1.0, 1.0, 1.0
    return math.exp(-s0 * distance), math.exp(-s1 * distance), math.exp(-s2 * distance)


def arriving1(media, m, rays, surf, i):
    """The weight (3-tuple) of ray ``i`` of ``rays`` as it reaches its hit ``i`` of ``surf``
    on material ``m``: ``w·exp(−σ_m·t)``, t = |P − O| (the length of the segment, inside
    the material it leaves), :func:`beer1`; ``w`` itself where ``media`` is None."""


@overload(arriving1, inline="always")
def _arriving1(media, m, rays, surf, i):
    if isinstance(media, types.NoneType):
        return lambda media, m, rays, surf, i: (rays.weight[i, 0], rays.weight[i, 1],
                                                rays.weight[i, 2])

    def arriving(media, m, rays, surf, i):
        d, o, p, g = rays.direction, rays.origin, surf.point, surf.geometric
        w = rays.weight
        leaving = d[i, 0] * g[i, 0] + d[i, 1] * g[i, 1] + d[i, 2] * g[i, 2] > 0.0
        if not leaving:
            return w[i, 0], w[i, 1], w[i, 2]
        ex, ey, ez = p[i, 0] - o[i, 0], p[i, 1] - o[i, 1], p[i, 2] - o[i, 2]
        a = beer1(media.sigma, m, leaving, math.sqrt(ex * ex + ey * ey + ez * ez))
        return w[i, 0] * a[0], w[i, 1] * a[1], w[i, 2] * a[2]
    return arriving


def crossing1(media, m, walk, surf, j):
    """The transmittance (3-tuple) of the segment of transparent shadow ray ``j`` of ``walk``
    (a :class:`raytrace.kernels.records.ShadowWalk`) up to the surface ``j`` of ``surf`` it
    crosses, on material ``m``: :func:`beer1` over the hit's ``t``; (1, 1, 1) where
    ``media`` is None."""


@overload(crossing1, inline="always")
def _crossing1(media, m, walk, surf, j):
    if isinstance(media, types.NoneType):
        return lambda media, m, walk, surf, j: (1.0, 1.0, 1.0)

    def crossing(media, m, walk, surf, j):
        d, g = walk.direction, surf.geometric
        leaving = d[j, 0] * g[j, 0] + d[j, 1] * g[j, 1] + d[j, 2] * g[j, 2] > 0.0
        return beer1(media.sigma, m, leaving, walk.t[j])
    return crossing


def thin_walled1(media, m):
    """Whether material ``m`` is a thin wall (a transmitted ray goes straight on, and Fresnel
    takes every hit as entering); False where ``media`` is None."""


@overload(thin_walled1, inline="always")
def _thin_walled1(media, m):
    if isinstance(media, types.NoneType):
        return lambda media, m: False
    return lambda media, m: media.thin[m]
