"""Previews (raytrace.film.tonemap): the wiring to colour-hdri's operators, the exact sRGB codes of
colour-science, automatic exposure, no overflow at any finite value, and no global state
left changed in the caller's process."""

from __future__ import annotations

import subprocess
import sys
import warnings

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from raytrace.film import tonemap
from raytrace.film.previews import auto_exposure, preview
from raytrace.film.tonemap import EXPOSURE_RANGE, TONEMAPS

with warnings.catch_warnings():
    warnings.simplefilter("ignore")
    import colour
    import colour_hdri

OPERATORS = [name for name in TONEMAPS if name != "clip"]
PER_PIXEL = [name for name in TONEMAPS if TONEMAPS[name].per_pixel]
PREFIX = "tonemapping_operator_"
#: colour-hdri's operators, found here by name: ``reinhard2004`` → its function.
INSTALLED = {n[len(PREFIX):].lower(): getattr(colour_hdri, n) for n in dir(colour_hdri)
             if n.startswith(PREFIX)}


def old_preview(rgb, exposure: float = 0.0, top: int = 255) -> np.ndarray:
    """The preview formula raytrace had before colour-hdri, as a reference: float64, non-finite
    as 0, max(x, 0)·2^EV, clip, colour-science's sRGB encoding, round."""
    x = np.nan_to_num(np.asarray(rgb, dtype=np.float64), nan=0.0, posinf=0.0, neginf=0.0)
    x = np.maximum(x, 0.0) * 2.0**exposure
    encoded = colour.cctf_encoding(np.clip(x, 0.0, 1.0), function="sRGB")
    return np.clip(np.round(encoded * top), 0, top).astype(np.uint8 if top == 255 else np.uint16)


def reference(rgb, name: str, exposure: float = 0.0, params: dict | None = None,
              top: int = 255) -> np.ndarray:
    """colour-hdri's own function on the exposed image, then the sRGB codes: what the preview
    must be (black where the operator gives NaN, i.e. 0/0 at black pixels)."""
    x = np.maximum(np.nan_to_num(np.asarray(rgb, np.float64), nan=0.0, posinf=0.0,
                                 neginf=0.0), 0.0) * 2.0**exposure
    with np.errstate(divide="ignore", invalid="ignore"):
        mapped = INSTALLED[name](x, **(params or {})) if name else x
    return old_preview(np.nan_to_num(mapped, nan=0.0), 0.0, top)


def hdr_image(h=37, w=29, seed=0) -> np.ndarray:
    """Log-uniform values over 10 decades, some black pixels, one NaN, one inf, negatives."""
    rng = np.random.default_rng(seed)
    rgb = (10.0 ** rng.uniform(-4, 6, (h, w, 3))).astype(np.float32)
    rgb[rng.random((h, w)) < 0.1] = 0.0
    rgb[0, 0] = [np.nan, np.inf, -1.0]
    rgb[1, 0] = [-np.inf, 0.5, 2.0]
    return rgb


# -- the registry -------------------------------------------------------------------------------
def test_the_operators_are_colour_hdris_by_its_own_names():
    # Every global operator colour-hdri exposes, under its name lower-cased without the prefix,
    # and each name mapped to that function; plus raytrace's own clip and reinhard.
    assert set(TONEMAPS) - {"clip", "reinhard"} == set(INSTALLED)
    for name, function in INSTALLED.items():
        assert TONEMAPS[name].function == function.__name__
    for name in ("reinhard2004", "filmic", "tumblin1999", "schlick1994", "logarithmic",
                 "exponential"):
        assert name in TONEMAPS
    assert TONEMAPS["reinhard"].function == PREFIX + "simple" and TONEMAPS["clip"].function is None


def test_unknown_names_and_parameters_are_one_line_errors_listing_the_valid_ones():
    with pytest.raises(ValueError, match="choose from clip, reinhard, .*reinhard2004"):
        preview(np.ones((1, 1, 3)), tonemap="reinhard2002")
    with pytest.raises(ValueError, match=r"no parameter 'key' \(it takes f, m, a, c\)"):
        preview(np.ones((1, 1, 3)), tonemap="reinhard2004", params={"key": 0.18})
    with pytest.raises(ValueError, match="must be a finite number"):
        preview(np.ones((1, 1, 3)), tonemap="reinhard2004", params={"f": float("nan")})
    with pytest.raises(ValueError, match="'clip' takes no parameters"):
        preview(np.ones((1, 1, 3)), params={"f": 1.0})
    with pytest.raises(ValueError, match="bit depth must be 8 or 16"):
        preview(np.ones((1, 1, 3)), bits=12)
    assert preview(np.ones((1, 1, 3)), tonemap="Filmic").shape == (1, 1, 3)  # any case


