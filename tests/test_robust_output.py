"""Bad input never corrupts anything; outputs are complete or absent.

* Every kind of bad input, through ``raytrace.cli.main``: exit status 2, exactly one line on
  stderr naming the scene file, the key and the problem, no traceback, and nothing written
  (no EXR, PNG or stats file, no temporary file) — also where an old output already exists.
* An interrupted write (KeyboardInterrupt inside the EXR, PNG or JSON writer) leaves the old
  file byte for byte, and no temporary file.
* SIGINT to a real ``python -m raytrace render`` mid-render (seen through its progress bar on a
  pseudo-terminal) leaves the old EXR untouched, no new PNG/stats, no temporary file, status 130.
* A successful render replaces an existing output with a complete new one.
"""

from __future__ import annotations

import json
import os
import select
import signal
import subprocess
import sys
import time
import types
from pathlib import Path

import numpy as np
import pytest

import raytrace
from raytrace.cli import main
from raytrace.film import read_exr, write_exr

ROOT = Path(__file__).resolve().parents[1]
OBJ_QUAD = b"v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3\nf 1 3 4\n"

SMALL = "[render]\nwidth = 8\nheight = 6\n"
SPHERE = '[[objects]]\ntype = "sphere"\ncenter = [0, 0, -3]\nradius = 1\n'


def mesh(vertices: str, faces: str = "[[0, 1, 2]]", extra: str = "") -> str:
    return f'[[objects]]\ntype = "mesh"\nvertices = {vertices}\nfaces = {faces}\n{extra}'


def mesh_file(name: str) -> str:
    return f'[[objects]]\ntype = "mesh"\nfile = "{name}"\n'


def light(kind: str, body: str) -> str:
    return f'[[lights]]\ntype = "{kind}"\n{body}'


