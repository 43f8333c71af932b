"""Image difference metrics: one registry for ``raytrace compare`` and :mod:`raytrace.testing`.

Every metric takes the test image and the reference as float64 arrays of the same shape
(H, W, C), linear and unclamped, and returns one number. ``METRICS`` maps a name to a
:class:`Metric`; :func:`get` is the dispatcher that names the valid choices on a bad one.

=========  =======================================================  =========  ===========
name       formula (a: test, b: reference, means over every value)   better     default
                                                                                 threshold
=========  =======================================================  =========  ===========
rmse       √mean((a − b)²)                                           lower      1e-3
mae        mean|a − b|                                               lower      1e-3
max        max|a − b|                                                lower      1e-3
relmse     mean((a − b)² / (b² + 10⁻²))  (Rousselle et al. 2011)     lower      1e-3
psnr       10·log10(1 / mean((a − b)²)) dB, peak 1 (display white)   higher     60 dB
flip       mean HDR-FLIP error (Andersson et al. 2021)               lower      0.01
=========  =======================================================  =========  ===========

* relMSE as in Rousselle, Knaus & Zwicker, "Adaptive sampling and reconstruction using greedy
  error minimization" (SIGGRAPH Asia 2011): the squared error relative to the reference's
  squared value, with 10⁻² keeping dark pixels from dominating.
* PSNR takes the peak as 1.0, the white of the (clip) preview, not the image's maximum, so one
  hot highlight does not move it; 60 dB is the same bar as the RMSE default 1e-3. Identical
  images give +inf.
* FLIP: NVIDIA's HDR-FLIP (Andersson, Nilsson, Shirley & Akenine-Möller, "Visualizing errors
  in rendered high dynamic range images", Eurographics 2021) through the ``flip-evaluator``
  package (``pip install 'raytrace[flip]'``), imported only when FLIP is asked for. The
  per-pixel error is in [0, 1]; the metric is its mean, at FLIP's default 67 pixels per degree.

A number is within a threshold when it is not worse: ``value <= threshold`` for the error
metrics, ``value >= threshold`` for PSNR; NaN is never within.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

#: Below this maximum luminance of the reference (twice float32's epsilon) HDR-FLIP has no
#: exposure range: flip-evaluator 1.7 ends the whole process (exit(-1)) instead of raising.
FLIP_MIN_LUMINANCE = 2.0 * float(np.finfo(np.float32).eps)


@dataclass(frozen=True)
class Metric:
    """One registered metric: ``function(test, reference) -> float`` and how to judge it."""

    name: str
    function: Callable[[np.ndarray, np.ndarray], float]
    description: str
    default_threshold: float
    higher_is_better: bool = False
    unit: str = ""

    def within(self, value: float, threshold: float) -> bool:
        """Whether ``value`` is no worse than ``threshold`` (NaN never is)."""
        return bool(value >= threshold) if self.higher_is_better else bool(value <= threshold)


def _mse(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.mean((a - b) ** 2))


def rmse(a: np.ndarray, b: np.ndarray) -> float:
    """Root mean squared error √mean((a − b)²).

    >>> rmse(np.array([0.0, 0.0, 0.0, 2.0]), np.zeros(4))
    1.0
    """
    return float(np.sqrt(_mse(a, b)))


def mae(a: np.ndarray, b: np.ndarray) -> float:
    """Mean absolute error mean|a − b|.

    >>> mae(np.array([1.0, -1.0]), np.zeros(2))
    1.0
    """
    return float(np.mean(np.abs(a - b)))


def max_abs(a: np.ndarray, b: np.ndarray) -> float:
    """Largest absolute difference max|a − b|.

    >>> max_abs(np.array([0.5, -2.0]), np.zeros(2))
    2.0
    """
    return float(np.max(np.abs(a - b)))


def relmse(a: np.ndarray, b: np.ndarray) -> float:
    """Relative MSE mean((a − b)² / (b² + 10⁻²)) (Rousselle et al. 2011).

    >>> round(relmse(np.array([1.1]), np.array([1.0])), 6)   # 0.01 / 1.01
    0.009901
    """
    return float(np.mean((a - b) ** 2 / (b * b + 1e-2)))


def psnr(a: np.ndarray, b: np.ndarray) -> float:
    """Peak signal-to-noise ratio 10·log10(peak² / MSE) in dB with peak 1 (display white);
    +inf for identical images.

    >>> psnr(np.full(4, 0.01), np.zeros(4))   # MSE 1e-4
    40.0
    """
    mse = _mse(a, b)
    if mse == 0.0:
        return float("inf")
    return float(10.0 * np.log10(1.0 / mse))


def flip_map(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, float]:
    """Per-pixel HDR-FLIP error (H, W) in [0, 1] of test ``a`` against reference ``b``
    (linear RGB; one channel is used as grey) and its mean, by
    ``flip_evaluator.evaluate(b, a, "HDR")`` with its default exposure range and 67 pixels
    per degree (Andersson et al. 2021).

    Raises ImportError naming the extra when flip-evaluator is missing, and ValueError for
    what HDR-FLIP does not define: non-finite or negative values, or a black reference.
    """
    try:
        import flip_evaluator
    except ImportError:
        raise ImportError("the 'flip' metric needs the flip-evaluator package: "
                          "pip install 'raytrace[flip]'") from None
    a, b = (np.asarray(x, dtype=np.float32) for x in (a, b))
    if a.ndim == 2:
        a, b = a[..., None], b[..., None]
    if a.shape[-1] == 1:
        a, b = np.repeat(a, 3, axis=-1), np.repeat(b, 3, axis=-1)
    if a.shape[-1] != 3:
        raise ValueError(f"FLIP compares RGB images, got {a.shape[-1]} channels")
    for image, role in ((a, "test"), (b, "reference")):
        if not np.isfinite(image).all() or (image < 0).any():
            raise ValueError(f"FLIP needs finite values >= 0; the {role} image has "
                             f"{int((~np.isfinite(image) | (image < 0)).sum())} others")
    # Rec. 709 luminance, as FLIP computes its exposure range from the reference.
    luminance = b @ np.array([0.2126, 0.7152, 0.0722], dtype=np.float32)
    if not luminance.max() >= FLIP_MIN_LUMINANCE:
        raise ValueError(f"FLIP needs a reference that is not black (its largest luminance "
                         f"is {float(luminance.max()):.3g}, under {FLIP_MIN_LUMINANCE:.3g}); "
                         f"use another metric")
    error, mean, _ = flip_evaluator.evaluate(np.ascontiguousarray(b), np.ascontiguousarray(a),
                                             "HDR", applyMagma=False)
    return np.asarray(error, dtype=np.float64).reshape(a.shape[:2]), float(mean)


def flip(a: np.ndarray, b: np.ndarray) -> float:
    """Mean HDR-FLIP error of test ``a`` against reference ``b``; see :func:`flip_map`."""
    return flip_map(a, b)[1]


#: The metrics by name, in the order reports list them.
METRICS: dict[str, Metric] = {m.name: m for m in (
    Metric("rmse", rmse, "root mean squared error", 1e-3),
    Metric("mae", mae, "mean absolute error", 1e-3),
    Metric("max", max_abs, "largest absolute difference", 1e-3),
    Metric("relmse", relmse, "relative MSE, mean (a-b)^2 / (b^2 + 0.01)", 1e-3),
    Metric("psnr", psnr, "peak signal-to-noise ratio, peak 1", 60.0, higher_is_better=True,
           unit=" dB"),
    Metric("flip", flip, "mean HDR-FLIP error (needs raytrace[flip])", 0.01),
)}

#: The metrics every report computes: all but FLIP (an optional package, and slower).
BASIC = ("rmse", "mae", "max", "relmse", "psnr")


def get(name: str) -> Metric:
    """The metric called ``name``; a ValueError listing the valid names otherwise."""
    if name not in METRICS:
        raise ValueError(f"unknown metric {name!r} (choose from {', '.join(METRICS)})")
    return METRICS[name]


def check_threshold(value: float) -> float:
    """A metric threshold as a float: finite and >= 0, else a ValueError saying so."""
    try:
        t = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"must be a number, got {value!r}") from None
    if not np.isfinite(t) or t < 0:
        raise ValueError(f"must be a finite number >= 0, got {t:g}")
    return t


def heatmap(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, float]:
    """A diff heatmap: (H, W, 3) uint8 pixels and the difference that maps to white.

    Each pixel shows max over channels |a − b| divided by the image's largest finite one, on
    the "hot" ramp (black → red → yellow → white: r = 3t, g = 3t − 1, b = 3t − 2, clipped), so
    white is the worst pixel and black equal ones; a pixel where either image is not finite
    (and the two differ) is cyan. All black when the images are equal.
    """
    a, b = (np.asarray(x, dtype=np.float64) for x in (a, b))
    if a.ndim == 2:
        a, b = a[..., None], b[..., None]
    with np.errstate(invalid="ignore"):
        diff = np.abs(a - b)
    same = (a == b) | (np.isnan(a) & np.isnan(b))
    diff = np.where(same, 0.0, diff).max(axis=-1)
    finite = np.isfinite(diff)
    scale = float(diff[finite].max()) if finite.any() else 0.0
    t = np.where(finite, diff / scale if scale > 0 else 0.0, 0.0)
    rgb = np.clip(np.stack([3 * t, 3 * t - 1, 3 * t - 2], axis=-1), 0.0, 1.0)
    rgb[~finite] = (0.0, 1.0, 1.0)
    return np.round(rgb * 255).astype(np.uint8), scale
