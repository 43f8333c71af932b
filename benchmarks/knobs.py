"""What each quality knob buys: image error against render time, measured.

    python3 benchmarks/knobs.py                  # the full sweep (a few minutes)
    python3 benchmarks/knobs.py --quick          # tiny sizes: checks the harness
    python3 benchmarks/knobs.py --threads 2 --json benchmarks/knobs.json \\
        --plots docs/knobs

Each knob is swept on a scene where it matters. Every setting is rendered in this process
with :func:`raytrace.render` (after one warm-up render of every scene, so numba's compiled
kernels are loaded and the times are render times, not start-up), timed as the best of a few
renders, and compared with a reference image of the same size:

``spp``
    samples per pixel (stratified k×k jitter) on ``scenes/area_light.toml``; the reference is
    a high-spp render with *another seed*, and two such references with different seeds,
    compared to each other, give the reference's own noise floor. For independent, unbiased
    estimates T and R of the true image I, E|T − R|² = |T − I|² + |R − I|² and
    E|R₁ − R₂|² = 2|R − I|², so the error of T against the truth is estimated as
    sqrt(RMSE² − floor²/2). The slope of log RMSE over log spp is fitted by least squares.
``max_depth``
    the recursion limit on ``scenes/whitted.toml`` and ``scenes/tir.toml`` against a deep
    render (same ``min_weight`` 0); the rays of each kind come from ``image.stats``. Because
    every term of Whitted's sum is non-negative, a shallower image is a prefix of the deeper
    one's sum and its error can only fall as the depth grows. For the TIR scene a converged
    render (very deep, with a tiny ``min_weight``) is compared as well: some of its light
    paths need more than 16 bounces.
``min_weight``
    Hall & Greenberg's (1983) adaptive depth control: a secondary ray whose weight (the
    product of the kr, kt, opacity factors on its path) is below the threshold is not traced;
    against ``min_weight`` 0 at the same depth.
``area_samples``
    the k² point samples of an :class:`raytrace.AreaLight`, on a grid (``jitter`` false) or
    stratified at random (``jitter`` true, averaged over a few seeds), against a
    4096-sample grid: the penumbra's error against its cost in shadow rays.

Errors are over linear RGB (every pixel and channel): RMSE = sqrt(mean((a − b)²)), the largest
|a − b|, and RMSE / mean(reference). Prints one table per knob, writes everything as JSON
(``--json``) and one log-log plot of error against seconds per knob (``--plots``; needs
matplotlib, which is imported only there). Other processes on the machine make the times
noisy: the load average at the start and the end is in the JSON.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import platform
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent

from bench_scenes import scene_path  # noqa: E402

import raytrace  # noqa: E402
from raytrace.scene import AreaLight, Scene  # noqa: E402

SCENES = {name: scene_path(name)
          for name in ("area_light", "whitted", "tir", "mesh_model")}
RAY_KINDS = ("camera", "shadow", "reflection", "refraction", "see_through", "total")

#: The full sweep. Sizes keep the whole run to a few minutes on two cores.
FULL = {
    "spp": {"scene": "area_light", "size": (240, 180), "values": [1, 4, 16, 64, 256],
            "fit_max": 64, "reference_spp": 1024, "reference_seeds": (101, 202)},
    "max_depth": {
        "whitted": {"size": (480, 360), "values": list(range(9)), "reference_depth": 16},
        "tir": {"size": (200, 125), "values": [*range(9), 10, 12, 14, 16],
                "reference_depth": 16, "converged": (128, 1e-7)},
        "tir_pruned": {"scene": "tir", "size": (200, 125), "values": [8, 16, 32, 64, 128],
                       "min_weight": 1e-3, "converged": (128, 1e-7)},
    },
    "min_weight": {
        "tir": {"size": (200, 125), "depth": 16, "converged": (128, 1e-7)},
        "whitted": {"size": (480, 360), "depth": 16},
        "values": [0.0, 1e-4, 1e-3, 1e-2, 5e-2],
    },
    "area_samples": {"scene": "area_light", "size": (240, 180), "values": [1, 4, 16, 64, 256],
                     "reference_samples": 4096, "check_samples": 1024,
                     "jitter_seeds": (1, 2, 3)},
    "jitter_spp": {"scene": "area_light", "size": (120, 90), "samples": 16,
                   "values": [1, 4, 16, 64], "reference": (64, 256)},
    "repeats": 3, "budget": 4.0,
}

#: ``--quick``: the same sweep at tiny sizes, one render per timing.
QUICK = {
    "spp": {"scene": "area_light", "size": (48, 36), "values": [1, 4, 16], "fit_max": 16,
            "reference_spp": 64, "reference_seeds": (101, 202)},
    "max_depth": {
        "whitted": {"size": (64, 48), "values": list(range(5)), "reference_depth": 6},
        "tir": {"size": (48, 30), "values": list(range(5)), "reference_depth": 6,
                "converged": (24, 1e-5)},
        "tir_pruned": {"scene": "tir", "size": (48, 30), "values": [4, 8, 16],
                       "min_weight": 1e-3, "converged": (24, 1e-5)},
    },
    "min_weight": {
        "tir": {"size": (48, 30), "depth": 8, "converged": (24, 1e-5)},
        "whitted": {"size": (64, 48), "depth": 8},
        "values": [0.0, 1e-4, 1e-3, 1e-2, 5e-2],
    },
    "area_samples": {"scene": "area_light", "size": (48, 36), "values": [1, 4, 16],
                     "reference_samples": 256, "check_samples": 64, "jitter_seeds": (1, 2)},
    "jitter_spp": {"scene": "area_light", "size": (32, 24), "samples": 4, "values": [1, 4],
                   "reference": (16, 64)},
    "repeats": 1, "budget": 0.0,
}


# -- error measures ------------------------------------------------------------------------------
def rmse(image: np.ndarray, reference: np.ndarray) -> float:
    """Root-mean-square error over every pixel and channel: sqrt(mean((a − b)²)), in float64."""
    d = np.asarray(image, np.float64) - np.asarray(reference, np.float64)
    return float(np.sqrt(np.mean(d * d)))


def max_error(image: np.ndarray, reference: np.ndarray) -> float:
    """The largest absolute difference of any pixel channel: max |a − b|."""
    return float(np.max(np.abs(np.asarray(image, np.float64) - np.asarray(reference, np.float64))))


def errors(image: np.ndarray, reference: np.ndarray) -> dict:
    """RMSE, max |error| and RMSE / mean(reference) (the error as a fraction of the image)."""
    e = rmse(image, reference)
    mean = float(np.mean(np.asarray(reference, np.float64)))
    return {"rmse": e, "max_error": max_error(image, reference),
            "relative": e / mean if mean > 0 else float("nan")}


def loglog_slope(x: Sequence[float], y: Sequence[float]) -> tuple[float, float]:
    """Least-squares fit of log10 y = slope·log10 x + intercept: (slope, intercept).

    y ∝ x^p gives slope p (Monte Carlo noise: p = −1/2; stratified jitter over edges: −3/4).

    >>> round(loglog_slope([1, 4, 16], [1.0, 0.5, 0.25])[0], 6)
    -0.5
    """
    lx, ly = np.log10(np.asarray(x, np.float64)), np.log10(np.asarray(y, np.float64))
    slope, intercept = np.polyfit(lx, ly, 1)
    return float(slope), float(intercept)


def truth_estimate(error: float, floor: float) -> float:
    """The error against the true image, sqrt(max(RMSE² − floor²/2, 0)), for a reference
    whose own error is ``floor / sqrt(2)`` (``floor``: RMSE between two references)."""
    return float(np.sqrt(max(error * error - floor * floor / 2.0, 0.0)))


# -- scenes and renders --------------------------------------------------------------------------
def load(name: str) -> Scene:
    """One of the scenes in scenes/ by name (``area_light``, ``whitted``, ``tir``)."""
    return raytrace.load_scene(SCENES[name])


def with_area_samples(scene: Scene, samples: int, jitter: bool) -> Scene:
    """A copy of ``scene`` with every area light sampled by ``samples`` (= k²) points, on a
    grid or jittered; the scene file and ``scene`` itself are left alone."""
    lights = [dataclasses.replace(light, samples=samples, jitter=jitter)
              if isinstance(light, AreaLight) else light for light in scene.lights]
    return dataclasses.replace(scene, lights=lights)


def timed_render(scene: Scene, *, repeats: int = 1, budget: float = 0.0, threads: int = 1,
                 **settings) -> tuple[float, raytrace.Image]:
    """Render ``repeats`` times (at least once, and no more once ``budget`` seconds have been
    spent) and return the fastest wall time of :func:`raytrace.render` and the image (every
    repeat renders the same image: a render is deterministic for a given seed)."""
    best, image, spent = float("inf"), None, 0.0
    for i in range(max(repeats, 1)):
        if i and spent >= budget:
            break
        t0 = time.perf_counter()
        image = raytrace.render(scene, threads=threads, **settings)
        seconds = time.perf_counter() - t0
        best, spent = min(best, seconds), spent + seconds
    return best, image


#: Reference renders already made in this process, by (scene, settings): the converged TIR
#: render serves three sweeps. The scene is kept in the value so that its id stays unique.
_REFERENCES: dict[tuple, tuple[Scene, float, raytrace.Image]] = {}


def reference_render(scene: Scene, *, threads: int = 1,
                     **settings) -> tuple[float, raytrace.Image]:
    """:func:`timed_render` once, remembered for later calls with the same scene object and
    settings (renders are deterministic, so the image is the same)."""
    key = (id(scene), threads, tuple(sorted(settings.items())))
    if key not in _REFERENCES:
        _REFERENCES[key] = (scene, *timed_render(scene, threads=threads, **settings))
    return _REFERENCES[key][1:]


def warm_up(scenes: Sequence[Scene], threads: int) -> float:
    """One tiny render of each scene, so numba's kernels are loaded before anything is timed."""
    t0 = time.perf_counter()
    for scene in scenes:
        raytrace.render(scene, width=16, height=12, spp=4, threads=threads)
    return time.perf_counter() - t0


