"""The image-sampling choices of ``[render]``, by name, without importing the kernels.

* ``filter``: :data:`FILTERS`, the pixel reconstruction filters with their radius in pixels
  (the formulas and the kernel: :mod:`raytrace.film.filters`);
* ``aa``: :data:`AA_MODES`, uniform stratified samples, adaptive corner refinement
  (:mod:`raytrace.adaptive`) or noise-driven sampling (:mod:`raytrace.noise`);
* ``texture_filter``: :data:`TEXTURE_FILTERS`, bilinear or trilinear (mip-mapped by ray
  cones, :mod:`raytrace.mipmap`) image-texture lookups.

Scenes are loaded and checked without numba: this module is all they import of the two.
"""

from __future__ import annotations

import math
from typing import NamedTuple

from .errors import SceneError
from .kernels.kinds import BOX, GAUSSIAN, MITCHELL, TENT  # noqa: F401


class Filter(NamedTuple):
    """A filter's kernel code (:func:`raytrace.film.filters.profile1`) and radius (pixels)."""

    code: int
    radius: float


#: The filters by their ``[render] filter`` name: radii of Mitsuba's tent and pbrt-v4's
#: Gaussian and Mitchell–Netravali defaults.
FILTERS = {"box": Filter(BOX, 0.5), "tent": Filter(TENT, 1.0),
           "gaussian": Filter(GAUSSIAN, 1.5), "mitchell": Filter(MITCHELL, 2.0)}
#: The anti-aliasing modes by their ``[render] aa`` name.
AA_MODES = {"uniform": "spp stratified jittered samples a pixel",
            "adaptive": "pixel corners, cells halved where their corners differ",
            "noise": "samples doubled where a pixel's noise is over noise_threshold"}
#: Noise-driven sampling's first round, samples a pixel, where ``min_spp`` is not given: by
#: threshold (as Cycles' rule reads the two streams' difference, 4 samples a stream), and by
#: target error or time, whose allocation reads each pixel's sample variance and gains from
#: starting lower (docs/sampling.md, "Stopping by error or time").
MIN_SPP = 8
MIN_SPP_GOAL = 4
#: The texture filters by their ``[render] texture_filter`` name (:mod:`raytrace.mipmap`,
#: :mod:`raytrace.kernels.mip`).
TEXTURE_FILTERS = {
    "bilinear": "the four texels around the point, whatever the footprint (aliases when "
                "minified)",
    "trilinear": "a mip-map level by the ray cone's footprint, bilinear in the two nearest "
                 "levels and linear between them",
}


def check_filter(name: object, key: str = "render.filter") -> str:
    """``name`` if it is one of :data:`FILTERS`, else a SceneError listing them."""
    if not isinstance(name, str) or name not in FILTERS:
        raise SceneError(f"unknown filter {name!r} (choose from {', '.join(FILTERS)})", key)
    return name


def check_aa(name: object, key: str = "render.aa") -> str:
    """``name`` if it is one of :data:`AA_MODES`, else a SceneError listing them."""
    if not isinstance(name, str) or name not in AA_MODES:
        raise SceneError(f"unknown anti-aliasing {name!r} (choose from "
                         f"{', '.join(AA_MODES)})", key)
    return name


def margin(name: str) -> int:
    """Pixels around a pixel whose samples its filter can reach: the largest ``m`` with a
    sample of pixel ``p + m`` (in ``[p + m, p + m + 1)``) nearer than the radius to
    ``p + ½``, ``⌈r + ½⌉ − 1`` (0 for the box)."""
    return math.ceil(FILTERS[name].radius + 0.5) - 1
