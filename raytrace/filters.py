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
Sample positions are those of the camera (:func:`raytrace.core.pixel_offset`), recomputed
from the samples' global indices. The names and radii: :mod:`raytrace.sampling`.
"""

from __future__ import annotations

import math

import numpy as np

from .core import pixel_offset
from .jit import kernel
from .sampling import BOX, FILTERS, GAUSSIAN, TENT, check_filter

#: Gaussian's standard deviation (pbrt-v4's default), in pixels.
SIGMA = 0.5
#: Mitchell–Netravali's (B, C): their recommended 1/3, 1/3.
B, C = 1.0 / 3.0, 1.0 / 3.0


@kernel
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
def _profile_rows(code, radius, x, out):
    for i in range(x.shape[0]):
        out[i] = profile1(code, radius, x[i])


def profile(name: str, x: np.ndarray) -> np.ndarray:
    """:func:`profile1` of filter ``name`` at each offset ``x`` (pixels), (n,) float64.

    >>> float(profile("tent", np.array([0.5]))[0])
    0.5
    """
    f = FILTERS[check_filter(name, "filter")]
    x = np.ascontiguousarray(x, dtype=np.float64).reshape(-1)
    out = np.empty(len(x))
    _profile_rows(f.code, f.radius, x, out)
    return out


@kernel
def filter_pixels(samples, traced, frame, profile, window, out):
    """Filtered pixels of ``window`` = (x0, y0, x1, y1) into ``out`` ((x1−x0)·(y1−y0), 3),
    rows in order.

    ``samples`` (n, 3) are the radiance sums of the samples of the ``traced`` window (x0, y0,
    x1, y1, a superset of ``window`` by ``reach`` pixels where the frame allows), pixel·spp +
    cell in its row order; ``frame`` = (width, spp, k (the stratification grid), seed);
    ``profile`` = (filter code, radius, reach in pixels). Sample (pixel, cell) lies at ``pixel
    + pixel_offset(…)``, from its global index, as the camera put it. Each pixel's sum runs
    over its footprint's pixels row by row, then their samples in order: one fixed order,
    whatever window was traced."""
    tx0, ty0, tx1, ty1 = traced
    width, spp, k, seed = frame
    code, radius, reach = profile
    x0, y0, x1, y1 = window
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
