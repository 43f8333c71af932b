"""The image-writer registry (raytrace/film/writers.py): the lookup and its error, every
registered writer's file read back, the memory check's figures, and a writer registered at
run time reaching Image.save, the command line (one render, --out-dir, --frames), frames and
the memory check with no other change: the one-file recipe of the module docstring. (That
reading the registry loads no compiler is test_cli's
test_loading_checking_and_comparing_import_no_renderer_machinery: every command builds its
flags from it.)"""

from __future__ import annotations

import dataclasses
import doctest
import importlib
import os

import numpy as np
import pytest
from helpers import read_png_library, write_text

import raytrace
from raytrace import cli
from raytrace.film import preview, writers
from raytrace.film.writers import MAIN_FLAG, WRITERS, Writer, writer_for

RENDER = importlib.import_module("raytrace.rendering")

SCENE = """\
[render]
width = 6
height = 4

[camera]
position = [0.0, 0.0, {z}]

[[objects]]
type = "sphere"
center = [0.0, 0.0, 0.0]
radius = 1.0

[[lights]]
type = "point"
position = [2.0, 2.0, 3.0]
"""


def _image() -> raytrace.Image:
    """A small image with HDR values, negatives and a NaN, so every writer has work to do."""
    rgb = np.linspace(-0.5, 4.0, 5 * 7 * 3, dtype=np.float32).reshape(5, 7, 3)
    rgb[0, 0, 1] = np.nan
    return raytrace.Image(rgb, metadata={"spp": 1})


# -- a writer for the tests: PPM (P6) of the 8-bit preview, numpy only -----------------------
def _write_ppm(path, image, settings) -> None:
    codes = preview(image.rgb, settings.exposure, settings.tonemap)
    with open(path, "wb") as f:
        f.write(b"P6 %d %d 255\n" % (image.width, image.height) + codes.tobytes())


def _read_ppm(path) -> np.ndarray:
    magic, width, height, top, data = open(path, "rb").read().split(maxsplit=4)
    assert (magic, top) == (b"P6", b"255")
    return np.frombuffer(data, np.uint8).reshape(int(height), int(width), 3)


PPM = Writer(".ppm", "--ppm", "also write a PPM of the preview to FILE", 30, _write_ppm)


@pytest.fixture
def ppm(monkeypatch):
    """The PPM writer registered for one test, after the EXR and the PNG."""
    monkeypatch.setitem(WRITERS, PPM.suffix, PPM)
    return PPM


# -- the lookup ----------------------------------------------------------------------------------
def _choices() -> str:
    """The registered suffixes as the errors name them: ".exr or .png", ".exr, .png or .ppm"."""
    *first, last = WRITERS
    return f"{', '.join(first)} or {last}"


def test_a_bad_suffix_is_an_error_naming_the_valid_ones(tmp_path):
    assert _choices().startswith(".exr, .png" if len(WRITERS) > 2 else ".exr or .png")
    with pytest.raises(ValueError) as e:
        writer_for("x.jpg")
    assert str(e.value) == f"x.jpg: unknown image type '.jpg' (use {_choices()})"
    with pytest.raises(ValueError) as e:
        writer_for("no_suffix")
    assert str(e.value) == f"no_suffix: unknown image type '' (use {_choices()})"
    with pytest.raises(ValueError) as e:
        _image().save(tmp_path / "x.tif")
    assert str(e.value) == f"{tmp_path / 'x.tif'}: unknown image type '.tif' (use {_choices()})"
    assert os.listdir(tmp_path) == []
    with pytest.raises(ValueError) as e:
        writers.named("jpg")
    names = ", ".join(w.name for w in WRITERS.values())
    assert str(e.value) == f"unknown output step 'jpg' (choose from {names})"


def test_a_registered_suffix_is_named_in_the_error(ppm):
    with pytest.raises(ValueError, match=r", \.png(, .*)? or \.ppm\)$"):
        writer_for("x.jpg")


def test_the_lookup_takes_any_case_and_names_steps_without_the_dot():
    assert writer_for("A.EXR") is WRITERS[".exr"] and writer_for("b.Png") is WRITERS[".png"]
    assert [writers.named(w.name) for w in WRITERS.values()] == list(WRITERS.values())
    assert writers.main_writer() is WRITERS[".exr"] and writers.main_writer().flag == "-o"
    assert writers.extra_writers() == [w for w in WRITERS.values() if w.flag != "-o"]
    assert WRITERS[".png"] in writers.extra_writers()


