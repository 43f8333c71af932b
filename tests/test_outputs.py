"""Outputs are all or nothing, checked before the work, and never an input (raytrace/outputs.py).

* Every output differs from every other output and from every file the scene reads (scene,
  meshes, library materials), compared resolved (``./x``, ``a/../x``, symbolic and hard links):
  exit status 2 before anything is rendered, and no file changes (bytes and mtimes), also as a
  hypothesis property over every pair of paths among scene, mesh, ``-o``, ``--png``,
  ``--stats``.
* ``--png`` must end in ``.png``.
* An output folder that takes no new file, or an immutable target, is refused before the
  render, naming the user's path.
* A failure while writing any output (a full disk: simulated, and on a real 1 MB tmpfs where
  this machine lets us mount one) leaves every old file as it was: one line, status 2.
* An interrupt between the renames: the message says exactly what was written.
* ``Image.save`` goes through the same transaction.
"""

from __future__ import annotations

import errno
import importlib
import os
import shutil
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import raytrace
import raytrace.film.outputs
from raytrace import cli
from raytrace.film import read_exr, write_exr
from raytrace.film.outputs import Outputs
from raytrace.material import library

ROOT = Path(__file__).resolve().parents[1]
RENDERING = importlib.import_module("raytrace.rendering")  # (raytrace.render: the function)
QUAD = "v 0 0 -3\nv 1 0 -3\nv 1 1 -3\nv 0 1 -3\nf 1 2 3\nf 1 3 4\n"
SCENE = """\
[render]
width = 8
height = 6
[ambient]
color = 0.5
[[objects]]
type = "sphere"
center = [0, 0, -3]
radius = 1
material = "{material}"
[[objects]]
type = "mesh"
file = "{mesh}"
"""


def folder(tmp_path: Path, mesh: str = "m.obj", material: str = "brass") -> Path:
    """scene.toml reading m.obj; old outputs out.exr, out.png, stats.json."""
    (tmp_path / "scene.toml").write_text(SCENE.format(mesh=mesh, material=material))
    (tmp_path / "m.obj").write_text(QUAD)
    write_exr(tmp_path / "out.exr", np.full((2, 3, 3), 7.0, np.float32))
    (tmp_path / "out.png").write_bytes(b"old png")
    (tmp_path / "stats.json").write_text('{"old": true}\n')
    return tmp_path


def snapshot(root: Path) -> dict[str, tuple]:
    """Every entry under ``root``: (kind, bytes or link target, mtime in ns)."""
    out = {}
    for p in sorted(root.rglob("*")):
        st_ = p.lstat()
        if p.is_symlink():
            out[str(p.relative_to(root))] = ("link", os.readlink(p), st_.st_mtime_ns)
        elif p.is_dir():
            out[str(p.relative_to(root))] = ("dir", None, None)
        else:
            out[str(p.relative_to(root))] = ("file", p.read_bytes(), st_.st_mtime_ns)
    return out


def run(cwd: Path, args: list, capsys) -> tuple[int, str]:
    here = os.getcwd()
    os.chdir(cwd)
    try:
        rc = cli.main([str(a) for a in args])
    finally:
        os.chdir(here)
    return rc, capsys.readouterr().err


@pytest.fixture
def no_render(monkeypatch):
    """Fail the test if the render starts: checks must come before it."""
    def refuse(*args, **kwargs):
        raise AssertionError("rendered although an output was bad")

    monkeypatch.setattr(RENDERING, "render", refuse)


# -- collisions, before anything is rendered --------------------------------------------------
@pytest.mark.parametrize("args,key,fragment", [
    (["scene.toml", "-o", "out.exr", "--stats", "out.exr"], "--stats", "same file as -o"),
    (["scene.toml", "-o", "out.exr", "--stats", "./out.exr"], "--stats", "same file as -o"),
    (["scene.toml", "-o", "out.exr", "--png", "out.exr"], "--png", ".png"),
    (["scene.toml", "--png", "scene.toml"], "--png", ".png"),
    (["scene.toml", "--stats", "scene.toml"], "--stats", "the scene file"),
    (["scene.toml", "--stats", "sub/../scene.toml"], "--stats", "the scene file"),
    (["scene.toml", "--stats", "m.obj"], "--stats", "mesh file of objects[1]"),
    (["scene.toml", "-o", "out.exr", "--png", "out.png", "--stats", "out.png"], "--stats",
     "same file as --png"),
    (["scene.toml", "--png", "x.jpg"], "--png", "must be a .png file"),
])
def test_colliding_or_misnamed_outputs_exit_2_before_rendering(tmp_path, capsys, no_render,
                                                               args, key, fragment):
    folder(tmp_path)
    (tmp_path / "sub").mkdir()
    before = snapshot(tmp_path)
    rc, err = run(tmp_path, ["render", *args, "-q"], capsys)
    assert rc == 2 and len(err.splitlines()) == 1, err
    assert err.startswith(f"raytrace: error: {key}: ") and fragment in err, err
    assert snapshot(tmp_path) == before


