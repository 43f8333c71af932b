"""What one sequence a pixel buys over two independent ones, and how true its noise estimate is.

    python3 benchmarks/noise_sequences.py                 # whitted, mesh_model, area_light
    python3 benchmarks/noise_sequences.py --seeds 4 --spp 4 16

A noise-driven render (``aa = "noise"``) samples each pixel with the first N points of one
Owen-scrambled Sobol sequence and reads its noise from the difference of the two halves
(:mod:`raytrace.noise`). For each scene at 160×120 on 2 threads, against the 1024-spp
uniform reference of ``benchmarks/noise.py`` (seed 12345, kept in ``--cache``), and for each
N of ``--spp``, over ``--seeds`` seeds (every pixel N samples: ``min_spp = max_spp = N``, so
no count is chosen from the samples):

* the MSE of one sequence of N points (the renderer), of two independent sequences of N/2
  (the pixel's second half drawn from another pixel's sequence instead: the design of
  independent streams, Cycles' two buffers), and of uniform N spp (a jittered grid), and the
  ratios one/two and one/uniform;
* the render's estimated relative RMSE over the one measured (``estimate/measured``, the
  mean and range over the seeds): the estimate divides the halves' difference by
  ``2^β − 1``, β from the quarters (:func:`raytrace.noise.convergence_rate`).

The reference's own error (1024 samples) is in every measured MSE: a few percent of the
16-sample ones.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from bench_scenes import scene_path
from noise import reference

import raytrace
from raytrace import noise
from raytrace.kernels.noise import KEY_STRIDE


class TwoSequences(noise.Round):
    """A round whose pixels' second halves come from the sequence of another pixel (its
    number plus a million frame widths): two independent sequences of N/2 points. For a
    single round from 0 to N samples a pixel, the box filter."""

    def points(self, start: int, stop: int) -> noise.Points:
        p = super().points(start, stop)
        per = int(self.new[0] - self.old[0])
        col, row = np.floor(p.x).astype(np.int64), np.floor(p.y).astype(np.int64)
        k = np.tile(np.arange(per), len(p.x) // per)
        second = k >= per // 2
        pixel = row * self.width + col + np.where(second, self.width * 10**6, 0)
        k = np.where(second, k - per // 2, k)
        sx, sy = noise.offsets(self.seed, pixel, k)
        return noise.Points(col + sx, row + sy, pixel * KEY_STRIDE + k, None)


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("--scenes", nargs="*", default=["whitted", "mesh_model", "area_light"])
    p.add_argument("--spp", type=int, nargs="*", default=[4, 16])
    p.add_argument("--seeds", type=int, default=8)
    p.add_argument("--cache", type=Path, default=Path("/tmp/raytrace-noise-references"))
    a = p.parse_args()
    common = dict(width=160, height=120, threads=2)
    plain = noise.Round
    print(f"{'scene':<12}{'N':>4}{'MSE one':>11}{'two':>11}{'uniform':>11}{'one/two':>9}"
          f"{'one/unif':>9}{'estimate/measured (range)':>28}")
    for name in a.scenes:
        scene = raytrace.load_scene(scene_path(name))
        ref = reference(scene, name, 1024, a.cache, **common)
        level = float(ref.mean())
        for n in a.spp:
            mse = {"one": [], "two": [], "uniform": []}
            ratio = []
            for seed in range(a.seeds):
                kw = dict(common, aa="noise", min_spp=n, max_spp=n, seed=seed)
                one = raytrace.render(scene, **kw)
                noise.Round = TwoSequences  # (what noise.plan makes)
                try:
                    two = raytrace.render(scene, **kw)
                finally:
                    noise.Round = plain
                uniform = raytrace.render(scene, **common, spp=n, seed=seed)
                for key, image in (("one", one), ("two", two), ("uniform", uniform)):
                    mse[key].append(float(np.mean((image.rgb.astype(np.float64) - ref) ** 2)))
                measured = np.sqrt(mse["one"][-1]) / level
                ratio.append(one.stats["aa"]["estimated_relative_rmse"] / measured)
            m = {k: float(np.mean(v)) for k, v in mse.items()}
            print(f"{name:<12}{n:>4}{m['one']:>11.3e}{m['two']:>11.3e}{m['uniform']:>11.3e}"
                  f"{m['one'] / m['two']:>9.2f}{m['one'] / m['uniform']:>9.2f}"
                  f"{np.mean(ratio):>14.2f} ({min(ratio):.2f}–{max(ratio):.2f})")


if __name__ == "__main__":
    main()
