"""Start-up, batches, a kept BVH and writes, against a baseline commit.

    python3 benchmarks/startup.py --baseline main          # every part but cold, ~2 min
    python3 benchmarks/startup.py --parts small,batch --repeat 7
    python3 benchmarks/startup.py --baseline main --cold   # also an empty numba cache
    python3 benchmarks/startup.py --baseline 12a033f --parts small,import,cold,warmup
                                                           # the start-up targets' rows

The baseline is a git ref of this repository, exported (``git archive``) to a temporary folder
and run from there with ``PYTHONPATH`` (its own numba cache, warmed by one untimed run), so
the same interpreter and libraries run both in one session. Runs alternate baseline, current,
baseline, current, ... and each row reports the best of ``--repeat`` of both: whole-process
wall seconds and CPU seconds (user + system of the child, from ``wait4``; steadier than wall
on a shared machine), and current / baseline.

Parts (``--parts``, comma-separated; default ``small,floor,batch,writes,compression,bvh``;
``--cold`` adds ``cold``; ``import`` and ``warmup`` run when named):

``small``
    ``raytrace render scenes/whitted.toml -o OUT.exr --width 64 --height 48 -q``.
``floor``
    What such a process cannot avoid (current code): ``python -c pass``, then importing numpy,
    numba, and loading numba's registries (lean, as the command line does, and all of them).
``batch``
    The same scene copied under 20 names, rendered by one ``raytrace render A.toml B.toml …
    --out-dir DIR --stats`` process: each scene's own seconds from loading it to its last file
    written (``--stats``' total), the first and the median and most of the 19 others, and the
    whole process. The baseline has no ``--out-dir``: its per-scene cost is a process a
    scene (``small``).
``writes``
    A fresh process renders a 4×3 image (numba's kernels and registries loaded, as in a
    command-line render), then writes a 4000×3000 image (the Whitted scene at 1000×750,
    tiled 4×4) as EXR (ZIP, 2 threads) and an 8-bit PNG preview: the seconds of the two
    writes, the part of ``--stats`` called ``write``.
``compression``
    The same 4000×3000 image written as EXR with each compression (2 threads, current code):
    seconds, size, and whether it reads back bit-identical.
``bvh``
    The 81 920-triangle mesh scene of ``benchmarks/bench.py`` at 1000×1000, rendered again
    in one process (current code only): the frame with its BVH kept, and with the build
    inside the frame (``raytrace.accel_cache.clear()`` before it), and the time to hash the
    geometry (:func:`raytrace.accel_cache.fingerprint`).
Every process runs as an installed package does, with Python's bytecode cached: the
caller's ``PYTHONDONTWRITEBYTECODE`` is dropped from the children's environment (with it,
each process compiles raytrace's modules afresh, 0.13 s; ``--keep-env`` keeps it).

``import``
    ``python3 -c "import raytrace"``, each tree.
``warmup``
    ``raytrace warmup -q`` of the shipped scenes from an empty ``NUMBA_CACHE_DIR`` (current
    code only), one process at a time and one a CPU; after each, the Whitted scene at 64×48
    in a fresh process on the cache it left (``small``'s command).
``cold``
    ``--cold-repeat`` rounds (default 2; the least wall of each is kept) in which a fresh
    process with an empty ``NUMBA_CACHE_DIR`` renders the diffuse scene
    (scenes/spotlights.toml) and the Whitted scene at 64×48: the wall seconds, and the
    compile seconds of each kernel (numba's ``numba:compile`` events; nested helpers inside
    their kernel), the five slowest listed, the kernels compiled, and the most signatures any
    kernel has.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from bench_scenes import WHITTED

ROOT = Path(__file__).resolve().parents[1]
DIFFUSE = ROOT / "scenes" / "spotlights.toml"
BATCH = 20
#: Keep the caller's PYTHONDONTWRITEBYTECODE (``--keep-env``).
KEEP_ENV = False
#: Rounds of the cold part (``--cold-repeat``).
COLD_ROUNDS = 2


def run(cmd: list[str], env: dict, cwd: Path) -> tuple[float, float, str]:
    """Run ``cmd``; return (wall seconds, child CPU seconds, stdout); raise if it fails."""
    with tempfile.TemporaryFile() as fo, tempfile.TemporaryFile() as fe:
        t0 = time.perf_counter()
        proc = subprocess.Popen(cmd, env=env, cwd=cwd, stdout=fo, stderr=fe,
                                stdin=subprocess.DEVNULL)
        _, status, usage = os.wait4(proc.pid, 0)
        wall = time.perf_counter() - t0
        fo.seek(0)
        fe.seek(0)
        out, err = fo.read().decode(), fe.read().decode()
    if os.waitstatus_to_exitcode(status) != 0:
        raise RuntimeError(f"{' '.join(map(str, cmd))} failed:\n{err[-2000:]}")
    return wall, usage.ru_utime + usage.ru_stime, out


class Tree:
    """A source tree to time: this checkout, or a git ref exported to a folder."""

    def __init__(self, name: str, path: Path):
        self.name, self.path = name, path
        self.env = {**os.environ, "PYTHONPATH": str(path)}
        self.env.pop("NUMBA_CACHE_DIR", None)
        # As an installed package runs: Python's bytecode cached (pip compiles it at install;
        # a checkout writes it on first import). With PYTHONDONTWRITEBYTECODE set, every
        # process compiles raytrace's 35 modules afresh (0.13 s; --keep-env measures that).
        if not KEEP_ENV:
            self.env.pop("PYTHONDONTWRITEBYTECODE", None)

    def python(self, *args: str) -> list[str]:
        return [sys.executable, *args]

    def render(self, *args) -> list[str]:
        return self.python("-m", "raytrace", "render", *map(str, args), "-q")


def export(ref: str, folder: Path) -> Tree:
    """``ref`` of this repository as plain files in ``folder``."""
    folder.mkdir()
    archive = subprocess.run(["git", "-C", str(ROOT), "archive", ref], check=True,
                             capture_output=True).stdout
    subprocess.run(["tar", "-x", "-C", str(folder)], input=archive, check=True)
    return Tree(ref, folder)


def best(trees: list[Tree], repeat: int, make_cmd, work: Path) -> dict[str, dict]:
    """Alternate the trees ``repeat`` times; the best wall and CPU of each."""
    rows = {t.name: {"wall": [], "cpu": []} for t in trees}
    for _ in range(repeat):
        for t in trees:
            wall, cpu, _ = run(make_cmd(t), t.env, work)
            rows[t.name]["wall"].append(wall)
            rows[t.name]["cpu"].append(cpu)
    return {k: {"wall": min(v["wall"]), "cpu": min(v["cpu"]), "walls": v["wall"]}
            for k, v in rows.items()}


def part_small(trees, repeat, work) -> dict:
    return best(trees, repeat, lambda t: t.render(WHITTED, "-o", work / f"{id(t)}.exr",
                                                  "--width", 64, "--height", 48), work)


#: What a command-line render cannot avoid, step by step (each a fresh process).
FLOOR = {"python": "pass", "+ numpy": "import numpy",
         "+ numba": "import numpy, numba",
         "+ registries, lean (CLI)":
             "from raytrace.kernels import compile as c; c.load_registries(True)",
         "+ registries, all (API)": "import raytrace.kernels.compile as c; c.load_registries()"}


def part_floor(trees, repeat, work) -> dict:
    current = next(t for t in trees if t.name == "current")
    return {label: best([current], repeat, lambda t, c=code: t.python("-c", c), work)["current"]
            for label, code in FLOOR.items()}


def part_batch(trees, repeat, work) -> dict:
    scenes = work / "batch"
    scenes.mkdir(exist_ok=True)
    names = [scenes / f"w{i:02d}.toml" for i in range(BATCH)]
    for n in names:
        shutil.copy(WHITTED, n)
    out = work / "batch_out"
    out.mkdir(exist_ok=True)
    current = [t for t in trees if t.name == "current"]
    size = ["--width", 64, "--height", 48, "--stats"]
    many = best(current, repeat, lambda t: t.render(*names, "--out-dir", out, *size), work)
    # Each scene's own seconds, from loading it to its last file written (--stats' total),
    # in the last batch run: the first scene pays numba's set-up, the others not.
    totals = [json.loads((out / f"{n.stem}.json").read_text())["seconds"]["total"]
              for n in names]
    later = sorted(totals[1:])
    return {"scenes": BATCH, "many": many["current"], "first_scene": totals[0],
            "per_scene_median": later[len(later) // 2], "per_scene_max": later[-1]}


WRITE_PROBE = """
import sys, time, numpy as np, raytrace
from raytrace.film import write_exr, write_png
raytrace.render(raytrace.load_scene(sys.argv[1]), width=4, height=3)  # kernels loaded
rgb = np.load(sys.argv[2])
t0 = time.perf_counter(); c0 = time.process_time()
write_exr(sys.argv[3] + ".exr", rgb, {}, 2, "zip")
t1 = time.perf_counter(); c1 = time.process_time()
write_png(sys.argv[3] + ".png", rgb)
t2 = time.perf_counter(); c2 = time.process_time()
print(t1 - t0, c1 - c0, t2 - t1, c2 - c1)
"""


def big_image(tree: Tree, work: Path) -> Path:
    """The 4000×3000 test image: the Whitted scene at 1000×750, tiled 4×4 (.npy)."""
    image = work / "big.npy"
    if not image.exists():
        code = ("import sys, numpy as np, raytrace; im = raytrace.render(raytrace.load_scene("
                "sys.argv[1]), width=1000, height=750); np.save(sys.argv[2], "
                "np.tile(im.rgb, (4, 4, 1)))")
        run([sys.executable, "-c", code, str(WHITTED), str(image)], tree.env, work)
    return image


def part_writes(trees, repeat, work) -> dict:
    image = big_image(trees[-1], work)
    rows = {t.name: [] for t in trees}
    for _ in range(repeat):
        for t in trees:
            _, _, out = run([sys.executable, "-c", WRITE_PROBE, str(WHITTED), str(image),
                             str(work / f"w_{t.name.replace('/', '_')}")], t.env, work)
            rows[t.name].append([float(x) for x in out.split()])
    result = {}
    for name, runs in rows.items():
        exr = min(r[0] for r in runs)
        png = min(r[2] for r in runs)
        result[name] = {"exr_wall": exr, "exr_cpu": min(r[1] for r in runs), "png_wall": png,
                        "png_cpu": min(r[3] for r in runs), "wall": min(r[0] + r[2] for r in runs),
                        "cpu": min(r[1] + r[3] for r in runs)}
    return result


COMPRESSION_PROBE = """
import os, sys, time, json, numpy as np, raytrace
from raytrace.film import EXR_COMPRESSIONS, exr_compression, write_exr
rgb = np.load(sys.argv[1])
out = {}
for name in EXR_COMPRESSIONS:
    try:
        exr_compression(name)
    except ValueError:
        continue
    runs = []
    for _ in range(int(sys.argv[3])):
        t, c = time.perf_counter(), time.process_time()
        write_exr(sys.argv[2], rgb, {}, 2, name)
        runs.append((time.perf_counter() - t, time.process_time() - c))
    back = raytrace.read_exr(sys.argv[2])[0]
    out[name] = {"wall": min(runs)[0], "cpu": min(r[1] for r in runs),
                 "mb": os.path.getsize(sys.argv[2]) / 1e6,
                 "lossless": bool(np.array_equal(back, rgb))}
