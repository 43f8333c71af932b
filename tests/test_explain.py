"""``raytrace explain``: one pixel sample's ray tree, recorded from the integrator itself. The
contributions of its rays sum to the sample's value, and with spp = 1 that value is the pixel
of the render."""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from helpers import make_scene
from test_threads import scene as every_ray_scene

import raytrace
from raytrace import cli, values
from raytrace.lights import LIGHT_TYPES, Emitter
from raytrace.raytree import explain, format_tree

WHITTED = Path(__file__).resolve().parent.parent / "scenes" / "whitted.toml"
W, H = 160, 120
GLASS = 2  # objects[2] of whitted.toml: the glass sphere


def project(point, camera: raytrace.Camera, width: int, height: int) -> tuple[int, int]:
    """The pixel (col, row) whose area a world point falls in (pinhole; SCENE_FORMAT.md)."""
    right, up, forward = camera.basis()
    v = np.asarray(point, dtype=np.float64) - camera.position
    x, y = (v @ right) / (v @ forward), (v @ up) / (v @ forward)
    t = np.tan(np.radians(camera.fov) / 2)
    col = (x / (t * width / height) + 1) / 2 * width
    row = (1 - y / t) / 2 * height
    return int(col), int(row)


@pytest.fixture(scope="module")
def whitted() -> raytrace.Scene:
    # One sample a pixel (the scene file asks for 4): the tests here read sample 0 as the pixel.
    scene = raytrace.load_scene(WHITTED)
    scene.render.spp = 1
    return scene


@pytest.fixture(scope="module")
def glass_pixel(whitted) -> tuple[int, int]:
    # The glass sphere's centre, moved a little off the axis so the ray is not head-on.
    sphere = whitted.objects[GLASS]
    return project(sphere.center + [0.3, 0.2, 0.0], whitted.camera, W, H)


@pytest.fixture(scope="module")
def report(whitted, glass_pixel) -> dict:
    return explain(whitted, glass_pixel, width=W, height=H)


def test_the_pixel_sees_glass(report):
    camera_ray = report["rays"][0]
    assert camera_ray["kind"] == "camera" and camera_ray["parent"] is None
    assert camera_ray["hit"]["object"] == GLASS
    assert camera_ray["hit"]["material"] == "whitted_glass"
    assert camera_ray["hit"]["side"] == "outside"
    kinds = {r["kind"] for r in report["rays"]}
    assert {"reflection", "refraction"} <= kinds
    assert any(r["hit"] and r["hit"]["side"] == "inside" for r in report["rays"])


def test_contributions_sum_to_the_rendered_pixel(whitted, glass_pixel, report):
    total = np.sum([r["contribution"] for r in report["rays"]], axis=0)
    value = np.array(report["value"])
    np.testing.assert_allclose(total, value, rtol=2**-24, atol=0)
    # spp = 1: the sample is the pixel, as the full render computes it (float32, exactly).
    x, y = glass_pixel
    image = raytrace.render(whitted, width=W, height=H, threads=2)
    assert np.array_equal(np.float32(value), image.rgb[y, x])
    assert np.array_equal(np.float32(report["pixel_value"]), image.rgb[y, x])


def test_the_tree_is_consistent(report):
    rays = report["rays"]
    for r in rays:
        assert r["id"] == rays.index(r)
        for c in r["children"]:
            child = rays[c]
            assert child["parent"] == r["id"] and child["depth"] == r["depth"] + 1
            np.testing.assert_allclose(child["origin"], r["hit"]["point"], atol=1e-9)
    # The glass hit from outside: a reflected child of weight kr = 0.1 and a refracted one of
    # kt = 0.9 (whitted_glass), both from the camera ray's weight 1.
    first = {rays[c]["kind"]: rays[c] for c in rays[0]["children"]}
    np.testing.assert_allclose(first["reflection"]["weight"], [0.1] * 3, rtol=1e-15)
    np.testing.assert_allclose(first["refraction"]["weight"], [0.9] * 3, rtol=1e-15)
    # Every ray past max_depth is pruned, none is traced.
    assert max(r["depth"] for r in rays) <= report["max_depth"]
    # A miss adds weight·background; a hit w·t·(ambient + Σ lights) (opacity 1 here).
    for r in rays:
        if r["hit"] is None:
            np.testing.assert_allclose(r["contribution"],
                                       np.multiply(r["weight"], r["background"]), rtol=1e-15)
        else:
            parts = np.sum([lt["contribution"] for lt in r["lights"]], axis=0) + r["ambient"]
            np.testing.assert_allclose(r["contribution"], parts, rtol=1e-12, atol=1e-300)


def test_samples_of_a_jittered_pixel_average_to_it():
    # spp = 4 with a jittered area light and transparent shadows: each sample explained on
    # its own (a one-pixel crop, keyed by its index in the full frame) — their mean is the
    # pixel of the full render.
    scene = every_ray_scene()
    image = raytrace.render(scene, width=48, height=36, spp=4, threads=2)
    for x, y in [(30, 20), (12, 25)]:
        reports = [explain(scene, (x, y), s, width=48, height=36, spp=4) for s in range(4)]
        for rep in reports:
            total = np.sum([r["contribution"] for r in rep["rays"]], axis=0)
            np.testing.assert_allclose(total, rep["value"], rtol=2**-24, atol=1e-30)
            assert np.array_equal(np.float32(rep["pixel_value"]), image.rgb[y, x])
        values = [rep["value"] for rep in reports]
        assert len({tuple(v) for v in values}) == 4      # four different samples
        np.testing.assert_allclose(np.mean(values, axis=0), image.rgb[y, x], rtol=2**-23)


