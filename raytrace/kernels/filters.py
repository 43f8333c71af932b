"""Compiled pixel reconstruction (:mod:`raytrace.film.filters`): a filter's 1-D profile by code
(:func:`profile1`) and the pass that gathers each pixel's footprint from the traced samples
(:func:`filter_pixels`)."""

from __future__ import annotations

import math

from .core import pixel_offset
from .jit import helper, kernel
from .kinds import BOX, GAUSSIAN, TENT

#: Gaussian's standard deviation (pbrt-v4's default), in pixels.
SIGMA = 0.5
#: Mitchell–Netravali's (B, C): their recommended 1/3, 1/3.
B, C = 1.0 / 3.0, 1.0 / 3.0


@helper
def profile1(code, radius, x):
    """The 1-D profile ``f(x)`` of filter ``code`` with ``radius``, 0 outside ``[−r, r]``
    (module docstring; Mitchell & Netravali 1988, eq. 8, scaled by 2/r)."""
    a = abs(x)
    if a > radius:
        return 0.0
    if code == BOX:
        return 1.0 / (2.0 * radius)
    if code == TENT:
        return (radius - a) / (radius * radius)
    if code == GAUSSIAN:
        tail = math.exp(-radius * radius / (2.0 * SIGMA * SIGMA))
        z = (SIGMA * math.sqrt(2.0 * math.pi) * math.erf(radius / (SIGMA * math.sqrt(2.0)))
             - 2.0 * radius * tail)
        return (math.exp(-a * a / (2.0 * SIGMA * SIGMA)) - tail) / z
    t = 2.0 * a / radius  # Mitchell–Netravali on [0, 2]
    if t < 1.0:
        m = ((12.0 - 9.0 * B - 6.0 * C) * t * t * t + (-18.0 + 12.0 * B + 6.0 * C) * t * t
             + (6.0 - 2.0 * B)) / 6.0
    else:
        m = ((-B - 6.0 * C) * t * t * t + (6.0 * B + 30.0 * C) * t * t
             + (-12.0 * B - 48.0 * C) * t + (8.0 * B + 24.0 * C)) / 6.0
    return m * 2.0 / radius


@kernel
def profile_rows(code, radius, x, out):
    for i in range(x.shape[0]):
        out[i] = profile1(code, radius, x[i])


@kernel
def filter_pixels(samples, traced, sampling, profile, window, out):
    """Filtered pixels of ``window`` (a :class:`raytrace.kernels.records.Window`, x0 … x1 − 1
    by y0 … y1 − 1) into ``out`` ((x1−x0)·(y1−y0), 3), rows in order.

    ``samples`` (n, 3) are the radiance sums of the samples of the ``traced`` window (a
    ``Window``, a superset of ``window`` by ``reach`` pixels where the frame allows),
    pixel·spp + cell in its row order; ``sampling``: how the camera numbered and placed them
    (a :class:`raytrace.kernels.records.Sampling`); ``profile``: the filter (a
    :class:`raytrace.kernels.records.FilterProfile`: code, radius, reach in pixels). Sample
    (pixel, cell) lies at ``pixel + pixel_offset(…)``, from its global index, as the camera
    put it. Each pixel's sum runs over its footprint's pixels row by row, then their samples
    in order: one fixed order, whatever window was traced."""
    tx0, ty0, tx1, ty1 = traced.x0, traced.y0, traced.x1, traced.y1
    width, spp, k, seed = sampling.width, sampling.spp, sampling.k, sampling.seed
    code, radius, reach = profile.code, profile.radius, profile.reach
    x0, y0, x1, y1 = window.x0, window.y0, window.x1, window.y1
    j = 0
    for py in range(y0, y1):
        for px in range(x0, x1):
            cx, cy = px + 0.5, py + 0.5
            r = g = b = wsum = 0.0
            for ny in range(max(py - reach, ty0), min(py + reach + 1, ty1)):
                for nx in range(max(px - reach, tx0), min(px + reach + 1, tx1)):
                    first = ((ny - ty0) * (tx1 - tx0) + (nx - tx0)) * spp
                    g0 = (ny * width + nx) * spp
                    for c in range(spp):
                        sx, sy = pixel_offset(spp, k, seed, g0 + c, c)
                        w = (profile1(code, radius, nx + sx - cx)
                             * profile1(code, radius, ny + sy - cy))
                        if w != 0.0:
                            r += w * samples[first + c, 0]
                            g += w * samples[first + c, 1]
                            b += w * samples[first + c, 2]
                            wsum += w
            if wsum != 0.0:
                out[j, 0], out[j, 1], out[j, 2] = r / wsum, g / wsum, b / wsum
            else:
                out[j, 0] = out[j, 1] = out[j, 2] = 0.0
            j += 1
