"""Sequences on one machine (raytrace.frames): frame lists and patterns, a frame per scene file
or per call of a function, atomic outputs, resume after a crash. The same code runs frames on a
Dask cluster (tests/test_distributed.py)."""

from __future__ import annotations

import os

import numpy as np
import pytest
from helpers import write_text

import raytrace
from raytrace import cli
from raytrace.frames import frame_path, parse_frames

SHOT = """
[render]
width = 12
height = 8
[camera]
position = [{x}, 1.0, 3.0]
look_at = [0.0, 0.0, 0.0]
[[lights]]
type = "point"
position = [1.0, 4.0, 2.0]
[[objects]]
type = "sphere"
center = [0.0, 0.5, 0.0]
radius = {radius}
material = "brass"
"""


def shot(frame: int) -> raytrace.Scene:
    return raytrace.scene_from_dict({
        "render": {"width": 12, "height": 8},
        "camera": {"position": [0.2 * frame, 1.0, 3.0], "look_at": [0.0, 0.0, 0.0]},
        "lights": [{"type": "point", "position": [1.0, 4.0, 2.0]}],
        "objects": [{"type": "sphere", "center": [0.0, 0.5, 0.0], "radius": 0.5,
                     "material": "brass"}]})


def same_bits(a: np.ndarray, b: np.ndarray) -> bool:
    return a.shape == b.shape and np.array_equal(a.view(np.uint32), b.view(np.uint32))


@pytest.mark.parametrize(("spec", "frames"), [
    ("1-4", [1, 2, 3, 4]), ("1..3", [1, 2, 3]), ("7", [7]), ("3,1-2,2", [3, 1, 2]),
    ("0-0", [0]), ([5, 2, 5], [5, 2])])
def test_frame_lists(spec, frames):
    assert parse_frames(spec) == frames


@pytest.mark.parametrize(("spec", "says"), [
    ("4-2", "ends before it starts"), ("a", "not a frame list"), ("1-", "not a frame list"),
    ("-3", "not a frame list"), ("1-2000000", "over 1,000,000 frames"), ([], "no frames"),
    ([1.5], "whole number")])
def test_bad_frame_lists(spec, says):
    with pytest.raises(raytrace.SceneError, match=says) as e:
        parse_frames(spec, "--frames")
    assert e.value.key == "--frames"


@pytest.mark.parametrize(("pattern", "frame", "path"), [
    ("out.####.exr", 7, "out.0007.exr"), ("out.#.exr", 12, "out.12.exr"),
    ("a/b_%04d.exr", 3, "a/b_0003.exr"), ("f%d.exr", 42, "f42.exr"),
    ("x_%03d.exr", 12345, "x_12345.exr")])
def test_frame_paths(pattern, frame, path):
    assert str(frame_path(pattern, frame)) == path


def test_a_scene_per_file_and_the_same_pixels_as_a_single_render(tmp_path):
    for f in (1, 2):
        write_text(tmp_path / f"shot_{f:03d}.toml", SHOT.format(x=0.2 * f, radius=0.5))
    result = raytrace.render_frames(str(tmp_path / "shot_%03d.toml"),
                                    str(tmp_path / "out.####.exr"), "1-2", threads=1)
    assert result.rendered == [1, 2] and result.skipped == []
    for f in (1, 2):
        want = raytrace.render(raytrace.load_scene(tmp_path / f"shot_{f:03d}.toml"), threads=1)
        back = raytrace.Image.from_exr(tmp_path / f"out.{f:04d}.exr")
        assert same_bits(back.rgb, want.rgb)
        assert back.metadata["scene"].endswith(f"shot_{f:03d}.toml")


def test_resume_after_a_crash_renders_only_the_missing_frames(tmp_path):
    out = str(tmp_path / "f.####.exr")
    calls = []

    def scene_at(frame):
        calls.append(frame)
        return shot(frame)

    def crash_after_two(frame, paths):
        if frame == 2:
            raise KeyboardInterrupt  # the render farm's node goes down

    with pytest.raises(KeyboardInterrupt):
        raytrace.render_frames(scene_at, out, "1-4", png=str(tmp_path / "p.####.png"),
                               on_frame=crash_after_two)
    written = sorted(os.listdir(tmp_path))  # complete files only: no temporary left
    assert written == ["f.0001.exr", "f.0002.exr", "p.0001.png", "p.0002.png"]
    (tmp_path / "p.0002.png").unlink()  # an output missing: frame 2 is rendered again
    stamps = {n: (tmp_path / n).stat().st_mtime_ns for n in ("f.0001.exr", "p.0001.png")}
    calls.clear()
    progress = []
    result = raytrace.render_frames(scene_at, out, "1-4", png=str(tmp_path / "p.####.png"),
                                    progress=lambda d, t: progress.append((d, t)))
    assert calls == [2, 3, 4] and result.rendered == [2, 3, 4] and result.skipped == [1]
    assert progress == [(1, 3), (2, 3), (3, 3)]
    assert stamps == {n: (tmp_path / n).stat().st_mtime_ns for n in stamps}
    assert len(os.listdir(tmp_path)) == 8
    for f in (1, 2, 3, 4):
        assert same_bits(raytrace.read_exr(tmp_path / f"f.{f:04d}.exr")[0],
                         raytrace.render(shot(f)).rgb)
    calls.clear()
    again = raytrace.render_frames(scene_at, out, "1-4", overwrite=True)
    assert calls == [1, 2, 3, 4] and again.skipped == []


