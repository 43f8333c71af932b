"""Warm frames of two checkouts side by side: is a change (a refactor) any slower?

Each round renders the benchmark's mesh frame (1000², 82k triangles, 1 light) and the Whitted
frame (1280×960, depth 5) warm — in a fresh process per checkout, after one render that loads
every kernel and builds the BVH, the seconds of the next render with its BVH kept — alternating
the checkouts round by round so that a drift of the machine's load hits both alike. It prints
each checkout's median over the rounds and the ratio against the baseline, and checks the two
images are bit-identical.

    python3 benchmarks/warm_ab.py --baseline edaefca            # this tree against a ref
    python3 benchmarks/warm_ab.py --baseline edaefca --rounds 5 --threads 2 --size 0.5
    python3 benchmarks/warm_ab.py --baseline edaefca --rounds 3 --renders 7   # busy machine

``--baseline`` is exported with ``git archive`` into a temporary folder (its numba cache is
compiled by a first, untimed round).
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

from bench import SIZES, scene_files

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent

#: Run in each checkout: render each frame twice (the second warm, BVH kept) and print the
#: second's seconds and its image's SHA-256.
PROBE = """
import hashlib, json, sys, time
import raytrace
out = {{}}
for name, (path, size) in {frames!r}.items():
    scene = raytrace.load_scene(path)
    w, h = size
    raytrace.render(scene, width=w, height=h, threads={threads})
    best = float("inf")
    for _ in range({renders}):
        t0 = time.perf_counter()
        image = raytrace.render(scene, width=w, height=h, threads={threads})
        best = min(best, time.perf_counter() - t0)
    out[name] = [best, hashlib.sha256(image.rgb.tobytes()).hexdigest()[:16]]
print(json.dumps(out))
"""


def export(ref: str, folder: Path) -> Path:
    """``ref`` of this repository as a plain tree in ``folder`` (git archive)."""
    folder.mkdir(parents=True)
    archive = subprocess.run(["git", "archive", ref], cwd=ROOT, check=True,
                             capture_output=True).stdout
    subprocess.run(["tar", "-x", "-C", str(folder)], input=archive, check=True)
    return folder


def run(tree: Path, frames: dict, threads: int, renders: int = 1) -> dict:
    env = {**os.environ, "PYTHONPATH": str(tree)}
    code = PROBE.format(frames=frames, threads=threads, renders=renders)
    out = subprocess.run([sys.executable, "-c", code], env=env, cwd=tree, check=True,
                         capture_output=True, text=True).stdout
    return json.loads(out.strip().splitlines()[-1])


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--baseline", required=True, help="git ref to compare this tree against")
    p.add_argument("--rounds", type=int, default=5)
    p.add_argument("--threads", type=int, default=2)
    p.add_argument("--size", type=float, default=1.0, help="scale of the frames' sides")
    p.add_argument("--renders", type=int, default=1,
                   help="warm renders a process, the fastest kept (a busy machine's hiccups)")
    args = p.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        work = tmp / "scenes"
        work.mkdir()
        files = scene_files(work)
        frames = {name: (str(files[name]), tuple(round(s * args.size) for s in SIZES[name]))
                  for name in ("mesh", "whitted")}
        trees = {"baseline": export(args.baseline, tmp / "baseline"), "this tree": ROOT}
        for tree in trees.values():  # compile (or load) each tree's kernels, untimed
            run(tree, frames, args.threads)
        times = {k: {"mesh": [], "whitted": []} for k in trees}
        images = {}
        for _ in range(args.rounds):
            for label, tree in trees.items():
                for name, (seconds, digest) in run(tree, frames, args.threads,
                                                   args.renders).items():
                    times[label][name].append(seconds)
                    images.setdefault(name, {})[label] = digest
    load = os.getloadavg()[0]
    best = f"the best of {args.renders} renders a round, " if args.renders > 1 else ""
    print(f"warm frames, BVH kept, {args.threads} threads, size ×{args.size}, {best}median "
          f"of {args.rounds} interleaved rounds (load {load:.2f})\n")
    print(f"{'frame':10} {'baseline s':>11} {'this tree s':>12} {'ratio':>7}  same image")
    for name in ("mesh", "whitted"):
        base = statistics.median(times["baseline"][name])
        this = statistics.median(times["this tree"][name])
        same = len(set(images[name].values())) == 1
        print(f"{name:10} {base:11.4f} {this:12.4f} {this / base:7.3f}  {same}")
    print("\nrounds:", json.dumps(times))
    return 0


if __name__ == "__main__":
    sys.exit(main())