def _name(scene: Scene) -> str:
    """The scene file relative to the repository (as the tables print it)."""
    path = Path(scene.path) if scene.path else None
    if path is None:
        return "<python>"
    try:
        return str(path.resolve().relative_to(ROOT))
    except ValueError:
        return str(path)


def _rays(image: raytrace.Image) -> dict:
    rays = image.stats["rays"]
    return {k: int(rays.get(k, 0)) for k in RAY_KINDS}


def _row(value, seconds: float, image: raytrace.Image, reference: np.ndarray) -> dict:
    return {"value": value, "seconds": seconds, "rays": _rays(image),
            **errors(image.rgb, reference)}


# -- the sweeps ----------------------------------------------------------------------------------
def sweep_spp(scene: Scene, values: Sequence[int], size: tuple[int, int], reference_spp: int,
              reference_seeds: tuple[int, int], fit_max: int | None = None, *,
              threads: int = 1, repeats: int = 1, budget: float = 0.0) -> dict:
    """Error of ``spp`` ∈ ``values`` (the scene's own seed) against a ``reference_spp`` render
    with ``reference_seeds[0]``; the two references' RMSE is the noise floor. The log-log slope
    is fitted over the values ≤ ``fit_max`` (all by default)."""
    w, h = size
    ref_seconds, ref = timed_render(scene, width=w, height=h, spp=reference_spp,
                                    seed=reference_seeds[0], threads=threads)
    _, ref2 = timed_render(scene, width=w, height=h, spp=reference_spp,
                           seed=reference_seeds[1], threads=threads)
    floor = errors(ref2.rgb, ref.rgb)
    rows = []
    for spp in values:
        seconds, image = timed_render(scene, width=w, height=h, spp=spp, threads=threads,
                                      repeats=repeats, budget=budget)
        row = _row(spp, seconds, image, ref.rgb)
        row["rmse_vs_truth"] = truth_estimate(row["rmse"], floor["rmse"])
        rows.append(row)
    fit = [r for r in rows if fit_max is None or r["value"] <= fit_max]
    slope, intercept = loglog_slope([r["value"] for r in fit], [r["rmse"] for r in fit])
    return {"scene": _name(scene), "size": list(size), "seed": scene.render.seed,
            "max_depth": scene.render.max_depth,
            "reference": {"spp": reference_spp, "seeds": list(reference_seeds),
                          "seconds": ref_seconds, "mean": float(np.mean(ref.rgb))},
            "noise_floor": floor, "rows": rows,
            "fit": {"over": [r["value"] for r in fit], "slope": slope, "intercept": intercept}}


