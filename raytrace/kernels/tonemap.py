"""Compiled quantisation of the preview, used by :mod:`raytrace.film.tonemap`.

``encode`` turns linear values into sRGB code values (8- or 16-bit) in one pass over a band of
pixels, reading float32 (or float64) in place: no float copy of the image is made. It does not
evaluate the sRGB transfer function itself; it looks each value up among the thresholds that
:func:`raytrace.film.tonemap.srgb_table` finds by bisection on the float64 sRGB encoding
(:func:`raytrace.film.tonemap.srgb_encode`: IEC 61966-2-1, the same numbers as colour-science's
``cctf_encoding(..., function="sRGB")``), so the codes are exactly those of
``round(255 · cctf_encoding(clip(x · 2^EV, 0, 1)))`` evaluated in float64.

A serial ``nogil`` kernel (``raytrace.kernels.jit.kernel``), like every other kernel of the package.
"""

from __future__ import annotations

import math

import numpy as np

from .jit import kernel


@kernel
def encode(src, scale, lut, thresholds, out):
    """Code values of ``src · scale``: ``out[i, j, c] = #{k : thresholds[k] ≤ y}``.

    Parameters
    ----------
    src : (h, w, 3) float32 or float64
        Linear values, any strides. NaN, ±inf and values ≤ 0 give code 0 (black).
    scale : float
        ``2^EV``, applied in float64 (no overflow for the exposures
        :func:`raytrace.film.tonemap.check_exposure` accepts).
    lut : (n,) uint16
        ``lut[b]`` is the code of ``y = b / n``: where to start counting thresholds for any
        ``y`` in ``[b / n, (b + 1) / n)``.
    thresholds : (top + 1,) float64
        ``thresholds[k]`` is the smallest ``y`` whose code is ``k + 1``, increasing; the last
        entry is ``+inf`` (a sentinel that ends the count at ``top``).
    out : (h, w, 3) uint8 or uint16
        The codes.
    """
    n = lut.shape[0]
    top = thresholds.shape[0] - 1
    for i in range(src.shape[0]):
        for j in range(src.shape[1]):
            for c in range(3):
                x = src[i, j, c]
                if not (x > 0.0 and math.isfinite(x)):  # NaN, inf, ≤ 0: black
                    out[i, j, c] = 0
                    continue
                y = np.float64(x) * scale
                if y >= 1.0:
                    out[i, j, c] = top
                    continue
                k = np.int64(lut[np.int64(y * n)])
                while y >= thresholds[k]:  # the sentinel stops it at top
                    k += 1
                out[i, j, c] = k


@kernel
def log_luminance(src, weights):
    """``(Σ log L, n)`` over the pixels of ``src`` with ``L > 0``: the sums behind the
    log-average luminance of Reinhard et al. 2002 (eq. 1), ``exp(Σ log L / n)``.

    ``L = Σ_c weights[c] · x_c`` in float64 with the channels ``x_c ≤ 0`` or non-finite taken
    as 0 (as a preview shows them); ``weights`` (3,) float64 is the Y row of the RGB → XYZ
    matrix. ``src`` is (h, w, 3) float32 or float64, read in place.
    """
    total = 0.0
    count = 0
    for i in range(src.shape[0]):
        for j in range(src.shape[1]):
            lum = 0.0
            for c in range(3):
                x = src[i, j, c]
                if x > 0.0 and math.isfinite(x):
                    lum += weights[c] * np.float64(x)
            if lum > 0.0:
                total += math.log(lum)
                count += 1
    return total, count


@kernel
def exposed(src, scale, out):
    """``out = max(x, 0) · scale`` in float64, with NaN and ±inf as 0: the linear values a
    tone-mapping operator sees, in one pass (``src`` (h, w, 3) float32 or float64, ``out`` the
    same shape, float64)."""
    for i in range(src.shape[0]):
        for j in range(src.shape[1]):
            for c in range(3):
                x = src[i, j, c]
                out[i, j, c] = np.float64(x) * scale if x > 0.0 and math.isfinite(x) else 0.0
