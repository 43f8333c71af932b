"""raytrace.malloc: passes reuse freed blocks instead of asking the kernel for fresh pages; the
command line tunes its own process, the library leaves its host's allocator alone."""

from __future__ import annotations

import os
import platform
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from raytrace import malloc

ROOT = Path(__file__).resolve().parents[1]
GLIBC = sys.platform.startswith("linux") and platform.libc_ver()[0] == "glibc"

#: A second 640×480 render of the Whitted scene at 1 spp on one thread: 16 passes of 19 200 samples
#: (``pass_samples`` pins them: one thread's own cut is 5 passes of 61 440, whose second render
#: still touched 850–5 900 new pages tuned, a few from the third on), whose arrays (460 KB for
#: three float64 a row) lie above glibc's default mmap threshold.
SECOND_RENDER_FAULTS = textwrap.dedent("""
    import resource, sys
    import raytrace
    from raytrace import malloc
    if sys.argv[1] == "tuned":
        assert malloc.tune()
    scene = raytrace.load_scene(sys.argv[2])
    raytrace.render(scene, width=640, height=480, spp=1, threads=1, pass_samples=19200)
    before = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
    raytrace.render(scene, width=640, height=480, spp=1, threads=1, pass_samples=19200)
    print(resource.getrusage(resource.RUSAGE_SELF).ru_minflt - before)
""")


def second_render_faults(mode: str) -> int:
    # glibc reads its thresholds from these at start: the untuned run must not inherit them.
    env = {k: v for k, v in os.environ.items()
           if k != "GLIBC_TUNABLES" and not k.startswith("MALLOC_")}
    out = subprocess.run([sys.executable, "-c", SECOND_RENDER_FAULTS, mode,
                          str(ROOT / "scenes" / "whitted.toml")],
                         capture_output=True, text=True, check=True, env=env)
    return int(out.stdout.split()[-1])


@pytest.mark.skipif(not GLIBC, reason="mallopt's thresholds are glibc's")
def test_tune_sets_both_thresholds_on_glibc():
    assert malloc.tune() is True
    assert malloc.tune() is True  # once per process, and again harmless


@pytest.mark.skipif(not GLIBC, reason="mallopt's thresholds are glibc's")
def test_a_second_render_reuses_the_blocks_of_the_first():
    # Measured: about 90-300 minor page faults tuned (first touches of numpy's and numba's
    # small pools), 3 000-3 300 untuned (every pass's arrays mmap-ed and unmapped afresh; about
    # 1 400 with the compiled loop, which allocates fewer): the library alone leaves the
    # allocator as it found it.
    tuned, untuned = second_render_faults("tuned"), second_render_faults("untuned")
    assert tuned < 1000 and untuned > 5 * tuned, (tuned, untuned)


def test_the_command_line_tunes_its_process(monkeypatch, tmp_path):
    from raytrace import cli

    calls = []
    monkeypatch.setattr(malloc, "tune", lambda: calls.append(1) or True)
    assert cli.main(["render", str(ROOT / "scenes" / "whitted.toml"), "-o",
                     str(tmp_path / "w.exr"), "--width", "8", "--height", "6", "-q"]) == 0
    assert calls == [1]