# -- the wiring: each operator is colour-hdri's function ------------------------------------------
@pytest.mark.parametrize("name", OPERATORS)
def test_each_operator_is_colour_hdris_function_on_the_same_input(name, monkeypatch):
    # Small bands (3 rows) so the per-pixel operators run band by band here.
    monkeypatch.setattr(tonemap, "BAND_PIXELS", 3 * 29)
    rgb = hdr_image()
    hdri = "simple" if name == "reinhard" else name
    for exposure in (0.0, -7.5):
        np.testing.assert_array_equal(preview(rgb, exposure, name),
                                      reference(rgb, hdri, exposure))
    np.testing.assert_array_equal(preview(rgb, 1.0, name, bits=16),
                                  reference(rgb, hdri, 1.0, top=65535))


@pytest.mark.parametrize("name,params", [("reinhard2004", {"f": -2.0, "m": 0.6, "a": 0.5,
                                                           "c": 0.25}),
                                         ("filmic", {"exposure_bias": 4, "linear_whitepoint": 6}),
                                         ("tumblin1999", {"L_da": 40.0, "C_max": 50.0}),
                                         ("gamma", {"gamma": 2.2, "EV": -1.0})])
def test_operator_parameters_reach_colour_hdri(name, params):
    rgb = hdr_image(seed=3)
    got = preview(rgb, 0.5, name, params=params)
    np.testing.assert_array_equal(got, reference(rgb, name, 0.5, params))
    assert not np.array_equal(got, preview(rgb, 0.5, name))  # the parameters changed it


# -- clip and reinhard keep their exact output -------------------------------------------------
def test_clip_is_the_old_formula_bit_for_bit_on_random_data():
    rng = np.random.default_rng(20)
    rgb = (rng.random((400, 500, 3)) ** 3 * 1.5).astype(np.float32)  # dense near 0 and 1
    rgb[:2] = hdr_image(2, 500)
    for exposure in (0.0, 1.0, -2.5, 0.3, 7.0):
        np.testing.assert_array_equal(preview(rgb, exposure), old_preview(rgb, exposure))
    np.testing.assert_array_equal(preview(rgb, 0.0, bits=16), old_preview(rgb, 0.0, 65535))


def test_every_8_bit_code_boundary_is_colour_sciences():
    # Just below and at each threshold the code steps exactly as the float64 formula does.
    t = tonemap.srgb_table(8).thresholds[:-1]
    below = np.nextafter(t, -np.inf)
    for y in (t, below):
        rgb = np.repeat(y[None, :, None], 3, axis=2)  # float64 input, read as is
        np.testing.assert_array_equal(preview(rgb), old_preview(rgb))
    np.testing.assert_array_equal(preview(np.repeat(t[None, :, None], 3, 2))[0, :, 0],
                                  np.arange(1, 256))


def test_reinhard_is_still_x_over_1_plus_x():
    rgb = hdr_image(seed=5)
    x = np.maximum(np.nan_to_num(rgb.astype(np.float64), nan=0, posinf=0, neginf=0), 0) * 2.0
    np.testing.assert_array_equal(preview(rgb, 1.0, "reinhard"), old_preview(x / (1.0 + x)))


# -- automatic exposure -------------------------------------------------------------------------
@settings(max_examples=40, deadline=None)
@given(level=st.floats(min_value=float(np.float32(1.4e-45)),
                      max_value=float(np.finfo(np.float32).max), allow_subnormal=True, width=32))
def test_auto_exposure_maps_a_uniform_grey_of_any_level_to_the_same_preview(level):
    grey = np.full((4, 5, 3), level, np.float32)
    # clip: the log-average lands on the key 0.18, sRGB 0.4614 → 117.7 → 118.
    assert np.all(preview(grey, "auto") == 118)
    for name in OPERATORS:
        np.testing.assert_array_equal(preview(grey, "auto", name),
                                      preview(np.ones_like(grey), "auto", name), err_msg=name)


def test_auto_exposure_is_the_key_over_the_log_average_of_lit_pixels():
    # log-average of 0.09 and 0.36 (geometric mean 0.18) over the lit pixels: EV 0. Black
    # pixels are left out, so a black background does not change it.
    rgb = np.zeros((4, 4, 3), np.float32)
    rgb[0] = 0.09
    rgb[1] = 0.36
    assert auto_exposure(rgb) == pytest.approx(0.0, abs=1e-6)  # float32 0.09, 0.36
    assert auto_exposure(rgb * 8.0) == pytest.approx(auto_exposure(rgb) - 3.0, abs=1e-12)
    # Luminance by the Rec. 709 primaries: pure green 1 has Y = 0.7152.
    green = np.zeros((2, 2, 3), np.float32)
    green[..., 1] = 1.0
    y = colour.RGB_luminance([0, 1, 0], colour.RGB_COLOURSPACES["sRGB"].primaries,
                             colour.RGB_COLOURSPACES["sRGB"].whitepoint)
    assert y == pytest.approx(0.7152, abs=1e-4)
    assert auto_exposure(green) == pytest.approx(np.log2(0.18 / y), abs=1e-12)
    assert auto_exposure(np.zeros((3, 3, 3))) == 0.0  # nothing lit: no change
    assert auto_exposure(np.full((2, 2, 3), np.nan)) == 0.0


