"""The compiled loop (raytrace/kernels/loop.py) against the integrator's Python loop: the same
kernels in the same order, so the same image bit for bit, the same AOVs and the same ray
counts, on scenes that between them use every feature the loop leaves out where unused
(meshes and textures, reflection and refraction, transparent shadows, jittered area lights,
spot lights, AOVs, crops, filters, adaptive anti-aliasing)."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest

import raytrace
from raytrace.integrator import WhittedIntegrator

SCENES = Path(__file__).resolve().parents[1] / "scenes"
CASES = [
    ("whitted.toml", {"spp": 4}),
    ("whitted.toml", {"aa": "adaptive"}),
    ("whitted.toml", {"aovs": "depth,normal,id", "pass_samples": 16, "max_depth": 6}),
    ("area_light.toml", {"spp": 2, "crop": (5, 3, 27, 20)}),
    ("cornell_box.toml", {"filter": "gaussian"}),
    ("materials_showcase.toml", {}),
    ("obj_mtl.toml", {"aovs": "albedo,uv"}),
    ("spotlights.toml", {}),
    ("tir.toml", {"max_depth": 3}),
    ("mesh_model.toml", {"min_weight": 0.05}),
]


def render(name: str, compiled: bool, **settings) -> raytrace.Image:
    WhittedIntegrator.compiled = compiled
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            return raytrace.render(raytrace.load_scene(SCENES / name), width=32, height=24,
                                   threads=2, **settings)
    finally:
        WhittedIntegrator.compiled = True


@pytest.mark.parametrize(("name", "settings"), CASES, ids=[f"{n}-{i}" for i, (n, _) in
                                                            enumerate(CASES)])
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
