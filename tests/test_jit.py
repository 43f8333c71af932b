"""The numba set-up (raytrace/jit.py): telling a cold kernel cache from a warm one, cheaply, so
the command line can say why the first render after installing sits still (15–20 s on 2 cores).
"""

from __future__ import annotations

import io
import os
import subprocess
import sys
from pathlib import Path

import pytest

from raytrace import cli

ROOT = Path(__file__).resolve().parents[1]
CHECK = "from raytrace.jit import cache_is_warm; print(cache_is_warm())"


def test_an_empty_cache_is_cold(tmp_path):
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path)}  # a cache folder with nothing in it
    out = subprocess.run([sys.executable, "-c", CHECK], env=env, capture_output=True,
                         text=True, check=True).stdout
    assert out == "False\n"
    assert not [p for p in tmp_path.rglob("*") if p.is_file()]  # asking compiled nothing


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
    monkeypatch.setattr("raytrace.jit.cache_is_warm", lambda: warm)
    err = stream()
    monkeypatch.setattr(sys, "stderr", err)
    scene = tmp_path / "s.toml"
    scene.write_text('[render]\nwidth = 4\nheight = 2\n[[objects]]\ntype = "sphere"\n'
                     'center = [0, 0, -3]\nradius = 1\n')
    assert cli.main(["render", str(scene), "-o", str(tmp_path / "o.exr"), *quiet]) == 0
    lines = err.getvalue().splitlines()
    assert ("raytrace: compiling kernels, first run only (about 15 s)" in lines) == said
    if said:
        assert lines[0] == "raytrace: compiling kernels, first run only (about 15 s)"
