"""Pixel reconstruction filters (``[render] filter``, ``--filter``): each profile integrates
to 1, a constant image comes back exactly, a sharp edge is spread by the filter's own weights
(worked by hand), and a filtered crop is the full render's window at any threads and pass
size (the samples of the margin are traced and gathered in one fixed order)."""

from __future__ import annotations

import math
import os
import warnings

import numpy as np
import pytest
from helpers import make_scene, write_text
from test_threads import scene as every_ray_scene

import raytrace
from raytrace import cli
from raytrace.errors import SceneError
from raytrace.film.filters import profile
from raytrace.sampling import FILTERS, margin

WIDE = ("tent", "gaussian", "mitchell")


@pytest.mark.parametrize("name", FILTERS)
def test_each_profile_integrates_to_one(name):
    r = FILTERS[name].radius
    x = np.linspace(-r, r, 400_001)
    assert np.trapezoid(profile(name, x), x) == pytest.approx(1.0, abs=1e-9)
    assert np.all(profile(name, np.array([-r - 1e-9, r + 1e-9, 7.0])) == 0.0)


def test_margins_are_the_pixels_a_radius_reaches():
    # A sample of pixel p + m lies at least m − ½ from p's centre: reached while m − ½ < r.
    assert [margin(n) for n in ("box", "tent", "gaussian", "mitchell")] == [0, 1, 1, 2]


@pytest.mark.parametrize("name", FILTERS)
def test_a_constant_image_comes_back_exactly(name):
    background = np.array([0.3, 0.2, 0.7], np.float32)
    scene = make_scene([], background=background.tolist())
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", raytrace.RenderWarning)  # no objects: on purpose
        image = raytrace.render(scene, width=9, height=7, spp=4, filter=name, threads=1)
    assert np.array_equal(image.rgb, np.broadcast_to(background, image.rgb.shape))


def _half_plane(width: int = 8, height: int = 6) -> raytrace.Scene:
    """Radiance 1 left of the frame's middle column boundary, 0 right of it: an ambient-only
    quad from x = −100 to 0 at z = −1, seen from the origin down −z."""
    quad = raytrace.Mesh(vertices=[[-100, -100, -1], [0, -100, -1], [0, 100, -1],
                                   [-100, 100, -1]], faces=[[0, 1, 2], [0, 2, 3]],
                         material={"ka": 1.0, "kd": 0.0})
    return make_scene([quad], ambient=1.0, width=width, height=height)


def _g(x: float) -> float:
    return math.exp(-x * x / (2 * 0.5**2)) - math.exp(-1.5**2 / (2 * 0.5**2))


@pytest.mark.parametrize(("name", "left", "right"), [
    ("box", 1.0, 0.0),
    ("tent", 1.0, 0.0),  # the neighbours' centres are at distance 1: weight 0
    # Mitchell–Netravali (B = C = 1/3) at 0 and ±1 pixel: M(0) = (6 − 2B)/6 = 8/9,
    # M(1) = B/6 = 1/18, M(2) = 0: (M0 + M1)/(M0 + 2·M1) and M1/(M0 + 2·M1).
    ("mitchell", (8 / 9 + 1 / 18) / (8 / 9 + 2 / 18), (1 / 18) / (8 / 9 + 2 / 18)),
    ("gaussian", (_g(0) + _g(1)) / (_g(0) + 2 * _g(1)), _g(1) / (_g(0) + 2 * _g(1))),
])
def test_a_sharp_edge_is_spread_by_the_filter_weights(name, left, right):
    # spp = 1: one sample at each pixel centre, so the pixels beside the edge (columns 3 and
    # 4 of 8) mix their neighbours' centres with the filter's weights at 0 and ±1 pixel.
    rgb = raytrace.render(_half_plane(), spp=1, filter=name, threads=1).rgb[..., 0]
    np.testing.assert_allclose(rgb[:, 3], left, rtol=1e-6)
    np.testing.assert_allclose(rgb[:, 4], right, rtol=1e-6, atol=1e-7)
    np.testing.assert_allclose(rgb[:, :2], 1.0, rtol=1e-6)  # out of every filter's reach
    np.testing.assert_allclose(rgb[:, 6:], 0.0, atol=1e-7)


@pytest.fixture(scope="module")
def full_filtered() -> dict[str, raytrace.Image]:
    return {name: raytrace.render(every_ray_scene(), width=24, height=18, spp=4, threads=1,
                                  filter=name, aovs=["depth", "id"]) for name in WIDE}


@pytest.mark.parametrize("name", WIDE)
@pytest.mark.parametrize("threads", [1, 2])
@pytest.mark.parametrize("crop", [(5, 4, 17, 13), (0, 0, 24, 1), (23, 17, 24, 18)])
def test_a_filtered_crop_is_the_full_render_s_window(full_filtered, name, threads, crop):
    x0, y0, x1, y1 = crop
    part = raytrace.render(every_ray_scene(), width=24, height=18, spp=4, threads=threads,
                           pass_samples=37, crop=crop, filter=name, aovs=["depth", "id"])
    full = full_filtered[name]
    assert np.array_equal(part.rgb.view(np.uint32), full.rgb[y0:y1, x0:x1].view(np.uint32))
    for aov in ("depth", "id"):
        np.testing.assert_array_equal(part.aov(aov), full.aov(aov)[y0:y1, x0:x1])


def test_a_wide_filter_blurs_but_keeps_the_mean():
    box = raytrace.render(every_ray_scene(), width=24, height=18, spp=4, threads=1)
    tent = raytrace.render(every_ray_scene(), width=24, height=18, spp=4, threads=1,
                           filter="tent")
    assert not np.array_equal(box.rgb, tent.rgb)
    # Total-variation goes down under a positive low-pass filter.
    assert np.abs(np.diff(tent.rgb, axis=1)).sum() < np.abs(np.diff(box.rgb, axis=1)).sum()


def test_an_unknown_filter_is_one_error_naming_the_key(tmp_path):
    path = write_text(tmp_path / "s.toml", '[render]\nfilter = "lanczos"\n')
    with pytest.raises(SceneError) as e:
        raytrace.load_scene(path)
    assert e.value.key == "render.filter" and "mitchell" in str(e.value)
    assert str(path) in str(e.value)


def test_the_cli_flag_renders_and_a_bad_one_is_one_line(tmp_path, capsys):
    scene = write_text(tmp_path / "s.toml", '[render]\nwidth = 4\nheight = 3\n'
                       '[[objects]]\ntype = "sphere"\ncenter = [0, 0, -3]\nradius = 1\n')
    assert cli.main(["render", str(scene), "-o", str(tmp_path / "a.exr"), "--filter",
                     "mitchell", "-q"]) == 0
    rgb, _ = raytrace.read_exr(tmp_path / "a.exr")
    expected = raytrace.render(raytrace.load_scene(scene), filter="mitchell").rgb
    np.testing.assert_array_equal(rgb, expected)
    capsys.readouterr()
    assert cli.main(["render", str(scene), "-o", str(tmp_path / "b.exr"), "--filter",
                     "lanczos"]) == 2
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and "--filter" in err[0] and "lanczos" in err[0]
    assert sorted(os.listdir(tmp_path)) == ["a.exr", "s.toml"]
