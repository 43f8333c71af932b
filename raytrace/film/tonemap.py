"""Previews: exposure, tone mapping by colour-hdri, sRGB encoding by colour-science.

A preview of linear RGB is, per pixel,

    code = round(top · cctf_encoding(clip(T(x · 2^EV), 0, 1)))        top = 255 or 65535

* ``EV``: the exposure in stops, or ``"auto"``: ``log2(a / L̄)`` with the key ``a = 0.18`` and
  ``L̄ = exp(mean(log L))`` the log-average luminance of the pixels with ``L > 0`` (Reinhard,
  Stark, Shirley & Ferwerda 2002, "Photographic tone reproduction for digital images",
  eqs. 1-2; black pixels are left out, so a black background does not drag ``L̄`` to 0).
  ``L`` is Y of the sRGB/Rec. 709 primaries, weights by colour-science (those of
  ``colour.RGB_luminance``).
* ``T``: a tone-mapping operator of :data:`TONEMAPS`: ``clip`` (none), or colour-hdri's global
  operators under their own names, lower-cased without the ``tonemapping_operator_`` prefix
  (``reinhard2004``, ``filmic``, ``tumblin1999``, ``schlick1994``, ``logarithmic``, ...), with
  colour-hdri's default parameters unless ``params`` names others. ``reinhard`` is the name
  raytrace has always had for ``x / (1 + x)`` per channel (Reinhard et al. 2002, eq. 3): it is
  colour-hdri's ``simple`` operator, with the same output as before.
* ``cctf_encoding``: the sRGB encoding of IEC 61966-2-1 in float64 (:func:`srgb_encode`, the
  same numbers as colour-science's ``cctf_encoding(..., function="sRGB")``).
  Non-finite and negative values show black.

Cost: ``clip`` and the per-pixel operators (``reinhard``/``simple``, ``gamma``, ``filmic``) run
band by band, so the memory a preview adds does not grow with the image; ``clip`` reads the
float32 image in place in one compiled pass (:mod:`raytrace.kernels.tonemap`). The other
operators compute statistics of the whole image (maximum, log-average, mean) inside
colour-hdri, so they run on the whole image in float64, as colour-hdri computes.
Measurements: docs/performance.md, "Previews".

colour-science and colour-hdri are imported by a preview that uses them (an operator other than
``clip``, or ``exposure="auto"``; not by ``import raytrace``);
the numpy print options they set on import (``legacy="1.13"``) are put back.
"""

from __future__ import annotations

import functools
import inspect
import math
import sys
import warnings
from collections.abc import Callable
from typing import Any, NamedTuple

import numpy as np


class ToneMap(NamedTuple):
    """A tone-mapping operator: colour-hdri's function (by name, imported on use), whether it
    works pixel by pixel (so a preview can run it band by band), and what it is."""

    function: str | None
    per_pixel: bool
    about: str


_HDRI = "tonemapping_operator_"

#: Tone-mapping operators by name → colour-hdri's function, applied after the exposure and
#: before clipping. The names are colour-hdri's, lower-cased, without the prefix; ``clip``
#: (no operator) and ``reinhard`` (an alias of ``simple``) are raytrace's older names.
TONEMAPS: dict[str, ToneMap] = {
    "clip": ToneMap(None, True, "none: the exposed values, clipped to [0, 1]"),
    "reinhard": ToneMap(_HDRI + "simple", True,
                        "x / (1 + x) per channel (Reinhard et al. 2002, eq. 3): 'simple'"),
    "simple": ToneMap(_HDRI + "simple", True, "x / (1 + x) per channel"),
    "gamma": ToneMap(_HDRI + "gamma", True, "(2^EV · x)^(1/gamma) (Banterle et al. 2011)"),
    "filmic": ToneMap(_HDRI + "filmic", True, "Hable's Uncharted 2 filmic curve (2010)"),
    "normalisation": ToneMap(_HDRI + "normalisation", False, "x / L_max (Banterle 2011)"),
    "logarithmic": ToneMap(_HDRI + "logarithmic", False,
                           "log10(1 + q·L) / log10(1 + k·L_max) (Banterle 2011)"),
    "exponential": ToneMap(_HDRI + "exponential", False,
                           "1 − exp(−q·L / (k·L_avg)) (Banterle 2011)"),
    "logarithmic_mapping": ToneMap(_HDRI + "logarithmic_mapping", False,
                                   "(log(1 + p·L) / log(1 + p·L_max))^(1/q) (Schlick 1994)"),
    "exponentiation_mapping": ToneMap(_HDRI + "exponentiation_mapping", False,
                                      "(L / L_max)^(p/q) (Schlick 1994)"),
    "schlick1994": ToneMap(_HDRI + "Schlick1994", False,
                           "p·L / (p·L − L + L_max) (Schlick 1994)"),
    "tumblin1999": ToneMap(_HDRI + "Tumblin1999", False,
                           "Tumblin, Hodgins & Guenter 1999, display adaptation"),
    "reinhard2004": ToneMap(_HDRI + "Reinhard2004", False,
                            "Reinhard & Devlin 2005 (photoreceptor model; f, m, a, c)"),
}

