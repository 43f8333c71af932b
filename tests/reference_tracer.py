"""A deliberately slow, plainly recursive Whitted tracer: the oracle for the wavefront.

It follows seed 003's pseudocode one ray at a time, in the contract's form
(SCENE_FORMAT.md, "The shading model")::

    trace(ray, depth):
        hit ← closest intersection
        no hit → background
        return shade(hit, ray, depth)

    shade(hit, ray, depth):
        local ← ka·Ia + Σ_l S_l · f_l · I_l · [kd·max(N·L, 0) + ks·spec]
        I     ← local + kr·trace(reflected, depth+1) + kt·trace(refracted or TIR, depth+1)
        return t·I + (1 − t)·trace(straight through, depth+1)

where a child is traced only while its depth ≤ max_depth and its path weight (the product of
the t·kr, t·kt, 1 − t factors, max over RGB) is ≥ min_weight, and S_l is the product of
``t·kt + (1 − t)`` over every surface the straight shadow ray crosses before the light.

Under TIR the kt share leaves along the mirror direction. With min_weight 0 a TIR ray on the
reflected ray's exact path is traced once, as (kr + kt)·trace(reflected): exact, since the sum
is linear in the children and both have the same depth, and only max_depth stops a path. With
min_weight > 0 the two stay separate rays (weights w·t·kr and w·t·kt), each pruned by its own
path weight, as the contract says.

Written independently of :mod:`raytrace.integrator`: it shares only the intersection code
(:class:`raytrace.accel.Accelerator`, its spawn rule and shadow-ray shortening) and the local
terms (:func:`raytrace.shading.direct`, :meth:`raytrace.lights.Emitter.incidence`). The camera
rays, the recursion, the weights, the opacity blend, reflection, Snell refraction with total
internal reflection and the transparent-shadow product are all done here, per ray, with Python
scalars and 3-vectors. Gouraud meshes are not supported (the reference scenes use none).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from raytrace.accel import SHADOW_SHORTEN, Accelerator, spawn_origins
from raytrace.lights import emitters
from raytrace.material import Checker, Material
from raytrace.rays import NO_SHAPE
from raytrace.scene import Scene
from raytrace.shading import HIGHLIGHT_CODES, direct

#: A shadow ray crossing more surfaces than this is a bug in the scene or the tracer.
MAX_CROSSINGS = 1000


@dataclass
class Counts:
    """What the reference traced: rays by kind, shadow-ray segments, TIR events."""

    camera: int = 0
    reflection: int = 0
    refraction: int = 0
    see_through: int = 0
    shadow: int = 0
    tir: int = 0
    pruned_depth: int = 0
    pruned_weight: int = 0


def coefficient(c: np.ndarray | Checker, world: np.ndarray) -> np.ndarray:
    """A material colour (3,) at one world point; a checker is evaluated there."""
    if isinstance(c, Checker):
        return c.evaluate(world[None])[0]
    return np.asarray(c, dtype=np.float64)


def mirror(d: np.ndarray, n: np.ndarray) -> np.ndarray:
    """Law of reflection: d − 2(d·n)n."""
    return d - 2.0 * float(d @ n) * n


def snell(d: np.ndarray, n: np.ndarray, eta: float) -> np.ndarray | None:
    """Refracted direction for η₁/η₂ = eta, n on the incoming side; None on TIR.

    From Snell's law sin θt = η sin θi: cos²θt = 1 − η²(1 − cos²θi) (Hecht, Optics, 4.4).
    """
    cos_i = min(max(-float(d @ n), 0.0), 1.0)
    cos2_t = 1.0 - eta * eta * (1.0 - cos_i * cos_i)
    if cos2_t < 0.0:
        return None
    return eta * d + (eta * cos_i - math.sqrt(cos2_t)) * n


class ReferenceTracer:
    """Render ``scene`` pixel by pixel with the recursive definition (spp = 1 only)."""

    def __init__(self, scene: Scene, max_depth: int | None = None,
                 min_weight: float | None = None, seed: int = 0):
        r = scene.render
        self.scene = scene
        self.max_depth = r.max_depth if max_depth is None else max_depth
        self.min_weight = r.min_weight if min_weight is None else min_weight
        self.background = np.asarray(r.background, dtype=np.float64)
        self.ambient = np.asarray(scene.ambient, dtype=np.float64)
        self.materials: list[Material] = []
        for o in scene.objects:
            if all(o.material is not m for m in self.materials):
                self.materials.append(o.material)
        self.accel = Accelerator(scene, self.materials)
        if np.any(getattr(self.accel, "tri_shading", np.zeros(0)) == 2):
            raise NotImplementedError("the reference tracer has no Gouraud shading")
        self.origin = self.accel.origin
        self.lights = emitters(scene.lights, self.origin, seed)
        self.counts = Counts()

    # -- camera ------------------------------------------------------------------------------
    def camera_ray(self, row: int, col: int, width: int, height: int) -> np.ndarray:
        """Unit direction through the centre of pixel (row, col); pixel (0, 0) is top-left."""
        cam = self.scene.camera
        forward = cam.look_at - cam.position
        forward = forward / np.linalg.norm(forward)
        right = np.cross(forward, cam.up)
        right = right / np.linalg.norm(right)
        up = np.cross(right, forward)
        tan_half = math.tan(math.radians(cam.fov) / 2.0)
        x = (2.0 * (col + 0.5) / width - 1.0) * tan_half * width / height
        y = (1.0 - 2.0 * (row + 0.5) / height) * tan_half
        d = forward + x * right + y * up
        return d / np.linalg.norm(d)

    def render(self, width: int, height: int) -> np.ndarray:
        """(height, width, 3) float64 linear RGB."""
        out = np.zeros((height, width, 3))
        for row in range(height):
            for col in range(width):
                self.counts.camera += 1
                d = self.camera_ray(row, col, width, height)
                out[row, col] = self.trace(np.zeros(3), d, NO_SHAPE, 0)
        return out

    # -- the recursion -----------------------------------------------------------------------
    def hit(self, origin: np.ndarray, d: np.ndarray, shape: int, tmax: float | None = None):
        """The closest surface along one ray, or None."""
        hits = self.accel.intersect(origin[None], d[None], np.array([shape]),
                                    None if tmax is None else np.array([tmax]))
        if not hits.hit[0]:
            return None, math.inf
        return self.accel.surface(hits, origin[None], d[None]), float(hits.t[0])

    def trace(self, origin: np.ndarray, d: np.ndarray, shape: int, depth: int) -> np.ndarray:
        """Seed 003's trace(): the colour seen along one ray."""
        surf, _ = self.hit(origin, d, shape)
        if surf is None:
            return self.background.copy()
        return self.shade(surf, d, depth, np.ones(3))

    def child(self, surf, d_new: np.ndarray, depth: int, weight: np.ndarray,
              kind: str) -> np.ndarray:
        """trace() of a secondary ray, or 0 when the depth or weight limit stops it."""
        if depth > self.max_depth:
            if weight.max() > 0:
                self.counts.pruned_depth += 1
            return np.zeros(3)
        if weight.max() <= 0:
            return np.zeros(3)
        if weight.max() < self.min_weight:
            self.counts.pruned_weight += 1
            return np.zeros(3)
        setattr(self.counts, kind, getattr(self.counts, kind) + 1)
        origin = spawn_origins(surf.point, surf.geometric, surf.offset, d_new[None])[0]
        nxt, _ = self.hit(origin, d_new, int(surf.shape[0]))
        if nxt is None:
            return self.background.copy()
        return self.shade(nxt, d_new, depth, weight)

    def shade(self, surf, d: np.ndarray, depth: int, weight: np.ndarray) -> np.ndarray:
        """Seed 003's shade() with the opacity blend: t·I_surface + (1 − t)·I_behind.

        ``weight`` is this ray's path weight, used only to decide whether children are traced.
        """
        mat = self.materials[int(surf.material[0])]
        point = surf.point[0]
        world = point + self.origin
        outward = surf.geometric[0]
        v = -d
        side = -1.0 if float(outward @ v) < 0 else 1.0  # two-sided: N towards the viewer
        ng, ns = outward * side, surf.shading[0] * side
        t = mat.opacity

        color = self.ambient * coefficient(mat.ambient, world)
        kd, ks = coefficient(mat.kd, world), coefficient(mat.ks, world)
        for light in self.lights:
            to_light, dist, f = light.incidence(point[None])
            term = direct(ns[None], to_light[:1], v[None], kd[None], ks[None],
                          np.array([mat.shininess]),
                          np.array([HIGHLIGHT_CODES[mat.highlight]]))[0] * f[0]
            if np.any(term > 0):
                color = color + term * self.shadow(surf, to_light[0], float(dist[0])) \
                    * light.color

        kr, kt = coefficient(mat.kr, world), coefficient(mat.kt, world)
        r = refracted = None
        if t > 0 and np.any(kr > 0):
            r = mirror(d, ns)
            if float(r @ ng) <= 0:  # the shading normal sent it inside: use the face
                r = mirror(d, ng)
        if t > 0 and np.any(kt > 0):
            entering = float(d @ outward) < 0  # decided by the outward geometric normal
            eta = 1.0 / mat.ior if entering else mat.ior
            refracted = snell(d, ns, eta)
            if refracted is not None and float(refracted @ ng) >= 0:
                refracted = snell(d, ng, eta)
            if refracted is None:  # TIR: the kt share goes along the mirror direction
                refracted = mirror(d, ns)
                if float(refracted @ ng) <= 0:
                    refracted = mirror(d, ng)
                if depth + 1 <= self.max_depth:
                    self.counts.tir += 1
                if (self.min_weight <= 0 and r is not None and np.array_equal(refracted, r)
                        and (weight * t * kr).max() > 0):
                    # The reflection and the kt share leave on the same path: one ray,
                    # I_r·(kr + kt), of weight w·t·(kr + kt) (the contract's sum is linear).
                    # Only without weight pruning: min_weight must see each path's own weight.
                    kr, refracted = kr + kt, None
        if r is not None:
            color = color + kr * self.child(surf, r, depth + 1, weight * t * kr, "reflection")
        if refracted is not None:
            color = color + kt * self.child(surf, refracted, depth + 1, weight * t * kt,
                                            "refraction")
        out = t * color
        if t < 1:
            out = out + (1.0 - t) * self.child(surf, d, depth + 1, weight * (1.0 - t),
                                               "see_through")
        return out

    def shadow(self, surf, to_light: np.ndarray, dist: float) -> np.ndarray:
        """S_l: the product of ``t·kt + (1 − t)`` over every surface before the light."""
        factor = np.ones(3)
        point, normal, offset = surf.point, surf.geometric, surf.offset
        shape = int(surf.shape[0])
        remaining = dist * (1.0 - SHADOW_SHORTEN)
        for _ in range(MAX_CROSSINGS):
            origin = spawn_origins(point, normal, offset, to_light[None])[0]
            self.counts.shadow += 1
            s2, t_hit = self.hit(origin, to_light, shape, remaining)
            if s2 is None:
                return factor
            m = self.materials[int(s2.material[0])]
            world = s2.point[0] + self.origin
            factor = factor * (m.opacity * coefficient(m.kt, world) + (1.0 - m.opacity))
            if not np.any(factor > 0):
                return factor
            point, normal, offset, shape = s2.point, s2.geometric, s2.offset, int(s2.shape[0])
            remaining -= t_hit
        raise RuntimeError("shadow ray crossed too many surfaces")
