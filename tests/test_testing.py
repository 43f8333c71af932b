"""raytrace.testing: assert_image_close passes equal images, fails a one-pixel change above
tolerance with a message that says where and by how much, writes its artefacts, and takes an
Image, an array or an EXR path."""

from __future__ import annotations

import re

import numpy as np
import pytest
from helpers import read_png

import raytrace
from raytrace import testing
from raytrace.film import write_exr


def _grey(h=6, w=8, v=0.5) -> np.ndarray:
    return np.full((h, w, 3), v, np.float32)


def _one_pixel(delta: float, x=5, y=2) -> tuple[np.ndarray, np.ndarray]:
    expected = _grey()
    actual = expected.copy()
    actual[y, x, 1] += delta
    return actual, expected


def test_identical_images_pass_and_write_nothing(tmp_path):
    _, expected = _one_pixel(0)
    c = testing.assert_image_close(expected.copy(), expected, rtol=0, atol=0, artefacts=tmp_path)
    assert c.bad == 0 and c.metrics["max"] == 0 and c.metrics["psnr"] == np.inf
    assert list(tmp_path.iterdir()) == []


def test_one_pixel_above_tolerance_fails_with_where_and_how_much(tmp_path):
    actual, expected = _one_pixel(0.25)
    with pytest.raises(AssertionError) as e:
        testing.assert_image_close(actual, expected, rtol=1e-3, atol=1e-4, artefacts=tmp_path,
                                   name="grey")
    msg = str(e.value)
    assert "1 of 48 pixels" in msg and "at most 0 may be" in msg
    assert "(5, 2): [0.5, 0.75, 0.5] vs [0.5, 0.5, 0.5]" in msg   # x, y and both values
    assert f"max={0.25:.6g}" in msg and f"rmse={np.sqrt(0.25**2 / 144):.6g}" in msg
    assert "psnr=" in msg and "relmse=" in msg
    folder = re.search(r"artefacts: (\S+)/ ", msg).group(1)
    assert folder == str(testing.artefact_dir("grey", tmp_path))
    assert folder.endswith("test_testing.test_one_pixel_above_tolerance_fails_with_where_and_"
                           "how_much/grey")
    files = {p.name: p for p in (tmp_path / folder).iterdir()}
    assert sorted(files) == sorted(testing.ARTEFACT_FILES)
    got, _ = raytrace.read_exr(files["actual.exr"])
    np.testing.assert_array_equal(got, actual)
    diff = read_png(files["diff.png"])
    assert diff.shape == (6, 8, 3) and diff[2, 5].tolist() == [255, 255, 255]
    assert int(diff.sum()) == 3 * 255                  # only that pixel is lit
    panels = _panels(read_png(files["side_by_side.png"]), 6)   # expected | actual | diff
    assert [image.shape for _, image in panels] == [(6, 8, 3)] * 3
    (_, expected_png), (_, actual_png), (_, diff_png) = panels
    assert actual_png[2, 5].tolist() != expected_png[2, 5].tolist()  # the actual differs there
    np.testing.assert_array_equal(diff_png, diff)


def _panels(side: np.ndarray, rows: int) -> list[tuple[np.ndarray, np.ndarray]]:
    """The panels of a ``side_by_side.png`` of images ``rows`` high, left to right, as
    (caption strip, the image's first ``rows`` x 8 pixels): the panels are cut at the grey
    gap columns, each caption strip is the rows above the image."""
    gap = (side == 64).all(axis=(0, 2))
    edges = np.flatnonzero(np.diff(np.concatenate([[True], gap, [True]]).astype(int)))
    spans = edges.reshape(-1, 2)  # [start, end) of each run of non-gap columns
    strip = side.shape[0] - rows
    return [(side[:strip, a:b], side[strip:, a:a + 8]) for a, b in spans]


def test_side_by_side_names_each_panel(tmp_path):
    actual, expected = _one_pixel(0.25)
    with pytest.raises(AssertionError):
        testing.assert_image_close(actual, expected, rtol=0, atol=0, artefacts=tmp_path)
    side = read_png(testing.artefact_dir(None, tmp_path) / "side_by_side.png")
    assert side.shape[0] > 6  # a caption strip above the images
    strips = [strip for strip, _ in _panels(side, 6)]
    assert len(strips) == 3
    for strip in strips:  # white text on black, wider than the 8-pixel images
        assert strip.max() > 200 and (strip == 0).mean() > 0.5 and strip.shape[1] > 8
    # three different words: expected, actual, difference (the longest)
    assert strips[2].shape[1] > max(strips[0].shape[1], strips[1].shape[1])
    assert not np.array_equal(strips[0][:, :strips[1].shape[1]], strips[1])


def test_a_change_within_tolerance_passes(tmp_path):
    actual, expected = _one_pixel(0.5e-3)            # tolerance 1e-4 + 1e-3 · 0.5 = 6e-4
    testing.assert_image_close(actual, expected, rtol=1e-3, atol=1e-4, artefacts=tmp_path)
    actual, expected = _one_pixel(0.7e-3)
    with pytest.raises(AssertionError, match="1 of 48 pixels"):
        testing.assert_image_close(actual, expected, rtol=1e-3, atol=1e-4, artefacts=tmp_path)


def test_max_bad_fraction_allows_that_many_pixels(tmp_path):
    actual, expected = _one_pixel(1.0)
    actual[0, 0] = 9.0
    kw = dict(rtol=0, atol=1e-6, artefacts=tmp_path)
    testing.assert_image_close(actual, expected, max_bad_fraction=2 / 48, **kw)
    with pytest.raises(AssertionError, match="2 of 48 pixels .* at most 1 may be"):
        testing.assert_image_close(actual, expected, max_bad_fraction=1.99 / 48, **kw)


