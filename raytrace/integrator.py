"""Whitted ray tracing as a wavefront (Whitted 1980; seed 003's trace/shade pseudocode).

The recursive definition, for a ray hitting a surface with opacity t,

    I = t·(ka·Ia + Σ_l S_l·f_l·I_l·[kd·max(N·L, 0) + ks·spec] + kr·I_reflected + kt·I_refracted)
        + (1 − t)·I_behind

is linear in the child rays. So each ray carries the product of the factors along its path
(``weight``, per channel) and its sample index; each depth is one batch: intersect → add the
background for misses → shade hits and add ``weight·t·local`` → spawn the children (weights
``weight·t·kr``, ``weight·t·kt``, ``weight·(1 − t)``) → next depth. Summing over depths gives
exactly the recursion. The image is rendered in passes of whole pixels, so memory is bounded
by the pass size, not the resolution.

What a scene does not need is left out: no shadow rays without lights or for unlit materials,
an occlusion query unless something is transparent, no reflection or refraction wavefront
unless some material reflects or transmits.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from .accel import SHADOW_SHORTEN, Accelerator, Surface, spawn_origins
from .camera import camera_rays
from .film import Image
from .lights import Emitter, emitters
from .material import COLOR_KEYS, Checker, Material
from .optics import dot, reflect, refract
from .rays import KIND_NAMES, REFLECTION, REFRACTION, SEE_THROUGH, RayBatch
from .scene import Scene
from .shading import HIGHLIGHT_CODES, direct

#: Camera samples per pass (whole pixels): bounds memory independently of resolution.
PASS_SAMPLES = 1 << 17
#: Most surfaces a transparent shadow ray passes through before it counts as blocked.
MAX_SHADOW_CROSSINGS = 64


@dataclass
class RenderOptions:
    """Settings of one render; ``None`` takes the scene's ``[render]`` value."""

    width: int
    height: int
    spp: int
    max_depth: int
    min_weight: float
    background: np.ndarray
    seed: int
    threads: int = 1
    pass_samples: int = PASS_SAMPLES


class MaterialTable:
    """Per-material coefficient arrays, gathered by material index at hit points.

    Constant colours are rows of (M, 3) arrays; :class:`Checker` patterns are evaluated at the
    world points of the hits that use them.
    """

    def __init__(self, materials: list[Material]):
        self.materials = materials
        self.const = {k: np.zeros((len(materials), 3)) for k in COLOR_KEYS}
        self.patterns: dict[str, list[tuple[int, Checker]]] = {k: [] for k in COLOR_KEYS}
        for i, m in enumerate(materials):
            for k in COLOR_KEYS:
                c = m.ambient if k == "ka" else getattr(m, k)
                if isinstance(c, Checker):
                    self.patterns[k].append((i, c))
                else:
                    self.const[k][i] = c
        self.shininess = np.array([m.shininess for m in materials], dtype=np.float64)
        self.highlight = np.array([HIGHLIGHT_CODES[m.highlight] for m in materials])
        self.ior = np.array([m.ior for m in materials], dtype=np.float64)
        self.opacity = np.array([m.opacity for m in materials], dtype=np.float64)
        self.lit = np.array([m.lit for m in materials], dtype=bool)
        self.reflects = np.array([m.reflects for m in materials], dtype=bool)
        self.transmits = np.array([m.transmits for m in materials], dtype=bool)
        self.transparent = np.array([m.transparent for m in materials], dtype=bool)

    def color(self, key: str, material: np.ndarray, world: np.ndarray) -> np.ndarray:
        """Coefficient ``key`` (n, 3) for hits with material indices (n,) at world points."""
        out = self.const[key][material]
        for i, pattern in self.patterns[key]:
            m = material == i
            if m.any():
                out[m] = pattern.evaluate(world[m])
        return out


@dataclass
class Stats:
    """Counters for ``--stats``."""

    rays: dict = field(default_factory=lambda: {k: 0 for k in (*KIND_NAMES, "shadow")})
    pruned_depth: int = 0
    pruned_weight: int = 0
    total_internal_reflections: int = 0
    trace_seconds: float = 0.0
    shade_seconds: float = 0.0


