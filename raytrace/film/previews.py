"""Previews of linear RGB: exposure (or automatic), a tone map of :mod:`.tonemap`, clip, sRGB
codes, band by band (the formula and its sources: :mod:`.tonemap`). The quantisation runs in
one compiled pass over the float32 image in place (:mod:`raytrace.kernels.tonemap`)."""

from __future__ import annotations

import math
import os
from collections.abc import Iterator
from typing import Any

import numpy as np

from ..kernels.tonemap import encode, exposed, log_luminance
from .png import write_png_bands
from .tonemap import (
    AUTO_KEY,
    BAND_PIXELS,
    BIT_DEPTHS,
    EXPOSURE_RANGE,
    TONEMAPS,
    check_bits,
    check_exposure,
    check_tonemap,
    colour,
    operator,
    srgb_table,
)


def _as_rgb(rgb: Any) -> np.ndarray:
    """``rgb`` as an (H, W, 3) float array without a copy where it already is one."""
    rgb = np.asarray(rgb)
    if rgb.ndim != 3 or rgb.shape[2] != 3:
        raise ValueError(f"expected an (H, W, 3) image, got shape {rgb.shape}")
    if rgb.dtype not in (np.float32, np.float64):
        rgb = rgb.astype(np.float32)
    return rgb


def _linear(band: np.ndarray, scale: float) -> np.ndarray:
    """``max(x, 0) · scale`` in float64 with non-finite values as 0: what an operator sees."""
    out = np.empty(band.shape, np.float64)
    exposed(band, scale, out)
    return out


def _rows(rgb: np.ndarray) -> int:
    return max(1, BAND_PIXELS // max(1, rgb.shape[1]))


def luminance_weights() -> np.ndarray:
    """The Y row of the sRGB/Rec. 709 RGB → XYZ matrix (D65), by colour-science: the weights
    of ``colour.RGB_luminance`` for these primaries (0.2126, 0.7152, 0.0722)."""
    c = colour()
    srgb = c.RGB_COLOURSPACES["sRGB"]
    return np.ascontiguousarray(c.normalised_primary_matrix(srgb.primaries, srgb.whitepoint)[1])


def auto_exposure(rgb: np.ndarray) -> float:
    """The exposure (stops) that maps the log-average luminance to :data:`AUTO_KEY`:
    ``log2(0.18 / L̄)``, ``L̄ = exp(mean(log L))`` over the pixels with ``L > 0``
    (Reinhard et al. 2002, eqs. 1-2), L the Rec. 709 luminance (:func:`luminance_weights`);
    0 for an image with no lit pixel. One compiled pass over the image in place; clamped to
    :data:`EXPOSURE_RANGE`.

    >>> round(auto_exposure(np.full((2, 2, 3), 0.36, np.float32)), 6)
    -1.0
    """
    log_sum, count = log_luminance(_as_rgb(rgb), luminance_weights())
    if not count:
        return 0.0
    ev = math.log2(AUTO_KEY) - log_sum / count / math.log(2.0)
    return float(min(max(ev, EXPOSURE_RANGE[0]), EXPOSURE_RANGE[1]))


def bands(rgb: np.ndarray, exposure: float | str = 0.0, tonemap: str = "clip", *,
          bits: int = 8, params: dict | None = None) -> Iterator[tuple[int, int, np.ndarray]]:
    """The preview of ``rgb`` (see the module docstring) as ``(row0, row1, codes)`` bands,
    top to bottom: ``codes`` is (row1 − row0, W, 3) uint8 or uint16 (``bits``).

    Arguments are checked before the first band (ValueError naming the problem).
    """
    rgb = _as_rgb(rgb)
    ev = check_exposure(exposure)
    dtype, _ = BIT_DEPTHS[check_bits(bits)]
    op = operator(tonemap, params)
    return _bands(rgb, ev, op, TONEMAPS[check_tonemap(tonemap)].per_pixel, dtype,
                  srgb_table(bits))


def _bands(rgb, ev, op, per_pixel, dtype, table) -> Iterator[tuple[int, int, np.ndarray]]:
    scale = 2.0 ** (auto_exposure(rgb) if ev == "auto" else ev)
    rows = _rows(rgb)
    whole = None
    if op is not None and not per_pixel:  # statistics of the whole image, in colour-hdri
        with np.errstate(divide="ignore", invalid="ignore"):  # 0/0 at black pixels: black
            whole = op(_linear(rgb, scale))
    for y0 in range(0, rgb.shape[0], rows):
        band = rgb[y0:y0 + rows]
        out = np.empty(band.shape, dtype)
        if whole is not None:
            encode(whole[y0:y0 + rows], 1.0, table.lut, table.thresholds, out)
        elif op is None:
            encode(band, scale, table.lut, table.thresholds, out)
        else:
            with np.errstate(divide="ignore", invalid="ignore"):  # 0/0 at black pixels
                encode(op(_linear(band, scale)), 1.0, table.lut, table.thresholds, out)
        yield y0, y0 + len(band), out


def preview(rgb: np.ndarray, exposure: float | str = 0.0, tonemap: str = "clip", *,
            bits: int = 8, params: dict | None = None) -> np.ndarray:
    """The sRGB preview (H, W, 3) uint8 (``bits=16``: uint16) of linear RGB: ``2^exposure``
    (``"auto"``: :func:`auto_exposure`), the operator ``tonemap`` of :data:`TONEMAPS` (with
    colour-hdri keyword ``params``), clip to [0, 1], sRGB encoding. Non-finite values and
    negatives show black.

    >>> preview(np.full((1, 2, 3), 0.5, np.float32))[0, 0].tolist()
    [188, 188, 188]
    """
    rgb = _as_rgb(rgb)
    out = None
    for y0, y1, codes in bands(rgb, exposure, tonemap, bits=bits, params=params):
        if out is None:
            out = np.empty(rgb.shape, codes.dtype)
        out[y0:y1] = codes
    return out if out is not None else np.zeros(rgb.shape, BIT_DEPTHS[bits][0])


def write_png(path: str | os.PathLike, rgb: np.ndarray, exposure: float | str = 0.0,
              tonemap: str = "clip", *, bits: int = 8, params: dict | None = None) -> None:
    """Write the sRGB preview of linear RGB (see :func:`preview`) as an 8- or 16-bit PNG,
    atomically, through OpenImageIO: band by band as they are tone-mapped, so neither a float
    copy nor the whole 8-bit image is held. Bad arguments are a ValueError before any file is
    made; a failing write an OSError that leaves the old file."""
    rgb = np.asarray(rgb)
    codes = bands(rgb, exposure, tonemap, bits=bits, params=params)  # checks first
    write_png_bands(path, rgb.shape[1], rgb.shape[0], bits, codes)
