"""``raytrace warmup`` (raytrace/warmup.py): which scenes it renders, in what order, what it
says of a scene that fails, and that a render after it compiles nothing."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from raytrace import cli, warmup
from raytrace.kernels.compile import COMPILING

ROOT = Path(__file__).resolve().parents[1]


def _raytrace(*args: str, env: dict | None = None, cwd: Path | None = None):
    return subprocess.run([sys.executable, "-m", "raytrace", *args], capture_output=True,
                          text=True, env=env, cwd=cwd, timeout=600)


def test_the_shipped_scenes_are_every_scene_file_of_scenes():
    listed = {p.name for p in warmup.shipped_scenes()}
    files = {p.name for p in (ROOT / "scenes").iterdir() if p.is_file()}
    assert listed == files  # a new kind of scene file is not skipped without a word
    # the scenes started first exist: a renamed one would silently lose its head start
    assert set(warmup.FIRST) <= {p.stem for p in warmup.shipped_scenes()}


def test_the_first_variants_start_first_and_results_come_in_the_order_given(monkeypatch):
    started = []

    def warm(scene, out):
        started.append(scene.stem)
        return warmup.Warmed(scene, 0.0, 0.0)

    monkeypatch.setattr(warmup, "warm", warm)
    scenes = [Path(f"{name}.toml") for name in ("a", "whitted", "b", "spotlights")]
    reports = []
    warmed = warmup.warmup(scenes, jobs=1, progress=lambda done, total: reports.append(
        (done, total)))
    assert started == ["whitted", "spotlights", "a", "b"]
    assert [w.scene for w in warmed] == scenes
    assert reports == [(1, 4), (2, 4), (3, 4), (4, 4)]


def test_a_scene_that_fails_is_one_error_line_and_exit_2(tmp_path):
    done = _raytrace("warmup", str(tmp_path / "missing.toml"), "-q")
    assert done.returncode == 2
    assert done.stdout == ""
    assert done.stderr.splitlines() == [
        f"raytrace: error: {tmp_path / 'missing.toml'}: scene file not found"]


def test_jobs_below_one_is_refused():
    done = _raytrace("warmup", "--jobs", "0")
    assert done.returncode == 2
    assert done.stderr.splitlines() == ["raytrace: error: --jobs: must be at least 1, got 0"]


@pytest.mark.slow
def test_a_render_after_warmup_compiles_nothing(tmp_path):
    # From an empty kernel cache: warmup compiles (its table says how long), and the render
    # that follows in a fresh process loads every kernel (no compile notice on its stderr).
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "cache")}
    scene = ROOT / "scenes" / "spotlights.toml"
    done = _raytrace("warmup", str(scene), env=env)
    assert done.returncode == 0, done.stderr
    row = next(line for line in done.stdout.splitlines() if line.startswith(str(scene)))
    assert float(row.split()[2]) > 0  # it compiled
    render = _raytrace("render", str(scene), "-o", str(tmp_path / "s.exr"), "--width", "64",
                       "--height", "48", env=env)
    assert render.returncode == 0, render.stderr
    assert COMPILING not in render.stderr


@pytest.mark.parametrize("crash,how", [("echo 'ValueError: boom' >&2; exit 1", "exit status 1"),
                                       ("kill -SEGV $$", "killed by signal 11")])
def test_a_render_that_crashes_is_one_line_naming_its_scene_and_exit_1(
        tmp_path, monkeypatch, capsys, crash, how):
    # A render process that dies without its own error line (a traceback, a signal): the
    # line names the scene and how it ended, and warmup exits 1 (an internal error), not the
    # raw status (a signal's would be negative).
    fake = tmp_path / "python"
    fake.write_text(f"#!/bin/sh\n{crash}\n")
    fake.chmod(0o755)
    monkeypatch.setattr(sys, "executable", str(fake))
    scene = tmp_path / "s.toml"
    assert cli.main(["warmup", str(scene), "-q"]) == 1
    line = capsys.readouterr().err.strip()
    assert line.startswith(f"raytrace: error: {scene}: the render crashed ({how})")
    assert "\n" not in line
