"""AOVs (arbitrary output variables): what the camera ray of each pixel sample first hit.

Asked for by name (``render(..., aovs=["depth", "id"])``, ``--aov depth,id``), each is an
image beside the colour, written as extra channels of the same EXR (the channel names
compositors know: OpenEXR's "Technical Introduction", "Standard layers"; Nuke's and Blender's
depth ``Z``):

========  ==============================  ==================  ======================
name      channels, value                 a miss              spp > 1
========  ==============================  ==================  ======================
depth     ``Z``: distance from the        +inf                the nearest sample's
          camera along the ray (t)
normal    ``N.X N.Y N.Z``: world-space    0, 0, 0             mean of the samples
          shading normal, facing the ray
albedo    ``albedo.R .G .B``: kd at the   0, 0, 0             mean of the samples
          hit (a checker evaluated there)
id        ``id``: the object's index in   −1                  the nearest sample's
          the scene's ``objects``
uv        ``uv.U uv.V``: a mesh's texture 0, 0                mean of the samples
          coordinates (s, t) where its
          file gives them, else 0, 0
position  ``P.X P.Y P.Z``: the world-     0, 0, 0             the nearest sample's
          space hit point
samples   ``samples``: the pixel's camera     —                   their count
          samples (``spp``, or as many as
          ``aa = "noise"`` spent)
========  ==============================  ==================  ======================

Depth, id and position are not averaged (an average of two depths, two ids or two points on
different surfaces is neither): they are the sample with the smallest t (the first one on
ties), as a Z buffer keeps the nearest surface. Normal, albedo and uv are filtered like the
colour: the mean over the pixel's samples, misses counting as 0, so an edge pixel's normal is
shorter than 1. Only the camera rays' first hits count; nothing is computed or stored for an
AOV that was not asked for.

**Adding an AOV** is one entry in :data:`AOVS` and, in :mod:`raytrace.kernels.aov`, its kind
code in ``AOV_KINDS`` and its branch in ``aov_value1`` (docs/architecture.md, "Extending").
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np

from ..errors import SceneError
from ..kernels.aov import AOV_KINDS, MEAN, NEAREST
from ..kernels.records import (
    AOV_COLUMNS,
    AOV_COMBINE,
    AOV_COUNT,
    AOV_DISTANCE,
    AOV_FIRST,
    AOV_KIND,
    AOVLayout,
)


@dataclass(frozen=True)
class AOV:
    """One AOV: its EXR ``channels``, the value of a ``miss``, the numpy ``dtype`` of
    :meth:`raytrace.Image.aov` and how a pixel's samples ``combine`` ("nearest" or "mean")."""

    channels: tuple[str, ...]
    miss: float
    dtype: type
    combine: str


#: The AOVs by name, in the order their channels are written.
AOVS: dict[str, AOV] = {
    "depth": AOV(("Z",), np.inf, np.float32, "nearest"),
    "normal": AOV(("N.X", "N.Y", "N.Z"), 0.0, np.float32, "mean"),
    "albedo": AOV(("albedo.R", "albedo.G", "albedo.B"), 0.0, np.float32, "mean"),
    "id": AOV(("id",), -1.0, np.int32, "nearest"),
    "uv": AOV(("uv.U", "uv.V"), 0.0, np.float32, "mean"),
    "position": AOV(("P.X", "P.Y", "P.Z"), 0.0, np.float32, "nearest"),
    "samples": AOV(("samples",), 0.0, np.int32, "count"),
}


def check_aovs(names: str | Iterable[str] | None, key: str = "aovs") -> tuple[str, ...]:
    """The AOV names asked for (a comma-separated string or a list), checked, without
    repeats, in :data:`AOVS`' order; a :class:`SceneError` naming the valid ones otherwise."""
    if names is None:
        return ()
    if isinstance(names, str):
        names = [n.strip() for n in names.split(",")]
    try:
        names = list(names)
    except TypeError:
        raise SceneError(f"must be a list of AOV names, got {type(names).__name__}",
                         key) from None
    for n in names:
        if not isinstance(n, str) or n not in AOVS:
            raise SceneError(f"unknown AOV {n!r} (choose from {', '.join(AOVS)})", key)
    return tuple(n for n in AOVS if n in names)


def traced(names: tuple[str, ...]) -> tuple[str, ...]:
    """The AOVs of ``names`` that the kernels record at the camera rays' hits: all but
    ``samples``, each pixel's sample count, which the integrator writes itself."""
    return tuple(n for n in names if AOVS[n].combine != "count")


def layout(names: tuple[str, ...]) -> AOVLayout:
    """The columns of the AOVs ``names`` (checked, in :data:`AOVS`' order) in the kernels'
    per-sample and per-pixel tables: column ``AOV_DISTANCE`` (0) the hit's distance, then each
    AOV's channels; a row of the layout's table per AOV, its columns named by
    ``kernels.records`` (``AOV_KIND``, …)."""
    names = traced(names)
    table = np.zeros((len(names), AOV_COLUMNS), np.int64)
    miss, col = [np.inf], AOV_DISTANCE + 1
    for k, name in enumerate(names):
        a = AOVS[name]
        table[k, AOV_KIND], table[k, AOV_FIRST] = AOV_KINDS[name], col
        table[k, AOV_COUNT] = len(a.channels)
        table[k, AOV_COMBINE] = NEAREST if a.combine == "nearest" else MEAN
        miss += [a.miss] * len(a.channels)
        col += len(a.channels)
    return AOVLayout(table, np.array(miss, np.float64))


def columns(names: tuple[str, ...]) -> dict[str, slice]:
    """Each AOV's columns in the tables of :func:`layout` (``names``' order)."""
    names = traced(names)
    table = layout(names).table
    return {name: slice(int(row[AOV_FIRST]), int(row[AOV_FIRST] + row[AOV_COUNT]))
            for name, row in zip(names, table, strict=True)}


def images(pixels: np.ndarray, names: tuple[str, ...], shape: tuple[int, int]
           ) -> dict[str, np.ndarray]:
    """The AOV images (H, W) or (H, W, channels) in their dtypes from the per-pixel table
    ``pixels`` (H·W, columns) of :func:`layout` ``names``."""
    out = {}
    for name, cols in columns(names).items():
        a = AOVS[name]
        image = pixels[:, cols].astype(a.dtype)
        out[name] = image.reshape(shape) if len(a.channels) == 1 else image.reshape(
            *shape, len(a.channels))
    return out


def empty(name: str, shape: tuple[int, ...]) -> np.ndarray:
    """A (H, W) or (H, W, 3) image of AOV ``name`` filled with its miss value."""
    a = AOVS[name]
    full = shape if len(a.channels) == 1 else (*shape, len(a.channels))
    return np.full(full, a.miss, a.dtype)


def channels(name: str, image: np.ndarray) -> dict[str, np.ndarray]:
    """The EXR channels (float32, C-contiguous) of AOV ``name``'s image."""
    a = AOVS[name]
    if len(a.channels) == 1:
        return {a.channels[0]: np.ascontiguousarray(image, dtype=np.float32)}
    return {c: np.ascontiguousarray(image[..., i], dtype=np.float32)
            for i, c in enumerate(a.channels)}


def from_channels(ch: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """The AOVs whose channels are all in ``ch`` (EXR channel name → (H, W) array)."""
    out = {}
    for name, a in AOVS.items():
        if all(c in ch for c in a.channels):
            planes = [np.asarray(ch[c], dtype=np.float32) for c in a.channels]
            image = planes[0] if len(planes) == 1 else np.stack(planes, axis=-1)
            out[name] = image.astype(a.dtype)
    return out
