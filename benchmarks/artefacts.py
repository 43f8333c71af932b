"""How many rays the float32-artefact rule of raytrace.accel costs, per scene.

Counts, in one-thread renders, the rays Embree is asked about, the rays whose hit the float64
re-solve showed to be a float32 artefact (traced again from past the triangle's error band,
``accel_kernels.refine_hits``) and the blocked shadow rays asked again as closest-hit queries
(``accel_kernels.occlusion``). docs/robustness.md quotes the table.

    python benchmarks/artefacts.py
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))

import bench  # noqa: E402

import raytrace  # noqa: E402
import raytrace.kernels.accel as K  # noqa: E402
from raytrace.integrator import WhittedIntegrator  # noqa: E402

#: The kernels are wrapped from Python, so the renders run the Python loop (the same kernels
#: in the same order as the compiled loop, tests/test_loop.py).
WhittedIntegrator.compiled = False
counts = {"embree": 0, "artefacts": 0, "rechecks": 0}
_refine, _occlusion = K.refine_hits, K.occlusion


def refine_hits(embree, traced, *rest):
    k = _refine(embree, traced, *rest)
    if len(traced.rows) == 0:  # a first pass: every ray of the query
        counts["embree"] += len(embree.geom_id)
    counts["artefacts"] += k
    return k


def occlusion(idx, result, *rest):
    k = _occlusion(idx, result, *rest)
    counts["embree"] += len(idx)
    counts["rechecks"] += k
    return k


def main() -> None:
    K.refine_hits, K.occlusion = refine_hits, occlusion  # accel calls them through K
    work = Path(tempfile.mkdtemp())
    scenes = {"mesh (bench.py)": (bench.write_mesh_scene(work), (1000, 1000))}
    for path in sorted((ROOT / "scenes").glob("*.toml")):
        scenes[path.stem] = (path, (320, 240))
    print(f"{'scene':18s} {'size':>9s} {'Embree rays':>12s} {'artefacts':>10s} {'rechecks':>9s}")
    for name, (path, (w, h)) in scenes.items():
        for key in counts:
            counts[key] = 0
        raytrace.render(raytrace.load_scene(path), width=w, height=h, threads=1)
        print(f"{name:18s} {w:>4d}x{h:<4d} {counts['embree']:>12d} {counts['artefacts']:>10d} "
              f"{counts['rechecks']:>9d}")


if __name__ == "__main__":
    main()
