"""raytrace's pytest plugin: golden-image tests of renders (installing raytrace is enough).

Registered through the ``pytest11`` entry point. It adds

* the fixture ``raytrace_golden``: ``raytrace_golden(scene, **render_kwargs)`` renders a scene
  (a :class:`raytrace.Scene`, a scene file path relative to the test file, or an
  :class:`raytrace.Image` already rendered) and compares it with the golden EXR
  ``goldens/<test module>/<test name>.exr`` beside the test file, by
  :func:`raytrace.testing.assert_image_close`;
* ``--raytrace-update-goldens``: write the goldens from this run's renders instead of comparing
  (only those whose pixels changed are rewritten) and list them at the end of the run;
* ``--raytrace-artefacts DIR``: where failing comparisons write their artefacts (default
  ``$RAYTRACE_ARTEFACTS``, else ``./raytrace-artefacts``); a comparison that passes (or
  updates its golden) deletes those an earlier failure of it left.

This module imports only pytest and the standard library, so it costs nothing at pytest
start-up in projects that never use it; raytrace (numpy, the renderer) is imported by the
fixture. docs/testing.md shows the workflow.
"""

from __future__ import annotations

import os
import re
from pathlib import Path

import pytest

UPDATE_OPTION = "--raytrace-update-goldens"
ARTEFACTS_OPTION = "--raytrace-artefacts"
#: The default tolerances: those of raytrace's own reference images (tests/test_scenes.py),
#: which absorb the last-ulp and silhouette differences between CPUs.
DEFAULT_RTOL = 0.0
DEFAULT_ATOL = 1e-4
DEFAULT_MAX_BAD_FRACTION = 0.005

_PROPERTY = "raytrace_golden"
_used = pytest.StashKey[dict]()
_saved_env = pytest.StashKey[tuple]()


def pytest_addoption(parser: pytest.Parser) -> None:
    group = parser.getgroup("raytrace", "raytrace golden images")
    group.addoption(UPDATE_OPTION, action="store_true", default=False,
                    help="write the golden EXRs of raytrace_golden tests from this run's "
                         "renders instead of comparing, and list the ones that changed")
    group.addoption(ARTEFACTS_OPTION, metavar="DIR", default=None,
                    help="folder for the artefacts of failing image comparisons (default: "
                         "$RAYTRACE_ARTEFACTS, else ./raytrace-artefacts)")


def pytest_configure(config: pytest.Config) -> None:
    config.stash[_used] = {}
    folder = config.getoption(ARTEFACTS_OPTION, None)
    if folder:  # raytrace.testing reads it, in this process and in xdist workers
        config.stash[_saved_env] = (os.environ.get("RAYTRACE_ARTEFACTS"),)
        os.environ["RAYTRACE_ARTEFACTS"] = str(Path(folder).resolve())
    if config.getoption(UPDATE_OPTION, False):
        config.pluginmanager.register(_UpdateReport(config), "raytrace-golden-updates")


def pytest_unconfigure(config: pytest.Config) -> None:
    if _saved_env in config.stash:
        (before,) = config.stash[_saved_env]
        if before is None:
            os.environ.pop("RAYTRACE_ARTEFACTS", None)
        else:
            os.environ["RAYTRACE_ARTEFACTS"] = before


