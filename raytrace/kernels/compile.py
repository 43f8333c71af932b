"""What the command line needs to know and say about compiling: whether numba's cache is warm
for this package's kernels (:func:`cache_is_warm`), the notice it prints before a compile
(:class:`CompileNotice`), and numba's registries loaded up front without the packages no
kernel uses (:func:`load_registries`)."""

from __future__ import annotations

import sys
import threading
from collections.abc import Callable, Iterator
from contextlib import contextmanager

from numba.core import event
from numba.core.dispatcher import Dispatcher
from numba.core.registry import cpu_target

from . import accel, shading


def cache_is_warm() -> bool:
    """Whether numba's on-disk cache holds machine code for the kernels of this numba and these
    sources, i.e. whether the next render starts without compiling (the first one after
    installing or editing a kernel module compiles for 8–11 s on 2 cores).

    Cheap (a few small index files are read, nothing is compiled): for each kernel module, at
    least one kernel must have a current cache index, which is numba's own test at load time
    (the index records the source file's stamp and numba's version;
    ``numba.core.caching.IndexDataCacheFile._load_index`` returns nothing when either
    differs; :func:`refresh_cache` has deleted the files of other sources by then). Every
    render calls kernels of these two modules, so a module without one will compile. These
    are numba internals: if they change, the answer is True (say nothing rather than something
    wrong).
    """


    try:
        for module in (accel, shading):
            kernels = [v for v in vars(module).values()
                       if isinstance(v, Dispatcher) and v.py_func.__module__ == module.__name__]
            if kernels and not any(k._cache._cache_file._load_index() for k in kernels):
                return False
    except Exception:
        return True
    return True


#: What the command line says before kernels compile.
COMPILE_NOTICE = "raytrace: compiling kernels, first run only (about 10 s)"


class CompileNotice(event.Listener):
    """:data:`COMPILE_NOTICE`, said at most once: up front where :func:`cache_is_warm` finds the
    cache cold (:meth:`say`), else on the first compile numba starts while it listens
    (:meth:`listening`: numba's ``numba:compile`` event, which fires only on a cache miss),
    such as a scene that needs kernel variants an earlier scene did not compile."""

    def __init__(self, write: Callable[[str], object]):
        self._write = write
        self._said = False
        self._lock = threading.Lock()  # a render's threads may each start a compile

    def say(self) -> None:
        with self._lock:
            if not self._said:
                self._said = True
                self._write(COMPILE_NOTICE + "\n")

    def on_start(self, event: event.Event) -> None:
        self.say()

    def on_end(self, event: event.Event) -> None:
        pass

    @contextmanager
    def listening(self) -> Iterator[None]:
        """Say it on the first compile inside the block."""
        event.register("numba:compile", self)
        try:
            yield
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
