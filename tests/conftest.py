"""Shared pytest configuration.

``--generate-ref`` makes the reference-image tests (tests/test_scenes.py) write
tests/references/<scene>.exr from the current renderer instead of comparing against it. Use it
on purpose, after a change that is meant to alter pictures, and look at the new images:

    python3 -m pytest tests/test_scenes.py --generate-ref
"""

from __future__ import annotations

import os

import pytest
from hypothesis import settings

# tests/test_pytest_plugin.py runs the raytrace plugin on small projects of its own.
pytest_plugins = ["pytester"]

# Property tests explore new random cases on a developer's machine (and keep the failures they
# find in .hypothesis/), but CI must judge a submission the same way every time: there the
# examples come from a fixed seed.
settings.register_profile("ci", derandomize=True, print_blob=True)
if os.environ.get("CI"):
    settings.load_profile("ci")


def pytest_addoption(parser: pytest.Parser) -> None:
    parser.addoption(
        "--generate-ref", action="store_true", default=False,
        help="(re)write the reference EXRs in tests/references/ instead of comparing to them")


@pytest.fixture
def generate_ref(request: pytest.FixtureRequest) -> bool:
    """True when the run was asked to (re)generate reference images."""
    return bool(request.config.getoption("--generate-ref"))


def pytest_configure(config: pytest.Config) -> None:
    # RAYTRACE_IMAGE_HASHES=FOLDER records every image's hash (tests/image_hashes.py).
    from image_hashes import plugin_from_env

    plugin_from_env(config)