def test_a_function_that_returns_no_scene_is_one_error(tmp_path):
    with pytest.raises(raytrace.SceneError, match=r"returned dict, not a raytrace.Scene") as e:
        raytrace.render_frames(lambda f: {"camera": {}}, str(tmp_path / "o.#.exr"), "1")
    assert e.value.file == "test_a_function_that_returns_no_scene_is_one_error.<locals>.<lambda>(1)"
    assert os.listdir(tmp_path) == []


def test_the_cli_renders_frames_from_a_function_and_skips_them_on_a_rerun(tmp_path, capsys):
    anim = write_text(tmp_path / "anim.py", "import raytrace\n\n"
                      "def scene_at(frame):\n"
                      "    return raytrace.Scene(\n"
                      "        camera=raytrace.Camera(position=[0.1 * frame, 1, 4]),\n"
                      "        objects=[raytrace.Sphere([0, 0, 0], 1, material='brass')],\n"
                      "        lights=[raytrace.PointLight([2, 3, 4])],\n"
                      "        render=raytrace.RenderSettings(width=10, height=6))\n")
    args = ["render", f"{anim}:scene_at", "--frames", "2-3", "-o", str(tmp_path / "a.%02d.exr"),
            "--stats", str(tmp_path / "s.json"), "--spp", "4"]
    assert cli.main(args) == 0
    import json

    stats = json.loads((tmp_path / "s.json").read_text())
    assert stats["rendered"] == [2, 3] and stats["skipped"] == []
    assert stats["frames"]["2"]["spp"] == 4 and stats["frames"]["2"]["rays"]["camera"] == 240
    assert stats["rays"]["total"] == sum(s["rays"]["total"] for s in stats["frames"].values())
    assert sorted(os.listdir(tmp_path)) == ["a.02.exr", "a.03.exr", "anim.py", "s.json"]
    assert cli.main(args) == 0
    stats = json.loads((tmp_path / "s.json").read_text())
    assert stats["rendered"] == [] and stats["skipped"] == [2, 3]
    assert capsys.readouterr().err == ""


def test_a_bad_flag_with_frames_names_the_flag(tmp_path, capsys):
    write_text(tmp_path / "shot_1.toml", SHOT.format(x=0.0, radius=0.5))
    rc = cli.main(["render", str(tmp_path / "shot_#.toml"), "--frames", "1", "-o",
                   str(tmp_path / "o.#.exr"), "--spp", "0"])
    err = capsys.readouterr().err
    assert rc == 2 and err.startswith("raytrace: error: --spp: ") and len(err.splitlines()) == 1
    rc = cli.main(["render", str(tmp_path / "shot_#.toml"), "--frames", "1", "-o",
                   str(tmp_path / "o.#.exr"), "--crop", "0", "0", "13", "8"])
    err = capsys.readouterr().err
    assert rc == 2 and "--crop: x bounds 0..13" in err and "shot_1.toml" in err
    # the sampling flags reach every frame (they were dropped without a word)
    rc = cli.main(["render", str(tmp_path / "shot_#.toml"), "--frames", "1", "-o",
                   str(tmp_path / "o.#.exr"), "--aa", "adaptive", "--filter", "tent"])
    err = capsys.readouterr().err
    assert rc == 2 and err.startswith("raytrace: error: --filter: ") and "adaptive" in err
    assert os.listdir(tmp_path) == ["shot_1.toml"]


def test_a_bad_scene_file_of_one_frame_names_its_file(tmp_path, capsys):
    write_text(tmp_path / "shot_1.toml", SHOT.format(x=0.0, radius=0.5))
    write_text(tmp_path / "shot_2.toml", SHOT.format(x=0.0, radius=-1))
    rc = cli.main(["render", str(tmp_path / "shot_#.toml"), "--frames", "1-2", "-o",
                   str(tmp_path / "o.#.exr")])
    err = capsys.readouterr().err
    assert rc == 2 and err == (f"raytrace: error: {tmp_path / 'shot_2.toml'}: objects[0].radius:"
                               " must be > 0, got -1 (written before it: frame 1, complete; a "
                               "rerun without --overwrite skips it)\n")
    assert sorted(os.listdir(tmp_path)) == ["o.1.exr", "shot_1.toml", "shot_2.toml"]


