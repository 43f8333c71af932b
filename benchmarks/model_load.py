"""Reading a model file: raytrace's ``load_scene`` of a glTF/OBJ against ``trimesh.load``
plus decoding each image its materials hold (base colour, normal, occlusion, emissive,
metallic-roughness) to an RGBA array once, and the build of the scene's
tables and BVH (``WhittedIntegrator``), in one process with the imports done first.

    python3 benchmarks/model_load.py MODEL [MODEL ...] [--rounds 5] [--cpu]

Loads alternate round by round (raytrace's glTF cache cleared each time) and each figure is
the best of ``--rounds``, so a busy machine's noise counts least. The builds are the first in
the process (numba loads its compiled kernels then: a start-up paid once per process) and
the best of the later ones. ``--cpu`` times the loads in this process's CPU seconds
(``time.process_time``) rather than the wall clock, which on a busy machine also counts the
time other processes hold the cores. Results: docs/performance.md, "Model files".
"""

from __future__ import annotations

import argparse
import time
import warnings

import numpy as np
import trimesh

from raytrace.integrator import RenderOptions, WhittedIntegrator
from raytrace.readers import gltf
from raytrace.readers.scene_file import load_scene


def ours(path: str):
    gltf._load_cached.cache_clear()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the "no camera / no lights" note
        return load_scene(path)


#: The images a trimesh PBR material holds (trimesh.visual.material.PBRMaterial).
TRIMESH_IMAGES = ("baseColorTexture", "normalTexture", "occlusionTexture", "emissiveTexture",
                  "metallicRoughnessTexture")


def theirs(path: str) -> None:
    """trimesh's load, then each distinct image its materials hold decoded to RGBA once."""
    loaded = trimesh.load(path)
    images = {}
    for g in getattr(loaded, "geometry", {"": loaded}).values():
        material = getattr(g.visual, "material", None)
        for name in TRIMESH_IMAGES:
            image = getattr(material, name, None)
            if image is not None:
                images[id(image)] = image
    for image in images.values():
        np.asarray(image.convert("RGBA"))


def best(f, path: str, rounds: int, clock=time.perf_counter) -> float:
    times = []
    for _ in range(rounds):
        t = clock()
        f(path)
        times.append(clock() - t)
    return min(times)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("models", nargs="+")
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--cpu", action="store_true", help="time the loads in CPU seconds")
    args = ap.parse_args()
    clock = time.process_time if args.cpu else time.perf_counter
    print("| model | triangles | raytrace load | trimesh + textures | ratio | first build "
          "| later build |\n|---|---|---|---|---|---|---|")
    for path in args.models:
        ours(path), theirs(path)  # the readers' own first-use costs apart
        load = [np.inf, np.inf]
        for _ in range(args.rounds):
            for i, f in enumerate((ours, theirs)):
                load[i] = min(load[i], best(f, path, 1, clock))
        scene = ours(path)
        t = time.perf_counter()
        first = WhittedIntegrator(scene, RenderOptions())
        first_build = time.perf_counter() - t
        later = min(WhittedIntegrator(scene, RenderOptions()).build_seconds
                    for _ in range(args.rounds))
        print(f"| {path.rsplit('/', 1)[-1]} | {first.arrays.n_triangles} | {load[0]:.3f} s "
              f"| {load[1]:.3f} s | {load[0] / load[1]:.2f} | {first_build:.3f} s "
              f"| {later:.4f} s |")


if __name__ == "__main__":
    main()
