"""The serial fraction of a warm render, two ways (issue 14's Amdahl row), for one checkout.

    PYTHONPATH=/path/to/checkout python3 benchmarks/serial.py [--repeat 3]

For the Whitted scene (1280×960, depth 5) and the mesh frame (bench.py's 82k-triangle sphere,
1000²): (1) one thread's split of the render into compiled code (numba kernels and Embree's
``run``, which release the GIL) and the Python between them (:func:`bench.kernel_breakdown`,
the BVH build apart), the run with the least Python of ``repeat``; its share s predicts
1/(s + (1 − s)/16) on 16 cores (Amdahl 1967); (2) the warm 1- and 2-thread wall times, best
of ``repeat`` alternating, and the serial fraction their ratio implies
(:func:`gil.amdahl`), which needs a free second core (say the load average beside it).
Run it once per checkout, alternating, to compare two.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))

import bench  # noqa: E402
import gil  # noqa: E402

import raytrace  # noqa: E402


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--repeat", type=int, default=3)
    a = p.parse_args(argv)
    work = Path(tempfile.mkdtemp())
    rows = []
    for name, path, (w, h) in (("whitted", bench.WHITTED, (1280, 960)),
                               ("mesh", bench.write_mesh_scene(work), (1000, 1000))):
        split = min((bench.kernel_breakdown(path, w, h) for _ in range(a.repeat)),
                    key=lambda r: r["python_seconds"])
        traced = split["render_seconds"] - split["build_seconds"]
        share = split["python_seconds"] / traced
        scene = raytrace.load_scene(path)
        best = {1: float("inf"), 2: float("inf")}
        for _ in range(a.repeat):
            for threads in (1, 2):
                t0 = time.perf_counter()
                raytrace.render(scene, width=w, height=h, threads=threads)
                best[threads] = min(best[threads], time.perf_counter() - t0)
        law = gil.amdahl(best[1], best[2])
        rows.append(f"{name}: Python {1000 * split['python_seconds']:.1f} ms of "
                    f"{1000 * traced:.0f} ms ({100 * share:.1f} %, "
                    f"{sum(split['calls'].values())} kernel calls) → "
                    f"{1 / (share + (1 - share) / 16):.1f}× on 16 cores; warm 1 thread "
                    f"{best[1]:.3f} s, 2 threads {best[2]:.3f} s ({law['speedup_2']:.2f}×, "
                    f"serial {100 * law['serial_fraction']:.0f} % → "
                    f"{law['predicted_speedup_16']:.1f}×)")
    print(Path(raytrace.__file__).parents[1].name, f"(load average {os.getloadavg()[0]:.2f})")
    print("\n".join(rows), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
