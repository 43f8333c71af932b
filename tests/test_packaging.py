"""The wheel carries the material library and the shipped scenes: ``raytrace.materials`` and
``raytrace warmup``'s default scenes work when installed, not only from a checkout. Slow:
builds a wheel with pip (``pytest -m slow``).
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
def test_wheel_ships_every_library_material_and_scene(tmp_path: Path) -> None:
    subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps", "-q", "-w",
                    str(tmp_path), str(ROOT)], check=True)
    (wheel,) = tmp_path.glob("raytrace-*.whl")
    with zipfile.ZipFile(wheel) as z:
        shipped = {Path(n).name for n in z.namelist() if n.startswith("raytrace/_materials/")}
        scenes = {n.removeprefix("raytrace/_scenes/") for n in z.namelist()
                  if n.startswith("raytrace/_scenes/")}
        z.extractall(tmp_path / "site")
    assert shipped == {p.name for p in (ROOT / "materials").glob("*.toml")}
    assert scenes == {str(p.relative_to(ROOT / "scenes")) for p in (ROOT / "scenes").rglob("*")
                      if p.is_file() and "__pycache__" not in p.parts}
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
    # ... and raytrace warmup's default scenes are the wheel's copy
    code = "from raytrace import warmup; print(*warmup.shipped_scenes(), sep='\\n')"
    out = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, check=True,
                         capture_output=True, text=True,
                         env={"PYTHONPATH": str(tmp_path / "site"), "PATH": "/usr/bin:/bin"})
    listed = [Path(line) for line in out.stdout.split("\n") if line]
    assert {p.parent for p in listed} == {tmp_path / "site" / "raytrace" / "_scenes"}
    assert {p.name for p in listed} == {p.name for p in (ROOT / "scenes").iterdir()
                                        if p.is_file()}
