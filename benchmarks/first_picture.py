"""What the README picture's own sampling costs: the README's first render command
(``raytrace render scenes/whitted.toml -o … --png …``, kernels cached, a fresh process each)
on the scene as it stands against a copy of it with plain checkers (no ``filter``) at one
sample a pixel, alternating round by round so that a drift of the machine's load hits both
alike.

    python3 benchmarks/first_picture.py [--rounds 8] [--size 1280x960]

Prints each variant's median wall seconds, the difference (the issue's budget: at most 0.5 s
more than one plain sample) and the load average before and after. Results: docs/sampling.md,
"The Whitted scene's own sampling".
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from bench_scenes import WHITTED

ROOT = Path(__file__).resolve().parent.parent
SCENE = ROOT / "scenes" / "whitted.toml"


def run(scene: Path, out: Path, size: list[str]) -> float:
    """Wall seconds of one README command on ``scene`` in a fresh process (``size``: its
    ``--width``/``--height`` arguments, or none)."""
    cmd = [sys.executable, "-m", "raytrace", "render", str(scene), "-o", str(out / "w.exr"),
           "--png", str(out / "w.png"), "-q", *size]
    for f in out.glob("w.*"):
        f.unlink()
    t = time.perf_counter()
    subprocess.run(cmd, check=True, cwd=ROOT)
    return time.perf_counter() - t


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--rounds", type=int, default=8)
    ap.add_argument("--size", help="WxH in place of the scene's 640x480")
    args = ap.parse_args()
    size = []
    if args.size:
        w, h = args.size.lower().split("x")
        size = ["--width", w, "--height", h]
    load = os.getloadavg()[0]
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp)
        variants = {"the scene as it stands": SCENE, "plain checkers, 1 spp": WHITTED}
        times: dict[str, list[float]] = {name: [] for name in variants}
        for scene in variants.values():  # untimed: kernels compiled and cached
            run(scene, out, size)
        for _ in range(args.rounds):
            for name, scene in variants.items():
                times[name].append(run(scene, out, size))
    medians = {name: statistics.median(t) for name, t in times.items()}
    print("| command | median wall | runs |")
    print("|---|---|---|")
    for name, t in times.items():
        print(f"| {name} | {medians[name]:.2f} s | {' '.join(f'{x:.2f}' for x in t)} |")
    own, one = medians["the scene as it stands"], medians["plain checkers, 1 spp"]
    print(f"\nthe scene's own sampling costs {own - one:+.2f} s ({own / one:.2f}×); "
          f"load average {load:.2f} before, {os.getloadavg()[0]:.2f} after")


if __name__ == "__main__":
    main()