class WhittedIntegrator:
    """Renders a scene, pass by pass and depth by depth."""

    def __init__(self, scene: Scene, options: RenderOptions):
        self.scene, self.opt = scene, options
        seen: dict[int, Material] = {}
        for o in scene.objects:
            seen.setdefault(id(o.material), o.material)
        self.materials = list(seen.values())
        self.table = MaterialTable(self.materials)
        t0 = time.perf_counter()
        self.accel = Accelerator(scene, self.materials, options.threads)
        self.build_seconds = time.perf_counter() - t0
        self.origin = self.accel.origin
        self.emitters: list[Emitter] = emitters(scene.lights, self.origin, options.seed)
        self.ambient = scene.ambient
        self.any_transparent = bool(self.table.transparent.any()) if self.materials else False
        self.stats = Stats()

    # -- the loop ----------------------------------------------------------------------------
    def render(self, progress: Callable[[int, int], None] | None = None) -> Image:
        o = self.opt
        t_start = time.perf_counter()
        total = o.width * o.height * o.spp
        per_pass = max(o.spp, (o.pass_samples // o.spp) * o.spp)
        pixels = np.zeros((o.width * o.height, 3), dtype=np.float64)
        try:
            for start in range(0, total, per_pass):
                stop = min(start + per_pass, total)
                samples = np.zeros((stop - start, 3))
                rays = camera_rays(self.scene.camera, o.width, o.height, o.spp, o.seed,
                                   start, stop)
                # Depth by depth; a batch grown past the pass size (2 children per glass hit)
                # is split and its chunks finished one after another, so memory stays
                # bounded by the pass size × max_depth rather than growing as 2^depth.
                pending = [rays]
                while pending:
                    rays = pending.pop()
                    if len(rays) > per_pass:
                        pending.extend(rays.take(slice(i, i + per_pass)) for i in
                                       reversed(range(0, len(rays), per_pass)))
                        continue
                    children = self.trace(rays, samples)
                    if len(children):
                        pending.append(children)
                pixels[start // o.spp: stop // o.spp] = samples.reshape(-1, o.spp, 3).mean(1)
                if progress is not None:
                    progress(stop, total)
        finally:
            self.accel.close()
        with np.errstate(over="ignore", invalid="ignore"):  # beyond float32's range → inf
            rgb = pixels.reshape(o.height, o.width, 3).astype(np.float32)
        bad = ~np.isfinite(rgb)
        nonfinite = int(bad.any(axis=2).sum())
        rgb = np.where(bad, np.float32(0.0), rgb)
        seconds = time.perf_counter() - t_start + self.build_seconds
        return Image(rgb, self._stats(nonfinite, seconds), self._metadata())

    def trace(self, rays: RayBatch, samples: np.ndarray) -> RayBatch:
        """One depth: intersect, add background and local shading, return the next depth."""
        st, o = self.stats, self.opt
        kinds = np.bincount(rays.kind, minlength=len(KIND_NAMES))
        for name, count in zip(KIND_NAMES, kinds, strict=True):
            st.rays[name] += int(count)
        t0 = time.perf_counter()
        hits = self.accel.intersect(rays.origin, rays.direction, rays.origin_shape)
        st.trace_seconds += time.perf_counter() - t0
        hit = hits.hit
        if (~hit).any() and np.any(o.background):
            add(samples, rays.sample[~hit], rays.weight[~hit] * o.background)
        if not hit.any():
            return RayBatch.empty(rays.depth + 1)
        t1 = time.perf_counter()
        trace_before = st.trace_seconds
        rays = rays.take(hit)
        hits_idx = np.flatnonzero(hit)
        hits.t, hits.shape = hits.t[hits_idx], hits.shape[hits_idx]
        hits.triangle, hits.uv = hits.triangle[hits_idx], hits.uv[hits_idx]
        surf = self.accel.surface(hits, rays.origin, rays.direction)
        children = self.shade(rays, surf, samples)
        st.shade_seconds += time.perf_counter() - t1 - (st.trace_seconds - trace_before)
        return children

    # -- shading -----------------------------------------------------------------------------
    def shade(self, rays: RayBatch, surf: Surface, samples: np.ndarray) -> RayBatch:
        tab, o = self.table, self.opt
        mat = surf.material
        world = surf.point + self.origin
        d = rays.direction
        to_eye = -d
        # Two-sided surfaces: turn the normals to the viewer's side of the geometric surface.
        facing = np.where(dot(surf.geometric, to_eye) < 0, -1.0, 1.0)[:, None]
        ng = surf.geometric * facing
        ns = surf.shading * facing
        opacity = tab.opacity[mat]
        local = self.ambient * tab.color("ka", mat, world)
        if self.emitters and tab.lit[mat].any():
            local += self.direct_lighting(surf, mat, world, ns, to_eye, rays.origin)
        add(samples, rays.sample, rays.weight * (opacity[:, None] * local))

        # Children: reflection, refraction (or TIR), see-through.
        children: list[RayBatch] = []
        depth = rays.depth + 1
        tw = rays.weight * opacity[:, None]
        if tab.reflects[mat].any():
            m = tab.reflects[mat]
            kr = tab.color("kr", mat[m], world[m])
            r = reflect(d[m], ns[m])
            r = self._keep_side(r, d[m], ng[m], +1)
            children.append(self._spawn(rays, surf, m, r, tw[m] * kr, REFLECTION))
        if tab.transmits[mat].any():
            m = tab.transmits[mat]
            kt = tab.color("kt", mat[m], world[m])
            entering = dot(d[m], surf.geometric[m]) < 0
            eta = np.where(entering, 1.0 / tab.ior[mat[m]], tab.ior[mat[m]])
            t_dir, tir = refract(d[m], ns[m], eta)
            # Interpolated normals may bend the ray back to the wrong side: use the face.
            wrong = np.where(tir, dot(t_dir, ng[m]) <= 0, dot(t_dir, ng[m]) >= 0)
            if wrong.any():
                t2, tir2 = refract(d[m][wrong], ng[m][wrong], eta[wrong])
                t_dir[wrong], tir[wrong] = t2, tir2
            if depth <= o.max_depth:
                self.stats.total_internal_reflections += int(tir.sum())
            children.append(self._spawn(rays, surf, m, t_dir, tw[m] * kt, REFRACTION))
        if (opacity < 1).any():
            m = opacity < 1
            behind = rays.weight[m] * (1.0 - opacity[m])[:, None]
            children.append(self._spawn(rays, surf, m, d[m], behind, SEE_THROUGH))
        return self._prune(RayBatch.concatenate(children, depth))

    @staticmethod
    def _keep_side(r: np.ndarray, d: np.ndarray, ng: np.ndarray, side: float) -> np.ndarray:
        """Reflect about the face normal where the shading normal sent ``r`` into the surface."""
        wrong = side * dot(r, ng) <= 0
        if wrong.any():
            r[wrong] = reflect(d[wrong], ng[wrong])
        return r

    @staticmethod
    def _spawn(parents: RayBatch, surf: Surface, m: np.ndarray, direction: np.ndarray,
               weight: np.ndarray, kind: int) -> RayBatch:
        """Children of the hits selected by ``m``, leaving along ``direction``."""
        origin = spawn_origins(surf.point[m], surf.geometric[m], surf.offset[m], direction)
        return RayBatch(origin, direction, parents.sample[m], weight, parents.depth + 1,
                        surf.shape[m].copy(), np.full(len(origin), kind, np.int8))

    def _prune(self, rays: RayBatch) -> RayBatch:
        """Drop rays past ``max_depth`` or under ``min_weight`` (Hall & Greenberg 1983)."""
        if not len(rays):
            return rays
        w = rays.weight.max(axis=1)
        alive = w > 0
        if rays.depth > self.opt.max_depth:
            self.stats.pruned_depth += int(alive.sum())
            return RayBatch.empty(rays.depth)
        light = alive & (w < self.opt.min_weight)
        self.stats.pruned_weight += int(light.sum())
        return rays.take(alive & ~light)

    def direct_lighting(self, surf: Surface, mat: np.ndarray, world: np.ndarray,
                        ns: np.ndarray, to_eye: np.ndarray, eye: np.ndarray) -> np.ndarray:
        """Σ_l S_l · f_l · I_l · [kd·max(N·L, 0) + ks·spec] at every hit, (n, 3)."""
        tab = self.table
        n = len(mat)
        out = np.zeros((n, 3))
        lit = tab.lit[mat]
        kd = tab.color("kd", mat, world)
        ks = tab.color("ks", mat, world)
        shin, model = tab.shininess[mat], tab.highlight[mat]
        gour = surf.gouraud
        if gour.any():
            vert = self.accel.tri_corners[surf.triangle[gour]]
            vnrm = self.accel.tri_vnormals[surf.triangle[gour]]
            flip = np.where(dot(surf.geometric[gour], to_eye[gour]) < 0, -1.0, 1.0)
            bary = np.column_stack([1 - surf.uv[gour].sum(1), surf.uv[gour]])
        for em in self.emitters:
            to_light, dist, f = em.incidence(surf.point)
            term = direct(ns, to_light, to_eye, kd, ks, shin, model) * f[:, None]
            if gour.any():
                term[gour] = self._gouraud(em, vert, vnrm, flip, bary, eye[gour], kd[gour],
                                           ks[gour], shin[gour], model[gour])
            cand = lit & np.any(term > 0, axis=1)
            if not cand.any():
                continue
            shadow = self.shadow(surf, cand, to_light[cand], dist[cand])
            out[cand] += term[cand] * shadow * em.color
        return out

    @staticmethod
    def _gouraud(em, vert, vnrm, flip, bary, eye, kd, ks, shin, model) -> np.ndarray:
        """Seed 000's Gouraud shading: the local model at the three vertices, interpolated."""
        acc = np.zeros((len(vert), 3))
        for k in range(3):
            p = vert[:, k]
            nrm = vnrm[:, k] * flip[:, None]
            v = eye - p
            v /= np.maximum(np.linalg.norm(v, axis=1, keepdims=True), 1e-300)
            to_light, _, f = em.incidence(p)
            acc += bary[:, k:k + 1] * direct(nrm, to_light, v, kd, ks, shin, model) * f[:, None]
        return acc

    def shadow(self, surf: Surface, m: np.ndarray, to_light: np.ndarray, dist: np.ndarray
               ) -> np.ndarray:
        """Shadow factor S (k, 3) for the hits selected by ``m`` towards a light.

        Opaque-only scenes use the occlusion query. Otherwise the straight shadow ray walks
        through every surface before the light, multiplying ``t·kt + (1 − t)`` (seed 003).
        """
        tab = self.table
        origin = spawn_origins(surf.point[m], surf.geometric[m], surf.offset[m], to_light)
        shape = surf.shape[m]
        tmax = dist * (1.0 - SHADOW_SHORTEN)
        self.stats.rays["shadow"] += len(origin)
        t0 = time.perf_counter()
        if not self.any_transparent:
            blocked = self.accel.occluded(origin, to_light, shape, tmax)
            self.stats.trace_seconds += time.perf_counter() - t0
            return np.where(blocked, 0.0, 1.0)[:, None] * np.ones(3)
        factor = np.ones((len(origin), 3))
        live = np.arange(len(origin))
        for _ in range(MAX_SHADOW_CROSSINGS):
            hits = self.accel.intersect(origin, to_light[live], shape, tmax)
            h = hits.hit
            if not h.any():
                break
            idx = np.flatnonzero(h)
            for name in ("t", "shape", "triangle", "uv"):
                setattr(hits, name, getattr(hits, name)[idx])
            s2 = self.accel.surface(hits, origin[idx], to_light[live[idx]])
            opac = tab.opacity[s2.material][:, None]
            world = s2.point + self.origin
            kt = tab.color("kt", s2.material, world)
            factor[live[idx]] *= opac * kt + (1.0 - opac)
            go = np.any(factor[live[idx]] > 0, axis=1)
            live, idx = live[idx[go]], idx[go]
            if not len(live):
                break
            origin = spawn_origins(s2.point[go], s2.geometric[go], s2.offset[go], to_light[live])
            shape = s2.shape[go]
            tmax = tmax[idx] - hits.t[go]
            self.stats.rays["shadow"] += len(live)
        else:
            factor[live] = 0.0
        self.stats.trace_seconds += time.perf_counter() - t0
        return factor

    # -- reporting ---------------------------------------------------------------------------
    def _stats(self, nonfinite: int, seconds: float) -> dict:
        st, o = self.stats, self.opt
        rays = dict(st.rays)
        rays["total"] = sum(rays.values())
        return {
            "rays": rays,
            "pruned": {"depth": st.pruned_depth, "weight": st.pruned_weight},
            "total_internal_reflections": st.total_internal_reflections,
            "nonfinite_pixels": nonfinite,
            "degenerate_triangles": self.accel.degenerate,
            "triangles": self.accel.n_triangles,
            "seconds": {"build": self.build_seconds, "trace": st.trace_seconds,
                        "shade": st.shade_seconds, "total": seconds},
            "width": o.width, "height": o.height, "spp": o.spp, "max_depth": o.max_depth,
            "min_weight": o.min_weight, "threads": o.threads,
        }

    def _metadata(self) -> dict:
        o = self.opt
        return {"scene": self.scene.path or "<python>", "width": o.width, "height": o.height,
                "spp": o.spp, "max_depth": o.max_depth, "min_weight": o.min_weight,
                "seed": o.seed, "renderer": "raytrace (Whitted, Embree)"}


def add(samples: np.ndarray, index: np.ndarray, values: np.ndarray) -> None:
    """``samples[index] += values`` with repeated indices summed in a fixed order."""
    n = len(samples)
    for c in range(3):
        samples[:, c] += np.bincount(index, weights=values[:, c], minlength=n)