def test_worst_pixels_come_first_and_nan_counts_as_worst(tmp_path):
    expected = _grey()
    actual = expected.copy()
    actual[1, 1] = 0.6
    actual[4, 7] = 3.0
    actual[5, 0, 2] = np.nan
    with pytest.raises(AssertionError) as e:
        testing.assert_image_close(actual, expected, rtol=0, atol=0, artefacts=tmp_path)
    lines = str(e.value).splitlines()
    first = lines.index("worst pixels (x, y from the top left): actual vs expected")
    assert [ln.split(":")[0].strip() for ln in lines[first + 1:first + 4]] == [
        "(0, 5)", "(7, 4)", "(1, 1)"]


def test_nan_matches_nan_and_inf_matches_inf():
    expected = _grey()
    expected[0, 0] = np.nan
    expected[1, 1] = np.inf                      # e.g. the depth of a miss
    testing.assert_image_close(expected.copy(), expected, rtol=0, atol=0)


def test_image_array_and_exr_path_are_all_accepted(tmp_path):
    actual, expected = _one_pixel(0.25)
    write_exr(tmp_path / "expected.exr", expected)
    image = raytrace.Image(actual, metadata={"scene": "grey"})
    for a in (image, actual, str(tmp_path / "actual.exr")):
        if isinstance(a, str):
            write_exr(a, actual)
        for e in (expected, tmp_path / "expected.exr"):
            with pytest.raises(AssertionError, match=r"\(5, 2\)"):
                testing.assert_image_close(a, e, rtol=0, atol=1e-3,
                                           artefacts=tmp_path / "out")
    testing.assert_image_close(image, tmp_path / "actual.exr", rtol=0, atol=0)


def test_a_different_size_fails_with_both_sizes(tmp_path):
    with pytest.raises(AssertionError, match="actual is 8x6, expected is 4x3"):
        testing.assert_image_close(_grey(), _grey(3, 4), rtol=0, atol=0, artefacts=tmp_path)
    (folder,) = [p for p in tmp_path.rglob("*") if p.is_dir() and any(p.iterdir())]
    assert {"actual.exr", "expected.exr", "side_by_side.png"} <= {p.name for p in
                                                                 folder.iterdir()}


def test_metric_threshold_is_checked_in_its_direction(tmp_path):
    actual, expected = _one_pixel(0.25)
    kw = dict(rtol=0, atol=1.0, artefacts=tmp_path)          # the pixel test passes
    psnr = 10 * np.log10(144 / 0.25**2)                        # 33.6 dB
    testing.assert_image_close(actual, expected, metric="psnr", threshold=33.0, **kw)
    with pytest.raises(AssertionError, match=r"psnr = 33\.6\d* dB is below the threshold 34"):
        testing.assert_image_close(actual, expected, metric="psnr", threshold=34.0, **kw)
    assert psnr == pytest.approx(33.62, abs=0.01)
    c = testing.assert_image_close(actual, expected, metric="flip", threshold=0.5, **kw)
    assert 0 < c.metrics["flip"] < 0.5
    with pytest.raises(AssertionError, match="flip = .* is over the threshold 1e-06"):
        testing.assert_image_close(actual, expected, metric="flip", threshold=1e-6, **kw)


@pytest.mark.parametrize("kw,match", [
    (dict(metric="ssim"), "unknown metric 'ssim'"),
    (dict(threshold=0.1), "threshold needs a metric"),
    (dict(metric="rmse", threshold=-1), "finite number >= 0"),
    (dict(max_bad_fraction=1.5), "max_bad_fraction"),
    (dict(rtol=-1), "rtol and atol"),
])
def test_bad_arguments_are_errors_not_failures(kw, match):
    args = dict(rtol=0, atol=0) | kw
    with pytest.raises(ValueError, match=match):
        testing.assert_image_close(_grey(), _grey(), **args)


def test_artefact_folder_from_the_environment_and_the_test_name(tmp_path, monkeypatch):
    monkeypatch.setenv(testing.ARTEFACTS_ENV, str(tmp_path / "env"))
    monkeypatch.setenv("PYTEST_CURRENT_TEST", "tests/sub/test_a.py::TestB::test_c[x/y] (call)")
    assert testing.artefact_dir() == tmp_path / "env" / "test_a.TestB.test_c[x_y]"
    assert testing.artefact_dir("n", tmp_path) == tmp_path / "test_a.TestB.test_c[x_y]" / "n"
    monkeypatch.delenv(testing.ARTEFACTS_ENV)
    monkeypatch.delenv("PYTEST_CURRENT_TEST")
    assert testing.artefact_dir().as_posix() == "raytrace-artefacts/assert_image_close"


def test_artefacts_never_overwrite_an_input(tmp_path):
    actual, expected = _one_pixel(0.25)
    folder = testing.artefact_dir(None, tmp_path)
    folder.mkdir(parents=True)
    write_exr(folder / "expected.exr", expected)
    before = (folder / "expected.exr").read_bytes()
    with pytest.raises(ValueError, match="would overwrite the input"):
        testing.assert_image_close(actual, folder / "expected.exr", rtol=0, atol=0,
                                   artefacts=tmp_path)
    assert (folder / "expected.exr").read_bytes() == before
    assert sorted(p.name for p in folder.iterdir()) == ["expected.exr"]


def test_compare_images_report_is_json_ready():
    import json

    actual, expected = _one_pixel(0.25)
    d = testing.compare_images(actual, expected).to_dict()
    assert json.loads(json.dumps(d, allow_nan=False)) == d
    assert d["bad_pixels"] == 1 and d["worst"][0]["x"] == 5 and d["worst"][0]["y"] == 2
    same = testing.compare_images(expected, expected).to_dict()
    assert same["metrics"]["psnr"] == "inf" and same["worst"] == []
