"""What numba's dispatch costs a render: every kernel called through its dispatcher against
the same kernels called through their compiled entry points (no argument typing).

    python3 benchmarks/dispatch.py scenes/whitted.toml --width 1280 --height 960
    python3 benchmarks/dispatch.py scenes/mesh_model.toml --width 160 --height 120 \\
        --spp 16 --threads 2 --pairs 9
    python3 benchmarks/dispatch.py scenes/mesh_model.toml --width 160 --height 120 \
        --target-error 0.025 --threads 2 --pairs 9

numba's dispatcher types every argument on every call (a fingerprint of each array of the
named records the kernels take) before it unboxes them and releases the GIL, and it holds
the GIL while it does; a compiled overload's ``entry_point`` only unboxes. Both variants
render the scene on ``--threads`` threads, alternating, ``pairs`` times ``best`` renders
each; printed are the process CPU seconds and the wall seconds of the fastest renders, and
the medians of the pairs' wall seconds. Every kernel of the package with exactly one compiled
signature is swapped, wherever a module of the package holds it (all of them after a render,
in this code).
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time

import numba.core.registry

import raytrace
from raytrace import integrator, malloc


def main(argv: list[str] | None = None) -> int:
    integrator.WhittedIntegrator.compiled = False  # kernels wrapped from Python: its loop
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("scene")
    p.add_argument("--width", type=int, default=1000)
    p.add_argument("--height", type=int, default=1000)
    p.add_argument("--spp", type=int, default=1)
    p.add_argument("--threads", type=int, default=1)
    p.add_argument("--target-error", type=float,
                   help="render noise-driven to this relative RMSE instead of at --spp")
    p.add_argument("--pairs", type=int, default=3)
    p.add_argument("--best", type=int, default=2)
    a = p.parse_args(argv)
    malloc.tune()  # as the command line does
    scene = raytrace.load_scene(a.scene)
    kw = dict(width=a.width, height=a.height, threads=a.threads)
    kw.update(spp=a.spp) if a.target_error is None else kw.update(target_error=a.target_error)
    raytrace.render(scene, **kw)  # compiles/loads all

    modules = [m for name, m in sorted(sys.modules.items())
               if name == "raytrace" or name.startswith("raytrace.")]
    swaps = []  # (module, name, dispatcher, entry point)
    for module in modules:
        for name, fn in list(vars(module).items()):
            if (isinstance(fn, numba.core.registry.CPUDispatcher)
                    and fn.__module__.startswith("raytrace") and len(fn.overloads) == 1):
                swaps.append((module, name, fn, next(iter(fn.overloads.values())).entry_point))

    def timed(use_entry: bool) -> tuple[float, float]:
        for module, name, fn, entry in swaps:
            setattr(module, name, entry if use_entry else fn)
        wall, cpu = [], []
        for _ in range(a.best):
            t0, c0 = time.perf_counter(), time.process_time()
            raytrace.render(scene, **kw)
            wall.append(time.perf_counter() - t0)
            cpu.append(time.process_time() - c0)
        return min(wall), min(cpu)

    dispatcher, entry = [], []
    try:
        for _ in range(a.pairs):
            dispatcher.append(timed(False))
            entry.append(timed(True))
    finally:
        for module, name, fn, _ in swaps:
            setattr(module, name, fn)

    def line(runs: list[tuple[float, float]]) -> str:
        return (f"CPU {min(c for _, c in runs):.3f} s, wall {min(w for w, _ in runs):.3f} s "
                f"(median {statistics.median(w for w, _ in runs):.3f})")

    how = f"{a.spp} spp" if a.target_error is None else f"target error {a.target_error}"
    cpu = 1 - min(c for _, c in entry) / min(c for _, c in dispatcher)
    wall = 1 - (statistics.median(w for w, _ in entry)
                / statistics.median(w for w, _ in dispatcher))
    print(f"{len({s[2] for s in swaps})} kernels, {a.threads} thread(s), {a.width}x"
          f"{a.height} at {how}: dispatcher {line(dispatcher)}; entry points "
          f"{line(entry)}; {100 * cpu:.1f} % less CPU, {100 * wall:.1f} % less wall "
          "(medians) with entry points")
    return 0


if __name__ == "__main__":
    sys.exit(main())
