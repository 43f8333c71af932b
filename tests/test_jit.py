"""The numba set-up (raytrace/kernels/jit.py, raytrace/kernels/compile.py): the cache guard that
drops machine code compiled from
other sources, so an edited helper in one module reaches the kernels of another (numba's own
cache only checks the kernel's file: numba issue #1833); and telling a cold kernel cache from
a warm one, cheaply, so the command line can say why the first render after installing sits
still (15–20 s on 2 cores)."""

from __future__ import annotations

import io
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

import raytrace
from raytrace import cli

PACKAGE = Path(raytrace.__file__).resolve().parent

HELPER = '''from .jit import kernel


@kernel
def scale1(x):
    return {factor} * x
'''
KERNEL = '''import numpy as np

from ._probe_helper import scale1
from .jit import kernel


@kernel
def scaled(x):
    out = np.empty_like(x)
    for i in range(x.shape[0]):
        out[i] = scale1(x[i])
    return out
'''
RUN = ("import numpy as np; from raytrace.kernels._probe_kernel import scaled; "
       "print(scaled(np.ones(1))[0])")


def test_an_edited_helper_in_another_module_takes_effect(tmp_path):
    # A copy of the package with a kernel in one module calling a helper in another: compile
    # (cached), edit the helper, run again. numba alone would load the stale machine code
    # (the kernel's own file did not change) and print 2.0 twice.
    copy = tmp_path / "raytrace"
    shutil.copytree(PACKAGE, copy, ignore=shutil.ignore_patterns("__pycache__"))
    (copy / "kernels" / "_probe_kernel.py").write_text(KERNEL)
    env = {**os.environ, "PYTHONPATH": str(tmp_path)}
    env.pop("NUMBA_CACHE_DIR", None)

    def run(factor: float) -> str:
        (copy / "kernels" / "_probe_helper.py").write_text(HELPER.format(factor=factor))
        return subprocess.run([sys.executable, "-c", RUN], env=env, capture_output=True,
                              text=True, check=True, cwd=tmp_path).stdout.strip()

    assert run(2.0) == "2.0"
    cached = list((copy / "kernels" / "__pycache__").glob("_probe_kernel.*.nbi"))
    assert cached, "the kernel was cached"
    assert run(3.0) == "3.0"
    assert run(3.0) == "3.0"  # and the new machine code is cached in turn


def test_the_guard_hashes_every_module_that_compiles_kernels():
    # A module importing `inline, kernel` (the analytic shapes' dispatch) compiles kernels as
    # much as one importing `kernel` alone; one importing only a plain function does not.
    from raytrace.kernels import jit

    names = {p.name for p in jit.kernel_modules()}
    assert {"accel.py", "shading.py", "core.py", "camera.py"} <= names
    assert "compile.py" not in names  # it imports the kernels, it compiles none


def test_the_guard_leaves_a_current_cache_alone(tmp_path):
    from raytrace.kernels import jit

    assert not jit.refresh_cache()  # the import already stamped today's sources
    stamp = PACKAGE / "kernels" / "__pycache__" / jit.STAMP
    assert stamp.read_text() == jit.source_hash(jit.hashed_modules())


# -- cold or warm: the compile notice ---------------------------------------------------------
ROOT = Path(__file__).resolve().parents[1]
CHECK = "from raytrace.kernels.compile import cache_is_warm; print(cache_is_warm())"


def test_an_empty_cache_is_cold(tmp_path):
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path)}  # a cache folder with nothing in it
    out = subprocess.run([sys.executable, "-c", CHECK], env=env, capture_output=True,
                         text=True, check=True).stdout
    assert out == "False\n"
    from raytrace.kernels.jit import STAMP  # asking compiled nothing (the guard's stamps aside)

    assert not [p for p in tmp_path.rglob("*") if p.is_file() and p.name != STAMP]


def test_a_first_compile_into_a_cache_folder_is_kept_by_the_next_process(tmp_path):
    # numba creates NUMBA_CACHE_DIR's folders when it decorates a module's kernels, after the
    # guard ran: unstamped, the next process took the first compile for a stale one.
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path)}
    guard = "import raytrace.kernels.jit"
    subprocess.run([sys.executable, "-c", guard], env=env, check=True)
    folders = {p.parent for p in tmp_path.rglob("raytrace-kernels.sha256")}
    assert folders  # the folders numba will write are stamped before it writes them
    compiled = [folder / "accel.kernel-1.py311.nbi" for folder in folders]
    for f in compiled:  # stands for what a first render's compile leaves there
        f.write_bytes(b"index")
    subprocess.run([sys.executable, "-c", guard], env=env, check=True)
    assert all(f.exists() for f in compiled)


def test_a_cache_a_render_has_filled_is_warm():
    code = ("import raytrace; raytrace.render(raytrace.Scene(objects=[raytrace.Sphere([0, 0, -3]"
            ", 1)]), width=2, height=2, threads=1); " + CHECK)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True, cwd=ROOT).stdout
    assert out == "True\n"


class _Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


