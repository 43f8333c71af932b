"""The numba set-up (raytrace/jit.py): the cache guard that drops machine code compiled from
other sources, so an edited helper in one module reaches the kernels of another (numba's own
cache only checks the kernel's file: numba issue #1833)."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import raytrace

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
RUN = ("import numpy as np; from raytrace._probe_kernel import scaled; "
       "print(scaled(np.ones(1))[0])")


def test_an_edited_helper_in_another_module_takes_effect(tmp_path):
    # A copy of the package with a kernel in one module calling a helper in another: compile
    # (cached), edit the helper, run again. numba alone would load the stale machine code
    # (the kernel's own file did not change) and print 2.0 twice.
    copy = tmp_path / "raytrace"
    shutil.copytree(PACKAGE, copy, ignore=shutil.ignore_patterns("__pycache__"))
    (copy / "_probe_kernel.py").write_text(KERNEL)
    env = {**os.environ, "PYTHONPATH": str(tmp_path)}
    env.pop("NUMBA_CACHE_DIR", None)

    def run(factor: float) -> str:
        (copy / "_probe_helper.py").write_text(HELPER.format(factor=factor))
        return subprocess.run([sys.executable, "-c", RUN], env=env, capture_output=True,
                              text=True, check=True, cwd=tmp_path).stdout.strip()

    assert run(2.0) == "2.0"
    cached = list((copy / "__pycache__").glob("_probe_kernel.*.nbi"))
    assert cached, "the kernel was cached"
    assert run(3.0) == "3.0"
    assert run(3.0) == "3.0"  # and the new machine code is cached in turn


def test_the_guard_leaves_a_current_cache_alone(tmp_path):
    from raytrace import jit

    assert not jit.refresh_cache()  # the import already stamped today's sources
    stamp = PACKAGE / "__pycache__" / jit.STAMP
    assert stamp.read_text() == jit.source_hash(jit.kernel_modules())
