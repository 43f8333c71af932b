"""Tiles on a local Dask cluster against the threaded render on one process (issue 18).

    python3 benchmarks/cluster.py             # the full run, a few minutes
    python3 benchmarks/cluster.py --quick     # a smoke run (small images)

Scenes (those of ``bench.py``): **whitted** (scenes/whitted.toml, 1280×960, depth 5, analytic:
no BVH to speak of) and **mesh** (an 81 920-triangle smooth icosphere on a ground quad,
1000×1000: a BVH build and a 3.3 MB pickled scene).

What is measured, all in this process, which is the Dask client (and, as in
``raytrace render --workers``, the scheduler):

``local``
    ``raytrace.render`` on 1 and 2 threads, warm (after one render, so numba is loaded): the
    fastest of ``--repeat`` runs, wall and CPU seconds (the least of the runs).
``cluster``
    For 1 and 2 workers (``raytrace.distributed.local_cluster``: one thread each, loopback,
    TLS): the seconds to start the cluster; the first render (cold: each worker loads the
    compiled kernels, receives the scene, builds the BVH); then warm renders at each tile size
    (the fastest of ``--repeat``; the workers keep the built scene, so these pay no build):
    wall seconds, CPU seconds of all the processes (client, scheduler, nannies, workers), the
    workers' summed tile seconds, the overhead per tile ``(workers × wall − work) / tiles``
    and in CPU ``(cpu − local 1-thread cpu) / tiles``; the workers' CPU seconds rendering the
    tiles (their threads' time in :func:`raytrace.distributed.render_tile`) and the rest of
    the CPU per tile (Dask: scheduling, serialising, TLS, heartbeats); ``work`` is the local
    1-thread seconds less its BVH build (the local render builds each time). The 1-worker rows
    at every tile size give a least-squares fit ``wall = work + fixed + per_tile · tiles``, and
    every cluster a fit of the Dask CPU (all the CPU less the tiles' rendering) against the
    number of tiles: ``fixed + per_tile · tiles``.
``transfer``
    The pickled scene's bytes and the seconds from submitting it to its arrival on every worker
    (a task that reads it on each), less the same round trip with an empty payload.
``builds``
    The BVH build's seconds (the mesh scene's ``stats['seconds']['build']`` on a worker, and
    locally), and the builds counted on the workers for a cold and a warm render.

Prints the tables and writes the numbers as JSON (``--json``, default
``benchmarks/cluster.json``). Other processes on a shared machine make timings noisy: the
load average at the start and end is recorded.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))

import bench  # noqa: E402

import raytrace  # noqa: E402
from raytrace import distributed as rd  # noqa: E402

TILES = (64, 128, 256, 512)
QUICK_TILES = (32, 64)


def scenes(workdir: Path, quick: bool) -> dict[str, tuple[raytrace.Scene, dict]]:
    mesh = raytrace.load_scene(bench.write_mesh_scene(workdir))
    if quick:
        return {"whitted": (raytrace.load_scene(bench.WHITTED), {"width": 160, "height": 120}),
                "mesh": (mesh, {"width": 128, "height": 128})}
    return {"whitted": (raytrace.load_scene(bench.WHITTED), {"width": 1280, "height": 960}),
            "mesh": (mesh, {"width": 1000, "height": 1000})}


def cpu_seconds() -> float:
    """User + system CPU seconds of this process and every process under it (a local
    cluster's nannies and workers): less disturbed than wall time by other jobs on the
    machine."""
    import psutil

    total = 0.0
    for proc in [psutil.Process(), *psutil.Process().children(recursive=True)]:
        try:
            t = proc.cpu_times()
        except psutil.NoSuchProcess:
            continue
        total += t.user + t.system
    return total


def timed(fn):
    """(result, wall seconds, CPU seconds of this process and its children) of ``fn()``."""
    w, c = time.perf_counter(), cpu_seconds()
    out = fn()
    return out, time.perf_counter() - w, cpu_seconds() - c


def local(scene: raytrace.Scene, kw: dict, repeat: int) -> dict:
    raytrace.render(scene, threads=1, **kw)  # numba loaded, not timed
    rows = {}
    for threads in (1, 2):
        runs = [timed(lambda t=threads: raytrace.render(scene, threads=t, **kw))
                for _ in range(repeat)]
        image, wall, cpu = min(runs, key=lambda r: r[1])
        rows[threads] = {"wall": wall, "cpu": min(r[2] for r in runs),
                         "build": image.stats["seconds"]["build"],
                         "rays": image.stats["rays"]["total"], "image": image.rgb}
    return rows


def transfer(client, scene: raytrace.Scene, kw: dict, repeat: int) -> dict:
    """Seconds for the pickled scene to reach every worker, less an empty payload's."""
    from raytrace.rendering import render_options

    payload, _, _ = rd.scene_payload(scene, render_options(scene, **kw))
    workers = list(client.scheduler_info()["workers"])

    def arrive(data: bytes) -> float:
        t = time.perf_counter()
        task = client.submit(rd.load_payload, data, pure=False)
        client.gather([client.submit(lambda s: s is not None, task, workers=[w], pure=False)
                       for w in workers])
        return time.perf_counter() - t

    import pickle

    empty = pickle.dumps(raytrace.Scene())
    scene_s = min(arrive(payload) for _ in range(repeat))
    empty_s = min(arrive(empty) for _ in range(repeat))
    return {"bytes": len(payload), "seconds": scene_s, "empty_seconds": empty_s,
            "net_seconds": scene_s - empty_s}


def cluster(n: int, scenes_: dict, reference: dict, tiles: tuple, repeat: int,
            tls: bool = True) -> dict:
    from distributed import Client

    t = time.perf_counter()
    c = rd.local_cluster(n, tls=tls)
    client = Client(c, set_as_default=False)
    start = time.perf_counter() - t
    out = {"workers": n, "tls": tls, "start_seconds": start, "scenes": {}}
    try:
        for name, (scene, kw) in scenes_.items():
            ref = reference[name]
            first, wall, _ = timed(lambda s=scene, k=kw: raytrace.render(
                s, client=client, tile=64, **k))
            workers = first.stats["distributed"]["workers"]
            row = {"cold": {"wall": wall, "tile": 64,
                            "builds": sum(w["builds"] for w in workers.values()),
                            "build_seconds": max(w["build_seconds"] for w in workers.values()),
                            "identical": bool(np.array_equal(first.rgb, ref[1]["image"]))},
                   "transfer": transfer(client, scene, kw, repeat), "tiles": []}
            for tile in tiles:
                runs = [timed(lambda s=scene, k=kw, ts=tile: raytrace.render(
                    s, client=client, tile=ts, **k)) for _ in range(repeat)]
                image, wall, _ = min(runs, key=lambda r: r[1])
                cpu = min(r[2] for r in runs)
                d = image.stats["distributed"]
                work = ref[1]["wall"] - ref[1]["build"]  # the local render builds each time
                row["tiles"].append({
                    "tile": tile, "tiles": d["tiles"], "wall": wall, "cpu": cpu,
                    "cpu_overhead_per_tile": (cpu - ref[1]["cpu"]) / d["tiles"],
                    "tiles_cpu": image.stats["seconds"]["tiles_cpu"],
                    "dask_cpu_per_tile": (cpu - image.stats["seconds"]["tiles_cpu"])
                    / d["tiles"],
                    "tile_seconds": image.stats["seconds"]["tiles"],
                    "builds": sum(w["builds"] for w in d["workers"].values()),
                    "overhead_per_tile": (n * wall - work) / d["tiles"],
                    "speedup_vs_1_thread": ref[1]["wall"] / wall,
                    "speedup_vs_2_threads": ref[2]["wall"] / wall,
                    "identical": bool(np.array_equal(image.rgb, ref[1]["image"]))})
            if n == 1:
                xs = [r["tiles"] for r in row["tiles"]]
                ys = [r["wall"] - (ref[1]["wall"] - ref[1]["build"]) for r in row["tiles"]]
                slope, fixed = np.polyfit(xs, ys, 1) if len(xs) > 1 else (ys[0] / xs[0], 0.0)
                row["fit"] = {"fixed": float(fixed), "per_tile": float(slope)}
            out["scenes"][name] = row
    finally:
        t = time.perf_counter()
        client.close()
        c.close()
        out["close_seconds"] = time.perf_counter() - t
    return out


def report(results: dict) -> str:
    f = bench._f
    parts = []
    rows = []
    for name, r in results["local"].items():
        for threads, x in r.items():
            rows.append([name, str(threads), f(x["wall"]), f(x["cpu"]), f(x["build"], "{:.4f}"),
                         f"{x['rays'] / 1e6:.2f}M"])
    parts.append("local (one process, warm)\n" + bench.table(
        ["scene", "threads", "wall s", "cpu s", "build s", "rays"], rows))
    rows = []
    for c in results["clusters"]:
        for name, r in c["scenes"].items():
            for x in r["tiles"]:
                rows.append([name, str(c["workers"]), "tls" if c["tls"] else "tcp",
                             str(x["tile"]), str(x["tiles"]), f(x["wall"]), f(x["cpu"]),
                             f(x["tile_seconds"]), f(1e3 * x["overhead_per_tile"], "{:.1f}"),
                             f(1e3 * x["cpu_overhead_per_tile"], "{:.1f}"),
                             f(x["tiles_cpu"]), f(1e3 * x["dask_cpu_per_tile"], "{:.1f}"),
                             f(x["speedup_vs_1_thread"], "{:.2f}"),
                             f(x["speedup_vs_2_threads"], "{:.2f}"), str(x["builds"]),
                             "yes" if x["identical"] else "NO"])
    parts.append("cluster, warm (the workers keep the built scene)\n" + bench.table(
        ["scene", "workers", "comm", "tile", "tiles", "wall s", "cpu s", "tile s", "ms/tile",
         "cpu ms/tile", "tile cpu s", "dask cpu ms/tile", "vs 1 thr", "vs 2 thr", "builds",
         "identical"], rows))
    rows = []
    for c in results["clusters"]:
        for name, r in c["scenes"].items():
            t, cold = r["transfer"], r["cold"]
            fit = r.get("fit", {})
            per_tile, fixed = np.polyfit([x["tiles"] for x in r["tiles"]],
                                         [x["cpu"] - x["tiles_cpu"] for x in r["tiles"]], 1)
            rows.append([name, str(c["workers"]), "tls" if c["tls"] else "tcp",
                         f(c["start_seconds"], "{:.2f}"), f(cold["wall"], "{:.2f}"),
                         str(cold["builds"]), f(cold["build_seconds"], "{:.4f}"),
                         f"{t['bytes'] / 1e6:.3f}", f(1e3 * t["net_seconds"], "{:.1f}"),
                         f(1e3 * fit["per_tile"], "{:.1f}") if fit else "-",
                         f(fit["fixed"], "{:.3f}") if fit else "-",
                         f(1e3 * per_tile, "{:.1f}"), f(fixed, "{:.2f}"),
                         f(c["close_seconds"], "{:.2f}")])
    parts.append("cluster set-up (cold: the first render, tile 64)\n" + bench.table(
        ["scene", "workers", "comm", "start s", "cold s", "builds", "build s", "scene MB",
         "transfer ms", "fit ms/tile", "fit fixed s", "dask cpu ms/tile", "dask cpu fixed s",
         "close s"], rows))
    return "\n\n".join(parts)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--quick", action="store_true", help="small images, two tile sizes")
    p.add_argument("--repeat", type=int, default=3, help="runs per timing; the fastest is kept")
    p.add_argument("--json", default=str(ROOT / "benchmarks" / "cluster.json"))
    p.add_argument("--no-tcp", action="store_true",
                   help="skip the 2-worker run without TLS (plain tcp://)")
    p.add_argument("--report", metavar="JSON", help="print the tables of an earlier run's JSON")
    args = p.parse_args(argv)
    if args.report:
        print(report(json.loads(Path(args.report).read_text())))
        return 0
    import tempfile

    with tempfile.TemporaryDirectory() as tmp:
        load_before = os.getloadavg()
        sc = scenes(Path(tmp), args.quick)
        tiles = QUICK_TILES if args.quick else TILES
        reference = {name: local(s, kw, args.repeat) for name, (s, kw) in sc.items()}
        clusters = [cluster(n, sc, reference, tiles, args.repeat) for n in (1, 2)]
        if not args.no_tcp:
            clusters.append(cluster(2, sc, reference, tiles, args.repeat, tls=False))
    for r in reference.values():
        for x in r.values():
            x.pop("image")
    results = {"machine": {**bench.machine(), "load_average_end": os.getloadavg(),
                           "load_average": load_before},
               "quick": args.quick, "repeat": args.repeat, "local": reference,
               "clusters": clusters,
               "median_overhead_ms_per_tile": 1e3 * statistics.median(
                   x["overhead_per_tile"] for c in clusters for r in c["scenes"].values()
                   for x in r["tiles"])}
    print(report(results))
    Path(args.json).write_text(json.dumps(results, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