def test_the_json_scene_as_its_own_stats_file(tmp_path, capsys, no_render):
    scene = tmp_path / "scene.json"
    scene.write_text('{"objects": [{"type": "sphere", "center": [0, 0, -3], "radius": 1}]}')
    before = snapshot(tmp_path)
    rc, err = run(tmp_path, ["render", "scene.json", "--stats", "scene.json", "-q"], capsys)
    assert rc == 2 and "--stats" in err and "the scene file" in err
    assert snapshot(tmp_path) == before


def test_symbolic_and_hard_links_to_an_input_are_the_input(tmp_path, capsys, no_render):
    folder(tmp_path)
    (tmp_path / "soft.json").symlink_to(tmp_path / "scene.toml")
    os.link(tmp_path / "m.obj", tmp_path / "hard.json")
    before = snapshot(tmp_path)
    for link, what in (("soft.json", "the scene file"), ("hard.json", "mesh file")):
        rc, err = run(tmp_path, ["render", "scene.toml", "--stats", link, "-q"], capsys)
        assert rc == 2 and what in err, err
    assert snapshot(tmp_path) == before


def test_a_library_material_file_the_scene_reads_is_an_input(tmp_path, capsys, no_render,
                                                             monkeypatch):
    # A library of two files in tmp_path (never the real one): "shiny" is based on "coat".
    lib = tmp_path / "lib"
    lib.mkdir()
    (lib / "coat.json").write_text('kd = 0.5\n')  # TOML, whatever the name says
    (lib / "shiny.toml").write_text('base = "coat"\nks = 0.4\n')
    monkeypatch.setattr(library, "_files", {"coat": lib / "coat.json",
                                            "shiny": lib / "shiny.toml"})
    monkeypatch.setattr(library, "_cache", {})
    folder(tmp_path, material="shiny")
    before = snapshot(tmp_path)
    for target in ("lib/coat.json", "lib/shiny.toml"):
        rc, err = run(tmp_path, ["render", "scene.toml", "--stats", target, "-q"], capsys)
        assert rc == 2 and "the file of material 'shiny'" in err, err
    assert snapshot(tmp_path) == before


def test_an_inline_material_s_texture_is_named_by_its_object(tmp_path, capsys):
    # An inline material has no name: the line names the object whose material reads the file.
    from PIL import Image as PILImage

    folder(tmp_path)
    PILImage.new("RGB", (2, 2), (200, 30, 30)).save(tmp_path / "tex.png")
    scene = (tmp_path / "scene.toml").read_text()
    (tmp_path / "scene.toml").write_text(scene.replace('material = "brass"',
                                                       'material = { kd = { texture = '
                                                       '"tex.png" } }'))
    before = snapshot(tmp_path)
    rc, err = run(tmp_path, ["render", "scene.toml", "--png", "tex.png", "-q"], capsys)
    assert (rc, err) == (2, "raytrace: error: --png: tex.png is the file of the material of "
                            "objects[0], which this command reads: an output never overwrites "
                            "an input\n")
    assert snapshot(tmp_path) == before

ROLES = ("scene", "mesh", "-o", "--png", "--stats")
NAMES = {"scene": "scene.toml", "mesh": "m.obj", "-o": "out.exr", "--png": "out.png",
         "--stats": "stats.json"}
SPELLINGS = ("plain", "dot", "updown", "absolute", "symlink", "hardlink")


#: Two roles that may name one file: both inputs (``raytrace render m.obj`` reads the model that
#: is its own mesh). It was refused only while an OBJ without MTL could not render alone.
INPUTS = {"scene", "mesh"}


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(pair=st.permutations(ROLES).map(lambda p: p[:2]).filter(lambda p: set(p) != INPUTS),
       spelling=st.sampled_from(SPELLINGS), old_outputs=st.booleans())
