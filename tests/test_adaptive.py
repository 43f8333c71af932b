"""Adaptive anti-aliasing (``aa = "adaptive"``): the refinement rule on closed-form images
(a flat frame traces its corners and no more; an edge refines exactly the pixels it crosses;
threshold 0 is uniform refinement to the deepest level), then the renderer's: sample counts
worked out by hand, and bit-identical images for any threads, pass size and crop."""

from __future__ import annotations

import os
import warnings

import numpy as np
import pytest
from helpers import make_scene, write_text
from test_threads import scene as every_ray_scene

import raytrace
from raytrace import cli
from raytrace.adaptive import levels, refine
from raytrace.errors import SceneError

W, H = 8, 6


def flat(x, y, ids):
    return np.tile([0.25, 0.5, 2.0], (len(x), 1))


def test_a_flat_frame_traces_each_corner_once_and_no_more():
    calls = []

    def trace(x, y, ids):
        calls.append(ids.copy())
        return flat(x, y, ids)

    pixels, deepest, traced = refine((0, 0, W, H), W, 3, 0.01, 0, trace)
    assert traced == (W + 1) * (H + 1) and len(calls) == 1
    assert len(np.unique(calls[0])) == len(calls[0])
    assert np.array_equal(pixels, np.tile([0.25, 0.5, 2.0], (W * H, 1)))
    assert not deepest.any()


def test_min_depth_cuts_every_pixel_whatever_its_corners():
    """``first`` = 1 on a flat frame: every pixel is 2×2 cells, the (2W + 1)·(2H + 1) points
    of the level-1 lattice, and nothing deeper; the pixels are still the flat colour."""
    pixels, deepest, traced = refine((0, 0, W, H), W, 3, 0.01, 0, flat, 1)
    assert traced == (2 * W + 1) * (2 * H + 1) and np.all(deepest == 1)
    assert np.array_equal(pixels, np.tile([0.25, 0.5, 2.0], (W * H, 1)))


def test_min_depth_sees_detail_between_the_corners():
    """A dot at a pixel's centre, away from its corners: the corners alone agree and leave
    the pixel dark; with one level everywhere the centre point sees it and the pixel is cut
    down to the deepest level."""
    def dot(x, y, ids):
        lit = (np.abs(x - 3.5) < 0.2) & (np.abs(y - 2.5) < 0.2)
        return np.repeat(lit.astype(float)[:, None], 3, 1)

    corners, deepest0, _ = refine((0, 0, W, H), W, 3, 0.5, 0, dot)
    assert not corners.any() and not deepest0.any()
    seen, deepest1, _ = refine((0, 0, W, H), W, 3, 0.5, 0, dot, 1)
    pixel = 2 * W + 3
    assert seen[pixel, 0] > 0.0 and deepest1[pixel] == 3
    assert np.count_nonzero(seen[:, 0]) == 1


def _side(x, y):
    """1 left of the line x = 3.3 + 0.4·y, else 0 (crosses columns 3 to 5 on 6 rows)."""
    return (x < 3.3 + 0.4 * y).astype(float)


def test_an_edge_refines_exactly_the_pixels_it_crosses():
    pixels, deepest, _ = refine((0, 0, W, H), W, 2, 0.5, 0,
                                lambda x, y, ids: np.repeat(_side(x, y)[:, None], 3, 1))
    # Pixel (c, r) is crossed where the line's x over the row, 3.3 + 0.4·[r, r + 1], meets
    # (c, c + 1): the corners of the pixel lie on both sides.
    crossed = np.zeros((H, W), bool)
    for r in range(H):
        lo, hi = 3.3 + 0.4 * r, 3.3 + 0.4 * (r + 1)
        crossed[r, int(np.floor(lo)):int(np.floor(hi)) + 1] = True
    assert np.array_equal(deepest.reshape(H, W) > 0, crossed)
    image = pixels[:, 0].reshape(H, W)
    r, c = np.mgrid[0:H, 0:W]
    whole = _side(c + 0.5, r + 0.5)  # an uncrossed pixel lies on one side: its centre's
    assert np.array_equal(image[~crossed], whole[~crossed])
    assert np.all((image[crossed] > 0.0) & (image[crossed] < 1.0))


