"""The numba set-up shared by every compiled kernel, and the guard that keeps its cache true.

Kernels are compiled with ``cache=True`` (the first run after installing compiles them once,
later starts load the machine code from the cache), ``nogil=True`` (so the integrator's
threads run them side by side) and without ``fastmath`` (IEEE results, reproducible across
runs). They are serial: the render is parallel over passes of whole pixels, one thread a
pass (:mod:`raytrace.integrator`), so no kernel starts threads of its own and numba's
threading layer (OpenMP or TBB) is never loaded.

**The cache guard.** numba's on-disk cache checks only the source file of the kernel it
compiled, not the files of the functions that kernel inlines (numba issue #1833): edit a
per-ray helper in one module and every kernel of another module that calls it would keep
running the old machine code; nor does it notice a constant a kernel reads from another module
(numba freezes a global's value into the machine code: a column of a packed row, a kind's
code). So, on import, :func:`refresh_cache` hashes the source of every module of the package
that compiles kernels and of the two whose constants they read (:data:`CONSTANTS`; with
numba's version); where that hash differs from the one stored beside the cache, the cache
files of the kernel modules are deleted and the kernels compile afresh (STUMPY's ``cache.py``
does the same by hand). The hash also covers the installed embreex and the Embree library it
ships (:func:`engine_stamp`): the traversal kernels are compiled against Embree's struct
layouts, so code compiled beside another Embree never loads. Reading and hashing the sources
costs about a millisecond. numpy's version is hashed too: numba's cache keys its files on numba's
version and the CPU, not on the numpy whose functions it compiled in.

**Side by side.** Processes that compile into one cache folder at once (``raytrace warmup``'s
workers, two renders, pytest-xdist) never leave it wrong: numba saves an entry as read the
index, add the entry, write the index, write the data, so two processes adding signatures of
one kernel at once lose one's entry, or pair one's index with the other's data file
(``numba.core.caching.IndexDataCacheFile.save``). :class:`LockedCacheFile` holds an exclusive
``flock`` on a lock file beside the index for the whole save and a shared one while loading.
"""

from __future__ import annotations

import hashlib
import importlib.util
import os
import re
import tempfile
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path

import numba
import numpy as np
from numba.core import caching
from numba.core.dispatcher import Dispatcher

try:
    import fcntl
except ImportError:  # not POSIX: numba's own unlocked cache
    fcntl = None


class LockedCacheFile(caching.IndexDataCacheFile):
    """numba's index and data files of one kernel, each save whole: an exclusive ``flock`` on
    ``<index>.lock`` from reading the index to writing the data, a shared one while loading.
    Where the lock file cannot be made (a read-only folder, where numba saves nothing either)
    it reads as numba does."""

    @contextmanager
    def _locked(self, how: int) -> Iterator[None]:
        fd = None
        if fcntl is not None:
            try:
                fd = os.open(self._index_path + ".lock", os.O_RDWR | os.O_CREAT, 0o666)
                fcntl.flock(fd, how)
            except OSError:
                if fd is not None:
                    os.close(fd)
                fd = None
        try:
            yield
        finally:
            if fd is not None:
                os.close(fd)  # releases the lock

    def save(self, key, data):
        with self._locked(fcntl.LOCK_EX if fcntl else 0):
            super().save(key, data)

    def load(self, key):
        with self._locked(fcntl.LOCK_SH if fcntl else 0):
            return super().load(key)


class LockedCache(caching.FunctionCache):
    """numba's cache of one kernel (``cache=True``) through :class:`LockedCacheFile`."""

    def __init__(self, py_func: Callable):
        super().__init__(py_func)
        self._cache_file = LockedCacheFile(self._cache_path, self._impl.filename_base,
                                           self._impl.locator.get_source_stamp())


#: The numba options of every kernel (see this module's docstring). None has numba's C entry
#: point (``no_cfunc_wrapper``): Python calls kernels through their CPython wrapper and
#: kernels call each other directly, so nothing takes a kernel's C address, and the wrapper
#: only cost compile time.
OPTIONS = {"nogil": True, "fastmath": False, "error_model": "numpy", "no_cfunc_wrapper": True}
#: Those of a kernel only compiled code calls (:data:`helper`): without numba's CPython and C
#: entry points. ``numba.extending.overload``'s ``jit_options`` for an implementation that
#: only kernels call: numba compiles the functions a kernel calls (``np.empty`` …) once per
#: set of options of the kernels that call them, so one set for all of them compiles each
#: once (kernels/loop.py).
INNER = {**OPTIONS, "no_cpython_wrapper": True}


def _cached(**options) -> Callable[[Callable], Dispatcher]:
    """A decorator compiling with ``options`` and caching through :class:`LockedCache`
    (what ``cache=True`` does, with numba's ``FunctionCache``)."""
    compile_ = numba.njit(**{**OPTIONS, **options})

    def decorate(fn: Callable) -> Dispatcher:
        dispatcher = compile_(fn)
        dispatcher._cache = LockedCache(dispatcher.py_func)  # Dispatcher.enable_caching's slot
        return dispatcher
    return decorate


