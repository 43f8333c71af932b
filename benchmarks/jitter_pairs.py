"""Grid against jittered area-light samples at equal spp: CPU seconds in alternation, RMSE.

    python3 benchmarks/jitter_pairs.py --rounds 5

scenes/area_light.toml with 16 light samples on the grid and jittered, 120×90, 16 spp, one
thread: the best of ``--rounds`` rounds of ``time.process_time`` per render, the two renders
alternating in each round; and each one's RMSE against the reference of
benchmarks/knobs.py's ``jitter_spp`` sweep (64 spp, a 256-sample grid light, the scene's seed),
for the scene's seed and as the mean over render seeds 0 … ``--seeds`` − 1 (one seed's RMSE
moves by ±8 % with the pixel jitter; docs/knobs.md#what-jitter-is-for-jitter--spp).
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import time
from pathlib import Path

import numpy as np

import raytrace
from raytrace.scene import AreaLight

ROOT = Path(__file__).resolve().parent.parent


def rmse(image: np.ndarray, reference: np.ndarray) -> float:
    """sqrt(mean((a − b)²)) over every pixel and channel, in float64."""
    return float(np.sqrt(np.mean((image.astype(np.float64) - reference) ** 2)))


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--rounds", type=int, default=5)
    p.add_argument("--spp", type=int, default=16)
    p.add_argument("--seeds", type=int, default=8)
    a = p.parse_args()
    scene = raytrace.load_scene(ROOT / "scenes" / "area_light.toml")

    def variant(jitter: bool) -> raytrace.Scene:
        return dataclasses.replace(scene, lights=[
            dataclasses.replace(light, samples=16, jitter=jitter)
            if isinstance(light, AreaLight) else light for light in scene.lights])

    scenes = {"grid": variant(False), "jitter": variant(True)}
    for s in scenes.values():
        raytrace.render(s, width=16, height=12, threads=1)  # warm-up
    reference = raytrace.render(dataclasses.replace(scene, lights=[
        dataclasses.replace(light, samples=256, jitter=False) if isinstance(light, AreaLight)
        else light for light in scene.lights]), width=120, height=90, spp=64).rgb
    best = dict.fromkeys(scenes, float("inf"))
    error = {}
    load = os.getloadavg()[0]
    for _ in range(a.rounds):
        for name, s in scenes.items():
            t0 = time.process_time()
            image = raytrace.render(s, width=120, height=90, spp=a.spp, threads=1)
            best[name] = min(best[name], time.process_time() - t0)
            error[name] = rmse(image.rgb, reference)
    mean = {name: float(np.mean([rmse(raytrace.render(s, width=120, height=90, spp=a.spp,
                                                      seed=seed).rgb, reference)
                                 for seed in range(a.seeds)])) for name, s in scenes.items()}
    ratio = best["jitter"] / best["grid"]
    print(f"load average {load:.1f}; CPU s: "
          + ", ".join(f"{k} {v:.3f}" for k, v in best.items()) + f"; jitter/grid {ratio:.2f}; "
          + "RMSE " + ", ".join(f"{k} {v:.3e}" for k, v in error.items())
          + f"; mean RMSE over seeds 0-{a.seeds - 1} "
          + ", ".join(f"{k} {v:.3e}" for k, v in mean.items()))


if __name__ == "__main__":
    main()
