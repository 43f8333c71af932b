"""What the command line needs to know and say about compiling: the notice it prints while
kernels compile (:class:`CompileNotice`, from numba's compile events), and numba's registries
loaded up front without the packages no kernel uses (:func:`load_registries`)."""

from __future__ import annotations

import sys
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import TextIO

from numba.core import event
from numba.core.registry import cpu_target

#: What the command line says while kernels compile (:class:`CompileNotice`), and when they are.
COMPILING = "raytrace: compiling kernels (kept for later runs)"
COMPILED = "raytrace: compiled kernels in {:.1f} s"


class CompileNotice(event.Listener):
    """Says on ``stream`` (stderr) what numba's compiler does while a render waits on it,
    from numba's ``numba:compile`` events (:mod:`numba.core.event`: one per kernel or helper
    compiled, the ones it calls nested inside; fired only on a cache miss, so a warm cache
    says nothing).

    A *spell* of compiling starts with a compile and ends at the first progress report
    (:meth:`listening`'s callback) from a thread that compiled in it once no compile is in
    flight, that is when the pass that waited for those kernels is done (any thread's
    report where only the listening thread compiled: it builds the scene, and the passes
    run on other threads, ``raytrace.integrator.pass_threads``), or when the block ends.
    On a terminal one line counts the spell's seconds, redrawn every :attr:`tick` s below
    the progress bar where one is drawn (whose reports wait meanwhile, so it goes on on
    the next line), and ends as :data:`COMPILED`;
    elsewhere :data:`COMPILING` is one line when a spell starts and :data:`COMPILED` one when
    it ends. The seconds run from the spell's first compile's start to its last one's end.
    """

    #: Seconds between redraws on a terminal.
    tick = 0.25

    def __init__(self, stream: TextIO):
        self._stream = stream
        self._live = stream.isatty()
        self._lock = threading.RLock()  # a render's threads compile and report side by side
        self._running = 0               # compiles in flight, nested ones included
        self._threads: set[int] = set()  # the threads that compiled in this spell
        self._listener: int | None = None  # the thread of listening()'s block
        self._began: float | None = None  # the spell's first compile's start; None: no spell
        self._ended = 0.0               # its latest compile's end
        self._width = 0                 # of the notice's line as drawn last
        self._bar_drawn = False         # the line holds the progress bar, unfinished
        self._stop = threading.Event()  # the spell's ticker's

    def on_start(self, event: event.Event) -> None:
        with self._lock:
            self._running += 1
            self._threads.add(threading.get_ident())
            if self._began is None:
                self._began = self._ended = time.perf_counter()
                if self._live:
                    if self._bar_drawn:  # the bar keeps its line, where it stopped
                        self._write("\n")
                    self._stop = threading.Event()
                    threading.Thread(target=self._tick_until, args=(self._stop,), daemon=True,
                                     name="raytrace-compile-notice").start()
                    self._draw(f"{COMPILING}: 0.0 s")
                else:
                    self._write(COMPILING + "\n")

    def on_end(self, event: event.Event) -> None:
        with self._lock:
            self._running -= 1
            self._ended = time.perf_counter()

    def _tick_until(self, stop: threading.Event) -> None:
        while not stop.wait(self.tick):
            with self._lock:
                if stop.is_set():
                    return
                self._draw(f"{COMPILING}: {time.perf_counter() - self._began:.1f} s")

    def _draw(self, line: str, end: str = "") -> None:
        """``line`` over the notice's line as drawn last."""
        self._write(f"\r{line:<{self._width}}{end}")
        self._width = 0 if end else len(line)

    def _write(self, text: str) -> None:
        self._stream.write(text)
        self._stream.flush()

    def _finish(self) -> None:
        """End the spell: :data:`COMPILED` with its seconds."""
        self._stop.set()
        done = COMPILED.format(self._ended - self._began)
        if self._live:
            self._draw(done, "\n")
        else:
            self._write(done + "\n")
        self._began, self._threads = None, set()

    def _report(self, progress: Callable[[int, int], None], done: int, total: int) -> None:
        """``progress(done, total)`` unless a spell is on (which this report may end)."""
        with self._lock:
            if self._began is not None:
                waited = self._threads - {self._listener}  # the pass threads that compiled
                if self._running or (waited and threading.get_ident() not in waited):
                    return
                self._finish()
            progress(done, total)
            self._bar_drawn = done < total

    @contextmanager
    def listening(self, progress: Callable[[int, int], None]
                  ) -> Iterator[Callable[[int, int], None]]:
        """Say the compiles inside the block; yields the callback to report progress to in
        place of ``progress`` (a render's ``progress(done, total)``). A block that raises
        (Ctrl-C) leaves a spell unfinished: no :data:`COMPILED` for a compile cut short."""
        self._listener = threading.get_ident()
        event.register("numba:compile", self)
        try:
            yield lambda done, total: self._report(progress, done, total)
        except BaseException:
            with self._lock:
                self._stop.set()
                self._began = None
            raise
        else:
            with self._lock:
                if self._began is not None:
                    self._finish()
        finally:
            event.unregister("numba:compile", self)


#: Optional packages that numba imports while it loads its typing and lowering registries,
#: for features no kernel of this package uses: ``scipy.linalg``'s BLAS (``np.dot`` and
#: ``np.linalg`` in nopython code; ``numba.np.linalg.ensure_blas``) and cffi (calling C
#: functions through cffi; ``numba.core.typing.cffi_utils``, whose ``cffi.FFI()`` builds
#: pycparser's tables).
#: Together 0.2–0.3 s of CPU of every command-line render (docs/performance.md, "The
#: start-up floor").
UNUSED_BY_KERNELS = ("scipy.linalg", "cffi")


def load_registries(lean: bool = False) -> None:
    """Load numba's typing and lowering registries now, on the calling thread (numba does so
    on the first kernel call, loading a cached kernel included: ``Cache.load_overload``
    refreshes the target context).

    ``lean``: while they load, the packages of :data:`UNUSED_BY_KERNELS` that are not yet
    imported look absent, so numba records "no BLAS, no cffi" instead of importing them; they
    import normally afterwards, for anything else. Only for a process whose numba runs this
    package's kernels alone (the ``raytrace`` command, :mod:`raytrace.cli`): in it, a numba
    function of someone else's calling ``np.dot`` would fail to compile ("scipy 0.16+ is
    required for linear algebra"). The Python API never does this.
    """
    hidden = [m for m in UNUSED_BY_KERNELS if m not in sys.modules] if lean else []
    for name in hidden:
        sys.modules[name] = None  # import raises ImportError (importlib's documented rule)
    try:
        cpu_target.target_context.refresh()  # refreshes the typing context too
    finally:
        for name in hidden:
            if sys.modules.get(name, 0) is None:
                del sys.modules[name]
