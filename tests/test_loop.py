"""The compiled loop (raytrace/kernels/loop.py) against the integrator's Python loop: the same
kernels in the same order, so the same image bit for bit, the same AOVs and the same ray
counts, on scenes that between them use every feature the loop leaves out where unused
(meshes and textures, reflection and refraction, transparent shadows, jittered area lights,
spot lights, AOVs, crops, filters, adaptive anti-aliasing)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest

import raytrace
from raytrace.integrator import WhittedIntegrator

SCENES = Path(__file__).resolve().parents[1] / "scenes"
#: Each case compiles a variant of the loop (about 40 s on 2 cores with an empty cache): one
#: runs by default, the others with ``-m slow``.
SLOW = pytest.mark.slow
CASES = [
    ("whitted.toml", {"spp": 4}),
    pytest.param("whitted.toml", {"aa": "adaptive"}, marks=SLOW),
    pytest.param("whitted.toml", {"aovs": "depth,normal,id", "pass_samples": 16,
                                  "max_depth": 6}, marks=SLOW),
    pytest.param("area_light.toml", {"spp": 2, "crop": (5, 3, 27, 20)}, marks=SLOW),
    pytest.param("cornell_box.toml", {"filter": "gaussian"}, marks=SLOW),
    pytest.param("materials_showcase.toml", {}, marks=SLOW),
    pytest.param("obj_mtl.toml", {"aovs": "albedo,uv"}, marks=SLOW),
    pytest.param("obj_mtl.toml", {"texture_filter": "trilinear", "spp": 4}, marks=SLOW),
    pytest.param("spotlights.toml", {}, marks=SLOW),
    pytest.param("tir.toml", {"max_depth": 3}, marks=SLOW),
    pytest.param("mesh_model.toml", {"min_weight": 0.05}, marks=SLOW),
    pytest.param("glass_model.glb", {"max_depth": 4}, marks=SLOW),  # Beer's law, thin walls
]


def render(name: str, compiled: bool, **settings) -> raytrace.Image:
    default = WhittedIntegrator.compiled
    WhittedIntegrator.compiled = compiled
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            return raytrace.render(raytrace.load_scene(SCENES / name), width=32, height=24,
                                   threads=2, **settings)
    finally:
        WhittedIntegrator.compiled = default


@pytest.mark.parametrize(("name", "settings"), CASES)
def test_compiled_loop_is_the_python_loop(name, settings):
    python = render(name, False, **settings)
    compiled = render(name, True, **settings)
    assert np.array_equal(python.rgb, compiled.rgb)
    assert python.rgb.any()  # a picture, not an empty frame
    for aov in (settings.get("aovs") or "").split(","):
        if aov:
            assert np.array_equal(python.aov(aov), compiled.aov(aov), equal_nan=True), aov
    for key in ("rays", "pruned", "total_internal_reflections"):
        assert python.stats[key] == compiled.stats[key], key
    seconds = compiled.stats["seconds"]
    assert 0 < seconds["trace"] and 0 < seconds["shade"]
    assert seconds["build"] + seconds["trace"] + seconds["shade"] <= seconds["total"]


TRACER = """
import json, sys
import raytrace
from raytrace.kernels import loop
raytrace.render(raytrace.load_scene(sys.argv[1]), width=8, height=6, threads=1)
(tracer,) = [sig[0] for sig in loop.trace_paths.signatures]  # this process: one variant
print(json.dumps(dict(zip(tracer.instance_class._fields, map(str, tracer.types)))))
"""


@pytest.mark.slow
def test_a_diffuse_scene_compiles_no_child_mesh_or_transparency_code():
    # scenes/spotlights.toml (spheres and planes, matte and plastic, spot lights), in a process
    # of its own: the loop's Tracer record types every feature the scene lacks None, which is
    # what the loop's overloads pick their code by (kernels/loop.py).
    out = subprocess.run([sys.executable, "-c", TRACER, str(SCENES / "spotlights.toml")],
                         env={**os.environ, "RAYTRACE_LOOP": "compiled"}, capture_output=True,
                         text=True, check=True).stdout
    fields = json.loads(out)
    assert {"children": "none", "shaded": "none", "transparent": "none",
            "embree": "none", "lit": "bool"}.items() <= fields.items()


COMPILES = """
import json, sys
from numba.core import event
import raytrace
names = []
class Compiles(event.Listener):
    def on_start(self, e):
        names.append(e.data["dispatcher"].py_func.__qualname__)
    def on_end(self, e):
        pass
event.register("numba:compile", Compiles())
raytrace.render(raytrace.load_scene(sys.argv[1]), width=8, height=6, threads=1)
print(json.dumps(names))
"""


@pytest.mark.slow
def test_the_loops_steps_compile_inside_it(tmp_path):
    # The Whitted scene's first render with an empty kernel cache (NUMBA_CACHE_DIR), in a
    # process of its own: numba's compile events name every function compiled on its own.
    # The loop's steps called from one place or in one form (trace_depth, intersect, spawn)
    # are inlined in numba's IR (jit.inline): typed and lowered inside trace_paths, with no
    # machine code of their own that trace_paths would link and optimize again; and nothing
    # calls numpy's count_nonzero (a compile of its own for each array type).
    env = {**os.environ, "RAYTRACE_LOOP": "compiled", "NUMBA_CACHE_DIR": str(tmp_path)}
    out = subprocess.run([sys.executable, "-c", COMPILES, str(SCENES / "whitted.toml")],
                         env=env, capture_output=True, text=True, check=True).stdout
    names = set(json.loads(out))
    assert {"trace_paths", "light_pass", "hit_terms", "spawn_children"} <= names
    assert not {"trace_depth", "intersect", "spawn"} & names
    assert not [name for name in names if name.startswith("np_count_nonzero.")]
