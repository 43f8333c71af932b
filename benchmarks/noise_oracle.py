"""What the renderer itself would take with each pixel's variance known, and with its own
estimates perfectly aimed: issue 30's two time targets traced and timed, not counted in rays.

    python3 benchmarks/noise_oracle.py                  # whitted, mesh_model, area_light
    python3 benchmarks/noise_oracle.py --seeds 10 --variance-seeds 12

``noise_ceiling.py`` counts the samples and rays an allocation by known variances would
take; this traces such allocations through the renderer's own noise-driven rounds and times
them. For each scene at 160×120 on 2 threads: each pixel's variance at 16 samples (``v16``,
its own Owen-scrambled Sobol sequence, from ``--variance-seeds`` renders) and β fitted from
the image's summed variances at 4 and 16 samples, as ``noise_ceiling.py`` reads them; each
pixel's rays a sample ``c``. A render then takes its first round of 4 samples a pixel, as
every render by target or time does (it must look before it allocates), and one more round
whose counts are chosen by the known variances (the allocator,
:func:`raytrace.noise.neyman_counts`, replaced for the render), then stops. The counts are
the renderer's own (4 doubled up to four times, at most 64), the doublings taken greedily in
order of the variance each takes off, ``v16·(16/m)^β − v16·(16/2m)^β``, over its cost
(``m`` samples, or ``m·c`` rays):

* ``least samples``: the fewest samples whose summed variance is uniform 16 spp's. The
  variances are read from a few renders and the model is a model, so the measured RMSE of
  the doublings predicted to reach it is off by a few per cent: the predicted goal is scaled
  by the measured RMSE's square over uniform's, twice (``--calibrate`` seeds each), so that
  the allocation timed reaches uniform's RMSE as measured;
* ``least rays``: the same, ranked by rays;
* ``uniform's rays``: ranked by rays, until they trace uniform 16 spp's rays.

Two more rows take the renderer's own allocation (:func:`raytrace.noise.neyman_counts` on
the variances its first round estimates, as its renders by target rank pixels) in the same
single round, without the bound on a round's samples (``ROUND_SHARE``) and with no third
round: what its estimates would give were its rounds aimed perfectly:

* ``own, its error``: aimed below each seed's uniform error by a margin (the renderer's
  ``TARGET_MARGIN``, 1.1) scaled by the measured RMSE's ratio to uniform's, twice, so that
  the one round reaches uniform's RMSE as measured (the margin found is printed);
* ``own, its time``: of as many samples as take uniform's time (the time's ratio to
  uniform's measured at 16 samples a pixel and at 16 over that ratio, medians of three
  times ``--calibrate`` seeds each, and the line through the two solved for a ratio of 1).

Each render is timed against uniform 16 spp of the same seed, one after the other, for
``--seeds`` seeds (the machine's drift cancels), and its error measured against the 1024-spp
reference of ``benchmarks/noise.py`` (``--cache``). Printed: the medians of the time over
uniform's and of the RMSE over uniform's, and the samples a pixel. The time of ``least
samples`` and ``least rays`` is the ceiling of the "time to uniform's RMSE" target (≤ 0.5),
and the RMSE of ``uniform's rays`` at the time it took that of the "RMSE at uniform's time"
target (≤ 0.7), on this renderer: two rounds, no estimate to make and no allocation to
compute. The allocation is a bound on knowing each pixel's variance, not a forecast. The
``own`` rows are what the renderer's estimates from its first round give, spent in one
round aimed perfectly: the time of ``own, its error`` for the first target, the RMSE of
``own, its time`` for the second (a render's later rounds estimate again from more samples,
and pay each round's fixed cost).
"""

from __future__ import annotations

import argparse
import time
from functools import partial
from pathlib import Path

import numpy as np
from bench_scenes import scene_path
from noise import reference, rms_error
from noise_ceiling import SIZE, SPP, rays_per_sample, variances

import raytrace
from raytrace import malloc, noise

#: The renderer's first round by target or time (samples a pixel), and its most doublings.
FIRST, DOUBLINGS = 4, noise.MAX_DOUBLINGS
#: The rows of the renderer's own allocation in one round: aimed so that it reaches uniform's
#: RMSE, and of the samples that take uniform's time.
AIMED, OWN_TIME = "own, its error", "own, its time"


