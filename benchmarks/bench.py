"""The performance benchmark of issue 6: raytrace against raw Embree and against POV-Ray 3.7.

    python3 benchmarks/bench.py                 # everything, full size (minutes)
    python3 benchmarks/bench.py --quick         # a smoke run (seconds)
    python3 benchmarks/bench.py --parts throughput,povray --threads 2

Parts (``--parts``, comma-separated; default all):

``throughput``
    Each benchmark scene is rendered by ``raytrace render`` in a subprocess (whole-process wall
    time, peak resident memory (VmHWM polled from /proc), the phase seconds of ``--stats``).
    The same render is then run in this process with :attr:`raytrace.accel.Accelerator.recorder`
    set, which collects every intersect/occluded batch the renderer traces (camera, shadow,
    reflection, refraction rays) as float32 arrays; those batches are replayed through embreex
    alone, with the renderer's chunk size and thread count (``INTERSECT`` with ``output=1``
    for closest hits, ``OCCLUDED`` for shadow queries), and timed. The ratio is the renderer's
    rays/s (all rays over build + trace + shade, the ``render()`` call) over the raw rays/s.
    Analytic spheres and planes are not traced by Embree in raytrace: for the raw baseline they
    are tessellated (icospheres of 20 480 triangles, a 2-triangle quad of half-size 10⁴ for a
    plane), and the renderer's own numpy analytic rate is reported beside it.
``povray``
    The same scenes written by ``benchmarks/povray.py`` and rendered by ``povray`` (no
    antialiasing, same size and threads): whole-process wall time, POV-Ray's parse and trace
    times, its peak memory.
``profile``
    Each scene rendered once more in this process on one thread with every pipeline stage
    wrapped in a timer (exclusive seconds): Embree's ``run`` calls, analytic intersection, the
    rest of raytrace.accel, camera rays, shading, compaction, accumulation, the integrator's
    loop, the BVH build, the scene load and the EXR write.
``kernels``
    Each scene rendered once more in this process on one thread (after a render that loads
    every kernel) with each compiled kernel and Embree's ``run`` timed: seconds and calls per
    kernel, their sum (the BVH build's kernels apart), and the rest of the render (Python and
    numpy between the kernels). With ``throughput`` in the same run it also gives the *warm
    ceiling*: the warm ratio the render would reach with no Python at all and a perfect
    speed-up from every thread, raw build + run over ``build + (Embree + kernels) /
    threads``: the most that removing overhead could buy.
``scaling``
    The mesh scene at growing pixel counts and spp, with a least-squares fit
    ``seconds = fixed + per_sample·samples`` and its largest residual; the full run also
    renders 3840×2160 at 4 spp (``--no-big`` skips it) and reports its peak memory.
``startup``
    ``raytrace render`` of a small analytic scene (the Whitted scene at 64×48) to EXR, three
    times: the wall time of each, and of ``python -c "import raytrace"``.
``threads``
    Both scenes at full size at each of ``--thread-counts`` (default 1, 2, 4; 1, 2 with
    ``--quick``): render seconds and speed-up over one thread, cold (a fresh ``raytrace
    render`` process, which pays numba's one-off set-up), warm (a second render in this
    process, its BVH built inside the timing) and kept (its BVH kept from the render before,
    :mod:`raytrace.accel_cache`), and whether each image is bit-identical to the one-thread
    image; from the warm 1- and 2-thread times, the serial fraction they imply and the
    speed-up it predicts on 16 cores (Amdahl, ``gil.amdahl``).
``meshes``
    Large meshes (``benchmarks/meshes.py``): the mesh scene with icospheres of 82 k to 5.2 M
    triangles as binary PLY and OBJ, each rendered by a fresh ``raytrace render``: wall time,
    peak memory, load, build and render seconds; reading with raytrace.readers.meshio against
    trimesh, making the mesh, and the build's steps (fingerprint, triangle tables, BVH).
``mitsuba``
    Mitsuba 3 (``llvm_ad_rgb``, ``direct`` integrator) as a second peer
    (``benchmarks/mitsuba_peer.py``): the mesh scene's warm frame against raytrace's, in this
    process; skipped with a note where Mitsuba or libLLVM is missing.
``gil``
    The share of a render's wall time spent holding the GIL at ``--threads`` and at one
    thread, each scene, sampled by py-spy (``benchmarks/gil.py``); skipped with a note where
    py-spy is missing.

Prints one table per part and writes everything as JSON (``--json``, default
``benchmarks/results.json``). Other processes on the machine make timings noisy: the load
average at the start is recorded with the results.
"""

from __future__ import annotations

import argparse
import inspect
import json
import os
import platform
import sys
import tempfile
import time
from collections import defaultdict
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(HERE))

import gil  # noqa: E402
import meshes  # noqa: E402
import mitsuba_peer  # noqa: E402
import povray  # noqa: E402
from bench_scenes import WHITTED  # noqa: E402

import raytrace  # noqa: E402
from raytrace import accel, accel_cache, malloc  # noqa: E402
from raytrace.scene import Mesh, Plane, Sphere  # noqa: E402


def render_built(scene: raytrace.Scene, **settings) -> raytrace.Image:
    """``raytrace.render`` with the BVH built inside the call, as raw Embree's side of every
    comparison builds its own: a scene rendered again keeps its accelerator
    (:mod:`raytrace.accel_cache`), so the cache is emptied first."""
    accel_cache.clear()
    return raytrace.render(scene, **settings)

PARTS = ("throughput", "povray", "profile", "kernels", "scaling", "startup", "threads",
         "meshes", "mitsuba", "gil")