def test_the_json_on_the_command_line(capsys, glass_pixel):
    x, y = glass_pixel
    assert cli.main(["explain", str(WHITTED), "--pixel", str(x), str(y), "--json",
                     "--width", str(W), "--height", str(H), "--spp", "1"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert {"value", "rays"} <= set(data)
    for r in data["rays"]:
        assert {"kind", "depth", "contribution"} <= set(r)
    np.testing.assert_allclose(np.sum([r["contribution"] for r in data["rays"]], axis=0),
                               data["value"], rtol=2**-24)


def test_the_tree_on_the_command_line_is_indented(capsys, glass_pixel, report):
    x, y = glass_pixel
    assert cli.main(["explain", str(WHITTED), "--pixel", str(x), str(y), "--width", str(W),
                     "--height", str(H), "--max-depth", "2", "--spp", "1"]) == 0
    out = capsys.readouterr().out
    lines = out.splitlines()
    assert lines[0].startswith(f"{WHITTED}: pixel ({x}, {y}) sample 0 of 1")
    assert any(ln.startswith("#0 camera ray, depth 0") for ln in lines)
    assert any(ln.startswith("  #1 reflection ray, depth 1") for ln in lines)
    assert any(ln.startswith("    #") and "depth 2" in ln for ln in lines)
    assert "pruned by max_depth" in out
    assert format_tree(report).count("camera ray") == 1


@pytest.mark.parametrize(("args", "flag"), [(["--pixel", "160", "0"], "--pixel"),
                                            (["--pixel", "0", "-1"], "--pixel"),
                                            (["--pixel", "1", "1", "--sample", "1"], "--sample"),
                                            (["--pixel", "1", "1", "--spp", "0"], "--spp")])
def test_bad_pixels_and_samples_are_one_line(capsys, args, flag):
    rc = cli.main(["explain", str(WHITTED), "--width", str(W), "--height", str(H), "--spp", "1",
                   *args])
    err = capsys.readouterr().err
    assert rc == 2 and len(err.splitlines()) == 1 and flag in err, err
    if flag != "--spp":
        assert "whitted.toml" in err


def test_a_tree_larger_than_a_batch_is_refused_in_one_line(whitted, glass_pixel):
    # One ray a pass: the glass hit's two children would be cut into two batches, which the
    # recorder cannot follow ray by ray; it says so instead of mislabelling rays.
    with pytest.raises(raytrace.SceneError, match="too many to explain"):
        explain(whitted, glass_pixel, width=W, height=H, pass_samples=1)


@dataclass
class LineLight(values.Checked):
    """A segment from ``start`` to ``end`` sampled by ``samples`` point lights at the centres
    of equal pieces, sharing ``color``: a light by docs/architecture.md's recipe (one record
    and its ``LIGHT_TYPES`` line), whose emitters name their parts."""

    start: Any
    end: Any
    samples: int = 3
    color: Any = 1.0
    type = "line"

    def check(self) -> None:
        self.start = values.vector(self.start, "start")
        self.end = values.vector(self.end, "end")
        self.samples = values.number(self.samples, "samples", lo=1, hi=4096, integer=True)
        self.color = values.color(self.color, "color")

    def emitters(self, origin: np.ndarray, seed: int, index: int) -> list:
        n = self.samples
        return [Emitter(self.color / n, self.start + (k + 0.5) / n * (self.end - self.start)
                        - origin, part=f"sample {k}") for k in range(n)]


def test_each_light_names_its_own_emitters(monkeypatch):
    # A light of several emitters registered by its one line, before a point light and an
    # area light: every emitter's label is its own light's key and part, none shifted.
    monkeypatch.setitem(LIGHT_TYPES, "line", LineLight)
    floor = raytrace.Plane([0, 0, 0], [0, 1, 0], raytrace.Material(kd=0.8))
    scene = make_scene([floor], [LineLight([-1, 2, 0], [1, 2, 0]), raytrace.PointLight([0, 3, 1]),
                                 raytrace.AreaLight([0, 2, -1], [0.4, 0, 0], [0, 0, 0.4],
                                                    samples=4)],
                       raytrace.Camera([0, 1, 3], [0, 0, 0]), ambient=0.1)
    report = explain(scene, (4, 3), width=8, height=6)
    lights = report["rays"][0]["lights"]
    assert [lt["light"] for lt in lights] == [
        "lights[0] (line, sample 0)", "lights[0] (line, sample 1)",
        "lights[0] (line, sample 2)", "lights[1] (point)", "lights[2] (area, cell 0)",
        "lights[2] (area, cell 1)", "lights[2] (area, cell 2)", "lights[2] (area, cell 3)"]
    assert all(np.all(np.array(lt["contribution"]) > 0) for lt in lights)  # all lit
    np.testing.assert_allclose(report["rays"][0]["contribution"], np.sum(
        [lt["contribution"] for lt in lights], axis=0) + report["rays"][0]["ambient"],
        rtol=1e-12)
    assert "lights[0] (line, sample 2)  term" in format_tree(report)


@pytest.mark.parametrize(("pixel", "sample", "line"), [
    ("a", 0, "pixel: must be two numbers (x, y), got 'a'"),
    ((1.5, 2), 0, "pixel: must be a whole number, got 1.5"),
    ((0, 999), 0, "pixel: (0, 999) is outside the 160x120 image (0 <= X < 160, 0 <= Y < 120)"),
    ((0, 0), 3, "sample: must be <= 0 (the range is [0, 0]), got 3 (the pixel has 1 sample)"),
])
def test_the_api_names_its_own_arguments_not_the_cli_flags(whitted, pixel, sample, line):
    with pytest.raises(raytrace.SceneError) as e:
        explain(whitted, pixel, sample, width=W, height=H, spp=1)
    assert str(e.value) == f"{WHITTED}: {line}"
