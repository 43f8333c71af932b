"""What a noise-driven round's allocation costs the main thread, against sorting its
candidates in numpy, on the renders' own inputs.

    python3 benchmarks/allocation.py                        # whitted, mesh_model; 160×120, 640×480
    python3 benchmarks/allocation.py --sizes 160x120 --repeats 50
    python3 benchmarks/allocation.py --cold                 # + the kernel's first compile

For each scene and size, a render by target error (``--target``, 2 threads) is run once
with :func:`raytrace.noise.neyman_counts` wrapped to keep the arguments of each allocation
between its rounds. Each allocation is then timed ``--repeats`` times, alternating between
the renderer's (numpy's ``argsort`` of σ, then the merge of per-count streams in
:func:`raytrace.kernels.noise.rank_doublings`) and the baseline, :func:`numpy_counts`: the
allocation of 9b6f263, its candidate doublings sorted in numpy by priority, then doubling,
then pixel. Both must give the same counts. Prints the medians (ms) and their ratio. The
allocator is set up as the ``raytrace`` command sets it (:func:`raytrace.malloc.tune`).

``--cold`` adds, in a fresh process with an empty kernel cache (``NUMBA_CACHE_DIR``), the
seconds of the first call of ``neyman_counts`` (compiling ``rank_doublings``) after
numba's own first compile, and of a second call; and numba's ``np.argsort`` of 8 000
values against numpy's, the reason the sort stays numpy's.
"""

from __future__ import annotations

import argparse
import math
import os
import subprocess
import sys
import tempfile
import time

import numpy as np
from bench_scenes import scene_path

import raytrace
from raytrace import malloc, noise


def descending(priority: np.ndarray, *ties: np.ndarray) -> np.ndarray:
    """The order of ``priority`` from highest to lowest, equal priorities in the order of the
    ``ties`` keys (the first first, each ascending): a stable sort, then a lexicographic sort
    of the runs of equal priority alone."""
    order = np.argsort(-priority, kind="stable")
    value = priority[order]
    same = value[1:] == value[:-1]
    if not same.any():
        return order
    member = np.zeros(len(value), bool)  # the runs of equal priority (no sort to find them)
    member[:-1] |= same
    member[1:] |= same
    members = np.flatnonzero(member)
    run = np.cumsum(np.concatenate([[1], np.diff(members) > 1]) |
                    np.concatenate([[False], value[members[1:]] != value[members[:-1]]]))
    keys = [key[order[members]] for key in reversed(ties)]
    order[members] = order[members][np.lexsort((*keys, run))]
    return order


def numpy_counts(n, variance, most, cols, share=noise.ROUND_SHARE, shrink=0.0, rate=1.0,
                 prior=math.inf):
    """:func:`raytrace.noise.neyman_counts` as 9b6f263 computed it, in numpy (σ̃ by
    :func:`raytrace.noise.ranking_sigma`): the first doublings ranked by ``np.argsort``, the
    candidates below the priority at which they alone reach the round's share left out, and
    the rest sorted by priority, then doubling, then pixel (:func:`descending`)."""
    s2, sigma = noise.ranking_sigma(n, variance, cols, prior)
    # each doubling's powers of its start m = n·2^j, per distinct count (the pixels' counts
    # take a few values) and doubling j, taken once each: ``cell`` = count·J + j
    present = np.bincount(n) > 0
    counts, kind = np.flatnonzero(present), (np.cumsum(present) - 1)[n]
    table = (counts[:, None] << np.arange(noise.MAX_DOUBLINGS)).astype(np.float64).ravel()
    scale = table ** (-0.5 * (1.0 + rate))
    open_ = np.flatnonzero((n < most) & (sigma > 0))
    first = sigma[open_] * scale[kind[open_] * noise.MAX_DOUBLINGS]
    order = np.argsort(-first)
    ranked, first = open_[order], first[order]
    goal = share * n.sum()
    # the first doublings alone reach the goal at priority ``floor``, so no doubling of
    # lower priority is taken: each doubling's candidates are those above it (a pixel's
    # priority falls by 2^(−j(1+β)/2) at its j-th; within a rounding, kept)
    cut = int(np.searchsorted(np.cumsum(np.minimum(2 * n[ranked], most) - n[ranked]), goal))
    floor = first[cut] * (1.0 - 1e-9) if cut < len(ranked) else 0.0
    runs = [ranked[:int(np.searchsorted(-first, -floor * 2.0 ** (0.5 * (1.0 + rate) * j),
                                        "right"))]
            for j in range(noise.MAX_DOUBLINGS)]
    runs = [r[(n[r] << j) < most] for j, r in enumerate(runs)]
    pixel = np.concatenate(runs)
    j = np.repeat(np.arange(noise.MAX_DOUBLINGS), [len(r) for r in runs])
    cell = kind[pixel] * noise.MAX_DOUBLINGS + j
    order = descending(sigma[pixel] * scale[cell], j, pixel)
    pixel, cell = pixel[order], cell[order]
    start = n[pixel] << j[order]
    added = np.cumsum(np.minimum(2 * start, most) - start)
    count = int(np.searchsorted(added, goal)) + 1
    if shrink > 0.0:  # each doubling's fall of the pixel's variance, s²·((2m)^−β − (2m')^−β)
        before = (2.0 * table) ** -rate
        fall = np.cumsum(s2[pixel[:count]] * (before - (2.0 * np.minimum(2 * table, most))
                                              ** -rate)[cell[:count]])
        total = (s2 * before[kind * noise.MAX_DOUBLINGS]).sum()
        enough = int(np.searchsorted(fall, (1.0 - shrink) * total))
        least = int(np.searchsorted(added, noise.MIN_ROUND_SHARE * n.sum())) + 1
        count = min(count, max(enough + 1, least))
    doublings = np.bincount(pixel[:count], minlength=len(n))
    return np.minimum(n << doublings, np.maximum(n, most))