#: (width, height) of each benchmark scene, full and --quick.
SIZES = {"mesh": (1000, 1000), "whitted": (1280, 960)}
QUICK_SIZES = {"mesh": (160, 160), "whitted": (160, 120)}
#: Icosphere subdivisions standing in for an analytic sphere in the raw-Embree baseline.
BASELINE_SPHERE_SUBDIVISIONS = 5
#: Half-size of the 2-triangle quad standing in for an analytic plane in the baseline.
BASELINE_PLANE_HALF = 1e4
#: Rays per embreex call in the raw replay, on a pool of threads: 16k–64k is Embree's
#: measured sweet spot (EMBREEX_NOTES.md).
RAW_CHUNK = 32768

MESH_SCENE = """\
# Benchmark scene of issue 6: an 81 920-triangle icosphere (smooth, brass) on a 2-triangle
# ground, one point light with shadows. Written by benchmarks/bench.py.
[render]
width = 1000
height = 1000
max_depth = 5

[camera]
position = [0.0, 1.4, 4.2]
look_at = [0.0, 0.9, 0.0]
fov = 40.0

[ambient]
color = 0.1

[materials.ground]
kd = 0.7

[[lights]]
type = "point"
position = [4.0, 6.0, 5.0]

[[objects]]
type = "mesh"
file = "sphere.ply"
shading = "smooth"
translate = [0.0, 1.0, 0.0]
material = "brass"

[[objects]]
type = "mesh"   # the ground: counter-clockwise seen from +y
vertices = [[-20.0, 0.0, -20.0], [20.0, 0.0, -20.0], [20.0, 0.0, 20.0], [-20.0, 0.0, 20.0]]
faces = [[0, 2, 1], [0, 3, 2]]
material = "ground"
"""


# -- scenes -----------------------------------------------------------------------------------
def write_mesh_scene(folder: Path, subdivisions: int = 6) -> Path:
    """The mesh scene as ``mesh.toml`` + ``sphere.ply`` in ``folder`` (subdivision 6: 81 920
    triangles)."""
    import trimesh

    sphere = trimesh.creation.icosphere(subdivisions=subdivisions, radius=1.0)
    sphere.export(folder / "sphere.ply")
    path = folder / "mesh.toml"
    path.write_text(MESH_SCENE)
    return path


def scene_files(workdir: Path) -> dict[str, Path]:
    return {"mesh": write_mesh_scene(workdir), "whitted": WHITTED}


# -- the renderer, whole process --------------------------------------------------------------
def render_cli(scene: Path, out: Path, width: int, height: int, threads: int, spp: int = 1,
               max_depth: int | None = None) -> dict:
    """``raytrace render`` in a subprocess: its ``--stats``, wall time and peak memory."""
    stats_path = out.with_suffix(".stats.json")
    cmd = [sys.executable, "-m", "raytrace", "render", str(scene), "-o", str(out),
           "--width", str(width), "--height", str(height), "--spp", str(spp),
           "--threads", str(threads), "--stats", str(stats_path), "-q"]
    if max_depth is not None:
        cmd += ["--max-depth", str(max_depth)]
    res = povray.measure_process(cmd, cwd=out.parent)
    if res["returncode"] != 0:
        raise RuntimeError(f"{' '.join(cmd)} failed:\n{res['stderr'][-2000:]}")
    stats = json.loads(stats_path.read_text())
    sec = stats["seconds"]
    render = sec["total"] - sec.get("load", 0.0) - sec.get("write", 0.0)
    seconds = {"load": sec.get("load", 0.0), "build": sec["build"], "trace": sec["trace"],
               "shade": sec["shade"], "other": render - sec["build"] - sec["trace"]
               - sec["shade"], "render": render, "write": sec.get("write", 0.0),
               "process_wall": res["wall_seconds"]}
    return {"rays": stats["rays"], "seconds": seconds, "peak_rss_mib": res["peak_rss_mib"],
            "triangles": stats.get("triangles"), "command": " ".join(cmd[1:])}


def best_of(repeat: int, fn):
    """The run with the least render time out of ``repeat`` calls of ``fn()``."""
    runs = [fn() for _ in range(max(1, repeat))]
    return min(runs, key=lambda r: r["seconds"]["render"])


# -- raw Embree on the same rays --------------------------------------------------------------
class Recorder:
    """:attr:`Accelerator.recorder`: keeps every (query, origins, directions, tfar) batch."""

    def __init__(self):
        self.batches: list[tuple[str, np.ndarray, np.ndarray, np.ndarray]] = []

    def __call__(self, query, origins, directions, tfar) -> None:
        self.batches.append((query, origins, directions, tfar))

    def count(self, query: str | None = None) -> int:
        return sum(len(b[1]) for b in self.batches if query in (None, b[0]))


def record_rays(scene_path: Path, width: int, height: int, threads: int, spp: int = 1
                ) -> tuple[raytrace.Scene, Recorder, dict]:
    """Render in this process with the recorder on; returns the scene, the batches, stats.
    The recorder sees the queries of the Python loop (:func:`python_loop`), which traces the
    same rays as the compiled one."""
    scene = raytrace.load_scene(scene_path)
    rec = Recorder()
    accel.Accelerator.recorder = rec
    python_loop()
    try:
        image = raytrace.render(scene, width=width, height=height, spp=spp, threads=threads)
    finally:
        python_loop(False)
        accel.Accelerator.recorder = None
    return scene, rec, image.stats


