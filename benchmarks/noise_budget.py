"""Renders by time at equal samples: how well a setting of the allocation spends them, free
of the machine's speed.

    python3 benchmarks/noise_budget.py                          # whitted, 12 and 16 spp
    python3 benchmarks/noise_budget.py --scene mesh_model --set TIME_PRIOR=inf,8

A render by ``--time-limit`` sizes each round to the time left
(:func:`raytrace.noise.time_share`), so its samples, and its error, move with the machine's
speed. Here that share is replaced by the share of a budget of ``--spp`` samples a pixel
that is left (at most :data:`raytrace.noise.ROUND_SHARE` of the samples spent, as a round by
time takes): the rounds are those of a render by time, with its first round, doublings and
ranking, but they stop at the budget (within a doubling), so every setting spends the same
samples and is judged by its RMSE. For one scene at 160×120 on 2 threads, ``--renders``
seeds each: the mean of each render's RMSE over uniform 16 spp's of the same seed (against
the 1024-spp reference of ``benchmarks/noise.py``, kept in ``--cache``), the samples a pixel
and the rounds, and the range of the error measured over the renderer's estimate. ``--set
NAME=A,B`` sets a constant of :mod:`raytrace.noise` (``TIME_PRIOR``, ``ROUND_SHARE``,
``MAX_DOUBLINGS``) to each value in turn.
"""

from __future__ import annotations

import argparse
from functools import partial
from pathlib import Path

import numpy as np
from bench_scenes import scene_path
from noise import reference, rms_error

import raytrace
from raytrace import noise


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("--scene", default="whitted")
    p.add_argument("--spp", type=float, nargs="*", default=[12.0, 16.0])
    p.add_argument("--renders", type=int, default=10)
    p.add_argument("--set", default="", metavar="NAME=A,B",
                   help="a constant of raytrace.noise and the values to measure it at")
    p.add_argument("--cache", type=Path, default=Path("/tmp/raytrace-noise-references"))
    a = p.parse_args()
    name, values = (a.set.split("=") + [""])[:2] if a.set else ("", "")
    scene = raytrace.load_scene(scene_path(a.scene))
    common = dict(width=160, height=120, threads=2)
    ref = reference(scene, a.scene, 1024, a.cache, **common)
    level = float(ref.mean())

    rmse = partial(rms_error, ref=ref)

    uniform = [rmse(raytrace.render(scene, spp=16, seed=seed, **common))
               for seed in range(a.renders)]
    budget = [0.0]

    def left_of_budget(seconds_left: float, cost: tuple[float, float], spent: float) -> float:
        return max(0.0, min(noise.ROUND_SHARE, (budget[0] - spent) / spent))

    time_share, noise.time_share = noise.time_share, left_of_budget
    print(f"{a.scene} 160x120, 2 threads, {a.renders} seeds: a render by time whose rounds "
          "stop at a budget of samples; its RMSE over uniform 16 spp's")
    print(f"{'spp':>5}  {'setting':<24}{'RMSE':>7}{'samples/px':>12}{'rounds':>8}"
          f"{'measured/estimate':>20}")
    try:
        for spp in a.spp:
            budget[0] = spp * common["width"] * common["height"]
            for value in values.split(",") if name else [""]:
                if name:
                    setattr(noise, name, type(getattr(noise, name))(value))
                rows = []
                for seed in range(a.renders):
                    image = raytrace.render(scene, time_limit=1e6, seed=seed, **common)
                    st = image.stats["aa"]
                    rows.append((rmse(image) / uniform[seed], st["samples_per_pixel"],
                                 st["rounds"],
                                 rmse(image) / level / st["estimated_relative_rmse"]))
                r = np.array(rows)
                label = f"{name}={value}" if name else "as is"
                print(f"{spp:>5g}  {label:<24}{r[:, 0].mean():>7.3f}{r[:, 1].mean():>12.2f}"
                      f"{r[:, 2].mean():>8.2f}{r[:, 3].min():>15.2f}–{r[:, 3].max():.2f}")
    finally:
        noise.time_share = time_share


if __name__ == "__main__":
    main()
