"""Shared pytest configuration.

``--generate-ref`` makes the reference-image tests (tests/test_scenes.py) write
tests/references/<scene>.exr from the current renderer instead of comparing against it. Use it
on purpose, after a change that is meant to alter pictures, and look at the new images:

    .venv/bin/pytest tests/test_scenes.py --generate-ref
"""

from __future__ import annotations

import pytest


def pytest_addoption(parser: pytest.Parser) -> None:
    parser.addoption(
        "--generate-ref", action="store_true", default=False,
        help="(re)write the reference EXRs in tests/references/ instead of comparing to them")


@pytest.fixture
def generate_ref(request: pytest.FixtureRequest) -> bool:
    """True when the run was asked to (re)generate reference images."""
    return bool(request.config.getoption("--generate-ref"))
