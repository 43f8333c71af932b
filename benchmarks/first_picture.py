"""What the README picture's own sampling costs: the README's first render command
(``raytrace render scenes/whitted.toml -o … --png …``, kernels cached, a fresh process each)
at the scene's own samples a pixel against the same command with ``--spp 1``, alternating
round by round so that a drift of the machine's load hits both alike.

    python3 benchmarks/first_picture.py [--rounds 8]

Prints each variant's median wall seconds, the difference (the issue's budget: at most 0.5 s
more than one sample) and the load average before and after. Results: docs/sampling.md,
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

ROOT = Path(__file__).resolve().parent.parent
SCENE = ROOT / "scenes" / "whitted.toml"


def run(out: Path, extra: list[str]) -> float:
    """Wall seconds of one README command in a fresh process."""
    cmd = [sys.executable, "-m", "raytrace", "render", str(SCENE), "-o", str(out / "w.exr"),
           "--png", str(out / "w.png"), "-q", *extra]
    for f in out.glob("w.*"):
        f.unlink()
    t = time.perf_counter()
    subprocess.run(cmd, check=True, cwd=ROOT)
    return time.perf_counter() - t


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--rounds", type=int, default=8)
    args = ap.parse_args()
    variants = {"scene's own spp": [], "--spp 1": ["--spp", "1"]}
    times: dict[str, list[float]] = {name: [] for name in variants}
    load = os.getloadavg()[0]
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp)
        for extra in variants.values():  # untimed: kernels compiled and cached
            run(out, extra)
        for _ in range(args.rounds):
            for name, extra in variants.items():
                times[name].append(run(out, extra))
    medians = {name: statistics.median(t) for name, t in times.items()}
    print("| command | median wall | runs |")
    print("|---|---|---|")
    for name, t in times.items():
        print(f"| {name} | {medians[name]:.2f} s | {' '.join(f'{x:.2f}' for x in t)} |")
    own, one = medians["scene's own spp"], medians["--spp 1"]
    print(f"\nthe scene's own sampling costs {own - one:+.2f} s ({own / one:.2f}×); "
          f"load average {load:.2f} before, {os.getloadavg()[0]:.2f} after")


if __name__ == "__main__":
    main()
