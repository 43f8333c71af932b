"""Mitsuba 3 as a second peer: the mesh scene's warm frame, side by side with raytrace's.

    python3 -m pip install mitsuba && apt-get install -y libllvm19   # the peer (optional)
    python3 benchmarks/mitsuba_peer.py --threads 2
    python3 benchmarks/bench.py --parts mitsuba --threads 2          # the same, in its JSON

The benchmark's mesh scene (:data:`bench.MESH_SCENE`: the 81 920-triangle sphere from its
PLY file, the 40×40 ground, one point light at (4, 6, 5), the camera at (0, 1.4, 4.2) looking
at (0, 0.9, 0) with a vertical field of view of 40°, 1000×1000) in Mitsuba's variant
``llvm_ad_rgb`` with its ``direct`` integrator, one emitter sample and no BSDF sample per
hit (one shadow ray a hit, as raytrace), a box filter and one sample a pixel. Both surfaces
are ``diffuse`` (Mitsuba has no Phong model; raytrace's brass highlight costs it a few
multiplications a hit). Mitsuba's ``mi.load_dict`` builds its Embree BVH once; a render
traces the frame's rays as wavefronts of packets through Embree (/work/shared/EMBREEX_NOTES.md;
embreex calls Embree one ray at a time), in kernels Dr.Jit compiles to LLVM on the first
render and keeps in memory.

Reported, in one run: Mitsuba's load (BVH build included), its first render (kernel
compilation included) and its best warm render out of ``repeat``, in a process of its own
(:func:`in_child`: where libLLVM is missing, Mitsuba's ``llvm`` variant aborts the whole
process, seen here before ``apt-get install libllvm19``; a child's abort ends the peer
measurement, not the caller's run); raytrace's best warm render of the same scene
in this process (kernels loaded, BVH kept) and the part of it without the build (the
``--stats`` ``build`` seconds taken out).
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import subprocess
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

VARIANT = "llvm_ad_rgb"


def available() -> str | None:
    """None where Mitsuba 3 and its LLVM variant can run, else why not (one line)."""
    if importlib.util.find_spec("mitsuba") is None:
        return "mitsuba not installed (python3 -m pip install mitsuba)"
    try:
        import mitsuba as mi

        mi.set_variant(VARIANT)
    except Exception as e:  # no libLLVM: Dr.Jit raises on the variant
        return (f"mitsuba's {VARIANT} variant unavailable ({type(e).__name__}: "
                f"{str(e).splitlines()[0] if str(e) else ''}; apt-get install libllvm19)")
    return None


def scene_dict(ply: Path, width: int, height: int) -> dict:
    """The mesh scene as a Mitsuba scene dictionary (see the module docstring)."""
    import mitsuba as mi

    mi.set_variant(VARIANT)
    T = mi.ScalarTransform4f
    diffuse = {"type": "diffuse", "reflectance": {"type": "rgb", "value": 0.7}}
    return {
        "type": "scene",
        "integrator": {"type": "direct", "emitter_samples": 1, "bsdf_samples": 0},
        "sensor": {"type": "perspective", "fov": 40.0, "fov_axis": "y",
                   "to_world": T().look_at(origin=[0, 1.4, 4.2], target=[0, 0.9, 0],
                                           up=[0, 1, 0]),
                   "film": {"type": "hdrfilm", "width": width, "height": height,
                            "rfilter": {"type": "box"}},
                   "sampler": {"type": "independent", "sample_count": 1}},
        "sphere": {"type": "ply", "filename": str(ply), "to_world": T().translate([0, 1, 0]),
                   "bsdf": diffuse},
        "ground": {"type": "rectangle", "to_world": T().rotate([1, 0, 0], -90).scale(20),
                   "bsdf": diffuse},
        "light": {"type": "point", "position": [4.0, 6.0, 5.0],
                  "intensity": {"type": "rgb", "value": 1.0}},
    }


def mitsuba_frame(ply: Path, width: int, height: int, threads: int, repeat: int = 3,
                  png: Path | None = None) -> dict:
    """Mitsuba's load, first render and best warm render of the mesh scene (wall seconds)."""
    import drjit as dr
    import mitsuba as mi

    mi.set_variant(VARIANT)
    dr.set_thread_count(threads)
    t0 = time.perf_counter()
    scene = mi.load_dict(scene_dict(Path(ply), width, height))
    load = time.perf_counter() - t0

    def frame() -> float:
        t = time.perf_counter()
        image = mi.render(scene, spp=1)
        dr.eval(image)
        dr.sync_thread()
        frame.image = image
        return time.perf_counter() - t

    first = frame()
    warm = min(frame() for _ in range(max(1, repeat)))
    if png is not None:
        mi.util.write_bitmap(str(png), frame.image)
    return {"variant": VARIANT, "version": mi.__version__, "threads": threads,
            "load_seconds": load, "first_render_seconds": first, "warm_seconds": warm}


