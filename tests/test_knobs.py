"""benchmarks/knobs.py: the error measures, the slope fit and the sweeps at tiny sizes.

The sweeps are checked against properties that hold whatever the timings are:

* max_depth: Whitted's sum has non-negative terms (weights and contributions are ≥ 0), and a
  render at depth d adds exactly the depth-≤ d terms of the deeper render, in the same order;
  floating-point addition of non-negative numbers is monotone, so every pixel approaches the
  deep reference from below and the error can only fall with d, reaching exactly 0 at the
  reference's depth.
* min_weight: a higher threshold prunes a superset of the rays (a pruned ray's subtree goes
  with it), so the ray count can only fall; min_weight 0 against itself is exactly 0.

Plotting is not tested (matplotlib is not a test dependency).
"""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))

import knobs  # noqa: E402

import raytrace  # noqa: E402


# -- error measures ------------------------------------------------------------------------------
def test_rmse_max_and_relative_on_a_2x2_image():
    reference = np.full((2, 2, 3), 0.5, np.float32)
    image = reference.copy()
    image[0, 1] = [1.5, -1.5, 2.5]          # differences (1, −2, 2) in one pixel, 0 elsewhere
    # mean of the 12 squared differences: (1 + 4 + 4) / 12 = 0.75, so RMSE = sqrt(0.75).
    assert knobs.rmse(image, reference) == pytest.approx(math.sqrt(0.75), rel=1e-12)
    e = knobs.errors(image, reference)
    assert e["max_error"] == pytest.approx(2.0)
    assert e["relative"] == pytest.approx(math.sqrt(0.75) / 0.5, rel=1e-12)
    assert knobs.rmse(reference, reference) == 0.0


def test_loglog_slope_recovers_a_known_power_law():
    x = np.array([1, 4, 16, 64, 256], float)
    slope, intercept = knobs.loglog_slope(x, 3.0 * x ** -0.75)
    assert slope == pytest.approx(-0.75, abs=1e-12)
    assert intercept == pytest.approx(math.log10(3.0), abs=1e-12)
    noisy = 2.0 * x ** -0.5 * np.array([1.05, 0.97, 1.02, 0.96, 1.03])
    assert knobs.loglog_slope(x, noisy)[0] == pytest.approx(-0.5, abs=0.03)


def test_truth_estimate_removes_the_references_share():
    # floor = sqrt(2)·3: each reference is 3 from the truth; 5² − 3² = 4².
    assert knobs.truth_estimate(5.0, math.sqrt(2) * 3.0) == pytest.approx(4.0)
    assert knobs.truth_estimate(1.0, 10.0) == 0.0


def test_with_area_samples_copies_and_leaves_the_scene_alone():
    scene = knobs.load("area_light")
    before = (scene.lights[0].samples, scene.lights[0].jitter)
    variant = knobs.with_area_samples(scene, 64, True)
    assert (variant.lights[0].samples, variant.lights[0].jitter) == (64, True)
    assert (scene.lights[0].samples, scene.lights[0].jitter) == before
    assert variant is not scene and variant.lights[0] is not scene.lights[0]


# -- the sweeps ----------------------------------------------------------------------------------
@pytest.mark.parametrize("name", ["tir", "whitted"])
def test_max_depth_error_falls_to_zero_at_the_reference_depth(name):
    out = knobs.sweep_max_depth(knobs.load(name), list(range(6)), (40, 25),
                                reference_depth=5)
    rmse = [r["rmse"] for r in out["rows"]]
    worst = [r["max_error"] for r in out["rows"]]
    assert all(b <= a for a, b in zip(rmse, rmse[1:], strict=False)), rmse
    assert all(b <= a for a, b in zip(worst, worst[1:], strict=False)), worst
    assert rmse[0] > 0.01                   # depth 0 really misses the mirrors and the glass
    assert rmse[-1] == 0.0 and worst[-1] == 0.0
    rays = [r["rays"]["total"] for r in out["rows"]]
    assert all(b >= a for a, b in zip(rays, rays[1:], strict=False)), rays
    assert out["rows"][0]["rays"]["reflection"] == 0 == out["rows"][0]["rays"]["refraction"]


