"""Crop windows: ``render(..., crop=(x0, y0, x1, y1))`` and ``--crop`` render only those
pixels (half-open bounds, like pbrt's ``--pixelbounds``), bit-identical to the same pixels of
the full render at any thread count and pass size; in the EXR the data window is the crop and
the display window the full frame."""

from __future__ import annotations

import os

import numpy as np
import pytest
from helpers import write_text
from test_threads import scene as every_ray_scene

import raytrace
from raytrace import cli

W, H, SPP = 48, 36, 4
#: Small passes (rounded down to whole pixels: 36 samples, 9 pixels), so a crop's passes
#: split its rows, and a glass pixel's rays outgrow a pass.
SMALL_PASS = 37
#: A 12×8 frame of a lit floor.
FLOOR = """
[render]
width = 12
height = 8
[camera]
position = [0.0, 1.0, 3.0]
look_at = [0.0, 0.0, 0.0]
[[lights]]
type = "point"
position = [1.0, 4.0, 2.0]
[[objects]]
type = "plane"
point = [0.0, 0.0, 0.0]
normal = [0.0, 1.0, 0.0]
material = "green_plastic"
"""


@pytest.fixture(scope="module")
def full() -> raytrace.Image:
    # Stratified jittered samples and a jittered area light: both are keyed by the sample's
    # index in the full frame, which a crop must reproduce.
    return raytrace.render(every_ray_scene(), width=W, height=H, spp=SPP, threads=1,
                           aovs=["depth", "normal", "albedo", "id"])


def same_bits(a: np.ndarray, b: np.ndarray) -> bool:
    return a.shape == b.shape and np.array_equal(a.view(np.uint32), b.view(np.uint32))


@pytest.mark.parametrize("threads", [1, 2])
@pytest.mark.parametrize("crop", [(7, 5, 30, 22), (0, 0, W, 1), (47, 35, 48, 36),
                                  (0, 0, W, H), (20, 0, 21, H)])
def test_a_crop_is_the_full_render_s_window(full, threads, crop):
    x0, y0, x1, y1 = crop
    part = raytrace.render(every_ray_scene(), width=W, height=H, spp=SPP, threads=threads,
                           pass_samples=SMALL_PASS, crop=crop,
                           aovs=["depth", "normal", "albedo", "id"])
    assert part.rgb.shape == (y1 - y0, x1 - x0, 3)
    assert same_bits(part.rgb, full.rgb[y0:y1, x0:x1])
    for name in ("depth", "normal", "albedo", "id"):
        np.testing.assert_array_equal(part.aov(name), full.aov(name)[y0:y1, x0:x1])
    assert part.crop == crop and part.frame == (W, H)
    assert part.stats["rays"]["camera"] == (x1 - x0) * (y1 - y0) * SPP
    assert part.stats["crop"] == list(crop)


@pytest.mark.parametrize("crop", [(1, 1, W - 1, H - 1), (2, 2, W - 2, H - 2), (0, 1, W, H)])
def test_a_crop_under_a_wide_filter_is_the_full_render_s_window(crop):
    """A filter wider than a pixel (Gaussian: one pixel's reach) traces the crop grown by its
    reach, clipped to the frame; where that is the whole frame, the crop's pixels are still
    the full render's."""
    kw = dict(width=W, height=H, spp=SPP, threads=1, filter="gaussian")
    whole = raytrace.render(every_ray_scene(), **kw)
    x0, y0, x1, y1 = crop
    part = raytrace.render(every_ray_scene(), crop=crop, pass_samples=SMALL_PASS, **kw)
    assert same_bits(part.rgb, whole.rgb[y0:y1, x0:x1])


def test_the_exr_data_window_is_the_crop_in_the_full_display_window(full, tmp_path):
    import OpenEXR

    scene = write_text(tmp_path / "floor.toml", FLOOR)
    out = tmp_path / "crop.exr"
    assert cli.main(["render", str(scene), "-o", str(out), "--crop", "3", "2", "9", "5",
                     "--aov", "depth", "-q", "--threads", "2"]) == 0
    with OpenEXR.File(str(out), separate_channels=True) as f:
        header = dict(f.header())
        r = f.channels()["R"].pixels.copy()
    (dx0, dy0), (dx1, dy1) = header["dataWindow"]
    (fx0, fy0), (fx1, fy1) = header["displayWindow"]
    assert (dx0, dy0, dx1, dy1) == (3, 2, 8, 4)          # inclusive: x 3..8, y 2..4
    assert (fx0, fy0, fx1, fy1) == (0, 0, 11, 7)         # the 12×8 frame
    whole = raytrace.render(raytrace.load_scene(scene), threads=1)
    np.testing.assert_array_equal(r, whole.rgb[2:5, 3:9, 0])
    back = raytrace.Image.from_exr(out)
    assert back.crop == (3, 2, 9, 5) and back.frame == (12, 8)
    assert back.aov("depth").shape == (3, 6)