def test_every_entry_is_well_formed():
    flags = [w.flag for w in WRITERS.values()]
    assert len(set(flags)) == len(flags) and flags.count(MAIN_FLAG) == 1
    for suffix, w in WRITERS.items():
        assert suffix == w.suffix == w.suffix.lower() and suffix.startswith(".")
        assert w.flag.startswith("-") and w.help and callable(w.write)
        assert isinstance(w.peak_bytes_per_pixel, int) and w.peak_bytes_per_pixel > 0


def test_the_doctests():
    assert doctest.testmod(writers).failed == 0


# -- every registered writer's file is read back ---------------------------------------------------
@pytest.mark.parametrize("suffix", list(WRITERS))
def test_every_writer_writes_a_file_a_reader_accepts(tmp_path, suffix):
    image = _image()
    path = tmp_path / f"x{suffix}"
    image.save(path)
    assert os.listdir(tmp_path) == [path.name]  # no temporary file left
    pixels, spec = read_png_library(path)  # OpenImageIO: a reader of every format
    assert (spec.width, spec.height, spec.nchannels) == (7, 5, 3)
    if suffix == ".exr":  # float and linear: the pixels bit for bit, the metadata
        back = raytrace.Image.from_exr(path)
        assert np.array_equal(back.rgb, image.rgb, equal_nan=True)
        assert back.metadata["spp"] == 1
    if suffix == ".png":  # the preview's codes
        assert np.array_equal(pixels, image.preview())


def test_the_settings_reach_their_writer(tmp_path):
    image = _image()
    image.save(tmp_path / "x.png", exposure=-1.0, tonemap="clip", bits=16)
    pixels, _ = read_png_library(tmp_path / "x.png")
    assert pixels.dtype == np.uint16
    assert np.array_equal(pixels, image.preview(-1.0, "clip", bits=16))
    image.save(tmp_path / "x.exr", compression="none")
    assert "NO_COMPRESSION" in str(raytrace.read_exr(tmp_path / "x.exr")[1]["compression"])


# -- the memory check ------------------------------------------------------------------------------
def test_the_memory_check_takes_each_step_s_figure_from_its_writer(monkeypatch):
    base, render = RENDER.PEAK_BASE_BYTES, RENDER.PEAK_RENDER_BYTES_PER_PIXEL
    figures = [WRITERS[s].peak_bytes_per_pixel for s in (".exr", ".png")]
    assert RENDER.peak_bytes(30, 20, ("exr", "png")) == base + max(render, *figures) * 600
    png = dataclasses.replace(WRITERS[".png"], peak_bytes_per_pixel=99)
    monkeypatch.setitem(WRITERS, ".png", png)
    assert RENDER.peak_bytes(30, 20, ("exr",)) == base + max(render, figures[0]) * 600
    assert RENDER.peak_bytes(30, 20, ("exr", "png")) == base + 99 * 600
    monkeypatch.setattr(RENDER, "available_bytes", lambda: base + 50 * 600)
    RENDER.check_memory(30, 20, ("exr",))
    with pytest.raises(raytrace.SceneError, match=r"\(render \+ exr \+ png\)"):
        RENDER.check_memory(30, 20, ("exr", "png"))


