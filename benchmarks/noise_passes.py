"""How many passes a thread a noise-driven round should go in: what each pass costs a round,
and what that does to issue 30's two time targets.

    python3 benchmarks/noise_passes.py                       # mesh_model, whitted, area_light
    python3 benchmarks/noise_passes.py --scenes mesh_model --per-thread 1 2 3 --seeds 12

A round's samples are cut into passes (:func:`raytrace.integrator.round_pass_size`: the fewest
passes a thread, each at most ``pass_samples``); here it is replaced by one that cuts
``k`` passes a thread, for each ``k`` of ``--per-thread`` in turn (``k`` = 1 is the
renderer's own for rounds up to 2 × 65 536 samples on 2 threads). For each scene at 160×120
on 2 threads, seed by seed, each timed once after a warm-up, so that the machine's drift
cancels in the medians:

* **rounds**: the same samples, 16 a pixel, traced in three rounds of 4, 4 and 8 (the
  allocation replaced by doubling every pixel) in ``k`` passes a thread, against one round
  of 16 a pixel and uniform 16 spp: what the rounds' passes cost, free of the allocation;
* **targets** (``--seeds`` seeds): uniform 16 spp; then for each ``k`` a render by uniform's
  relative RMSE (against the 1024-spp reference of ``benchmarks/noise.py``, kept in
  ``--cache``), its wall seconds over uniform's; then for each ``k`` a render by a time
  limit of uniform's median wall seconds, its RMSE over uniform's of the same seed and its
  samples a pixel (medians over the seeds; ``interleaved`` measures the same two
  ratios for the renderer as it is, in ``benchmarks/noise.py --seeds``).
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable
from functools import partial
from pathlib import Path

import numpy as np
from bench_scenes import scene_path
from noise import reference, rms_error

import raytrace
from raytrace import integrator, malloc, noise

COMMON = dict(width=160, height=120, threads=2)
#: The renderer's own cut, which :func:`per_thread` replaces.
ROUND_PASS_SIZE = integrator.round_pass_size


def per_thread(k: int) -> Callable[[int, int, int], int]:
    """A :func:`raytrace.integrator.round_pass_size` that cuts ``k`` passes a thread."""
    return lambda samples, threads, most: ROUND_PASS_SIZE(samples, k * threads, most)


def in_rounds(scene: raytrace.Scene, seed: int) -> raytrace.Image:
    """16 samples a pixel in three rounds, 4, 4 and 8, every pixel doubled each round."""
    allocate = noise.neyman_counts
    noise.neyman_counts = lambda n, *args, **kw: np.minimum(2 * n, 8)  # (n: half the samples)
    try:
        return raytrace.render(scene, target_error=1e-12, min_spp=4, max_spp=16, seed=seed,
                               **COMMON)
    finally:
        noise.neyman_counts = allocate


def timed(render: Callable[..., raytrace.Image], *args, **kw) -> tuple[raytrace.Image, float]:
    """``render(*args, **kw)`` and its wall seconds."""
    t0 = time.perf_counter()
    image = render(*args, **kw)
    return image, time.perf_counter() - t0


def rounds(scene: raytrace.Scene, ks: list[int], seeds: int) -> dict[str, float]:
    """Median wall ms of each way to trace 16 samples a pixel (module docstring)."""
    ways = {"uniform 16 spp": (None, lambda s: raytrace.render(scene, spp=16, seed=s, **COMMON)),
            "one round of 16": (None, lambda s: raytrace.render(
                scene, aa="noise", min_spp=16, max_spp=16, seed=s, **COMMON))}
    ways |= {f"rounds of 4, 4, 8 in {k} pass{'es' * (k > 1)} a thread":
             (k, lambda s: in_rounds(scene, s)) for k in ks}
    seconds: dict[str, list[float]] = {name: [] for name in ways}
    try:
        for turn in range(seeds + 1):  # the first turn a warm-up, not counted
            for name, (k, way) in ways.items():
                integrator.round_pass_size = ROUND_PASS_SIZE if k is None else per_thread(k)
                _, s = timed(way, max(0, turn - 1))
                if turn:
                    seconds[name].append(s)
    finally:
        integrator.round_pass_size = ROUND_PASS_SIZE
    return {name: 1e3 * float(np.median(s)) for name, s in seconds.items()}


def targets(scene: raytrace.Scene, name: str, ks: list[int], seeds: int,
            cache: Path) -> dict[int, tuple[float, float, float]]:
    """Per ``k``: the medians of the time to uniform's error over uniform's, of the RMSE at
    uniform's time over uniform's, and of the samples a pixel at uniform's time."""
    ref = reference(scene, name, 1024, cache, **COMMON)
    level = float(ref.mean())

    rmse = partial(rms_error, ref=ref)

    uniform, by_error = [], {k: [] for k in ks}
    by_time = {k: [] for k in ks}
    raytrace.render(scene, time_limit=0.05, **COMMON)  # warm-up
    try:
        for seed in range(seeds):
            image, t = timed(raytrace.render, scene, spp=16, seed=seed, **COMMON)
            uniform.append((t, rmse(image)))
            for k in ks:
                integrator.round_pass_size = per_thread(k)
                _, s = timed(raytrace.render, scene, target_error=uniform[-1][1] / level,
                             seed=seed, **COMMON)
                by_error[k].append(s / t)
        limit = float(np.median([t for t, _ in uniform]))
        for seed, (_, e) in enumerate(uniform):
            for k in ks:
                integrator.round_pass_size = per_thread(k)
                image = raytrace.render(scene, time_limit=limit, seed=seed, **COMMON)
                by_time[k].append((rmse(image) / e, image.stats["aa"]["samples_per_pixel"]))
    finally:
        integrator.round_pass_size = ROUND_PASS_SIZE
    return {k: (float(np.median(by_error[k])), float(np.median([r for r, _ in by_time[k]])),
                float(np.median([n for _, n in by_time[k]]))) for k in ks}


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("--scenes", nargs="*", default=["mesh_model", "whitted", "area_light"])
    p.add_argument("--per-thread", type=int, nargs="*", default=[1, 2])
    p.add_argument("--seeds", type=int, default=10)
    p.add_argument("--cache", type=Path, default=Path("/tmp/raytrace-noise-references"))
    a = p.parse_args()
    malloc.tune()  # as the command line does
    for name in a.scenes:
        scene = raytrace.load_scene(scene_path(name))
        print(f"{name} 160x120, 2 threads, medians of {a.seeds} seeds")
        ms = rounds(scene, a.per_thread, a.seeds)
        base = ms["one round of 16"]
        for way, t in ms.items():
            print(f"  {way:<40}{t:>8.1f} ms{t / base:>7.2f}x one round")
        print(f"  {'passes a thread':<18}{'time to uniform error':>24}{'RMSE at uniform time':>22}"
              f"{'samples/px':>12}")
        for k, (time_ratio, rmse_ratio, spp) in targets(scene, name, a.per_thread, a.seeds,
                                                        a.cache).items():
            print(f"  {k:<18}{time_ratio:>23.3f}x{rmse_ratio:>21.3f}x{spp:>12.1f}")


if __name__ == "__main__":
    main()