def allocations(scene, size: tuple[int, int], target: float) -> list[tuple[tuple, dict]]:
    """The arguments of every allocation of a render of ``scene`` at ``size`` by ``target``."""
    kept, allocate = [], noise.neyman_counts

    def noted(*args, **kw):
        kept.append((args, kw))
        return allocate(*args, **kw)

    noise.neyman_counts = noted
    try:
        raytrace.render(scene, width=size[0], height=size[1], threads=2, target_error=target,
                        seed=3)
    finally:
        noise.neyman_counts = allocate
    return kept


def cold() -> str:
    """The first compile's seconds and the sorts' (module docstring), from a fresh process."""
    code = """
import time, numpy as np, numba
import raytrace.noise as noise
@numba.njit
def first(x): return x + 1
@numba.njit
def argsort(x): return np.argsort(x)
first(1)
n, v = np.array([2, 2, 4, 2], np.int64), np.array([1.0, 2.0, 0.5, 0.0])
t0 = time.perf_counter(); noise.neyman_counts(n, v, 16, 2, 1.0, 0.5, 1.5)
t1 = time.perf_counter(); noise.neyman_counts(n, v, 16, 2, 1.0, 0.5, 1.5)
t2 = time.perf_counter()
x = np.random.default_rng(0).random(8000); argsort(x)
sorts = []
for f in (argsort, np.argsort):
    t = time.perf_counter()
    for _ in range(200): f(x)
    sorts.append((time.perf_counter() - t) / 200 * 1e3)
print(f"empty kernel cache: neyman_counts' first call {t1 - t0:.2f} s (compiling "
      f"rank_doublings), its second {1e3 * (t2 - t1):.2f} ms; argsort of 8 000 values: "
      f"numba's {sorts[0]:.2f} ms, numpy's {sorts[1]:.2f} ms")
"""
    with tempfile.TemporaryDirectory(prefix="raytrace-cold-") as cache:
        env = dict(os.environ, NUMBA_CACHE_DIR=cache)
        return subprocess.run([sys.executable, "-c", code], env=env, check=True,
                              capture_output=True, text=True).stdout.strip()


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("--scenes", nargs="*", default=["whitted", "mesh_model"])
    p.add_argument("--sizes", nargs="*", default=["160x120", "640x480"])
    p.add_argument("--target", type=float, default=0.02)
    p.add_argument("--repeats", type=int, default=20)
    p.add_argument("--cold", action="store_true")
    a = p.parse_args()
    malloc.tune()  # as the command line does
    print(f"{'scene':<12}{'size':>9}{'allocations':>13}{'numpy ms':>10}{'merged ms':>11}"
          f"{'ratio':>8}")
    for name in a.scenes:
        scene = raytrace.load_scene(scene_path(name))
        for size in a.sizes:
            w, h = (int(v) for v in size.split("x"))
            kept = allocations(scene, (w, h), a.target)
            times = {"numpy": [], "merged": []}
            for _ in range(a.repeats):
                for label, f in (("numpy", numpy_counts), ("merged", noise.neyman_counts)):
                    for args, kw in kept:
                        t = time.perf_counter()
                        f(*args, **kw)
                        times[label].append(time.perf_counter() - t)
            for args, kw in kept:
                if not np.array_equal(numpy_counts(*args, **kw),
                                      noise.neyman_counts(*args, **kw)):
                    raise SystemExit(f"{name} {size}: the counts differ")
            ms = {k: 1e3 * float(np.median(v)) for k, v in times.items()}
            print(f"{name:<12}{size:>9}{len(kept):>13}{ms['numpy']:>10.2f}{ms['merged']:>11.2f}"
                  f"{ms['merged'] / ms['numpy']:>8.2f}")
    if a.cold:
        print(cold())


if __name__ == "__main__":
    main()
