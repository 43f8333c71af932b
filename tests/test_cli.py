"""The command line: ``--stats`` counts, ``compare`` exit codes, flags over ``[render]``, bad
flag values."""

from __future__ import annotations

import io
import json
import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from helpers import read_png_library, write_text

import raytrace
from raytrace import cli
from raytrace.film import write_exr

# A floor under a camera looking level: with an even height, exactly the lower half of the
# pixel centres look down (y = (1 − 2(row + ½)/H)·tan(fov/2) < 0 for row >= H/2) and every
# downward ray hits the infinite plane y = 0 (the camera is at y = 1).
FLOOR_SCENE = """\
[render]
width = {w}
height = {h}
spp = {spp}
max_depth = {depth}

[camera]
position = [0.0, 1.0, 0.0]
look_at = [0.0, 1.0, -1.0]

[ambient]
color = 0.1

[materials.floor]
kd = 0.5
kr = 0.25

[[lights]]
type = "point"
position = [0.0, 5.0, -3.0]    # above the floor: every floor hit faces it

[[lights]]
type = "point"
position = [0.0, -5.0, -3.0]   # below the floor: no floor hit faces it (N·L < 0)

[[objects]]
type = "plane"
point = [0.0, 0.0, 0.0]
normal = [0.0, 1.0, 0.0]
material = "floor"
"""


def _floor(tmp_path, w=8, h=6, spp=1, depth=5):
    return write_text(tmp_path / "floor.toml", FLOOR_SCENE.format(w=w, h=h, spp=spp,
                                                                  depth=depth))


def _render(args, capsys):
    rc = cli.main(["render", *map(str, args), "-q"])
    captured = capsys.readouterr()
    return rc, captured