def test_without_o_the_frames_are_named_after_the_scene_pattern(tmp_path, monkeypatch):
    (tmp_path / "shots").mkdir()
    for f in (9, 10):
        write_text(tmp_path / "shots" / f"shot_{f:02d}.toml", SHOT.format(x=0.1 * f, radius=0.5))
    monkeypatch.chdir(tmp_path)
    assert cli.main(["render", "shots/shot_##.toml", "--frames", "9-10", "-q"]) == 0
    assert sorted(p for p in os.listdir(tmp_path) if p.endswith(".exr")) == [
        "shot.0009.exr", "shot.0010.exr"]


@pytest.mark.parametrize(("flags", "says"), [
    (["-o", "missing/o.####.exr"], "-o: folder does not exist: missing"),
    (["-o", "o.####.tif"], "-o: must end in .exr, got 'o.####.tif'"),
    (["--png", "p.####.jpg"], "--png: must end in .png"),
    (["--png", "p/#/x.png"], "--png: 'p/#/x.png' needs one frame number in its file name"),
    (["--stats", "shot_1.toml"], "--stats: would overwrite the input shot_1.toml")])
def test_bad_frame_output_patterns_are_one_line(tmp_path, monkeypatch, capsys, flags, says):
    write_text(tmp_path / "shot_1.toml", SHOT.format(x=0.0, radius=0.5))
    monkeypatch.chdir(tmp_path)
    assert cli.main(["render", "shot_#.toml", "--frames", "1", *flags]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"raytrace: error: {says}") and len(err.splitlines()) == 1, err
    assert os.listdir(tmp_path) == ["shot_1.toml"]


ANIM = ("import raytrace\n\n"
        "def scene_at(frame):\n"
        "    if frame == 3:\n"
        "        return {}['camera']\n"
        "    return raytrace.Scene(\n"
        "        camera=raytrace.Camera(position=[0.1 * frame, 1, 4]),\n"
        "        objects=[raytrace.Sphere([0, 0, 0], 1, material='brass')],\n"
        "        render=raytrace.RenderSettings(width=6, height=4))\n")


def test_a_frames_function_that_raises_is_one_line_naming_it_and_the_frames_written(
        tmp_path, capsys, monkeypatch):
    write_text(tmp_path / "anim.py", ANIM)
    monkeypatch.chdir(tmp_path)
    rc = cli.main(["render", "anim.py:scene_at", "--frames", "1-4", "-o", "a.#.exr"])
    assert (rc, capsys.readouterr().err) == (
        2, "raytrace: error: anim.py:scene_at(3): raised KeyError: 'camera' (written before "
           "it: frames 1-2, complete; a rerun without --overwrite skips them)\n")
    assert sorted(os.listdir(tmp_path)) == ["a.1.exr", "a.2.exr", "anim.py"]


def test_an_engine_error_on_a_later_frame_says_which_frames_were_written(tmp_path, capsys,
                                                                       monkeypatch):
    import raytrace.frames
    from raytrace.errors import EngineError

    real = raytrace.frames.render

    def render(scene, **kwargs):
        if scene.camera.position[0] > 0.15:  # frame 2
            raise EngineError("Embree: out of memory building the BVH")
        return real(scene, **kwargs)

    monkeypatch.setattr(raytrace.frames, "render", render)
    write_text(tmp_path / "anim.py", ANIM)
    monkeypatch.chdir(tmp_path)
    rc = cli.main(["render", "anim.py:scene_at", "--frames", "1-2", "-o", "a.#.exr"])
    assert (rc, capsys.readouterr().err) == (
        cli.EXIT_ENGINE, "raytrace: error: Embree: out of memory building the BVH (written "
                         "before it: frame 1, complete; a rerun without --overwrite skips it)\n")


def test_a_missing_scene_file_of_a_sequence_is_found_before_any_frame_is_written(tmp_path,
                                                                                capsys):
    for frame in (1, 3):
        write_text(tmp_path / f"shot_{frame}.toml", SHOT.format(x=0.0, radius=0.5))
    rc = cli.main(["render", str(tmp_path / "shot_#.toml"), "--frames", "1-3", "-o",
                   str(tmp_path / "o.#.exr")])
    assert (rc, capsys.readouterr().err) == (
        2, f"raytrace: error: {tmp_path / 'shot_2.toml'}: scene file not found\n")
    assert sorted(os.listdir(tmp_path)) == ["shot_1.toml", "shot_3.toml"]


