"""The numba set-up shared by every compiled kernel.

Kernels are compiled with ``cache=True`` (the first run after installing compiles them once,
later starts load the machine code from the cache), ``nogil=True`` (so they can run in the
integrator's thread pool) and without ``fastmath`` (IEEE results, reproducible across runs).
Parallel kernels use ``numba.prange`` over rays: every ray writes only its own rows, so
results do not depend on the number of threads.
"""

from __future__ import annotations

import numba

#: Decorator for serial kernels.
kernel = numba.njit(cache=True, nogil=True, fastmath=False, error_model="numpy")
#: Decorator for kernels parallel over rays (``numba.prange``).
parallel_kernel = numba.njit(cache=True, nogil=True, fastmath=False, error_model="numpy",
                             parallel=True)
prange = numba.prange


def set_threads(n: int) -> None:
    """Use ``n`` threads (at most the number numba started with) in parallel kernels."""
    numba.set_num_threads(max(1, min(int(n), numba.config.NUMBA_NUM_THREADS)))