#: Decorator for every kernel.
kernel = _cached()
#: Decorator for a small dispatcher that must vanish into its callers (numba inlines it in
#: its own IR, before LLVM: ``accel_kernels.shape_t`` called as a kernel cost 50 % more per
#: analytic query, 33.8 against 22.7 ns a ray on the Whitted scene), and for a step of the
#: compiled loop called from one place (kernels/loop.py): typed and lowered in its caller, it
#: has no machine code of its own that the caller would link and optimize again.
inline = _cached(inline="always")
#: Decorator for a per-ray helper that only other kernels call: compiled without the wrappers
#: that let Python (and C) call it, so its first compile lowers and emits less machine code
#: (a matte scene's first render, measured with 40 helpers: 14.8–14.9 s of CPU against
#: 16.7–16.8 s; docs/performance.md, "Cold compile"). LLVM links and inlines it into its
#: callers exactly as a :data:`kernel`. Calling one from Python raises numba's error; a test
#: that checks a helper against hand-worked values calls it through a kernel, or the helper
#: stays a :data:`kernel`.
helper = _cached(**INNER)


PACKAGE = Path(__file__).resolve().parent
#: The file beside a cache that holds the hash of the sources its files were compiled from.
STAMP = "raytrace-kernels.sha256"


#: An import of a decorator of this module, the mark of a module that compiles kernels.
_DECORATORS = re.compile(r"^from \.jit import .*\b(helper|inline|kernel)\b", re.MULTILINE)


def kernel_modules() -> list[Path]:
    """The package's modules that compile kernels: every ``.py`` file that imports from this
    one (:data:`kernel`, :data:`inline`, :data:`helper`; this one excluded), in a fixed
    order."""
    return sorted(p for p in PACKAGE.rglob("*.py") if p != Path(__file__).resolve()
                  and _DECORATORS.search(p.read_text("utf-8")))


#: The modules of this folder that compile no kernel but whose values the kernels read as
#: constants: the codes and the packed rows' columns.
CONSTANTS = ("kinds.py", "records.py")


def hashed_modules() -> list[Path]:
    """The sources the cache's machine code depends on: :func:`kernel_modules` and
    :data:`CONSTANTS`."""
    return kernel_modules() + [PACKAGE / name for name in CONSTANTS]


def engine_stamp() -> str:
    """The installed embreex's distribution folder (its version) and the names of the
    libraries its wheel ships (auditwheel hashes each build into the name): found on disk,
    without importing embreex."""
    spec = importlib.util.find_spec("embreex")
    if spec is None or not spec.submodule_search_locations:
        return "no embreex"
    site = Path(next(iter(spec.submodule_search_locations))).parent
    names = [p.name for pattern in ("embreex-*.dist-info", "embreex.libs/*embree*",
                                    "embreex/.dylibs/*embree*", "embreex/*embree4*")
             for p in site.glob(pattern)]
    return "\0".join(sorted(names))


def source_hash(modules: list[Path]) -> str:
    """SHA-256 of numba's and numpy's versions, the Embree this install calls
    (:func:`engine_stamp`) and every module's path and source."""
    h = hashlib.sha256(f"{numba.__version__}\0{np.__version__}\0{engine_stamp()}".encode())
    for path in modules:
        h.update(str(path.relative_to(PACKAGE)).encode() + b"\0" + path.read_bytes() + b"\0")
    return h.hexdigest()


def cache_dirs(modules: list[Path]) -> set[Path]:
    """Where numba may keep these modules' cache files, as its locators choose them:
    ``__pycache__`` beside each module, the mirrored folder under ``NUMBA_CACHE_DIR`` when
    that is set, and under the user's cache folder (where ``__pycache__`` is read-only)."""
    from numba.core import caching, config
    from numba.misc.appdirs import AppDirs

    user = Path(AppDirs(appname="numba", appauthor=False).user_cache_dir)
    dirs = set()
    for path in modules:
        dirs.add(path.parent / "__pycache__")
        sub = caching._CacheLocator.get_suitable_cache_subpath(str(path))
        if config.CACHE_DIR:
            dirs.add(Path(config.CACHE_DIR) / sub)
        dirs.add(user / sub)
    return dirs


def numba_cache_dir(module: Path) -> Path | None:
    """The folder numba will cache ``module``'s kernels in: the first of its locators that
    takes the file (``numba.core.caching.CacheImpl``: ``NUMBA_CACHE_DIR``'s mirror, else
    a writable ``__pycache__`` beside it, else the user's cache folder), created as numba
    creates it when it decorates the module's first kernel; None where none takes it."""
    from numba.core import caching

    try:
        for cls in caching.CacheImpl._locator_classes:
            locator = cls.from_function(numba_cache_dir, str(module))
            if locator is not None:
                return Path(locator.get_cache_path())
    except Exception:  # numba internals changed: stamp what exists, as before
        return None
    return None


def refresh_cache() -> bool:
    """Delete the cache files of the kernel modules wherever they were compiled from other
    sources than today's; returns whether any folder was refreshed. The folders numba is
    about to write are stamped now, before any kernel compiles, or the next process would
    find their first compile unstamped and delete it. Never raises for a folder it cannot
    read or write (numba then compiles in memory as it would anyway)."""
    modules = kernel_modules()
    digest = source_hash(hashed_modules())
    names = {p.stem for p in modules}
    for module in modules:
        numba_cache_dir(module)
    refreshed = False
    for folder in cache_dirs(modules):
        stamp = folder / STAMP
        try:
            if stamp.read_text() == digest:
                continue
        except OSError:
            pass
        try:
            if not folder.is_dir():  # not where numba caches (numba_cache_dir made that one)
                continue
            for f in folder.iterdir():
                if f.suffix in (".nbi", ".nbc") and f.name.split(".", 1)[0] in names:
                    f.unlink(missing_ok=True)
            fd, tmp = tempfile.mkstemp(dir=folder, prefix=f".{STAMP}.")
            with os.fdopen(fd, "w") as out:
                out.write(digest)
            os.replace(tmp, stamp)
            refreshed = True
        except OSError:
            continue
    return refreshed


refresh_cache()