def doublings(v16: np.ndarray, cost: np.ndarray, beta: float, goal: float | None = None,
              budget: float | None = None) -> np.ndarray:
    """Each pixel's samples (4·2^k, k ≤ :data:`DOUBLINGS`): the doublings of most variance
    off a unit of ``cost`` (a sample's cost of each pixel) taken greedily, until the summed
    variance ``Σ v16·(16/n)^β`` is at most ``goal``, or until ``Σ cost·n`` would pass
    ``budget``. A pixel's doublings fall in priority (``∝ m^−(1+β)``), so its doublings are
    taken in order."""
    m = FIRST * 2.0 ** np.arange(DOUBLINGS)  # each doubling's start, m → 2m
    scale = SPP ** beta
    off = v16[:, None] * scale * (m ** -beta - (2 * m) ** -beta)  # (pixels, doublings)
    spend = cost[:, None] * m
    order = np.argsort(-(off / spend).ravel(), kind="stable")
    pixel = order // DOUBLINGS
    if goal is not None:
        left = (v16 * scale * FIRST ** -beta).sum() - np.cumsum(off.ravel()[order])
        take = int(np.searchsorted(-left, -goal)) + 1
    else:
        spent = (cost * FIRST).sum() + np.cumsum(spend.ravel()[order])
        take = int(np.searchsorted(spent, budget, "right"))
    return FIRST * 2 ** np.bincount(pixel[:take], minlength=len(v16))


