"""The pytest plugin (raytrace_pytest, registered through the pytest11 entry point): a missing
golden fails clearly, --raytrace-update-goldens writes goldens and a second run passes, a
changed render fails with its artefacts, the update run lists what changed, and loading the
plugin imports nothing heavy. Run with pytest's own ``pytester``."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

import raytrace

SCENE = """\
[camera]
position = [0.0, 1.0, 4.0]
look_at = [0.0, 0.5, 0.0]

[ambient]
color = 0.1

[[lights]]
type = "point"
position = [3.0, 5.0, 4.0]
color = {light}

[[objects]]
type = "sphere"
center = [0.0, 0.5, 0.0]
radius = 0.5
material = {{ kd = [0.8, 0.3, 0.2], ks = 0.4, shininess = 40 }}

[[objects]]
type = "plane"
point = [0.0, 0.0, 0.0]
normal = [0.0, 1.0, 0.0]
material = "matte_white"
"""

TEST_FILE = """\
import raytrace

def test_ball(raytrace_golden):
    image = raytrace_golden("ball.toml", width=16, height=12, threads=1)
    assert image.rgb.shape == (12, 16, 3)

def test_two_sizes(raytrace_golden):
    raytrace_golden("ball.toml", name="small", width=8, height=6, threads=1)
    scene = raytrace.load_scene("ball.toml")
    raytrace_golden(scene, name="wide", width=12, height=6, threads=1)