def _plane_quad(point: np.ndarray, normal: np.ndarray, near: np.ndarray, half: float
                ) -> tuple[np.ndarray, np.ndarray]:
    """Two triangles of a square of half-size ``half`` on the plane, centred at the foot of
    ``near`` (the camera), counter-clockwise about ``normal``."""
    n = normal / np.linalg.norm(normal)
    a = np.array([1.0, 0.0, 0.0]) if abs(n[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    u = np.cross(n, a)
    u /= np.linalg.norm(u)
    w = np.cross(n, u)
    c = near - ((near - point) @ n) * n
    v = np.array([c - half * u - half * w, c + half * u - half * w,
                  c + half * u + half * w, c - half * u + half * w])
    return v, np.array([[0, 2, 1], [0, 3, 2]])


def baseline_geometry(scene: raytrace.Scene) -> list[tuple[np.ndarray, np.ndarray]]:
    """Camera-relative float64 (vertices, faces) of every object as Embree would hold it:
    meshes as they are, spheres as icospheres, planes as large quads."""
    import trimesh

    origin = np.asarray(scene.camera.position, dtype=np.float64)
    ico = trimesh.creation.icosphere(subdivisions=BASELINE_SPHERE_SUBDIVISIONS, radius=1.0)
    out = []
    for o in scene.objects:
        if isinstance(o, Mesh):
            out.append((o.vertices - origin, o.faces))
        elif isinstance(o, Sphere):
            out.append((ico.vertices * o.radius + o.center - origin, ico.faces))
        elif isinstance(o, Plane):
            out.append(_plane_quad(o.point - origin, o.normal, np.zeros(3), BASELINE_PLANE_HALF))
    return out


def embree_scene(geometry: list[tuple[np.ndarray, np.ndarray]]):
    """An embreex scene of the geometry, committed (the first ``run`` builds the BVH)."""
    from embreex import rtcore_scene
    from embreex.mesh_construction import TriangleMesh

    es = rtcore_scene.EmbreeScene()
    for v, f in geometry:
        TriangleMesh(es, np.ascontiguousarray(v, dtype=np.float32),
                     np.ascontiguousarray(f, dtype=np.int32))
    es.run(np.zeros((1, 3), np.float32), np.array([[0, 0, 1]], np.float32), output=0)
    return es


def replay(es, batches, threads: int, chunk: int = RAW_CHUNK) -> dict:
    """Time the batches through embreex alone, driven as fast as Python can: all the rays of
    each query, in the order recorded, cut into chunks of ``chunk`` rays that ``threads``
    threads take from a queue (the embreex notes' fastest way; the renderer's own batches are
    smaller, one pass's rays at a time)."""
    seconds = {"INTERSECT": 0.0, "OCCLUDED": 0.0}
    with ThreadPoolExecutor(threads) as pool:
        for query in seconds:
            mine = [b for b in batches if b[0] == query and len(b[1])]
            if not mine:
                continue
            o = np.concatenate([b[1] for b in mine])
            d = np.concatenate([b[2] for b in mine])
            far = np.concatenate([b[3] for b in mine])
            n = len(o)
            slices = [slice(i, min(i + chunk, n)) for i in range(0, n, chunk)]
            dists = [far[s].copy() for s in slices]  # Embree overwrites them
            if query == "INTERSECT":
                def run(k, o=o, d=d, slices=slices, dists=dists):
                    es.run(o[slices[k]], d[slices[k]], dists=dists[k], output=1)
            else:
                def run(k, o=o, d=d, slices=slices, dists=dists):
                    es.run(o[slices[k]], d[slices[k]], dists=dists[k], query="OCCLUDED")
            t0 = time.perf_counter()
            if threads == 1:
                for k in range(len(slices)):
                    run(k)
            else:
                list(pool.map(run, range(len(slices))))
            seconds[query] += time.perf_counter() - t0
    return seconds


def raw_embree(scene: raytrace.Scene, rec: Recorder, threads: int) -> dict:
    """Build the baseline scene and replay the recorded rays; rays/s over the replay time."""
    geometry = baseline_geometry(scene)
    t0 = time.perf_counter()
    es = embree_scene(geometry)
    build = time.perf_counter() - t0
    sec = replay(es, rec.batches, threads)
    total = sec["INTERSECT"] + sec["OCCLUDED"]
    rays = rec.count()
    analytic = any(isinstance(o, (Sphere, Plane)) for o in scene.objects)
    return {"rays": rays, "intersect_rays": rec.count("INTERSECT"),
            "occluded_rays": rec.count("OCCLUDED"), "batches": len(rec.batches),
            "triangles": int(sum(len(f) for _, f in geometry)),
            "seconds": {"build": build, "intersect": sec["INTERSECT"],
                        "occluded": sec["OCCLUDED"], "trace": total},
            "rays_per_second": rays / total if total > 0 else None,
            "baseline": ("analytic shapes tessellated (icosphere subdivision "
                         f"{BASELINE_SPHERE_SUBDIVISIONS}, plane quad half-size "
                         f"{BASELINE_PLANE_HALF:g})") if analytic else "the scene's own meshes",
            "chunk": RAW_CHUNK, "threads": threads}


def throughput(name: str, path: Path, size: tuple[int, int], threads: int, workdir: Path,
               repeat: int) -> dict:
    """Part ``throughput`` for one scene."""
    w, h = size
    cli = best_of(repeat, lambda: render_cli(path, workdir / f"{name}.exr", w, h, threads))
    scene, rec, stats = record_rays(path, w, h, threads)
    raw = raw_embree(scene, rec, threads)
    del rec
    # Warm: the same render again in this process (numba's kernels already loaded), BVH
    # build included, against raw Embree's BVH build + replay: the same work on both sides.
    warm_sec = min((render_built(scene, width=w, height=h, threads=threads).stats["seconds"]
                    for _ in range(max(3, repeat))), key=lambda sec: sec["total"])
    warm = warm_sec["total"]
    raw_warm = raw["seconds"]["build"] + raw["seconds"]["trace"]
    sec = cli["seconds"]
    total = cli["rays"]["total"]
    rate = total / sec["render"]
    row = {"scene": name, "file": str(path), "width": w, "height": h, "pixels": w * h, "spp": 1,
           "max_depth": scene.render.max_depth, "threads": threads,
           "triangles": cli["triangles"], "analytic_shapes": sum(
               isinstance(o, (Sphere, Plane)) for o in scene.objects),
           "rays": cli["rays"], "seconds": sec, "rays_per_second": rate,
           "trace_rays_per_second": total / sec["trace"] if sec["trace"] > 0 else None,
           "peak_rss_mib": cli["peak_rss_mib"], "raw_embree": raw,
           "ratio": rate / raw["rays_per_second"] if raw["rays_per_second"] else None,
           "warm_seconds": warm, "warm_rays_per_second": total / warm,
           "raw_build_and_trace_seconds": raw_warm,
           "warm_ratio": raw_warm / warm,
           # the BVH kept from render to render, as if: both builds left out
           "warm_build_seconds": warm_sec["build"],
           "warm_ratio_without_build": raw["seconds"]["trace"] / (warm - warm_sec["build"]),
           "rays_match": raw["rays"] == total and stats["rays"]["total"] == total,
           "command": cli["command"]}
    return row


def povray_part(name: str, path: Path, size: tuple[int, int], threads: int, workdir: Path,
                rt: dict | None) -> dict:
    """Part ``povray`` for one scene: render the POV-Ray equivalent, side by side."""
    w, h = size
    scene = raytrace.load_scene(path)
    pov = povray.write_pov(scene, workdir / f"{name}.pov", w, h)
    res = povray.run_povray(pov, w, h, threads)
    row = {"scene": name, "width": w, "height": h, "threads": threads,
           "version": povray.version(), "returncode": res["returncode"],
           "wall_seconds": res["wall_seconds"], "seconds": res["seconds"],
           "peak_rss_mib": res["peak_rss_mib"], "counts": res["counts"],
           "command": res["command"], "pov_file_mib": pov.stat().st_size / 2**20}
    if res["returncode"]:
        row["log_tail"] = res["log_tail"]
    if rt is not None and not res["returncode"]:
        trace = res["seconds"].get("trace")
        ours = rt["seconds"]["trace"] + rt["seconds"]["shade"] + rt["seconds"]["other"]
        row["raytrace_wall_seconds"] = rt["seconds"]["process_wall"]
        row["raytrace_trace_seconds"] = ours
        row["wall_ratio"] = rt["seconds"]["process_wall"] / res["wall_seconds"]
        row["trace_ratio"] = ours / trace if trace else None
    return row


# -- where the time goes ----------------------------------------------------------------------
class Timers:
    """Exclusive wall time per category of nested, wrapped calls (one thread only)."""

    def __init__(self):
        self.seconds: dict[str, float] = defaultdict(float)
        self.calls: dict[str, int] = defaultdict(int)
        self._stack: list[float] = []

    def wrap(self, category: str, fn):
        def timed(*args, **kwargs):
            t0 = time.perf_counter()
            self._stack.append(0.0)
            try:
                return fn(*args, **kwargs)
            finally:
                dt = time.perf_counter() - t0
                inner = self._stack.pop()
                self.seconds[category] += dt - inner
                self.calls[category] += 1
                if self._stack:
                    self._stack[-1] += dt
        return timed


def python_loop(on: bool = True) -> None:
    """Run renders through the integrator's Python loop (``on``), or as configured again
    (``RAYTRACE_LOOP``): the per-stage and per-kernel breakdowns and the recorder time and see
    the steps from Python, which the compiled loop (``raytrace.kernels.loop.trace_paths``)
    runs inside one call. Both call the same kernels in the same order (tests/test_loop.py)."""
    from raytrace import integrator

    integrator.WhittedIntegrator.compiled = False if on else integrator.COMPILED_LOOP


def time_embree(timers: Timers) -> Callable[[], None]:
    """Time Embree's traversal kernels (:mod:`raytrace.kernels.embree`'s ``closest_hits`` and
    ``any_hits``, the packet calls and their packing) as ``embree``; returns the undo."""
    from raytrace.kernels import embree as embree_kernels

    saved = {name: getattr(embree_kernels, name) for name in ("closest_hits", "any_hits")}
    for name, fn in saved.items():
        setattr(embree_kernels, name, timers.wrap("embree", fn))
    return lambda: [setattr(embree_kernels, name, fn) for name, fn in saved.items()]


#: (module or class, attribute, category) timed by :func:`profile_breakdown`.
def _targets():
    from raytrace import analytic, integrator, rays

    W, A = integrator.WhittedIntegrator, accel.Accelerator
    return [
        (A, "intersect", "accel"), (A, "occluded", "accel"), (A, "surface", "accel"),
        (analytic.AnalyticShapes, "intersect", "analytic"),
        (analytic.AnalyticShapes, "surface", "analytic"),
        (integrator, "camera_rays", "camera"),
        (integrator, "add", "accumulation"),
        (rays.RayBatch, "take", "compaction"),
        (W, "_prune", "compaction"), (integrator, "take_hits", "compaction"),
        (W, "trace", "integrator"), (W, "render", "integrator"),
        (W, "shade", "shading"), (W, "direct_lighting", "shading"), (W, "shadow", "shading"),
        (W, "_spawn", "compaction"),
    ]


def profile_breakdown(path: Path, width: int, height: int) -> dict:
    """One single-threaded render in this process with every pipeline stage timed
    exclusively: Embree's ``run`` calls, analytic intersection, the rest of raytrace.accel
    (float32 conversion, float64 hit refinement, surfaces), camera rays, shading (lights,
    highlights, materials, spawning children), compaction, accumulation, the integrator's own
    loop; plus the BVH build, the scene load and the EXR write."""
    from raytrace.film import write_exr

    timers = Timers()
    saved = []
    for owner, name, category in _targets():
        raw = inspect.getattr_static(owner, name)  # a renamed stage fails here, not silently
        fn = raw.__func__ if isinstance(raw, staticmethod) else raw
        wrapped = timers.wrap(category, fn)
        setattr(owner, name, staticmethod(wrapped) if isinstance(raw, staticmethod) else wrapped)
        saved.append((owner, name, raw))
    build = accel.Accelerator._build_meshes

    def timed_build(self, *args, **kwargs):
        t0 = time.perf_counter()
        build(self, *args, **kwargs)
        timers.seconds["build"] += time.perf_counter() - t0

    accel.Accelerator._build_meshes = timed_build
    untime = time_embree(timers)
    python_loop()
    try:
        t0 = time.perf_counter()
        scene = raytrace.load_scene(path)
        load = time.perf_counter() - t0
        t0 = time.perf_counter()
        image = raytrace.render(scene, width=width, height=height, threads=1)
        render = time.perf_counter() - t0
        t0 = time.perf_counter()
        write_exr(Path(tempfile.gettempdir()) / f"raytrace-profile-{os.getpid()}.exr", image.rgb)
        write = time.perf_counter() - t0
    finally:
        python_loop(False)
        untime()
        accel.Accelerator._build_meshes = build
        for owner, name, raw in saved:
            setattr(owner, name, raw)
        (Path(tempfile.gettempdir()) / f"raytrace-profile-{os.getpid()}.exr").unlink(
            missing_ok=True)
    sec = dict(timers.seconds)
    sec["other"] = render - sum(sec.values())
    sec["load"], sec["write"] = load, write
    return {"scene": Path(path).stem, "width": width, "height": height, "threads": 1,
            "rays": image.stats["rays"], "render_seconds": render,
            "seconds": dict(sorted(sec.items(), key=lambda kv: -kv[1])),
            "calls": dict(timers.calls)}


def kernel_breakdown(path: Path, width: int, height: int) -> dict:
    """Seconds and calls of every compiled kernel and of Embree's traversal kernels in one
    single-threaded render through the Python loop (:func:`python_loop`), after a first
    render that loads every kernel from numba's cache. Kernels run during the BVH build are
    reported apart (``build_kernels``)."""
    from raytrace import analytic, camera, integrator, rays
    from raytrace.kernels import accel as accel_kernels
    from raytrace.kernels import shading as shading_kernels

    scene = raytrace.load_scene(path)
    python_loop()
    try:
        raytrace.render(scene, width=width, height=height, threads=1)
    finally:
        python_loop(False)
    timers = Timers()
    saved = []
    owners = (accel_kernels, shading_kernels, camera, rays, integrator, accel, analytic)
    for module in (accel_kernels, shading_kernels, camera, rays):
        for name, fn in list(vars(module).items()):
            if not hasattr(fn, "py_func") or fn.__module__ != module.__name__:
                continue
            wrapped = timers.wrap(name, fn)
            for owner in owners:  # the module itself and every module that imported the name
                if getattr(owner, name, None) is fn:
                    saved.append((owner, name, fn))
                    setattr(owner, name, wrapped)
    build = accel.Accelerator._build_meshes
    during_build: dict[str, float] = {}

    def timed_build(self, *args, **kwargs):
        before = dict(timers.seconds)
        t0 = time.perf_counter()
        build(self, *args, **kwargs)
        during_build["seconds"] = time.perf_counter() - t0
        during_build.update({k: v - before.get(k, 0.0) for k, v in timers.seconds.items()
                             if v != before.get(k, 0.0)})

    accel.Accelerator._build_meshes = timed_build
    untime = time_embree(timers)
    python_loop()
    try:
        t0 = time.perf_counter()
        image = render_built(scene, width=width, height=height, threads=1)
        render = time.perf_counter() - t0
    finally:
        python_loop(False)
        untime()
        accel.Accelerator._build_meshes = build
        for owner, name, fn in saved:
            setattr(owner, name, fn)
    build_seconds = during_build.pop("seconds", 0.0)
    seconds = {k: v - during_build.get(k, 0.0) for k, v in timers.seconds.items()}
    embree = seconds.pop("embree", 0.0)
    kernels = {k: v for k, v in sorted(seconds.items(), key=lambda kv: -kv[1]) if v > 0}
    total = sum(kernels.values())
    return {"scene": Path(path).stem, "width": width, "height": height, "threads": 1,
            "rays": image.stats["rays"]["total"], "render_seconds": render,
            "build_seconds": build_seconds, "build_kernels": during_build,
            "embree_seconds": embree, "kernel_seconds": total,
            "python_seconds": render - build_seconds - embree - total,
            "kernels": kernels, "calls": {k: timers.calls[k] for k in kernels}}


def warm_ceiling(kernels: dict, throughput_row: dict) -> float:
    """The warm ratio with no Python between the kernels and a perfect speed-up from every
    thread: raw build + run over ``build + (Embree + kernels) / threads`` of the
    single-threaded render (the BVH build is serial on both sides)."""
    raw = throughput_row["raw_embree"]["seconds"]
    best = kernels["build_seconds"] + (kernels["embree_seconds"] + kernels["kernel_seconds"]) \
        / throughput_row["threads"]
    return (raw["build"] + raw["trace"]) / best


# -- scaling, start-up, threads ----------------------------------------------------------------
def linear_fit(samples: list[int], seconds: list[float]) -> dict:
    """Least-squares ``seconds = fixed + per_sample·samples`` and the largest relative
    residual: how far the runs are from linear growth."""
    x, y = np.asarray(samples, float), np.asarray(seconds, float)
    if len(x) < 2 or np.ptp(x) == 0:
        return {"fixed_seconds": None, "microseconds_per_sample": None, "max_residual": None}
    b, a = np.polyfit(x, y, 1)
    resid = np.abs(y - (a + b * x)) / y
    return {"fixed_seconds": float(a), "microseconds_per_sample": float(b * 1e6),
            "max_residual": float(resid.max())}


def scaling(path: Path, threads: int, workdir: Path, quick: bool, big: bool) -> dict:
    """Render seconds against pixels and spp; the 4K × 4 spp peak memory when ``big``."""
    cases = ([(80, 80, 1), (160, 160, 1), (80, 80, 4)] if quick else
             [(250, 250, 1), (500, 500, 1), (1000, 1000, 1), (500, 500, 4), (250, 250, 16)])
    rows = []
    for w, h, spp in cases:
        r = render_cli(path, workdir / "scale.exr", w, h, threads, spp)
        n = w * h * spp
        rows.append({"width": w, "height": h, "spp": spp, "samples": n, "rays": r["rays"],
                     "seconds": r["seconds"]["render"],
                     "microseconds_per_sample": 1e6 * r["seconds"]["render"] / n,
                     "peak_rss_mib": r["peak_rss_mib"]})
    out = {"scene": "mesh", "runs": rows, **linear_fit([r["samples"] for r in rows],
                                                       [r["seconds"] for r in rows])}
    if big:
        r = render_cli(path, workdir / "big.exr", 3840, 2160, threads, 4)
        out["big"] = {"width": 3840, "height": 2160, "spp": 4, "rays": r["rays"],
                      "seconds": r["seconds"], "peak_rss_mib": r["peak_rss_mib"],
                      "under_2_gib": r["peak_rss_mib"] < 2048}
        (workdir / "big.exr").unlink(missing_ok=True)
    return out


def startup(workdir: Path, threads: int, runs: int = 3) -> dict:
    """Whole-process wall time of a small analytic render to EXR, and of importing raytrace."""
    walls, stats = [], None
    for _ in range(runs):
        r = render_cli(WHITTED, workdir / "small.exr", 64, 48, threads)
        walls.append(r["seconds"]["process_wall"])
        stats = r["seconds"]
    imports = [povray.measure_process([sys.executable, "-c", "import raytrace"])["wall_seconds"]
               for _ in range(runs)]
    return {"scene": "whitted", "width": 64, "height": 48, "walls": walls, "best": min(walls),
            "under_1_s": min(walls) < 1.0, "last_seconds": stats,
            "import_walls": imports, "import_best": min(imports)}


def threads_part(files: dict[str, Path], workdir: Path, quick: bool, repeat: int,
                 counts: tuple[int, ...] | None = None) -> list:
    """Each scene at each of ``counts`` threads (default 1, 2, 4): render seconds and
    speed-up over the first count, cold (``raytrace render`` in a fresh process, which pays
    numba's one-off set-up), warm (a render in this process after one that loaded the
    kernels, its BVH built inside the timing, best of ``repeat``, at least 3) and kept (the
    BVH kept from the render before), and whether each EXR is bit-identical to the first
    count's image."""
    sizes = QUICK_SIZES if quick else SIZES  # at full size 16 (mesh), 19–20 passes (Whitted)
    counts = counts or ((1, 2) if quick else (1, 2, 4))
    out = []
    for name, path in files.items():
        w, h = sizes[name]
        scene = raytrace.load_scene(path)
        raytrace.render(scene, width=16, height=16)  # loads every kernel the scene needs
        ref = base = warm_base = kept_base = None
        for t in counts:
            exr = workdir / f"threads{t}.exr"
            r = best_of(repeat, lambda t=t, exr=exr, p=path, w=w, h=h: render_cli(p, exr, w, h, t))
            rgb = raytrace.read_exr(exr)[0]
            # one sample a pixel, as render_cli renders (the Whitted scene's own is 4)
            images = [render_built(scene, width=w, height=h, threads=t, spp=1)
                      for _ in range(max(3, repeat))]
            warm = min(im.stats["seconds"]["total"] for im in images)
            kept = min(raytrace.render(scene, width=w, height=h, threads=t, spp=1)
                       .stats["seconds"]["total"] for _ in range(max(3, repeat)))
            if ref is None:
                ref, base, warm_base, kept_base = rgb, r["seconds"]["render"], warm, kept
            out.append({"scene": name, "width": w, "height": h, "threads": t,
                        "seconds": r["seconds"]["render"],
                        "speedup": base / r["seconds"]["render"],
                        "warm_seconds": warm, "warm_speedup": warm_base / warm,
                        "kept_seconds": kept, "kept_speedup": kept_base / kept,
                        "identical": all(np.array_equal(x.view(np.uint32), ref.view(np.uint32))
                                         for x in (rgb, images[0].rgb))})
            if t == 2 and counts[0] == 1:
                out[-1].update(gil.amdahl(warm_base, warm))
    return out


def gil_part(files: dict[str, Path], threads: int, quick: bool) -> list:
    """Each scene's GIL share at ``threads`` threads and at one (``benchmarks/gil.py``)."""
    missing = gil.available()
    if missing:
        return [{"missing": missing}]
    sizes = QUICK_SIZES if quick else SIZES
    return [gil.measure(path, *sizes[name], t, seconds=2.0 if quick else 6.0)
            for name, path in files.items() for t in dict.fromkeys((threads, 1))]


# -- reporting --------------------------------------------------------------------------------
def _f(x, fmt="{:.3f}") -> str:
    return "-" if x is None else fmt.format(x)


def _m(x) -> str:
    return "-" if x is None else f"{x / 1e6:.2f}M"


def table(headers: list[str], rows: list[list[str]]) -> str:
    widths = [max(len(h), *(len(r[i]) for r in rows)) if rows else len(h)
              for i, h in enumerate(headers)]
    line = "  ".join(h.rjust(w) for h, w in zip(headers, widths, strict=True))
    body = ["  ".join(c.rjust(w) for c, w in zip(r, widths, strict=True)) for r in rows]
    return "\n".join([line, "-" * len(line), *body])


def report(results: dict) -> str:
    out = []
    if results.get("throughput"):
        rows = []
        for r in results["throughput"]:
            s, rays, raw = r["seconds"], r["rays"], r["raw_embree"]
            rows.append([r["scene"], f"{r['width']}x{r['height']}", _m(rays["camera"]),
                         _m(rays["shadow"]), _m(rays["reflection"]), _m(rays["refraction"]),
                         _m(rays["total"]), _f(s["build"]), _f(s["trace"]), _f(s["shade"]),
                         _f(s["other"]), _f(s["write"]), _f(s["process_wall"]),
                         _m(r["rays_per_second"]), _m(raw["rays_per_second"]),
                         _f(r["ratio"], "{:.2f}"), _f(r.get("warm_seconds")),
                         _f(r.get("raw_build_and_trace_seconds")),
                         _f(r.get("warm_ratio"), "{:.2f}"), _f(r["peak_rss_mib"], "{:.0f}")])
        out.append("throughput (rays/s = all rays / render seconds of a fresh process; raw = "
                   "embreex alone on the same rays, run calls only; warm = a second render in "
                   "one process, BVH build included, against raw build + run calls)\n" + table(
                       ["scene", "pixels", "camera", "shadow", "reflect", "refract", "total",
                        "build", "trace", "shade", "other", "write", "wall", "rays/s",
                        "raw/s", "ratio", "warm s", "raw s", "ratio", "MiB"], rows))
    if results.get("povray"):
        rows = [[r["scene"], f"{r['width']}x{r['height']}", _f(r.get("raytrace_wall_seconds")),
                 _f(r["wall_seconds"]), _f(r.get("wall_ratio"), "{:.2f}"),
                 _f(r.get("raytrace_trace_seconds")), _f(r["seconds"].get("parse")),
                 _f(r["seconds"].get("trace")), _f(r.get("trace_ratio"), "{:.2f}"),
                 _f(r["peak_rss_mib"], "{:.0f}")] for r in results["povray"]]
        out.append("POV-Ray 3.7 (ratios: raytrace time / POV-Ray time; < 1 means raytrace is "
                   "faster)\n" + table(
                       ["scene", "pixels", "rt wall", "pov wall", "ratio", "rt trace+shade",
                        "pov parse", "pov trace", "ratio", "pov MiB"], rows))
    if results.get("profile"):
        for r in results["profile"]:
            total = r["render_seconds"] + r["seconds"]["load"] + r["seconds"]["write"]
            rows = [[k, _f(v), f"{100 * v / total:.1f}%"] for k, v in r["seconds"].items()]
            out.append(f"where the time goes: {r['scene']} {r['width']}x{r['height']}, 1 thread, "
                       f"{r['rays']['total'] / 1e6:.2f}M rays, {total:.2f} s\n"
                       + table(["stage", "seconds", "share"], rows))
    for r in results.get("kernels", []):
        rows = [[k, _f(1e3 * v, "{:.1f}"), str(r["calls"][k])] for k, v in r["kernels"].items()]
        ceiling = (f"; warm ceiling with no Python and perfect threads: "
                   f"{r['warm_ceiling']:.2f}" if r.get("warm_ceiling") is not None else "")
        out.append(f"kernels: {r['scene']} {r['width']}x{r['height']}, 1 thread, render "
                   f"{r['render_seconds']:.3f} s = build {r['build_seconds']:.3f} + Embree "
                   f"{r['embree_seconds']:.3f} + kernels {r['kernel_seconds']:.3f} + Python "
                   f"{r['python_seconds']:.3f}{ceiling}\n"
                   + table(["kernel", "ms", "calls"], rows))
    if results.get("scaling"):
        sc = results["scaling"]
        rows = [[f"{r['width']}x{r['height']}", str(r["spp"]), str(r["samples"]),
                 _f(r["seconds"]), _f(r["microseconds_per_sample"], "{:.2f}"),
                 _f(r["peak_rss_mib"], "{:.0f}")] for r in sc["runs"]]
        if "big" in sc:
            b = sc["big"]
            n = b["width"] * b["height"] * b["spp"]
            rows.append([f"{b['width']}x{b['height']}", str(b["spp"]), str(n),
                         _f(b["seconds"]["render"]),
                         _f(1e6 * b["seconds"]["render"] / n, "{:.2f}"),
                         _f(b["peak_rss_mib"], "{:.0f}")])
        out.append(f"scaling (mesh scene; fit: {_f(sc['fixed_seconds'])} s + "
                   f"{_f(sc['microseconds_per_sample'], '{:.2f}')} us/sample, largest "
                   f"residual {_f(sc['max_residual'], '{:.1%}')})\n"
                   + table(["pixels", "spp", "samples", "render s", "us/sample", "peak MiB"],
                           rows))
    if results.get("startup"):
        s = results["startup"]
        out.append(f"start-up: raytrace render whitted 64x48 to EXR, wall "
                   f"{', '.join(f'{w:.3f}' for w in s['walls'])} s (best {s['best']:.3f}); "
                   f"import raytrace {s['import_best']:.3f} s")
    if results.get("threads"):
        rows = [[r["scene"], f"{r['width']}x{r['height']}", str(r["threads"]),
                 _f(r["seconds"]), _f(r["speedup"], "{:.2f}"), _f(r.get("warm_seconds")),
                 _f(r.get("warm_speedup"), "{:.2f}"), _f(r.get("kept_seconds")),
                 _f(r.get("kept_speedup"), "{:.2f}"), str(r["identical"])]
                for r in results["threads"]]
        out.append("threads (cold: a fresh process; warm: a second render in one process, BVH "
                   "built inside; kept: its BVH kept)\n"
                   + table(["scene", "pixels", "threads", "cold s", "speed-up", "warm s",
                            "speed-up", "kept s", "speed-up", "identical"], rows))
        for r in results["threads"]:
            if "serial_fraction" in r:
                out.append(f"Amdahl, {r['scene']} warm 1 -> 2 threads: {r['speedup_2']:.2f}x, "
                           f"serial fraction {r['serial_fraction']:.1%}, predicts "
                           f"{r['predicted_speedup_16']:.1f}x on 16 cores")
    if results.get("meshes"):
        out.append(meshes.report(results["meshes"]))
    if results.get("mitsuba"):
        out.append(mitsuba_peer.report(results["mitsuba"]))
    if results.get("gil"):
        out.append(gil.report(results["gil"]))
    return "\n\n".join(out)


def machine() -> dict:
    import embreex

    return {"cpus": os.cpu_count(), "platform": platform.platform(),
            "python": platform.python_version(), "numpy": np.__version__,
            "embreex": getattr(embreex, "__version__", None), "povray": povray.version(),
            "load_average": os.getloadavg()}


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--quick", action="store_true", help="small sizes: a smoke run")
    p.add_argument("--parts", default=",".join(PARTS),
                   help=f"comma-separated subset of {', '.join(PARTS)}")
    p.add_argument("--scenes", default="mesh,whitted", help="comma-separated: mesh, whitted")
    p.add_argument("--threads", type=int, default=os.cpu_count() or 1)
    p.add_argument("--repeat", type=int, default=1, help="renders per timing (best kept)")
    p.add_argument("--thread-counts", default=None,
                   help="the threads part's thread counts, comma-separated (default 1,2,4)")
    p.add_argument("--no-big", action="store_true", help="skip the 3840x2160 4 spp render")
    p.add_argument("--json", default=str(HERE / "results.json"), help="results file")
    p.add_argument("--workdir", help="folder for scenes and images (default: a temp folder)")
    a = p.parse_args(argv)
    malloc.tune()  # as the command line does for its process (docs/performance.md, "The allocator")
    parts = [x for x in a.parts.split(",") if x]
    unknown = sorted(set(parts) - set(PARTS))
    if unknown:
        p.error(f"unknown part(s) {', '.join(unknown)} "
                f"(choose from {', '.join(PARTS)})")
    names = [x for x in a.scenes.split(",") if x]
    if set(names) - set(SIZES):
        p.error(f"unknown scene(s) in {a.scenes!r} (choose from {', '.join(SIZES)})")
    sizes = QUICK_SIZES if a.quick else SIZES
    results: dict = {"machine": machine(), "command": " ".join(sys.argv),
                     "settings": {"quick": a.quick, "threads": a.threads, "parts": parts,
                                  "repeat": a.repeat}}
    with tempfile.TemporaryDirectory(prefix="raytrace-bench-") as tmp:
        workdir = Path(a.workdir) if a.workdir else Path(tmp)
        workdir.mkdir(parents=True, exist_ok=True)
        files = {k: v for k, v in scene_files(workdir).items() if k in names}
        rt_rows = {}
        if "throughput" in parts:
            results["throughput"] = []
            for name, path in files.items():
                row = throughput(name, path, sizes[name], a.threads, workdir, a.repeat)
                results["throughput"].append(row)
                rt_rows[name] = row
        if "povray" in parts:
            if povray.available():
                results["povray"] = [povray_part(n, f, sizes[n], a.threads, workdir,
                                                 rt_rows.get(n)) for n, f in files.items()]
            else:
                results["povray"] = []
                results["povray_missing"] = "povray not found (apt-get install povray)"
        if "profile" in parts:
            results["profile"] = [profile_breakdown(f, *sizes[n]) for n, f in files.items()]
        if "kernels" in parts:
            results["kernels"] = [kernel_breakdown(f, *sizes[n]) for n, f in files.items()]
            for row in results["kernels"]:
                if row["scene"] in rt_rows:
                    row["warm_ceiling"] = warm_ceiling(row, rt_rows[row["scene"]])
        if "scaling" in parts:
            results["scaling"] = scaling(scene_files(workdir)["mesh"], a.threads, workdir,
                                         a.quick, big=not (a.quick or a.no_big))
        if "startup" in parts:
            results["startup"] = startup(workdir, a.threads, runs=2 if a.quick else 3)
        if "threads" in parts:
            counts = tuple(int(x) for x in a.thread_counts.split(",")) if a.thread_counts \
                else None
            results["threads"] = threads_part(files, workdir, a.quick, a.repeat, counts)
        if "meshes" in parts:
            results["meshes"] = meshes.run(workdir / "meshes", a.threads, a.quick)
        if "mitsuba" in parts:
            results["mitsuba"] = mitsuba_peer.compare(workdir / "mitsuba", a.threads, a.quick,
                                                      max(3, a.repeat))
        if "gil" in parts:
            results["gil"] = gil_part(files, a.threads, a.quick)
    results["machine"]["load_average_end"] = os.getloadavg()
    Path(a.json).write_text(json.dumps(results, indent=2, default=float) + "\n")
    print(report(results))
    print(f"\nwrote {a.json}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