def sweep_max_depth(scene: Scene, values: Sequence[int], size: tuple[int, int],
                    reference_depth: int | None = None, min_weight: float = 0.0,
                    converged: tuple[int, float] | None = None, *, threads: int = 1,
                    repeats: int = 1, budget: float = 0.0) -> dict:
    """Error of ``max_depth`` ∈ ``values`` at ``min_weight`` against a ``reference_depth``
    render at the same ``min_weight`` and, with ``converged = (depth, min_weight)``, against
    that (deeper, pruned) render as well (``rmse_converged``, ``max_error_converged``)."""
    w, h = size
    refs = {}
    if reference_depth is not None:
        refs["deep"] = timed_render(scene, width=w, height=h, max_depth=reference_depth,
                                    min_weight=min_weight, threads=threads)
    if converged is not None:
        refs["converged"] = reference_render(scene, width=w, height=h,
                                             max_depth=converged[0], min_weight=converged[1],
                                             threads=threads)
    main = refs["deep" if "deep" in refs else "converged"][1].rgb
    rows = []
    for depth in values:
        seconds, image = timed_render(scene, width=w, height=h, max_depth=depth,
                                      min_weight=min_weight, threads=threads,
                                      repeats=repeats, budget=budget)
        row = _row(depth, seconds, image, main)
        row["pruned"] = dict(image.stats["pruned"])
        row["total_internal_reflections"] = int(image.stats["total_internal_reflections"])
        if "converged" in refs:
            e = errors(image.rgb, refs["converged"][1].rgb)
            row["rmse_converged"], row["max_error_converged"] = e["rmse"], e["max_error"]
        rows.append(row)
    out = {"scene": _name(scene), "size": list(size), "min_weight": min_weight, "rows": rows,
           "reference": {"max_depth": reference_depth, "min_weight": min_weight,
                         "against": "deep" if "deep" in refs else "converged"}}
    if "deep" in refs:
        out["reference"].update(seconds=refs["deep"][0], rays=_rays(refs["deep"][1]),
                                mean=float(np.mean(refs["deep"][1].rgb)))
    if "converged" in refs:
        c_seconds, c = refs["converged"]
        out["converged"] = {"max_depth": converged[0], "min_weight": converged[1],
                            "seconds": c_seconds, "rays": _rays(c),
                            "pruned": dict(c.stats["pruned"])}
        if "deep" in refs:  # how far the deep reference itself is from convergence
            out["converged"]["reference_error"] = errors(refs["deep"][1].rgb, c.rgb)
    return out


def sweep_min_weight(scene: Scene, values: Sequence[float], size: tuple[int, int],
                     depth: int, converged: tuple[int, float] | None = None, *,
                     threads: int = 1, repeats: int = 1, budget: float = 0.0) -> dict:
    """Error, rays and time of ``min_weight`` ∈ ``values`` at ``max_depth = depth`` against
    ``min_weight`` 0 at the same depth (Hall & Greenberg 1983), and optionally against a
    converged render ``(depth, min_weight)``."""
    w, h = size
    ref_seconds, ref = timed_render(scene, width=w, height=h, max_depth=depth, min_weight=0.0,
                                    threads=threads, repeats=repeats, budget=budget)
    conv = None
    if converged is not None:
        _, conv = reference_render(scene, width=w, height=h, max_depth=converged[0],
                                   min_weight=converged[1], threads=threads)
    rows = []
    for mw in values:
        if mw == 0.0:
            seconds, image = ref_seconds, ref
        else:
            seconds, image = timed_render(scene, width=w, height=h, max_depth=depth,
                                          min_weight=mw, threads=threads, repeats=repeats,
                                          budget=budget)
        row = _row(mw, seconds, image, ref.rgb)
        row["pruned"] = dict(image.stats["pruned"])
        if conv is not None:
            e = errors(image.rgb, conv.rgb)
            row["rmse_converged"], row["max_error_converged"] = e["rmse"], e["max_error"]
        rows.append(row)
    out = {"scene": _name(scene), "size": list(size), "max_depth": depth, "rows": rows,
           "reference": {"min_weight": 0.0, "max_depth": depth, "mean": float(np.mean(ref.rgb))}}
    if converged is not None:
        out["converged"] = {"max_depth": converged[0], "min_weight": converged[1]}
    return out


