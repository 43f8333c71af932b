"""Large meshes: how load, build and render grow from 80 k to 5 M triangles (issue 14).

    python3 benchmarks/meshes.py                 # 82k, 328k, 1.3M, 5.2M triangles (~2 min)
    python3 benchmarks/meshes.py --quick         # 1.3k and 5k triangles: checks the harness
    python3 benchmarks/bench.py --parts meshes   # the same, inside the benchmark's JSON

Each size is the benchmark's mesh scene (:data:`bench.MESH_SCENE`: a smooth brass sphere on a
2-triangle ground, one point light, 1000×1000, spp 1) with the sphere an icosphere of
subdivision 6, 7, 8 or 9 (20·4ˢ triangles), written by trimesh into a temporary folder as
binary PLY and, up to 1.3 M triangles, as OBJ. For each file:

* a fresh ``raytrace render --stats`` process (``--threads``): its wall time, peak resident
  memory and the ``--stats`` seconds (load, build, trace, shade, write);
* in this process, the parts of load and build: reading the file with
  :func:`raytrace.readers.meshio.read_mesh` against trimesh's ``load`` + ``merge_vertices``
  (process CPU seconds), making the ``raytrace.Mesh`` (transform, zero-area faces dropped,
  checks; CPU seconds), and the three steps of the accelerator: the fingerprint it is kept
  by (:func:`raytrace.accel_cache.fingerprint`, CPU seconds), the float64 triangle tables
  (``SceneArrays.triangles``, CPU seconds) and Embree's BVH over the float32 vertices it
  shares (:class:`raytrace.embree.Meshes`, wall seconds on ``--threads`` threads).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

import raytrace
from raytrace.accel_cache import fingerprint
from raytrace.embree import Meshes
from raytrace.readers import meshio
from raytrace.tables import scene_arrays

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

#: Icosphere subdivisions: 81 920, 327 680, 1 310 720 and 5 242 880 triangles.
SUBDIVISIONS = (6, 7, 8, 9)
QUICK_SUBDIVISIONS = (3, 4)
#: Largest subdivision also written as OBJ (a 5.2 M-triangle OBJ is 220 MB of text).
MAX_OBJ_SUBDIVISION = 8


def write_sphere(folder: Path, subdivisions: int, suffix: str) -> Path:
    """The mesh scene with an icosphere of ``subdivisions`` as ``sphere<suffix>``."""
    import trimesh
    from bench import MESH_SCENE

    folder.mkdir(parents=True, exist_ok=True)
    mesh = folder / f"sphere{suffix}"
    if not mesh.exists():
        trimesh.creation.icosphere(subdivisions=subdivisions, radius=1.0).export(mesh)
    scene = folder / f"mesh{suffix.replace('.', '_')}.toml"
    scene.write_text(MESH_SCENE.replace('"sphere.ply"', f'"{mesh.name}"'))
    return scene


def load_parts(mesh: Path) -> dict:
    """CPU seconds of reading ``mesh`` with raytrace.readers.meshio and with trimesh (load +
    merge_vertices, raytrace's reading before meshio)."""
    import trimesh

    t0 = time.process_time()
    fast = meshio.read_mesh(mesh)
    t1 = time.process_time()
    loaded = trimesh.load(str(mesh), process=False)
    loaded.merge_vertices(merge_tex=True, merge_norm=True)
    t2 = time.process_time()
    same = fast is not None and np.array_equal(fast[0], loaded.vertices) and np.array_equal(
        fast[1], loaded.faces)
    return {"meshio_cpu": t1 - t0, "trimesh_cpu": t2 - t1, "same_as_trimesh": bool(same)}


def build_parts(scene_path: Path, threads: int) -> dict:
    """The seconds of each step raytrace takes from the file to the BVH, in this process:
    making the mesh (``raytrace.load_scene``, CPU), the accelerator's fingerprint and the
    float64 triangle tables (CPU), and Embree's BVH (wall, ``threads`` threads; the second
    of two builds, Embree's library and device loaded by the first)."""
    t0 = time.process_time()
    scene = raytrace.load_scene(scene_path)
    made = time.process_time() - t0
    arrays = scene_arrays(scene)
    t0 = time.process_time()
    fingerprint(scene, arrays.materials)
    t1 = time.process_time()
    arrays.triangles  # noqa: B018 (a cached property: the tables)
    t2 = time.process_time()
    Meshes(arrays.meshes, threads).close()
    t3 = time.perf_counter()
    Meshes(arrays.meshes, threads).close()
    return {"mesh_cpu": made, "fingerprint_cpu": t1 - t0, "tables_cpu": t2 - t1,
            "bvh_wall": time.perf_counter() - t3}


def run(workdir: Path, threads: int, quick: bool = False) -> list[dict]:
    """One row per (size, format): the fresh process's numbers and the in-process parts."""
    from bench import render_cli

    rows = []
    sizes = QUICK_SUBDIVISIONS if quick else SUBDIVISIONS
    build_parts(write_sphere(workdir / f"ico{sizes[0]}", sizes[0], ".ply"), threads)  # (the
    # kernels the tables take loaded, Embree's library too: the rows time the work alone)
    for s in sizes:
        for suffix in (".ply", ".obj"):
            if suffix == ".obj" and s > MAX_OBJ_SUBDIVISION:
                continue
            folder = workdir / f"ico{s}"
            scene = write_sphere(folder, s, suffix)
            w = h = 160 if quick else 1000
            cli = render_cli(scene, folder / "out.exr", w, h, threads)
            row = {"subdivisions": s, "format": suffix[1:], "triangles": cli["triangles"],
                   "width": w, "height": h, "threads": threads, "seconds": cli["seconds"],
                   "peak_rss_mib": cli["peak_rss_mib"], "command": cli["command"],
                   "file_mib": (folder / f"sphere{suffix}").stat().st_size / 2**20}
            row.update(load_parts(folder / f"sphere{suffix}"))
            row.update(build_parts(scene, threads))
            rows.append(row)
            (folder / "out.exr").unlink(missing_ok=True)
    return rows


def report(rows: list[dict]) -> str:
    from bench import _f, table

    body = [[f"{r['triangles'] / 1e6:.2f}M", r["format"], _f(r["file_mib"], "{:.0f}"),
             _f(r["seconds"]["process_wall"]), _f(r["seconds"]["load"]),
             _f(r["seconds"]["build"]), _f(r["seconds"]["trace"] + r["seconds"]["shade"]),
             _f(r["seconds"]["write"]), _f(r["peak_rss_mib"], "{:.0f}"),
             _f(r["meshio_cpu"]), _f(r["trimesh_cpu"]), _f(r["mesh_cpu"]),
             _f(r["fingerprint_cpu"]), _f(r["tables_cpu"]), _f(r["bvh_wall"])] for r in rows]
    size = f"{rows[0]['width']}x{rows[0]['height']}" if rows else ""
    return (f"large meshes (a fresh `raytrace render` at {size}: wall and --stats seconds; "
            "in-process: reading with meshio / trimesh, making the mesh, the accelerator's "
            "fingerprint and triangle tables (CPU s), and the BVH (wall s))\n" + table(
                ["triangles", "file", "MiB", "wall", "load", "build", "trace+shade", "write",
                 "peak MiB", "meshio", "trimesh", "mesh", "fingerprint", "tables", "BVH"],
                body))


def main(argv: list[str] | None = None) -> int:
    import tempfile

    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--quick", action="store_true", help="1.3k and 5k triangles at 160x160")
    p.add_argument("--threads", type=int, default=2)
    p.add_argument("--json", help="also write the rows to this JSON file")
    a = p.parse_args(argv)
    with tempfile.TemporaryDirectory(prefix="raytrace-meshes-") as tmp:
        rows = run(Path(tmp), a.threads, a.quick)
    print(report(rows))
    if a.json:
        Path(a.json).write_text(json.dumps(rows, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