def test_threshold_zero_is_uniform_refinement_to_the_deepest_level():
    depth, n = 2, 4
    side = W * n + 1  # lattice points a row

    def value(i, j):  # a smooth colour of the lattice point, jitter aside
        return np.stack([np.sin(0.3 * i) + j, 0.01 * i * j, np.cos(0.2 * j)], axis=-1)

    def trace(x, y, ids):
        j, i = np.divmod(ids, side)
        return value(i, j)

    pixels, deepest, traced = refine((0, 0, W, H), W, depth, 0.0, 0, trace)
    assert traced == (W * n + 1) * (H * n + 1) and np.all(deepest == depth)
    # Each pixel: the mean over its n×n finest cells of the mean of their four corners.
    j, i = np.mgrid[0:H * n + 1, 0:W * n + 1]
    v = value(i, j)
    cells = (v[:-1, :-1] + v[1:, :-1] + v[:-1, 1:] + v[1:, 1:]) / 4
    expected = cells.reshape(H, n, W, n, 3).mean(axis=(1, 3)).reshape(-1, 3)
    np.testing.assert_allclose(pixels, expected, rtol=1e-13, atol=1e-13)


def test_levels_of_lattice_points():
    # depth 2: pixel corners every 4 points; midpoints of a pixel every 2; the rest level 2
    assert levels(np.array([0, 4, 2, 2, 1, 3, 0]), np.array([0, 8, 0, 2, 0, 4, 1]),
                  2).tolist() == [0, 0, 1, 1, 2, 2, 2]


def _quad_scene(edge_x: float) -> raytrace.Scene:
    """Radiance 1 where x < edge_x on the plane z = −1 seen from the origin down −z, 0
    elsewhere: an ambient-only quad."""
    quad = raytrace.Mesh(vertices=[[-100, -100, -1], [edge_x, -100, -1], [edge_x, 100, -1],
                                   [-100, 100, -1]], faces=[[0, 1, 2], [0, 2, 3]],
                         material={"ka": 1.0, "kd": 0.0})
    return make_scene([quad], ambient=1.0, width=W, height=H, aa="adaptive", aa_threshold=0.5)


def test_the_renderer_traces_the_corners_of_a_flat_frame():
    scene = make_scene([], background=[0.1, 0.2, 0.3], width=W, height=H, aa="adaptive",
                       aa_threshold=0.01, aa_depth=3)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", raytrace.RenderWarning)
        image = raytrace.render(scene, threads=1)
    assert image.stats["rays"]["camera"] == (W + 1) * (H + 1)
    assert np.array_equal(image.rgb, np.broadcast_to(np.float32([0.1, 0.2, 0.3]), (H, W, 3)))


def test_the_renderer_refines_the_column_an_edge_crosses():
    # fov 40°, 8×6: the image plane's half width is tan 20°·4/3; x = 0.1 at z = −1 falls in
    # column (0.1/(tan 20°·4/3) + 1)·4 = 4.82: column 4 of every row is cut once (depth 1),
    # adding 4·H + 1 points (H + 1 edge midpoints on the rows' boundaries, 2·H on the
    # pixels' sides, H centres).
    image = raytrace.render(_quad_scene(0.1), aa_depth=1, threads=1)
    assert image.stats["rays"]["camera"] == (W + 1) * (H + 1) + 4 * H + 1
    rgb = image.rgb[..., 0]
    assert np.all(rgb[:, :4] == 1.0) and np.all(rgb[:, 5:] == 0.0)
    assert np.all((rgb[:, 4] > 0.0) & (rgb[:, 4] < 1.0))


def test_the_renderer_at_threshold_zero_traces_the_whole_lattice():
    image = raytrace.render(_quad_scene(0.1), aa_depth=2, aa_threshold=0.0, threads=1)
    assert image.stats["rays"]["camera"] == (4 * W + 1) * (4 * H + 1)
    assert image.stats["aa"]["samples_per_pixel"] == (4 * W + 1) * (4 * H + 1) / (W * H)


