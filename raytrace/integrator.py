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

This module is the loop; the per-ray arithmetic of each step is a compiled pass over the batch
in :mod:`raytrace.shading_kernels`. With ``threads`` > 1 the passes run side by side, one
thread a pass (the kernels and Embree release the GIL), like the image tiles of pbrt or
Mitsuba: a pass touches only its own samples, each thread has its own scratch arrays and
counters, and every sample's contributions are summed in a fixed order (depth by depth, in
batch order), so the image does not depend on the number of threads or on which thread
rendered which pass.
"""

from __future__ import annotations

import copy
import dataclasses
import os
import threading
import time
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field

import numpy as np

from . import aov as aov_images
from . import shading_kernels as K
from .accel import SHADOW_SHORTEN, Accelerator, Hits, Surface
from .camera import camera_columns, camera_rays, global_samples
from .film import Image
from .lights import Emitter, emitters
from .material import COLOR_KEYS, Checker, Material
from .rays import (
    KIND_NAMES,
    REFLECTION,
    REFRACTION,
    SEE_THROUGH,
    RayBatch,
    count_kinds,
    sample_chunks,
    split_hits,
    take_hits,
)
from .scene import Scene
from .shading import HIGHLIGHT_CODES

#: Camera samples per pass (whole pixels): the unit of work of a thread. Memory is bounded by
#: threads × pass size, independently of the resolution.
PASS_SAMPLES = 1 << 16
#: A smaller image is cut into this many passes, so that every thread gets some…
MIN_PASSES = 16
#: …but no pass is smaller than this (per-batch Python work would dominate).
MIN_PASS_SAMPLES = 4096
#: Most surfaces a transparent shadow ray passes through before it counts as blocked.
MAX_SHADOW_CROSSINGS = 64
#: Kinds of the children, in the order of :meth:`WhittedIntegrator._spawn`'s columns.
CHILD_KINDS = np.array([REFLECTION, REFRACTION, SEE_THROUGH], np.int8)
#: Check invariants of every spawned batch (unit directions, finite origins): set
#: ``RAYTRACE_DEBUG=1`` in the environment. Off by default (it costs a pass over each batch).
DEBUG = os.environ.get("RAYTRACE_DEBUG", "") not in ("", "0")
NO_LIGHT = np.zeros((0, 3))
NO_KEY = np.zeros(0, np.int64)
#: :func:`add`'s factor for contributions that are already weighted.
ONE = np.ones((1, 3))
#: Per-sample AOV columns (depth, normal, albedo, id) of a render without AOVs, and of an
#: image without one of them: no rows, so :func:`raytrace.shading_kernels.aov_hits` skips it.
NO_AOV_SAMPLES = (np.zeros(0), np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0, np.int64))
NO_AOV_PIXELS = (np.zeros(0, np.float32), np.zeros((0, 3), np.float32),
                 np.zeros((0, 3), np.float32), np.zeros(0, np.int32))


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
    #: Pixel bounds (x0, y0, x1, y1), half-open, of the window to render (None: the frame).
    crop: tuple[int, int, int, int] | None = None
    #: The AOVs to render besides the colour (:data:`raytrace.aov.AOVS`' names).
    aovs: tuple[str, ...] = ()


class MaterialTable:
    """Per-material coefficients, looked up by material index at the hits.

    ``colors`` (M, 15) holds the constant colours ka kd ks kr kt, three columns each
    (``shading_kernels.KA`` …); where colour k of material m is a :class:`Checker`,
    ``pattern[m, k]`` indexes its row of ``checkers`` (colour 0, colour 1, scale), evaluated
    at the world points of the hits; −1 means constant. :attr:`arrays` is the whole table as
    the kernels take it.
    """

    def __init__(self, materials: list[Material]):
        self.materials = materials
        self.colors = np.zeros((len(materials), 3 * len(COLOR_KEYS)))
        self.pattern = np.full((len(materials), len(COLOR_KEYS)), -1, np.int64)
        checkers = []
        for i, m in enumerate(materials):
            for k, key in enumerate(COLOR_KEYS):
                c = m.ambient if key == "ka" else getattr(m, key)
                if isinstance(c, Checker):
                    self.pattern[i, k] = len(checkers)
                    checkers.append([*c.colors[0], *c.colors[1], c.scale])
                else:
                    self.colors[i, 3 * k:3 * k + 3] = c
        self.checkers = np.array(checkers, dtype=np.float64).reshape(-1, 7)
        self.shininess = np.array([m.shininess for m in materials], dtype=np.float64)
        self.highlight = np.array([HIGHLIGHT_CODES[m.highlight] for m in materials], np.int64)
        self.ior = np.array([m.ior for m in materials], dtype=np.float64)
        self.opacity = np.array([m.opacity for m in materials], dtype=np.float64)
        self.lit = np.array([m.lit for m in materials], dtype=bool)
        self.reflects = np.array([m.reflects for m in materials], dtype=bool)
        self.transmits = np.array([m.transmits for m in materials], dtype=bool)
        self.transparent = np.array([m.transparent for m in materials], dtype=bool)
        self.arrays = (self.colors, self.pattern, self.checkers, self.shininess, self.highlight,
                       self.ior, self.opacity, self.lit, self.reflects, self.transmits)


class Scratch:
    """Arrays reused from batch to batch, by name (no batch outgrows the pass): the shading
    passes are quick enough that fresh pages for their temporaries would cost more."""

    def __init__(self):
        self._arrays: dict[str, np.ndarray] = {}

    def __call__(self, name: str, n: int, columns: int = 0, dtype=np.float64) -> np.ndarray:
        """An uninitialised (n,) or (n, columns) C-contiguous array of ``dtype``."""
        a = self._arrays.get(name)
        if a is None or len(a) < n:
            a = self._arrays[name] = np.empty((n, columns) if columns else n, dtype)
        return a[:n]


@dataclass
class Stats:
    """Counters for ``--stats``."""

    rays: dict = field(default_factory=lambda: {k: 0 for k in (*KIND_NAMES, "shadow")})
    pruned_depth: int = 0
    pruned_weight: int = 0
    total_internal_reflections: int = 0
    trace_seconds: float = 0.0
    shade_seconds: float = 0.0
    pass_seconds: float = 0.0

    def merge(self, other: Stats) -> None:
        """Add ``other``'s counts and seconds to these."""
        for k, v in other.rays.items():
            self.rays[k] += v
        self.pruned_depth += other.pruned_depth
        self.pruned_weight += other.pruned_weight
        self.total_internal_reflections += other.total_internal_reflections
        self.trace_seconds += other.trace_seconds
        self.shade_seconds += other.shade_seconds
        self.pass_seconds += other.pass_seconds


