"""The film: bit-exact float EXR round trips with the header we promise, PNG previews in
range, and atomic writes."""

from __future__ import annotations

import os

import numpy as np
import OpenEXR
import pytest
from helpers import aimed_camera, make_scene, read_png, read_png_library

import raytrace
from raytrace.film import EXR_COMPRESSIONS, atomic_path, preview, write_exr, write_png
from raytrace.film.exr import SRGB_CHROMATICITIES

HDR = np.array([1e6, -3.5, 1e-30, 0.0, -0.0, 1.4e-45, 3.0e38, 0.5, 1.0 / 3.0, -1e-7, 65504.0,
                123456.789], dtype=np.float32)


def _hdr_image(h=5, w=7, seed=0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    rgb = rng.choice(HDR, size=(h, w, 3)).astype(np.float32)
    rgb.flat[: len(HDR)] = HDR                       # every special value at least once
    return rgb


def _same_bits(a: np.ndarray, b: np.ndarray) -> None:
    assert a.dtype == np.float32 and b.dtype == np.float32 and a.shape == b.shape
    np.testing.assert_array_equal(a.view(np.uint32), b.view(np.uint32))


def test_exr_round_trip_is_bit_exact(tmp_path):
    rgb = _hdr_image()
    write_exr(tmp_path / "a.exr", rgb)
    back, _ = raytrace.read_exr(tmp_path / "a.exr")
    _same_bits(back, rgb)


def test_exr_round_trip_of_a_strided_view(tmp_path):
    big = _hdr_image(12, 15, seed=1)
    for view in (big[::2, ::3], big[:, ::-1], big.transpose(1, 0, 2), big[..., ::-1]):
        assert not view.flags.c_contiguous
        write_exr(tmp_path / "v.exr", view)
        back, _ = raytrace.read_exr(tmp_path / "v.exr")
        _same_bits(back, np.ascontiguousarray(view))


def test_reading_a_missing_exr_is_file_not_found_and_silent(tmp_path, capfd):
    # capfd: the OpenEXR library would print its own line on the process's stderr.
    with pytest.raises(FileNotFoundError) as e:
        raytrace.read_exr(tmp_path / "missing.exr")
    assert e.value.filename == str(tmp_path / "missing.exr")
    with pytest.raises(IsADirectoryError):
        raytrace.read_exr(tmp_path)
    assert capfd.readouterr() == ("", "")


def test_a_damaged_exr_is_one_scene_error_naming_the_file(tmp_path):
    # The binding raised a bare RuntimeError (or, truncated, a ValueError about "0 parts").
    good = tmp_path / "good.exr"
    write_exr(good, np.ones((32, 32, 3), np.float32))
    data = good.read_bytes()
    damaged = {"garbage.exr": np.random.default_rng(28).bytes(500), "empty.exr": b"",
               "header-only.exr": data[:40], "truncated.exr": data[:len(data) // 2]}
    for name, content in damaged.items():
        (tmp_path / name).write_bytes(content)
        for read in (raytrace.Image.from_exr, raytrace.read_exr):
            with pytest.raises(raytrace.SceneError) as e:
                read(tmp_path / name)
            assert str(e.value).startswith(f"{tmp_path / name}: not a readable OpenEXR file: "
                                           "damaged, truncated or another format (OpenEXR: ")
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    OpenEXR.File(header, {"Y": np.ones((4, 4), np.float32)}).write(str(tmp_path / "grey.exr"))
    with pytest.raises(raytrace.SceneError) as e:
        raytrace.Image.from_exr(tmp_path / "grey.exr")
    assert str(e.value) == f"{tmp_path / 'grey.exr'}: no channel(s) R, G, B (has Y)"


def test_exr_header_has_srgb_chromaticities_and_render_settings(tmp_path):
    scene = make_scene([raytrace.Sphere([0, 0, 0], 1.0)], [raytrace.PointLight([2, 2, 2])],
                       camera=aimed_camera([0, 0, 4], [0, 0, 0]))
    image = raytrace.render(scene, width=6, height=4, spp=4, max_depth=3, seed=9)
    image.save(tmp_path / "r.exr")
    back, header = raytrace.read_exr(tmp_path / "r.exr")
    _same_bits(back, image.rgb)
    # Stored as float32 in the file.
    np.testing.assert_allclose(header["chromaticities"], SRGB_CHROMATICITIES, rtol=1e-7)
    assert (header["raytrace:width"], header["raytrace:height"]) == (6, 4)
    assert header["raytrace:spp"] == 4 and header["raytrace:max_depth"] == 3
    assert header["raytrace:seed"] == 9


def test_srgb_chromaticities_are_rec709_d65():
    # ITU-R BT.709: R (0.64, 0.33), G (0.30, 0.60), B (0.15, 0.06), D65 (0.3127, 0.3290).
    assert SRGB_CHROMATICITIES == (0.64, 0.33, 0.30, 0.60, 0.15, 0.06, 0.3127, 0.3290)


def test_png_preview_of_known_greys(tmp_path):
    # sRGB encoding (IEC 61966-2-1): 1.055·x^(1/2.4) − 0.055 above 0.0031308, 12.92·x below.
    # linear 0.5 → 0.73536 → ·255 = 187.5 → 188; 0.002 → 0.02584 → 6.59 → 7; 0.18 → 117.9 → 118.
    lin = np.array([0.0, 0.5, 1.0, 0.002, 0.18, 2.0, -1.0, np.nan])
    rgb = np.repeat(lin[None, :, None], 3, axis=2)
    assert preview(rgb).dtype == np.uint8
    expected = [0, 188, 255, 7, 118, 255, 0, 0]
    np.testing.assert_array_equal(preview(rgb)[0, :, 0], expected)
    write_png(tmp_path / "g.png", rgb)
    png = read_png(tmp_path / "g.png")
    assert png.shape == (1, len(lin), 3)
    np.testing.assert_array_equal(png[0, :, 1], expected)
    # one stop of exposure doubles: 0.25 → 0.5 → 188
    np.testing.assert_array_equal(preview(np.full((1, 1, 3), 0.25), exposure=1.0), 188)


def test_preview_of_a_1e6_light_stays_in_range(tmp_path):
    scene = make_scene([raytrace.Plane([0, 0, 0], [0, 1, 0], material=raytrace.Material(kd=0.8))],
                       [raytrace.PointLight([0, 1, 0], color=1e6)],
                       camera=raytrace.Camera(position=[0, 1, 4], look_at=[0, 0, 0]))
    image = raytrace.render(scene, width=16, height=12)
    lit = image.rgb[..., 0] > 0
    assert image.rgb.max() > 1e4 and lit.any() and (~lit).any()
    for tonemap in ("clip", "reinhard"):
        image.save(tmp_path / f"{tonemap}.png", tonemap=tonemap)
        png = read_png(tmp_path / f"{tonemap}.png")
        assert png.dtype == np.uint8 and png.shape == (12, 16, 3)
        # Saturated, not wrapped around: a very bright pixel is (nearly) white, the sky black.
        assert np.all(png[lit] >= 254) and np.all(png[~lit] == 0)


def test_reinhard_preview_maps_1_to_half():
    # x/(1 + x) at x = 1 is 0.5 → 188 after the sRGB encoding.
    np.testing.assert_array_equal(preview(np.ones((1, 1, 3)), tonemap="reinhard"), 188)
    with pytest.raises(ValueError, match="reinhard"):
        preview(np.ones((1, 1, 3)), tonemap="nope")


def test_failing_exr_write_leaves_the_old_file_and_no_temp(tmp_path, monkeypatch):
    target = tmp_path / "out.exr"
    target.write_bytes(b"the old image")
    real_file = OpenEXR.File

    class FailingFile:
        """Writes a partial file, then fails like a full disk."""

        def __init__(self, *args, **kwargs):
            self._f = real_file(*args, **kwargs)

        def __enter__(self):
            return self

        def __exit__(self, *exc):
            return False

        def write(self, path):
            with open(path, "wb") as f:
                f.write(b"\x76\x2f\x31\x01 truncated")
            raise OSError("No space left on device")

    monkeypatch.setattr(OpenEXR, "File", FailingFile)
    with pytest.raises(OSError, match="No space"):
        write_exr(target, _hdr_image())
    assert target.read_bytes() == b"the old image"
    assert os.listdir(tmp_path) == ["out.exr"]


def test_interrupted_write_leaves_the_old_file_and_no_temp(tmp_path):
    target = tmp_path / "out.png"
    target.write_bytes(b"old")
    with pytest.raises(KeyboardInterrupt), atomic_path(target, ".png") as tmp:
        tmp.write_bytes(b"half")
        raise KeyboardInterrupt
    assert target.read_bytes() == b"old"
    assert os.listdir(tmp_path) == ["out.png"]
    # And a completed block replaces it.
    with atomic_path(target, ".png") as tmp:
        tmp.write_bytes(b"new")
    assert target.read_bytes() == b"new" and os.listdir(tmp_path) == ["out.png"]


def test_bad_shapes_and_types_are_refused_before_writing(tmp_path):
    with pytest.raises(ValueError, match="H, W, 3"):
        write_exr(tmp_path / "x.exr", np.zeros((4, 4)))
    with pytest.raises(ValueError, match="unknown image type"):
        raytrace.Image(np.zeros((2, 2, 3), np.float32)).save(tmp_path / "x.jpg")
    assert os.listdir(tmp_path) == []


def test_threaded_write_gives_the_same_bytes_and_restores_the_pool(tmp_path):
    # Compression on OpenEXR's pool must not change the file, and the process-wide pool size
    # must be put back (another library in the process may rely on it).
    import OpenEXR

    rng = np.random.default_rng(7)
    rgb = rng.random((97, 131, 3)).astype(np.float32) * 10.0  # several 16-line ZIP blocks
    before = OpenEXR.global_thread_count()
    write_exr(tmp_path / "one.exr", rgb, {"spp": 1}, threads=1)
    write_exr(tmp_path / "two.exr", rgb, {"spp": 1}, threads=2)
    assert OpenEXR.global_thread_count() == before
    assert (tmp_path / "one.exr").read_bytes() == (tmp_path / "two.exr").read_bytes()
    back, _ = raytrace.read_exr(tmp_path / "two.exr")
    assert np.array_equal(back, rgb)


# -- compression -----------------------------------------------------------------------------------

#: Every offered name → the OpenEXR binding's constant, written out here (not taken from
#: raytrace.film.EXR_COMPRESSIONS) so that a name mapped to the wrong compression fails.
EXPECTED_COMPRESSION = {"none": OpenEXR.NO_COMPRESSION, "rle": OpenEXR.RLE_COMPRESSION,
                        "zips": OpenEXR.ZIPS_COMPRESSION, "zip": OpenEXR.ZIP_COMPRESSION,
                        "piz": OpenEXR.PIZ_COMPRESSION,
                        "zstd": getattr(OpenEXR, "ZSTD_COMPRESSION", None)}  # binding >= 3.5
HAS_ZSTD = EXPECTED_COMPRESSION["zstd"] is not None
#: The compression attribute's byte in the file, from the OpenEXR file layout (ImfCompression.h):
#: NO 0, RLE 1, ZIPS 2, ZIP 3, PIZ 4. Read from the raw bytes, independently of the binding.
FILE_CODE = {"none": 0, "rle": 1, "zips": 2, "zip": 3, "piz": 4}


def _file_compression_code(path) -> int:
    """The one-byte value of the header attribute ``compression`` (name, type name, int32 size
    1, then the byte), found in the raw file."""
    data = path.read_bytes()
    tag = b"compression\x00compression\x00\x01\x00\x00\x00"
    assert data.count(tag) == 1
    return data[data.index(tag) + len(tag)]


def _awkward_image(h=40, w=37) -> np.ndarray:
    """Negatives, 1e-30, 3e38, denormals, −0 and a ramp: several 16- and 32-line blocks."""
    rgb = _hdr_image(h, w, seed=3)
    rgb[h // 2:, :, 1] = np.linspace(-2.0, 3.0e38, (h - h // 2) * w, dtype=np.float32).reshape(
        h - h // 2, w)
    rgb[:, : w // 2, 2] = np.linspace(1e-30, 1.0, h * (w // 2), dtype=np.float32).reshape(
        h, w // 2)
    return rgb


def _smooth_ramp(h=48, w=64) -> np.ndarray:
    y, x = np.mgrid[0:h, 0:w].astype(np.float32)
    return np.stack([x / w, y / h, (x + y) / (w + h)], axis=-1).astype(np.float32)


def test_offered_compressions_are_the_lossless_ones():
    assert set(EXR_COMPRESSIONS) == set(EXPECTED_COMPRESSION)
    for lossy in ("pxr24", "b44", "b44a", "dwaa", "dwab"):
        assert lossy not in EXR_COMPRESSIONS


@pytest.mark.parametrize("name", sorted(EXPECTED_COMPRESSION))
def test_every_compression_round_trips_bit_exactly_and_is_in_the_header(tmp_path, name):
    if name == "zstd" and not HAS_ZSTD:
        pytest.skip("this OpenEXR binding has no ZSTD (added in 3.5)")
    rgb = _awkward_image()
    path = tmp_path / f"{name}.exr"
    write_exr(path, rgb, {"spp": 1}, compression=name)
    back, header = raytrace.read_exr(path)
    _same_bits(back, rgb)
    assert header["compression"] == EXPECTED_COMPRESSION[name]
    if name in FILE_CODE:
        assert _file_compression_code(path) == FILE_CODE[name]
    # Compressed on a pool of 2: the same bytes, the pool size put back.
    before = OpenEXR.global_thread_count()
    write_exr(tmp_path / "two.exr", rgb, {"spp": 1}, threads=2, compression=name.upper())
    assert OpenEXR.global_thread_count() == before
    assert (tmp_path / "two.exr").read_bytes() == path.read_bytes()


def test_default_compression_is_zip_byte_for_byte(tmp_path):
    rgb = _awkward_image()
    write_exr(tmp_path / "default.exr", rgb, {"spp": 2})
    write_exr(tmp_path / "zip.exr", rgb, {"spp": 2}, compression="zip")
    assert _file_compression_code(tmp_path / "default.exr") == FILE_CODE["zip"]
    assert (tmp_path / "default.exr").read_bytes() == (tmp_path / "zip.exr").read_bytes()


def test_compressed_sizes_on_a_smooth_ramp(tmp_path):
    # OpenEXR stores a block raw when compressing would not shrink it, so no compression makes
    # a larger file than none; uncompressed float32 RGB holds at least H·W·3·4 bytes of pixels.
    # On a smooth ramp zlib finds the repetition: ZIP (16 lines per block) is smaller than
    # ZIPS (one line per block, so less context and more block overhead), ZIP smaller than raw.
    rgb = _smooth_ramp()
    size = {}
    for name in [n for n in EXPECTED_COMPRESSION if HAS_ZSTD or n != "zstd"]:
        write_exr(tmp_path / f"{name}.exr", rgb, compression=name)
        size[name] = (tmp_path / f"{name}.exr").stat().st_size
    raw = rgb.size * 4
    assert size["none"] >= raw
    assert all(size[name] <= size["none"] for name in size), size
    assert size["zip"] < size["zips"] < size["none"], size
    assert size["zip"] < 0.9 * raw and size.get("zstd", 0) < 0.9 * raw, size


def test_image_save_passes_the_compression_through(tmp_path):
    image = raytrace.Image(_awkward_image(6, 5), metadata={"spp": 1})
    image.save(tmp_path / "piz.exr", compression="piz")
    image.save(tmp_path / "default.exr")
    assert _file_compression_code(tmp_path / "piz.exr") == FILE_CODE["piz"]
    assert _file_compression_code(tmp_path / "default.exr") == FILE_CODE["zip"]
    _same_bits(raytrace.read_exr(tmp_path / "piz.exr")[0], image.rgb)


@pytest.mark.parametrize("bad", ["zip2", "dwaa", "pxr24", "", None])
def test_unknown_compression_is_refused_before_writing(tmp_path, bad):
    with pytest.raises(ValueError) as e:
        write_exr(tmp_path / "x.exr", _hdr_image(), compression=bad)
    message = str(e.value)
    assert len(message.splitlines()) == 1 and repr(bad) in message
    assert all(name in message for name in EXPECTED_COMPRESSION), message
    with pytest.raises(ValueError, match="unknown EXR compression"):
        raytrace.Image(_hdr_image()).save(tmp_path / "y.exr", compression=bad)
    assert os.listdir(tmp_path) == []


def test_compression_missing_from_an_older_binding_is_a_clear_error(tmp_path, monkeypatch):
    monkeypatch.delattr(OpenEXR, "ZSTD_COMPRESSION", raising=False)
    with pytest.raises(ValueError, match="'zstd' needs a newer OpenEXR"):
        write_exr(tmp_path / "x.exr", _hdr_image(), compression="zstd")
    assert os.listdir(tmp_path) == []


def test_a_preview_before_the_first_render_leaves_rendering_working():
    # Without SciPy, colour-science (the preview's sRGB encoding) puts a mock in
    # sys.modules["scipy"], and numba's import then failed: raytrace.testing writes previews
    # of arrays, so a test suite could preview before it renders. A fresh interpreter shows it.
    import subprocess
    import sys

    code = ("import numpy as np, raytrace\nfrom raytrace.film import preview\n"
            "print(preview(np.full((1, 1, 3), 0.5))[0, 0].tolist())\n"
            "scene = raytrace.load_scene('scenes/whitted.toml')\n"
            "print(raytrace.render(scene, width=4, height=3, threads=1).rgb.shape)\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=300, cwd=os.path.dirname(os.path.dirname(__file__)))
    assert out.returncode == 0, out.stderr[-2000:]
    assert out.stdout.split("\n")[:2] == ["[188, 188, 188]", "(3, 4, 3)"]


# -- previews: 16-bit PNG, notebooks ------------------------------------------------------------
def test_16_bit_png_round_trips_through_the_image_library(tmp_path):
    import OpenImageIO as oiio

    rng = np.random.default_rng(16)
    rgb = (rng.random((23, 31, 3)) ** 2 * 1.2).astype(np.float32)
    write_png(tmp_path / "p16.png", rgb, 0.5, "filmic", bits=16)
    pixels, spec = read_png_library(tmp_path / "p16.png")
    assert spec.format == oiio.UINT16 and pixels.dtype == np.uint16
    assert (spec.width, spec.height, spec.nchannels) == (31, 23, 3)
    np.testing.assert_array_equal(pixels, preview(rgb, 0.5, "filmic", bits=16))
    # 16 bits resolve what 8 cannot: the sRGB slope at 0.5 is (1.055/2.4)·0.5^(1/2.4 − 1)
    # = 0.659, so a ramp 0.5 .. 0.501 spans 6.59e-4: 0.17 of an 8-bit code, 43 16-bit codes.
    ramp = np.linspace(0.5, 0.501, 64, dtype=np.float32)[None, :, None].repeat(3, axis=2)
    assert len(np.unique(preview(ramp))) <= 2
    assert 42 <= len(np.unique(preview(ramp, bits=16))) <= 45
    # The 8-bit codes are the 16-bit ones to within rounding: c8 ≈ c16 / 257.
    both = preview(rgb), preview(rgb, bits=16)
    assert np.abs(both[0].astype(int) - both[1] / 257.0).max() <= 0.5 + 1e-9
    # And an 8-bit file reads back as 8-bit, through the library and the spec's decoder alike.
    write_png(tmp_path / "p8.png", rgb)
    pixels, spec = read_png_library(tmp_path / "p8.png")
    assert spec.format == oiio.UINT8
    np.testing.assert_array_equal(pixels, read_png(tmp_path / "p8.png"))
    np.testing.assert_array_equal(pixels, both[0])


def test_bad_preview_arguments_write_nothing(tmp_path):
    rgb = np.ones((2, 2, 3), np.float32)
    for kwargs in ({"bits": 12}, {"exposure": float("nan")}, {"tonemap": "fancy"},
                   {"exposure": 2000.0}):
        with pytest.raises(ValueError):
            write_png(tmp_path / "x.png", rgb, **kwargs)
    assert os.listdir(tmp_path) == []


def test_image_preview_is_what_a_png_holds(tmp_path):
    image = raytrace.Image(_hdr_image(9, 11, seed=4))
    pixels = image.preview(exposure=-1.0, tonemap="reinhard2004")
    assert pixels.dtype == np.uint8 and pixels.shape == (9, 11, 3)
    image.save(tmp_path / "p.png", exposure=-1.0, tonemap="reinhard2004")
    np.testing.assert_array_equal(read_png(tmp_path / "p.png"), pixels)
    assert image.preview(bits=16).dtype == np.uint16


def test_repr_png_is_a_valid_png_of_the_default_preview(tmp_path):
    image = raytrace.Image(_hdr_image(12, 20, seed=6))
    data = image._repr_png_()
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    (tmp_path / "r.png").write_bytes(data)
    np.testing.assert_array_equal(read_png(tmp_path / "r.png"), image.preview())


def test_repr_png_of_a_large_image_is_box_filtered_in_linear_light(tmp_path):
    # 2100×1030: the factor 3 brings it to 700×344 (the last row of blocks 1 pixel tall).
    # A 0/1 checkerboard of single pixels (0 at the top left) averages to 4/9 in a 3×3 block
    # that starts on a 0, 5/9 in one that starts on a 1.
    h, w = 1030, 2100
    y, x = np.mgrid[0:h, 0:w]
    rgb = np.repeat(((x + y) % 2).astype(np.float32)[..., None], 3, axis=2)
    rgb[-1, :, 0] = np.nan  # non-finite counts as black
    (tmp_path / "r.png").write_bytes(raytrace.Image(rgb)._repr_png_())
    shown = read_png(tmp_path / "r.png")
    assert shown.shape == (344, 700, 3)
    means = np.where((np.arange(343)[:, None] + np.arange(700)[None, :]) % 2 == 0, 4 / 9, 5 / 9)
    expected = preview(np.repeat(means[..., None], 3, axis=2))
    np.testing.assert_array_equal(shown[:343], expected)
    # The last block row is one source row (1029: 1 at even x), so 2 or 1 of 3 are lit (G, B);
    # its red channel holds NaN, shown black.
    last = np.where(np.arange(700) % 2 == 0, 2 / 3, 1 / 3)
    np.testing.assert_array_equal(shown[343, :, 1], preview(np.repeat(
        last[None, :, None], 3, axis=2))[0, :, 0])
    assert (shown[343, :, 0] == 0).all()