def test_stats_keys_and_counts(tmp_path, capsys):
    w, h, spp = 8, 6, 4
    scene = _floor(tmp_path, w, h, spp)
    rc, cap = _render([scene, "-o", tmp_path / "o.exr", "--stats", tmp_path / "s.json"], capsys)
    assert rc == 0 and cap.err == ""
    stats = json.loads((tmp_path / "s.json").read_text())
    for key in ("camera", "shadow", "reflection", "refraction", "total"):
        assert isinstance(stats["rays"][key], int)
    assert stats["seconds"]["total"] > 0
    assert (stats["width"], stats["height"], stats["spp"]) == (w, h, spp)
    # spp = 4 is a 2×2 stratified grid: every sample of a pixel stays in its pixel, so the
    # lower-half pixels send all their samples down (their centres' rows are >= H/2 and the
    # row's top edge is the horizon at worst).
    floor_hits = (w * h // 2) * spp
    rays = stats["rays"]
    assert rays["camera"] == w * h * spp
    assert rays["shadow"] == floor_hits            # one per floor hit, only the upper light
    assert rays["reflection"] == floor_hits        # kr > 0: one mirror ray per floor hit
    assert rays["refraction"] == 0                 # kt = 0
    assert rays["total"] == sum(v for k, v in rays.items() if k != "total")


def test_stats_with_max_depth_zero_has_no_secondary_rays(tmp_path, capsys):
    scene = _floor(tmp_path, 4, 2, 1, depth=0)
    rc, _ = _render([scene, "-o", tmp_path / "o.exr", "--stats", tmp_path / "s.json"], capsys)
    assert rc == 0
    rays = json.loads((tmp_path / "s.json").read_text())["rays"]
    assert (rays["camera"], rays["shadow"], rays["reflection"]) == (8, 4, 0)


def test_flags_override_the_scene_render_table(tmp_path, capsys):
    scene = _floor(tmp_path, w=8, h=6, spp=1, depth=5)
    out = tmp_path / "o.exr"
    rc, _ = _render([scene, "-o", out, "--width", 5, "--height", 4, "--spp", 9,
                     "--max-depth", 0, "--seed", 3, "--stats", tmp_path / "s.json"], capsys)
    assert rc == 0
    rgb, header = raytrace.read_exr(out)
    assert rgb.shape == (4, 5, 3)
    assert (header["raytrace:spp"], header["raytrace:max_depth"], header["raytrace:seed"]) == (
        9, 0, 3)
    stats = json.loads((tmp_path / "s.json").read_text())
    assert (stats["width"], stats["height"], stats["spp"]) == (5, 4, 9)
    assert stats["rays"]["camera"] == 5 * 4 * 9 and stats["rays"]["reflection"] == 0


def test_without_flags_the_scene_values_hold(tmp_path, capsys):
    scene = _floor(tmp_path, w=3, h=2, spp=1, depth=2)
    rc, _ = _render([scene, "-o", tmp_path / "o.exr"], capsys)
    rgb, header = raytrace.read_exr(tmp_path / "o.exr")
    assert rc == 0 and rgb.shape == (2, 3, 3) and header["raytrace:max_depth"] == 2


def test_cli_output_equals_the_python_api(tmp_path, capsys):
    scene = _floor(tmp_path, 6, 4, 1)
    rc, _ = _render([scene, "-o", tmp_path / "o.exr", "--threads", 2], capsys)
    assert rc == 0
    rgb, _ = raytrace.read_exr(tmp_path / "o.exr")
    image = raytrace.render(raytrace.load_scene(scene))
    np.testing.assert_array_equal(rgb, image.rgb)


def test_default_output_name_and_png(tmp_path, capsys, monkeypatch):
    scene = _floor(tmp_path, 4, 2)
    work = tmp_path / "work"
    work.mkdir()
    monkeypatch.chdir(work)
    rc, _ = _render([scene, "--png", "prev.png"], capsys)
    assert rc == 0
    assert sorted(os.listdir(work)) == ["floor.exr", "prev.png"]


@pytest.mark.parametrize("flag,value", [("--width", "0"), ("--spp", "0"), ("--height", "-1"),
                                        ("--max-depth", "-1"), ("--threads", "0"),
                                        ("--min-weight", "-0.5"), ("--tonemap", "fancy"),
                                        ("--width", "100001")])
def test_bad_flag_values(tmp_path, capsys, flag, value):
    scene = _floor(tmp_path, 4, 2)
    rc, cap = _render([scene, "-o", tmp_path / "o.exr", flag, value], capsys)
    assert rc == 2
    lines = cap.err.splitlines()
    assert len(lines) == 1 and "Traceback" not in cap.err, cap.err
    assert flag in lines[0] and value.lstrip("-") in lines[0]
    assert sorted(os.listdir(tmp_path)) == ["floor.toml"]


@pytest.mark.parametrize("args,named", [(["--width", "abc"], "--width"),
                                        (["--spp", "1.5"], "--spp"),
                                        (["--bogus"], "--bogus")])
def test_unparsable_flags_give_one_line(tmp_path, capsys, args, named):
    scene = _floor(tmp_path, 4, 2)
    with pytest.raises(SystemExit) as e:
        cli.main(["render", str(scene), "-o", str(tmp_path / "o.exr"), *args])
    assert e.value.code == 2
    err = capsys.readouterr().err
    assert len(err.splitlines()) == 1, err
    assert named in err and "Traceback" not in err
    assert sorted(os.listdir(tmp_path)) == ["floor.toml"]


def test_version_comes_from_the_package_metadata(capsys):
    from importlib.metadata import version

    with pytest.raises(SystemExit) as e:
        cli.main(["--version"])
    assert e.value.code == 0
    assert capsys.readouterr().out == f"raytrace {version('raytrace')}\n"
    assert raytrace.__version__ == version("raytrace")


@pytest.mark.parametrize("value", ["2000", "-300", "nan", "inf", "-inf", "bright", ""])
def test_bad_exposures_are_refused_before_rendering(tmp_path, capsys, value):
    # Before: 2000 overflowed in the PNG writer after the EXR was written (a traceback); nan
    # and inf wrote a blank PNG and exited 0.
    scene = _floor(tmp_path, 4, 2)
    with pytest.raises(SystemExit) as e:
        cli.main(["render", str(scene), "-o", str(tmp_path / "o.exr"), "--png",
                  str(tmp_path / "o.png"), f"--exposure={value}"])
    assert e.value.code == 2
    err = capsys.readouterr().err
    assert len(err.splitlines()) == 1 and "Traceback" not in err, err
    assert "--exposure" in err and repr(value) in err and "[-256, 256] or 'auto'" in err
    assert sorted(os.listdir(tmp_path)) == ["floor.toml"]


def test_auto_exposure_an_operator_and_16_bits_from_the_command_line(tmp_path, capsys):
    import OpenImageIO as oiio

    from raytrace.film import preview

    scene = _floor(tmp_path, 8, 6)
    rc, cap = _render([scene, "-o", tmp_path / "o.exr", "--png", tmp_path / "o.png",
                       "--exposure", "auto", "--tonemap", "Reinhard2004", "--png-bits", "16"],
                      capsys)
    assert rc == 0, cap.err
    pixels, spec = read_png_library(tmp_path / "o.png")
    assert spec.format == oiio.UINT16
    rgb, _ = raytrace.read_exr(tmp_path / "o.exr")
    np.testing.assert_array_equal(pixels, preview(rgb, "auto", "reinhard2004", bits=16))
    with pytest.raises(SystemExit) as e:
        cli.main(["render", str(scene), "-o", str(tmp_path / "p.exr"), "--png-bits", "12"])
    assert e.value.code == 2 and "--png-bits" in capsys.readouterr().err


def test_bad_output_paths(tmp_path, capsys):
    scene = _floor(tmp_path, 4, 2)
    rc, cap = _render([scene, "-o", tmp_path / "o.png"], capsys)
    assert rc == 2 and "-o" in cap.err and ".exr" in cap.err
    rc, cap = _render([scene, "-o", tmp_path / "nodir" / "o.exr"], capsys)
    assert rc == 2 and "nodir" in cap.err and len(cap.err.splitlines()) == 1
    assert sorted(os.listdir(tmp_path)) == ["floor.toml"]


# -- compare ---------------------------------------------------------------------------------------

def _pair(tmp_path, delta: float):
    ref = np.full((4, 5, 3), 0.5, np.float32)
    test = ref.copy()
    test[0, 0, 0] += delta           # one of 60 values: rmse = delta/√60, max = delta
    write_exr(tmp_path / "ref.exr", ref)
    write_exr(tmp_path / "test.exr", test)
    return str(tmp_path / "test.exr"), str(tmp_path / "ref.exr")


def test_compare_within_and_over_threshold(tmp_path, capsys):
    test, ref = _pair(tmp_path, 0.6)
    rmse = 0.6 / np.sqrt(60)                      # 0.0775
    assert cli.main(["compare", test, ref, "--threshold", "0.08"]) == 0
    assert cli.main(["compare", test, ref, "--threshold", "0.07"]) == 1
    assert cli.main(["compare", test, ref, "--metric", "max", "--threshold", "0.61"]) == 0
    assert cli.main(["compare", test, ref, "--metric", "max", "--threshold", "0.59"]) == 1
    assert cli.main(["compare", ref, ref, "--threshold", "0"]) == 0
    out = capsys.readouterr().out.splitlines()
    assert f"{rmse:.4g}"[:5] in out[0] and "within" in out[0] and "over" in out[1]


def test_compare_bad_input(tmp_path, capsys):
    test, ref = _pair(tmp_path, 0.1)
    small = tmp_path / "small.exr"
    write_exr(small, np.zeros((2, 2, 3), np.float32))
    for args, piece in ((["compare", test, str(small)], "differs"),
                        (["compare", test, str(tmp_path / "none.exr")], "not found"),
                        (["compare", test, ref, "--metric", "ssim"], "ssim")):
        assert cli.main(args) == 2
        err = capsys.readouterr().err
        assert len(err.splitlines()) == 1 and piece in err, err


def test_compare_psnr_and_flip_with_their_default_thresholds(tmp_path, capsys):
    test, ref = _pair(tmp_path, 0.6)
    psnr = 10 * np.log10(60 / 0.36)                   # MSE 0.36/60, peak 1: 22.2 dB
    assert cli.main(["compare", test, ref, "--metric", "psnr"]) == 1     # default 60 dB
    assert cli.main(["compare", test, ref, "--metric", "psnr", "--threshold", "22"]) == 0
    assert cli.main(["compare", test, ref, "--metric", "psnr", "--threshold", "23"]) == 1
    assert cli.main(["compare", ref, ref, "--metric", "psnr"]) == 0      # +inf dB
    out = capsys.readouterr().out.splitlines()
    assert out[0] == f"psnr = {psnr:.6g} dB (below threshold 60 dB)"
    assert "within threshold 22 dB" in out[1] and out[3] == "psnr = inf dB (within threshold 60 dB)"
    assert cli.main(["compare", test, ref, "--metric", "flip"]) == 1     # default 0.01
    assert cli.main(["compare", ref, ref, "--metric", "flip", "--threshold", "0"]) == 0
    flip = float(capsys.readouterr().out.split()[2])
    assert 0.01 < flip < 1


@pytest.mark.parametrize("bad", ["-1", "nan", "inf", "-0.5"])
def test_compare_threshold_must_be_finite_and_not_negative(tmp_path, capsys, bad):
    test, ref = _pair(tmp_path, 0.1)
    assert cli.main(["compare", test, ref, "--threshold", bad]) == 2
    cap = capsys.readouterr()
    lines = cap.err.splitlines()
    assert len(lines) == 1 and "--threshold" in lines[0] and "finite number >= 0" in lines[0]
    assert cap.out == ""


def test_compare_flip_without_the_package_is_one_line(tmp_path, capsys, monkeypatch):
    monkeypatch.setitem(sys.modules, "flip_evaluator", None)
    test, ref = _pair(tmp_path, 0.1)
    assert cli.main(["compare", test, ref, "--metric", "flip"]) == 2
    lines = capsys.readouterr().err.splitlines()
    assert len(lines) == 1 and "--metric" in lines[0] and "raytrace[flip]" in lines[0]


def test_compare_diff_writes_the_heatmap(tmp_path, capsys):
    from helpers import read_png

    test, ref = _pair(tmp_path, 0.6)
    diff = tmp_path / "diff.png"
    assert cli.main(["compare", test, ref, "--diff", str(diff)]) == 1   # exit code unchanged
    pixels = read_png(diff)
    assert pixels.shape == (4, 5, 3) and pixels[0, 0].tolist() == [255, 255, 255]
    assert int(pixels.sum()) == 3 * 255                 # the one changed pixel, white
    assert cli.main(["compare", ref, ref, "--diff", str(diff)]) == 0
    assert not read_png(diff).any()                     # equal images: black


@pytest.mark.parametrize("diff,piece", [("ref.exr", ".png"), ("d.txt", ".png"),
                                        ("nodir/d.png", "does not exist"),
                                        ("folder.png", "folder")])
def test_compare_bad_diff_path_is_one_line_and_writes_nothing(tmp_path, capsys, diff, piece):
    test, ref = _pair(tmp_path, 0.6)
    if piece == "folder":
        (tmp_path / diff).mkdir()
    before = {p.name: p.is_file() and p.read_bytes() for p in tmp_path.iterdir()}
    assert cli.main(["compare", test, ref, "--diff", str(tmp_path / diff)]) == 2
    lines = capsys.readouterr().err.splitlines()
    assert len(lines) == 1 and "--diff" in lines[0] and piece in lines[0], lines
    assert {p.name: p.is_file() and p.read_bytes() for p in tmp_path.iterdir()} == before


def test_compare_diff_never_overwrites_an_input(tmp_path, capsys):
    test, ref = _pair(tmp_path, 0.6)
    png = tmp_path / "in.png"
    png.write_bytes(b"not an image")
    # An input named .png: refused before anything is read or written.
    assert cli.main(["compare", str(png), ref, "--diff", str(png)]) == 2
    assert "would overwrite the input" in capsys.readouterr().err
    assert png.read_bytes() == b"not an image"


def test_compare_json_report(tmp_path, capsys):
    test, ref = _pair(tmp_path, 0.6)
    assert cli.main(["compare", test, ref, "--json", "--metric", "max",
                     "--threshold", "0.5"]) == 1
    report = json.loads(capsys.readouterr().out)
    assert report["metric"] == "max" and report["threshold"] == 0.5
    assert report["value"] == pytest.approx(0.6) and report["within"] is False
    assert report["metrics"]["rmse"] == pytest.approx(0.6 / np.sqrt(60))
    assert set(report["metrics"]) == {"rmse", "mae", "max", "relmse", "psnr"}
    assert report["bad_pixels"] == 1 and report["pixels"] == 20
    assert report["worst"][0]["x"] == 0 and report["worst"][0]["y"] == 0
    assert report["worst"][0]["actual"][0] == pytest.approx(1.1)
    assert cli.main(["compare", ref, ref, "--json", "--metric", "flip"]) == 0
    report = json.loads(capsys.readouterr().out)      # strict JSON: no Infinity
    assert report["metrics"]["psnr"] == "inf" and report["metrics"]["flip"] == 0.0


def test_compare_in_a_subprocess(tmp_path):
    test, ref = _pair(tmp_path, 1.0)
    proc = subprocess.run([sys.executable, "-m", "raytrace", "compare", test, ref],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 1 and "over" in proc.stdout and proc.stderr == ""


# -- --compression ---------------------------------------------------------------------------------

def _header_compression(path):
    import OpenEXR

    with OpenEXR.File(str(path)) as f:
        return f.header()["compression"]


@pytest.mark.parametrize("flag,expected", [(None, "ZIP_COMPRESSION"),
                                           ("none", "NO_COMPRESSION"),
                                           ("piz", "PIZ_COMPRESSION"),
                                           ("RLE", "RLE_COMPRESSION")])
def test_compression_flag_reaches_the_file_header(tmp_path, capsys, flag, expected):
    import OpenEXR

    scene = _floor(tmp_path, 6, 4)
    out = tmp_path / "o.exr"
    rc, cap = _render([scene, "-o", out, *(["--compression", flag] if flag else [])], capsys)
    assert rc == 0 and cap.err == ""
    assert _header_compression(out) == getattr(OpenEXR, expected)
    rgb, _ = raytrace.read_exr(out)                # lossless: the same pixels as the API's
    np.testing.assert_array_equal(rgb, raytrace.render(raytrace.load_scene(scene)).rgb)


def test_compression_choices_are_in_the_help(capsys):
    with pytest.raises(SystemExit) as e:
        cli.main(["render", "--help"])
    assert e.value.code == 0
    help_text = capsys.readouterr().out
    assert "--compression {none,rle,zips,zip,piz,zstd}" in help_text


@pytest.mark.parametrize("bad", ["fancy", "dwaa", "pxr24"])
def test_bad_compression_is_one_line_and_writes_nothing(tmp_path, capsys, bad):
    scene = _floor(tmp_path, 4, 2)
    with pytest.raises(SystemExit) as e:
        cli.main(["render", str(scene), "-o", str(tmp_path / "o.exr"), "--compression", bad,
                  "--png", str(tmp_path / "p.png"), "--stats", str(tmp_path / "s.json")])
    assert e.value.code == 2
    err = capsys.readouterr().err
    lines = err.splitlines()
    assert len(lines) == 1 and "Traceback" not in err, err
    assert "--compression" in lines[0] and bad in lines[0]
    assert all(name in lines[0] for name in ("none", "rle", "zips", "zip", "piz", "zstd"))
    assert sorted(os.listdir(tmp_path)) == ["floor.toml"]


def test_compression_missing_from_the_binding_fails_before_the_render(tmp_path, capsys,
                                                                      monkeypatch):
    import OpenEXR

    monkeypatch.delattr(OpenEXR, "ZSTD_COMPRESSION", raising=False)
    monkeypatch.setattr(cli, "Progress", lambda *a: pytest.fail("rendered"))  # never reached
    scene = _floor(tmp_path, 4, 2)
    rc, cap = _render([scene, "-o", tmp_path / "o.exr", "--compression", "zstd"], capsys)
    assert rc == 2
    lines = cap.err.splitlines()
    assert len(lines) == 1 and "--compression" in lines[0] and "zstd" in lines[0], cap.err
    assert sorted(os.listdir(tmp_path)) == ["floor.toml"]


# -- heavy imports only where they are used ------------------------------------------------------
ROOT = Path(__file__).resolve().parents[1]
HEAVY = ("numba", "trimesh", "colour", "scipy", "matplotlib", "embreex", "colour_hdri",
         "OpenImageIO", "imageio", "PIL")


def _imported_after(code: str) -> set[str]:
    """The heavy top-level modules a fresh interpreter has imported after running ``code``."""
    probe = (f"import sys\n{code}\n"
             f"print('HEAVY:' + ','.join(m for m in {HEAVY!r} if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True,
                         check=True, cwd=ROOT).stdout
    line = next(x for x in out.splitlines() if x.startswith("HEAVY:"))
    return set(filter(None, line.removeprefix("HEAVY:").split(",")))


def test_loading_checking_and_comparing_import_no_renderer_machinery(tmp_path):
    # Loading and validating an analytic scene, listing materials and comparing EXRs need
    # neither the compiler (numba), Embree, trimesh, colour-science nor SciPy.
    a = tmp_path / "a.exr"
    write_exr(a, np.zeros((2, 3, 3), np.float32))
    assert _imported_after("import raytrace; raytrace.load_scene('scenes/whitted.toml')") == set()
    assert _imported_after("from raytrace import cli; cli.main(['materials'])") == set()
    assert _imported_after(f"from raytrace import cli; cli.main(['compare', {str(a)!r}, "
                           f"{str(a)!r}])") == set()


def test_rendering_imports_numba_but_not_the_preview_or_mesh_libraries():
    # An analytic render to EXR needs numba; trimesh (mesh files), colour-science, colour-hdri
    # and OpenImageIO (PNG previews) stay out. (numba itself imports SciPy for its BLAS check
    # where it is installed.)
    got = _imported_after("import raytrace; raytrace.render(raytrace.load_scene("
                          "'scenes/whitted.toml'), width=4, height=3)")
    assert "numba" in got and not {"trimesh", "colour", "matplotlib", "embreex", "colour_hdri",
                                   "OpenImageIO", "imageio", "PIL"} & got
    # A preview loads them.
    got = _imported_after("import raytrace, numpy; raytrace.Image(numpy.ones((2, 2, 3)))"
                          ".preview(tonemap='filmic')")
    assert {"colour", "colour_hdri"} <= got


class _Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_a_terminal_gets_the_bar_and_one_summary_line_and_a_pipe_gets_nothing(
        tmp_path, monkeypatch):
    scene = Path(__file__).resolve().parents[1] / "scenes" / "whitted.toml"
    out, png = tmp_path / "w.exr", tmp_path / "w.png"
    args = ["render", str(scene), "-o", str(out), "--png", str(png), "--width", "8",
            "--height", "6"]
    assert cli.main([*args, "-q"]) == 0  # kernels compiled (and said so) before the runs
    for stream, quiet in ((_Terminal(), []), (io.StringIO(), []), (_Terminal(), ["-q"])):
        monkeypatch.setattr(sys, "stderr", stream)
        assert cli.main([*args, *quiet]) == 0
        text = stream.getvalue()
        if stream.isatty() and not quiet:
            lines = text.replace("\r", "\n").strip().splitlines()
            bar = lines[-2]  # the finished bar: tqdm's, with the time left and the rate
            assert bar.startswith("100%|") and re.search(r"48/48 \[\d\d:\d\d<00:00, "
                                                         r"[\d.]+k? camera rays/s\]", bar), bar
            assert lines[-1].startswith(f"wrote {out}, {png}: 8×6, 1 spp, ")
            assert lines[-1].endswith(" s")
        else:
            assert text == ""


def test_an_adaptive_render_s_bar_counts_rows(tmp_path, monkeypatch):
    scene = Path(__file__).resolve().parents[1] / "scenes" / "spotlights.toml"
    monkeypatch.setattr(sys, "stderr", _Terminal())
    assert cli.main(["render", str(scene), "-o", str(tmp_path / "a.exr"), "--width", "8",
                     "--height", "6", "--aa", "adaptive"]) == 0
    bar = sys.stderr.getvalue().split("\n")[-3].split("\r")[-1]
    assert bar.startswith("100%|") and " 6/6 [" in bar and " rows/s]" in bar, bar


def test_an_interrupted_render_s_bar_is_not_drawn_again_after_the_message(tmp_path,
                                                                          monkeypatch):
    import gc
    import importlib

    module = importlib.import_module("raytrace.rendering")

    def interrupted(*args, progress, **kwargs):
        progress(1, 4)
        raise KeyboardInterrupt

    monkeypatch.setattr(module, "render", interrupted)
    monkeypatch.setattr(sys, "stderr", _Terminal())
    scene = Path(__file__).resolve().parents[1] / "scenes" / "spotlights.toml"
    assert cli.main(["render", str(scene), "-o", str(tmp_path / "a.exr")]) == 130
    gc.collect()
    bar, message = sys.stderr.getvalue().split("\n")[-3:-1]
    assert "%|" in bar and message.startswith("raytrace: interrupted; ")


# -- many scenes, one start-up (--out-dir) -------------------------------------------------------
def _scenes(tmp_path, names=("a", "b")):
    """Two floor scenes of different sizes, so each output can be told by its shape."""
    folder = tmp_path / "scenes"
    folder.mkdir()
    return [write_text(folder / f"{n}.toml", FLOOR_SCENE.format(w=4 + 2 * i, h=2 + 2 * i, spp=1,
                                                                depth=2))
            for i, n in enumerate(names)]


def test_out_dir_writes_each_scene_as_its_own_render_would(tmp_path, capsys):
    a, b = _scenes(tmp_path)
    out = tmp_path / "out"
    out.mkdir()
    rc, cap = _render([a, b, "--out-dir", out, "--png", "--stats"], capsys)
    assert rc == 0 and cap.err == ""
    assert sorted(os.listdir(out)) == ["a.exr", "a.json", "a.png", "b.exr", "b.json", "b.png"]
    for scene in (a, b):
        one = tmp_path / f"one_{scene.stem}.exr"
        assert _render([scene, "-o", one], capsys)[0] == 0
        batch_rgb, alone_rgb = raytrace.read_exr(out / f"{scene.stem}.exr")[0], \
            raytrace.read_exr(one)[0]
        assert batch_rgb.shape == alone_rgb.shape and np.array_equal(batch_rgb, alone_rgb)
        stats = json.loads((out / f"{scene.stem}.json").read_text())
        assert stats["output"] == str(out / f"{scene.stem}.exr")
        assert (stats["width"], stats["height"]) == alone_rgb.shape[1::-1]


def test_out_dir_refuses_two_scenes_of_one_name_before_rendering(tmp_path, capsys):
    (a,) = _scenes(tmp_path, ("a",))
    other = tmp_path / "other"
    other.mkdir()
    same_name = write_text(other / "a.json", json.dumps({"camera": {"position": [0, 1, 0]}}))
    out = tmp_path / "out"
    out.mkdir()
    rc, cap = _render([a, same_name, "--out-dir", out], capsys)
    lines = cap.err.splitlines()
    assert rc == 2 and len(lines) == 1, cap.err
    assert "--out-dir" in lines[0] and str(a) in lines[0] and str(same_name) in lines[0]
    assert os.listdir(out) == []


def test_out_dir_a_bad_scene_is_one_line_and_the_others_are_rendered(tmp_path, capsys):
    a, b = _scenes(tmp_path)
    bad = write_text(tmp_path / "scenes" / "bad.toml", "[render]\nwidth = -3\n")
    out = tmp_path / "out"
    out.mkdir()
    rc, cap = _render([a, bad, b, "--out-dir", out, "--png"], capsys)
    lines = cap.err.splitlines()
    assert rc == 2 and len(lines) == 1, cap.err
    assert lines[0].startswith(f"raytrace: error: {bad}: render.width: ")
    assert sorted(os.listdir(out)) == ["a.exr", "a.png", "b.exr", "b.png"]


def test_out_dir_never_overwrites_a_file_another_scene_of_the_batch_reads(tmp_path, capsys):
    # c.toml's floor is textured with out/a.png, which a.toml's preview would be: a's outputs
    # are refused (one line), c and b are rendered, the texture is untouched.
    from PIL import Image as PILImage

    a, b = _scenes(tmp_path)
    out = tmp_path / "out"
    out.mkdir()
    PILImage.new("RGB", (2, 2), (200, 30, 30)).save(out / "a.png")
    texture = (out / "a.png").read_bytes()
    c = write_text(tmp_path / "scenes" / "c.toml", FLOOR_SCENE.format(w=4, h=2, spp=1, depth=2)
                   .replace('material = "floor"',
                            'material = { kd = { texture = "../out/a.png" } }'))
    rc, cap = _render([c, a, b, "--out-dir", out, "--png"], capsys)
    lines = cap.err.splitlines()
    assert rc == 2 and len(lines) == 1, cap.err
    # (the inline material has no name: the line names the object whose material it is)
    assert f"{out / 'a.png'} is the file of the material of objects[0] of {c} (" in lines[0]
    assert (out / "a.png").read_bytes() == texture
    assert sorted(os.listdir(out)) == ["a.png", "b.exr", "b.png", "c.exr", "c.png"]


def test_out_dir_checks_aa_min_depth_against_each_scene_s_own_aa_depth(tmp_path, capsys):
    a, b = _scenes(tmp_path)
    for scene in (a, b):
        scene.write_text(scene.read_text().replace("[render]", "[render]\naa = \"adaptive\"\n"
                                                   "aa_depth = 4"))
    out = tmp_path / "out"
    out.mkdir()
    rc, cap = _render([a, b, "--out-dir", out, "--aa-min-depth", "3"], capsys)
    assert rc == 0 and cap.err == ""
    assert sorted(os.listdir(out)) == ["a.exr", "b.exr"]
    deeper = tmp_path / "deeper"
    deeper.mkdir()
    rc, cap = _render([a, b, "--out-dir", deeper, "--aa-min-depth", "5"], capsys)
    lines = cap.err.splitlines()
    assert rc == 2 and len(lines) == 2 and all("--aa-min-depth" in line for line in lines), cap.err
    assert os.listdir(deeper) == []


@pytest.mark.parametrize(("extra", "flag"), [
    (["-o", "x.exr"], "-o"), (["--png", "x.png"], "--png"), (["--stats", "s.json"], "--stats"),
    (["--frames", "1-2"], "--frames")])
def test_out_dir_flags_that_name_one_file_are_refused(tmp_path, capsys, extra, flag):
    a, b = _scenes(tmp_path)
    out = tmp_path / "out"
    out.mkdir()
    rc, cap = _render([a, b, "--out-dir", out, *extra], capsys)
    assert rc == 2 and len(cap.err.splitlines()) == 1 and f"error: {flag}: " in cap.err, cap.err
    assert os.listdir(out) == []


def test_several_scenes_need_out_dir_and_a_preview_needs_a_name(tmp_path, capsys):
    a, b = _scenes(tmp_path)
    rc, cap = _render([a, b], capsys)
    assert rc == 2 and "--out-dir" in cap.err and len(cap.err.splitlines()) == 1
    rc, cap = _render([a, "--png"], capsys)
    assert rc == 2 and "error: --png: needs a file name" in cap.err
    rc, cap = _render([a, b, "--out-dir", tmp_path / "missing"], capsys)
    assert rc == 2 and "error: --out-dir: is not an existing folder" in cap.err
    assert sorted(os.listdir(tmp_path)) == ["scenes"]


def test_the_command_line_loads_neither_scipy_linalg_nor_cffi_for_its_kernels(tmp_path):
    # numba imports them while it loads its registries, for BLAS (np.dot) and cffi calls that
    # no kernel makes; the command runs no other numba code, so it hides them (jit.py).
    probe = ("import sys; from raytrace import cli\n"
             f"assert cli.main(['render', 'scenes/whitted.toml', '-o', {str(tmp_path)!r} + "
             "'/w.exr', '--width', '4', '--height', '3', '-q']) == 0\n"
             "from numba.np import arraymath\n"
             "print(sorted(m for m in ('scipy.linalg', 'cffi', 'pycparser', 'trimesh', "
             "'colour', 'OpenImageIO', 'pygltflib', 'dask', 'distributed', 'PIL') "
             "if m in sys.modules), arraymath._HAVE_BLAS)\n"
             "import scipy.linalg; print('later imports work')")
    out = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True,
                         check=True, cwd=ROOT).stdout.split("\n")
    assert out[:2] == ["[] False", "later imports work"]


@pytest.mark.timeout(20)
def test_a_python_warning_in_a_block_is_shown_once_and_the_block_ends(capsys):
    """A warning that is not a RenderWarning (numpy's overflow while a scene loads) is shown as
    Python shows it, once: shown inside the recording, it was recorded again for ever (a render
    of a scene whose camera sat at 1e200 grew without end)."""
    import warnings

    with warnings.catch_warnings(record=True) as shown:
        warnings.simplefilter("always")
        with cli._warnings_as_lines():
            warnings.warn("overflow encountered in dot", RuntimeWarning, stacklevel=1)
            warnings.warn("a model note", raytrace.RenderWarning, stacklevel=1)
    assert [str(w.message) for w in shown] == ["overflow encountered in dot"]
    assert capsys.readouterr().err == "raytrace: warning: a model note\n"


def test_the_documented_exit_statuses_are_the_cli_constants():
    # docs/scene_format.md's table and the cli module docstring against raytrace.cli's EXIT_*
    text = (Path(cli.__file__).resolve().parents[1] / "docs" / "scene_format.md").read_text()
    section = text.split("### Exit status", 1)[1].split("\n### ", 1)[0]
    rows = re.findall(r"^\| (\d+) \| .+ \| (`EXIT_\w+`(?:, `EXIT_\w+`)*) \|$", section, re.M)
    documented = {name.strip("` "): int(status) for status, names in rows
                  for name in names.split(",")}
    constants = {name: value for name, value in vars(cli).items() if name.startswith("EXIT_")}
    assert documented == constants
    assert sorted({int(s) for s, _ in rows}) == [0, 1, 2, 3, 130]
    for name, value in constants.items():
        assert re.search(rf"^    {value} .* {name}$", cli.__doc__, re.M), name


# -- Ctrl-C ------------------------------------------------------------------------------------
#: The command line, with a line on stdout after each pass (so the test knows the kernels are
#: compiled and the render is under way).
ANNOUNCING = """
import sys
from raytrace import cli
from raytrace.integrator import WhittedIntegrator
render_pass = WhittedIntegrator._render_pass
def announced(self, *args):
    render_pass(self, *args)
    print("pass", flush=True)
WhittedIntegrator._render_pass = announced
sys.exit(cli.main(sys.argv[1:]))
"""
#: A floor and a ball under a 20 × 20 area light: 400 shadow rays a hit, seconds a pass of
#: 65 536 samples, a minute or more for the frame.
SOFT_SHADOWS = """\
[render]
width = 1200
height = 900
[camera]
position = [0.0, 3.0, 7.0]
look_at = [0.0, 0.6, 0.0]
[[lights]]
type = "area"
position = [0.0, 3.5, 0.0]
edge_u = [2.0, 0.0, 0.0]
edge_v = [0.0, 0.0, 1.5]
samples = 400
[[objects]]
type = "plane"
point = [0.0, 0.0, 0.0]
normal = [0.0, 1.0, 0.0]
[[objects]]
type = "sphere"
center = [0.0, 0.7, 0.0]
radius = 0.7
"""


@pytest.mark.timeout(600)
@pytest.mark.parametrize("loop", ["python", pytest.param("compiled", marks=pytest.mark.slow)])
def test_ctrl_c_ends_a_render_within_two_seconds(tmp_path, loop):
    # SIGINT once the first pass is done (the other thread is then in the middle of one):
    # exit 130 with the one line, no traceback, nothing written, within 2 s; with
    # RAYTRACE_LOOP=compiled too, where a pass is one nogil call (its first run compiles the
    # loop for minutes, hence slow).
    scene = write_text(tmp_path / "soft.toml", SOFT_SHADOWS)
    out = tmp_path / "o.exr"
    env = {**os.environ, "RAYTRACE_LOOP": loop}
    # the kernels compiled into the cache first (a first run says so on stderr, for minutes)
    subprocess.run([sys.executable, "-m", "raytrace", "render", str(scene), "--width", "8",
                    "--height", "6", "-o", str(tmp_path / "warm.exr"), "-q"], env=env,
                   check=True, capture_output=True)
    (tmp_path / "warm.exr").unlink()
    proc = subprocess.Popen(
        [sys.executable, "-c", ANNOUNCING, "render", str(scene), "-o", str(out), "--threads",
         "2"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=tmp_path,
        env=env)
    try:
        assert proc.stdout.readline().startswith("pass")  # (two threads may write at once)
        signalled = time.monotonic()
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=120)
        seconds = time.monotonic() - signalled
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert proc.returncode == 130, err
    assert err.startswith("raytrace: interrupted; no output written") and len(
        err.splitlines()) == 1, err
    assert seconds < 2.0
    assert os.listdir(tmp_path) == ["soft.toml"]