@pytest.fixture(scope="module")
def adaptive_full() -> raytrace.Image:
    return raytrace.render(every_ray_scene(), width=24, height=18, threads=1, aa="adaptive",
                           aa_threshold=0.02, aa_depth=2)


def test_adaptive_refines_some_pixels_of_the_scene(adaptive_full):
    spp = adaptive_full.stats["aa"]["samples_per_pixel"]
    # more than the corners alone, less than the whole depth-2 lattice
    assert 25 * 19 / (24 * 18) < spp < (4 * 24 + 1) * (4 * 18 + 1) / (24 * 18)


@pytest.mark.parametrize("threads", [1, 2])
@pytest.mark.parametrize("crop", [None, (5, 4, 17, 13), (0, 17, 24, 18)])
def test_adaptive_images_do_not_depend_on_threads_passes_or_crops(adaptive_full, threads,
                                                                   crop):
    x0, y0, x1, y1 = crop or (0, 0, 24, 18)
    part = raytrace.render(every_ray_scene(), width=24, height=18, threads=threads,
                           pass_samples=40, crop=crop, aa="adaptive", aa_threshold=0.02,
                           aa_depth=2)
    assert np.array_equal(part.rgb.view(np.uint32),
                          adaptive_full.rgb[y0:y1, x0:x1].view(np.uint32))


@pytest.mark.parametrize(("text", "key"), [
    ('aa = "fancy"', "render.aa"), ("aa_depth = 9", "render.aa_depth"),
    ("aa_threshold = -1", "render.aa_threshold"),
    ("aa_depth = 1\naa_min_depth = 2", "render.aa_min_depth"),
    ('aa = "adaptive"\nfilter = "tent"', "render.filter")])
def test_bad_adaptive_settings_name_their_key(tmp_path, text, key):
    path = write_text(tmp_path / "s.toml", f"[render]\n{text}\n")
    with pytest.raises(SceneError) as e:
        raytrace.load_scene(path)
    assert e.value.key == key and str(path) in str(e.value)


def test_adaptive_refuses_aovs():
    with pytest.raises(SceneError, match="aovs"):
        raytrace.render(_quad_scene(0.1), aovs=["depth"])


def test_the_cli_flags(tmp_path, capsys):
    scene = write_text(tmp_path / "s.toml", '[render]\nwidth = 8\nheight = 6\n'
                       '[[objects]]\ntype = "sphere"\ncenter = [0, 0, -3]\nradius = 1\n')
    out = tmp_path / "a.exr"
    assert cli.main(["render", str(scene), "-o", str(out), "--aa", "adaptive",
                     "--aa-threshold", "0.01", "--aa-depth", "3", "-q"]) == 0
    rgb, _ = raytrace.read_exr(out)
    expected = raytrace.render(raytrace.load_scene(scene), aa="adaptive", aa_threshold=0.01,
                               aa_depth=3)
    np.testing.assert_array_equal(rgb, expected.rgb)
    capsys.readouterr()
    assert cli.main(["render", str(scene), "-o", str(tmp_path / "b.exr"),
                     "--aa-depth", "12"]) == 2
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and "--aa-depth" in err[0]
    assert cli.main(["render", str(scene), "-o", str(tmp_path / "b.exr"),
                     "--aa-min-depth", "3"]) == 2  # more than the scene's aa_depth 2
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and "--aa-min-depth" in err[0]
    assert sorted(os.listdir(tmp_path)) == ["a.exr", "s.toml"]
    assert cli.main(["render", str(scene), "-o", str(tmp_path / "c.exr"), "--aa", "adaptive",
                     "--aa-min-depth", "1", "-q"]) == 0
    rgb, _ = raytrace.read_exr(tmp_path / "c.exr")
    expected = raytrace.render(raytrace.load_scene(scene), aa="adaptive", aa_min_depth=1)
    np.testing.assert_array_equal(rgb, expected.rgb)