#: name: (scene text after SMALL, extra files, key the error names, fragment of the problem)
BAD_INPUT = {
    "nan in inline vertices": (mesh("[[0, 0, 0], [1, 0, 0], [nan, 1, 0]]"), {},
                               "objects[0].vertices", "not finite"),
    "inf in inline vertices": (mesh("[[0, 0, 0], [1, 0, 0], [0, inf, 0]]"), {},
                               "objects[0].vertices", "not finite"),
    "nan in an OBJ": (mesh_file("m.obj"), {"m.obj": b"v 0 0 0\nv 1 0 0\nv nan 1 0\nf 1 2 3\n"},
                      "objects[0].file", "not finite"),
    "inf in an OBJ": (mesh_file("m.obj"), {"m.obj": b"v 0 0 0\nv 1 0 0\nv 0 inf 0\nf 1 2 3\n"},
                      "objects[0].file", "not finite"),
    "OBJ vertices beyond float32": (mesh_file("big.obj"),
                                    {"big.obj": b"v 0 0 0\nv 1e30 0 0\nv 0 1 0\nf 1 2 3\n"},
                                    "objects[0].file", "float32"),
    "vertices beyond float32": (mesh("[[0, 0, 0], [1e30, 0, 0], [0, 1, 0]]"), {},
                                "objects[0].vertices", "float32"),
    "scale beyond float32": (mesh("[[0, 0, 0], [1, 0, 0], [0, 1, 0]]", extra="scale = 1e20\n"),
                             {}, "objects[0].scale", "float32"),
    "only zero-area faces": (mesh("[[0, 0, 0], [1, 0, 0], [2, 0, 0]]"), {},
                             "objects[0].faces", "non-zero area"),
    "quads as faces": (mesh("[[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]]", "[[0, 1, 2, 3]]"),
                       {}, "objects[0].faces", "triangles only"),
    "zero directional direction": (light("directional", "direction = [0, 0, 0]\n"), {},
                                   "lights[0].direction", "zero vector"),
    "zero spot direction": (light("spot", "position = [0, 1, 0]\ndirection = [0, 0, 0]\n"), {},
                            "lights[0].direction", "zero vector"),
    "zero plane normal": ('[[objects]]\ntype = "plane"\npoint = [0, 0, 0]\nnormal = [0, 0, 0]\n',
                          {}, "objects[0].normal", "zero vector"),
    "zero area-light edge": (light("area", "position = [0, 2, 0]\nedge_u = [0, 0, 0]\n"
                                   "edge_v = [0, 0, 1]\n"), {}, "lights[0].edge_u",
                             "zero vector"),
    "up parallel to view": ("[camera]\nposition = [0, 0, 0]\nlook_at = [0, 5, 0]\n"
                            "up = [0, 1, 0]\n", {}, "camera.up", "parallel"),
    "up antiparallel to view": ("[camera]\nposition = [0, 0, 0]\nlook_at = [0, -5, 0]\n"
                                "up = [0, 2, 0]\n", {}, "camera.up", "parallel"),
    "fov 0": ("[camera]\nfov = 0\n", {}, "camera.fov", "(0, 180)"),
    "fov negative": ("[camera]\nfov = -10\n", {}, "camera.fov", "(0, 180)"),
    "fov 180": ("[camera]\nfov = 180\n", {}, "camera.fov", "(0, 180)"),
    "fov 200": ("[camera]\nfov = 200\n", {}, "camera.fov", "(0, 180)"),
    "negative radius": (SPHERE.replace("radius = 1", "radius = -1"), {}, "objects[0].radius",
                        "> 0"),
    "negative ior": ("[materials.g]\nior = -1.5\n", {}, "materials.g.ior", "> 0"),
    "negative inline ior": (SPHERE + "material = { ior = -1 }\n", {},
                            "objects[0].material.ior", "> 0"),
    "kr above 1": ("[materials.g]\nkr = 1.5\n", {}, "materials.g.kr", "[0, 1]"),
    "kt below 0": ("[materials.g]\nkt = -0.1\n", {}, "materials.g.kt", "[0, 1]"),
    "opacity above 1": ("[materials.g]\nopacity = 1.01\n", {}, "materials.g.opacity", "[0, 1]"),
    "kr channel above 1": ("[materials.g]\nkr = [0.1, 1.2, 0.3]\n", {}, "materials.g.kr[1]",
                           "got 1.2"),
    "area samples not square": (light("area", "position = [0, 2, 0]\nedge_u = [1, 0, 0]\n"
                                      "edge_v = [0, 0, 1]\nsamples = 15\n"), {},
                                "lights[0].samples", "perfect square"),
    "attenuation all zero": (light("point", "position = [0, 2, 0]\nattenuation = [0, 0, 0]\n"),
                             {}, "lights[0].attenuation", "not all zero"),
    "attenuation negative": (light("point", "position = [0, 2, 0]\n"
                                   "attenuation = [1, -0.5, 0]\n"), {},
                             "lights[0].attenuation", ">= 0"),
    "spot cutoff 0": (light("spot", "position = [0, 2, 0]\ndirection = [0, -1, 0]\n"
                            "cutoff = 0\n"), {}, "lights[0].cutoff", "(0, 90]"),
    "spot cutoff above 90": (light("spot", "position = [0, 2, 0]\ndirection = [0, -1, 0]\n"
                                   "cutoff = 90.5\n"), {}, "lights[0].cutoff", "(0, 90]"),
    "garbage mesh file": (mesh_file("junk.obj"),
                          {"junk.obj": b"hello world\nthis is not a mesh\n\x01\x02garbage"},
                          "objects[0].file", "junk.obj"),
    "OBJ with only points and lines": (mesh_file("lines.obj"),
                                       {"lines.obj": b"v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\n"
                                                     b"p 1\nl 1 2\nl 2 3 4\n"},
                                       "objects[0].file", "no triangle"),
    "missing mesh file": (mesh_file("nowhere.obj"), {}, "objects[0].file", "not found"),
    "random bytes as STL": (mesh_file("noise.stl"),
                            {"noise.stl": bytes(np.random.default_rng(4).integers(0, 256, 300,
                                                                                 np.uint8))},
                            "objects[0].file", "noise.stl"),
    "truncated STL": (mesh_file("cut.stl"), {"cut.stl": b"solid x\nfacet normal 0 0 1\n"},
                      "objects[0].file", "cut.stl"),
    "zero up vector": ("[camera]\nup = [0, 0, 0]\n", {}, "camera.up", "zero vector"),
    "look_at equals position": ("[camera]\nposition = [1, 2, 3]\nlook_at = [1, 2, 3]\n", {},
                                "camera.look_at", "differ"),
    "absurd image": ("[render]\nwidth = 100000\nheight = 100000\n", {}, "render.width",
                     "pixels"),
    "absurd width": ("[render]\nwidth = 1e12\nheight = 1\n", {}, "render.width", "100000"),
}


