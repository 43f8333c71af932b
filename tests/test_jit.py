"""The numba set-up (raytrace/kernels/jit.py, raytrace/kernels/compile.py): the cache guard that
drops machine code compiled from
other sources, so an edited helper in one module reaches the kernels of another (numba's own
cache only checks the kernel's file: numba issue #1833); and the command line's notice while
kernels compile, driven by numba's compile events (here fake ones), which says what the
first render after installing waits for and for how long."""

from __future__ import annotations

import io
import os
import re
import shutil
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

import raytrace
from raytrace import cli
from raytrace.kernels.compile import COMPILING, CompileNotice

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


RACE_KERNELS = "from raytrace.kernels.jit import kernel\n\n" + "".join(
    f"@kernel\ndef f{i}(x):\n    return x * 2 + {i}\n\n" for i in range(12)) + \
    "FUNCS = [" + ", ".join(f"f{i}" for i in range(12)) + "]\n"
RACE = """
import sys, time
from numba.core import caching, event
save_index = caching.IndexDataCacheFile._save_index

def slow_save_index(self, overloads):  # widens the window a race needs: 50 ms, not ~0.1 ms
    time.sleep(0.05)
    save_index(self, overloads)

caching.IndexDataCacheFile._save_index = slow_save_index
compiles = []

class Count(event.Listener):
    def on_start(self, e):
        compiles.append(1)

    def on_end(self, e):
        pass

event.register("numba:compile", Count())
import race_kernels
start, args = float(sys.argv[1]), [eval(a) for a in sys.argv[2:]]
while time.time() < start:
    time.sleep(0.001)
wrong = [(f.__name__, a) for a in args for i, f in enumerate(race_kernels.FUNCS)
         if f(a) != a * 2 + i]
print(len(compiles), wrong)
"""


def test_processes_compiling_side_by_side_leave_every_entry_in_the_cache(tmp_path):
    # Two processes compile the same 12 kernels for different argument types into one cache
    # folder at once (numba's index write slowed to 50 ms in both, so their saves overlap):
    # a third process then finds all 24 machine codes there, each the right one. numba's own
    # cache lost about a quarter of the entries to the race (one process's index write
    # dropping the other's entry), so the third process compiled them again.
    (tmp_path / "race_kernels.py").write_text(RACE_KERNELS)
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(tmp_path), str(PACKAGE.parent)])}
    env.pop("NUMBA_CACHE_DIR", None)

    def run(start: float, *args: str) -> subprocess.Popen:
        return subprocess.Popen([sys.executable, "-c", RACE, str(start), *args], env=env,
                                cwd=tmp_path, stdout=subprocess.PIPE, text=True)

    start = time.time() + 3.0  # both imported numba and the kernels by then
    both = [run(start, "3"), run(start, "1.5")]
    outputs = [p.communicate(timeout=120)[0].split(maxsplit=1) for p in both]
    assert [o[1].strip() for o in outputs] == ["[]", "[]"]
    assert [o[0] for o in outputs] == ["12", "12"]  # each compiled its own signatures
    third = run(0.0, "3", "1.5").communicate(timeout=120)[0].split(maxsplit=1)
    assert third == ["0", "[]\n"]  # both processes' 24 entries loaded, each right


# -- the compile notice: numba's compile events, said while they run ------------------------
COMPILED = re.compile(r"raytrace: compiled kernels in \d+\.\d s")


class _Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def _compile(seconds: float = 0.0, until=lambda: True) -> None:
    """What numba does on a cache miss: a compile, with a helper compiled inside it, that
    lasts ``seconds`` and until ``until()``."""
    from numba.core import event

    with event.trigger_event("numba:compile", data={}):
        with event.trigger_event("numba:compile", data={}):
            pass
        time.sleep(seconds)
        deadline = time.monotonic() + 30
        while not until() and time.monotonic() < deadline:
            time.sleep(0.01)


def _scene(folder: Path, name: str = "s") -> Path:
    path = folder / f"{name}.toml"
    path.write_text('[render]\nwidth = 4\nheight = 2\n[[objects]]\ntype = "sphere"\n'
                    'center = [0, 0, -3]\nradius = 1\n')
    return path


@pytest.fixture
def compiling(monkeypatch):
    """raytrace.render compiles (fake events, see :func:`_compile`) before it renders; set
    ``compiling.until`` to make the compile last until a condition holds."""
    import importlib

    module = importlib.import_module("raytrace.rendering")
    real = module.render

    def render(*args, **kwargs):
        _compile(0.2, state.until)
        return real(*args, **kwargs)

    state = type("State", (), {"until": staticmethod(lambda: True)})()
    monkeypatch.setattr(module, "render", render)
    return state


@pytest.mark.parametrize("quiet", [[], ["-q"]])
def test_the_command_line_says_when_kernels_compile_and_for_how_long_when_piped(
        tmp_path, monkeypatch, compiling, quiet):
    err = io.StringIO()
    monkeypatch.setattr(sys, "stderr", err)
    assert cli.main(["render", str(_scene(tmp_path)), "-o", str(tmp_path / "o.exr"),
                     "--threads", "1", *quiet]) == 0
    lines = err.getvalue().splitlines()
    if quiet:
        assert lines == []
    else:  # a line when it starts and one when it ends, and nothing else (no bar: not a tty)
        assert len(lines) == 2 and lines[0] == COMPILING and COMPILED.fullmatch(lines[1]), lines
        assert float(lines[1].split()[-2]) >= 0.2  # the compile's seconds