def test_frame_lists_are_written_back_as_parse_frames_reads_them():
    from raytrace.frames import format_frames

    assert format_frames([7, 1, 2, 3, 5]) == "1-3,5,7"
    assert parse_frames(format_frames([4, 9, 10, 11])) == [4, 9, 10, 11]


def test_a_full_disk_writing_the_sequence_stats_names_the_file_and_what_was_written(
        tmp_path, capsys, monkeypatch):
    import errno
    from pathlib import Path

    real = Path.write_text

    def full(self, data, *a, **kw):
        if self.name.startswith(".s.json."):
            raise OSError(errno.ENOSPC, "No space left on device")
        return real(self, data, *a, **kw)

    write_text(tmp_path / "anim.py", ANIM)
    write_text(tmp_path / "s.json", "old\n")
    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(Path, "write_text", full)
    rc = cli.main(["render", "anim.py:scene_at", "--frames", "1", "-o", "a.#.exr",
                   "--stats", "s.json"])
    assert (rc, capsys.readouterr().err) == (
        2, "raytrace: error: s.json: --stats: cannot write: No space left on device; no output "
           "written (s.json left as it was) (written before it: frame 1, complete; a rerun "
           "without --overwrite skips it)\n")
    assert (tmp_path / "s.json").read_text() == "old\n"
    assert sorted(os.listdir(tmp_path)) == ["a.1.exr", "anim.py", "s.json"]


def test_a_frames_function_s_error_of_several_lines_is_its_first_line(tmp_path, capsys,
                                                                     monkeypatch):
    write_text(tmp_path / "anim.py", "def scene_at(frame):\n"
                                     "    raise ValueError('line one\\nline two')\n")
    monkeypatch.chdir(tmp_path)
    rc = cli.main(["render", "anim.py:scene_at", "--frames", "1", "-o", "a.#.exr"])
    assert (rc, capsys.readouterr().err) == (
        2, "raytrace: error: anim.py:scene_at(1): raised ValueError: line one\n")
    assert os.listdir(tmp_path) == ["anim.py"]


def test_a_worker_timeout_without_a_client_names_the_keyword(tmp_path):
    write_text(tmp_path / "s_1.toml", SHOT.format(x=0.0, radius=0.5))
    with pytest.raises(raytrace.SceneError) as e:
        raytrace.render_frames(tmp_path / "s_#.toml", tmp_path / "o_#.exr", "1",
                               worker_timeout=5)
    assert str(e.value) == ("worker_timeout: a worker timeout needs a client: "
                            "render_frames(..., client=..., worker_timeout=...)")
    assert sorted(os.listdir(tmp_path)) == ["s_1.toml"]


def ceiling_line(width: int, height: int, ceiling: str) -> str:
    """The refusal of a ``width`` x ``height`` render under ``ceiling`` (rendering.py)."""
    from raytrace.rendering import peak_bytes, size_text

    return (f"{width}x{height} needs about {size_text(peak_bytes(width, height))} of memory at "
            f"its peak (render), over the memory ceiling of {ceiling}; give a larger size to "
            "raise it")


def test_a_memory_ceiling_of_frames_names_the_flag_or_the_keyword_not_a_scene_file(
        tmp_path, capsys):
    for f in (1, 2):
        write_text(tmp_path / f"s_{f}.toml", SHOT.format(x=0.1 * f, radius=0.5))
    rc = cli.main(["render", str(tmp_path / "s_#.toml"), "--frames", "1..2", "-o",
                   str(tmp_path / "o_#.exr"), "--max-memory", "1M"])
    assert (rc, capsys.readouterr().err) == (
        2, f"raytrace: error: --max-memory: {ceiling_line(12, 8, '1.0 MiB')}\n")
    with pytest.raises(raytrace.errors.MemoryLimitError) as e:
        raytrace.render_frames(tmp_path / "s_#.toml", tmp_path / "o_#.exr", "1-2",
                               max_memory="1M")
    assert str(e.value) == f"max_memory: {ceiling_line(12, 8, '1.0 MiB')}"
    with pytest.raises(raytrace.SceneError) as e:
        raytrace.render_frames(tmp_path / "s_#.toml", tmp_path / "o_#.exr", "1", max_memory="x")
    assert str(e.value) == ("max_memory: must be a size such as 4G, 512M or a number of bytes, "
                            "got 'x'")
    assert sorted(os.listdir(tmp_path)) == ["s_1.toml", "s_2.toml"]