def test_any_two_paths_that_are_one_file_exit_2_and_change_nothing(pair, spelling,
                                                                    old_outputs):
    import tempfile

    owner, other = pair  # `other` names `owner`'s file, spelt another way
    with tempfile.TemporaryDirectory() as d:
        root = Path(d)
        (root / "sub").mkdir()
        shared = root / NAMES[owner]
        exists = old_outputs or owner in ("scene", "mesh")
        if spelling == "hardlink" and not exists:
            spelling = "symlink"  # no hard link to a file that does not exist
        spelt = {"plain": NAMES[owner], "dot": f"./{NAMES[owner]}",
                 "updown": f"sub/../{NAMES[owner]}", "absolute": str(shared),
                 "symlink": "link" + shared.suffix, "hardlink": "hard" + shared.suffix}[spelling]
        names = {**NAMES, other: spelt}
        (root / "scene.toml").write_text(SCENE.format(mesh=names["mesh"], material="brass"))
        (root / "m.obj").write_text(QUAD)
        if old_outputs:
            write_exr(root / "out.exr", np.full((2, 3, 3), 7.0, np.float32))
            (root / "out.png").write_bytes(b"old png")
            (root / "stats.json").write_text('{"old": true}\n')
        if spelling == "symlink":
            (root / spelt).symlink_to(shared)
        elif spelling == "hardlink":
            os.link(shared, root / spelt)
        args = ["render", names["scene"], "-o", names["-o"], "--png", names["--png"],
                "--stats", names["--stats"], "-q"]
        before = snapshot(root)
        here = os.getcwd()
        os.chdir(root)
        try:
            rc = cli.main(args)
        finally:
            os.chdir(here)
        assert rc == 2, (pair, spelling, old_outputs)
        assert snapshot(root) == before, (pair, spelling, old_outputs)


# -- checked before the render -----------------------------------------------------------------
def test_a_folder_that_takes_no_new_file_is_found_before_the_render(tmp_path, capsys,
                                                                     no_render, monkeypatch):
    folder(tmp_path)
    ro = tmp_path / "ro"
    ro.mkdir()
    real = raytrace.film.outputs.tempfile.mkstemp

    def mkstemp(*args, dir=None, **kwargs):  # noqa: A002  (tempfile's name)
        if Path(dir) == ro:
            raise PermissionError(errno.EACCES, "Permission denied")
        return real(*args, dir=dir, **kwargs)

    monkeypatch.setattr(raytrace.film.outputs.tempfile, "mkstemp", mkstemp)
    before = snapshot(tmp_path)
    for flag, name in (("--png", "ro/p.png"), ("--stats", "ro/s.json")):
        rc, err = run(tmp_path, ["render", "scene.toml", "-o", "out.exr", flag, name, "-q"],
                      capsys)
        assert rc == 2 and len(err.splitlines()) == 1, err
        assert err == f"raytrace: error: {name}: {flag}: cannot create a file in ro: " \
                      "Permission denied\n"
    assert snapshot(tmp_path) == before


def chattr(flag: str, path: Path) -> bool:
    if shutil.which("chattr") is None:
        return False
    return subprocess.run(["chattr", flag, str(path)], capture_output=True).returncode == 0


def test_an_immutable_folder_or_file_is_found_before_the_render(tmp_path, capsys, no_render):
    folder(tmp_path)
    locked = tmp_path / "locked"
    locked.mkdir()
    if not chattr("+i", locked):
        pytest.skip("chattr +i is not permitted here (needs root on ext4/tmpfs/xfs)")
    try:
        assert chattr("+i", tmp_path / "out.png")
        before = snapshot(tmp_path)
        rc, err = run(tmp_path, ["render", "scene.toml", "--png", "locked/p.png", "-q"], capsys)
        assert rc == 2 and "locked/p.png: --png: cannot create a file in locked" in err, err
        rc, err = run(tmp_path, ["render", "scene.toml", "--png", "out.png", "-q"], capsys)
        assert rc == 2 and "out.png: --png: cannot be replaced: the file is immutable" in err
        assert ".tmp" not in err
        assert snapshot(tmp_path) == before
    finally:
        chattr("-i", locked)
        chattr("-i", tmp_path / "out.png")


def test_a_stream_is_not_an_output(tmp_path, capsys, no_render):
    folder(tmp_path)
    rc, err = run(tmp_path, ["render", "scene.toml", "--stats", "/dev/stdout", "-q"], capsys)
    assert rc == 2 and "/dev/stdout: --stats: is a device or stream" in err


