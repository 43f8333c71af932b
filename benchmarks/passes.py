"""Render seconds by thread count and pass size: what the pass size does to a many-core render.

    python3 benchmarks/passes.py --threads 1,2 --json benchmarks/passes.json

Each benchmark scene of ``benchmarks/bench.py`` (the 82k-triangle mesh at 1000², the Whitted
scene at 1280×960) is rendered in one process with its BVH kept (:mod:`raytrace.accel_cache`)
and its kernels loaded, at each thread count, with the image cut into 16, 32, 64 and 128
passes (``pass_samples`` = ⌈pixels / passes⌉; the integrator never cuts an image into fewer
than :data:`raytrace.integrator.MIN_PASSES` = 16, and by default into passes of at most
:data:`raytrace.integrator.PASS_SAMPLES` samples: 16 and 19 passes here): the best and the
median of ``--repeat`` renders' ``stats["seconds"]["total"]``. The image is the same for
every pass size (tests/test_threads.py), so only the time can differ: more passes balance the
threads more finely, and each pass costs the same Python between its kernel calls, which
holds the GIL.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

import bench  # noqa: E402

import raytrace  # noqa: E402
from raytrace import malloc  # noqa: E402

#: How many passes the image is cut into.
PASSES = (16, 32, 64, 128)


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


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--threads", default="1,2", help="comma-separated thread counts")
    p.add_argument("--repeat", type=int, default=4)
    p.add_argument("--json", help="write the rows here")
    a = p.parse_args(argv)
    threads = [int(x) for x in a.threads.split(",")]
    malloc.tune()  # as the command line does
    with tempfile.TemporaryDirectory(prefix="raytrace-passes-") as tmp:
        files = bench.scene_files(Path(tmp))
        rows = [r for name, path in files.items()
                for r in measure(path, bench.SIZES[name], threads, a.repeat)]
    if a.json:
        Path(a.json).write_text(json.dumps({"machine": bench.machine(), "cores": os.cpu_count(),
                                            "rows": rows}, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
