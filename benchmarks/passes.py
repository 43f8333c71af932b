"""Render seconds by thread count and pass size: what the pass size does to a many-core render.

    python3 benchmarks/passes.py --threads 1,2 --json benchmarks/passes.json
    python3 benchmarks/passes.py --small --threads 2    # small frames: the least pass size

Each benchmark scene of ``benchmarks/bench.py`` (the 82k-triangle mesh at 1000², the Whitted
scene at 1280×960) is rendered in one process with its BVH kept (:mod:`raytrace.accel_cache`)
and its kernels loaded, at each thread count, with the image cut into 16, 32, 64 and 128
passes (``pass_samples`` = ⌈pixels / passes⌉; from 8 threads up the integrator never cuts an
image into fewer than :data:`raytrace.integrator.MIN_PASSES` = 16, and by default into
passes of at most :data:`raytrace.integrator.PASS_SAMPLES` samples: 16 or 17 and 19 passes
here; below, into as many as that many threads' ``PASSES_PER_THREAD`` ask): the best and the
median of ``--repeat`` renders' ``stats["seconds"]["total"]``. The image is the same for
every pass size (tests/test_threads.py), so only the time can differ: more passes balance the
threads more finely, and each pass costs the same Python between its kernel calls, which
holds the GIL.

``--small``: frames of fewer than 16 full passes, cut into 16 passes as from 8 threads up
(:data:`raytrace.integrator.PASSES_PER_THREAD` set to 16 while it runs), or into fewer of
:data:`raytrace.integrator.MIN_PASS_SAMPLES`: the scenes of ``scenes/`` that
benchmarks/noise.py renders, at 160×120 and 4 samples a pixel, and the Whitted scene at
320×240 and 1, rendered with each least pass size of :data:`SMALL_LEAST` in turn (interleaved,
``--repeat`` rounds, the API's wall seconds), and the ratio of each to the first.

``--per-thread``: frames of 16 to 64 least passes (307 200 samples: 18.75), which the
integrator cuts into :data:`raytrace.integrator.PASSES_PER_THREAD` passes a thread where that
is fewer than 16 (:func:`raytrace.integrator.frame_passes`): the three scenes at 160×120 and
16 samples a pixel, the Whitted scene at 320×240 and 4 and at 640×480 and 1 (the README's
size), rendered with each count a thread of :data:`PER_THREAD` in turn, the first 16 (every
frame in 16 passes or more, whatever the threads), interleaved as ``--small``.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

import bench  # noqa: E402
from bench_scenes import scene_path  # noqa: E402

import raytrace  # noqa: E402
from raytrace import integrator, malloc  # noqa: E402

#: How many passes the image is cut into.
PASSES = (16, 32, 64, 128)
#: The least pass sizes ``--small`` compares, the first the baseline.
SMALL_LEAST = (4096, 8192, 16384, 32768)
#: ``--small``'s frames: scene, width, height, samples a pixel.
SMALL_FRAMES = (("whitted", 160, 120, 4), ("mesh_model", 160, 120, 4),
                ("area_light", 160, 120, 4), ("whitted", 320, 240, 1))
#: The passes a thread ``--per-thread`` compares, the first the baseline.
PER_THREAD = (integrator.MIN_PASSES, 2, 4)
#: ``--per-thread``'s frames.
PER_THREAD_FRAMES = (("whitted", 160, 120, 16), ("mesh_model", 160, 120, 16),
                     ("area_light", 160, 120, 16), ("whitted", 320, 240, 4),
                     ("whitted", 640, 480, 1))


def measure(path: Path, size: tuple[int, int], threads: list[int], repeat: int) -> list[dict]:
    """Rows of one scene: threads, passes, pass samples, best and median seconds."""
    w, h = size
    scene = raytrace.load_scene(path)
    raytrace.render(scene, width=16, height=16)  # loads the kernels and builds the BVH
    rows = []
    for t in threads:
        for passes in PASSES:
            samples = -(-w * h // passes)
            secs = sorted(raytrace.render(scene, width=w, height=h, threads=t,
                                          pass_samples=samples).stats["seconds"]["total"]
                          for _ in range(repeat))
            rows.append({"scene": path.stem, "threads": t, "passes": passes,
                         "pass_samples": samples, "best": secs[0],
                         "median": secs[len(secs) // 2]})
            print(f"{path.stem:8s} threads {t:2d}  {passes:3d} passes of {samples:6d}: "
                  f"best {secs[0]:.3f} s, median {secs[len(secs) // 2]:.3f} s", flush=True)
    return rows


def small(threads: list[int], repeat: int) -> list[dict]:
    """Rows of ``--small``: each frame of :data:`SMALL_FRAMES` at each least pass size of
    :data:`SMALL_LEAST`."""
    cut, integrator.PASSES_PER_THREAD = integrator.PASSES_PER_THREAD, integrator.MIN_PASSES
    try:  # (16 passes, as from 8 threads up, whatever the threads here)
        return interleaved(SMALL_FRAMES, "MIN_PASS_SAMPLES", SMALL_LEAST, threads, repeat,
                           "least_pass_samples")
    finally:
        integrator.PASSES_PER_THREAD = cut


def per_thread(threads: list[int], repeat: int) -> list[dict]:
    """Rows of ``--per-thread``: each frame of :data:`PER_THREAD_FRAMES` at each count of
    :data:`PER_THREAD` passes a thread."""
    return interleaved(PER_THREAD_FRAMES, "PASSES_PER_THREAD", PER_THREAD, threads, repeat,
                       "passes_per_thread")


def interleaved(frames, setting: str, values: tuple[int, ...], threads: list[int],
                repeat: int, key: str) -> list[dict]:
    """Each frame rendered with each value of the integrator's ``setting`` in turn,
    ``repeat`` rounds: best and median wall seconds, and the median's ratio to the first
    value's (the setting put back after), the value under ``key`` in each row."""
    rows, default = [], getattr(integrator, setting)
    for name, w, h, spp in frames:
        scene = raytrace.load_scene(scene_path(name))
        for t in threads:
            raytrace.render(scene, width=w, height=h, spp=spp, threads=t)  # kernels loaded
            seconds = {value: [] for value in values}
            try:
                for _ in range(repeat):
                    for value in values:
                        setattr(integrator, setting, value)
                        t0 = time.perf_counter()
                        raytrace.render(scene, width=w, height=h, spp=spp, threads=t)
                        seconds[value].append(time.perf_counter() - t0)
            finally:
                setattr(integrator, setting, default)
            base = statistics.median(seconds[values[0]])
            for value, secs in seconds.items():
                median = statistics.median(secs)
                rows.append({"scene": name, "size": [w, h], "spp": spp, "threads": t,
                             key: value, "best": min(secs), "median": median,
                             "ratio": median / base})
                print(f"{name:10s} {w}x{h} {spp:2d} spp, threads {t}, {setting} {value:5d}: "
                      f"best {min(secs):.4f} s, median {median:.4f} s, "
                      f"{median / base:.3f} of {values[0]}'s", flush=True)
    return rows


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--threads", default="1,2", help="comma-separated thread counts")
    p.add_argument("--repeat", type=int, default=4)
    p.add_argument("--json", help="write the rows here")
    p.add_argument("--small", action="store_true", help="small frames by least pass size")
    p.add_argument("--per-thread", action="store_true",
                   help="frames of 16 to 64 least passes (18.75) by passes a thread")
    a = p.parse_args(argv)
    threads = [int(x) for x in a.threads.split(",")]
    malloc.tune()  # as the command line does
    if a.small:
        rows = small(threads, max(a.repeat, 5))
    elif a.per_thread:
        rows = per_thread(threads, max(a.repeat, 5))
    else:
        rows = large(threads, a.repeat)
    if a.json:
        Path(a.json).write_text(json.dumps({"machine": bench.machine(), "cores": os.cpu_count(),
                                            "rows": rows}, indent=2) + "\n")
    return 0


def large(threads: list[int], repeat: int) -> list[dict]:
    """Rows of the benchmark scenes of ``benchmarks/bench.py`` by pass count."""
    with tempfile.TemporaryDirectory(prefix="raytrace-passes-") as tmp:
        files = bench.scene_files(Path(tmp))
        return [r for name, path in files.items()
                for r in measure(path, bench.SIZES[name], threads, repeat)]


if __name__ == "__main__":
    raise SystemExit(main())
