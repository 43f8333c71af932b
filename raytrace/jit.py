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