# -- failures while writing: nothing changes ---------------------------------------------------
def test_a_failing_png_or_stats_write_leaves_the_old_exr(tmp_path, capsys, monkeypatch):
    folder(tmp_path)
    before = snapshot(tmp_path)
    real_write_text = Path.write_text

    def full(self, data, *a, **kw):
        if self.name.startswith(".stats.json."):
            raise OSError(errno.ENOSPC, "No space left on device")
        return real_write_text(self, data, *a, **kw)

    monkeypatch.setattr(Path, "write_text", full)
    rc, err = run(tmp_path, ["render", "scene.toml", "-o", "out.exr", "--png", "out.png",
                             "--stats", "stats.json", "-q"], capsys)
    assert rc == 2 and len(err.splitlines()) == 1, err
    assert err == ("raytrace: error: stats.json: --stats: cannot write: No space left on "
                   "device; no output written (out.exr, out.png, stats.json left as they "
                   "were)\n")
    assert snapshot(tmp_path) == before  # the EXR and PNG, complete, were not renamed


def test_a_full_disk_in_the_exr_writer_is_one_line_naming_the_output(tmp_path, capsys,
                                                                      monkeypatch):
    # OpenEXR reports a full disk as RuntimeError naming the file it was writing: the message
    # must name the user's file instead, the status is 2, and the old file stays.
    import OpenEXR

    real = OpenEXR.File

    class Full:
        def __init__(self, *args, **kwargs):
            self._f = real(*args, **kwargs)

        def __enter__(self):
            return self

        def __exit__(self, *exc):
            return False

        def write(self, path):
            Path(path).write_bytes(b"v/1\x01 half")
            raise RuntimeError(f'Failed to write pixel data to image file "{path}". No space '
                               "left on device.")

    folder(tmp_path)
    before = snapshot(tmp_path)
    monkeypatch.setattr(OpenEXR, "File", Full)
    rc, err = run(tmp_path, ["render", "scene.toml", "-o", "out.exr", "-q"], capsys)
    assert rc == 2 and len(err.splitlines()) == 1 and "Traceback" not in err, err
    assert err == ("raytrace: error: out.exr: -o: cannot write: Failed to write pixel data to "
                   "image file out.exr. No space left on device; no output written (out.exr "
                   "left as it was)\n")
    assert snapshot(tmp_path) == before


@pytest.fixture
def tiny_tmpfs(tmp_path):
    """A 1 MB tmpfs, where this machine lets the tests mount one (root in a container)."""
    mnt = tmp_path / "tiny"
    mnt.mkdir()
    if shutil.which("mount") is None or subprocess.run(
            ["mount", "-t", "tmpfs", "-o", "size=1m", "tmpfs", str(mnt)],
            capture_output=True).returncode != 0:
        pytest.skip("mounting a tmpfs is not permitted here")
    try:
        yield mnt
    finally:
        subprocess.run(["umount", str(mnt)], check=True)


def test_a_real_full_disk_is_one_line_and_the_old_file_stays(tiny_tmpfs, capsys):
    old = tiny_tmpfs / "w.exr"
    write_exr(old, np.full((2, 3, 3), 7.0, np.float32))
    before = snapshot(tiny_tmpfs)
    # Whitted at 640×480 compresses to ~1.8 MB: more than the 1 MB there is.
    rc, err = run(tiny_tmpfs, ["render", ROOT / "scenes" / "whitted.toml", "-o", old,
                               "--width", "640", "--height", "480", "-q"], capsys)
    assert rc == 2 and len(err.splitlines()) == 1 and "Traceback" not in err, err
    assert err.startswith(f"raytrace: error: {old}: -o: cannot write: ")
    assert err.rstrip().endswith(f"No space left on device; no output written ({old} left as "
                                 "it was)") and ".tmp" not in err
    assert snapshot(tiny_tmpfs) == before


# -- interrupts between the renames ------------------------------------------------------------
def test_ctrl_c_during_the_renames_waits_for_them(tmp_path, capsys, monkeypatch):
    folder(tmp_path)
    targets = {(tmp_path / n).resolve() for n in ("out.exr", "out.png", "stats.json")}
    real = os.replace

    def replace(src, dst):
        real(src, dst)
        if Path(dst) in targets:  # a real SIGINT right after the first rename
            targets.clear()
            os.kill(os.getpid(), signal.SIGINT)

    monkeypatch.setattr(raytrace.film.outputs.os, "replace", replace)
    rc, err = run(tmp_path, ["render", "scene.toml", "-o", "out.exr", "--png", "out.png",
                             "--stats", "stats.json", "-q"], capsys)
    assert rc == 130
    assert err == ("raytrace: interrupted; wrote out.exr, out.png, stats.json (every "
                   "output)\n")
    assert read_exr(tmp_path / "out.exr")[0].shape == (6, 8, 3)
    assert (tmp_path / "out.png").read_bytes()[:4] == b"\x89PNG"
    assert '"rays"' in (tmp_path / "stats.json").read_text()
    assert not list(tmp_path.glob(".*"))  # no temporary file


