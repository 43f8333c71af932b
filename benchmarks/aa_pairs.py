"""The AA study's key comparison timed in alternation: uniform 16 spp against the adaptive
settings that reach its RMSE, CPU seconds (``time.process_time``, all threads) and wall seconds,
best of ``--rounds`` rounds, each round rendering every setting once in turn, so that load from
other processes falls on all of them alike (docs/knobs.md#adaptive-or-uniform-anti-aliasing).

    python3 benchmarks/aa_pairs.py --rounds 3
"""

from __future__ import annotations

import argparse
import json
import os
import time
from pathlib import Path

from bench_scenes import scene_path

import raytrace

ROOT = Path(__file__).resolve().parent.parent
PAIRS = {
    "whitted": [("uniform 16 spp", dict(spp=16)),
                ("adaptive t 0.05 d 3 min 1", dict(aa="adaptive", aa_threshold=0.05, aa_depth=3,
                                                   aa_min_depth=1)),
                ("adaptive t 0.1 d 3 min 1", dict(aa="adaptive", aa_threshold=0.1, aa_depth=3,
                                                  aa_min_depth=1)),
                ("adaptive t 0.05 d 2 min 1", dict(aa="adaptive", aa_threshold=0.05, aa_depth=2,
                                                   aa_min_depth=1))],
    "mesh_model": [("uniform 16 spp", dict(spp=16)),
                   ("adaptive t 0.02 d 3 min 1", dict(aa="adaptive", aa_threshold=0.02,
                                                      aa_depth=3, aa_min_depth=1)),
                   ("adaptive t 0.05 d 2 min 1", dict(aa="adaptive", aa_threshold=0.05,
                                                      aa_depth=2, aa_min_depth=1))],
}


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--rounds", type=int, default=3)
    p.add_argument("--threads", type=int, default=2)
    p.add_argument("--size", type=int, nargs=2, default=(640, 480))
    p.add_argument("--json", type=Path)
    a = p.parse_args()
    out = {"load_start": os.getloadavg(), "threads": a.threads, "size": a.size, "scenes": {}}
    for name, runs in PAIRS.items():
        scene = raytrace.load_scene(scene_path(name))
        raytrace.render(scene, width=32, height=24, threads=1, aa="adaptive")  # warm-up
        best = {label: [float("inf"), float("inf")] for label, _ in runs}
        for _ in range(a.rounds):
            for label, kw in runs:
                c0, w0 = time.process_time(), time.perf_counter()
                raytrace.render(scene, width=a.size[0], height=a.size[1], threads=a.threads,
                                **kw)
                cpu, wall = time.process_time() - c0, time.perf_counter() - w0
                best[label] = [min(best[label][0], cpu), min(best[label][1], wall)]
        out["scenes"][name] = {label: {"cpu": c, "wall": w} for label, (c, w) in best.items()}
        for label, (c, w) in best.items():
            print(f"{name:11s} {label:28s} cpu {c:6.2f} s  wall {w:6.2f} s", flush=True)
    out["load_end"] = os.getloadavg()
    print(f"load average {out['load_start']} -> {out['load_end']}")
    if a.json:
        a.json.write_text(json.dumps(out, indent=1) + "\n")


if __name__ == "__main__":
    main()