def sweep_area_samples(scene: Scene, values: Sequence[int], size: tuple[int, int],
                       reference_samples: int, check_samples: int | None = None,
                       jitter_seeds: Sequence[int] = (1,), *, threads: int = 1,
                       repeats: int = 1, budget: float = 0.0) -> dict:
    """Penumbra error of ``samples`` ∈ ``values`` per area light, on the grid (``jitter``
    false) and jittered (RMSE and max averaged over ``jitter_seeds``; a seed moves the jittered
    points, and at 1 spp nothing else), against a ``reference_samples`` grid at 1 spp. The
    ``check_samples`` grid against the reference bounds the reference's own error."""
    w, h = size
    ref_seconds, ref = timed_render(with_area_samples(scene, reference_samples, False),
                                    width=w, height=h, spp=1, threads=threads)
    out = {"scene": _name(scene), "size": list(size), "spp": 1,
           "reference": {"samples": reference_samples, "jitter": False, "seconds": ref_seconds,
                         "rays": _rays(ref), "mean": float(np.mean(ref.rgb))}}
    if check_samples is not None:
        _, check = timed_render(with_area_samples(scene, check_samples, False), width=w,
                                height=h, spp=1, threads=threads)
        out["reference"]["check"] = {"samples": check_samples, **errors(check.rgb, ref.rgb)}
    for jitter in (False, True):
        rows = []
        for n in values:
            variant = with_area_samples(scene, n, jitter)
            per_seed = []
            for seed in (jitter_seeds if jitter else [scene.render.seed]):
                seconds, image = timed_render(variant, width=w, height=h, spp=1, seed=seed,
                                              threads=threads, repeats=repeats, budget=budget)
                per_seed.append(_row(n, seconds, image, ref.rgb))
            row = dict(per_seed[0])
            row["seconds"] = min(r["seconds"] for r in per_seed)
            for key in ("rmse", "max_error", "relative"):
                row[key] = float(np.mean([r[key] for r in per_seed]))
            if jitter:
                row["rmse_per_seed"] = [r["rmse"] for r in per_seed]
                row["seeds"] = list(jitter_seeds)
            rows.append(row)
        slope, intercept = loglog_slope([r["value"] for r in rows if r["value"] > 1] or [1, 2],
                                        [r["rmse"] for r in rows if r["value"] > 1] or [1, 1])
        out["jitter" if jitter else "grid"] = {
            "rows": rows, "fit": {"over": [r["value"] for r in rows if r["value"] > 1],
                                  "slope": slope, "intercept": intercept}}
    return out


def sweep_jitter_spp(scene: Scene, samples: int, values: Sequence[int], size: tuple[int, int],
                     reference: tuple[int, int], *, threads: int = 1, repeats: int = 1,
                     budget: float = 0.0) -> dict:
    """What ``jitter`` is for: ``samples`` per area light, on the grid and jittered, at
    ``spp`` ∈ ``values``, against a ``reference = (spp, samples)`` grid render (antialiased
    edges and a fine penumbra). The grid's penumbra steps are the same in every pixel sample,
    so more spp cannot remove them; jittered samples are drawn anew at every hit, so their
    noise averages away with spp."""
    w, h = size
    ref_seconds, ref = timed_render(with_area_samples(scene, reference[1], False), width=w,
                                    height=h, spp=reference[0], threads=threads)
    out = {"scene": _name(scene), "size": list(size), "samples": samples,
           "reference": {"spp": reference[0], "samples": reference[1], "jitter": False,
                         "seconds": ref_seconds, "mean": float(np.mean(ref.rgb))}}
    for jitter in (False, True):
        variant = with_area_samples(scene, samples, jitter)
        out["jitter" if jitter else "grid"] = {"rows": [
            _row(spp, *timed_render(variant, width=w, height=h, spp=spp, threads=threads,
                                    repeats=repeats, budget=budget), ref.rgb)
            for spp in values]}
    return out


#: ``--aa``: adaptive against uniform stratified anti-aliasing (issue 16's study).
AA = {"scenes": ("whitted", "mesh_model"), "size": (640, 480), "reference": (1024, 12345),
      "uniform": [1, 4, 16, 64],
      "adaptive": [(0.1, 2, 0), (0.05, 2, 0), (0.02, 3, 0), (0.1, 2, 1), (0.05, 2, 1),
                   (0.1, 3, 1), (0.05, 3, 1), (0.02, 3, 1), (0.01, 3, 1)],
      "repeats": 2}
AA_QUICK = {"scenes": ("whitted",), "size": (32, 24), "reference": (16, 12345),
            "uniform": [1, 4], "adaptive": [(0.05, 2, 0), (0.05, 2, 1)], "repeats": 1}


def aa_reference(scene: Scene, size: tuple[int, int], spp: int, seed: int, threads: int,
                 cache: Path) -> tuple[np.ndarray, float | None]:
    """The reference of the AA study: ``spp`` uniform samples with another ``seed``, read from
    ``cache`` (an EXR named after the scene, size, spp and seed) or rendered and written
    there; returns the image and the seconds it took (None when read)."""
    path = cache / f"{Path(scene.path).stem}_{size[0]}x{size[1]}_{spp}spp_seed{seed}.exr"
    if path.exists():
        return raytrace.read_exr(path)[0], None
    t0 = time.perf_counter()
    image = raytrace.render(scene, width=size[0], height=size[1], spp=spp, seed=seed,
                            threads=threads)
    seconds = time.perf_counter() - t0
    cache.mkdir(parents=True, exist_ok=True)
    image.save(path)
    return image.rgb, seconds


def sweep_aa(scene: Scene, config: dict, threads: int, cache: Path) -> dict:
    """Uniform stratified spp against adaptive (threshold, depth, min depth) on ``scene``:
    per setting the best wall and CPU seconds (``time.process_time``: every thread's, far less
    sensitive than wall time to other processes on a shared machine) of ``repeats`` rounds,
    each round rendering every setting once in turn, the camera samples traced per pixel,
    RMSE and mean HDR-FLIP (:mod:`raytrace.film.metrics`) against :func:`aa_reference`."""
    from raytrace.film.metrics import METRICS

    w, h = config["size"]
    ref, ref_seconds = aa_reference(scene, (w, h), *config["reference"], threads, cache)
    flip = METRICS["flip"].function
    runs = [(f"uniform {s} spp", "uniform", dict(spp=s)) for s in config["uniform"]]
    runs += [(f"adaptive t {t} d {d}" + (f" min {m}" if m else ""), "adaptive",
              dict(aa="adaptive", aa_threshold=t, aa_depth=d, aa_min_depth=m))
             for t, d, m in config["adaptive"]]
    rows = [{"label": label, "mode": mode, "settings": settings, "seconds": float("inf"),
             "cpu_seconds": float("inf")} for label, mode, settings in runs]
    for _ in range(config["repeats"]):  # rounds: every setting once, in turn
        for row in rows:
            c0, t0 = time.process_time(), time.perf_counter()
            image = raytrace.render(scene, width=w, height=h, threads=threads,
                                    **row["settings"])
            row["seconds"] = min(row["seconds"], time.perf_counter() - t0)
            row["cpu_seconds"] = min(row["cpu_seconds"], time.process_time() - c0)
            row.update(samples_per_pixel=image.stats["rays"]["camera"] / (w * h),
                       rays=_rays(image), rmse=rmse(image.rgb, ref),
                       flip=float(flip(image.rgb, ref)))
    return {"scene": _name(scene), "size": [w, h],
            "reference": {"spp": config["reference"][0], "seed": config["reference"][1],
                          "seconds": ref_seconds}, "rows": rows}


