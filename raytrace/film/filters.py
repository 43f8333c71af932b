"""Pixel reconstruction filters: a pixel is a weighted average of the samples around it.

A pixel centred at ``c`` takes ``Σ_s f(x_s − c_x)·f(y_s − c_y)·L_s / Σ_s f(…)·f(…)`` over the
samples ``s`` (at image positions ``x_s, y_s``, radiance ``L_s``) of every pixel whose area
reaches within the filter's radius (pbrt-v4, "Image Reconstruction", §8.8; Mitchell &
Netravali 1988). The filters are separable, ``f(x)·f(y)``, and each 1-D profile integrates
to 1 over ``[−r, r]``:

==========  ======  =============================================================
name        radius  profile ``f(x)`` on ``|x| ≤ r``
==========  ======  =============================================================
box         0.5     1 (the mean of the pixel's own samples: the default)
tent        1       ``1 − |x|`` (Mitsuba's ``tent``)
gaussian    1.5     ``(g(x) − g(r)) / Z``, ``g = exp(−x²/2σ²)``, σ = 0.5 (pbrt-v4's
                    defaults), ``Z = σ√(2π)·erf(r/σ√2) − 2r·g(r)``
mitchell    2       Mitchell–Netravali cubic with B = C = 1/3, ``(2/r)·M(2x/r)``
==========  ======  =============================================================

``box`` keeps today's images bit for bit (the integrator averages each pixel's samples). A
wider filter needs the samples of neighbouring pixels: the integrator traces the window plus
a margin of :func:`raytrace.sampling.margin` pixels (clipped to the frame) and gathers each
pixel's footprint in one fixed order (rows, then columns, then the pixel's samples), so a
pixel's value is the same for any pass size, thread count or crop (:func:`filter_pixels`).
Sample positions are those of the camera (:func:`raytrace.kernels.core.pixel_offset`), recomputed
from the samples' global indices. The names and radii: :mod:`raytrace.sampling`.

Noise-driven sampling (:mod:`raytrace.noise`) draws each sample from the filter instead
(:func:`importance`, filter importance sampling): a pixel is then the plain Monte Carlo
estimate of ``∫ f(x − c_x)·f(y − c_y)·L(x, y)``, made of its own samples alone.
"""

from __future__ import annotations

import functools

import numpy as np

from ..kernels.filters import filter_pixels, profile_rows
from ..kernels.records import FilterProfile, Sampling, Window
from ..sampling import FILTERS, check_filter, margin


def profile(name: str, x: np.ndarray) -> np.ndarray:
    """:func:`profile1` of filter ``name`` at each offset ``x`` (pixels), (n,) float64.

    >>> float(profile("tent", np.array([0.5]))[0])
    0.5
    """
    f = FILTERS[check_filter(name, "filter")]
    x = np.ascontiguousarray(x, dtype=np.float64).reshape(-1)
    out = np.empty(len(x))
    profile_rows(f.code, f.radius, x, out)
    return out


#: Bins of the tabulated ``|f|`` that :func:`importance` inverts over ``[−r, r]``.
IMPORTANCE_BINS = 4096


@functools.cache
def _tabulated(name: str) -> tuple[np.ndarray, np.ndarray, float]:
    """Filter ``name``'s ``|f|`` as a piecewise-constant density over :data:`IMPORTANCE_BINS`
    equal bins of ``[−r, r]`` (its value at each bin's middle): the bins' edges, the CDF at
    the edges, and the weight ``∫|f̃| / ∫f̃`` of the tabulated profile ``f̃``."""
    r = FILTERS[name].radius
    edges = np.linspace(-r, r, IMPORTANCE_BINS + 1)
    f = profile(name, 0.5 * (edges[:-1] + edges[1:]))
    cdf = np.concatenate([[0.0], np.cumsum(np.abs(f))])
    return edges, cdf / cdf[-1], 1.0 if (f >= 0).all() else float(cdf[-1] / f.sum())


def importance(name: str, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Filter importance sampling (pbrt-v4, "Image Reconstruction", §8.8.2, its
    ``FilterSampler``; Ernst et al. 2006): offsets ``x`` (n,) from a pixel's centre, in
    ``[−r, r]``, for uniform ``u`` (n,) in [0, 1), distributed as ``|f̃|``, the profile
    tabulated in :data:`IMPORTANCE_BINS` bins (:func:`_tabulated`; inverted bin by bin, so
    stratified ``u`` stay stratified), and each sample's weight ``f̃/p = sign(f(x))·∫|f̃|``,
    normalised so that ``f̃`` integrates to 1: with ``x`` and ``y`` drawn so, ``w_x·w_y·L(x,
    y)`` has the pixel filtered by ``f̃`` as its expectation, whatever the pixel's
    neighbours. ``f̃`` is ``f`` to within its slope times half a bin (1/4096 of the
    diameter). The weight is exactly 1 for the positive filters (box, tent, Gaussian), and
    ``±∫|f|/∫f`` = ±1.06 for Mitchell–Netravali (negative lobes); the box is ``x = u − ½``.

    >>> x, w = importance("tent", np.array([0.5]))
    >>> float(x[0]), float(w[0])
    (0.0, 1.0)
    """
    u = np.asarray(u, np.float64)
    if name == "box":
        return u - 0.5, np.ones_like(u)
    edges, cdf, weight = _tabulated(name)
    x = np.interp(u, cdf, edges)
    return x, np.where(profile(name, x) < 0.0, -weight, weight)


def gather(samples: np.ndarray, name: str, traced: tuple[int, int, int, int],
           window: tuple[int, int, int, int], frame: tuple[int, int, int, int]) -> np.ndarray:
    """The pixels (n, 3) float32 of ``window`` (x0, y0, x1, y1) from the sums (m, 3) of every
    sample of the ``traced`` window, by filter ``name``: each pixel's footprint gathered in one
    compiled pass (:func:`raytrace.kernels.filters.filter_pixels`). ``frame`` = (width, spp,
    stratification grid, seed) (a :class:`raytrace.kernels.records.Sampling`): where the
    camera put each sample."""
    f = FILTERS[name]
    window, traced = Window(*window), Window(*traced)
    out = np.empty(((window.x1 - window.x0) * (window.y1 - window.y0), 3), np.float32)
    with np.errstate(over="ignore", invalid="ignore"):
        filter_pixels(samples, traced, Sampling(*frame),
                      FilterProfile(f.code, f.radius, margin(name)), window, out)
    return out