# -- a writer added to the registry, and nothing else --------------------------------------------
def test_a_registered_writer_is_a_save_suffix_a_flag_a_batch_output_and_a_frame_pattern(
        tmp_path, capsys, monkeypatch, ppm):
    image = _image()
    image.save(tmp_path / "x.ppm", exposure=1.0)
    assert np.array_equal(_read_ppm(tmp_path / "x.ppm"), image.preview(1.0))

    with pytest.raises(SystemExit) as e:  # the flag and its help, generated from the entry
        cli.main(["render", "--help"])
    assert e.value.code == 0
    shown = " ".join(capsys.readouterr().out.split())
    assert "--ppm [FILE] also write a PPM of the preview to FILE (.ppm; no FILE only with " \
           "--out-dir)" in shown
    extras = writers.extra_writers()  # --png, any other registered, --ppm last
    assert extras[0].flag == "--png" and extras[-1] is ppm
    assert (f"and {', '.join(w.suffix for w in extras)}, .json with "
            f"{', '.join(w.flag for w in extras)}, --stats given no file name") in shown
    assert f"-o, {', '.join(w.flag for w in extras[:-1])} and --ppm are patterns too" in shown

    a = write_text(tmp_path / "a.toml", SCENE.format(z=4.0))
    b = write_text(tmp_path / "b.toml", SCENE.format(z=5.0))
    # One render: the EXR and the PPM, the PPM the preview of the EXR's pixels.
    assert cli.main(["render", str(a), "-o", str(tmp_path / "a.exr"), "--ppm",
                     str(tmp_path / "a.ppm"), "--exposure", "1", "-q"]) == 0
    rgb = raytrace.read_exr(tmp_path / "a.exr")[0]
    assert np.array_equal(_read_ppm(tmp_path / "a.ppm"), preview(rgb, 1.0))
    # Its errors are the others' lines, with its flag and suffix.
    assert cli.main(["render", str(a), "--ppm", str(tmp_path / "a.png"), "-q"]) == 2
    assert capsys.readouterr().err == (f"raytrace: error: --ppm: must be a .ppm file (it holds "
                                       f"PPM data), got '{tmp_path / 'a.png'}'\n")
    assert cli.main(["render", str(a), "--ppm", "-q"]) == 2
    assert "raytrace: error: --ppm: needs a file name" in capsys.readouterr().err
    # A batch: DIR/<scene name>.ppm beside the EXRs.
    out = tmp_path / "out"
    out.mkdir()
    assert cli.main(["render", str(a), str(b), "--out-dir", str(out), "--ppm", "-q"]) == 0
    assert sorted(os.listdir(out)) == ["a.exr", "a.ppm", "b.exr", "b.ppm"]
    assert cli.main(["render", str(a), str(b), "--out-dir", str(out), "--ppm", "x.ppm"]) == 2
    assert "--ppm: takes no file name with --out-dir (each scene's goes to DIR/<scene " \
           "name>.ppm)" in capsys.readouterr().err
    # Frames: a pattern like -o's, its frames skipped on a rerun once written.
    for f in (1, 2):
        write_text(tmp_path / f"shot_{f}.toml", SCENE.format(z=3.0 + f))
    frames = tmp_path / "frames"
    frames.mkdir()
    args = ["render", str(tmp_path / "shot_#.toml"), "--frames", "1-2", "-o",
            str(frames / "f.#.exr"), "--ppm", str(frames / "p.#.ppm"), "-q"]
    assert cli.main(args) == 0
    assert sorted(os.listdir(frames)) == ["f.1.exr", "f.2.exr", "p.1.ppm", "p.2.ppm"]
    assert cli.main([*args[:-3], "--ppm", str(frames / "p.#.png"), "-q"]) == 2
    assert "raytrace: error: --ppm: must end in .ppm" in capsys.readouterr().err
    # The memory check counts its step with its own figure.
    monkeypatch.setattr(RENDER, "available_bytes", lambda: RENDER.PEAK_BASE_BYTES)
    assert cli.main(["render", str(a), "-o", str(tmp_path / "m.exr"), "--ppm",
                     str(tmp_path / "m.ppm"), "-q"]) == 2
    assert "(render + exr + ppm)" in capsys.readouterr().err
    assert not (tmp_path / "m.exr").exists()


def test_render_frames_writes_the_extras_by_their_suffixes(tmp_path, ppm):
    def scene_at(frame: int) -> raytrace.Scene:
        return raytrace.load_scene(write_text(tmp_path / f"s{frame}.toml",
                                              SCENE.format(z=3.0 + frame)))

    result = raytrace.render_frames(scene_at, str(tmp_path / "o.##.exr"), "1-2", threads=1,
                                    png=str(tmp_path / "p.##.png"),
                                    extras={".ppm": str(tmp_path / "q.##.ppm")})
    assert result.outputs[2] == [str(tmp_path / n) for n in ("o.02.exr", "p.02.png",
                                                             "q.02.ppm")]
    for f in (1, 2):
        rgb = raytrace.read_exr(tmp_path / f"o.{f:02d}.exr")[0]
        assert np.array_equal(_read_ppm(tmp_path / f"q.{f:02d}.ppm"), preview(rgb))


@pytest.mark.parametrize(("extras", "says"), [
    ({".jpg": "q.#.jpg"}, r"unknown image type '\.jpg' \(use \.exr.*\.png"),
    ({".exr": "q.#.exr"}, r"\.exr is given twice"),
    ({".png": "q.#.ppm"}, r"must end in \.png, got 'q\.#\.ppm'")])
def test_render_frames_checks_its_extras_before_any_frame(tmp_path, extras, says):
    key = "png" if ".png" in extras else "extras"
    with pytest.raises(raytrace.SceneError, match=says) as e:
        raytrace.render_frames(lambda f: pytest.fail("rendered"), str(tmp_path / "o.#.exr"),
                               "1", extras=extras)
    assert e.value.key == key
    assert os.listdir(tmp_path) == []