def test_min_weight_prunes_rays_monotonically():
    weights = [0.0, 1e-4, 1e-3, 1e-2, 5e-2, 0.2]
    out = knobs.sweep_min_weight(knobs.load("tir"), weights, (40, 25), depth=8)
    first = out["rows"][0]
    assert first["value"] == 0.0 and first["rmse"] == 0.0 and first["max_error"] == 0.0
    rays = [r["rays"]["total"] for r in out["rows"]]
    assert all(b <= a for a, b in zip(rays, rays[1:], strict=False)), rays
    assert rays[-1] < rays[0]               # the TIR scene's ray tree really gets pruned
    assert out["rows"][-1]["rmse"] > 0.0


def test_more_spp_gives_less_error_on_the_area_light():
    # Deterministic: the jitter is a hash of (seed, sample), so this is the same every run.
    out = knobs.sweep_spp(knobs.load("area_light"), [1, 16], (48, 36), reference_spp=256,
                          reference_seeds=(101, 202))
    one, sixteen = out["rows"]
    assert sixteen["rmse"] < 0.5 * one["rmse"]
    assert sixteen["max_error"] < one["max_error"]
    # The two 256-spp references are closer to each other than 16 spp is to them.
    assert out["noise_floor"]["rmse"] < sixteen["rmse"]


def test_quick_run_is_complete_and_serialisable():
    result = knobs.run(knobs.QUICK, threads=1, log=lambda _: None)
    text = knobs.report(result)
    json.loads(json.dumps(result))
    for title in ("### spp", "### max_depth", "### min_weight", "### area-light samples"):
        assert title in text
    for m in result["max_depth"].values():
        for r in m["rows"]:
            assert r["seconds"] > 0 and r["rays"]["total"] >= r["rays"]["camera"] > 0
    assert len(result["load_average_start"]) == 3


def test_importing_knobs_does_not_import_matplotlib():
    code = ("import sys; sys.path.insert(0, 'benchmarks'); import knobs; "
            "assert 'matplotlib' not in sys.modules")
    subprocess.run([sys.executable, "-c", code], cwd=ROOT, check=True, timeout=60)


def test_aa_study_counts_samples_and_caches_its_reference(tmp_path):
    """The AA study at a tiny size: uniform rows trace exactly spp camera samples a pixel,
    adaptive ones at least every pixel corner ((W + 1)·(H + 1)), with min depth 1 at least
    the level-1 lattice; the reference is written once and read back as it was rendered."""
    scene = knobs.load("whitted")
    config = dict(knobs.AA_QUICK, size=(16, 12), reference=(4, 7))
    result = knobs.sweep_aa(scene, config, 1, tmp_path)
    (cached,) = tmp_path.iterdir()
    again, seconds = knobs.aa_reference(scene, (16, 12), 4, 7, 1, tmp_path)
    assert seconds is None  # read, not rendered
    np.testing.assert_array_equal(again, raytrace.render(scene, width=16, height=12, spp=4,
                                                         seed=7, threads=1).rgb)
    rows = {r["label"]: r for r in result["rows"]}
    assert rows["uniform 1 spp"]["samples_per_pixel"] == 1.0
    assert rows["uniform 4 spp"]["samples_per_pixel"] == 4.0
    assert rows["adaptive t 0.05 d 2"]["samples_per_pixel"] >= 17 * 13 / (16 * 12)
    assert rows["adaptive t 0.05 d 2 min 1"]["samples_per_pixel"] >= 33 * 25 / (16 * 12)
    assert all(r["rmse"] > 0 and 0 < r["flip"] < 1 for r in result["rows"])
    assert "### whitted.toml at 16×12" in knobs.report_aa({"aa": {"whitted": result}})
