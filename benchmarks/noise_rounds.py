"""Where a noise-driven render's wall time goes: its rounds' passes, and the main thread's
work before, between and after them.

    python3 benchmarks/noise_rounds.py                          # whitted, by uniform's error
    python3 benchmarks/noise_rounds.py --scene mesh_model --renders 5
    python3 benchmarks/noise_rounds.py --target 0.01 --set MIN_ROUND_SHARE=0.25
    python3 benchmarks/noise_rounds.py --renders 15 --window-order

For one scene at 160×120 on 2 threads, a render by ``--target``, or by the target of
uniform 16 spp's relative RMSE (against the 1024-spp reference of ``benchmarks/noise.py``,
kept in ``--cache``), timed ``--renders`` times after a warm-up, render i with seed i. Each
round's passes run inside one call of the integrator's ``_run`` (wrapped here to note when
it starts and ends); the rest of the render is the main thread's: building the integrator,
then per round the estimate, the allocation (:func:`raytrace.noise.neyman_counts`) and the
round's plan, and after the last round the image. Prints, per render, the milliseconds
before the first round's passes, between each two rounds, after the last, in the passes,
and in all, how long the first thread to finish a round sat idle until the last finished it
(each thread's last pass of the round timed), its samples a pixel and rounds, and the
relative RMSE measured against the reference over the target; then the medians of the
total, of each round's idle time and of an allocation's; then, round by round, the
estimated relative RMSE and β (:func:`raytrace.noise.convergence_rate`), and for each
allocation the fall of the summed variance it was to give (``shrink``,
:func:`raytrace.noise.variance_shrink`), the fall the model predicts for the counts chosen
(:func:`predicted_fall`), the fall of the estimate's square the round gave, and the actual
over the predicted. ``--window-order`` traces each round's pixels in window order instead
of :func:`raytrace.noise.spread_order`'s.
"""

from __future__ import annotations

import argparse
import inspect
import threading
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
    p.add_argument("--target", type=float, help="the target error (default: uniform 16 spp's "
                   "relative RMSE)")
    p.add_argument("--set", nargs="*", default=[], metavar="NAME=VALUE",
                   help="set constants of raytrace.noise (ROUND_SHARE, MIN_ROUND_SHARE, "
                   "TARGET_MARGIN, MAX_DOUBLINGS) for this run")
    p.add_argument("--cache", type=Path, default=Path("/tmp/raytrace-noise-references"))
    p.add_argument("--window-order", action="store_true",
                   help="trace each round's pixels in window order")
    a = p.parse_args()
    if a.window_order:
        noise.spread_order = lambda w: np.arange((w[2] - w[0]) * (w[3] - w[1]))
    for setting in a.set:
        name, value = setting.split("=")
        setattr(noise, name, type(getattr(noise, name))(value))
    malloc.tune()  # as the command line does
    scene = raytrace.load_scene(scene_path(a.scene))
    common = dict(width=160, height=120, threads=2)
    ref = reference(scene, a.scene, 1024, a.cache, **common)
    level = float(ref.mean())
    uniform = raytrace.render(scene, spp=16, **common).rgb.astype(np.float64)
    target = a.target or float(np.sqrt(np.mean((uniform - ref) ** 2)) / level)
    raytrace.render(scene, target_error=target, **common)  # warm-up
    marks: list[float] = []
    ends: list[dict[int, float]] = []  # per round, when each thread's last pass ended
    run, render_pass = integrator.WhittedIntegrator._run, integrator.WhittedIntegrator._render_pass

    def timed_run(self, *args, **kw):
        marks.append(time.perf_counter())
        ends.append({})
        try:
            return run(self, *args, **kw)
        finally:
            marks.append(time.perf_counter())

    def timed_pass(self, *args, **kw):
        try:
            return render_pass(self, *args, **kw)
        finally:
            ends[-1][threading.get_ident()] = time.perf_counter()

    integrator.WhittedIntegrator._run = timed_run
    integrator.WhittedIntegrator._render_pass = timed_pass
    rounds: list[tuple] = []  # (estimate, β) and (shrink, predicted fall) by turns
    estimate, allocate = noise.relative_rmse, noise.neyman_counts

    def noted_estimate(a, b, rate):
        e = estimate(a, b, rate)
        rounds.append((e, rate))
        return e

    allocations: list[float] = []  # each allocation's milliseconds

    def noted_allocation(*args, **kw):  # whatever arguments the renderer passes
        t = time.perf_counter()
        new = allocate(*args, **kw)
        allocations.append(1e3 * (time.perf_counter() - t))
        given = inspect.signature(allocate).bind(*args, **kw)
        given.apply_defaults()
        n, variance, shrink, rate = (given.arguments[k]
                                     for k in ("n", "variance", "shrink", "rate"))
        rounds.append((shrink, predicted_fall(n, new, variance, rate)))
        return new

    noise.relative_rmse, noise.neyman_counts = noted_estimate, noted_allocation
    print(f"{a.scene} 160x120, 2 threads, target {target:.4f}"
          f"{'' if a.target else ' (uniform 16 spp' + chr(39) + 's)'} {' '.join(a.set)}: ms")
    print(f"{'before':>8}{'between rounds':>24}{'after':>8}{'passes':>9}{'total':>8}"
          f"{'idle at ends':>18}{'samples/px':>12}{'rounds':>8}{'measured/target':>17}")
    notes, spent, totals, idles = [], [], [], []
    for seed in range(a.renders):
        marks.clear()
        ends.clear()
        rounds.clear()
        t0 = time.perf_counter()
        image = raytrace.render(scene, target_error=target, seed=seed, **common)
        t1 = time.perf_counter()
        ms = 1e3 * np.diff([t0, *marks, t1])
        between = ", ".join(f"{x:.1f}" for x in ms[2:-1:2])
        st = image.stats["aa"]
        measured = np.sqrt(np.mean((image.rgb.astype(np.float64) - ref) ** 2)) / level
        spent.append((st["samples_per_pixel"], st["rounds"]))
        idle = [1e3 * (max(e.values()) - min(e.values())) for e in ends]
        totals.append(1e3 * (t1 - t0))
        idles.append(idle)
        print(f"{ms[0]:>8.1f}{between:>24}{ms[-1]:>8.1f}{ms[1::2].sum():>9.1f}"
              f"{totals[-1]:>8.1f}  {', '.join(f'{x:.1f}' for x in idle):>16}"
              f"{st['samples_per_pixel']:>12.2f}{st['rounds']:>8}{measured / target:>17.2f}")
        notes.append(list(rounds))
    mean = np.mean(spent, axis=0)
    print(f"mean of {a.renders}: {mean[0]:.2f} samples a pixel in {mean[1]:.2f} rounds")
    idle = [np.median([x[k] for x in idles if len(x) > k]) for k in range(max(map(len, idles)))]
    print(f"medians: {np.median(totals):.1f} ms in all (best {min(totals):.1f}); idle at the "
          f"end of each round {', '.join(f'{x:.1f}' for x in idle)} ms; an allocation "
          f"(neyman_counts) {np.median(allocations):.1f} ms")
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
