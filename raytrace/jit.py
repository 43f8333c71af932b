"""The numba set-up shared by every compiled kernel.

Kernels are compiled with ``cache=True`` (the first run after installing compiles them once,
later starts load the machine code from the cache), ``nogil=True`` (so the integrator's
threads run them side by side) and without ``fastmath`` (IEEE results, reproducible across
runs). They are serial: the render is parallel over passes of whole pixels, one thread a
pass (:mod:`raytrace.integrator`), so no kernel starts threads of its own and numba's
threading layer (OpenMP or TBB) is never loaded.
"""

from __future__ import annotations

import numba

#: Decorator for every kernel.
kernel = numba.njit(cache=True, nogil=True, fastmath=False, error_model="numpy")


def cache_is_warm() -> bool:
    """Whether numba's on-disk cache holds machine code for the kernels of this numba and these
    sources, i.e. whether the next render starts without compiling (the first one after
    installing or editing a kernel module compiles for 15–20 s on 2 cores).

    Cheap (a few small index files are read, nothing is compiled): for each kernel module, at
    least one kernel must have a current cache index, which is numba's own test at load time
    (the index records the source file's stamp and numba's version;
    ``numba.core.caching.IndexDataCacheFile._load_index`` returns nothing when either
    differs). A render calls kernels of both modules, so a module without one will compile.
    These are numba internals: if they change, the answer is True (say nothing rather than
    something wrong).
    """
    from numba.core.dispatcher import Dispatcher

    from . import accel_kernels, shading_kernels

    try:
        for module in (accel_kernels, shading_kernels):
            kernels = [v for v in vars(module).values()
                       if isinstance(v, Dispatcher) and v.py_func.__module__ == module.__name__]
            if kernels and not any(k._cache._cache_file._load_index() for k in kernels):
                return False
    except Exception:
        return True
    return True