#: Exposures a preview accepts, in stops. 2^±256 spans float32's whole range (2^-149 to
#: 2^128) with room to spare: beyond it every finite value is black or white anyway. Within
#: it, ``x · 2^EV`` and what the operators compute from it stay finite in float64.
EXPOSURE_RANGE = (-256.0, 256.0)

#: Reinhard et al. 2002's key value: the log-average luminance maps to middle grey.
AUTO_KEY = 0.18

#: Bit depths of a preview → (numpy type, largest code).
BIT_DEPTHS = {8: (np.uint8, 255), 16: (np.uint16, 65535)}

#: Pixels per band of a banded preview: 2^18 (about 65 rows at 4000 wide) keeps a float64
#: band at 6 MB, so the per-pixel operators' temporaries stay well under the 150 MB bound.
BAND_PIXELS = 1 << 18


def check_exposure(value: Any) -> float | str:
    """``value`` as a number of stops in :data:`EXPOSURE_RANGE`, or ``"auto"`` (any case); a
    ValueError saying what is accepted otherwise (NaN, inf, out of range, not a number)."""
    stops = value
    if isinstance(value, str):
        if value.strip().lower() == "auto":
            return "auto"
        try:
            stops = float(value)
        except ValueError:
            stops = None
    lo, hi = EXPOSURE_RANGE
    if isinstance(stops, bool) or not isinstance(stops, (int, float, np.integer, np.floating)) \
            or not (math.isfinite(stops) and lo <= stops <= hi):
        raise ValueError(f"exposure must be a finite number of stops in [{lo:g}, {hi:g}] or "
                         f"'auto', got {value!r}")
    return float(stops)


def check_tonemap(name: Any) -> str:
    """The :data:`TONEMAPS` name ``name`` stands for (any case); a ValueError listing the
    names otherwise."""
    key = name.lower() if isinstance(name, str) else None
    if key not in TONEMAPS:
        raise ValueError(f"unknown tone map {name!r} (choose from {', '.join(TONEMAPS)})")
    return key


def check_bits(bits: Any) -> int:
    """8 or 16; a ValueError otherwise."""
    if isinstance(bits, bool) or bits not in BIT_DEPTHS:
        raise ValueError(f"PNG bit depth must be 8 or 16, got {bits!r}")
    return int(bits)


def _quiet_import(name: str):
    """Import colour-science or colour-hdri without their side effects on the caller: the
    warning that matplotlib is absent (not needed here), and numpy's global print options,
    which both set to ``legacy="1.13"`` on import (put back as they were), and the mock
    ``scipy`` module colour installs where SciPy is absent (taken out again)."""
    import importlib

    options = np.get_printoptions()
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            return importlib.import_module(name)
    finally:
        np.set_printoptions(**options)
        # Without SciPy, colour puts a MagicMock in sys.modules["scipy"] (keeping its own
        # reference); numba, imported later by a render, would read the mock's __version__
        # and fail.
        for module in ("scipy", "scipy.interpolate"):
            if type(sys.modules.get(module)).__module__ == "unittest.mock":
                del sys.modules[module]


def colour():
    """The ``colour`` module (colour-science), imported quietly on first use."""
    return _quiet_import("colour")


def colour_hdri():
    """The ``colour_hdri`` module, imported quietly on first use."""
    colour()  # colour-hdri imports colour: quietly first
    return _quiet_import("colour_hdri")


