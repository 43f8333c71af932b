"""The compiled kernels: every numba function of the renderer, and nothing that is not one.

Imports nothing outside this folder. :mod:`.jit` holds the decorators and the cache guard,
:mod:`.kinds` the codes every stage shares, :mod:`.records` the named records that cross into
the kernels, :mod:`.core` the per-ray primitives; then one module per pipeline stage.
"""
