"""Image comparison: :func:`compare_images` measures an image against a reference (per-pixel
tolerances, metrics by name, the worst pixels) as a :class:`Comparison`; :func:`write_diff`
writes the diff heatmap. Reads EXRs and writes PNG codes only: no renderer, no tone mapping,
so ``raytrace compare`` starts quickly. :mod:`raytrace.testing` asserts with these."""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from . import metrics as _metrics
from .exr import read_exr
from .png import write_png_pixels

#: What the comparisons take: an Image (anything with an ``rgb`` array), an array, an EXR path.
ImageLike = Any | np.ndarray | str | os.PathLike


@dataclass
class Comparison:
    """What :func:`compare_images` measured.

    ``metrics`` maps metric names to values; ``bad`` counts the pixels with a channel off by
    more than ``atol + rtol·|expected|`` out of ``pixels``; ``worst`` lists the pixels that
    differ most beyond that tolerance (most first) as dicts with ``x``, ``y`` (column and row
    from the top left), ``actual`` and ``expected`` (per channel) and ``excess`` (the largest
    channel difference minus its tolerance; inf where one is not finite).
    """

    width: int
    height: int
    rtol: float
    atol: float
    metrics: dict[str, float]
    bad: int
    worst: list[dict] = field(default_factory=list)
    bad_mask: np.ndarray | None = field(default=None, repr=False)

    @property
    def pixels(self) -> int:
        return self.width * self.height

    def to_dict(self) -> dict:
        """A JSON-ready dict; a non-finite number (PSNR of equal images) is a string."""

        def num(v: float) -> float | str:
            return v if math.isfinite(v) else str(v)

        return {"width": self.width, "height": self.height, "rtol": self.rtol,
                "atol": self.atol, "metrics": {k: num(v) for k, v in self.metrics.items()},
                "bad_pixels": self.bad, "pixels": self.pixels,
                "worst": [{**w, "actual": [num(v) for v in w["actual"]],
                           "expected": [num(v) for v in w["expected"]],
                           "excess": num(w["excess"])} for w in self.worst]}


def load_image(image: ImageLike, role: str = "image") -> np.ndarray:
    """An :class:`~raytrace.film.image.Image` (anything with an ``rgb`` array), an array (H, W) or
    (H, W, C), or an EXR path as float64 (H, W, C);
    ``role`` names it in errors."""
    if hasattr(image, "rgb"):  # an Image
        rgb = np.asarray(image.rgb)
    elif isinstance(image, (str, os.PathLike)):
        if not Path(image).is_file():
            raise FileNotFoundError(f"{role}: no such EXR file: {image}")
        rgb, _ = read_exr(image)
    else:
        rgb = np.asarray(image)
    if rgb.ndim == 2:
        rgb = rgb[..., None]
    if rgb.ndim != 3 or not np.issubdtype(rgb.dtype, np.number):
        raise ValueError(f"{role}: expected an image of shape (H, W) or (H, W, C), "
                         f"got {rgb.dtype} {rgb.shape}")
    return rgb.astype(np.float64)


def compare_images(actual: ImageLike, expected: ImageLike, *, rtol: float = 0.0,
                   atol: float = 0.0, metrics: Sequence[str] = _metrics.BASIC,
                   worst: int = 5) -> Comparison:
    """Measure ``actual`` against ``expected`` (each an :class:`Image`, array or EXR path).

    A pixel is bad when a channel fails numpy's ``isclose(actual, expected, rtol, atol)``,
    which holds where ``|actual − expected| <= atol + rtol·|expected|``, NaN equal only to
    NaN, inf only to the same inf. ``metrics`` are names from
    :data:`raytrace.film.metrics.METRICS`, taken over every value (a non-finite one makes them nan
    or inf). The shapes must be equal (a ValueError says both otherwise).
    """
    a, e = load_image(actual, "actual"), load_image(expected, "expected")
    if a.shape != e.shape:
        raise ValueError(f"actual is {size(a)}, expected is {size(e)}")
    rtol, atol = float(rtol), float(atol)
    if not (rtol >= 0 and atol >= 0 and math.isfinite(rtol) and math.isfinite(atol)):
        raise ValueError(f"rtol and atol must be finite and >= 0, got {rtol!r}, {atol!r}")
    with np.errstate(invalid="ignore", over="ignore"):  # inf - inf: the metric is nan
        values = {name: _metrics.get(name).function(a, e) for name in metrics}
    close = np.isclose(a, e, rtol=rtol, atol=atol, equal_nan=True)
    bad_mask = ~close.all(axis=-1)
    identical = (a == e) | (np.isnan(a) & np.isnan(e))
    with np.errstate(invalid="ignore"):  # inf - inf: identical, masked below
        excess = np.abs(a - e) - (atol + rtol * np.abs(e))
    excess = np.where(identical, -np.inf, np.where(np.isnan(excess), np.inf, excess)).max(axis=-1)
    differ = ~identical.all(axis=-1)
    order = np.argsort(-np.where(differ, excess, -np.inf), axis=None, kind="stable")
    listed = []
    for flat in order[:worst]:
        y, x = divmod(int(flat), a.shape[1])
        if not differ[y, x]:
            break
        listed.append({"x": x, "y": y, "actual": a[y, x].tolist(),
                       "expected": e[y, x].tolist(), "excess": float(excess[y, x])})
    return Comparison(a.shape[1], a.shape[0], rtol, atol, values, int(bad_mask.sum()), listed,
                      bad_mask)


def size(a: np.ndarray) -> str:
    return f"{a.shape[1]}x{a.shape[0]}" + (f"x{a.shape[2]}" if a.shape[2] != 3 else "")


def write_diff(path: str | os.PathLike, actual: np.ndarray,
               expected: np.ndarray) -> tuple[np.ndarray, float]:
    """Write the diff heatmap PNG of :func:`raytrace.film.metrics.heatmap` atomically; return its
    pixels and the difference shown as white."""
    pixels, scale = _metrics.heatmap(actual, expected)
    write_png_pixels(path, pixels)
    return pixels, scale
