"""Where a noise-driven render's wall time goes: its rounds' passes, and the main thread's
work before, between and after them.

    python3 benchmarks/noise_rounds.py                          # whitted, by uniform's error
    python3 benchmarks/noise_rounds.py --scene mesh_model --renders 5

For one scene at 160×120 on 2 threads, a render by the target of uniform 16 spp's relative
RMSE (against the 1024-spp reference of ``benchmarks/noise.py``, kept in ``--cache``), timed
``--renders`` times after a warm-up, render i with seed i. Each round's passes run inside
one call of the integrator's ``_run`` (wrapped here to note when it starts and ends); the
rest of the render is the main thread's: building the integrator, then per round the
estimate, the allocation (:func:`raytrace.noise.neyman_counts`) and the round's plan, and
after the last round the image. Prints, per render, the milliseconds before the first
round's passes, between each two rounds, after the last, in the passes, and in all; then,
round by round, the estimated relative RMSE and β (:func:`raytrace.noise.convergence_rate`),
and for each allocation the fall of the summed variance it was to give (``shrink``,
:func:`raytrace.noise.variance_shrink`), the fall the model predicts for the counts chosen
(:func:`predicted_fall`), the fall of the estimate's square the round gave, and the actual
over the predicted.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
from bench_scenes import scene_path
from noise import reference

import raytrace
from raytrace import integrator, malloc, noise


def predicted_fall(n: np.ndarray, new: np.ndarray, variance: np.ndarray, rate: float) -> float:
    """The share of the summed variance of the pixels' means that ``new`` samples a half
    leave of ``n``'s, by the model :func:`raytrace.noise.neyman_counts` allocates by (a
    pixel's mean varies by ``s²·(2n)^−β``, s² its per-sample ``variance``)."""
    s2 = np.where(np.isfinite(variance), variance, 0.0)
    return float((s2 * (2.0 * new) ** -rate).sum() / (s2 * (2.0 * n) ** -rate).sum())


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("--scene", default="whitted")
    p.add_argument("--renders", type=int, default=3)
    p.add_argument("--cache", type=Path, default=Path("/tmp/raytrace-noise-references"))
    a = p.parse_args()
    malloc.tune()  # as the command line does
    scene = raytrace.load_scene(scene_path(a.scene))
    common = dict(width=160, height=120, threads=2)
    ref = reference(scene, a.scene, 1024, a.cache, **common)
    uniform = raytrace.render(scene, spp=16, **common).rgb.astype(np.float64)
    target = float(np.sqrt(np.mean((uniform - ref) ** 2)) / ref.mean())
    raytrace.render(scene, target_error=target, **common)  # warm-up
    marks: list[float] = []
    run = integrator.WhittedIntegrator._run

    def timed_run(self, *args, **kw):
        marks.append(time.perf_counter())
        try:
            return run(self, *args, **kw)
        finally:
            marks.append(time.perf_counter())

    integrator.WhittedIntegrator._run = timed_run
    rounds: list[tuple] = []  # (estimate, β) and (shrink, predicted fall) by turns
    estimate, allocate = noise.relative_rmse, noise.neyman_counts

    def noted_estimate(a, b, rate):
        e = estimate(a, b, rate)
        rounds.append((e, rate))
        return e

    def noted_allocation(n, variance, most, cols, share, shrink, rate):
        new = allocate(n, variance, most, cols, share, shrink, rate)
        rounds.append((shrink, predicted_fall(n, new, variance, rate)))
        return new

    noise.relative_rmse, noise.neyman_counts = noted_estimate, noted_allocation
    print(f"{a.scene} 160x120, 2 threads, target {target:.4f} (uniform 16 spp's): ms")
    print(f"{'before':>8}{'between rounds':>24}{'after':>8}{'passes':>9}{'total':>8}")
    notes = []
    for seed in range(a.renders):
        marks.clear()
        rounds.clear()
        t0 = time.perf_counter()
        raytrace.render(scene, target_error=target, seed=seed, **common)
        t1 = time.perf_counter()
        ms = 1e3 * np.diff([t0, *marks, t1])
        between = ", ".join(f"{x:.1f}" for x in ms[2:-1:2])
        print(f"{ms[0]:>8.1f}{between:>24}{ms[-1]:>8.1f}{ms[1::2].sum():>9.1f}"
              f"{1e3 * (t1 - t0):>8.1f}")
        notes.append(list(rounds))
    print("round by round: estimate, beta; shrink asked, fall predicted, fall of the "
          "estimate's square, actual/predicted")
    for steps in notes:
        text = []
        for i in range(0, len(steps), 2):
            e, rate = steps[i]
            text.append(f"{e:.4f} b={rate:.2f}")
            if i + 2 < len(steps):
                shrink, predicted = steps[i + 1]
                fall = (steps[i + 2][0] / e) ** 2
                text.append(f"[{shrink:.3f} {predicted:.3f} {fall:.3f} {fall / predicted:.2f}]")
        print("  " + " ".join(text))


if __name__ == "__main__":
    main()
