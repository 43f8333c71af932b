"""Embree's packets against embreex's single rays, on the rays of the 1000² mesh frame.

    python3 benchmarks/packets.py                 # 1000×1000, one thread, best of 3
    python3 benchmarks/packets.py --size 500 --repeat 5

The frame's camera rays (closest hit) and the shadow rays of its hits (occlusion) are recorded
from a render (``raytrace.accel.Accelerator.recorder``, the Python loop), then traced through
embreex's ``run`` (one ``rtcIntersect1``/``rtcOccluded1`` a ray) and through
``raytrace.kernels.embree``'s packet kernels at each width, with and without the COHERENT
flag, and for the camera rays also in 4×4-pixel tiles. Each row's ratio is embreex's seconds
over the form's, in the same run. docs/decisions.md ("Embree and the loop") quotes the table.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

import bench  # noqa: E402

import raytrace  # noqa: E402
from raytrace import accel, accel_cache  # noqa: E402
from raytrace.kernels import embree as ek  # noqa: E402
from raytrace.kernels.records import EmbreeHits, EmbreeRays  # noqa: E402
from raytrace.tables import scene_arrays  # noqa: E402


def best(repeat: int, fn) -> float:
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times)


def tiles(width: int, height: int, tile: int) -> np.ndarray:
    """Row-major pixel indices reordered into tile × tile blocks."""
    index = np.arange(width * height).reshape(height // tile, tile, width // tile, tile)
    return index.transpose(0, 2, 1, 3).reshape(-1)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--size", type=int, default=1000)
    p.add_argument("--repeat", type=int, default=3)
    args = p.parse_args(argv)
    size = args.size - args.size % 4
    scene = raytrace.load_scene(bench.write_mesh_scene(Path(tempfile.mkdtemp())))
    batches: list = []
    accel.Accelerator.recorder = staticmethod(lambda *batch: batches.append(batch))
    bench.python_loop()
    try:
        raytrace.render(scene, width=size, height=size, threads=1)
    finally:
        bench.python_loop(False)
        accel.Accelerator.recorder = None
    meshes = accel.Accelerator(scene_arrays(scene)).embree
    lib = meshes.library
    embreex_scene = bench.embree_scene(scene_arrays(scene).meshes)
    rows = []
    for query in ("INTERSECT", "OCCLUDED"):
        mine = [b for b in batches if b[0] == query]
        if query == "INTERSECT":  # the camera rays: the first size² of the closest-hit rays
            mine = mine[:1] if len(mine[0][1]) == size * size else mine
        o = np.concatenate([b[1] for b in mine])
        d = np.concatenate([b[2] for b in mine])
        far = np.concatenate([b[3] for b in mine])
        if query == "INTERSECT":
            o, d, far = o[:size * size], d[:size * size], far[:size * size]
        n = len(o)
        out = {"INTERSECT": {"output": 1}, "OCCLUDED": {"query": "OCCLUDED"}}[query]
        base = best(args.repeat, lambda o=o, d=d, far=far, out=out: embreex_scene.run(
            o, d, dists=far.copy(), **out))
        rows.append((query, n, "embreex run (single rays)", base))
        orders = [("", np.arange(n))]
        if query == "INTERSECT" and n == size * size:
            orders.append((", 4x4 tiles", tiles(size, size, 4)))
        for width in (4, 8, 16):
            record = meshes.record._replace(
                width=width, intersect=lib.addresses[f"rtcIntersect{width}"],
                occluded=lib.addresses[f"rtcOccluded{width}"])
            for coherent in (False, True):
                for label, order in orders:
                    rays = EmbreeRays(np.ascontiguousarray(o[order]),
                                      np.ascontiguousarray(d[order]), far[order])
                    if query == "INTERSECT":
                        hits = EmbreeHits(np.empty(n, np.int32), np.empty(n, np.int32),
                                          np.empty(n, np.float32), np.empty(n, np.float32))
                        run = lambda r=record, c=coherent, x=rays, h=hits: \
                            ek.closest_hits(r, x, c, h)  # noqa: E731
                    else:
                        flags = np.empty(n, np.int32)
                        run = lambda r=record, c=coherent, x=rays, f=flags: \
                            ek.any_hits(r, x, c, f)  # noqa: E731
                    run()  # loads the kernel
                    rows.append((query, n, f"{width}-wide{' COHERENT' if coherent else ''}"
                                 f"{label}", best(args.repeat, run)))
    print(f"Embree {lib.version}, native packet width {lib.width}, one thread, "
          f"{size}x{size} mesh frame, best of {args.repeat}, load {os.getloadavg()[0]:.2f}")
    print(f"{'query':10s} {'rays':>8s}  {'form':34s} {'seconds':>8s} {'vs embreex':>10s}")
    bases = {q: s for q, _, f, s in rows if f.startswith("embreex")}
    for query, n, form, seconds in rows:
        print(f"{query:10s} {n:8d}  {form:34s} {seconds:8.4f} {bases[query] / seconds:9.2f}x")
    accel_cache.clear()
    return 0


if __name__ == "__main__":
    sys.exit(main())