@pytest.mark.parametrize("warm,stream,quiet,said", [
    (False, _Terminal, [], True),        # the only case that says it
    (True, _Terminal, [], False),
    (False, io.StringIO, [], False),     # not a terminal
    (False, _Terminal, ["-q"], False),
])
def test_the_command_line_says_it_is_compiling_on_a_terminal(tmp_path, monkeypatch, warm,
                                                              stream, quiet, said):
    monkeypatch.setattr("raytrace.kernels.compile.cache_is_warm", lambda: warm)
    err = stream()
    monkeypatch.setattr(sys, "stderr", err)
    scene = tmp_path / "s.toml"
    scene.write_text('[render]\nwidth = 4\nheight = 2\n[[objects]]\ntype = "sphere"\n'
                     'center = [0, 0, -3]\nradius = 1\n')
    assert cli.main(["render", str(scene), "-o", str(tmp_path / "o.exr"), *quiet]) == 0
    lines = err.getvalue().splitlines()
    assert ("raytrace: compiling kernels, first run only (about 10 s)" in lines) == said
    if said:
        assert lines[0] == "raytrace: compiling kernels, first run only (about 10 s)"


@pytest.mark.parametrize("quiet,said", [([], True), (["-q"], False)])
def test_the_command_line_says_so_when_a_warm_cache_still_compiles(tmp_path, monkeypatch,
                                                                   quiet, said):
    # A cache warm for one scene may lack another's kernel variants: numba's compile event,
    # not the guess, is what the notice answers to; it is said once for a whole batch.
    import importlib

    from numba.core import event

    module = importlib.import_module("raytrace.rendering")
    monkeypatch.setattr("raytrace.kernels.compile.cache_is_warm", lambda: True)
    err = _Terminal()
    monkeypatch.setattr(sys, "stderr", err)
    real = module.render

    def compiling(*args, **kwargs):  # what numba does on a cache miss, twice
        for _ in range(2):
            with event.trigger_event("numba:compile", data={}):
                pass
        return real(*args, **kwargs)

    monkeypatch.setattr(module, "render", compiling)
    scenes = []
    for name in ("a", "b"):
        scenes.append(tmp_path / f"{name}.toml")
        scenes[-1].write_text('[render]\nwidth = 4\nheight = 2\n[[objects]]\ntype = "sphere"\n'
                              'center = [0, 0, -3]\nradius = 1\n')
    (tmp_path / "out").mkdir()
    assert cli.main(["render", *map(str, scenes), "--out-dir", str(tmp_path / "out"),
                     *quiet]) == 0
    lines = err.getvalue().splitlines()
    notice = "raytrace: compiling kernels, first run only (about 10 s)"
    assert lines.count(notice) == (1 if said else 0), lines
    assert not event._registered["numba:compile"]  # the listener left with the render


def test_a_colour_slot_does_not_compile_a_kernel_per_value(tmp_path):
    # numba compiles a kernel called from another kernel once per *literal* argument value:
    # with the colour slots as Python ints, color1 compiled six times (KA ... KE) in a first
    # render. With numpy integers it compiles once for all six.
    probe = (
        "import numpy as np\n"
        "from raytrace.kernels import material as sk\n"
        "import numba\n"
        "from raytrace.kernels.kinds import KA, KD, KS, KE  # globals, as the kernels see them\n"
        "@numba.njit\n"
        "def every_slot(palette):\n"
        "    t = 0.0\n"
        "    for c in (sk.color1(palette, 0, KA, 0.0, 0.0, 0.0),\n"
        "              sk.color1(palette, 0, KD, 0.0, 0.0, 0.0),\n"
        "              sk.color1(palette, 0, KS, 0.0, 0.0, 0.0),\n"
        "              sk.color1(palette, 0, KE, 0.0, 0.0, 0.0)):\n"
        "        t += c[0] + c[1] + c[2]\n"
        "    return t\n"
        "colors = np.arange(18, dtype=np.float64).reshape(1, 18)\n"
        "from raytrace.kernels.records import Palette\n"
        "palette = Palette(colors, np.full((1, 6), -1, np.int64), np.zeros((1, 7)))\n"
        "print(every_slot(palette), len(sk.color1.signatures))\n")
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path)}  # compiled here, not loaded
    out = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True,
                         check=True, env=env, cwd=tmp_path).stdout.split()
    assert out == [str(float(sum(range(9)) + sum(range(15, 18)))), "1"]


def test_a_texel_channel_does_not_compile_a_kernel_per_value(tmp_path):
    # The same for bilinear1's channel: texture1 reads R, G and B with one compilation.
    probe = (
        "import numpy as np, numba\n"
        "from raytrace.kernels import core\n"
        "@numba.njit\n"
        "def rgb(texels, info):\n"
        "    return core.texture1(texels, info, 0, 0.5, 0.5)\n"
        "texels = np.array([1, 2, 3, 4], np.float32)  # one RGBA texel\n"
        "info = np.array([[0, 1, 1, 0, 0]], np.int64)\n"
        "print(*rgb(texels, info), len(core.bilinear1.signatures))\n")
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path)}
    out = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True,
                         check=True, env=env, cwd=tmp_path).stdout.split()
    assert out == ["1.0", "2.0", "3.0", "1"]