class Golden:
    """The ``raytrace_golden`` fixture's value: call it to render and compare."""

    def __init__(self, request: pytest.FixtureRequest):
        self.request = request
        self.folder = request.path.parent / "goldens" / request.path.stem
        self._mine: set[Path] = set()  # the goldens this test has compared so far

    def path(self, name: str | None = None) -> Path:
        """The golden EXR of this test (or of ``name``, for a test with several)."""
        stem = re.sub(r"[^\w.\-\[\]]+", "_", name or self.request.node.name)
        return self.folder / f"{stem}.exr"

    def __call__(self, scene, *, name: str | None = None, rtol: float = DEFAULT_RTOL,
                 atol: float = DEFAULT_ATOL,
                 max_bad_fraction: float = DEFAULT_MAX_BAD_FRACTION,
                 metric: str | None = None, threshold: float | None = None, **render_kwargs):
        """Render ``scene`` with ``render_kwargs`` (as :func:`raytrace.render`) and compare it
        with the golden by :func:`raytrace.testing.assert_image_close` with these tolerances
        (``name``: a second image in one test). Returns the rendered :class:`raytrace.Image`.
        """
        __tracebackhide__ = True
        import numpy as np

        import raytrace
        from raytrace import testing

        config = self.request.config
        golden = self.path(name)
        owner = config.stash[_used].setdefault(golden, self.request.node.nodeid)
        if owner != self.request.node.nodeid or golden in self._mine:
            pytest.fail(f"golden {_shown(config, golden)} is already used by {owner}: "
                        f"give each image its own name=", pytrace=False)
        self._mine.add(golden)
        if isinstance(scene, raytrace.Image):
            image = scene
        else:
            if not isinstance(scene, raytrace.Scene):
                path = Path(scene)
                scene = raytrace.load_scene(path if path.is_absolute()
                                            else self.request.path.parent / path)
            image = raytrace.render(scene, **render_kwargs)
        if config.getoption(UPDATE_OPTION):
            entry = {"path": _shown(config, golden), "status": "new"}
            if golden.is_file():
                old, _ = raytrace.read_exr(golden)
                if old.shape == image.rgb.shape and np.array_equal(old, image.rgb,
                                                                   equal_nan=True):
                    entry["status"] = "unchanged"
                else:
                    entry["status"] = "changed"
                    if old.shape == image.rgb.shape:
                        c = testing.compare_images(image, old, metrics=["max"])
                        entry.update(max=c.metrics["max"], pixels=c.bad, of=c.pixels)
            if entry["status"] != "unchanged":
                golden.parent.mkdir(parents=True, exist_ok=True)
                image.save(golden)
            self.request.node.user_properties.append((_PROPERTY, entry))
            testing.clear_artefacts(name)  # the golden is this render now
            return image
        if not golden.is_file():
            folder = testing.write_artefacts(testing.artefact_dir(name), image, None,
                                             image.metadata)
            pytest.fail(f"golden image {_shown(config, golden)} does not exist. Look at this "
                        f"render in {folder}/, then create the golden with "
                        f"pytest {UPDATE_OPTION} and commit it", pytrace=False)
        try:
            testing.assert_image_close(image, golden, rtol=rtol, atol=atol,
                                       max_bad_fraction=max_bad_fraction, metric=metric,
                                       threshold=threshold, name=name)
        except AssertionError as e:
            failure = str(e)
        else:
            testing.clear_artefacts(name)  # those of an earlier failure are stale
            return image
        pytest.fail(f"render differs from the golden {_shown(config, golden)}: {failure}\n"
                    f"If the change is intended, look at the artefacts, then run pytest "
                    f"{UPDATE_OPTION} and commit the new golden", pytrace=False)


@pytest.fixture
def raytrace_golden(request: pytest.FixtureRequest) -> Golden:
    """Render a scene and compare it with its golden EXR beside the test (see
    :class:`Golden`); ``pytest --raytrace-update-goldens`` writes the goldens."""
    return Golden(request)


class _UpdateReport:
    """Collects the goldens written in an update run (from xdist workers too: the entries
    travel in the reports' user_properties) and lists them in the terminal summary."""

    def __init__(self, config: pytest.Config):
        self.config = config
        self.entries: list[dict] = []

    def pytest_runtest_logreport(self, report: pytest.TestReport) -> None:
        if report.when == "call":
            self.entries += [v for k, v in report.user_properties if k == _PROPERTY]

    def pytest_terminal_summary(self, terminalreporter) -> None:
        tr = terminalreporter
        tr.write_sep("=", "raytrace goldens")
        written = [e for e in self.entries if e["status"] != "unchanged"]
        for e in sorted(written, key=lambda e: e["path"]):
            detail = (f" (max |diff| {e['max']:.3g}; {e['pixels']} of {e['of']} pixels differ)"
                      if "max" in e else "")
            tr.write_line(f"{e['status']:8s} {e['path']}{detail}")
        tr.write_line(f"{len(written)} written, "
                      f"{len(self.entries) - len(written)} unchanged: look at the new "
                      f"images before committing them" if written else
                      f"no golden changed ({len(self.entries)} unchanged)")


def _shown(config: pytest.Config, path: Path) -> str:
    """``path`` relative to the rootdir where it is inside it."""
    try:
        return str(path.relative_to(config.rootpath))
    except ValueError:
        return str(path)
