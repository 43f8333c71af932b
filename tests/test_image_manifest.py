"""The image manifest (tests/image_hashes.py): every scene of scenes/ at six settings renders
the very bits recorded in tests/references/image_hashes.json. A change meant to alter pictures
records the manifest anew (``python3 tests/image_hashes.py record``) and says so; a refactor
leaves it alone. Hashes are of float32 bytes on the recording machine's numpy, numba and CPU,
so the test runs only where those match."""

from __future__ import annotations

import json

import image_hashes
import pytest


@pytest.mark.slow
def test_every_scene_renders_the_recorded_bits():
    manifest = json.loads(image_hashes.MANIFEST.read_text())
    if manifest["platform"] != image_hashes.platform_info():
        pytest.skip(f"recorded on {manifest['platform']}, here {image_hashes.platform_info()}")
    got = image_hashes.scene_hashes()
    moved = sorted(k for k, v in manifest["scenes"].items() if got.get(k) != v)
    assert moved == []
