"""CPU seconds of one compiled kernel over the calls of a warm one-thread frame, replayed in
isolation (no Embree, no Python between the kernels), for comparing two checkouts or two forms
of a kernel's arithmetic (docs/robustness.md, "Precision budget").

    PYTHONPATH=/path/to/checkout python3 benchmarks/replay.py SCENE KERNEL [KERNEL ...]

SCENE is ``mesh`` (bench.py's 82k-triangle sphere on a two-triangle ground, 1000²) or
``whitted`` (scenes/whitted.toml, 1280×960, depth 5); KERNEL a name in
:mod:`raytrace.kernels.accel` or :mod:`raytrace.kernels.shading` (``light_pass``,
``refine_hits``, ``hit_surfaces``, …). The frame is rendered once with every call's arguments
copied as they were passed (the scene's read-only records are shared), then each
kernel's calls are run again in order, best of seven, in ``time.process_time`` seconds. A
kernel that updates an argument in place (``refine_hits``' hits) replays on its own earlier
results; the time is then that of the same work. Whitted's ``light_pass`` and ``hit_terms``
together peak at 2.7 GB of memory, the mesh scene's three largest kernels at 0.75 GB. Run it
once per checkout, alternating, as benchmarks/paired.py.
"""

from __future__ import annotations

import copy
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))

import bench  # noqa: E402

import raytrace  # noqa: E402
from raytrace import accel, integrator  # noqa: E402
from raytrace.kernels import accel as accel_kernels  # noqa: E402
from raytrace.kernels import records  # noqa: E402
from raytrace.kernels import shading as shading_kernels  # noqa: E402

#: Kernels are wrapped from Python: the renders run the Python loop (the same kernels in the
#: same order as the compiled loop, tests/test_loop.py).
integrator.WhittedIntegrator.compiled = False
#: The scene's records, read-only once built: shared by the copies, not copied.
SHARED = (records.Scene, records.Shapes, records.Triangles, records.Materials)

SIZES = {"mesh": (1000, 1000), "whitted": (1280, 960)}


def capture(scene: raytrace.Scene, size: tuple[int, int], names: list[str]) -> dict:
    """Every call of the kernels ``names`` in a one-thread render of ``scene``, its arguments
    copied before the call (the scene's read-only records, :data:`SHARED`, are not copied)."""
    calls: dict[str, list] = {n: [] for n in names}
    saved = []
    for name in names:
        module = accel_kernels if hasattr(accel_kernels, name) else shading_kernels
        fn = getattr(module, name)

        def wrapped(*args, _fn=fn, _name=name):
            calls[_name].append((_fn, copy.deepcopy(args, _shared(args, {}))))
            return _fn(*args)

        for owner in (accel_kernels, shading_kernels, accel, integrator):
            if getattr(owner, name, None) is fn:
                saved.append((owner, name, fn))
                setattr(owner, name, wrapped)
    try:
        raytrace.render(scene, width=size[0], height=size[1], threads=1)
    finally:
        for owner, name, fn in saved:
            setattr(owner, name, fn)
    return calls


def _shared(value, memo: dict) -> dict:
    """``memo`` with every :data:`SHARED` record inside ``value`` mapped to itself."""
    if isinstance(value, SHARED):
        memo[id(value)] = value
    elif isinstance(value, tuple):
        for item in value:
            _shared(item, memo)
    return memo


def main() -> None:
    which, names = sys.argv[1], sys.argv[2:]
    path = (bench.write_mesh_scene(Path(tempfile.mkdtemp())) if which == "mesh"
            else bench.WHITTED)
    scene = raytrace.load_scene(path)
    raytrace.render(scene, width=64, height=64, threads=1)  # kernels loaded, not timed
    calls = capture(scene, SIZES[which], names)
    out = []
    for name in names:
        best = float("inf")
        for _ in range(7):
            t0 = time.process_time()
            for fn, args in calls[name]:
                fn(*args)
            best = min(best, time.process_time() - t0)
        out.append(f"{name} {1e3 * best:.1f} ms ({len(calls[name])} calls)")
    print(Path(raytrace.__file__).parents[1].name, which, "; ".join(out), flush=True)


if __name__ == "__main__":
    main()