def run_cli(tmp_path: Path, args: list, capsys) -> tuple[int, str, str]:
    cwd = os.getcwd()
    os.chdir(tmp_path)  # relative outputs land in tmp_path too
    try:
        rc = main([str(a) for a in args])
    finally:
        os.chdir(cwd)
    cap = capsys.readouterr()
    return rc, cap.out, cap.err


@pytest.mark.parametrize("case", list(BAD_INPUT), ids=list(BAD_INPUT))
def test_bad_input_one_line_exit_2_nothing_written(tmp_path, capsys, case):
    body, files, key, fragment = BAD_INPUT[case]
    scene = tmp_path / "bad.toml"
    scene.write_text(SMALL + body if not body.startswith("[render]") else body)
    for name, data in files.items():
        (tmp_path / name).write_bytes(data)
    before = sorted(os.listdir(tmp_path))
    rc, out, err = run_cli(tmp_path, ["render", scene, "-o", tmp_path / "out.exr", "--png",
                                      tmp_path / "out.png", "--stats", tmp_path / "s.json",
                                      "-q"], capsys)
    assert rc == 2
    assert out == ""
    lines = err.splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith(f"raytrace: error: {scene}: {key}: "), lines[0]
    assert fragment in lines[0]
    assert "Traceback" not in err
    assert sorted(os.listdir(tmp_path)) == before  # no output, no temporary file


def test_bad_json_scene_with_nan(tmp_path, capsys):
    scene = tmp_path / "bad.json"
    scene.write_text(json.dumps({"objects": [{"type": "sphere", "center": [0, 0, float("nan")],
                                              "radius": 1}]}))
    rc, _, err = run_cli(tmp_path, ["render", scene, "-o", tmp_path / "o.exr", "-q"], capsys)
    assert rc == 2 and len(err.splitlines()) == 1
    assert f"{scene}: objects[0].center[2]: must be finite" in err
    assert sorted(os.listdir(tmp_path)) == ["bad.json"]


@pytest.mark.parametrize("flags,named", [
    (["--width", "100000", "--height", "100000"], "--width"),
    (["--width", "0"], "--width"),
    (["--spp", "0"], "--spp"),
    (["--max-depth", "-1"], "--max-depth"),
])
def test_absurd_flags_one_line_nothing_written(tmp_path, capsys, flags, named):
    scene = tmp_path / "ok.toml"
    scene.write_text(SMALL + SPHERE)
    rc, _, err = run_cli(tmp_path, ["render", scene, "-o", tmp_path / "o.exr", "-q", *flags],
                         capsys)
    assert rc == 2 and len(err.splitlines()) == 1, err
    assert named in err
    assert sorted(os.listdir(tmp_path)) == ["ok.toml"]


def test_output_that_is_a_folder_is_refused_before_rendering(tmp_path, capsys):
    scene = tmp_path / "ok.toml"
    scene.write_text(SMALL + SPHERE)
    (tmp_path / "out.exr").mkdir()
    rc, _, err = run_cli(tmp_path, ["render", scene, "-o", tmp_path / "out.exr", "-q"], capsys)
    assert rc == 2 and len(err.splitlines()) == 1 and "-o" in err and "folder" in err
    assert sorted(os.listdir(tmp_path)) == ["ok.toml", "out.exr"]