# -- no overflow, no warnings, at any finite value ----------------------------------------------
EXTREMES = np.array([0.0, 1.4e-45, 1.2e-38, 1e-30, 1e-6, 0.18, 1.0, 1e6, 1e30, 3.4028235e38],
                    np.float32)


@settings(max_examples=60, deadline=None)
@given(values=st.lists(st.floats(min_value=0.0, max_value=float(np.finfo(np.float32).max),
                                 width=32), min_size=1, max_size=12),
       stops=st.one_of(st.floats(*EXPOSURE_RANGE), st.sampled_from(EXPOSURE_RANGE)),
       auto=st.booleans(), name=st.sampled_from(list(TONEMAPS)))
def test_no_finite_value_overflows_at_any_exposure(values, stops, auto, name):
    # A row of greys, sorted: every operator is increasing in luminance for a fixed image, so
    # the codes must not decrease along the row (an overflow to inf and then NaN would show
    # as a black pixel after white ones); overflow raises here instead of warning.
    grey = np.sort(np.concatenate([EXTREMES, np.asarray(values, np.float32)]))
    rgb = np.repeat(grey[None, :, None], 3, axis=2)
    exposure = "auto" if auto else stops
    with warnings.catch_warnings(), np.errstate(over="raise"):
        warnings.simplefilter("error")
        codes = preview(rgb, exposure, name)[0, :, 0]
    assert codes.dtype == np.uint8
    assert np.all(np.diff(codes.astype(int)) >= 0), codes
    if name == "clip":
        ev = auto_exposure(rgb) if exposure == "auto" else exposure
        np.testing.assert_array_equal(codes, old_preview(rgb, ev)[0, :, 0])


@pytest.mark.parametrize("bad", [2000.0, -256.5, float("nan"), float("inf"), "nan", "-inf",
                                 "bright", None, True])
def test_bad_exposures_are_refused(bad):
    with pytest.raises(ValueError, match=r"finite number of stops in \[-256, 256\] or 'auto'"):
        preview(np.ones((1, 1, 3)), bad)
    assert tonemap.check_exposure("AUTO") == "auto" and tonemap.check_exposure("-2.5") == -2.5


# -- no global state ---------------------------------------------------------------------------
def test_a_preview_leaves_numpys_print_options_as_they_were():
    # colour and colour_hdri set legacy="1.13" when imported; a fresh process must see its own
    # options unchanged after a preview (the first one imports both), and a PNG written.
    code = (
        "import numpy as np, raytrace, tempfile, os\n"
        "np.set_printoptions(precision=5)\n"
        "before = np.get_printoptions()\n"
        "image = raytrace.Image(np.full((2, 3, 3), 0.5, np.float32))\n"
        "image.preview(tonemap='reinhard2004')\n"
        "image.save(os.path.join(tempfile.mkdtemp(), 'p.png'), exposure='auto')\n"
        "import sys; assert 'colour_hdri' in sys.modules and 'OpenImageIO' in sys.modules\n"
        "after = np.get_printoptions()\n"
        "print(before == after, after['legacy'], repr(np.float64(0.1)))\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    assert out.stdout.split() == ["True", "False", "np.float64(0.1)"]


def test_every_16_bit_code_boundary_is_colour_sciences():
    # The thresholds are found with raytrace's own float64 sRGB encoding (no colour import on
    # the preview's path): at each one colour's encoding gives the next code, just below it
    # the one before, so every code is the one colour-science's formula gives.
    t = tonemap.srgb_table(16).thresholds[:-1]

    def code(y):
        return np.round(colour.cctf_encoding(y, function="sRGB") * 65535)

    np.testing.assert_array_equal(code(t), np.arange(1, 65536))
    np.testing.assert_array_equal(code(np.nextafter(t, -np.inf)), np.arange(0, 65535))


def test_a_clip_preview_does_not_import_colour():
    import subprocess
    import sys

    probe = ("import sys, numpy as np, raytrace; raytrace.Image(np.ones((4, 4, 3), np.float32))"
             ".preview(); print('colour' in sys.modules)")
    assert subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True,
                          check=True).stdout.strip() == "False"