class Worker(threading.local):
    """What each rendering thread keeps to itself: scratch arrays, the constant columns of
    its camera rays, and its counters for one render (merged after it, in a fixed order)."""

    def __init__(self):
        self.scratch = Scratch()
        self.camera_columns: RayBatch | None = None  # raytrace.camera.camera_columns
        self.first_sample = 0  # index (in the window) of the current pass's first sample
        self.aov = NO_AOV_SAMPLES  # this pass's per-sample AOV columns
        self.stats: Stats | None = None
        self.render = -1  # the render (WhittedIntegrator._renders) the stats count


class WhittedIntegrator:
    """Renders a scene, pass by pass and depth by depth.

    Samples are numbered within the window rendered (``options.crop``, or the whole frame):
    ``sample = pixel·spp + k``, pixels row by row in the window; each is the same ray, with
    the same jitter, as the sample of the full frame it stands for
    (:func:`raytrace.camera.global_samples`).
    """

    #: An observer of every ray traced (``raytrace.explain.Recorder``), or None: one test per
    #: step of a batch. It sees the integrator's own arrays, so what it records is what was
    #: rendered; with it, a hit's contribution goes through a per-ray row first (the same
    #: additions in the same order, so the same sums).
    observer = None

    def __init__(self, scene: Scene, options: RenderOptions):
        self.scene, self.opt = scene, options
        x0, y0, x1, y1 = options.crop or (0, 0, options.width, options.height)
        #: Columns and rows of the window rendered.
        self.size = (x1 - x0, y1 - y0)
        self._aov_out = NO_AOV_PIXELS  # the AOV images of the render in progress, flat
        seen: dict[int, Material] = {}
        for o in scene.objects:
            seen.setdefault(id(o.material), o.material)
        self.materials = list(seen.values())
        self.table = MaterialTable(self.materials)
        t0 = time.perf_counter()
        self.accel = Accelerator(scene, self.materials)
        self.build_seconds = time.perf_counter() - t0
        self.origin = self.accel.origin
        self.emitters: list[Emitter] = emitters(scene.lights, self.origin, options.seed)
        self.ambient = np.asarray(scene.ambient, np.float64)
        self.background = np.asarray(options.background, np.float64).reshape(1, 3).copy()
        self.any_transparent = bool(self.table.transparent.any()) if self.materials else False
        self.lit = bool(self.emitters) and bool(self.table.lit.any())
        self.jittered = any(em.jittered for em in self.emitters)
        #: What :func:`raytrace.shading_kernels.light_pass` needs of smooth and Gouraud
        #: triangles.
        self.smooth_table = (self.accel.tri_corners, self.accel.tri_vnormals,
                             self.accel.tri_shading)
        self._lock = threading.Lock()
        self._renders = 0  # renders started: each counts its rays afresh
        self._stats_per_thread: list[Stats] = []
        self._worker = Worker()

    def for_window(self, crop: tuple[int, int, int, int] | None,
                   threads: int | None = None) -> WhittedIntegrator:
        """This integrator for another window (``crop``, checked by the caller) of the same
        frame, on ``threads`` threads (default: as this one), without building anything again:
        the copy shares the accelerator (BVH), materials and lights, which are read-only once
        built, and has its own per-render state, so copies may render at the same time on
        different threads. Its images report 0 build seconds (a distributed render's tiles,
        :mod:`raytrace.distributed`, count each build once)."""
        other = copy.copy(self)
        other.opt = dataclasses.replace(
            self.opt, crop=crop, threads=self.opt.threads if threads is None else threads)
        x0, y0, x1, y1 = crop or (0, 0, self.opt.width, self.opt.height)
        other.size = (x1 - x0, y1 - y0)
        other.build_seconds = 0.0
        other._aov_out = NO_AOV_PIXELS
        other._lock = threading.Lock()
        other._renders = 0
        other._stats_per_thread = []
        other._worker = Worker()
        return other

    @property
    def scratch(self) -> Scratch:
        """This thread's scratch arrays."""
        return self._worker.scratch

    @property
    def stats(self) -> Stats:
        """This thread's counters for the current render: new ones, registered for the
        merge, the first time a thread asks in a render."""
        w = self._worker
        if w.render != self._renders:
            w.stats, w.render = Stats(), self._renders
            with self._lock:
                self._stats_per_thread.append(w.stats)
        return w.stats

    @property
    def pass_size(self) -> int:
        """Camera samples per pass, in whole pixels: at most ``pass_samples``, and for images
        of fewer than :data:`MIN_PASSES` full passes, a :data:`MIN_PASSES`-th of the image
        (not below :data:`MIN_PASS_SAMPLES`), so small images still use every thread. It
        depends on the image and the options, never on the number of threads."""
        o = self.opt
        total = self.size[0] * self.size[1] * o.spp
        size = min(o.pass_samples, max(MIN_PASS_SAMPLES, -(-total // MIN_PASSES)))
        return max(o.spp, (size // o.spp) * o.spp)

    # -- the loop ----------------------------------------------------------------------------
    def render(self, progress: Callable[[int, int], None] | None = None) -> Image:
        """The image, pass by pass on ``threads`` threads (the calling one included);
        ``progress(done, total)`` is called, one thread at a time, after each pass."""
        o = self.opt
        t_start = time.perf_counter()
        with self._lock:  # a second render of this integrator counts from zero
            self._renders += 1
            self._stats_per_thread = []
        cols, rows = self.size
        total = cols * rows * o.spp
        per_pass = self.pass_size
        passes = [(a, min(a + per_pass, total)) for a in range(0, total, per_pass)]
        # Each pass rounds its pixels to float32 as it ends (the same rounding as at the end
        # would be), so no float64 copy of the whole image is held.
        pixels = np.empty((cols * rows, 3), dtype=np.float32)
        aovs = {name: aov_images.empty(name, (rows, cols)) for name in o.aovs}
        flat = {name: a.reshape(len(pixels), *a.shape[2:]) for name, a in aovs.items()}
        self._aov_out = tuple(flat.get(name, none)
                              for name, none in zip(aov_images.AOVS, NO_AOV_PIXELS, strict=True))
        self._run(passes, pixels, progress, total)
        t_passes = time.perf_counter() - t_start
        rgb = pixels.reshape(rows, cols, 3)
        bad = ~np.isfinite(rgb)
        nonfinite = 0
        if bad.any():
            nonfinite = int(bad.any(axis=2).sum())
            rgb[bad] = 0.0
        seconds = time.perf_counter() - t_start + self.build_seconds
        return Image(rgb, self._stats(nonfinite, seconds, t_passes), self._metadata(), aovs,
                     o.crop, (o.width, o.height))

    def _run(self, passes: list[tuple[int, int]], pixels: np.ndarray,
             progress: Callable[[int, int], None] | None, total: int) -> None:
        """Render ``passes`` into ``pixels``: the threads take the next pass from a shared
        queue until none is left. After an exception in any thread (Ctrl-C included), no
        thread starts another pass, and the first exception is raised once all have
        stopped."""
        queue, stop, done = iter(passes), threading.Event(), [0]

        def work() -> None:
            while not stop.is_set():
                with self._lock:
                    item = next(queue, None)
                if item is None:
                    return
                try:
                    self._render_pass(*item, pixels)
                except BaseException:
                    stop.set()
                    raise
                if progress is not None:
                    with self._lock:
                        done[0] += item[1] - item[0]
                        progress(done[0], total)

        threads = min(self.opt.threads, len(passes))
        if threads <= 1:
            work()
            return
        with ThreadPoolExecutor(threads - 1, thread_name_prefix="raytrace") as pool:
            others = [pool.submit(work) for _ in range(threads - 1)]
            try:
                work()
            finally:
                for f in others:  # each finishes the pass it is on
                    f.exception()
            for f in others:
                f.result()

    def _render_pass(self, start: int, stop: int, pixels: np.ndarray) -> None:
        """Camera samples ``start`` to ``stop`` (whole pixels), depth by depth, into their
        pixels (and AOVs)."""
        o, w, n = self.opt, self._worker, stop - start
        t0 = time.perf_counter()
        samples = self.scratch("samples", n, 3)
        samples.fill(0.0)
        if o.aovs:
            w.aov = self._aov_samples(n)
        self.trace_samples(start, stop, samples)
        first, last = start // o.spp, stop // o.spp
        with np.errstate(over="ignore", invalid="ignore"):  # beyond float32's range → inf
            pixels[first:last] = (
                samples if o.spp == 1 else samples.reshape(-1, o.spp, 3).mean(1))
        if o.aovs:
            K.aov_pixels(last - first, o.spp, *w.aov,
                         *(a[first:last] for a in self._aov_out))
        self.stats.pass_seconds += time.perf_counter() - t0

    def trace_samples(self, start: int, stop: int, samples: np.ndarray) -> None:
        """Add into ``samples`` (stop − start, 3) everything the samples ``start`` to ``stop``
        of the window see: their camera rays, then depth by depth.

        A batch grown past the pass size (2 children per glass hit) is cut into chunks that
        keep each sample's rays together (:func:`raytrace.rays.sample_chunks`), finished one
        after another, so memory stays bounded by the pass size × max_depth rather than
        growing as 2^depth, and each sample's sum is added up in the same order whatever the
        pass size, the crop or the threads."""
        o, w, n = self.opt, self._worker, stop - start
        w.first_sample = start
        if w.camera_columns is None or len(w.camera_columns.origin) < n:
            w.camera_columns = camera_columns(n)
        rays = camera_rays(self.scene.camera, o.width, o.height, o.spp, o.seed, start, stop,
                           w.camera_columns, self.scratch("camera_direction", n, 3), o.crop)
        per_pass = self.pass_size
        pending = [rays]
        while pending:
            rays = pending.pop()
            if len(rays) > per_pass:
                pending.extend(reversed(chunks(rays, n, per_pass)))
                continue
            children = self.trace(rays, samples)
            if len(children):
                pending.append(children)

    def _aov_samples(self, n: int) -> tuple[np.ndarray, ...]:
        """This thread's per-sample AOV columns for a pass of ``n`` samples, set to a miss
        (depth +inf, normal and albedo 0, id −1); no rows for what was not asked for (depth
        is kept for id too: the nearest sample's id)."""
        want, new = self.opt.aovs, self.scratch
        depth, normal, albedo, ident = NO_AOV_SAMPLES
        if "depth" in want or "id" in want:
            depth = new("aov_depth", n)
            depth.fill(np.inf)
        if "normal" in want:
            normal = new("aov_normal", n, 3)
            normal.fill(0.0)
        if "albedo" in want:
            albedo = new("aov_albedo", n, 3)
            albedo.fill(0.0)
        if "id" in want:
            ident = new("aov_id", n, dtype=np.int64)
            ident.fill(-1)
        return depth, normal, albedo, ident

    def trace(self, rays: RayBatch, samples: np.ndarray) -> RayBatch:
        """One depth: intersect, add background and local shading, return the next depth."""
        st, o, n = self.stats, self.opt, len(rays)
        counts = np.zeros(len(KIND_NAMES), np.int64)
        count_kinds(rays.kind, counts)
        for name, count in zip(KIND_NAMES, counts.tolist(), strict=True):
            st.rays[name] += count
        t0 = time.perf_counter()
        hits = self.accel.intersect(rays.origin, rays.direction, rays.origin_shape)
        st.trace_seconds += time.perf_counter() - t0
        found, missed = (self.scratch(name, n, dtype=np.int64) for name in ("found", "missed"))
        k = split_hits(hits.t, found, missed)
        found, missed = found[:k], missed[:n - k]
        if self.observer is not None:
            self.observer.traced(rays, found, missed, self.background)
        if len(missed) and np.any(o.background):
            add(samples, rays.sample, rays.weight, self.background, missed)
        if not len(found):
            return RayBatch.empty(rays.depth + 1)
        t1 = time.perf_counter()
        trace_before = st.trace_seconds
        if len(found) < len(rays):  # compaction: only the hits go on, in one pass
            k, new = len(found), self.scratch  # these rays and hits end with this call
            out = tuple(new(f"hit_{i}", k, *shape) for i, shape in enumerate((
                (3,), (3,), (0, rays.sample.dtype), (3,), (0, rays.origin_shape.dtype),
                (0, rays.kind.dtype), (0, hits.t.dtype), (0, hits.shape.dtype),
                (0, hits.triangle.dtype), (hits.uv.shape[1], hits.uv.dtype))))
            take_hits(found, rays.origin, rays.direction, rays.sample, rays.weight,
                      rays.origin_shape, rays.kind, hits.t, hits.shape, hits.triangle, hits.uv,
                      out)
            origin, direction, sample, weight, origin_shape, kind = out[:6]
            hits.t, hits.shape, hits.triangle, hits.uv = out[6:]
            rays = RayBatch(origin, direction, sample, weight, rays.depth, origin_shape, kind)
        surf = self.accel.surface(hits, rays.origin, rays.direction)
        if rays.depth == 0 and o.aovs:  # the camera rays' first hits
            self.aov_hits(rays, hits, surf, *self._worker.aov)
        if self.observer is not None:
            self.observer.hits(rays, hits, surf)
        children = self.shade(rays, surf, samples)
        st.shade_seconds += time.perf_counter() - t1 - (st.trace_seconds - trace_before)
        return children

    def aov_hits(self, rays: RayBatch, hits: Hits, surf: Surface, depth: np.ndarray,
                 normal: np.ndarray, albedo: np.ndarray, ident: np.ndarray) -> None:
        """Write the AOVs of the hits (rays that all hit) into the rows ``rays.sample`` of the
        outputs (:func:`raytrace.shading_kernels.aov_hits`; an output without rows is
        skipped)."""
        a = self.accel
        K.aov_hits(rays.sample, hits.t, rays.direction, surf.geometric, surf.shading,
                   surf.material, surf.point, self.origin, self.table.arrays, surf.shape,
                   surf.triangle, a.shape_object, a.geom_first, a.geom_object, depth, normal,
                   albedo, ident)

    # -- shading -----------------------------------------------------------------------------

    def shade(self, rays: RayBatch, surf: Surface, samples: np.ndarray) -> RayBatch:
        """Add ``weight·t·I_local`` of every hit to its sample (t the opacity) and return the
        children, with

            I_local = ka·Ia + Σ_l S_l·f_l·I_l·[kd·max(N·L, 0) + ks·spec]

        N turned to the viewer (two-sided surfaces), V = −d.
        """
        n, new = len(rays), self.scratch
        lights = self.direct_lighting(rays, surf) if self.lit else NO_LIGHT  # Σ_l S_l·f_l·…
        # One pass over the hits: w·t·I_local into their samples, and each child's direction,
        # weight and status.
        r_dir, t_dir, w_r, w_t, w_s = (new(name, n, 3) for name in (
            "r_dir", "t_dir", "w_r", "w_t", "w_s"))
        status, tir = new("status", n, 3, np.int8), new("tir", n, dtype=bool)
        # Observed, each hit's term goes to a row of its own, then to its sample: the same
        # additions in the same order (0 + x and x·1 are exact).
        obs = self.observer
        into, rows = (samples, rays.sample) if obs is None else (np.zeros((n, 3)), np.arange(n))
        K.hit_terms(rays.direction, rays.weight, surf.geometric, surf.shading, surf.material,
                    surf.point, self.origin, self.table.arrays, self.ambient, lights,
                    self.opt.min_weight, into, rows, r_dir, t_dir, w_r, w_t, w_s, status, tir)
        depth = rays.depth + 1
        if obs is not None:
            add(samples, rays.sample, into, ONE, rows)
            obs.shaded(into, status, (w_r, w_t, w_s), tir, depth > self.opt.max_depth)
        if depth <= self.opt.max_depth:
            self.stats.total_internal_reflections += int(np.count_nonzero(tir))
        # The next depth: reflected, refracted (or TIR) and see-through children.
        if not self._prune(status, depth):
            return RayBatch.empty(depth)
        children, parent = self._spawn(rays, surf, status, (r_dir, t_dir, rays.direction),
                                       (w_r, w_t, w_s))
        if obs is not None:
            obs.spawned(children, parent)
        return children

    def _spawn(self, parents: RayBatch, surf: Surface, status: np.ndarray, directions: tuple,
               weights: tuple) -> tuple[RayBatch, np.ndarray]:
        """The children of the hits whose ``status`` is KEEP, in one batch (reflected, then
        refracted, then see-through, each in hit order), and the row of each one's parent
        hit; ``directions`` and ``weights``: reflected, refracted, see-through. Two passes:
        count the children of each kind (:func:`raytrace.shading_kernels.count_keep`), then
        fill the rows from where each kind starts
        (:func:`raytrace.shading_kernels.spawn_children`)."""
        per_kind = K.count_keep(status)
        first = np.concatenate([[0], np.cumsum(per_kind)[:-1]])  # where each kind starts
        k = int(per_kind.sum())
        origin, direction, weight = np.empty((k, 3)), np.empty((k, 3)), np.empty((k, 3))
        sample, shape = np.empty(k, np.int64), np.empty(k, np.int64)
        kind, parent = np.empty(k, np.int8), np.empty(k, np.int64)
        K.spawn_children(status, first, *directions, *weights, surf.point, surf.geometric,
                         surf.offset, surf.shape, parents.sample, CHILD_KINDS, origin,
                         direction, weight, sample, shape, kind, parent)
        children = RayBatch(origin, direction, sample, weight, parents.depth + 1, shape, kind)
        if DEBUG:
            check_spawned(children)
        return children, parent

    def _prune(self, status: np.ndarray, depth: int) -> bool:
        """Whether any children (the columns of ``status``) may go on: none past
        ``max_depth``, none under ``min_weight`` (Hall & Greenberg 1983); the dropped ones are
        counted."""
        if depth > self.opt.max_depth:
            self.stats.pruned_depth += int(np.count_nonzero(status))
            return False
        self.stats.pruned_weight += int(np.count_nonzero(status == K.LIGHT))
        return True

    def direct_lighting(self, rays: RayBatch, surf: Surface) -> np.ndarray:
        """Σ_l S_l · f_l · I_l · [kd·max(N·L, 0) + ks·spec] at every hit, (n, 3): per emitter,
        one pass for the unshadowed term and the shadow rays of the hits it lights
        (:func:`raytrace.shading_kernels.light_pass`), then their shadow factors."""
        n, new = len(rays), self.scratch
        out = new("lights", n, 3)
        out.fill(0.0)
        term, rows = new("term", n, 3), new("shadow_rows", n, dtype=np.int64)
        origin, direction = new("shadow_origin", n, 3), new("shadow_direction", n, 3)
        tmax, shape = new("shadow_tmax", n), new("shadow_shape", n, dtype=np.int64)
        shadow = (rows, origin, direction, tmax, shape)
        # Jittered area lights draw a point per hit from its global camera sample and depth.
        key = global_samples(rays.sample + self._worker.first_sample, self.opt.width,
                             self.opt.spp, self.opt.crop) if self.jittered else NO_KEY
        for e, em in enumerate(self.emitters):
            k = K.light_pass(surf.point, surf.geometric, surf.shading, rays.direction,
                             rays.origin, surf.material, surf.offset, surf.shape, surf.triangle,
                             surf.uv, self.origin, self.table.arrays,
                             self.smooth_table, em.packed, key, rays.depth, SHADOW_SHORTEN, term,
                             shadow)
            if self.observer is not None:
                self.observer.light(e, term, rows[:k])
            if k:
                self.shadow(out, term, np.asarray(em.color, np.float64),
                            *(column[:k] for column in shadow))
        return out

    def shadow(self, out: np.ndarray, term: np.ndarray, color: np.ndarray, rows: np.ndarray,
               origin: np.ndarray, direction: np.ndarray, tmax: np.ndarray,
               shape: np.ndarray) -> None:
        """``out[rows] += term[rows]·S·I_l``, with S (k, 3) the shadow factor of the shadow
        rays (``origin``, ``direction``, ``tmax``, starting on ``shape``) of the hits ``rows``.

        Opaque-only scenes use the occlusion query: S is 0 or 1. Otherwise the straight
        shadow ray walks through every surface before the light, multiplying
        ``t·kt + (1 − t)`` (seed 003).
        """
        self.stats.rays["shadow"] += len(rows)
        t0 = time.perf_counter()
        if not self.any_transparent:
            blocked = self.accel.occluded(origin, direction, shape, tmax)
            self.stats.trace_seconds += time.perf_counter() - t0
            K.add_unblocked(out, rows, term, blocked, color)
            if self.observer is not None:
                self.observer.shadow(np.where(blocked[:, None], 0.0, np.ones(3)))
            return
        factor = self.scratch("shadow", len(rows), 3)
        factor.fill(1.0)
        live = np.arange(len(rows))  # the row of factor each walking ray multiplies
        tab = self.table.arrays
        for _ in range(MAX_SHADOW_CROSSINGS):
            hits = self.accel.intersect(origin, direction, shape, tmax)
            t, hit_shape, triangle, uv, origin, direction, tmax, live = K.crossing_rays(
                hits.t, hits.shape, hits.triangle, hits.uv, origin, direction, tmax, live)
            if not len(live):
                break
            s2 = self.accel.surface(Hits(t, hit_shape, triangle, uv), origin, direction)
            origin, direction, shape, tmax, live = K.cross_surfaces(
                factor, live, s2.material, s2.point, s2.geometric, s2.offset, s2.shape,
                direction, t, tmax, self.origin, tab)
            if not len(live):
                break
            self.stats.rays["shadow"] += len(live)
        else:
            factor[live] = 0.0
        self.stats.trace_seconds += time.perf_counter() - t0
        K.add_light(out, rows, term, factor, color)
        if self.observer is not None:
            self.observer.shadow(factor.copy())

    # -- reporting ---------------------------------------------------------------------------
    def _stats(self, nonfinite: int, seconds: float, pass_wall: float) -> dict:
        """The ``--stats`` dictionary. Counts are summed over the threads. ``trace`` and
        ``shade`` are wall seconds: the passes' wall time split in proportion to the thread
        time spent tracing and shading, so build + trace + shade ≤ total with any number of
        threads."""
        st, o = Stats(), self.opt
        for part in self._stats_per_thread:
            st.merge(part)
        share = pass_wall / st.pass_seconds if st.pass_seconds > 0 else 0.0
        rays = dict(st.rays)
        rays["total"] = sum(rays.values())
        return {
            "rays": rays,
            "pruned": {"depth": st.pruned_depth, "weight": st.pruned_weight},
            "total_internal_reflections": st.total_internal_reflections,
            "nonfinite_pixels": nonfinite,
            "degenerate_triangles": self.accel.degenerate,
            "triangles": self.accel.n_triangles,
            "seconds": {"build": self.build_seconds, "trace": st.trace_seconds * share,
                        "shade": st.shade_seconds * share, "total": seconds},
            "width": o.width, "height": o.height, "spp": o.spp, "max_depth": o.max_depth,
            "min_weight": o.min_weight, "threads": o.threads,
            **({"crop": list(o.crop)} if o.crop else {}),
            **({"aovs": list(o.aovs)} if o.aovs else {}),
        }

    def _metadata(self) -> dict:
        o = self.opt
        return {"scene": self.scene.path or "<python>", "width": o.width, "height": o.height,
                "spp": o.spp, "max_depth": o.max_depth, "min_weight": o.min_weight,
                "seed": o.seed, "renderer": "raytrace (Whitted, Embree)",
                **({"crop": " ".join(map(str, o.crop))} if o.crop else {})}


def chunks(rays: RayBatch, samples: int, most: int) -> list[RayBatch]:
    """``rays`` (of ``samples`` pixel samples) cut into batches of at most ``most`` rays that
    keep each sample's rays together, in batch order (:func:`raytrace.rays.sample_chunks`)."""
    chunk = np.empty(len(rays), np.int64)
    count = sample_chunks(rays.sample, samples, most, chunk)
    order = np.argsort(chunk, kind="stable")
    bounds = np.searchsorted(chunk[order], np.arange(count + 1))
    return [rays.take(order[a:b]) for a, b in zip(bounds[:-1], bounds[1:], strict=True)]


def check_spawned(rays: RayBatch) -> None:
    """The debug path's invariants of a spawned batch (:data:`DEBUG`): every direction a unit
    vector (to 1e-9; SCENE_FORMAT.md's smooth-mesh rules) and every origin finite."""
    length = np.linalg.norm(rays.direction, axis=1)
    bad = np.flatnonzero(~(np.abs(length - 1.0) <= 1e-9))
    assert not len(bad), (f"{len(bad)} spawned directions are not a unit vector, e.g. "
                          f"{rays.direction[bad[0]].tolist()} of length {length[bad[0]]!r}")
    assert np.isfinite(rays.origin).all(), "a spawned ray has a non-finite origin"


def add(samples: np.ndarray, sample: np.ndarray, weight: np.ndarray, factor: np.ndarray,
        rows: np.ndarray) -> None:
    """``samples[sample[r]] += weight[r]·factor[r]`` for the rays ``rows`` (``factor`` of one
    row applies to every ray), one ray after another in batch order
    (:func:`raytrace.shading_kernels.accumulate`)."""
    K.accumulate(samples, sample, weight, factor, rows)
