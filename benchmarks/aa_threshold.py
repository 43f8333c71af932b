"""Adaptive thresholds and contrast measures against uniform 16 spp, one thread, CPU seconds.

    python3 benchmarks/aa_threshold.py whitted 0.2,0.25,0.3 [--contrast channel|luminance|relative]
        [--reference DIR] [--rounds 2]

SCENE at 640×480, ``aa_depth = 3``, ``aa_min_depth = 1``: uniform 16 spp, then adaptive at each
threshold, ``--rounds`` times in alternation; ``time.process_time`` and RMSE over linear RGB
against the 1024-spp reference of ``benchmarks/knobs.py --aa`` (its cached EXR,
``DIR/SCENE_640x480_1024spp_seed12345.exr``). ``--contrast`` swaps the cells' contrast
measure for this run only (``raytrace.adaptive.judge_cells``): ``channel`` is the renderer's,
``max − min`` per linear RGB channel; ``luminance`` the ``max − min`` of the corners'
Rec. 709 luminance Y; ``relative`` that divided by ``Ymax + Ymin + 0.1`` (a Weber-like
contrast, as POV-Ray's and Mitsuba's adaptive samplers judge relative differences).
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np
import OpenEXR
from bench_scenes import scene_path

import raytrace
import raytrace.adaptive as adaptive
from raytrace.kernels.adaptive import add_mean1, corners1
from raytrace.kernels.jit import kernel

ROOT = Path(__file__).resolve().parent.parent
CONTRASTS = ("channel", "luminance", "relative")


def judge_by_luminance(relative: bool):
    """A ``judge_cells`` whose spread is the corners' luminance range (÷ ``Ymax + Ymin + 0.1``
    where ``relative``); otherwise as :func:`raytrace.adaptive.judge_cells`."""

    @kernel
    def judge(slot, values, grid, cells, level, out, cut):
        ci, cj, pixel = cells.ci, cells.cj, cells.pixel
        s, threshold, everywhere = level.size, level.threshold, level.everywhere
        last, weight = level.last, level.weight
        n = 0
        ys = np.empty(4)
        for k in range(ci.shape[0]):
            r = corners1(slot, grid, ci[k], cj[k], s)
            split = False
            if not last:
                if everywhere:
                    split = True
                else:
                    for q in range(4):
                        ys[q] = (0.2126 * values[r[q], 0] + 0.7152 * values[r[q], 1]
                                 + 0.0722 * values[r[q], 2])
                    d = ys.max() - ys.min()
                    if relative:
                        d = d / (ys.max() + ys.min() + 0.1)
                    split = d >= threshold
            cut[k] = split
            if split:
                n += 1
                continue
            add_mean1(out, pixel[k], values, r, weight)
        return n

    return judge


def read_rgb(path: Path) -> np.ndarray:
    """The RGB pixels (h, w, 3) float64 of an EXR."""
    channels = OpenEXR.File(str(path)).channels()
    if "RGB" in channels:
        return np.asarray(channels["RGB"].pixels, np.float64)
    return np.stack([np.asarray(channels[c].pixels, np.float64) for c in "RGB"], -1)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("scene")
    p.add_argument("thresholds")
    p.add_argument("--contrast", choices=CONTRASTS, default="channel")
    p.add_argument("--reference", type=Path,
                   default=Path(tempfile.gettempdir()) / "raytrace-knobs")
    p.add_argument("--rounds", type=int, default=2)
    a = p.parse_args()
    ref = read_rgb(a.reference / f"{a.scene}_640x480_1024spp_seed12345.exr")
    scene = raytrace.load_scene(scene_path(a.scene))
    if a.contrast != "channel":
        adaptive.judge_cells = judge_by_luminance(a.contrast == "relative")
    raytrace.render(scene, width=32, height=24, threads=1, aa="adaptive", aa_min_depth=1)
    raytrace.render(scene, width=32, height=24, threads=1, spp=16)  # warm-up: compiled

    def run(label: str, **options) -> None:
        t0 = time.process_time()
        image = raytrace.render(scene, width=640, height=480, threads=1, **options)
        seconds = time.process_time() - t0
        rmse = np.sqrt(np.mean((image.rgb - ref) ** 2))
        print(f"{a.scene} {label}: CPU {seconds:.2f} s RMSE {rmse:.5f}", flush=True)

    for _ in range(a.rounds):
        run("uniform 16", spp=16)
        for t in (float(x) for x in a.thresholds.split(",")):
            run(f"{a.contrast} {t}/3/1", aa="adaptive", aa_threshold=t, aa_depth=3,
                aa_min_depth=1)


if __name__ == "__main__":
    main()