def test_an_interrupt_between_renames_is_reported_exactly(tmp_path, capsys, monkeypatch):
    # Where Ctrl-C cannot be held off (a KeyboardInterrupt raised inside the second rename),
    # the line says which outputs were replaced and which were left as they were.
    folder(tmp_path)
    old = snapshot(tmp_path)
    finals = [(tmp_path / n).resolve() for n in ("out.exr", "out.png", "stats.json")]
    real = os.replace

    def replace(src, dst):
        if Path(dst) == finals[1]:
            raise KeyboardInterrupt
        real(src, dst)

    monkeypatch.setattr(raytrace.film.outputs.os, "replace", replace)
    rc, err = run(tmp_path, ["render", "scene.toml", "-o", "out.exr", "--png", "out.png",
                             "--stats", "stats.json", "-q"], capsys)
    assert rc == 130
    assert err == ("raytrace: interrupted; wrote out.exr; not written: out.png, stats.json "
                   "(left as they were)\n")
    now = snapshot(tmp_path)
    assert now["out.exr"] != old["out.exr"]
    assert now["out.png"] == old["out.png"] and now["stats.json"] == old["stats.json"]
    assert sorted(now) == sorted(old)  # no temporary file


def test_an_interrupted_render_names_what_was_left(tmp_path, capsys, monkeypatch):
    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(RENDERING, "render", interrupted)
    folder(tmp_path)
    before = snapshot(tmp_path)
    rc, err = run(tmp_path, ["render", "scene.toml", "-o", "out.exr", "--png", "out.png",
                             "-q"], capsys)
    assert rc == 130
    assert err == ("raytrace: interrupted; no output written (out.exr, out.png left as they "
                   "were)\n")
    assert snapshot(tmp_path) == before


# -- the transaction itself, and Image.save ------------------------------------------------------
def test_outputs_commit_only_when_all_are_staged(tmp_path):
    with Outputs() as out:
        a = out.add(tmp_path / "a.txt", "a")
        b = out.add(tmp_path / "b.txt", "b")
        out.preflight()
        with out.stage(a) as tmp:
            tmp.write_text("A")
        with pytest.raises(RuntimeError, match="not staged"):
            out.commit()
        assert out.written == [] and out.not_written == [str(a.path), str(b.path)]
    assert os.listdir(tmp_path) == []  # the staged temporary file is gone too


def test_image_save_into_a_missing_folder_names_the_folder(tmp_path):
    image = raytrace.Image(np.zeros((2, 2, 3), np.float32))
    with pytest.raises(FileNotFoundError) as e:
        image.save(tmp_path / "nodir" / "x.exr")
    assert e.value.filename == str(tmp_path / "nodir" / "x.exr")
    assert "folder does not exist" in str(e.value) and ".tmp" not in str(e.value)
    assert os.listdir(tmp_path) == []


def test_image_save_on_a_full_disk_keeps_the_old_file(tmp_path, monkeypatch):
    target = tmp_path / "x.png"
    target.write_bytes(b"old")

    def full(path, *args):  # the PNG writer fills the disk halfway through its file
        Path(path).write_bytes(b"\x89PN")
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr("raytrace.film.previews.write_png_bands", full)
    with pytest.raises(OSError) as e:
        raytrace.Image(np.ones((2, 2, 3), np.float32)).save(target)
    assert e.value.errno == errno.ENOSPC and e.value.filename == str(target)
    assert target.read_bytes() == b"old" and os.listdir(tmp_path) == ["x.png"]


def test_outputs_module_is_light():
    # The transaction imports nothing heavy: the command line loads it before anything else.
    got = subprocess.run([sys.executable, "-c", "import sys, raytrace.film.outputs; "
                          "print(' '.join(sys.modules))"], capture_output=True, text=True,
                         check=True).stdout.split()
    assert not {"numba", "OpenEXR", "colour", "trimesh", "embreex"} & set(got)