def run_aa(config: dict, threads: int, cache: Path, log: Callable[[str], None] = print) -> dict:
    """The AA study on each of ``config["scenes"]``; returns the JSON document."""
    scenes = {name: load(name) for name in config["scenes"]}
    started = time.perf_counter()
    result = {"machine": machine(threads), "load_average_start": list(os.getloadavg()),
              "warm_up_seconds": warm_up(list(scenes.values()), threads), "aa": {}}
    for name, scene in scenes.items():
        log(f"aa {name} ...")
        result["aa"][name] = sweep_aa(scene, config, threads, cache)
    result["total_seconds"] = time.perf_counter() - started
    result["load_average_end"] = list(os.getloadavg())
    return result


def report_aa(result: dict) -> str:
    """The AA study's tables as Markdown, one per scene."""
    out = []
    for a in result["aa"].values():
        out.append(f"### {Path(a['scene']).name} at {a['size'][0]}×{a['size'][1]}, reference "
                   f"{a['reference']['spp']} spp (seed {a['reference']['seed']})")
        out.append(table(["setting", "CPU seconds", "wall seconds", "samples/px", "rays",
                          "RMSE", "FLIP"],
                         [[r["label"], f"{r['cpu_seconds']:.2f}", f"{r['seconds']:.2f}",
                           f"{r['samples_per_pixel']:.2f}",
                           f"{r['rays']['total']:,}", _g(r["rmse"]), f"{r['flip']:.4f}"]
                          for r in a["rows"]]))
    return "\n\n".join(out)