print(json.dumps(out))
"""


def part_compression(trees, repeat, work) -> dict:
    current = next(t for t in trees if t.name == "current")
    _, _, out = run([sys.executable, "-c", COMPRESSION_PROBE, str(big_image(current, work)),
                     str(work / "c.exr"), str(repeat)], current.env, work)
    return json.loads(out)


BVH_PROBE = """
import sys, time, json, raytrace, raytrace.integrator
from raytrace import accel_cache
from raytrace.rendering import render_options
scene = raytrace.load_scene(sys.argv[1])
raytrace.render(scene, width=1000, height=1000, threads=2)  # kernels loaded, BVH built
kept, built = [], []
for _ in range(int(sys.argv[2])):
    t, c = time.perf_counter(), time.process_time()
    raytrace.render(scene, width=1000, height=1000, threads=2)
    kept.append((time.perf_counter() - t, time.process_time() - c))
    accel_cache.clear()
    t, c = time.perf_counter(), time.process_time()
    raytrace.render(scene, width=1000, height=1000, threads=2)
    built.append((time.perf_counter() - t, time.process_time() - c))
materials = raytrace.integrator.WhittedIntegrator(
    scene, render_options(scene)).materials
hashes = []
for _ in range(20):
    t = time.perf_counter(); accel_cache.fingerprint(scene, materials)
    hashes.append(time.perf_counter() - t)