def test_on_a_terminal_the_notice_counts_the_seconds_then_the_bar_follows(tmp_path,
                                                                          monkeypatch,
                                                                          compiling):
    err = _Terminal()
    monkeypatch.setattr(sys, "stderr", err)
    monkeypatch.setattr(CompileNotice, "tick", 0.01)
    drawn = re.compile(re.escape(COMPILING) + r": (\d+\.\d) s")
    compiling.until = lambda: len(set(drawn.findall(err.getvalue()))) >= 3  # still counting
    assert cli.main(["render", str(_scene(tmp_path)), "-o", str(tmp_path / "o.exr"),
                     "--threads", "1"]) == 0
    out = err.getvalue()
    seconds = [float(s) for s in drawn.findall(out)]
    assert len(set(seconds)) >= 3 and seconds == sorted(seconds)  # redrawn as time passes
    assert all(draw.startswith(COMPILING) for draw in out.split("\n")[0].split("\r")[1:-1])
    notice, bar, summary = out.split("\n")[:3]
    assert COMPILED.fullmatch(notice.split("\r")[-1].rstrip())  # the line ends said
    assert "100%|" in bar and "camera rays/s]" in bar and summary.startswith("wrote ")


def test_a_compile_mid_render_holds_the_bar_until_the_pass_that_waited_is_done():
    # Two render threads: one compiles a kernel variant the earlier passes did not need; the
    # other's passes go on meanwhile, but the line is the notice's until the compile is over
    # and the compiling thread's pass is reported.
    err, shown = io.StringIO(), []
    notice = CompileNotice(err)
    started, finish = threading.Event(), threading.Event()

    def compiling_pass(report) -> None:
        _compile(until=lambda: started.set() or finish.is_set())
        report(3, 4)

    with notice.listening(lambda done, total: shown.append(done)) as report:
        report(1, 4)                                  # no compile yet: the bar
        other = threading.Thread(target=compiling_pass, args=(report,))
        other.start()
        started.wait(30)
        report(2, 4)                                  # compiling: held
        finish.set()
        other.join(30)
        assert shown == [1, 3] and not other.is_alive()
        report(4, 4)
    assert shown == [1, 3, 4]
    lines = err.getvalue().splitlines()
    assert len(lines) == 2 and lines[0] == COMPILING and COMPILED.fullmatch(lines[1])


def test_on_a_terminal_a_compile_mid_render_leaves_the_bar_where_it_stopped():
    err = _Terminal()
    with CompileNotice(err).listening(lambda done, total: err.write(f"\rbar {done}/{total}")
                                      ) as report:
        report(1, 4)
        _compile()
        report(2, 4)
    bar, notice, after = err.getvalue().split("\n")
    assert bar == "\rbar 1/4"               # left as it was: what the render waited at
    assert notice.startswith(f"\r{COMPILING}: ") and COMPILED.fullmatch(
        notice.split("\r")[-1].rstrip())
    assert after == "\rbar 2/4"             # and the bar goes on below


@pytest.mark.parametrize("stream", [io.StringIO, _Terminal])
def test_a_compile_cut_short_is_not_said_to_be_over(monkeypatch, stream):
    # Ctrl-C while kernels compile: the line says what was going on, never "compiled".
    from numba.core import event

    err = stream()
    monkeypatch.setattr(CompileNotice, "tick", 0.01)
    with pytest.raises(KeyboardInterrupt), CompileNotice(err).listening(print):
        with event.trigger_event("numba:compile", data={}):
            time.sleep(0.05)
            raise KeyboardInterrupt
    said = err.getvalue()
    time.sleep(0.05)
    assert err.getvalue() == said  # the terminal's counter stopped with the block
    assert said.lstrip("\r").startswith(COMPILING) and "compiled" not in said
    assert not event._registered["numba:compile"]


def test_each_scene_of_a_batch_says_its_own_compile(tmp_path, monkeypatch, compiling):
    # A cache warm for one scene may lack another's kernel variants: each compile is said.
    from numba.core import event

    err = io.StringIO()
    monkeypatch.setattr(sys, "stderr", err)
    (tmp_path / "out").mkdir()
    scenes = [str(_scene(tmp_path, name)) for name in ("a", "b")]
    assert cli.main(["render", *scenes, "--out-dir", str(tmp_path / "out")]) == 0
    lines = err.getvalue().splitlines()
    assert lines[::2] == [COMPILING] * 2 and all(COMPILED.fullmatch(x) for x in lines[1::2])
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
        "from raytrace.kernels.records import Palette\n"
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
        "palette = Palette(colors, np.full((1, 6), -1, np.int64), np.zeros((1, 8)), None)\n"
        "print(every_slot(palette), len(sk.color1.signatures))\n")
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path)}  # compiled here, not loaded
    out = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True,
                         check=True, env=env, cwd=tmp_path).stdout.split()
    assert out == [str(float(sum(range(9)) + sum(range(15, 18)))), "1"]


def test_a_texel_channel_does_not_compile_a_kernel_per_value(tmp_path):
    # The same for the texel channel: texture1 reads R, G and B through blend1 (bilinear1's
    # arithmetic, the texels' indices found once) with one compilation.
    probe = (
        "import numpy as np, numba\n"
        "from raytrace.kernels import core\n"
        "@numba.njit\n"
        "def rgb(texels, info):\n"
        "    return core.texture1(texels, info, 0, 0.5, 0.5)\n"
        "texels = np.array([1, 2, 3, 4], np.float32)  # one RGBA texel\n"
        "info = np.array([[0, 1, 1, 0, 0]], np.int64)\n"
        "print(*rgb(texels, info), len(core.blend1.signatures))\n")
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path)}
    out = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True,
                         check=True, env=env, cwd=tmp_path).stdout.split()
    assert out == ["1.0", "2.0", "3.0", "1"]
