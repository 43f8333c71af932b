"""CPU seconds of warm one-thread renders of the two benchmark scenes, for comparing two
checkouts of raytrace side by side (run it once per checkout, alternating, on a quiet machine).

    PYTHONPATH=/path/to/checkout python3 benchmarks/paired.py

Prints the checkout's folder and, for the mesh frame (bench.py's 82k-triangle sphere on a
two-triangle ground, 1000²) and the Whitted scene (1280×960, depth 5), the fastest of five
renders in process CPU seconds (``time.process_time``: less sensitive than wall time to other
work on the machine). docs/performance.md quotes it.
"""

from __future__ import annotations

import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))

import bench  # noqa: E402

import raytrace  # noqa: E402


def _forget_bvh() -> None:
    """Empty the kept-BVH cache of a checkout that has one (raytrace.accel_cache)."""
    try:
        from raytrace import accel_cache
    except ImportError:
        return
    accel_cache.clear()


def main() -> None:
    work = Path(tempfile.mkdtemp())
    out = {}
    for name, path, (w, h) in (("mesh", bench.write_mesh_scene(work), (1000, 1000)),
                               ("whitted", bench.WHITTED, (1280, 960))):
        scene = raytrace.load_scene(path)
        raytrace.render(scene, width=64, height=64, threads=1)  # kernels loaded, not timed
        times = []
        for _ in range(5):
            _forget_bvh()  # both checkouts build it inside the timing
            t0 = time.process_time()
            raytrace.render(scene, width=w, height=h, threads=1)
            times.append(time.process_time() - t0)
        out[name] = min(times)
    print(Path(raytrace.__file__).parents[1].name,
          " ".join(f"{k} {v:.3f}" for k, v in out.items()), flush=True)


if __name__ == "__main__":
    main()