print(json.dumps({"kept": min(kept)[0], "built": min(built)[0], "kept_cpu": min(kept)[1],
                  "built_cpu": min(built)[1], "builds": accel_cache.builds,
                  "fingerprint_seconds": sorted(hashes)[len(hashes) // 2]}))
"""


def part_bvh(trees, repeat, work) -> dict:
    sys.path.insert(0, str(ROOT / "benchmarks"))
    import bench

    scene = bench.write_mesh_scene(work)
    current = next(t for t in trees if t.name == "current")
    _, _, out = run([sys.executable, "-c", BVH_PROBE, str(scene), str(repeat)], current.env,
                    work)
    return json.loads(out)


COLD_PROBE = """
import sys, time, json
from numba.core import event
t0 = time.perf_counter()
open_, done = {}, []
class Timer(event.Listener):
    def on_start(self, ev):
        open_[id(ev.data["dispatcher"])] = (time.perf_counter(), len(open_))
    def on_end(self, ev):
        start, depth = open_.pop(id(ev.data["dispatcher"]))
        d = ev.data["dispatcher"]
        done.append((d.py_func.__module__.split(".")[-1] + "." + d.py_func.__name__,
                     time.perf_counter() - start, depth))
event.register("numba:compile", Timer())
import raytrace
raytrace.render(raytrace.load_scene(sys.argv[1]), width=64, height=48, threads=1)
top = sorted((d for d in done if d[2] == 0), key=lambda d: -d[1])
from numba.core.dispatcher import Dispatcher
signatures = {f"{m.__name__}.{k}": len(v.signatures) for m in list(sys.modules.values())
              if getattr(m, "__name__", "").startswith("raytrace.")
              for k, v in vars(m).items() if isinstance(v, Dispatcher) and v.signatures
              and v.py_func.__module__ == m.__name__}
print(json.dumps({"wall": time.perf_counter() - t0, "kernels": len(top),
                  "compile": sum(d[1] for d in top), "slowest": top[:5],
                  "compiled": sorted(d[0] for d in top),
                  "most_signatures": max(signatures.values())}))
"""


def part_cold(trees, repeat, work) -> dict:
    """Each tree's first render of each scene from an empty cache folder, :data:`COLD_ROUNDS`
    rounds alternating the trees: the round with the least process wall time."""
    result = {}
    for _ in range(COLD_ROUNDS):
        for label, scene in (("diffuse", DIFFUSE), ("whitted", WHITTED)):
            for t in trees:
                cache = Path(tempfile.mkdtemp(dir=work))
                env = {**t.env, "NUMBA_CACHE_DIR": str(cache)}
                wall, cpu, out = run([sys.executable, "-c", COLD_PROBE, str(scene)], env, work)
                shutil.rmtree(cache)
                key = f"{t.name} {label}"
                walls = result.get(key, {}).get("walls", []) + [wall]
                if wall <= min(walls):
                    result[key] = {**json.loads(out), "process_wall": wall, "cpu": cpu}
                result[key]["walls"] = walls
    return result


def part_import(trees, repeat, work) -> dict:
    """``python3 -c "import raytrace"``, best of ``repeat`` for each tree."""
    return best(trees, repeat, lambda t: t.python("-c", "import raytrace"), work)


def part_warmup(trees, repeat, work) -> dict:
    """``raytrace warmup`` of the shipped scenes from an empty cache folder (current tree
    only), with one process at a time and with one a CPU, then the Whitted scene's 64×48
    render in a fresh process on the cache it left."""
    current = next(t for t in trees if t.name == "current")
    jobs = len(os.sched_getaffinity(0))
    result = {"jobs": jobs}
    for n in sorted({1, jobs}):
        cache = Path(tempfile.mkdtemp(dir=work))
        env = {**current.env, "NUMBA_CACHE_DIR": str(cache)}
        wall, cpu, _ = run(current.python("-m", "raytrace", "warmup", "--jobs", str(n), "-q"),
                           env, work)
        after = best([current], repeat, lambda t: t.render(
            WHITTED, "-o", work / "after.exr", "--width", 64, "--height", 48), work)
        result[f"jobs {n}"] = {"wall": wall, "cpu": cpu, "render_after": after["current"]}
        shutil.rmtree(cache)
    return result


def table(results: dict, baseline: str | None) -> str:
    """The printed table: one row per measure, current, baseline and their ratio."""
    lines = [f"{'measure':48s} {'current':>12s} {'baseline':>16s} {'ratio':>7s}"]

    def row(label, cur, base=None):
        ratio = f"{cur / base:7.2f}" if base else ""
        b = f"{base:16.3f}" if base is not None else f"{'':16s}"
        lines.append(f"{label:48s} {cur:12.3f} {b} {ratio}")

    for key in ("wall", "cpu"):
        if "small" in results:
            r = results["small"]
            row(f"small 64x48 to EXR, process {key} s", r["current"][key],
                r[baseline][key] if baseline else None)
    if "floor" in results:
        for label, r in results["floor"].items():
            row(f"  floor: {label}, CPU s", r["cpu"])
    if "batch" in results:
        r = results["batch"]
        small = results.get("small", {}).get(baseline, {}) if baseline else {}
        row(f"batch of {r['scenes']}: a scene after the 1st, median s", r["per_scene_median"],
            small.get("wall"))
        row(f"batch of {r['scenes']}: a scene after the 1st, most s", r["per_scene_max"])
        row(f"batch of {r['scenes']}: the first scene, s", r["first_scene"])
        row(f"batch of {r['scenes']}: the process, wall s", r["many"]["wall"])
        row(f"batch of {r['scenes']}: the process, CPU s", r["many"]["cpu"])
    if "writes" in results:
        r = results["writes"]
        for key, label in (("wall", "write 4000x3000 EXR+PNG, wall s"),
                           ("cpu", "write 4000x3000 EXR+PNG, CPU s"),
                           ("exr_wall", "  EXR alone (ZIP, 2 threads), wall s"),
                           ("png_wall", "  PNG preview alone, wall s")):
            row(label, r["current"][key], r[baseline][key] if baseline else None)
    if "compression" in results:
        for name, r in results["compression"].items():
            lines.append(f"EXR {name:5s} 4000x3000: {r['wall']:.3f} s wall, {r['cpu']:.3f} s CPU, "
                         f"{r['mb']:.1f} MB, reads back identical: {r['lossless']}")
    if "bvh" in results:
        r = results["bvh"]
        row("mesh 1000^2 again, BVH kept / built, wall s", r["kept"], r["built"])
        row("mesh 1000^2 again, BVH kept / built, CPU s", r["kept_cpu"], r["built_cpu"])
        row("  its fingerprint (median of 20), s", r["fingerprint_seconds"])
    if "import" in results:
        r = results["import"]
        row("python3 -c 'import raytrace', wall s", r["current"]["wall"],
            r[baseline]["wall"] if baseline else None)
    if "warmup" in results:
        r = results["warmup"]
        for name, w in r.items():
            if name == "jobs":
                continue
            row(f"raytrace warmup, shipped scenes, {name}, wall s", w["wall"])
            row("  then Whitted 64x48, fresh process, wall s", w["render_after"]["wall"])
    if "cold" in results:
        for name, r in results["cold"].items():
            base_key = name.replace("current", baseline) if baseline else None
            base = results["cold"].get(base_key, {}).get("process_wall") \
                if base_key and name.startswith("current") else None
            row(f"cold cache {name}, process wall s", r["process_wall"], base)
            row(f"  compile s ({r['kernels']} kernels, <= {r['most_signatures']} signature)",
                r["compile"])
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--baseline", help="git ref to compare with (e.g. main)")
    p.add_argument("--parts", default="small,floor,batch,writes,compression,bvh")
    p.add_argument("--cold", action="store_true", help="also time an empty numba cache")
    p.add_argument("--repeat", type=int, default=5)
    p.add_argument("--cold-repeat", type=int, default=2,
                   help="rounds of the cold part (each compiles every kernel: 15-60 s)")
    p.add_argument("--json", help="write the results here as JSON")
    p.add_argument("--keep-env", action="store_true",
                   help="keep PYTHONDONTWRITEBYTECODE (compile every module in every process)")
    args = p.parse_args(argv)
    global KEEP_ENV, COLD_ROUNDS
    KEEP_ENV, COLD_ROUNDS = args.keep_env, args.cold_repeat
    parts = args.parts.split(",") + (["cold"] if args.cold else [])
    with tempfile.TemporaryDirectory(prefix="raytrace-startup-") as tmp:
        work = Path(tmp)
        trees = [Tree("current", ROOT)]
        if args.baseline:
            trees.insert(0, export(args.baseline, work / "baseline"))
            trees[0].name = args.baseline
            run(trees[0].render(WHITTED, "-o", work / "warm.exr", "--width", 8, "--height", 6,
                                "--png", work / "warm.png"), trees[0].env, work)
        run(trees[-1].render(WHITTED, "-o", work / "warm.exr", "--width", 8, "--height", 6,
                             "--png", work / "warm.png"), trees[-1].env, work)
        load = os.getloadavg()
        results: dict = {"load_average": load, "baseline": args.baseline,
                         "repeat": args.repeat, "keep_env": args.keep_env}
        funcs = {"floor": part_floor, "small": part_small, "batch": part_batch,
                 "writes": part_writes,
                 "compression": part_compression, "bvh": part_bvh, "cold": part_cold,
                 "import": part_import, "warmup": part_warmup}
        for part in parts:
            results[part] = funcs[part](trees, args.repeat, work)
        results["load_average_after"] = os.getloadavg()
    print(f"load average {load[0]:.2f} before, {results['load_average_after'][0]:.2f} after; "
          f"best of {args.repeat}")
    print(table(results, args.baseline))
    if args.json:
        Path(args.json).write_text(json.dumps(results, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
