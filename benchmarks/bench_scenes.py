"""The scene files the benchmarks measure, by name: ``scenes/<name>.toml``, with any
``filter = "box"`` of its checkers left out (a copy in the temporary folder).

The Whitted scene's floor takes box-filtered checkers (scenes/whitted.toml, the README's
picture), but the benchmarks measure it with plain ones: every Whitted number in docs/ and
the issues' targets was measured so, the sampling studies measure how each method meets the
aliasing plain checkers make, and a checkout from before the key (``warm_ab.py``,
``startup.py``) reads the copy too. The copy keeps the scene's own settings (the Whitted
scene's ``spp = 1``) and lives in another folder, so a scene with relative file paths would
need them rewritten (none with a filter has any). ``first_picture.py`` measures what the
filter costs (docs/shading.md, "Box-filtered checkers").

    from bench_scenes import scene_path, WHITTED
"""

from __future__ import annotations

import os
import re
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
#: Where the plain copies are written (the same content on every run).
FOLDER = Path(tempfile.gettempdir()) / "raytrace-bench-scenes"
_FILTER = re.compile(r',\s*filter\s*=\s*"[a-z]+"')


def scene_path(name: str) -> Path:
    """``scenes/<name>.toml`` itself where no checker of it is filtered, else its copy
    without the ``filter`` keys (written atomically: benchmarks run side by side)."""
    source = ROOT / "scenes" / f"{name}.toml"
    text = source.read_text(encoding="utf-8")
    plain = _FILTER.sub("", text)
    if plain == text:
        return source
    copy = FOLDER / source.name
    if not copy.is_file() or copy.read_text(encoding="utf-8") != plain:
        FOLDER.mkdir(exist_ok=True)
        part = FOLDER / f".{source.name}.{os.getpid()}"
        part.write_text(plain, encoding="utf-8")
        part.replace(copy)
    return copy


#: The Whitted scene with plain checkers.
WHITTED = scene_path("whitted")
