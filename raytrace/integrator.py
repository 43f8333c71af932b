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

This module describes the loop and runs it two ways, step for step the same: here in Python,
batch by batch, each step a compiled pass over the batch (:mod:`raytrace.kernels.shading`,
:mod:`raytrace.accel`: how renders run by default, what ``raytrace explain``'s observer
watches), and compiled, every depth of a pass in one ``nogil`` call
(:func:`raytrace.kernels.loop.trace_paths`, with ``RAYTRACE_LOOP=compiled``:
:data:`COMPILED_LOOP`). Both call the same kernels in the same order, so they give the same
images bit for bit (tests/test_loop.py). With ``threads`` > 1 the passes run side by side, one
thread a pass (the kernels and Embree release the GIL), like the image tiles of pbrt or
Mitsuba: a pass touches only its own samples, each thread has its own scratch arrays and
counters, and every sample's contributions are summed in a fixed order (depth by depth, in
batch order), so the image does not depend on the number of threads or on which thread
rendered which pass.

A render can be asked to end early (:class:`Stop`: Ctrl-C, the memory ceiling of
:mod:`raytrace.rendering`): the passes run on pass threads (:func:`pass_threads`) while the
calling thread only waits, so it takes a Ctrl-C at once (Python runs signal handlers in the
main thread, between bytecodes, never inside a compiled call); each pass reads the stop flag
before each batch and each light's pass over it, the compiled loop too, so a render ends
within one of those steps.
"""

from __future__ import annotations

import copy
import ctypes
import dataclasses
import os
import sys
import threading
import time
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from concurrent.futures import wait as wait_for
from dataclasses import dataclass, field

import numpy as np

from . import adaptive, fast_phong, noise, sampling
from .accel import Hits, Surface
from .accel_cache import accelerator
from .camera import camera_columns, camera_rays, directions_at, global_samples, grid, pinhole
from .film import aov as aov_images
from .film import filters
from .film.image import Image
from .kernels import loop
from .kernels import shading as sk  # the compiled passes of this stage
from .kernels.aov import aov_hits, aov_pixels
from .kernels.camera import block_shape, own_hits, pixel_packets
from .kernels.kinds import KIND_NAMES
from .kernels.rays import count_kinds, gather_chunks, sample_chunks, split_hits, take_hits
from .kernels.records import (
    EMITTER_FIELDS,
    FAST_COLUMNS,
    AOVLayout,
    CameraPackets,
    Children,
    LightTable,
    Local,
    Objects,
    PassIO,
    PassSettings,
    Rays,
    SampleSums,
    Sampling,
    Shadows,
    ShadowWalk,
    Spawned,
    Tally,
    Tracer,
)
from .lights import Emitter, emitters
from .mipmap import with_mips, with_spread
from .rays import NO_SHAPE, RayBatch
from .scene import RenderSettings, Scene
from .shading import NO_KEY, light_words, path_keys
from .tables import scene_arrays

#: Camera samples per pass (whole pixels): the unit of work of a thread. Memory is bounded by
#: threads × pass size, independently of the resolution.
PASS_SAMPLES = 1 << 16
#: A smaller image is cut into this many passes, so that more threads get some…
MIN_PASSES = 16
#: …or, where fewer threads render it, into this many a thread (rounded up to a multiple of
#: the threads, so that they end together, as near as whole bands of camera-ray blocks
#: allow): each pass drives its depths from Python, so a frame in fewer, larger passes
#: renders faster (:func:`frame_passes`).
PASSES_PER_THREAD = 2
#: …but no pass is smaller than this: the Python loop's work per depth, and the two threads'
#: turns at the GIL, make smaller passes slow (2 threads, 160×120 at 4 spp cut into 16
#: passes: a Whitted frame in 0.134 s at passes of 4 800 samples, 0.094 at 8 192, 0.077 at
#: 16 384, 0.082 at 32 768; docs/performance.md, "Threads"). A frame of fewer than 16 such
#: passes gets fewer threads.
MIN_PASS_SAMPLES = 16384
#: The least pass of a noise-driven round (:func:`round_pass_size`): a small round still goes
#: to every thread of a many-core machine.
MIN_ROUND_PASS_SAMPLES = 4096
#: Most surfaces a transparent shadow ray passes through before it counts as blocked
#: (:data:`raytrace.kernels.loop.MAX_SHADOW_CROSSINGS`, one value for both loops).
MAX_SHADOW_CROSSINGS = loop.MAX_SHADOW_CROSSINGS
#: Kinds of the children, in the order of :meth:`WhittedIntegrator._spawn`'s columns.
CHILD_KINDS = loop.CHILD_KINDS
#: Check invariants of every spawned batch (unit directions, finite origins): set
#: ``RAYTRACE_DEBUG=1`` in the environment. Off by default (it costs a pass over each batch).
DEBUG = os.environ.get("RAYTRACE_DEBUG", "") not in ("", "0")
#: Run every pass through the compiled loop (:mod:`raytrace.kernels.loop`): set
#: ``RAYTRACE_LOOP=compiled``. Off by default: it renders the same images bit for bit, but a
#: first render compiles for 2.5× as long (40 s for a matte scene against 15 s; numba links
#: and optimizes every kernel again into each variant of the loop: docs/performance.md,
#: "The compiled loop").
COMPILED_LOOP = os.environ.get("RAYTRACE_LOOP", "") == "compiled"
#: Trace camera rays through meshes in Embree's COHERENT packets, each packet a block of the
#: frame's pixels that fills it (:func:`raytrace.kernels.camera.frame_packets`), or a
#: noise-driven round's samples of one pixel (:func:`raytrace.kernels.camera.pixel_packets`):
#: the warm mesh frame takes 0.81–0.83 of its one-thread time (docs/decisions.md). A tie on a
#: shared edge is traced again in a plain packet (:func:`raytrace.kernels.embree.closest_hits`),
#: and a packet is the same rays in any crop, pass or tile, so those stay bit-identical even
#: where triangles overlap in one plane. ``RAYTRACE_COHERENT_CAMERA=0`` (or false, off, no) turns it
#: off (plain packets, each ray answered as its single-ray call would).
COHERENT_CAMERA = os.environ.get("RAYTRACE_COHERENT_CAMERA", "").lower() not in (
    "0", "false", "off", "no")
#: Seconds between two looks of the thread waiting for the passes at whether a Ctrl-C came.
#: On Linux a SIGINT ends the lock wait itself (CPython waits on a POSIX semaphore there), so
#: the look is only a net for a signal that lands between Python's last check and the wait:
#: 1 s. macOS and Windows, whose lock waits no signal ends, look every 0.1 s. Each wake takes
#: the GIL from the passes: at 0.1 s, 6 % of a 2-thread mesh render's GIL samples
#: (benchmarks/gil.py).
WAKE_SECONDS = 1.0 if sys.platform.startswith("linux") else 0.1
NO_LIGHT = np.zeros((0, 3))
#: :func:`add`'s factor for contributions that are already weighted.
ONE = np.ones((1, 3))
#: The per-pixel AOV table of a render without AOVs (:func:`raytrace.film.aov.layout`).
NO_AOV_PIXELS = np.zeros((0, 1))


def monotonic_clock() -> tuple[int, int]:
    """The address of the C library's ``clock_gettime`` and its monotonic clock's id, for the
    compiled loop's trace and shade seconds ((0, 0) where there is none: those read 0)."""
    try:
        return ctypes.cast(ctypes.CDLL(None).clock_gettime, ctypes.c_void_p).value, \
            time.CLOCK_MONOTONIC
    except (AttributeError, OSError, TypeError):
        return 0, 0


