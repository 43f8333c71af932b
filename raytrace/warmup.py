"""``raytrace warmup``: compile the kernels of a set of scenes up front, side by side.

A first render compiles the numba kernels its scene uses (seconds to tens of seconds on a
cold cache: docs/performance.md, "Cold compile"); users and CI who want that cost paid before
the first render they time run::

    raytrace warmup                 # the scenes shipped with raytrace (scenes/)
    raytrace warmup my.toml b.glb   # the variants these scenes use
    raytrace warmup --jobs 4

Each scene is rendered once, small (:data:`SIZE`) and to a temporary folder, by
``python -m raytrace render`` in a process of its own, :attr:`Warmup.jobs` at a time: the
processes compile into numba's on-disk cache (``raytrace.kernels.jit``: one lock per kernel's
cache files, so processes compiling side by side never lose an entry), where every later
render finds the kernels. A render is the one way to compile exactly what a scene's render
calls, with its settings (depth, lights, materials, AOVs); the scenes' own frame size is
what a small frame cannot stand for, so a kernel only a pixel of the full frame reaches (a
sphere smaller than a pixel at 48×36) still compiles at its first use. Environment settings
reach the processes: ``RAYTRACE_LOOP=compiled`` warms the compiled loop's variants.

Scenes are started in the order given, the ones whose name comes first in
:data:`FIRST` (one scene of each kernel variant the shipped scenes use) ahead of the rest, so
the variants compile side by side and the scenes that share them load them afterwards.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor, as_completed
from dataclasses import dataclass
from pathlib import Path

from .kernels.compile import COMPILED

#: The frame each scene is rendered at (width, height): small, so the render is the compile.
SIZE = (48, 36)
#: Suffixes of the files :func:`shipped_scenes` lists (scene files and model files).
SCENE_SUFFIXES = (".toml", ".json", ".glb", ".gltf", ".obj", ".ply", ".stl", ".off")
#: Shipped scenes started first: between them they use every kernel variant the shipped
#: scenes use (matte analytic, mirrors and glass, meshes, textured meshes, normal maps).
FIRST = ("spotlights", "whitted", "mesh_model", "gltf_scene", "normal_mapped")
#: numba's notice of a compile on stderr, piped (``raytrace.kernels.compile.COMPILED``).
_COMPILED = re.compile(re.escape(COMPILED).replace(r"\{:\.1f\}", r"([0-9.]+)"))


def shipped_folder() -> Path:
    """``raytrace/_scenes`` in a wheel, else the checkout's top-level ``scenes/``."""
    here = Path(__file__).resolve().parent
    packaged = here / "_scenes"
    return packaged if packaged.is_dir() else here.parent / "scenes"


def shipped_scenes() -> list[Path]:
    """The scene files shipped with raytrace (:func:`shipped_folder`), sorted; none where the
    install has no such folder."""
    folder = shipped_folder()
    if not folder.is_dir():
        return []
    return sorted(p for p in folder.iterdir() if p.suffix.lower() in SCENE_SUFFIXES)


@dataclass(frozen=True)
class Warmed:
    """One scene's warm-up: its process's wall seconds, the seconds it spent compiling (0:
    every kernel came from the cache), and for a scene that did not render its error line
    (naming the scene) and its render's exit status (negative: the signal that killed it)."""

    scene: Path
    seconds: float
    compile_seconds: float
    error: str | None = None
    returncode: int = 0


def warm(scene: Path, out: Path, size: tuple[int, int] = SIZE) -> Warmed:
    """Render ``scene`` at ``size`` into the new folder ``out`` in a process of its own (an
    EXR and a PNG preview, so the preview's kernels compile too) and say what it cost."""
    out.mkdir()
    command = [sys.executable, "-m", "raytrace", "render", str(scene),
               "--width", str(size[0]), "--height", str(size[1]),
               "-o", str(out / "image.exr"), "--png", str(out / "image.png")]
    t0 = time.perf_counter()
    done = subprocess.run(command, capture_output=True, text=True, stdin=subprocess.DEVNULL)
    seconds = time.perf_counter() - t0
    compiled = sum(float(m.group(1)) for m in _COMPILED.finditer(done.stderr))
    if done.returncode:
        lines = [line for line in done.stderr.splitlines() if line.startswith("raytrace: error")]
        if lines:  # its own error line, which names the file
            return Warmed(scene, seconds, compiled, lines[-1].removeprefix("raytrace: error: "),
                          done.returncode)
        last = (done.stderr.strip().splitlines() or ["no output"])[-1]
        how = (f"killed by signal {-done.returncode}" if done.returncode < 0
               else f"exit status {done.returncode}")
        return Warmed(scene, seconds, compiled, f"{scene}: the render crashed ({how}): {last}",
                      done.returncode)
    return Warmed(scene, seconds, compiled)


def warmup(scenes: Sequence[Path], jobs: int | None = None,
           progress: Callable[[int, int], None] | None = None) -> list[Warmed]:
    """Render every scene of ``scenes`` small (:func:`warm`), ``jobs`` processes at a time
    (default: the CPUs this process may use); ``progress(done,
    total)`` after each. Returns one :class:`Warmed` a scene, in the order given; the scenes
    named in :data:`FIRST` start first, the rest in the order given."""
    jobs = max(1, min(jobs or cpus(), len(scenes) or 1))
    order = sorted(range(len(scenes)), key=lambda i: (scenes[i].stem not in FIRST, i))
    results: list[Warmed | None] = [None] * len(scenes)
    with tempfile.TemporaryDirectory(prefix="raytrace-warmup-") as tmp, \
            ThreadPoolExecutor(jobs) as pool:  # each thread waits on its render's process
        futures = {pool.submit(warm, scenes[i], Path(tmp) / str(i)): i for i in order}
        for done, future in enumerate(as_completed(futures), 1):
            results[futures[future]] = future.result()
            if progress is not None:
                progress(done, len(scenes))
    return results


def cpus() -> int:
    """The CPUs this process may run on."""
    if hasattr(os, "sched_getaffinity"):
        return len(os.sched_getaffinity(0))
    return os.cpu_count() or 1