# -- old outputs survive --------------------------------------------------------------------------
def old_outputs(tmp_path: Path) -> dict[str, bytes]:
    """An existing EXR (2×3, value 7), PNG and stats file, as a user's earlier render left."""
    write_exr(tmp_path / "out.exr", np.full((2, 3, 3), 7.0, np.float32))
    (tmp_path / "out.png").write_bytes(b"old png")
    (tmp_path / "s.json").write_text('{"old": true}\n')
    return {n: (tmp_path / n).read_bytes() for n in ("out.exr", "out.png", "s.json")}


def test_bad_input_leaves_existing_outputs_untouched(tmp_path, capsys):
    old = old_outputs(tmp_path)
    scene = tmp_path / "bad.toml"
    scene.write_text(SMALL + SPHERE.replace("radius = 1", "radius = -1"))
    rc, _, _ = run_cli(tmp_path, ["render", scene, "-o", tmp_path / "out.exr", "--png",
                                  tmp_path / "out.png", "--stats", tmp_path / "s.json", "-q"],
                       capsys)
    assert rc == 2
    assert {n: (tmp_path / n).read_bytes() for n in old} == old
    assert sorted(os.listdir(tmp_path)) == sorted([*old, "bad.toml"])


def test_successful_render_replaces_outputs_with_complete_ones(tmp_path, capsys):
    old = old_outputs(tmp_path)
    scene = tmp_path / "ok.toml"
    scene.write_text(SMALL + SPHERE + '[ambient]\ncolor = 0.5\n')
    rc, _, err = run_cli(tmp_path, ["render", scene, "-o", tmp_path / "out.exr", "--png",
                                    tmp_path / "out.png", "--stats", tmp_path / "s.json", "-q"],
                         capsys)
    assert rc == 0, err
    rgb, _ = read_exr(tmp_path / "out.exr")
    want = raytrace.render(raytrace.load_scene(scene)).rgb
    np.testing.assert_array_equal(rgb, want)  # the whole new 8×6 image
    assert (tmp_path / "out.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert json.loads((tmp_path / "s.json").read_text())["width"] == 8
    assert sorted(os.listdir(tmp_path)) == sorted([*old, "ok.toml"])


# -- interrupted writes ---------------------------------------------------------------------------
def interrupting_openexr() -> types.ModuleType:
    """A stand-in for the OpenEXR module whose write puts half a header down, then is
    interrupted (as by Ctrl-C in the middle of writing)."""
    fake = types.ModuleType("OpenEXR")
    fake.ZIP_COMPRESSION, fake.scanlineimage = 0, 0

    class File:
        def __init__(self, header, channels):
            pass

        def __enter__(self):
            return self

        def __exit__(self, *exc):
            return False

        def write(self, path):
            Path(path).write_bytes(b"\x76\x2f\x31\x01\x02\x00")
            raise KeyboardInterrupt

    fake.File = File
    return fake


def test_interrupted_exr_write_keeps_the_old_file(tmp_path, capsys, monkeypatch):
    old = old_outputs(tmp_path)
    scene = tmp_path / "ok.toml"
    scene.write_text(SMALL + SPHERE)
    monkeypatch.setitem(sys.modules, "OpenEXR", interrupting_openexr())
    rc, _, err = run_cli(tmp_path, ["render", scene, "-o", tmp_path / "out.exr", "--png",
                                    tmp_path / "out.png", "-q"], capsys)
    assert rc == 130 and "interrupted" in err and len(err.splitlines()) == 1
    assert "no output written" in err
    assert {n: (tmp_path / n).read_bytes() for n in old} == old
    assert sorted(os.listdir(tmp_path)) == sorted([*old, "ok.toml"])


def interrupt_after_half(monkeypatch, method: str, tmp_path: Path) -> None:
    """The PNG writer (OpenImageIO, fed band by band) or the JSON writer (``Path.write_text``)
    puts part of its file down, then is interrupted like Ctrl-C."""
    if method == "png_bands":
        from raytrace.film import previews

        original = previews._bands

        def first_band_then_interrupt(*args, **kwargs):
            for band in original(*args, **kwargs):
                yield band  # the writer puts it into its temporary file
                assert any(n.endswith(".png.tmp") for n in os.listdir(tmp_path))
                raise KeyboardInterrupt

        monkeypatch.setattr(previews, "_bands", first_band_then_interrupt)
        return
    original = getattr(Path, method)

    def half_then_interrupt(self, data, *a, **kw):
        original(self, data[: len(data) // 2], *a, **kw)
        raise KeyboardInterrupt

    monkeypatch.setattr(Path, method, half_then_interrupt)


@pytest.mark.parametrize("method,flag,name", [("png_bands", "--png", "out.png"),
                                               ("write_text", "--stats", "s.json")])
def test_interrupted_png_or_stats_write_keeps_the_old_file(tmp_path, capsys, monkeypatch,
                                                           method, flag, name):
    old = old_outputs(tmp_path)
    scene = tmp_path / "ok.toml"
    scene.write_text(SMALL + SPHERE)
    interrupt_after_half(monkeypatch, method, tmp_path)
    rc, _, err = run_cli(tmp_path, ["render", scene, "-o", tmp_path / "new.exr", flag,
                                    tmp_path / name, "-q"], capsys)
    monkeypatch.undo()
    assert rc == 130
    # All or nothing: the EXR, complete by then, is not renamed into place either, and the
    # one line says so.
    assert len(err.splitlines()) == 1
    assert "no output written" in err and str(tmp_path / "new.exr") in err
    assert (tmp_path / name).read_bytes() == old[name]
    assert sorted(os.listdir(tmp_path)) == sorted([*old, "ok.toml"])


def test_sigint_mid_render_leaves_no_partial_output(tmp_path):
    # A render of a few minutes, interrupted once its progress bar (drawn on a pseudo-terminal)
    # shows the first pass done. The old EXR must stay byte for byte; the PNG and stats that
    # did not exist must still not exist; no temporary file; status 130.
    old = tmp_path / "out.exr"
    write_exr(old, np.full((2, 3, 3), 7.0, np.float32))
    before = old.read_bytes()
    master, slave = os.openpty()
    proc = subprocess.Popen(
        [sys.executable, "-m", "raytrace", "render", str(ROOT / "scenes" / "whitted.toml"),
         "-o", str(old), "--png", str(tmp_path / "new.png"), "--stats",
         str(tmp_path / "new.json"), "--width", "2000", "--height", "1500", "--spp", "4",
         "--threads", "1"],
        stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=slave, cwd=tmp_path)
    os.close(slave)
    seen = b""
    try:
        deadline = time.monotonic() + 120
        while b"%" not in seen:
            ready, _, _ = select.select([master], [], [], max(0.0, deadline - time.monotonic()))
            assert ready, f"no progress within 120 s: {seen!r}"
            seen += os.read(master, 4096)
        proc.send_signal(signal.SIGINT)
        proc.wait(timeout=120)
        while True:
            ready, _, _ = select.select([master], [], [], 1.0)
            if not ready:
                break
            try:
                chunk = os.read(master, 4096)
            except OSError:  # EIO once the child has closed its side
                break
            if not chunk:
                break
            seen += chunk
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
        os.close(master)
    assert proc.returncode == 130, seen
    assert b"interrupted" in seen and b"Traceback" not in seen
    assert b"100%|" not in seen, "the render was interrupted, not finished"
    assert old.read_bytes() == before
    assert sorted(os.listdir(tmp_path)) == ["out.exr"]