def plot_aa(result: dict, folder: Path) -> list[Path]:
    """One PNG per scene, ``aa_<scene>.png``: RMSE and FLIP against seconds, log-log, uniform
    and adaptive (by min depth) as series, each point labelled. matplotlib imported here."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    folder.mkdir(parents=True, exist_ok=True)
    paths = []
    for name, a in result["aa"].items():
        fig, axes = plt.subplots(1, 2, figsize=(11, 5))
        groups = [("uniform stratified", [r for r in a["rows"] if r["mode"] == "uniform"]),
                  ("adaptive, min depth 0", [r for r in a["rows"] if r["mode"] == "adaptive"
                                             and not r["settings"]["aa_min_depth"]]),
                  ("adaptive, min depth 1", [r for r in a["rows"] if r["mode"] == "adaptive"
                                             and r["settings"]["aa_min_depth"]])]
        for ax, key, ylabel in zip(axes, ("rmse", "flip"), ("RMSE (linear RGB)", "mean FLIP"),
                                   strict=True):
            for (label, rows), fmt in zip(groups, ("o-", "s", "^"), strict=True):
                if not rows:
                    continue
                ax.plot([r["cpu_seconds"] for r in rows], [r[key] for r in rows], fmt,
                        label=label)
                for r in rows:
                    text = (f"{r['settings']['spp']}" if r["mode"] == "uniform" else
                            f"{r['settings']['aa_threshold']:g}/{r['settings']['aa_depth']}")
                    ax.annotate(text, (r["cpu_seconds"], r[key]), textcoords="offset points",
                                xytext=(4, 4), fontsize=7)
            ax.set_xscale("log")
            ax.set_yscale("log")
            ax.set_xlabel(f"render CPU seconds ({result['machine']['threads']} threads, all "
                          "threads' time)")
            ax.set_ylabel(ylabel)
            ax.grid(True, which="both", alpha=0.3)
            ax.legend(fontsize=8)
        fig.suptitle(f"{name} {a['size'][0]}×{a['size'][1]} against {a['reference']['spp']} "
                     "spp (labels: spp, or threshold/depth)", fontsize=10)
        fig.tight_layout()
        path = folder / f"aa_{name}.png"
        fig.savefig(path, dpi=110)
        plt.close(fig)
        paths.append(path)
    return paths


# -- the whole run -------------------------------------------------------------------------------
def run(config: dict, threads: int, log: Callable[[str], None] = print) -> dict:
    """Every sweep of ``config`` (:data:`FULL` or :data:`QUICK`); returns the JSON document."""
    scenes = {name: load(name) for name in SCENES}
    started = time.perf_counter()
    result = {"machine": machine(threads), "load_average_start": list(os.getloadavg()),
              "warm_up_seconds": warm_up(list(scenes.values()), threads),
              "repeats": config["repeats"], "budget_seconds": config["budget"]}
    timing = {"threads": threads, "repeats": config["repeats"], "budget": config["budget"]}

    c = config["spp"]
    log("spp ...")
    result["spp"] = sweep_spp(scenes[c["scene"]], c["values"], c["size"], c["reference_spp"],
                              c["reference_seeds"], c["fit_max"], **timing)

    result["max_depth"] = {}
    for key, c in config["max_depth"].items():
        log(f"max_depth {key} ...")
        result["max_depth"][key] = sweep_max_depth(
            scenes[c.get("scene", key)], c["values"], c["size"], c.get("reference_depth"),
            c.get("min_weight", 0.0), c.get("converged"), **timing)

    result["min_weight"] = {}
    c = config["min_weight"]
    for key in ("tir", "whitted"):
        log(f"min_weight {key} ...")
        result["min_weight"][key] = sweep_min_weight(
            scenes[key], c["values"], c[key]["size"], c[key]["depth"], c[key].get("converged"),
            **timing)

    c = config["area_samples"]
    log("area_samples ...")
    result["area_samples"] = sweep_area_samples(
        scenes[c["scene"]], c["values"], c["size"], c["reference_samples"],
        c["check_samples"], c["jitter_seeds"], **timing)

    c = config["jitter_spp"]
    log("jitter_spp ...")
    result["jitter_spp"] = sweep_jitter_spp(
        scenes[c["scene"]], c["samples"], c["values"], c["size"], c["reference"], **timing)

    result["total_seconds"] = time.perf_counter() - started
    result["load_average_end"] = list(os.getloadavg())
    return result


def machine(threads: int) -> dict:
    """What the numbers were measured on, and which source (the git commit, and the files of
    raytrace/ that differ from it, if any)."""
    return {"cpus": os.cpu_count(), "threads": threads, "platform": platform.platform(),
            "processor": platform.processor() or platform.machine(),
            "python": platform.python_version(), "numpy": np.__version__,
            "raytrace": raytrace.__version__, "date": time.strftime("%Y-%m-%d %H:%M:%S %Z"),
            "commit": _git("rev-parse", "HEAD"),
            "raytrace_modified": [line.split(maxsplit=1)[-1] for line in (
                _git("status", "--porcelain", "--", "raytrace") or "").splitlines()]}


def _git(*args: str) -> str | None:
    """The output of a read-only git command in the repository, or None without git."""
    try:
        done = subprocess.run(["git", *args], cwd=ROOT, capture_output=True, text=True,
                              timeout=10)
    except (OSError, subprocess.SubprocessError):
        return None
    return done.stdout.strip() if done.returncode == 0 else None


# -- tables --------------------------------------------------------------------------------------
def _g(x: float) -> str:
    return f"{x:.3g}" if x else "0"


def table(headers: Sequence[str], rows: Sequence[Sequence]) -> str:
    """A Markdown table (also readable as plain text)."""
    lines = ["| " + " | ".join(headers) + " |", "|" + "---|" * len(headers)]
    lines += ["| " + " | ".join(str(c) for c in r) + " |" for r in rows]
    return "\n".join(lines)


def report(result: dict) -> str:
    """Every table of ``result`` as Markdown."""
    out = []
    s = result["spp"]
    floor = s["noise_floor"]
    out.append(f"### spp — {Path(s['scene']).name} at {s['size'][0]}×{s['size'][1]}, "
               f"reference {s['reference']['spp']} spp (seed {s['reference']['seeds'][0]}), "
               f"noise floor (two references, seeds {s['reference']['seeds']}) RMSE "
               f"{_g(floor['rmse'])}, max {_g(floor['max_error'])}; log-log slope "
               f"{s['fit']['slope']:.2f} over spp {s['fit']['over']}")
    out.append(table(["spp", "seconds", "rays", "RMSE", "max error", "RMSE / mean",
                      "est. RMSE vs truth"],
                     [[r["value"], f"{r['seconds']:.3f}", f"{r['rays']['total']:,}",
                       _g(r["rmse"]), _g(r["max_error"]), f"{r['relative']:.2%}",
                       _g(r["rmse_vs_truth"])] for r in s["rows"]]))
    for m in result["max_depth"].values():
        ref = m["reference"]
        title = (f"### max_depth — {Path(m['scene']).name} at {m['size'][0]}×{m['size'][1]}, "
                 f"min_weight {m['min_weight']:g}")
        if ref["max_depth"] is not None:
            title += f", reference depth {ref['max_depth']} ({ref['seconds']:.2f} s)"
        conv = m.get("converged")
        if conv:
            title += (f"; converged = depth {conv['max_depth']}, min_weight "
                      f"{conv['min_weight']:g}")
            if "reference_error" in conv:
                title += (f" (the reference against it: RMSE "
                          f"{_g(conv['reference_error']['rmse'])}, max "
                          f"{_g(conv['reference_error']['max_error'])})")
        out.append(title)
        headers = ["depth", "seconds", "camera", "shadow", "reflection", "refraction", "total",
                   "RMSE", "max error", "RMSE / mean"]
        if conv:
            headers += ["RMSE vs converged", "max vs converged"]
        rows = []
        for r in m["rows"]:
            k = r["rays"]
            row = [r["value"], f"{r['seconds']:.3f}", f"{k['camera']:,}", f"{k['shadow']:,}",
                   f"{k['reflection']:,}", f"{k['refraction']:,}", f"{k['total']:,}",
                   _g(r["rmse"]), _g(r["max_error"]), f"{r['relative']:.2%}"]
            if conv:
                row += [_g(r["rmse_converged"]), _g(r["max_error_converged"])]
            rows.append(row)
        out.append(table(headers, rows))
    for m in result["min_weight"].values():
        conv = m.get("converged")
        out.append(f"### min_weight — {Path(m['scene']).name} at "
                   f"{m['size'][0]}×{m['size'][1]}, max_depth {m['max_depth']}, against "
                   f"min_weight 0" + (f" and converged (depth {conv['max_depth']}, min_weight "
                                      f"{conv['min_weight']:g})" if conv else ""))
        headers = ["min_weight", "seconds", "rays", "pruned by weight", "RMSE", "max error",
                   "RMSE / mean"] + (["RMSE vs converged"] if conv else [])
        out.append(table(headers, [
            [f"{r['value']:g}", f"{r['seconds']:.3f}", f"{r['rays']['total']:,}",
             f"{r['pruned']['weight']:,}", _g(r["rmse"]), _g(r["max_error"]),
             f"{r['relative']:.2%}"] + ([_g(r["rmse_converged"])] if conv else [])
            for r in m["rows"]]))
    a = result["area_samples"]
    ref = a["reference"]
    title = (f"### area-light samples — {Path(a['scene']).name} at {a['size'][0]}×"
             f"{a['size'][1]}, 1 spp, reference {ref['samples']}-sample grid "
             f"({ref['seconds']:.2f} s)")
    if "check" in ref:
        title += (f"; the {ref['check']['samples']}-sample grid against it: RMSE "
                  f"{_g(ref['check']['rmse'])}, max {_g(ref['check']['max_error'])}")
    out.append(title)
    rows = []
    for mode in ("grid", "jitter"):
        for r in a[mode]["rows"]:
            rows.append([r["value"], mode, f"{r['seconds']:.3f}", f"{r['rays']['shadow']:,}",
                         _g(r["rmse"]), _g(r["max_error"]), f"{r['relative']:.2%}"])
    out.append(table(["samples", "placement", "seconds", "shadow rays", "RMSE", "max error",
                      "RMSE / mean"], rows))
    out.append(f"log-log slope of RMSE over samples (> 1): grid "
               f"{a['grid']['fit']['slope']:.2f}, jitter {a['jitter']['fit']['slope']:.2f}"
               f" (jitter: mean over seeds {a['jitter']['rows'][0].get('seeds')})")
    j = result["jitter_spp"]
    out.append(f"### area light, grid or jitter, against spp — {Path(j['scene']).name} at "
               f"{j['size'][0]}×{j['size'][1]}, {j['samples']} samples, reference "
               f"{j['reference']['spp']} spp × {j['reference']['samples']}-sample grid "
               f"({j['reference']['seconds']:.2f} s)")
    out.append(table(["spp", "placement", "seconds", "shadow rays", "RMSE", "max error",
                      "RMSE / mean"],
                     [[r["value"], mode, f"{r['seconds']:.3f}", f"{r['rays']['shadow']:,}",
                       _g(r["rmse"]), _g(r["max_error"]), f"{r['relative']:.2%}"]
                      for mode in ("grid", "jitter") for r in j[mode]["rows"]]))
    return "\n\n".join(out)


# -- plots ---------------------------------------------------------------------------------------
def plot(result: dict, folder: Path) -> list[Path]:
    """One PNG per knob under ``folder``: RMSE and max error against seconds, log-log, each
    point labelled with its setting. Zero errors (a setting equal to its reference) cannot be
    drawn on a log axis and are left out. Imports matplotlib here only."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.ticker import NullFormatter

    folder.mkdir(parents=True, exist_ok=True)

    def series(ax, rows, key, label, fmt="o-", fmt_label=str, annotate=True, **kw):
        pts = [(r["seconds"], r[key], r["value"]) for r in rows if r[key] > 0]
        if not pts:
            return
        x, y, v = zip(*pts, strict=True)
        ax.plot(x, y, fmt, label=label, **kw)
        for xi, yi, vi in pts if annotate else ():
            ax.annotate(fmt_label(vi), (xi, yi), textcoords="offset points", xytext=(4, 4),
                        fontsize=7)

    def spread_labels(fig, ax):
        """Move each point's label, in drawing order, to the first free place (above right,
        below right, above left, below left of its point) where it overlaps no earlier label:
        two settings giving nearly the same render (TIR at min_weight 1e-4 and 1e-3) must
        both read. Positions are in display units, so this runs after the layout."""
        renderer = fig.canvas.get_renderer()
        placed = []
        for ann in (t for t in ax.texts if isinstance(t, matplotlib.text.Annotation)):
            for dx, dy, ha, va in ((4, 4, "left", "bottom"), (4, -4, "left", "top"),
                                   (-4, 4, "right", "bottom"), (-4, -4, "right", "top")):
                ann.xyann = (dx, dy)
                ann.set_horizontalalignment(ha)
                ann.set_verticalalignment(va)
                box = ann.get_window_extent(renderer)
                if not any(box.overlaps(b) for b in placed):
                    break
            placed.append(ann.get_window_extent(renderer))

    def figure(name, title, draw):
        fig, axes = plt.subplots(1, 2, figsize=(11, 5.4))
        for ax, key, ylabel in zip(axes, ("rmse", "max_error"),
                                   ("RMSE (linear RGB)", "max |error| (linear RGB)"),
                                   strict=True):
            draw(ax, key)
            ax.set_xscale("log")
            ax.set_yscale("log")
            ax.set_xlabel("render seconds (best of repeats, "
                          f"{result['machine']['threads']} threads)")
            ax.set_ylabel(ylabel)
            ax.grid(True, which="both", alpha=0.3)
            ax.xaxis.set_minor_formatter(NullFormatter())   # decades only: no overlapping
            ax.yaxis.set_minor_formatter(NullFormatter())   # 2×10⁻², 3×10⁻², ... labels
        handles, labels = axes[0].get_legend_handles_labels()
        fig.legend(handles, labels, loc="lower center", ncol=2, fontsize=8, frameon=False)
        fig.suptitle(title, fontsize=10)
        fig.tight_layout(rect=(0, 0.04 + 0.035 * ((len(labels) + 1) // 2), 1, 1))
        for ax in axes:
            spread_labels(fig, ax)
        path = folder / f"{name}.png"
        fig.savefig(path, dpi=110)
        plt.close(fig)
        return path

    paths = []
    s = result["spp"]

    def draw_spp(ax, key):
        series(ax, s["rows"], key, f"{Path(s['scene']).stem}, spp", fmt_label=lambda v: f"{v}")
        ax.axhline(s["noise_floor"][key], color="grey", ls="--",
                   label=f"noise floor ({s['reference']['spp']} spp vs {s['reference']['spp']}"
                         " spp, other seed)")
        if key == "rmse":
            x = np.array([r["seconds"] for r in s["rows"]])
            spp = np.array([r["value"] for r in s["rows"]], np.float64)
            ax.plot(x, 10 ** s["fit"]["intercept"] * spp ** s["fit"]["slope"], ":", color="C1",
                    label=f"fit: RMSE ∝ spp^{s['fit']['slope']:.2f}")
    paths.append(figure("spp", f"spp: {Path(s['scene']).name} "
                               f"{s['size'][0]}×{s['size'][1]}", draw_spp))

    def draw_depth(ax, key):
        for i, m in enumerate(result["max_depth"].values()):
            stem = Path(m["scene"]).stem
            if m["reference"]["max_depth"] is not None:
                series(ax, m["rows"], key, f"{stem} vs depth {m['reference']['max_depth']}"
                       f" (min_weight {m['min_weight']:g})", color=f"C{i}")
            ckey = key + "_converged" if key == "max_error" else "rmse_converged"
            if "converged" in m and m["rows"] and ckey in m["rows"][0]:
                rows = [dict(r, **{key: r[ckey]}) for r in m["rows"]]
                series(ax, rows, key, f"{stem} (min_weight {m['min_weight']:g}) vs converged",
                       fmt="s--", color=f"C{i}", alpha=0.6,
                       annotate=m["reference"]["max_depth"] is None)
    paths.append(figure("max_depth", "max_depth (label: depth)", draw_depth))

    def draw_weight(ax, key):
        for i, m in enumerate(result["min_weight"].values()):
            stem = Path(m["scene"]).stem
            series(ax, m["rows"], key, f"{stem}, depth {m['max_depth']}, vs min_weight 0",
                   fmt_label=lambda v: f"{v:g}", color=f"C{i}")
            ax.axvline(m["rows"][0]["seconds"], color=f"C{i}", ls=":",
                       label=f"{stem}: min_weight 0 (the reference)")
            if "converged" in m:
                rows = [dict(r, **{key: r["rmse_converged" if key == "rmse" else
                                       "max_error_converged"]}) for r in m["rows"]]
                series(ax, rows, key, f"{stem}, depth {m['max_depth']}, vs converged",
                       fmt="s--", fmt_label=lambda v: f"{v:g}", color=f"C{i}", alpha=0.6)
    paths.append(figure("min_weight", "min_weight (label: threshold)", draw_weight))

    a = result["area_samples"]

    def draw_area(ax, key):
        series(ax, a["grid"]["rows"], key, "grid (jitter = false)")
        series(ax, a["jitter"]["rows"], key, "jitter = true (mean over seeds)", fmt="s-")
        if "check" in a["reference"]:
            ax.axhline(a["reference"]["check"][key], color="grey", ls="--",
                       label=f"{a['reference']['check']['samples']}-sample grid vs reference")
    paths.append(figure("area_samples", f"area-light samples: {Path(a['scene']).name} "
                                        f"{a['size'][0]}×{a['size'][1]}, 1 spp, vs "
                                        f"{a['reference']['samples']}-sample grid "
                                        "(label: samples)", draw_area))

    j = result["jitter_spp"]

    def draw_jitter(ax, key):
        series(ax, j["grid"]["rows"], key, f"{j['samples']} samples, grid")
        series(ax, j["jitter"]["rows"], key, f"{j['samples']} samples, jitter", fmt="s-")
    paths.append(figure("jitter_spp", f"area light: grid vs jitter as spp grows "
                                      f"({Path(j['scene']).name} {j['size'][0]}×"
                                      f"{j['size'][1]}, {j['samples']} samples, vs "
                                      f"{j['reference']['spp']} spp × "
                                      f"{j['reference']['samples']}-sample grid; label: spp)",
                        draw_jitter))
    return paths


def main(argv: Sequence[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--quick", action="store_true", help="tiny sizes, one render per timing")
    p.add_argument("--threads", type=int, default=os.cpu_count() or 1,
                   help="render threads (default: all cores)")
    p.add_argument("--json", type=Path, default=HERE / "knobs.json",
                   help="where to write the results (default benchmarks/knobs.json)")
    p.add_argument("--plots", type=Path, default=None,
                   help="folder for one PNG per knob (needs matplotlib)")
    p.add_argument("--from-json", type=Path, default=None, metavar="JSON",
                   help="measure nothing: print the tables and draw the plots of an earlier run")
    p.add_argument("--aa", action="store_true",
                   help="only the adaptive-vs-uniform study (JSON default benchmarks/aa.json)")
    p.add_argument("--cache", type=Path, default=Path(tempfile.gettempdir()) / "raytrace-knobs",
                   help="where the AA study keeps its reference EXRs")
    args = p.parse_args(argv)
    if args.aa:
        return main_aa(args)
    config = QUICK if args.quick else FULL

    def log(msg: str) -> None:
        print(msg, file=sys.stderr, flush=True)

    if args.from_json is not None:
        result = json.loads(args.from_json.read_text())
    else:
        log(f"load average {os.getloadavg()}, {args.threads} threads")
        result = run(config, args.threads, log)
        result["command"] = " ".join(["python3", "benchmarks/knobs.py",
                                      *(argv if argv is not None else sys.argv[1:])])
        result["quick"] = args.quick
    print(report(result))
    print(f"\ntotal {result['total_seconds']:.1f} s; load average start "
          f"{result['load_average_start']}, end {result['load_average_end']}")
    if args.from_json is None:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps(result, indent=1) + "\n")
    if args.plots is not None:
        for path in plot(result, args.plots):
            log(f"wrote {path}")
    return 0


def main_aa(args: argparse.Namespace) -> int:
    """``--aa``: the adaptive-vs-uniform study alone, its own JSON and plots."""
    path = args.json if args.json != HERE / "knobs.json" else HERE / "aa.json"
    if args.from_json is not None:
        result = json.loads(args.from_json.read_text())
    else:
        print(f"load average {os.getloadavg()}, {args.threads} threads", file=sys.stderr)
        result = run_aa(AA_QUICK if args.quick else AA, args.threads, args.cache,
                        lambda m: print(m, file=sys.stderr, flush=True))
        result["command"] = "python3 benchmarks/knobs.py --aa" + (" --quick" if args.quick
                                                                    else "")
    print(report_aa(result))
    print(f"\ntotal {result['total_seconds']:.1f} s; load average start "
          f"{result['load_average_start']}, end {result['load_average_end']}")
    if args.from_json is None:
        path.write_text(json.dumps(result, indent=1) + "\n")
    if args.plots is not None:
        for p in plot_aa(result, args.plots):
            print(f"wrote {p}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