def render_counts(scene: raytrace.Scene, counts: np.ndarray, seed: int,
                  **common) -> raytrace.Image:
    """A noise-driven render of a first round of :data:`FIRST` samples a pixel and one round
    to ``counts`` (each pixel's samples), its allocator replaced by ``counts``."""
    allocate = noise.neyman_counts

    def known(n, *args, **kw):
        return np.maximum(n, counts // 2) if n.max() <= FIRST // 2 else n

    noise.neyman_counts = known
    try:  # a target no round reaches: the rounds end when the counts stop growing
        return raytrace.render(scene, target_error=1e-12, min_spp=FIRST, seed=seed, **common)
    finally:
        noise.neyman_counts = allocate


def render_own(scene: raytrace.Scene, seed: int, target: float, margin: float = 1.0,
               share: float = 2.0 ** DOUBLINGS, **common) -> raytrace.Image:
    """A noise-driven render by ``target`` (relative RMSE) of a first round of :data:`FIRST`
    samples a pixel and at most one more (none where the first meets the target), allocated
    by the renderer's own estimates (:func:`raytrace.noise.neyman_counts` on its first
    round's samples), aimed ``margin`` below the target (where the renderer aims
    :data:`raytrace.noise.TARGET_MARGIN` below it and takes more rounds while its estimate is
    above it) and adding at most ``share`` of the first round's samples (the renderer's
    :data:`raytrace.noise.ROUND_SHARE`; by default no bound but a pixel's :data:`DOUBLINGS`,
    as the other allocations here)."""
    saved = noise.neyman_counts, noise.TARGET_MARGIN, noise.ROUND_SHARE
    allocate = saved[0]

    def once(n, *args, **kw):
        return allocate(n, *args, **kw) if n.max() <= FIRST // 2 else n

    noise.neyman_counts, noise.TARGET_MARGIN, noise.ROUND_SHARE = once, margin, share
    try:  # the rounds end when the counts stop growing
        return raytrace.render(scene, target_error=target, min_spp=FIRST, seed=seed,
                               aovs="samples", **common)
    finally:
        noise.neyman_counts, noise.TARGET_MARGIN, noise.ROUND_SHARE = saved


def measure(name: str, a: argparse.Namespace, common: dict) -> list[tuple]:
    """The rows of one scene (module docstring): per allocation, its label, counts (the own
    rows': each pixel's mean over the seeds), and the medians over the seeds of its time and
    RMSE over uniform 16 spp's, and its rays over uniform's."""
    scene = raytrace.load_scene(scene_path(name))
    ref = reference(scene, name, 1024, a.cache, **common)
    goal = variances(scene, SPP, a.variance_seeds, "uniform").sum()
    v16, v4 = (variances(scene, n, a.variance_seeds, "sequence") for n in (SPP, FIRST))
    beta = float(np.log(v4.sum() / v16.sum()) / np.log(SPP / FIRST))
    cost = rays_per_sample(scene)
    raytrace.render(scene, spp=SPP, **common)  # warm-up

    rmse = partial(rms_error, ref=ref)

    uniform_rmse = [rmse(raytrace.render(scene, spp=SPP, seed=1000 + seed, **common))
                    for seed in range(a.calibrate)]

    def calibrated(weight: np.ndarray) -> np.ndarray:
        aim = goal
        for _ in range(2):  # seeds apart from the timed ones
            counts = doublings(v16, weight, beta, goal=aim)
            reached = [rmse(render_counts(scene, counts, 1000 + seed, **common)) / e
                       for seed, e in enumerate(uniform_rmse)]
            aim /= float(np.median(reached)) ** 2
        return doublings(v16, weight, beta, goal=aim)

    plans = {"least samples": calibrated(np.ones_like(cost)),
             "least rays": calibrated(cost),
             "uniform's rays": doublings(v16, cost, beta, budget=(cost * SPP).sum())}
    level = float(ref.mean())
    margin = noise.TARGET_MARGIN
    for _ in range(2):  # the margin whose one round reaches uniform's RMSE as measured
        margin *= float(np.median([rmse(render_own(scene, 1000 + seed, e / level, margin,
                                                   **common)) / e
                                   for seed, e in enumerate(uniform_rmse)]))

    def time_ratio(spp: float, seed: int) -> float:
        """The time of a render of one round to ``spp`` samples a pixel over uniform's."""
        t0 = time.perf_counter()
        render_own(scene, seed, 1e-12, share=spp / FIRST - 1, **common)
        t1 = time.perf_counter()
        raytrace.render(scene, spp=SPP, seed=seed, **common)
        return (t1 - t0) / (time.perf_counter() - t1)

    # the samples whose one round takes uniform's time: the time's ratio measured at 16 and
    # at 16 over it, and the line through the two points (a round has a fixed cost, so the
    # ratio is not proportional to the samples) solved for a ratio of 1; times are noisier
    # than errors, so each ratio is the median of three times the seeds
    seeds = range(1000, 1000 + 3 * a.calibrate)
    ratio = float(np.median([time_ratio(SPP, seed) for seed in seeds]))
    spp = SPP / ratio
    again = float(np.median([time_ratio(spp, seed) for seed in seeds]))
    if again != ratio:
        spp = min(max(SPP + (1.0 - ratio) * (spp - SPP) / (again - ratio), FIRST + 1.0),
                  FIRST * 2.0 ** DOUBLINGS)
    own = {AIMED: lambda seed, e: render_own(scene, seed, e / level, margin, **common),
           OWN_TIME: lambda seed, e: render_own(scene, seed, 1e-12, share=spp / FIRST - 1,
                                                **common)}
    ratios = {label: [] for label in (*plans, *own)}
    own_counts = {label: [] for label in own}
    for seed in range(a.seeds):
        t0 = time.perf_counter()
        uniform = raytrace.render(scene, spp=SPP, seed=seed, **common)
        t_u = time.perf_counter() - t0
        for label, counts in plans.items():
            t0 = time.perf_counter()
            image = render_counts(scene, counts, seed, **common)
            seconds = time.perf_counter() - t0
            assert image.stats["aa"]["samples_per_pixel"] == counts.mean()
            ratios[label].append((seconds / t_u, rmse(image) / rmse(uniform)))
        for label, render in own.items():
            t0 = time.perf_counter()
            image = render(seed, rmse(uniform))
            seconds = time.perf_counter() - t0
            own_counts[label].append(image.aov("samples").reshape(-1))
            ratios[label].append((seconds / t_u, rmse(image) / rmse(uniform)))
    plans.update({label: np.mean(counts, axis=0) for label, counts in own_counts.items()})
    print(f"{name}: own, its error aimed {margin:.2f}× below the target "
          f"({noise.TARGET_MARGIN}× in the renderer); own, its time {spp:.2f} samples a pixel")
    return [(label, counts, *np.median(ratios[label], axis=0),
             (cost * counts).sum() / (cost * SPP).sum()) for label, counts in plans.items()]


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("--scenes", nargs="*", default=["whitted", "mesh_model", "area_light"])
    p.add_argument("--seeds", type=int, default=10)
    p.add_argument("--variance-seeds", type=int, default=24)
    p.add_argument("--calibrate", type=int, default=3)
    p.add_argument("--cache", type=Path, default=Path("/tmp/raytrace-noise-references"))
    a = p.parse_args()
    malloc.tune()  # as the command line does
    common = dict(width=SIZE[0], height=SIZE[1], threads=2)
    print(f"{SIZE[0]}x{SIZE[1]}, 2 threads: a first round of {FIRST} and one round to counts "
          f"by known variances ({a.variance_seeds} renders), or by the renderer's own "
          f"estimates (own); medians over {a.seeds} seeds, each against uniform 16 spp of its "
          "seed (the own rows' samples and rays: means)")
    print(f"{'scene':<12}{'allocation':<16}{'samples/px':>11}{'time':>7}{'RMSE':>7}"
          f"{'rays':>7}")
    for name in a.scenes:
        for label, counts, t, e, rays in measure(name, a, common):
            print(f"{name:<12}{label:<16}{counts.mean():>11.2f}{t:>7.2f}{e:>7.2f}{rays:>7.2f}")


if __name__ == "__main__":
    main()
