"""Adaptive against uniform stratified anti-aliasing: error against render time.

    python3 benchmarks/aa.py                      # whitted and mesh_model, 320×240
    python3 benchmarks/aa.py --size 640 480 --reference-spp 1024   # the issue's setting

Each scene is rendered with uniform spp 1, 4, 16, 64 and adaptive (threshold × depth), timed
(best of ``--repeats``, one warm-up render first, ``--threads`` threads), and compared with a
reference rendered at ``--reference-spp`` uniform samples with another seed: RMSE over linear
RGB and HDR-FLIP (:mod:`raytrace.film.metrics`), seconds and camera samples traced. Prints one
table per scene.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from bench_scenes import scene_path

import raytrace
from raytrace.film.metrics import METRICS

ROOT = Path(__file__).resolve().parent.parent


def timed(scene, repeats: int, **kw) -> tuple[raytrace.Image, float]:
    best, image = float("inf"), None
    for _ in range(repeats):
        t0 = time.perf_counter()
        image = raytrace.render(scene, **kw)
        best = min(best, time.perf_counter() - t0)
    return image, best


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("--size", type=int, nargs=2, default=(320, 240))
    p.add_argument("--reference-spp", type=int, default=256)
    p.add_argument("--threads", type=int, default=2)
    p.add_argument("--repeats", type=int, default=2)
    p.add_argument("--scenes", nargs="*", default=["whitted", "mesh_model"])
    a = p.parse_args()
    w, h = a.size
    rmse, flip = METRICS["rmse"].function, METRICS["flip"].function
    for name in a.scenes:
        scene = raytrace.load_scene(scene_path(name))
        common = dict(width=w, height=h, threads=a.threads)
        raytrace.render(scene, width=32, height=24, threads=1)  # warm-up
        ref = raytrace.render(scene, spp=a.reference_spp, seed=12345, **common).rgb
        print(f"\n{name} {w}x{h}, reference {a.reference_spp} spp (seed 12345)")
        print(f"{'setting':<28}{'seconds':>9}{'samples/px':>12}{'rmse':>11}{'flip':>9}")
        runs = [(f"uniform {s} spp", dict(spp=s)) for s in (1, 4, 16, 64)]
        runs += [(f"adaptive t={t} d={d}", dict(aa="adaptive", aa_threshold=t, aa_depth=d))
                 for d in (2, 3) for t in (0.2, 0.1, 0.05, 0.02)]
        for label, kw in runs:
            image, seconds = timed(scene, a.repeats, **common, **kw)
            spp = image.stats["rays"]["camera"] / (w * h)
            print(f"{label:<28}{seconds:>9.3f}{spp:>12.2f}{rmse(image.rgb, ref):>11.5f}"
                  f"{flip(image.rgb, ref):>9.4f}")


if __name__ == "__main__":
    main()