CLOCK = monotonic_clock()


@dataclass(kw_only=True)
class RenderOptions(RenderSettings):
    """Everything one render is asked for: the scene's ``[render]`` settings
    (:class:`raytrace.scene.RenderSettings`, checked the same way) and how to run it. Built
    with keywords only (``raytrace.rendering.render_options`` makes it from a scene and
    overrides)."""

    threads: int = 1
    pass_samples: int = PASS_SAMPLES
    #: Pixel bounds (x0, y0, x1, y1), half-open, of the window to render (None: the frame).
    crop: tuple[int, int, int, int] | None = None
    #: The AOVs to render besides the colour (:data:`raytrace.film.aov.AOVS`' names).
    aovs: tuple[str, ...] = ()
    #: ``aa = "noise"``: stop once the estimated relative RMSE is at most this (None: no
    #: target; :func:`raytrace.noise.relative_rmse`).
    target_error: float | None = None
    #: ``aa = "noise"``: start no pass after this many seconds from the render's start, the
    #: build included (None: no limit; the first round, ``min_spp`` a pixel, always ends;
    #: the last round is sized to the time left, :func:`raytrace.noise.time_share`).
    time_limit: float | None = None

    def __post_init__(self) -> None:
        """Checked as :class:`raytrace.scene.RenderSettings`; ``min_spp`` None becomes the
        first round's default, by threshold or by target error or time
        (:data:`raytrace.sampling.MIN_SPP`, :data:`raytrace.sampling.MIN_SPP_GOAL`), at most
        ``max_spp``."""
        super().__post_init__()
        if self.min_spp is None:
            goal = self.target_error is not None or self.time_limit is not None
            self.min_spp = min(sampling.MIN_SPP_GOAL if goal else sampling.MIN_SPP,
                               self.max_spp)


class Stop:
    """A request to end a render early, and what the render then raises: set from any thread
    (:meth:`request`: the thread waiting for the passes on a Ctrl-C, the memory watch of
    :mod:`raytrace.rendering`, a pass that failed), read by every pass before each batch, the
    compiled loop included (``flag``, its :class:`raytrace.kernels.records.PassIO` field). The
    first request wins."""

    def __init__(self):
        #: (1,) int64, 1 once a stop is asked for: the compiled loop reads it without the GIL.
        self.flag = np.zeros(1, np.int64)
        #: What the render raises once its passes have stopped (None: not asked).
        self.reason: BaseException | None = None
        self._lock = threading.Lock()

    def request(self, reason: BaseException) -> None:
        """Ask the render to stop and raise ``reason`` (ignored after a first request)."""
        with self._lock:
            if self.reason is None:
                self.reason = reason
                self.flag[0] = 1

    @property
    def requested(self) -> bool:
        """Whether a stop was asked for."""
        return bool(self.flag[0])

    def check(self) -> None:
        """Raise the reason of a stop asked for; nothing otherwise."""
        if self.reason is not None:
            raise self.reason


class PassThreads(threading.local):
    """Each calling thread's pool of pass threads (:func:`pass_threads`)."""

    pool: ThreadPoolExecutor | None = None
    size = 0


_pass_threads = PassThreads()


def pass_threads(n: int) -> ThreadPoolExecutor:
    """The calling thread's pool of at least ``n`` pass threads, kept from render to render
    (each calling thread its own, so that renders from several threads, a Dask worker's say,
    run side by side): a pass thread's glibc heap (an arena per thread) serves the next
    render's passes too, as the tuned allocator means it to (:mod:`raytrace.malloc`).
    Idle threads wait on the pool's queue; they end with the pool."""
    own = _pass_threads
    if own.size < n:
        if own.pool is not None:
            own.pool.shutdown(wait=False)
        own.pool, own.size = ThreadPoolExecutor(n, thread_name_prefix="raytrace"), n
    return own.pool


