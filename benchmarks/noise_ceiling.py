"""What any per-pixel allocation could save against uniform 16 spp: the ceiling of issue 30's
"time to uniform's RMSE" target, with each pixel's variance known exactly.

    python3 benchmarks/noise_ceiling.py                  # whitted, mesh_model, area_light
    python3 benchmarks/noise_ceiling.py --seeds 24       # variances from more renders

For each scene at 160×120 (2 threads): each pixel's variance at 16 and at 4 samples is read
from ``--seeds`` renders of different seeds each, by the sampler the noise-driven renders
use (``--sampler sequence``: each pixel's own Owen-scrambled Sobol sequence, ``aa =
"noise"`` with ``min_spp = max_spp``; or ``uniform``, the jittered grid), and its cost ``c``
as the rays it traces a sample (camera rays and their children, counted in one render by an
observer of the integrator; shadow rays not counted). A pixel's variance is modelled as
falling by ``n^−β`` from its 16-sample value: β = 1 for independent samples, and β fitted to
the image's summed variances at 4 and 16 samples for these stratified ones. The goal is
always uniform 16 spp's summed variance (its own ``--seeds`` renders). The fewest samples
that reach it are then ``n ∝ v16^(1/(1+β))`` (Neyman's ``n ∝ σ`` at β = 1: J. Neyman 1934,
§5), the fewest rays ``n ∝ (v16/c)^(1/(1+β))`` (Cochran, "Sampling Techniques", 3rd ed.,
§5.5). The table gives their mean samples a pixel and the rays they cost against uniform's,
every pixel taking at least 1 sample, or at least ``--floor`` (the first round a render
needs to estimate anything: 4 by target or time). The last column is the ceiling of the
"RMSE at uniform's time" target, time taken as rays: the RMSE of the least-variance
allocation of uniform 16 spp's rays (``n ∝ (v16/c)^(1/(1+β))`` scaled to ``Σ c·n = Σ c·16``)
over uniform's. It is a bound on what knowing each pixel's variance buys, not a forecast.
"""

from __future__ import annotations

import argparse

import numpy as np
from bench_scenes import scene_path

import raytrace
from raytrace.integrator import WhittedIntegrator
from raytrace.rendering import render_options

SIZE = (160, 120)
SPP = 16


