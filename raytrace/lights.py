"""Light sources as seen from shading points: direction, distance and attenuation.

Seed 000: ``f_radial(d) = 1/(a0 + a1·d + a2·d²)`` for local sources, 1 at infinity;
``f_angular = 0`` where ``cos α < cos θ`` (outside the cone), else ``(cos α)^a``. Area lights
(seed 001, "distributed sources") are a k×k grid of point samples sharing the colour: at the
cell centres, or, jittered, at a point drawn inside its cell anew for every shading point
(stratified sampling of the light, as in Cook, Porter & Carpenter, "Distributed Ray
Tracing", SIGGRAPH 1984), so that the penumbra's steps become noise that more pixel samples
average away.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from .records import Emitter as EmitterRecord

#: ``Emitter.incidence`` without keys: every jittered cell at its centre.
NO_KEY = np.zeros(0, np.int64)


@dataclass(frozen=True)
class Emitter:
    """One point-like sample of a light (camera-relative).

    ``position`` is None for a directional light, whose ``direction`` is the way the light
    travels. ``cos_cutoff`` is None unless it is a spot light. A jittered cell of an area light
    has its centre as ``position``, its edges ``cell_u``, ``cell_v``, its light's ``stream`` ≥ 0
    that seeds the points drawn for each hit and its canonical ``offset`` (j/k, i/k) for cell
    (i, j) of k × k (:func:`raytrace.shading_kernels.incidence1`); ``stream`` is −1 for every
    other emitter.
    """

    color: np.ndarray
    position: np.ndarray | None = None
    direction: np.ndarray | None = None
    attenuation: np.ndarray | None = None
    cos_cutoff: float | None = None
    exponent: float = 0.0
    cell_u: np.ndarray | None = None
    cell_v: np.ndarray | None = None
    stream: int = -1
    offset: tuple[float, float] = (0.0, 0.0)

    @property
    def jittered(self) -> bool:
        return self.stream >= 0

    def incidence(self, points: np.ndarray, key: np.ndarray | None = None,
                  depth: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Unit vectors to the light L (n, 3), distances (n,) (inf for directional) and the
        attenuation ``f_radial · f_angular`` (n,) at ``points`` (n, 3).

        A point exactly at the light's position gets factor 0 (no direction is defined). A
        jittered area-light cell is taken at the point drawn for each ``key`` (n,) (the
        global camera sample of the hit the point belongs to, :func:`path_keys` of it below the
        camera rays) and ``depth``, the point the
        integrator's shadow rays of that hit aim at; without ``key``, at the cell centre.
        (:func:`raytrace.shading_kernels.incidence_rows`.)
        """
        points = np.ascontiguousarray(np.asarray(points, np.float64).reshape(-1, 3))
        n = len(points)
        words = NO_KEY if key is None else light_words(key, self.stream, depth)
        to_light, dist, factor = np.empty((n, 3)), np.empty(n), np.empty(n)
        from .shading_kernels import incidence_rows

        incidence_rows(points, self.record, words, to_light, dist, factor)
        return to_light, dist, factor

    @cached_property
    def record(self) -> EmitterRecord:
        """The emitter as the kernels take it, a :class:`raytrace.records.Emitter` of 21
        floats: kind (POINT, SPOT, DIRECTIONAL), position, direction, attenuation, cos θ,
        exponent, cell edges u and v, stream (below 2⁵², so exact in a float64), offset. A named
        tuple of floats, not an array: numba passes it by value, where an array argument costs
        a reference count per call of the per-hit function that takes it (13 ns a hit in the
        light pass)."""
        from .shading_kernels import DIRECTIONAL, POINT, SPOT

        kind = (DIRECTIONAL if self.position is None else
                POINT if self.cos_cutoff is None else SPOT)
        zero = np.zeros(3)
        return EmitterRecord(*np.concatenate([
            [kind], zero if self.position is None else self.position,
            zero if self.direction is None else self.direction,
            [1.0, 0.0, 0.0] if self.attenuation is None else self.attenuation,
            [0.0 if self.cos_cutoff is None else self.cos_cutoff, self.exponent],
            zero if self.cell_u is None else self.cell_u,
            zero if self.cell_v is None else self.cell_v, [self.stream], self.offset]
        ).astype(np.float64).tolist())


def light_words(key: np.ndarray, stream: int, depth: int) -> np.ndarray:
    """The draws (n,) int64 of a jittered area light (its ``stream``) at hits of camera-sample
    or path ``key`` (n,) and ``depth``: :func:`raytrace.core.light_word` of each, one per hit
    for all the light's cells (no rows for an unjittered emitter, stream < 0)."""
    if stream < 0:
        return NO_KEY
    from .core import light_words as kernel

    out = np.empty(len(key), np.int64)
    kernel(np.ascontiguousarray(key, np.int64), np.int64(stream), np.int64(depth), out)
    return out


def path_keys(key: np.ndarray, origin: np.ndarray, direction: np.ndarray) -> np.ndarray:
    """The jitter keys (n,) int64 of the hits of secondary rays: each ray's camera-sample
    ``key`` (n,) hashed with its ``origin`` and ``direction`` (n, 3) float64
    (:func:`raytrace.core.path_key1`), so that the children of one hit, and every path
    of a camera sample, draw their own points on a jittered area light."""
    from .core import path_keys as kernel

    out = np.empty(len(key), np.int64)
    kernel(np.ascontiguousarray(key, np.int64),
           np.ascontiguousarray(origin, np.float64).view(np.uint64),
           np.ascontiguousarray(direction, np.float64).view(np.uint64), out)
    return out


def cos_cutoff(degrees: float) -> float:
    """cos θ of the cone's half-angle, exactly 0 at 90° (where cos(π/2) would be 6e-17)."""
    return 0.0 if degrees == 90.0 else math.cos(math.radians(degrees))


def emitters(lights: list, origin: np.ndarray, seed: int) -> list[Emitter]:
    """Every light as point-like samples, positions made relative to ``origin``: each light
    record's own ``emitters(origin, seed, index)``."""
    return [e for i, light in enumerate(lights) for e in light.emitters(origin, seed, i)]
