"""The metric registry (raytrace/metrics.py): each metric against a value worked out by hand,
the direction of its threshold, HDR-FLIP through flip-evaluator, and the diff heatmap."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

from raytrace.film import metrics


def _pair(delta: float = 0.6):
    """A 4×5 grey 0.5 reference and a test with one of its 60 values raised by ``delta``."""
    ref = np.full((4, 5, 3), 0.5)
    test = ref.copy()
    test[1, 2, 0] += delta
    return test, ref


def test_hand_worked_values_of_one_changed_value():
    test, ref = _pair(0.6)
    mse = 0.36 / 60
    expected = {"rmse": np.sqrt(mse), "mae": 0.6 / 60, "max": 0.6,
                "relmse": 0.36 / (0.25 + 0.01) / 60, "psnr": 10 * np.log10(1 / mse)}
    for name, want in expected.items():
        assert metrics.get(name).function(test, ref) == pytest.approx(want, rel=1e-12), name


def test_identical_images():
    _, ref = _pair()
    for name in metrics.BASIC:
        value = metrics.get(name).function(ref, ref)
        assert value == (np.inf if name == "psnr" else 0.0), name


def test_within_follows_the_direction_and_refuses_nan():
    assert metrics.get("rmse").within(1e-3, 1e-3) and not metrics.get("rmse").within(2e-3, 1e-3)
    assert metrics.get("psnr").within(61.0, 60.0) and not metrics.get("psnr").within(59.0, 60.0)
    assert metrics.get("psnr").within(np.inf, 60.0)
    assert not metrics.get("rmse").within(np.nan, 1.0)
    assert not metrics.get("psnr").within(np.nan, 1.0)


def test_unknown_metric_lists_the_valid_names():
    with pytest.raises(ValueError, match="ssim") as e:
        metrics.get("ssim")
    assert all(name in str(e.value) for name in ("rmse", "mae", "max", "relmse", "psnr", "flip"))


@pytest.mark.parametrize("bad", [-1, -1e-9, np.nan, np.inf, "x", None])
def test_thresholds_must_be_finite_and_not_negative(bad):
    with pytest.raises(ValueError, match="must be a"):
        metrics.check_threshold(bad)
    assert metrics.check_threshold(0) == 0.0 and metrics.check_threshold("0.5") == 0.5


def test_flip_is_zero_for_equal_images_and_grows_with_the_error():
    test, ref = _pair(0.6)
    small, _ = _pair(0.06)
    assert metrics.flip(ref, ref) == 0.0
    assert 0.0 < metrics.flip(small, ref) < metrics.flip(test, ref) < 1.0
    error, _ = metrics.flip_map(test, ref)       # the map peaks at the changed pixel
    assert np.unravel_index(np.argmax(error), error.shape) == (1, 2)


def test_flip_is_flip_evaluator_with_the_reference_first():
    import flip_evaluator

    test, ref = _pair(0.6)
    ref[0, :, 1] = 2.0          # an HDR row: the exposure range comes from the reference
    _, mean, _ = flip_evaluator.evaluate(ref.astype(np.float32), test.astype(np.float32), "HDR")
    _, swapped, _ = flip_evaluator.evaluate(test.astype(np.float32), ref.astype(np.float32),
                                            "HDR")
    assert mean != swapped
    assert metrics.flip(test, ref) == mean
    error, mean2 = metrics.flip_map(test, ref)
    assert error.shape == (4, 5) and mean2 == mean


def test_flip_refuses_what_hdr_flip_does_not_define_without_ending_the_process():
    # flip-evaluator itself calls exit(-1) on a black reference; the guard must raise first.
    code = ("import numpy as np\nfrom raytrace.film import metrics\n"
            "for ref in (np.zeros((4, 4, 3)), np.full((4, 4, 3), 1e-8)):\n"
            "    try:\n        metrics.flip(ref + 0.5, ref)\n"
            "    except ValueError as e:\n        print('refused:', e)\n"
            "print('still running')\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=120)
    assert out.returncode == 0, out.stdout + out.stderr
    assert out.stdout.count("refused: FLIP needs a reference that is not black") == 2
    assert "still running" in out.stdout
    test, ref = _pair()
    for bad in (np.nan, np.inf, -1.0):
        broken = test.copy()
        broken[0, 0, 0] = bad
        with pytest.raises(ValueError, match="finite values >= 0"):
            metrics.flip(broken, ref)


def test_flip_without_the_package_names_the_extra(monkeypatch):
    monkeypatch.setitem(sys.modules, "flip_evaluator", None)   # import fails
    test, ref = _pair()
    with pytest.raises(ImportError, match=r"raytrace\[flip\]"):
        metrics.flip(test, ref)


def test_heatmap_white_at_the_worst_pixel_and_scaled_below():
    test, ref = _pair(0.6)
    test[3, 4] += 0.2           # a third of the worst difference: t = 1/3 -> pure red
    test[0, 0] = np.nan         # not finite: cyan
    pixels, scale = metrics.heatmap(test, ref)
    assert scale == pytest.approx(0.6)
    assert pixels.shape == (4, 5, 3) and pixels.dtype == np.uint8
    assert pixels[1, 2].tolist() == [255, 255, 255]
    assert pixels[3, 4].tolist() == [255, 0, 0]
    assert pixels[0, 0].tolist() == [0, 255, 255]
    assert pixels[2, 2].tolist() == [0, 0, 0]
    same, zero = metrics.heatmap(ref, ref)
    assert zero == 0.0 and not same.any()
