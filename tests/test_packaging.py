"""The wheel carries the material library: ``raytrace.materials`` works when installed, not
only from a checkout (issue 2). Slow: builds a wheel with pip (``pytest -m slow``).
"""

from __future__ import annotations

import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

from raytrace.material import MaterialLibrary

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.slow
def test_wheel_ships_every_library_material(tmp_path: Path) -> None:
    subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps", "-q", "-w",
                    str(tmp_path), str(ROOT)], check=True)
    (wheel,) = tmp_path.glob("raytrace-*.whl")
    with zipfile.ZipFile(wheel) as z:
        shipped = {Path(n).name for n in z.namelist() if n.startswith("raytrace/_materials/")}
        z.extractall(tmp_path / "site")
    assert shipped == {p.name for p in (ROOT / "materials").glob("*.toml")}
    # The installed package finds its own copy (raytrace/_materials), not the checkout's.
    code = ("import raytrace, sys; m = raytrace.materials; "
            "print(m.folder); print(m['brass'].shininess)")
    out = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, check=True,
                         capture_output=True, text=True,
                         env={"PYTHONPATH": str(tmp_path / "site"), "PATH": "/usr/bin:/bin"})
    folder, shininess = out.stdout.split()
    assert Path(folder) == tmp_path / "site" / "raytrace" / "_materials"
    assert float(shininess) == 27.8974
    assert len(MaterialLibrary(Path(folder))) == len(shipped)
