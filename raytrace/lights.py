"""Light sources as seen from shading points: direction, distance and attenuation.

Seed 000: ``f_radial(d) = 1/(a0 + a1·d + a2·d²)`` for local sources, 1 at infinity;
``f_angular = 0`` where ``cos α < cos θ`` (outside the cone), else ``(cos α)^a``. Two opt-in
laws of KHR_lights_punctual (Khronos, glTF 2.0 extension, "Inner and Outer Cone Angles" and
"Range Property", the spec's recommended implementation), by key: a spot's ``inner_cutoff``
makes ``f_angular = t²``, ``t = clamp((cos α − cos θ_outer)/max(0.001, cos θ_inner −
cos θ_outer), 0, 1)``; a local light's ``range`` r multiplies ``f_radial`` by
``max(min(1 − (d/r)⁴, 1), 0)``. Area lights
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
from typing import Any

import numpy as np

from . import values
from .errors import SceneError
from .kernels.kinds import DIRECTIONAL, POINT, SMOOTH_SPOT, SPOT
from .kernels.records import Emitter as EmitterRecord


@dataclass(frozen=True)
class Emitter:
    """One point-like sample of a light (camera-relative).

    ``position`` is None for a directional light, whose ``direction`` is the way the light
    travels. ``cos_cutoff`` is None unless it is a spot light. A jittered cell of an area light
    has its centre as ``position``, its edges ``cell_u``, ``cell_v``, its light's ``stream`` ≥ 0
    that seeds the points drawn for each hit and its canonical ``offset`` (j/k, i/k) for cell
    (i, j) of k × k (:func:`raytrace.kernels.shading.incidence1`); ``stream`` is −1 for every
    other emitter. ``part`` names which part of its light the emitter is where the light has
    several (an area light's ``"cell 5"``), for the labels of ``raytrace explain``
    (:func:`labels`); empty for a light of one emitter.
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
    part: str = ""
    #: cos of a smooth spot's inner cone (the KHR_lights_punctual law); None: seed 000's spot.
    cos_inner: float | None = None
    #: > 0: the KHR_lights_punctual range window of a local light; 0: none.
    range: float = 0.0

    @property
    def jittered(self) -> bool:
        return self.stream >= 0

    @cached_property
    def record(self) -> EmitterRecord:
        """The emitter as the kernels take it, a :class:`raytrace.kernels.records.Emitter` of 23
        floats: kind (POINT, SPOT, DIRECTIONAL, SMOOTH_SPOT), position, direction, attenuation,
        cos θ, exponent, cell edges u and v, stream (below 2⁵², so exact in a float64), offset,
        cos of the inner cone, range. A named
        tuple of floats, not an array: numba passes it by value, where an array argument costs
        a reference count per call of the per-hit function that takes it (13 ns a hit in the
        light pass)."""
        kind = (DIRECTIONAL if self.position is None else POINT if self.cos_cutoff is None
                else SPOT if self.cos_inner is None else SMOOTH_SPOT)
        zero = np.zeros(3)
        return EmitterRecord(*np.concatenate([
            [kind], zero if self.position is None else self.position,
            zero if self.direction is None else self.direction,
            [1.0, 0.0, 0.0] if self.attenuation is None else self.attenuation,
            [0.0 if self.cos_cutoff is None else self.cos_cutoff, self.exponent],
            zero if self.cell_u is None else self.cell_u,
            zero if self.cell_v is None else self.cell_v, [self.stream], self.offset,
            [1.0 if self.cos_inner is None else self.cos_inner, self.range]]
        ).astype(np.float64).tolist())


def cos_cutoff(degrees: float) -> float:
    """cos θ of the cone's half-angle, exactly 0 at 90° (where cos(π/2) would be 6e-17)."""
    return 0.0 if degrees == 90.0 else math.cos(math.radians(degrees))


def emitters(lights: list, origin: np.ndarray, seed: int) -> list[Emitter]:
    """Every light as point-like samples, positions made relative to ``origin``: each light
    record's own ``emitters(origin, seed, index)``."""
    return [e for i, light in enumerate(lights) for e in light.emitters(origin, seed, i)]


def labels(lights: list, origin: np.ndarray, seed: int) -> list[str]:
    """A label per emitter of :func:`emitters` (the same arguments), in its order, for
    ``raytrace explain``: the light's key and type, and the emitter's ``part`` where it has
    one (``lights[2] (area, cell 5)``). Each light record names the parts of its own
    emitters, so a light of several emitters never shifts the labels of those after it."""
    return [f"lights[{i}] ({light.type}{', ' + e.part if e.part else ''})"
            for i, light in enumerate(lights) for e in light.emitters(origin, seed, i)]


def _range(value: Any) -> float | None:
    """A light's ``range`` (a :func:`raytrace.values.length`), or None: no window."""
    return None if value is None else values.length(value, "range")


def _attenuation(value: Any, key: str) -> np.ndarray:
    a = values.vector(value, key)
    if np.any(a < 0) or not np.any(a > 0):
        raise SceneError(f"needs a0, a1, a2 >= 0, not all zero (1/(a0 + a1·d + a2·d²)), "
                         f"got {a.tolist()}", key)
    return a


@dataclass
class PointLight(values.Checked):
    """An isotropic point source with radial attenuation 1/(a0 + a1·d + a2·d²), times the
    KHR_lights_punctual window max(min(1 − (d/range)⁴, 1), 0) where ``range`` is given."""

    position: Any
    color: Any = 1.0
    attenuation: Any = (1.0, 0.0, 0.0)
    range: Any = None
    type = "point"

    def check(self) -> None:
        self.position = values.position(self.position, "position")
        self.color = values.color(self.color, "color")
        self.attenuation = _attenuation(self.attenuation, "attenuation")
        self.range = _range(self.range)

    def emitters(self, origin: np.ndarray, seed: int, index: int) -> list:
        """One point sample (:class:`raytrace.lights.Emitter`), camera-relative."""
        return [Emitter(self.color, self.position - origin, attenuation=self.attenuation,
                        range=self.range or 0.0)]


@dataclass
class DirectionalLight(values.Checked):
    """A source at infinity; ``direction`` is the way the light travels. No attenuation."""

    direction: Any
    color: Any = 1.0
    type = "directional"

    def check(self) -> None:
        self.direction = values.unit(self.direction, "direction")
        self.color = values.color(self.color, "color")

    def emitters(self, origin: np.ndarray, seed: int, index: int) -> list:
        """One sample at infinity (:class:`raytrace.lights.Emitter`)."""
        return [Emitter(self.color, direction=self.direction)]


@dataclass
class SpotLight(values.Checked):
    """A point source limited to a cone: f_angular = (cos α)^exponent inside, 0 outside; with
    ``inner_cutoff`` KHR_lights_punctual's falloff instead, t² with t = clamp((cos α − cos
    cutoff)/max(0.001, cos inner_cutoff − cos cutoff), 0, 1). ``range``: as a point light's."""

    position: Any
    direction: Any
    cutoff: float = 45.0
    exponent: float = 0.0
    color: Any = 1.0
    attenuation: Any = (1.0, 0.0, 0.0)
    inner_cutoff: Any = None
    range: Any = None
    type = "spot"

    def check(self) -> None:
        self.position = values.position(self.position, "position")
        self.direction = values.unit(self.direction, "direction")
        self.cutoff = values.number(self.cutoff, "cutoff", lo=0, hi=90, lo_open=True)
        self.exponent = values.number(self.exponent, "exponent", lo=0)
        self.color = values.color(self.color, "color")
        self.attenuation = _attenuation(self.attenuation, "attenuation")
        if self.inner_cutoff is not None:
            self.inner_cutoff = values.number(self.inner_cutoff, "inner_cutoff", lo=0,
                                              hi=self.cutoff)
            if self.exponent != 0:
                raise SceneError("a spot falls off by exponent (cos α)^a or between "
                                 "inner_cutoff and cutoff, not both: drop one", "inner_cutoff")
        self.range = _range(self.range)

    def emitters(self, origin: np.ndarray, seed: int, index: int) -> list:
        """One point sample with its cone (:class:`raytrace.lights.Emitter`)."""
        inner = None if self.inner_cutoff is None else cos_cutoff(self.inner_cutoff)
        return [Emitter(self.color, self.position - origin, self.direction, self.attenuation,
                        cos_cutoff(self.cutoff), self.exponent, cos_inner=inner,
                        range=self.range or 0.0)]


@dataclass
class AreaLight(values.Checked):
    """A two-sided rectangle ``position ± edge_u/2 ± edge_v/2``, sampled by k×k point lights.

    ``color`` is the total over all samples; ``jitter`` places each sample at a random spot
    in its cell, drawn anew for every shading point from ``[render] seed`` (stratified
    sampling of the light), otherwise at the cell centre.
    """

    position: Any
    edge_u: Any
    edge_v: Any
    samples: int = 16
    jitter: bool = False
    color: Any = 1.0
    attenuation: Any = (1.0, 0.0, 0.0)
    range: Any = None
    type = "area"

    def check(self) -> None:
        self.position = values.position(self.position, "position")
        self.edge_u = values.edge(self.edge_u, "edge_u")
        self.edge_v = values.edge(self.edge_v, "edge_v")
        cross = np.linalg.norm(np.cross(self.edge_u, self.edge_v))
        if cross <= 1e-12 * np.linalg.norm(self.edge_u) * np.linalg.norm(self.edge_v):
            raise SceneError("must not be parallel to edge_u", "edge_v")
        self.samples = values.number(self.samples, "samples", lo=1, hi=4096, integer=True)
        k = math.isqrt(self.samples)
        if k * k != self.samples:
            raise SceneError(f"must be a perfect square k² (a k×k grid), got {self.samples}; "
                             f"try {k * k} or {(k + 1) ** 2}", "samples")
        self.jitter = values.boolean(self.jitter, "jitter")
        self.color = values.color(self.color, "color")
        self.attenuation = _attenuation(self.attenuation, "attenuation")
        self.range = _range(self.range)

    def sample_points(self) -> np.ndarray:
        """The k² cell centres (k², 3), cell (i, j) at ``position + ((i + ½)/k − ½)·edge_u +
        ((j + ½)/k − ½)·edge_v``; with ``jitter`` the renderer draws each sample inside its
        cell anew for every shading point."""
        k = math.isqrt(self.samples)
        i, j = np.meshgrid(np.arange(k), np.arange(k), indexing="ij")
        fu = ((i + 0.5) / k - 0.5).ravel()
        fv = ((j + 0.5) / k - 0.5).ravel()
        return self.position + fu[:, None] * self.edge_u + fv[:, None] * self.edge_v

    def emitters(self, origin: np.ndarray, seed: int, index: int) -> list:
        """k² point samples sharing the colour (seed 001's distributed source), at the cell
        centres; a jittered light gets a hash stream from (``seed``, ``index``) and each cell
        its canonical offset, drawn per shading point
        (:func:`raytrace.kernels.shading.incidence1`). Cell c is the part ``"cell c"``."""
        pts = self.sample_points() - origin
        col = self.color / len(pts)
        if not self.jitter:
            return [Emitter(col, position=p, attenuation=self.attenuation, part=f"cell {c}",
                            range=self.range or 0.0)
                    for c, p in enumerate(pts)]
        k = math.isqrt(self.samples)
        stream = int(np.random.default_rng([seed, index]).integers(0, 2**52))
        i, j = np.meshgrid(np.arange(k), np.arange(k), indexing="ij")  # sample_points' order
        return [Emitter(col, position=p, attenuation=self.attenuation, cell_u=self.edge_u / k,
                        cell_v=self.edge_v / k, stream=stream, offset=(b / k, a / k),
                        part=f"cell {c}", range=self.range or 0.0)
                for c, (p, a, b) in enumerate(zip(pts, i.ravel(), j.ravel(), strict=True))]


Light = PointLight | DirectionalLight | SpotLight | AreaLight
#: The light types by their scene-file ``type``: a light is one record (its fields are its
#: scene-file keys, ``emitters`` its samples, each naming its ``part`` where there are several)
#: plus one line here, which also exports it (``raytrace.<its class name>``).
LIGHT_TYPES = {"point": PointLight, "directional": DirectionalLight, "spot": SpotLight,
               "area": AreaLight}
