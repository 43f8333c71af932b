"""What docs/testing.md's "Determinism" promises, tested: a render is bit-identical across
repeated runs (in one process and in a new one), thread counts, pass sizes (even where a glass
pixel's rays outgrow a pass and the batch is cut), and crops (tests/test_crop.py); the AOVs
too. Thread counts alone: tests/test_threads.py."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from test_integrator import reference_scene
from test_threads import scene as every_ray_scene

import raytrace

WHITTED = Path(__file__).resolve().parent.parent / "scenes" / "whitted.toml"


def same_bits(a: np.ndarray, b: np.ndarray) -> bool:
    return a.shape == b.shape and np.array_equal(a.view(np.uint32), b.view(np.uint32))


@pytest.mark.parametrize("scene", [reference_scene, every_ray_scene])
def test_each_sample_is_summed_in_one_order_however_the_batches_are_cut(scene):
    # Below the float32 rounding of the image: the float64 sums of every sample, traced
    # whole and in batches cut to 64 rays, are equal bit for bit, not just to float32
    # precision. (At depth 6 one sample has at most 2⁶ = 64 rays, so no sample is cut.)
    from raytrace.integrator import RenderOptions, WhittedIntegrator

    sums = []
    for pass_samples in (64, 1 << 16):
        opts = RenderOptions(width=24, height=18, max_depth=6, background=[0.2, 0.3, 0.5],
                             pass_samples=pass_samples)
        samples = np.zeros((24 * 18, 3))
        WhittedIntegrator(scene(), opts).trace_samples(0, 24 * 18, samples)
        sums.append(samples)
    assert np.array_equal(sums[0].view(np.uint64), sums[1].view(np.uint64))


@pytest.mark.parametrize("pass_samples", [7, 36, 1000])
def test_any_pass_size_and_thread_count_gives_the_same_bits(pass_samples):
    kw = dict(width=30, height=20, spp=4, aovs=["depth", "normal", "albedo", "id"])
    ref = raytrace.render(every_ray_scene(), threads=1, **kw)
    img = raytrace.render(every_ray_scene(), threads=2, pass_samples=pass_samples, **kw)
    assert same_bits(img.rgb, ref.rgb)
    for name in ref.aovs:
        np.testing.assert_array_equal(img.aov(name), ref.aov(name))


def test_repeated_runs_in_one_process_are_identical():
    scene = raytrace.load_scene(WHITTED)
    a = raytrace.render(scene, width=64, height=48, spp=4, threads=2)
    b = raytrace.render(scene, width=64, height=48, spp=4, threads=1)
    assert same_bits(a.rgb, b.rgb)


def test_a_run_in_a_new_process_is_identical(tmp_path):
    # The command line in a fresh interpreter (numba's cached machine code, a new Embree
    # scene) against this process's render.
    out = tmp_path / "w.exr"
    subprocess.run([sys.executable, "-m", "raytrace", "render", str(WHITTED), "-o",
                    str(out), "--width", "64", "--height", "48", "--spp", "4", "--threads",
                    "2", "-q"], check=True)
    here = raytrace.render(raytrace.load_scene(WHITTED), width=64, height=48,
                           spp=4, threads=1)
    rgb, _ = raytrace.read_exr(out)
    assert same_bits(rgb, here.rgb)