def in_child(function: str, *args) -> dict:
    """``function(*args)`` of this module run in a fresh Python process (arguments and result
    through JSON; paths as strings)."""
    code = (f"import json, sys; sys.path.insert(0, {str(HERE)!r}); import mitsuba_peer; "
            f"print(json.dumps(mitsuba_peer.{function}(*json.loads(sys.argv[1]))))")
    out = subprocess.run([sys.executable, "-c", code, json.dumps([str(a) if isinstance(a, Path)
                                                                  else a for a in args])],
                         capture_output=True, text=True, check=True).stdout
    return json.loads(out.strip().splitlines()[-1])


def mitsuba_images(ply: str, width: int, height: int, out: str) -> dict:
    """Mitsuba's 16-spp image and depth AOV of the mesh scene, saved to ``out`` (.npz):
    for :func:`in_child`."""
    import mitsuba as mi
    import numpy as np

    mi.set_variant(VARIANT)
    spec = scene_dict(Path(ply), width, height)
    image = np.array(mi.render(mi.load_dict(spec), spp=16), dtype=np.float64)
    spec["integrator"] = {"type": "aov", "aovs": "d:depth"}
    depth = np.array(mi.render(mi.load_dict(spec), spp=16), dtype=np.float64)[..., 0]
    np.savez(out, image=image, depth=depth)
    return {"out": out}


def raytrace_frame(scene_path: Path, width: int, height: int, threads: int,
                   repeat: int = 3) -> dict:
    """raytrace's best warm render of the same scene in this process, and its build part."""
    import raytrace

    scene = raytrace.load_scene(scene_path)
    raytrace.render(scene, width=64, height=64, threads=threads)  # loads the kernels
    runs = [raytrace.render(scene, width=width, height=height, threads=threads).stats
            for _ in range(max(1, repeat))]
    best = min(runs, key=lambda s: s["seconds"]["total"])
    sec = best["seconds"]
    return {"warm_seconds": sec["total"], "build_seconds": sec["build"],
            "without_build_seconds": sec["total"] - sec["build"],
            "rays": best["rays"]["total"]}


def compare(workdir: Path, threads: int, quick: bool = False, repeat: int = 3) -> dict:
    """Both frames of the mesh scene, Mitsuba first (its threads idle afterwards)."""
    from bench import QUICK_SIZES, SIZES, write_mesh_scene

    w, h = (QUICK_SIZES if quick else SIZES)["mesh"]
    missing = available()
    if missing:
        return {"missing": missing}
    workdir.mkdir(parents=True, exist_ok=True)
    scene_path = write_mesh_scene(workdir)
    try:
        mit = in_child("mitsuba_frame", workdir / "sphere.ply", w, h, threads, repeat)
    except subprocess.CalledProcessError as e:  # e.g. its llvm variant without libLLVM
        return {"missing": f"Mitsuba's process failed (status {e.returncode}): "
                           f"{(e.stderr or '').strip().splitlines()[-1:]}"}
    rt = raytrace_frame(scene_path, w, h, threads, repeat)
    return {"scene": "mesh", "width": w, "height": h, "threads": threads, "mitsuba": mit,
            "raytrace": rt, "ratio": rt["warm_seconds"] / mit["warm_seconds"],
            "ratio_without_build": rt["without_build_seconds"] / mit["warm_seconds"]}


def report(row: dict) -> str:
    if "missing" in row:
        return f"Mitsuba 3: skipped, {row['missing']}"
    m, r = row["mitsuba"], row["raytrace"]
    return (f"Mitsuba 3 {m['version']} ({m['variant']}, direct, {row['threads']} threads) "
            f"against raytrace, mesh scene {row['width']}x{row['height']}, warm frame: "
            f"Mitsuba {m['warm_seconds']:.3f} s (load + BVH {m['load_seconds']:.3f} s, first "
            f"render {m['first_render_seconds']:.3f} s); raytrace {r['warm_seconds']:.3f} s "
            f"({r['build_seconds']:.3f} s of it the BVH build, {r['without_build_seconds']:.3f}"
            f" s without): {row['ratio']:.2f}x Mitsuba's time, "
            f"{row['ratio_without_build']:.2f}x without the build")


def main(argv: list[str] | None = None) -> int:
    import tempfile

    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--threads", type=int, default=2)
    p.add_argument("--quick", action="store_true")
    p.add_argument("--repeat", type=int, default=3)
    p.add_argument("--json", help="also write the result to this JSON file")
    a = p.parse_args(argv)
    with tempfile.TemporaryDirectory(prefix="raytrace-mitsuba-") as tmp:
        row = compare(Path(tmp), a.threads, a.quick, a.repeat)
    print(report(row))
    if a.json:
        Path(a.json).write_text(json.dumps(row, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
