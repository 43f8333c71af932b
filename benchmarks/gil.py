"""The share of a render's wall time spent holding the GIL, sampled by py-spy (issue 14).

    python3 -m pip install py-spy                     # the sampler (optional)
    python3 benchmarks/gil.py SCENE.toml --width 1000 --height 1000 --threads 2
    python3 benchmarks/bench.py --parts gil --threads 2      # both benchmark scenes

raytrace's threads render passes side by side, and only the Python between the compiled
kernels (numba ``nogil`` kernels and embreex's ``run``, which release the GIL) runs one thread
at a time: that share caps the speed-up on more cores (Amdahl). A probe process renders the
scene once (the kernels load), then renders it again and again for ``seconds``; py-spy
attaches to it and samples ``rate`` times a second with ``--gil`` (only the thread holding
the GIL is recorded: CPython 3.11 clears the current thread state when a thread releases it,
py-spy reads that state). The share is the samples over ``rate × seconds``, and the lines
that held it most are listed by the innermost raytrace frame of each sample (a kernel's call
line is numba's dispatch: typing and unboxing its arguments, with the GIL held).

What the share is not: time another thread spent *waiting* for the GIL; a thread descheduled
by the OS while holding the GIL counts as holding it, so a busy machine inflates the share
(say the load average beside it).
"""

from __future__ import annotations

import argparse
import collections
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent


def probe(scene_path: str, width: int, height: int, threads: int, seconds: float) -> None:
    """The sampled process: one render to load the kernels, ``READY <pid>``, a second's
    pause for the sampler to attach, then renders until ``seconds`` have passed."""
    import raytrace

    scene = raytrace.load_scene(scene_path)
    raytrace.render(scene, width=width, height=height, threads=threads)
    print("READY", os.getpid(), flush=True)
    time.sleep(1.0)
    t0, n = time.perf_counter(), 0
    while time.perf_counter() - t0 < seconds + 1.0:
        raytrace.render(scene, width=width, height=height, threads=threads)
        n += 1
    print("RENDERS", n, time.perf_counter() - t0, flush=True)


def available() -> str | None:
    """None where py-spy can sample, else why not."""
    return None if shutil.which("py-spy") else "py-spy not found (python3 -m pip install py-spy)"


def measure(scene_path: Path, width: int, height: int, threads: int, seconds: float = 6.0,
            rate: int = 200, top: int = 8) -> dict:
    """Sample a probe process rendering ``scene_path``; the GIL share and its top lines."""
    with tempfile.TemporaryDirectory(prefix="raytrace-gil-") as tmp:
        raw = Path(tmp) / "gil.txt"
        proc = subprocess.Popen(
            [sys.executable, str(Path(__file__).resolve()), "--probe", str(scene_path),
             "--width", str(width), "--height", str(height), "--threads", str(threads),
             "--seconds", str(seconds)], stdout=subprocess.PIPE, text=True)
        line = proc.stdout.readline()
        if not line.startswith("READY"):
            proc.kill()
            raise RuntimeError(f"the probe did not start: {line!r}")
        spy = subprocess.run(["py-spy", "record", "--pid", line.split()[1], "--gil",
                              "--threads", "-r", str(rate), "-d", str(int(seconds)), "-f",
                              "raw", "-o", str(raw)], capture_output=True, text=True)
        tail = proc.communicate()[0]
        if spy.returncode != 0 or not raw.exists():
            raise RuntimeError(f"py-spy failed: {spy.stderr.strip()[-500:]}")
        samples, by_line = 0, collections.Counter()
        for row in raw.read_text().splitlines():
            stack, count = row.rsplit(" ", 1)
            frames = stack.split(";")
            ours = [f for f in frames if "raytrace/" in f]
            samples += int(count)
            by_line[ours[-1] if ours else frames[-1]] += int(count)
    ticks = rate * int(seconds)
    renders = int(tail.split()[1]) if tail.startswith("RENDERS") else None
    errors = [ln for ln in spy.stderr.splitlines() if "behind" in ln or "Errors" in ln]
    return {"scene": Path(scene_path).stem, "width": width, "height": height,
            "threads": threads, "seconds": seconds, "rate": rate, "gil_samples": samples,
            "ticks": ticks, "gil_share": samples / ticks, "renders": renders,
            "top_lines": [[k, v / ticks] for k, v in by_line.most_common(top)],
            "sampler_notes": errors, "load_average": os.getloadavg()}


def amdahl(one: float, two: float, cores: int = 16) -> dict:
    """Amdahl's law from the 1- and 2-thread times: speed-up S = one/two on 2 threads gives
    the serial fraction s = 2/S − 1 (from S = 1/(s + (1 − s)/2)), which predicts
    1/(s + (1 − s)/N) on N cores (Amdahl 1967)."""
    speedup = one / two
    s = min(max(2.0 / speedup - 1.0, 0.0), 1.0)
    return {"speedup_2": speedup, "serial_fraction": s,
            f"predicted_speedup_{cores}": 1.0 / (s + (1.0 - s) / cores)}


def report(rows: list[dict]) -> str:
    out = []
    for r in rows:
        if "missing" in r:
            out.append(f"GIL share: skipped, {r['missing']}")
            continue
        lines = "; ".join(f"{k} {100 * v:.1f}%" for k, v in r["top_lines"][:5])
        out.append(f"GIL share: {r['scene']} {r['width']}x{r['height']}, {r['threads']} "
                   f"threads: {100 * r['gil_share']:.1f}% of wall time ({r['gil_samples']} of "
                   f"{r['ticks']} samples, {r['renders']} renders, load average "
                   f"{r['load_average'][0]:.2f}); most: {lines}")
    return "\n".join(out)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("scene")
    p.add_argument("--width", type=int, default=1000)
    p.add_argument("--height", type=int, default=1000)
    p.add_argument("--threads", type=int, default=2)
    p.add_argument("--seconds", type=float, default=6.0)
    p.add_argument("--probe", action="store_true", help=argparse.SUPPRESS)
    a = p.parse_args(argv)
    if a.probe:
        probe(a.scene, a.width, a.height, a.threads, a.seconds)
        return 0
    missing = available()
    row = {"missing": missing} if missing else measure(Path(a.scene), a.width, a.height,
                                                       a.threads, a.seconds)
    print(report([row]))
    return 0


if __name__ == "__main__":
    sys.exit(main())
