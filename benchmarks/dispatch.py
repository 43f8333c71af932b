"""What numba's dispatch costs a render: every kernel called through its dispatcher against
the same kernels called through their compiled entry points (no argument typing).

    python3 benchmarks/dispatch.py scenes/whitted.toml --width 1280 --height 960

numba's dispatcher types every argument on every call (``typeof``, slower for the named
records the kernels take than for plain arrays) before it unboxes them and releases the GIL;
a compiled overload's ``entry_point`` only unboxes. Both variants render the scene on one
thread, alternating, ``pairs`` times ``best`` renders each; the process CPU seconds of the
fastest renders are printed. Only kernels with exactly one compiled signature are swapped
(all of them after a render, in this code).
"""

from __future__ import annotations

import argparse
import sys
import time


def main(argv: list[str] | None = None) -> int:
    import raytrace
    from raytrace import accel, analytic, camera, integrator, rays
    from raytrace.film import filters
    from raytrace.kernels import accel as accel_kernels
    from raytrace.kernels import shading as shading_kernels

    integrator.WhittedIntegrator.compiled = False  # kernels wrapped from Python: its loop
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("scene")
    p.add_argument("--width", type=int, default=1000)
    p.add_argument("--height", type=int, default=1000)
    p.add_argument("--pairs", type=int, default=3)
    p.add_argument("--best", type=int, default=2)
    a = p.parse_args(argv)
    scene = raytrace.load_scene(a.scene)
    raytrace.render(scene, width=a.width, height=a.height, threads=1)  # compiles/loads all

    owners = (accel_kernels, shading_kernels, camera, rays, filters, integrator, accel, analytic)
    swaps = []  # (owner, name, dispatcher, entry point)
    for module in (accel_kernels, shading_kernels, camera, rays, filters):
        for name, fn in list(vars(module).items()):
            if (getattr(fn, "__module__", None) != module.__name__
                    or len(getattr(fn, "overloads", ())) != 1):
                continue
            entry = next(iter(fn.overloads.values())).entry_point
            swaps += [(o, name, fn, entry) for o in owners if getattr(o, name, None) is fn]

    def cpu(use_entry: bool) -> float:
        for owner, name, fn, entry in swaps:
            setattr(owner, name, entry if use_entry else fn)
        best = []
        for _ in range(a.best):
            t0 = time.process_time()
            raytrace.render(scene, width=a.width, height=a.height, threads=1)
            best.append(time.process_time() - t0)
        return min(best)

    dispatcher, entry = [], []
    try:
        for _ in range(a.pairs):
            dispatcher.append(cpu(False))
            entry.append(cpu(True))
    finally:
        for owner, name, fn, _ in swaps:
            setattr(owner, name, fn)
    print(f"{len({s[1] for s in swaps})} kernels; process CPU seconds, one thread: dispatcher "
          f"{', '.join(f'{x:.3f}' for x in dispatcher)}; entry points "
          f"{', '.join(f'{x:.3f}' for x in entry)}; "
          f"{100 * (1 - min(entry) / min(dispatcher)):.1f} % less with entry points")
    return 0


if __name__ == "__main__":
    sys.exit(main())