def operator(name: str, params: dict | None = None) -> Callable[[np.ndarray], np.ndarray] | None:
    """colour-hdri's function for ``name`` with ``params`` bound (``None`` for ``clip``).

    ``params`` are keyword arguments of that function (e.g. ``{"f": -2, "m": 0.5}`` for
    ``reinhard2004``), finite numbers; an unknown name or a bad value is a ValueError that
    lists the parameters the operator takes.
    """
    name = check_tonemap(name)
    tm = TONEMAPS[name]
    params = dict(params or {})
    if tm.function is None:
        if params:
            raise ValueError(f"tone map 'clip' takes no parameters, got {sorted(params)}")
        return None
    fn = getattr(colour_hdri(), tm.function)
    names = [p for p in inspect.signature(fn).parameters if p not in ("RGB", "colourspace")]
    for key, value in params.items():
        if key not in names:
            raise ValueError(f"tone map {name!r} has no parameter {key!r} "
                             f"(it takes {', '.join(names)})")
        if isinstance(value, bool) or not isinstance(value, (int, float, np.integer,
                                                             np.floating)) \
                or not math.isfinite(value):
            raise ValueError(f"tone map {name!r}: parameter {key!r} must be a finite number, "
                             f"got {value!r}")
    return functools.partial(fn, **params) if params else fn


def srgb_encode(y: np.ndarray) -> np.ndarray:
    """The sRGB encoding of linear ``y`` in [0, 1], float64 (IEC 61966-2-1):
    ``12.92·y`` up to 0.0031308, ``1.055·y^(1/2.4) − 0.055`` above.

    The operations of colour-science's ``eotf_inverse_sRGB`` (``cctf_encoding(...,
    function="sRGB")``) in its order, so the same float64 results (tests/test_tonemap.py
    checks every 8- and 16-bit code boundary against colour); written here because importing
    colour costs 0.9 s of a fresh process's first preview, to compute 2 KB of thresholds.

    >>> float(srgb_encode(np.float64(0.18)))  # doctest: +ELLIPSIS
    0.4613561...
    """
    y = np.asarray(y, dtype=np.float64)
    with np.errstate(invalid="ignore"):  # the branch not taken
        return np.where(y <= 0.0031308, y * 12.92,
                        1.055 * (np.sign(y) * np.abs(y) ** (1 / 2.4)) - 0.055)


class SRGBTable(NamedTuple):
    """Where each sRGB code begins, for :func:`raytrace.kernels.tonemap.encode`."""

    lut: np.ndarray
    thresholds: np.ndarray


@functools.lru_cache(maxsize=2)
def srgb_table(bits: int = 8) -> SRGBTable:
    """The linear values where each code of an 8- or 16-bit sRGB preview begins.

    ``code(y) = round(top · srgb_encode(clip(y, 0, 1)))`` in float64 (IEC 61966-2-1; the
    same numbers as ``colour.cctf_encoding(..., function="sRGB")``) is increasing in ``y``,
    so it is fixed by ``top`` thresholds: the smallest float64 ``y`` with ``code(y) ≥ k``,
    found by bisection on the float64 bit patterns of
    [0, 1] (non-negative floats sort as their bits), 63 halvings of all ``top`` intervals at
    once. ``lut`` gives the code at 2^16 (8-bit) or 2^20 (16-bit) evenly spaced ``y``, where
    the kernel starts counting.
    """
    top = BIT_DEPTHS[check_bits(bits)][1]

    def code(y: np.ndarray) -> np.ndarray:
        return np.clip(np.round(srgb_encode(np.clip(y, 0.0, 1.0)) * top), 0, top)

    k = np.arange(1, top + 1, dtype=np.float64)
    lo = np.zeros(top, np.int64)                                # bits of 0.0: code 0
    hi = np.full(top, np.float64(1.0).view(np.int64))          # bits of 1.0: code top
    while np.any(lo < hi):
        mid = lo + (hi - lo) // 2
        above = code(mid.view(np.float64)) >= k
        hi = np.where(above, mid, hi)
        lo = np.where(above, lo, mid + 1)
    thresholds = np.append(hi.view(np.float64), np.inf)
    n = 1 << (16 if bits == 8 else 20)
    lut = np.searchsorted(thresholds, np.arange(n) / n, side="right").astype(np.uint16)
    return SRGBTable(lut, thresholds)
