"""Embree's packets against embreex's single rays, on the rays of the 1000² mesh frame.

    python3 benchmarks/packets.py                 # 1000×1000, one thread, best of 3
    python3 benchmarks/packets.py --size 500 --repeat 5

The frame's camera rays (closest hit; row by row, and in the blocks of pixels that fill each
packet width, as renders trace them: ``raytrace.camera.camera_rays``' ``lanes``) and the
shadow rays of its hits (occlusion, recorded from a render by
``raytrace.accel.Accelerator.recorder``, the Python loop) are traced through embreex's ``run``
(one ``rtcIntersect1``/``rtcOccluded1`` a ray) and through ``raytrace.kernels.embree``'s packet
kernels at each width, with and without the COHERENT flag (COHERENT closest hits include
their tie guard). Each row's ratio is embreex's seconds over the form's, in the same run.
docs/decisions.md ("Embree and the loop") quotes the table.
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
from raytrace import RenderSettings, accel, accel_cache  # noqa: E402
from raytrace.camera import camera_rays  # noqa: E402
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
    frame = RenderSettings(width=size, height=size)

    def camera(lanes: int) -> tuple[EmbreeRays, np.ndarray]:
        """The frame's camera rays (origin 0: the scene is camera-relative) and, with
        ``lanes``, the packets of pixel blocks they go in, as renders trace them."""
        n = size * size
        if lanes:
            packets = camera_rays(scene.camera, frame, 0, n, lanes=lanes).packets
            direction, bounds = packets.direction, packets.bounds
        else:
            direction, bounds = camera_rays(scene.camera, frame, 0, n).direction, None
        return EmbreeRays(np.zeros((len(direction), 3), np.float32),
                          direction.astype(np.float32),
                          np.full(len(direction), np.finfo(np.float32).max, np.float32)), bounds

    shadow = [b for b in batches if b[0] == "OCCLUDED"]
    shadow_rays = EmbreeRays(*(np.concatenate([b[k] for b in shadow]) for k in (1, 2, 3)))
    for query in ("INTERSECT", "OCCLUDED"):
        plain = camera(0)[0] if query == "INTERSECT" else shadow_rays
        n = len(plain.far)
        out = {"INTERSECT": {"output": 1}, "OCCLUDED": {"query": "OCCLUDED"}}[query]
        base = best(args.repeat, lambda r=plain, out=out: embreex_scene.run(
            r.origin, r.direction, dists=r.far.copy(), **out))
        rows.append((query, n, "embreex run (single rays)", base))
        for width in (4, 8, 16):
            record = meshes.record._replace(
                width=width, intersect=lib.addresses[f"rtcIntersect{width}"],
                occluded=lib.addresses[f"rtcOccluded{width}"])
            rows_in_order = np.append(np.arange(0, n, width), n)
            forms = [("", plain, rows_in_order)]
            if query == "INTERSECT":
                forms.append((", blocks (as rendered)", *camera(width)))
            for coherent in (False, True):
                for label, rays, bounds in forms:
                    if query == "INTERSECT":
                        m = len(rays.far)
                        hits = EmbreeHits(np.empty(m, np.int32), np.empty(m, np.int32),
                                          np.empty(m, np.float32), np.empty(m, np.float32))
                        packets = bounds if coherent else ek.PLAIN
                        run = lambda r=record, p=packets, x=rays, h=hits: \
                            ek.closest_hits(r, x, p, h)  # noqa: E731
                    else:
                        flags = np.empty(n, np.int32)
                        run = lambda r=record, c=coherent, x=rays, f=flags: \
                            ek.any_hits(r, x, c, f)  # noqa: E731
                    run()  # loads the kernel
                    rows.append((query, n, f"{width}-wide{' COHERENT' if coherent else ''}"
                                 f"{label}", best(args.repeat, run)))
    print(f"Embree {lib.version}, native packet width {lib.width}, one thread, "
          f"{size}x{size} mesh frame, best of {args.repeat}, load {os.getloadavg()[0]:.2f}")
    print(f"{'query':10s} {'rays':>8s}  {'form':40s} {'seconds':>8s} {'vs embreex':>10s}")
    bases = {q: s for q, _, f, s in rows if f.startswith("embreex")}
    for query, n, form, seconds in rows:
        print(f"{query:10s} {n:8d}  {form:40s} {seconds:8.4f} {bases[query] / seconds:9.2f}x")
    accel_cache.clear()
    return 0


if __name__ == "__main__":
    sys.exit(main())