"""


@pytest.fixture(scope="module", autouse=True)
def _renderer_loaded():
    """One render in this process before pytester's in-process runs: each of those runs drops
    the modules it imported, and numba's first kernel call imports modules that register
    types globally, which a second import would register twice (KeyError). OpenImageIO,
    which the artefacts' PNGs use, is loaded here too: a nanobind module imported a second
    time aborts the process."""
    import OpenImageIO  # noqa: F401
    raytrace.render(raytrace.load_scene(Path(__file__).resolve().parents[1] / "scenes" /
                                        "whitted.toml"), width=2, height=2, threads=1)


@pytest.fixture
def project(pytester: pytest.Pytester, monkeypatch):
    """A user's project: a scene and a test file using the fixture; artefacts go to the
    default folder under the project."""
    monkeypatch.delenv("RAYTRACE_ARTEFACTS", raising=False)
    pytester.makefile(".toml", ball=SCENE.format(light=1.0))
    pytester.makepyfile(test_render=TEST_FILE)
    return pytester


GOLDENS = ("goldens/test_render/test_ball.exr", "goldens/test_render/small.exr",
           "goldens/test_render/wide.exr")


def test_a_missing_golden_fails_and_says_how_to_create_it(project):
    result = project.runpytest("-p", "no:cacheprovider")
    result.assert_outcomes(failed=2)
    result.stdout.fnmatch_lines([
        "*golden image goldens/test_render/test_ball.exr does not exist*"
        "--raytrace-update-goldens*"])
    assert not (project.path / "goldens").exists()
    # The render is kept for a look before the golden is made.
    folder = project.path / "raytrace-artefacts" / "test_render.test_ball"
    assert sorted(p.name for p in folder.iterdir()) == ["actual.exr", "side_by_side.png"]


def test_update_writes_the_goldens_and_a_second_run_passes(project):
    result = project.runpytest("--raytrace-update-goldens", "-p", "no:cacheprovider")
    result.assert_outcomes(passed=2)
    result.stdout.fnmatch_lines(["*raytrace goldens*", *[f"new * {g}" for g in sorted(GOLDENS)],
                                 "3 written, 0 unchanged*"])
    for g in GOLDENS:
        assert (project.path / g).is_file()
    golden, header = raytrace.read_exr(project.path / GOLDENS[0])
    scene = raytrace.load_scene(project.path / "ball.toml")
    np.testing.assert_array_equal(golden, raytrace.render(scene, width=16, height=12).rgb)
    assert golden.max() > 0.1                       # a picture, not a black frame
    assert project.runpytest("-p", "no:cacheprovider").ret == 0

    # Updating again changes nothing and rewrites nothing.
    mtimes = [(project.path / g).stat().st_mtime_ns for g in GOLDENS]
    again = project.runpytest("--raytrace-update-goldens", "-p", "no:cacheprovider")
    again.stdout.fnmatch_lines(["*no golden changed (3 unchanged)*"])
    assert [(project.path / g).stat().st_mtime_ns for g in GOLDENS] == mtimes


def test_a_changed_render_fails_with_artefacts_and_update_reports_it(project):
    assert project.runpytest("--raytrace-update-goldens", "-p", "no:cacheprovider").ret == 0
    project.makefile(".toml", ball=SCENE.format(light=1.5))       # a brighter light
    result = project.runpytest("-p", "no:cacheprovider", "-k", "test_ball")
    result.assert_outcomes(failed=1)
    result.stdout.fnmatch_lines([
        "*render differs from the golden goldens/test_render/test_ball.exr*pixels*",
        "*metrics: rmse=*", "*worst pixels*", "*artefacts: *test_render.test_ball/*"])
    folder = project.path / "raytrace-artefacts" / "test_render.test_ball"
    assert sorted(p.name for p in folder.iterdir()) == ["actual.exr", "diff.png",
                                                        "expected.exr", "side_by_side.png"]
    # The failure does not touch the golden; an update on purpose does, and says so.
    updated = project.runpytest("--raytrace-update-goldens", "-p", "no:cacheprovider",
                                "-k", "test_ball")
    updated.stdout.fnmatch_lines(["changed  goldens/test_render/test_ball.exr (max |diff| *"
                                  " of 192 pixels differ)", "1 written, 0 unchanged*"])
    assert project.runpytest("-p", "no:cacheprovider", "-k", "test_ball").ret == 0


def test_a_comparison_that_passes_again_leaves_no_artefacts_of_its_earlier_failure(project):
    root = project.path / "raytrace-artefacts"
    assert project.runpytest("-p", "no:cacheprovider").ret == 1      # no goldens: artefacts
    assert sorted(p.name for p in root.iterdir()) == ["test_render.test_ball",
                                                     "test_render.test_two_sizes"]
    assert project.runpytest("--raytrace-update-goldens", "-p", "no:cacheprovider").ret == 0
    assert list(root.iterdir()) == []                 # the goldens are those renders now
    project.makefile(".toml", ball=SCENE.format(light=1.5))
    assert project.runpytest("-p", "no:cacheprovider").ret == 1
    folder = root / "test_render.test_two_sizes" / "small"  # the first to fail
    assert (folder / "diff.png").is_file()
    (root / "test_render.test_two_sizes" / "notes.txt").write_text("mine")  # not an artefact
    project.makefile(".toml", ball=SCENE.format(light=1.0))          # the change undone
    assert project.runpytest("-p", "no:cacheprovider").ret == 0
    assert sorted(p.relative_to(root).as_posix() for p in root.rglob("*")) == [
        "test_render.test_two_sizes", "test_render.test_two_sizes/notes.txt"]


def test_the_same_golden_twice_in_a_test_is_an_error(pytester: pytest.Pytester):
    pytester.makefile(".toml", ball=SCENE.format(light=1.0))
    pytester.makepyfile("""
        def test_twice(raytrace_golden):
            raytrace_golden("ball.toml", width=4, height=3)
            raytrace_golden("ball.toml", width=8, height=6)
    """)
    result = pytester.runpytest("--raytrace-update-goldens", "-p", "no:cacheprovider")
    result.assert_outcomes(failed=1)
    result.stdout.fnmatch_lines(["*is already used by*give each image its own name=*"])


def test_artefacts_option_sets_the_folder(project, tmp_path_factory):
    elsewhere = tmp_path_factory.mktemp("artefacts")
    result = project.runpytest("-p", "no:cacheprovider", "-k", "test_ball",
                               f"--raytrace-artefacts={elsewhere}")
    result.assert_outcomes(failed=1)
    assert (elsewhere / "test_render.test_ball" / "actual.exr").is_file()
    assert not (project.path / "raytrace-artefacts").exists()


def test_loading_the_plugin_imports_neither_numpy_nor_raytrace(pytester: pytest.Pytester):
    # Every pytest run in an environment with raytrace loads the plugin: it must stay cheap.
    pytester.makepyfile("""
        import sys

        def test_modules(pytestconfig):
            assert pytestconfig.pluginmanager.has_plugin("raytrace")
            assert "raytrace_pytest" in sys.modules
            heavy = {"numpy", "raytrace", "numba", "OpenEXR"} & set(sys.modules)
            assert not heavy, heavy
    """)
    result = pytester.runpytest_subprocess("-p", "no:cacheprovider")
    result.assert_outcomes(passed=1)


def test_the_example_in_docs_testing_md_works_as_documented(pytester: pytest.Pytester,
                                                            monkeypatch):
    monkeypatch.delenv("RAYTRACE_ARTEFACTS", raising=False)
    root = Path(__file__).resolve().parents[1]
    doc = (root / "docs" / "testing.md").read_text(encoding="utf-8")
    code = re.search(r"```python\n(# tests/test_pictures\.py\n.*?)```", doc, re.S).group(1)
    (pytester.path / "scenes").mkdir()
    (pytester.path / "scenes" / "whitted.toml").write_bytes(
        (root / "scenes" / "whitted.toml").read_bytes())
    (pytester.path / "tests").mkdir()
    (pytester.path / "tests" / "test_pictures.py").write_text(code, encoding="utf-8")
    first = pytester.runpytest("-p", "no:cacheprovider")
    first.assert_outcomes(failed=2, passed=1)
    first.stdout.fnmatch_lines(["golden image tests/goldens/test_pictures/test_whitted.exr "
                                "does not exist.*"])
    update = pytester.runpytest("-p", "no:cacheprovider", "--raytrace-update-goldens")
    update.assert_outcomes(passed=3)
    update.stdout.fnmatch_lines(["new      tests/goldens/test_pictures/test_whitted.exr",
                                 "new      tests/goldens/test_pictures/whitted_depth1.exr",
                                 "new      tests/goldens/test_pictures/whitted_depth5.exr",
                                 "3 written, 0 unchanged*"])
    pytester.runpytest("-p", "no:cacheprovider").assert_outcomes(passed=3)