@pytest.mark.parametrize(("crop", "says"), [
    ((0, 0, 0, 5), "0 <= x0 < x1 <= 12"),       # empty
    ((5, 1, 3, 4), "x bounds 5..3"),             # reversed
    ((-1, 0, 4, 4), "x bounds -1..4"),           # outside, left
    ((0, 0, 12, 9), "y bounds 0..9"),            # outside, below
    ((0, 0, 4), "4 pixel bounds"),               # three numbers
    ((0, 0, 4.5, 4), "whole number"),            # not a pixel bound
])
def test_bad_crops_are_one_clear_error(tmp_path, crop, says):
    scene = raytrace.load_scene(write_text(tmp_path / "floor.toml", FLOOR))
    with pytest.raises(raytrace.SceneError) as e:
        raytrace.render(scene, crop=crop)
    assert e.value.key == "crop" and says in str(e.value)
    assert e.value.file and e.value.file.endswith("floor.toml")


@pytest.mark.parametrize("bounds", [["0", "0", "13", "8"], ["4", "4", "4", "6"]])
def test_a_bad_crop_flag_is_one_line_and_writes_nothing(tmp_path, capsys, bounds):
    scene = write_text(tmp_path / "floor.toml", FLOOR)
    rc = cli.main(["render", str(scene), "-o", str(tmp_path / "o.exr"), "--crop", *bounds])
    err = capsys.readouterr().err
    assert rc == 2 and len(err.splitlines()) == 1, err
    assert "floor.toml" in err and "--crop" in err and "12x8" in err
    assert sorted(os.listdir(tmp_path)) == ["floor.toml"]


def test_the_terminal_summary_names_the_crop(tmp_path, monkeypatch):
    import io
    import sys

    class Terminal(io.StringIO):
        def isatty(self) -> bool:
            return True

    scene, out = write_text(tmp_path / "floor.toml", FLOOR), tmp_path / "c.exr"
    monkeypatch.setattr(sys, "stderr", Terminal())
    assert cli.main(["render", str(scene), "-o", str(out), "--crop", "1", "2", "5", "7"]) == 0
    last = sys.stderr.getvalue().replace("\r", "\n").strip().splitlines()[-1]
    assert last.startswith(f"wrote {out}: crop 1 2 5 7 of 12×8, 1 spp, ")


@pytest.mark.parametrize("tile", [1, 7, 16, 36, 100])
def test_tiles_of_any_size_put_together_are_the_full_render(full, tile):
    """A distributed render's tiles (raytrace.distributed.tile_grid) are crops: rendered one
    by one and put in place they are the full image, bit for bit, whatever the tile size
    (cut tiles at the right and bottom edges included), and cover each pixel once."""
    from raytrace.distributed import tile_grid

    grid = tile_grid((0, 0, W, H), tile)
    covered = np.zeros((H, W), np.int64)
    image = np.full((H, W, 3), np.nan, np.float32)
    for x0, y0, x1, y1 in (grid if tile > 1 else grid[::97]):  # 1728 one-pixel tiles: a few
        part = raytrace.render(every_ray_scene(), width=W, height=H, spp=SPP, threads=1,
                               pass_samples=SMALL_PASS, crop=(x0, y0, x1, y1))
        image[y0:y1, x0:x1] = part.rgb
        assert same_bits(part.rgb, full.rgb[y0:y1, x0:x1])
    for x0, y0, x1, y1 in grid:
        covered[y0:y1, x0:x1] += 1
    assert (covered == 1).all()
    if tile > 1:
        assert same_bits(image, full.rgb)


def test_for_window_reuses_the_build_for_any_window_even_at_once(full):
    """WhittedIntegrator.for_window: a copy for another crop sharing the built accelerator
    (no second BVH build), with its own per-render state, so copies render side by side."""
    from concurrent.futures import ThreadPoolExecutor

    from raytrace.integrator import WhittedIntegrator
    from raytrace.rendering import render_options

    options = render_options(every_ray_scene(), width=W, height=H, spp=SPP, threads=1,
                             pass_samples=SMALL_PASS)
    base = WhittedIntegrator(every_ray_scene(), options)
    crops = [(0, 0, 20, 36), (20, 0, 48, 13), (20, 13, 48, 36), None]
    copies = [base.for_window(c, threads=2) for c in crops]
    assert all(c.accel is base.accel and c.table is base.table for c in copies)
    with ThreadPoolExecutor(4) as pool:
        images = list(pool.map(lambda c: c.render(), copies))
    for crop, image in zip(crops, images, strict=True):
        x0, y0, x1, y1 = crop or (0, 0, W, H)
        assert same_bits(image.rgb, full.rgb[y0:y1, x0:x1])
        assert image.stats["seconds"]["build"] == 0.0 and image.stats["threads"] == 2
        assert image.stats["rays"]["camera"] == (x1 - x0) * (y1 - y0) * SPP
    assert base.opt.crop is None and base.opt.threads == 1  # the original is untouched