class RayCounter:
    """An integrator observer (the hooks of ``raytrace.raytree.Recorder``, which ``raytrace
    explain`` records by) that counts the rays each pixel traces: camera rays and their
    children. A ray's sample is its pass's first sample (the worker's, as the integrator
    keeps it) plus its row's ``sample``."""

    def __init__(self, integ: WhittedIntegrator, pixels: int):
        self.integ, self.rays = integ, np.zeros(pixels)

    def traced(self, rays, found, missed, background) -> None:
        sample = self.integ._worker.first_sample + rays.sample
        np.add.at(self.rays, sample // self.integ.opt.spp, 1.0)

    def hits(self, rays, hits, surf) -> None:
        pass

    def light(self, emitter, term, rows) -> None:
        pass

    def shadow(self, factor) -> None:
        pass

    def shaded(self, contribution, status, weights, tir, past_max_depth) -> None:
        pass

    def spawned(self, children, parent) -> None:
        pass


def rays_per_sample(scene: raytrace.Scene) -> np.ndarray:
    """Each pixel's rays a sample (row-major, (w·h,)) in one uniform 16-spp render."""
    integ = WhittedIntegrator(scene, render_options(scene, width=SIZE[0], height=SIZE[1],
                                                    spp=SPP, threads=1))
    integ.observer = counter = RayCounter(integ, SIZE[0] * SIZE[1])
    integ.render()
    return counter.rays / SPP


def variances(scene: raytrace.Scene, spp: int, seeds: int, sampler: str) -> np.ndarray:
    """Each pixel's variance (w·h,) across ``seeds`` renders of ``spp`` samples by
    ``sampler`` (the mean over its channels)."""
    kw = dict(spp=spp) if sampler == "uniform" else dict(aa="noise", min_spp=spp,
                                                           max_spp=spp)
    images = np.array([raytrace.render(scene, width=SIZE[0], height=SIZE[1], threads=2,
                                       seed=seed, **kw).rgb.astype(np.float64)
                       for seed in range(100, 100 + seeds)])
    return images.var(0, ddof=1).reshape(-1, 3).mean(-1)


def allocation(v16: np.ndarray, weight: np.ndarray, beta: float, floor: float,
               goal: float) -> np.ndarray:
    """``n = max(floor, k·weight)`` with k such that ``Σ v16·(16/n)^β``, the summed variance
    of the pixels at n samples if each falls as ``n^−β`` from its 16-sample variance
    ``v16``, is ``goal`` (uniform 16 spp's; bisection in log k)."""
    lo, hi = 1e-9, 1e9
    for _ in range(200):
        k = np.sqrt(lo * hi)
        n = np.maximum(floor, k * weight)
        lo, hi = (k, hi) if (v16 * (SPP / n) ** beta).sum() > goal else (lo, k)
    return np.maximum(floor, hi * weight)


def at_rays(v16: np.ndarray, cost: np.ndarray, beta: float, floor: float,
            goal: float) -> float:
    """The RMSE over uniform 16 spp's (its summed variance ``goal``) of the allocation of
    least summed variance that traces uniform's rays, ``n = max(floor, k·(v16/c)^(1/(1+β)))``
    with k such that ``Σ c·n`` is uniform's ``Σ c·16`` (bisection in log k; Cochran §5.5's
    cost-optimal allocation)."""
    weight, budget = (v16 / cost) ** (1 / (1 + beta)), (cost * SPP).sum()
    lo, hi = 1e-9, 1e9
    for _ in range(200):
        k = np.sqrt(lo * hi)
        lo, hi = (k, hi) if (cost * np.maximum(floor, k * weight)).sum() < budget else (lo, k)
    n = np.maximum(floor, lo * weight)
    return float(np.sqrt((v16 * (SPP / n) ** beta).sum() / goal))


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("--scenes", nargs="*", default=["whitted", "mesh_model", "area_light"])
    p.add_argument("--seeds", type=int, default=12)
    p.add_argument("--floor", type=float, default=4.0)
    p.add_argument("--sampler", choices=["sequence", "uniform"], default="sequence")
    a = p.parse_args()
    print(f"{SIZE[0]}x{SIZE[1]}, variances from {a.seeds} {a.sampler} renders a sample count; "
          f"samples and rays of the least-sample allocation against uniform {SPP} spp's "
          "(least rays: of the least-ray one)")
    print(f"{'scene':<12}{'model':<12}{'floor':>6}{'samples/px':>12}{'samples':>9}"
          f"{'rays':>7}{'least rays':>12}{'RMSE at its rays':>18}")
    for name in a.scenes:
        scene = raytrace.load_scene(scene_path(name))
        goal = variances(scene, SPP, a.seeds, "uniform").sum()
        v16, v4 = (variances(scene, n, a.seeds, a.sampler) for n in (SPP, 4))
        fitted = float(np.log(v4.sum() / v16.sum()) / np.log(SPP / 4))
        cost = rays_per_sample(scene)
        for label, beta in (("β = 1", 1.0), (f"β = {fitted:.2f}", fitted)):
            for floor in (1.0, a.floor):
                n = allocation(v16, v16 ** (1 / (1 + beta)), beta, floor, goal)
                cheap = allocation(v16, (v16 / cost) ** (1 / (1 + beta)), beta, floor, goal)
                print(f"{name:<12}{label:<12}{floor:>6g}{n.mean():>12.2f}"
                      f"{n.mean() / SPP:>9.3f}{(cost * n).sum() / (cost * SPP).sum():>7.3f}"
                      f"{(cost * cheap).sum() / (cost * SPP).sum():>12.3f}"
                      f"{at_rays(v16, cost, beta, floor, goal):>18.3f}")


if __name__ == "__main__":
    main()