def frame_passes(samples: int, threads: int, most: int) -> int:
    """How many passes a frame of ``samples`` camera samples is cut into evenly on
    ``threads`` threads, before :attr:`WhittedIntegrator.pass_size` bounds a pass by ``most``
    and :data:`MIN_PASS_SAMPLES` and rounds it to whole pixels: :data:`MIN_PASSES`, so that
    16 threads get some; where :data:`PASSES_PER_THREAD` a thread is fewer, that many, or the
    fewest of at most ``most`` samples, rounded up to a multiple of the threads so that each
    takes as many (as near as :attr:`WhittedIntegrator.pass_size`'s whole pixels or bands
    within ``most`` allow: one pass more may be left).

    Each pass drives its depths from Python, between ~150 kernel calls, so a frame in fewer,
    larger passes renders faster: on 2 threads 160×120 at 16 samples a pixel in 6 passes
    takes 0.76–0.80× the time of 16 on the Whitted scene, 0.91–0.92× that of 18 on the mesh
    scene (docs/performance.md, "Threads": ``python3 benchmarks/passes.py --per-thread``)."""
    least = PASSES_PER_THREAD * threads
    if least >= MIN_PASSES:
        return MIN_PASSES
    count = max(least, -(-samples // most))
    return -(-count // threads) * threads


def round_pass_size(samples: int, threads: int, most: int) -> int:
    """Samples a pass of a noise-driven round of ``samples`` samples on ``threads`` threads:
    the fewest passes of at most ``most`` samples, rounded up to a multiple of the threads and
    cut evenly, so that each thread takes as many whole passes and they end together (a round
    orders its pixels so that any run of them holds a like share of sky and of geometry,
    :func:`raytrace.noise.spread_order`); none under :data:`MIN_ROUND_PASS_SAMPLES` unless
    ``most`` (which bounds the memory a pass takes) is smaller.

    One pass a thread where a round fits: each pass pays its depths' Python and kernel
    dispatch once, however few its samples, and two threads wait for each other's turns at
    the GIL. 16 samples a pixel in three rounds of 4, 4 and 8 take 163 ms cut so, 190 ms in
    two passes a thread and 195 ms in three, against 134 ms in one round of 16 (the mesh
    scene at 160×120 on 2 threads, medians of 12: ``python3 benchmarks/noise_passes.py
    --per-thread 1 2 3 --seeds 12``; the third round's 153 600 samples go in two passes a
    thread in the first two cuts, at most 65 536 a pass; docs/sampling.md, "Stopping by
    error or time")."""
    count = -(-samples // most)
    count = -(-count // threads) * threads
    return min(most, max(MIN_ROUND_PASS_SAMPLES, -(-samples // count)))


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
        self.keys: np.ndarray | None = None  # adaptive: each sample's lattice id (light key)
        self.aov = NO_AOV_PIXELS  # this pass's per-sample AOV table
        self.stats: Stats | None = None
        self.render = -1  # the render (WhittedIntegrator._renders) the stats count


class WhittedIntegrator:
    """Renders a scene, pass by pass and depth by depth.

    Samples are numbered within the window rendered (``options.crop``, or the whole frame):
    ``sample = pixel·spp + k``, pixels row by row in the window; each is the same ray, with
    the same jitter, as the sample of the full frame it stands for
    (:func:`raytrace.camera.global_samples`).
    """

    #: An observer of every ray traced (``raytrace.raytree.Recorder``), or None: one test per
    #: step of a batch. It sees the integrator's own arrays, so what it records is what was
    #: rendered; with it, a hit's contribution goes through a per-ray row first (the same
    #: additions in the same order, so the same sums).
    observer = None
    #: Whether passes run the compiled loop (:data:`COMPILED_LOOP`; the Python loop runs
    #: where this is False, where an observer watches, or under ``RAYTRACE_DEBUG``): tests
    #: compare the two.
    compiled = COMPILED_LOOP
    #: Whether camera rays go in COHERENT packets (:data:`COHERENT_CAMERA`).
    coherent_camera = COHERENT_CAMERA

    def __init__(self, scene: Scene, options: RenderOptions):
        self.scene = scene
        self._set_options(options)
        self._aov_out = NO_AOV_PIXELS  # the AOV images of the render in progress, flat
        t0 = time.perf_counter()
        #: The scene as arrays, camera-relative (:func:`raytrace.tables.scene_arrays`).
        self.arrays = scene_arrays(scene)
        self.accel = accelerator(scene, self.arrays, options.threads)  # once per geometry
        #: Camera rays go in COHERENT packets of this many rays, blocks of the frame
        #: (:func:`raytrace.camera.camera_rays`), in a scene with meshes; else 0.
        self.lanes = self.accel.embree.record.width if (
            self.coherent_camera and self.accel.embree is not None) else 0
        self.build_seconds = time.perf_counter() - t0
        self.materials, self.table = self.arrays.materials, self.arrays.table
        self.origin = self.arrays.origin
        self.emitters: list[Emitter] = emitters(scene.lights, self.origin, options.seed)
        self.ambient = np.asarray(scene.ambient, np.float64)
        self.background = np.asarray(options.background, np.float64).reshape(1, 3).copy()
        self.any_transparent = bool(self.table.transparent.any()) if self.materials else False
        self.lit = bool(self.emitters) and bool(self.table.lit.any())
        self.jittered = any(em.jittered for em in self.emitters)
        #: Which variant of the shading kernels the scene compiles and loads (a scene leaves
        #: out the compiled code of what it lacks: :func:`kernel_features`).
        self.features = kernel_features(self.table, self.arrays.triangles)
        #: Which scene object each analytic shape and mesh is (the id AOV).
        self.objects = Objects(self.arrays.shapes.object, self.arrays.geom_object)
        #: What every shading kernel needs of the scene (:class:`raytrace.kernels.records.Scene`),
        #: with its mip-maps for ``texture_filter = "trilinear"`` (:func:`with_mips`) and
        #: the cone spread of its box-filtered checkers (:func:`with_spread`).
        self.tables = with_spread(with_mips(self.arrays.record, self.table, scene.camera,
                                            options), self.table, scene.camera, options)
        #: Each emitter's fast-Phong table (:mod:`raytrace.fast_phong`), or none (exact).
        self.fast = fast_phong.tables(self.arrays.triangles, self.table.highlight, self.emitters)
        self._lock = threading.Lock()
        self._renders = 0  # renders started: each counts its rays afresh
        self._stats_per_thread: list[Stats] = []
        self._worker = Worker()
        self._compiled: tuple[Tracer, LightTable, PassSettings] | None = None
        self._stop = Stop()  # the render in progress's (render's argument)
        self._noise: noise.Result | None = None  # aa = "noise": the last render's result
        self._round: noise.Round | None = None  # aa = "noise": the round being traced

    def _set_options(self, options: RenderOptions) -> None:
        """The options and the windows they give: the window of the image (the crop or the
        frame) and the window traced: the same, or, for a filter wider than a pixel, grown by
        its reach (clipped to the frame)."""
        self.opt = options
        #: The columns of the AOVs asked for (:func:`raytrace.film.aov.layout`).
        self.aov_layout = aov_images.layout(options.aovs)
        #: The AOVs the kernels record at hits (all but the sample count).
        self.traced_aovs = aov_images.traced(options.aovs)
        #: Whether missed rays add anything (the background is not black).
        self.any_background = bool(np.any(options.background))
        self.window = options.crop or (0, 0, options.width, options.height)
        # noise-driven: each pixel made of its own samples (drawn from the filter), but its
        # counts, by threshold, read its neighbours'
        if options.aa == "noise":
            self.reach = noise.margin(options.min_spp, options.max_spp) if (
                options.target_error is None and options.time_limit is None) else 0
        else:
            self.reach = sampling.margin(options.filter)
        x0, y0, x1, y1 = self.window
        m = self.reach
        self.traced = (max(x0 - m, 0), max(y0 - m, 0), min(x1 + m, options.width),
                       min(y1 + m, options.height))
        #: The traced window as a crop of the frame (None: the whole frame).
        self.trace_crop = None if self.traced == (0, 0, options.width, options.height) \
            else self.traced
        #: Columns and rows of the window traced.
        self.size = (self.traced[2] - self.traced[0], self.traced[3] - self.traced[1])
        #: The frame as the camera sees it, as the kernels take it: made once, not per pass
        #: (its axes' cross products take 0.14 ms).
        self.view = pinhole(self.scene.camera, options.width, options.height)

    def for_window(self, crop: tuple[int, int, int, int] | None,
                   threads: int | None = None) -> WhittedIntegrator:
        """This integrator for another window (``crop``, checked by the caller) of the same
        frame, on ``threads`` threads (default: as this one), without building anything again:
        the copy shares the accelerator (BVH), materials and lights, which are read-only once
        built, and has its own per-render state, so copies may render at the same time on
        different threads. Its images report 0 build seconds (a distributed render's tiles,
        :mod:`raytrace.distributed`, count each build once)."""
        other = copy.copy(self)
        other._set_options(dataclasses.replace(
            self.opt, crop=crop, threads=self.opt.threads if threads is None else threads))
        other.build_seconds = 0.0
        other._aov_out = NO_AOV_PIXELS
        other._lock = threading.Lock()
        other._renders = 0
        other._stats_per_thread = []
        other._worker = Worker()
        other._compiled = None
        other._stop = Stop()
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
        """Camera samples per pass, in whole pixels: the image cut evenly into
        :func:`frame_passes` passes, but at most ``pass_samples`` and none below
        :data:`MIN_PASS_SAMPLES` (a small image goes in fewer, larger passes, which the Python
        loop runs faster than many small ones), rounded up to whole pixels, or where camera
        rays go in packets of blocks h pixels high (:attr:`lanes`) to whole bands of h rows
        where it holds one, so that no pass cuts a block of a frame and traces samples not its
        own (:func:`raytrace.kernels.camera.frame_packets`); down where up would pass
        ``pass_samples`` (and then one pass more may be left). Any cut gives the same image."""
        opt = self.opt
        total = self.size[0] * self.size[1] * opt.spp
        size = min(opt.pass_samples, max(MIN_PASS_SAMPLES, -(-total // frame_passes(
            total, opt.threads, opt.pass_samples))))
        unit = opt.spp  # whole pixels, or whole bands where one fits
        if self.lanes:
            band = block_shape(opt.spp, self.lanes)[0] * self.size[0] * opt.spp
            unit = band if size >= band else unit
        up = -(-size // unit) * unit  # up, so that the cut leaves no pass over
        return up if up <= opt.pass_samples else max(opt.spp, size // unit * unit)

    # -- the loop ----------------------------------------------------------------------------
    def render(self, progress: Callable[[int, int], None] | None = None,
               stop: Stop | None = None) -> Image:
        """The image, pass by pass on ``threads`` worker threads while the calling thread
        waits; ``progress(done, total)`` is called, one thread at a time, after each pass.
        ``stop``: a :class:`Stop` that ends the render early, within a batch of each pass,
        raising its reason (a Ctrl-C while waiting stops the passes and is raised)."""
        opt = self.opt
        t_start = time.perf_counter()
        self._stop = stop = Stop() if stop is None else stop
        with self._lock:  # a second render of this integrator counts from zero
            self._renders += 1
            self._stats_per_thread = []
        cols, rows = self.size
        self._noise = None
        if opt.aa == "noise":
            return self._finish(*self._render_noise(progress, stop, t_start), t_start)
        if opt.aa == "adaptive":  # passes of whole rows, counted in rows
            total, per_pass = rows, self._adaptive_rows(cols, rows)
        else:
            total, per_pass = cols * rows * opt.spp, self.pass_size
        passes = [(a, min(a + per_pass, total)) for a in range(0, total, per_pass)]
        # Each pass rounds its pixels to float32 as it ends (the same rounding as at the end
        # would be), so no float64 copy of the whole image is held; a filter wider than a
        # pixel keeps every sample (float64) and gathers the pixels once all are traced.
        filtered = opt.filter != "box"
        pixels = np.empty((total if filtered else cols * rows, 3),
                          dtype=np.float64 if filtered else np.float32)
        self._aov_out = NO_AOV_PIXELS
        self._compiled = self._loop_records() if self.compiled else None
        if self.traced_aovs:  # one table, a row per pixel (raytrace.film.aov.layout's columns)
            self._aov_out = np.empty((cols * rows, len(self.aov_layout.miss)))
            self._aov_out[:] = self.aov_layout.miss
        self._run(passes, pixels, progress, total, stop)
        aovs = aov_images.images(self._aov_out, self.traced_aovs, (rows, cols))
        if filtered:
            pixels, (cols, rows) = self._filter(pixels), self.window_size
            dx, dy = self.window[0] - self.traced[0], self.window[1] - self.traced[1]
            aovs = {name: np.ascontiguousarray(a[dy:dy + rows, dx:dx + cols])
                    for name, a in aovs.items()}
        if "samples" in opt.aovs:  # every pixel its own spp samples
            aovs["samples"] = np.full((rows, cols), opt.spp, np.int32)
        return self._finish(pixels.reshape(rows, cols, 3), aovs, t_start)

    def _finish(self, rgb: np.ndarray, aovs: dict[str, np.ndarray], t_start: float) -> Image:
        """The :class:`Image` of the pixels ``rgb`` (rows, cols, 3) float32, non-finite ones
        counted and written as 0, with its stats and metadata."""
        opt = self.opt
        t_passes = time.perf_counter() - t_start
        bad = ~np.isfinite(rgb)
        nonfinite, first = 0, None
        if bad.any():
            bad_pixels = bad.any(axis=2)
            nonfinite = int(bad_pixels.sum())
            y, x = np.unravel_index(int(np.argmax(bad_pixels)), bad_pixels.shape)
            x0, y0 = opt.crop[:2] if opt.crop else (0, 0)
            first = [int(x) + x0, int(y) + y0]  # the first in reading order, in the frame
            rgb[bad] = 0.0
        seconds = time.perf_counter() - t_start + self.build_seconds
        return Image(rgb, self._stats(nonfinite, first, seconds, t_passes),
                     self._metadata(nonfinite, seconds), aovs, opt.crop, (opt.width, opt.height))

    def _render_noise(self, progress: Callable[[int, int], None] | None, stop: Stop,
                      t_start: float) -> tuple[np.ndarray, dict[str, np.ndarray]]:
        """The window's pixels (rows, cols, 3) float32, and its samples AOV if asked for, by
        adaptive sampling to a noise threshold (:func:`raytrace.noise.sample`) over the
        traced window (a crop's grown by :func:`raytrace.noise.margin`): each round's samples
        are cut into passes at pixel bounds and run on the threads (:meth:`_run`); with a time
        limit no pass starts after the deadline (the first round's always run), so each pixel
        keeps whole rounds. The result (counts, estimate) is kept for the stats and metadata."""
        opt = self.opt
        deadline = None if opt.time_limit is None else (
            t_start + opt.time_limit - self.build_seconds)

        def trace(r: noise.Round, first: bool) -> int:
            self._round = r
            size = round_pass_size(r.size, opt.threads, opt.pass_samples)
            done = self._run(noise.passes(r.bounds, size), None, progress, r.size, stop,
                             None if first else deadline)
            return sum(b - a for a, b in done)

        result = noise.sample(self.traced, opt.width, opt.seed, noise.Budget(
            opt.min_spp, opt.max_spp, opt.noise_threshold, opt.target_error, deadline), trace,
            opt.filter)
        (x0, y0, x1, y1), (tx, ty) = self.window, self.traced[:2]
        cols = self.size[0]
        inside = ((np.arange(y0, y1) - ty)[:, None] * cols + (np.arange(x0, x1) - tx)).ravel()
        result.pixels, result.counts = result.pixels[inside], result.counts[inside]
        self._noise = result
        shape = (y1 - y0, x1 - x0)
        aovs = {"samples": result.counts.astype(np.int32).reshape(shape)} \
            if "samples" in opt.aovs else {}
        with np.errstate(over="ignore", invalid="ignore"):  # beyond float32's range → inf
            return result.pixels.astype(np.float32).reshape(*shape, 3), aovs

    def _loop_records(self) -> tuple[Tracer, LightTable, PassSettings]:
        """What the compiled loop (:func:`raytrace.kernels.loop.trace_paths`) reads of this
        render: the scene, the lights and the settings, as records."""
        opt, embree = self.opt, self.accel.embree
        def flag(on: bool) -> bool | None:  # a feature the loop's code is chosen by: None: off
            return True if on else None

        tracer = Tracer(self.arrays.shapes, self.tables, None if embree is None else embree.record,
                        embree is not None, self.objects, self.aov_layout, flag(self.lit),
                        flag(self.any_transparent), flag("children" in self.features),
                        flag("meshes" in self.features))
        fast = [np.zeros((0, FAST_COLUMNS)), *(f.reshape(-1, FAST_COLUMNS) for f in self.fast)]
        lights = LightTable(
            np.array([tuple(em.record) for em in self.emitters],
                     np.float64).reshape(-1, EMITTER_FIELDS),
            np.array([em.color for em in self.emitters], np.float64).reshape(-1, 3),
            np.ascontiguousarray(np.concatenate(fast)),
            np.cumsum([0, *(len(f) for f in fast[1:])]).astype(np.int64))
        per_pass = self.opt.pass_samples if self.opt.aa != "uniform" else self.pass_size
        settings = PassSettings(per_pass, opt.max_depth, float(opt.min_weight),
                                self.any_background, self.background, self.ambient, *CLOCK)
        return tracer, lights, settings

    def _adaptive_rows(self, cols: int, rows: int) -> int:
        """Rows per pass of adaptive anti-aliasing: the fewest passes of at most
        ``pass_samples`` corners (a level's batches are cut to that size anyway), rounded up
        to a multiple of the threads and cut evenly. Each level of a pass is a few batches
        through the integrator whatever its size, so few large passes cost the least Python
        per sample; any cut gives the same image (a pass traces its own corner rows)."""
        threads = max(1, min(self.opt.threads, rows))
        count = max(-(-rows * (cols + 1) // self.opt.pass_samples), threads)
        count = -(-count // threads) * threads
        return -(-rows // count)

    @property
    def window_size(self) -> tuple[int, int]:
        """Columns and rows of the image (the crop, or the frame)."""
        x0, y0, x1, y1 = self.window
        return x1 - x0, y1 - y0

    def _filter(self, samples: np.ndarray) -> np.ndarray:
        """The image's pixels (n, 3) float32 from every traced sample's sum ``samples``, by
        the options' filter (:func:`raytrace.film.filters.gather`)."""
        opt = self.opt
        return filters.gather(samples, opt.filter, self.traced, self.window,
                              Sampling(opt.width, opt.spp, grid(opt.spp), opt.seed))

    def _run(self, passes: list[tuple[int, int]], pixels: np.ndarray | None,
             progress: Callable[[int, int], None] | None, total: int, stop: Stop,
             deadline: float | None = None) -> list[tuple[int, int]]:
        """Render ``passes`` into ``pixels`` (None: a noise-driven round, whose passes add to
        it, :meth:`_render_pass`): worker threads take the next pass from a shared
        queue until none is left, while this thread waits (so that it takes a Ctrl-C at
        once). A stop asked for (``stop``), an exception in any thread, or a Ctrl-C while
        waiting stops them all at their next batch, and the first of these is raised once
        all have stopped. No pass starts after ``deadline`` (``time.perf_counter()``; None:
        none). Returns the passes rendered."""
        queue, done, finished = iter(passes), [0], []

        def work() -> None:
            while not stop.requested:
                if deadline is not None and time.perf_counter() >= deadline:
                    return
                with self._lock:
                    item = next(queue, None)
                if item is None:
                    return
                try:
                    self._render_pass(*item, pixels)
                    with self._lock:
                        finished.append(item)
                    if progress is not None and not stop.requested:
                        with self._lock:
                            done[0] += item[1] - item[0]
                            progress(done[0], total)
                except BaseException as e:  # the pass's or progress's: raised by _run
                    stop.request(e)
                    return

        threads, workers = max(1, min(self.opt.threads, len(passes))), []
        try:  # (waking every WAKE_SECONDS where a lock wait takes no signal)
            pool = pass_threads(threads)
            for _ in range(threads):  # one by one: a Ctrl-C between two leaves none unseen
                workers.append(pool.submit(work))
            while wait_for(workers, WAKE_SECONDS).not_done:
                pass
        except BaseException as e:  # Ctrl-C (KeyboardInterrupt) while starting or waiting
            stop.request(e)  # (a pass whose submission it cut short finds the stop at once)
            wait_for(workers)  # each ends at its pass's next batch
        stop.check()
        return finished

    def _render_pass(self, start: int, stop: int, pixels: np.ndarray | None) -> None:
        """Camera samples ``start`` to ``stop`` (whole pixels), depth by depth, into their
        pixels (and AOVs); with adaptive anti-aliasing, the rows ``start`` to ``stop``; with
        noise-driven sampling, the samples ``start`` to ``stop`` of the round, drawn and added
        to it here (:class:`raytrace.noise.Round`), on the pass's thread."""
        opt, w, n = self.opt, self._worker, stop - start
        t0 = time.perf_counter()
        if opt.aa == "adaptive":
            self._render_rows(start, stop, pixels)
            self.stats.pass_seconds += time.perf_counter() - t0
            return
        if opt.aa == "noise":  # samples start to stop of the round, added to it
            r = self._round
            bounds = r.bounds[np.searchsorted(r.bounds, start):
                              np.searchsorted(r.bounds, stop, "right")] - start
            points = r.points(start, stop)
            r.add(start, stop, self.trace_points(points.x, points.y, points.keys, bounds),
                  points.weight)
            self.stats.pass_seconds += time.perf_counter() - t0
            return
        keep = pixels.dtype == np.float64  # every sample kept for the filter
        samples = pixels[start:stop] if keep else self.scratch("samples", n, 3)
        samples.fill(0.0)
        if self.traced_aovs:  # every camera sample a miss until its ray hits
            w.aov = self.scratch("aov", n, len(self.aov_layout.miss))
            w.aov[:] = self.aov_layout.miss
        self.trace_samples(start, stop, samples)
        first, last = start // opt.spp, stop // opt.spp
        if not keep:
            with np.errstate(over="ignore", invalid="ignore"):  # beyond float32's range → inf
                pixels[first:last] = (
                    samples if opt.spp == 1 else samples.reshape(-1, opt.spp, 3).mean(1))
        if self.traced_aovs:
            aov_pixels(last - first, opt.spp, w.aov, self.aov_layout,
                       self._aov_out[first:last])
        self.stats.pass_seconds += time.perf_counter() - t0

    def _render_rows(self, start: int, stop: int, pixels: np.ndarray) -> None:
        """Rows ``start`` to ``stop`` of the window by adaptive refinement
        (:func:`raytrace.adaptive.refine`): each level's new lattice points are one
        wavefront (:meth:`trace_points`)."""
        opt = self.opt
        x0, y0, x1, _ = self.window
        values, _, _ = adaptive.refine((x0, y0 + start, x1, y0 + stop), opt.width,
                                       opt.aa_depth, opt.aa_threshold, opt.seed,
                                       self.trace_points, opt.aa_min_depth)
        with np.errstate(over="ignore", invalid="ignore"):  # beyond float32's range → inf
            pixels[start * (x1 - x0):stop * (x1 - x0)] = values

    def trace_points(self, x: np.ndarray, y: np.ndarray, ids: np.ndarray,
                     pixels: np.ndarray | None = None) -> np.ndarray:
        """Radiance (n, 3) float64 of camera rays through image positions ``x``, ``y`` (n,)
        (pixels of the frame), one sample each; ``ids`` (n,) key their jittered area-light
        points, as global sample indices do for uniform samples. ``pixels``: where each
        pixel's points start (then n), where they come pixel by pixel: in a scene with meshes
        each pixel's rays then go in COHERENT packets of their own
        (:func:`raytrace.kernels.camera.pixel_packets`)."""
        n, w = len(x), self._worker
        columns = camera_columns(n)
        direction = directions_at(self.view, self.opt.width, self.opt.height, x, y)
        found = None
        if self.lanes and pixels is not None:
            if not (len(pixels) and pixels[0] == 0 and pixels[-1] == n):  # kernels read them
                raise ValueError(f"pixel bounds must run from 0 to {n}")
            bounds = np.empty(len(pixels) + n // self.lanes + 1, np.int64)
            k = pixel_packets(np.ascontiguousarray(pixels, np.int64), self.lanes, bounds)
            found = CameraPackets(direction, columns.sample, bounds[:k + 1])
        rays = RayBatch(columns.origin, direction, columns.sample, columns.weight, 0,
                        columns.origin_shape, columns.kind, found)
        samples = np.zeros((n, 3))
        w.keys = np.ascontiguousarray(ids, np.int64)
        try:
            self._trace_batch(rays, n, samples)
        finally:
            w.keys = None
        return samples

    def trace_samples(self, start: int, stop: int, samples: np.ndarray) -> None:
        """Add into ``samples`` (stop − start, 3) everything the samples ``start`` to ``stop``
        of the window see: their camera rays, then depth by depth.

        A batch grown past the pass size (2 children per glass hit) is cut into chunks that
        keep each sample's rays together (:func:`raytrace.rays.sample_chunks`), finished one
        after another, so memory stays bounded by the pass size × max_depth rather than
        growing as 2^depth, and each sample's sum is added up in the same order whatever the
        pass size, the crop or the threads."""
        opt, w, n = self.opt, self._worker, stop - start
        w.first_sample = start
        if w.camera_columns is None or len(w.camera_columns.origin) < n:
            w.camera_columns = camera_columns(n)
        rays = camera_rays(self.view, opt, start, stop, columns=w.camera_columns,
                           direction=self.scratch("camera_direction", n, 3),
                           window=self.traced, lanes=self.lanes)  # None would be the crop
        self._trace_batch(rays, n, samples)

    def _trace_batch(self, rays: RayBatch, n: int, samples: np.ndarray) -> None:
        """Trace camera ``rays`` of ``n`` samples and their descendants, depth by depth, into
        ``samples`` (n, 3), in chunks of at most a pass (:meth:`trace_samples`); camera rays
        in packets whole (a noise-driven pass, cut at pixel bounds, may hold more)."""
        if self.compiled and self.observer is None and not DEBUG:
            self._trace_compiled(rays, n, samples)
            return
        # an adaptive level's or round's points are single samples: batches of the pass size
        per_pass = self.opt.pass_samples if self.opt.aa != "uniform" else self.pass_size
        pending, stop = [rays], self._stop.flag
        while pending and not stop[0]:  # a stop asked for ends the pass here
            rays = pending.pop()
            if len(rays) > per_pass and rays.packets is None:  # packets: traced whole
                pending.extend(reversed(chunks(rays, n, per_pass)))
                continue
            children = self.trace(rays, samples)
            if len(children):
                pending.append(children)

    def _trace_compiled(self, rays: RayBatch, n: int, samples: np.ndarray) -> None:
        """:meth:`_trace_batch` in one compiled call (:func:`raytrace.kernels.loop.trace_paths`):
        the same kernels in the same order, its counters added to this thread's."""
        opt, w = self.opt, self._worker
        if self._compiled is None:  # a caller that did not go through render
            self._compiled = self._loop_records()
        tracer, lights, settings = self._compiled
        keys = None
        if self.jittered:  # each sample's key (raytrace.camera.global_samples, or the points')
            keys = w.keys if w.keys is not None else global_samples(
                np.arange(w.first_sample, w.first_sample + n), opt.width, opt.spp,
                self.trace_crop)
        tally = Tally(np.zeros(loop.COUNTERS, np.int64), np.zeros(loop.SECONDS),
                      np.zeros(2, np.int64))
        loop.trace_paths(tracer, lights, settings, rays.record,
                         PassIO(samples, None if keys is None else np.ascontiguousarray(
                             keys, np.int64), w.aov if self.traced_aovs else None, self._stop.flag,
                             rays.packets),
                         tally)
        st, counters = self.stats, tally.counters.tolist()
        for name, count in zip(KIND_NAMES, counters, strict=False):
            st.rays[name] += count
        st.rays["shadow"] += counters[loop.SHADOW_RAYS]
        st.pruned_depth += counters[loop.PRUNED_DEPTH]
        st.pruned_weight += counters[loop.PRUNED_WEIGHT]
        st.total_internal_reflections += counters[loop.TIR]
        st.trace_seconds += float(tally.seconds[loop.TRACE_SECONDS])
        st.shade_seconds += float(tally.seconds[loop.SHADE_SECONDS])

    def _hits(self, rays: RayBatch) -> Hits:
        """The closest hits of ``rays``: camera rays with packets through all of them, every
        slot traced (origin 0, no start shape) and the hits of the batch's own rays kept
        (:func:`raytrace.kernels.camera.own_hits`); other batches in plain packets."""
        p = rays.packets
        if p is None:
            return self.accel.intersect(rays.origin, rays.direction, rays.origin_shape)
        n, m = len(rays), len(p.sample)
        every = self.accel.intersect(np.zeros((m, 3)), p.direction,
                                     np.full(m, NO_SHAPE, np.int64), packets=p.bounds)
        if m == n:  # every slot the batch's own, in its order
            return every
        hits = Hits(np.empty(n), np.empty(n, np.int64), np.empty(n, np.int64), np.empty((n, 2)))
        own_hits(p, every, hits)
        return hits

    def trace(self, rays: RayBatch, samples: np.ndarray) -> RayBatch:
        """One depth: intersect, add background and local shading, return the next depth."""
        st, n = self.stats, len(rays)
        counts = np.zeros(len(KIND_NAMES), np.int64)
        count_kinds(rays.kind, counts)
        for name, count in zip(KIND_NAMES, counts.tolist(), strict=True):
            st.rays[name] += count
        t0 = time.perf_counter()
        hits = self._hits(rays)
        st.trace_seconds += time.perf_counter() - t0
        found, missed = (self.scratch(name, n, dtype=np.int64) for name in ("found", "missed"))
        k = split_hits(hits.t, found, missed)
        found, missed = found[:k], missed[:n - k]
        if self.observer is not None:
            self.observer.traced(rays, found, missed, self.background)
        if len(missed) and self.any_background:
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
            taken, kept = Rays(*out[:6]), Hits(*out[6:])
            take_hits(found, rays.record, hits, taken, kept)
            hits = kept
            rays = RayBatch(taken.origin, taken.direction, taken.sample, taken.weight,
                            rays.depth, taken.origin_shape, taken.kind)
        surf = self.accel.surface(hits, rays.origin, rays.direction, self.tables.reliefs)
        if rays.depth == 0 and self.traced_aovs:  # the camera rays' first hits
            self.aov_hits(rays, hits, surf, self.aov_layout, self._worker.aov)
        if self.observer is not None:
            self.observer.hits(rays, hits, surf)
        children = self.shade(rays, surf, samples)
        st.shade_seconds += time.perf_counter() - t1 - (st.trace_seconds - trace_before)
        return children

    def aov_hits(self, rays: RayBatch, hits: Hits, surf: Surface, layout: AOVLayout,
                 out: np.ndarray) -> None:
        """Write the AOVs of ``layout`` at the hits (rays that all hit) into the rows
        ``rays.sample`` of the per-sample table ``out`` (:func:`raytrace.kernels.aov.aov_hits`)."""
        aov_hits(rays.record, hits.t, surf, self.tables, self.objects, layout, out)

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
        obs = self.observer
        if "children" not in self.features and obs is None:  # no hit has a child
            sk.hit_terms(rays.record, surf, self.tables, Local(self.ambient, lights),
                         self.opt.min_weight, SampleSums(samples, rays.sample), None)
            return RayBatch.empty(rays.depth + 1)
        children = Children(*(new(name, n, 3) for name in ("r_dir", "t_dir", "w_r", "w_t", "w_s")),
                            new("status", n, 3, np.int8), new("tir", n, dtype=bool))
        status, tir = children.status, children.tir
        # Observed, each hit's term goes to a row of its own, then to its sample: the same
        # additions in the same order (0 + x and x·1 are exact).
        into, rows = (samples, rays.sample) if obs is None else (np.zeros((n, 3)), np.arange(n))
        sk.hit_terms(rays.record, surf, self.tables, Local(self.ambient, lights),
                     self.opt.min_weight, SampleSums(into, rows), children)
        depth = rays.depth + 1
        if obs is not None:
            add(samples, rays.sample, into, ONE, rows)
            obs.shaded(into, status, (children.w_r, children.w_t, children.w_s), tir,
                       depth > self.opt.max_depth)
        if depth <= self.opt.max_depth:
            self.stats.total_internal_reflections += int(np.count_nonzero(tir))
        # The next depth: reflected, refracted (or TIR) and see-through children.
        if not self._prune(status, depth):
            return RayBatch.empty(depth)
        spawned, parent = self._spawn(rays, surf, children)
        if obs is not None:
            obs.spawned(spawned, parent)
        return spawned

    def _spawn(self, parents: RayBatch, surf: Surface,
               children: Children) -> tuple[RayBatch, np.ndarray]:
        """The children of the hits whose ``status`` is KEEP, in one batch (reflected, then
        refracted, then see-through, each in hit order), and the row of each one's parent
        hit. Two passes:
        count the children of each kind (:func:`raytrace.kernels.shading.count_keep`), then
        fill the rows from where each kind starts
        (:func:`raytrace.kernels.shading.spawn_children`)."""
        per_kind = sk.count_keep(children.status)
        first = np.concatenate([[0], np.cumsum(per_kind)[:-1]])  # where each kind starts
        k = int(per_kind.sum())
        origin, direction, weight = np.empty((k, 3)), np.empty((k, 3)), np.empty((k, 3))
        sample, shape = np.empty(k, np.int64), np.empty(k, np.int64)
        kind, parent = np.empty(k, np.int8), np.empty(k, np.int64)
        sk.spawn_children(children, parents.record, surf, first, CHILD_KINDS,
                         Spawned(origin, direction, weight, sample, shape, kind, parent))
        batch = RayBatch(origin, direction, sample, weight, parents.depth + 1, shape, kind)
        if DEBUG:
            check_spawned(batch)
        return batch, parent

    def _prune(self, status: np.ndarray, depth: int) -> bool:
        """Whether any children (the columns of ``status``) may go on: none past
        ``max_depth``, none under ``min_weight`` (Hall & Greenberg 1983); the dropped ones are
        counted."""
        if depth > self.opt.max_depth:
            self.stats.pruned_depth += int(np.count_nonzero(status))
            return False
        self.stats.pruned_weight += int(np.count_nonzero(status == sk.PRUNED))
        return True

    def direct_lighting(self, rays: RayBatch, surf: Surface) -> np.ndarray:
        """Σ_l S_l · f_l · I_l · [kd·max(N·L, 0) + ks·spec] at every hit, (n, 3): per emitter,
        one pass for the unshadowed term and the shadow rays of the hits it lights
        (:func:`raytrace.kernels.shading.light_pass`), then their shadow factors."""
        n, new = len(rays), self.scratch
        out = new("lights", n, 3)
        out.fill(0.0)
        term, rows = new("term", n, 3), new("shadow_rows", n, dtype=np.int64)
        origin, direction = new("shadow_origin", n, 3), new("shadow_direction", n, 3)
        tmax, shape = new("shadow_tmax", n), new("shadow_shape", n, dtype=np.int64)
        shadow = Shadows(rows, origin, direction, tmax, shape)
        # Jittered area lights draw a point per hit from its global camera sample, depth and,
        # below the camera rays, its path (core.path_key1).
        w = self._worker
        key = NO_KEY if not self.jittered else (
            w.keys[rays.sample] if w.keys is not None else global_samples(
                rays.sample + w.first_sample, self.opt.width, self.opt.spp, self.trace_crop))
        if len(key) and rays.depth > 0:  # each path of a sample its own points
            key = path_keys(key, rays.origin, rays.direction)
        words = {}  # a jittered light's draws, one per hit for all its cells
        for e, em in enumerate(self.emitters):
            if self._stop.requested:  # the pass ends (an area light's emitters take seconds)
                break
            if em.stream not in words:
                words[em.stream] = light_words(key, em.stream, rays.depth)
            tables = self.tables if not len(self.fast[e]) else self.tables._replace(
                fast=self.fast[e])
            depth = rays.depth if "meshes" in self.features else None
            k = sk.light_pass(rays.record, surf, tables, em.record, words[em.stream], depth,
                              term, shadow)
            if self.observer is not None:
                self.observer.light(e, term, rows[:k])
            if k:  # the camera rays' hits send coherent shadow rays to a point
                self.shadow(out, term, np.asarray(em.color, np.float64),
                            *(column[:k] for column in shadow),
                            coherent=rays.depth == 0 and not em.jittered)
        return out

    def shadow(self, out: np.ndarray, term: np.ndarray, color: np.ndarray, rows: np.ndarray,
               origin: np.ndarray, direction: np.ndarray, tmax: np.ndarray,
               shape: np.ndarray, coherent: bool = False) -> None:
        """``out[rows] += term[rows]·S·I_l``, with S (k, 3) the shadow factor of the shadow
        rays (``origin``, ``direction``, ``tmax``, starting on ``shape``) of the hits ``rows``.

        Opaque-only scenes use the occlusion query: S is 0 or 1. Otherwise the straight
        shadow ray walks through every surface before the light, multiplying
        ``t·kt + (1 − t)`` (seed 003).
        """
        self.stats.rays["shadow"] += len(rows)
        t0 = time.perf_counter()
        if not self.any_transparent:
            blocked = self.accel.occluded(origin, direction, shape, tmax, coherent)
            self.stats.trace_seconds += time.perf_counter() - t0
            sk.add_unblocked(out, rows, term, blocked, color)
            if self.observer is not None:
                self.observer.shadow(np.where(blocked[:, None], 0.0, np.ones(3)))
            return
        factor = self.scratch("shadow", len(rows), 3)
        factor.fill(1.0)
        live = np.arange(len(rows))  # the row of factor each walking ray multiplies
        for _ in range(MAX_SHADOW_CROSSINGS):
            hits = self.accel.intersect(origin, direction, shape, tmax)
            t, hit_shape, triangle, uv, origin, direction, tmax, live = sk.crossing_rays(
                hits, origin, direction, tmax, live)
            if not len(live):
                break
            s2 = self.accel.surface(Hits(t, hit_shape, triangle, uv), origin, direction,
                                    self.tables.reliefs)
            origin, direction, shape, tmax, live = sk.cross_surfaces(
                factor, live, s2, ShadowWalk(direction, t, tmax), self.tables)
            if not len(live):
                break
            self.stats.rays["shadow"] += len(live)
        else:
            factor[live] = 0.0
        self.stats.trace_seconds += time.perf_counter() - t0
        sk.add_light(out, rows, term, factor, color)
        if self.observer is not None:
            self.observer.shadow(factor.copy())

    # -- reporting ---------------------------------------------------------------------------
    def _stats(self, nonfinite: int, first: list[int] | None, seconds: float,
               pass_wall: float) -> dict:
        """The ``--stats`` dictionary. Counts are summed over the threads. ``trace`` and
        ``shade`` are wall seconds: the passes' wall time split in proportion to the thread
        time spent tracing and shading, so build + trace + shade ≤ total with any number of
        threads."""
        st, opt = Stats(), self.opt
        for part in self._stats_per_thread:
            st.merge(part)
        share = pass_wall / st.pass_seconds if st.pass_seconds > 0 else 0.0
        rays = dict(st.rays)
        rays["total"] = sum(rays.values())
        return {
            "rays": rays,
            "pruned": {"depth": st.pruned_depth, "weight": st.pruned_weight},
            "total_internal_reflections": st.total_internal_reflections,
            "nonfinite_pixels": nonfinite, "nonfinite_first_pixel": first,  # [x, y] or None
            "degenerate_triangles": self.arrays.degenerate,
            "triangles": self.arrays.n_triangles,
            "seconds": {"build": self.build_seconds, "trace": st.trace_seconds * share,
                        "shade": st.shade_seconds * share, "total": seconds},
            "width": opt.width, "height": opt.height, "spp": opt.spp, "max_depth": opt.max_depth,
            "min_weight": opt.min_weight, "threads": opt.threads,
            **({"crop": list(opt.crop)} if opt.crop else {}),
            **({"aovs": list(opt.aovs)} if opt.aovs else {}),
            **({"filter": opt.filter} if opt.filter != "box" else {}),
            **({"aa": {"mode": "adaptive", "threshold": opt.aa_threshold, "depth": opt.aa_depth,
                       "min_depth": opt.aa_min_depth,
                       "samples_per_pixel": rays["camera"] / (opt.width * opt.height
                                                              if not opt.crop else
                                                              self.size[0] * self.size[1])}}
               if opt.aa == "adaptive" else {}),
            **({"aa": self._noise_record()} if self._noise is not None else {}),
        }

    def _noise_record(self) -> dict:
        """What a noise-driven render (:mod:`raytrace.noise`) asked for and spent: its
        settings, the samples (in all and a pixel on average), rounds, the estimated relative
        RMSE (:func:`raytrace.noise.relative_rmse`) and why it stopped."""
        opt, res = self.opt, self._noise
        return {"mode": "noise", "noise_threshold": opt.noise_threshold,
                "min_spp": opt.min_spp, "max_spp": opt.max_spp,
                "target_error": opt.target_error, "time_limit": opt.time_limit,
                "samples": int(res.counts.sum()),
                "samples_per_pixel": float(res.counts.mean()), "rounds": res.rounds,
                "estimated_relative_rmse": res.estimate, "stopped_by": res.stopped}

    def _metadata(self, nonfinite: int, seconds: float) -> dict:
        opt = self.opt
        return {"scene": self.scene.path or "<python>", "width": opt.width, "height": opt.height,
                "spp": opt.spp, "max_depth": opt.max_depth, "min_weight": opt.min_weight,
                "seed": opt.seed, "nonfinite_pixels": nonfinite,
                "renderer": "raytrace (Whitted, Embree)",
                **({"crop": " ".join(map(str, opt.crop))} if opt.crop else {}),
                **({"filter": opt.filter} if opt.filter != "box" else {}),
                **({"aa": f"adaptive threshold {opt.aa_threshold} depth {opt.aa_depth}"
                          + (f" min_depth {opt.aa_min_depth}" if opt.aa_min_depth else "")}
                   if opt.aa == "adaptive" else {}),
                **({f"noise_{k}": v for k, v in self._noise_record().items()
                    if k != "mode" and v is not None} | {"render_seconds": seconds}
                   if self._noise is not None else {})}


#: The scene features that select a variant of the shading kernels, name -> whether a
#: scene's material table and triangles have it. A scene without a feature calls the
#: kernels with None in its argument, and numba compiles (and loads from its cache) a
#: specialisation without that code (dead-branch pruning on ``arg is None`` before typing):
#: a first render compiles only the code its scene can run (docs/performance.md, "cold
#: compile"); every variant adds the same numbers in the same order.
KERNEL_FEATURES: dict[str, Callable] = {
    # light_pass' Gouraud, fast-Phong, Hanika-lift and texture code (its ``depth``)
    "meshes": lambda table, triangles: len(triangles.material) > 0
    or bool(table.textured.any()),
    # the material lookup's texture code in hit_terms and cross_surfaces (their ``texcoords``;
    # vertex colours are read by it too)
    "textures": lambda table, triangles: bool(table.textured.any())
    or triangles.colors is not None,
    # hit_terms' reflected, refracted and see-through children, and the spawn kernels
    "children": lambda table, triangles: bool(table.reflects.any())
    or bool(table.transparent.any()),
    # hit_terms' and cross_surfaces' Beer's law and thin walls (the scene record's ``media``)
    "media": lambda table, triangles: any(m.absorbs or m.thin_walled for m in table.materials),
}


def kernel_features(table, triangles) -> frozenset[str]:
    """The names of :data:`KERNEL_FEATURES` a scene has (``table``: its
    :class:`raytrace.tables.MaterialTable`, ``triangles``: its
    :class:`raytrace.kernels.records.Triangles`)."""
    if not len(table.materials):
        return frozenset()
    return frozenset(name for name, has in KERNEL_FEATURES.items() if has(table, triangles))


def chunks(rays: RayBatch, samples: int, most: int) -> list[RayBatch]:
    """``rays`` (of ``samples`` pixel samples) cut into batches of at most ``most`` rays that
    keep each sample's rays together, in batch order (:func:`raytrace.rays.sample_chunks`)."""
    n = len(rays)
    chunk = np.empty(n, np.int64)
    count = sample_chunks(rays.sample, samples, most, chunk)
    out = RayBatch(np.empty((n, 3)), np.empty((n, 3)), np.empty(n, rays.sample.dtype),
                   np.empty((n, 3)), rays.depth, np.empty(n, rays.origin_shape.dtype),
                   np.empty(n, rays.kind.dtype))
    bounds = gather_chunks(chunk, count, rays.record, out.record).tolist()
    return [out.take(slice(a, b)) for a, b in zip(bounds[:-1], bounds[1:], strict=True)]


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
    (:func:`raytrace.kernels.shading.accumulate`)."""
    sk.accumulate(samples, sample, weight, factor, rows)
