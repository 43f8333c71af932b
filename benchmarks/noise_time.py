"""Renders by time, paired seed by seed: how close to its limit each ends, and its RMSE.

    python3 benchmarks/noise_time.py                                   # whitted, limits 0.5 1 2
    python3 benchmarks/noise_time.py --scene mesh_model --limits 1 --set TIME_PRIOR=inf,8

For one scene at 160×120 on 2 threads, seed by seed (``--seeds``): uniform 16 spp timed
(wall seconds of ``raytrace.render``), then at once, for each multiple of ``--limits`` and
each value of ``--set NAME=A,B`` (a constant of :mod:`raytrace.noise`, each value read as
its type: ``inf``, ``1`` or ``true``; the order of the values alternates from seed to
seed), a render by ``time_limit`` = that multiple of this seed's uniform time, so that the
machine's drift cancels in the pairs. Printed per limit and value: the medians over the
seeds of the render's wall seconds over its limit and of its RMSE over uniform's of the
same seed (against the 1024-spp reference of ``benchmarks/noise.py``, kept in
``--cache``), the range of wall over limit, the mean samples a pixel and how many rounds.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
from bench_scenes import scene_path
from noise import reference, rms_error

import raytrace
from raytrace import malloc, noise


def value_of(text: str, like: object) -> object:
    """``text`` as a value of ``like``'s type (a bool from 0/1/true/false)."""
    if isinstance(like, bool):
        return text.strip().lower() in ("1", "true", "yes", "on")
    return int(text) if isinstance(like, int) else float(text)


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("--scene", default="whitted")
    p.add_argument("--seeds", type=int, default=10)
    p.add_argument("--limits", type=float, nargs="+", default=[0.5, 1.0, 2.0],
                   help="time limits, in multiples of uniform 16 spp's wall seconds")
    p.add_argument("--set", default="", metavar="NAME=A,B",
                   help="a constant of raytrace.noise and the values to measure it at")
    p.add_argument("--cache", type=Path, default=Path("/tmp/raytrace-noise-references"))
    a = p.parse_args()
    malloc.tune()  # as the command line does
    if a.set and "=" not in a.set:
        p.error("--set takes NAME=A,B")
    name, values = a.set.split("=", 1) if a.set else ("", "")
    default = getattr(noise, name) if name else None
    settings = list(dict.fromkeys(value_of(v, default) for v in values.split(","))) \
        if name else [None]
    scene = raytrace.load_scene(scene_path(a.scene))
    common = dict(width=160, height=120, threads=2)
    ref = reference(scene, a.scene, 1024, a.cache, **common)
    for seed in range(2):  # kernels loaded, the allocation's included (a second round)
        raytrace.render(scene, spp=16, seed=seed, **common)
        raytrace.render(scene, target_error=0.02, seed=seed, **common)
    rows: dict = {(f, v): [] for f in a.limits for v in settings}
    try:
        for seed in range(a.seeds):
            t0 = time.perf_counter()
            image = raytrace.render(scene, spp=16, seed=seed, **common)
            limit = time.perf_counter() - t0
            uniform = rms_error(image, ref)
            for f in a.limits:
                for v in settings if seed % 2 == 0 else settings[::-1]:
                    if name:
                        setattr(noise, name, v)
                    t0 = time.perf_counter()
                    image = raytrace.render(scene, time_limit=f * limit, seed=seed, **common)
                    wall = (time.perf_counter() - t0) / (f * limit)
                    st = image.stats["aa"]
                    rows[f, v].append((wall, rms_error(image, ref) / uniform,
                                       st["samples_per_pixel"], st["rounds"]))
    finally:
        if name:
            setattr(noise, name, default)
    print(f"{a.scene} 160x120, 2 threads, {a.seeds} seeds: renders by time at multiples of "
          "uniform 16 spp's wall seconds (medians)")
    print(f"{'limit':>6}  {'setting':<18}{'wall/limit':>11}{'range':>14}{'RMSE/uniform':>14}"
          f"{'samples/px':>12}{'rounds':>8}")
    for (f, v), r in rows.items():
        r = np.array(r)
        label = f"{name}={v}" if name else "as is"
        print(f"{f:>5g}x  {label:<18}{np.median(r[:, 0]):>11.3f}"
              f"{r[:, 0].min():>8.3f}–{r[:, 0].max():.3f}{np.median(r[:, 1]):>14.3f}"
              f"{r[:, 2].mean():>12.2f}{r[:, 3].mean():>8.2f}")


if __name__ == "__main__":
    main()
