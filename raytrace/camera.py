"""Camera rays: a pinhole camera, pixel (0, 0) top-left, rows going down.

With ``spp = 1`` each ray passes through its pixel's centre. With ``spp = k²`` the pixel is cut
into a k×k grid and each sample is jittered within its cell (stratified sampling); other
counts jitter over the whole pixel. The jitter is a hash of (seed, sample index), so an image
does not depend on how it is split into passes or threads.

A render may cover a window of the frame only (a crop, pbrt's ``--pixelbounds``): its samples
are numbered within the window (``local``), but every ray, and the jitter, is that of the same
sample of the full frame (its ``global`` index ``pixel·spp + k``, :func:`global_samples`), so a
crop's pixels are those of the full render.
"""

from __future__ import annotations

import math

import numpy as np

from .core import camera_uniform, pixel_offset
from .jit import kernel
from .rays import CAMERA, NO_SHAPE, RayBatch
from .scene import Camera


@kernel
def _uniform_rows(seed, index, stream, out):
    for i in range(index.shape[0]):
        out[i] = camera_uniform(seed, index[i], stream)


@kernel
def _offset_rows(spp, k, seed, sample, sx, sy):
    for i in range(sample.shape[0]):
        sx[i], sy[i] = pixel_offset(spp, k, seed, sample[i], sample[i] % spp)


@kernel
def direction1(x, y, size, view):
    """The unit direction through image position (x, y) (pixels, (0, 0) the frame's top-left
    corner) of a frame of ``size`` = (width, height) seen with ``view`` = (tan(fov/2), right,
    up, forward) (3-tuples): ``(2x/W − 1)·tan(fov/2)·W/H·right + (1 − 2y/H)·tan(fov/2)·up +
    forward``, normalised (the image plane one unit along ``forward``)."""
    width, height = size
    tan_half, right, up, forward = view
    rx, ry, rz = right
    ux, uy, uz = up
    fx, fy, fz = forward
    a = (2.0 * x / width - 1.0) * tan_half * (width / height)
    b = (1.0 - 2.0 * y / height) * tan_half
    dx = a * rx + b * ux + fx
    dy = a * ry + b * uy + fy
    dz = a * rz + b * uz + fz
    length = math.sqrt(dx * dx + dy * dy + dz * dz)
    return dx / length, dy / length, dz / length


@kernel
def _directions_at(x, y, size, view, out):
    for j in range(out.shape[0]):
        out[j, 0], out[j, 1], out[j, 2] = direction1(x[j], y[j], size, view)


@kernel
def _directions(start, frame, view, window, out):
    """Unit directions of the samples ``start …`` of the window of columns ``x0 … x1 − 1``
    from row ``y0`` on (the whole frame: 0, 0, ``width``) into ``out`` (n, 3): through
    ``x = (2(col + sx)/W − 1)·tan(fov/2)·W/H``, ``y = (1 − 2(row + sy)/H)·tan(fov/2)`` on the
    image plane one unit along ``forward``, jittered by the sample's global index ``g``. The
    pixel (row, col), the sample's cell within it and ``g`` are counted along, not divided
    out of the sample index for every sample. ``frame`` = (width, height, spp, k (the
    stratification grid, :func:`grid`), seed); ``view`` = (tan(fov/2), right, up, forward)
    as arrays; ``window`` = (x0, y0, x1)."""
    width, height, spp, k, seed = frame
    tan_half, right, up, forward = view
    x0, y0, x1 = window
    view3 = (tan_half, (right[0], right[1], right[2]), (up[0], up[1], up[2]),
             (forward[0], forward[1], forward[2]))
    cols = x1 - x0
    pixel, cell = start // spp, start % spp
    row, col = y0 + pixel // cols, x0 + pixel % cols
    g = (row * width + col) * spp + cell
    for j in range(out.shape[0]):
        sx, sy = pixel_offset(spp, k, seed, g, cell)
        out[j, 0], out[j, 1], out[j, 2] = direction1(col + sx, row + sy, (width, height),
                                                     view3)
        cell += 1
        g += 1
        if cell == spp:
            cell = 0
            col += 1
            if col == x1:
                col = x0
                row += 1
                g += (width - cols) * spp


def grid(spp: int) -> int:
    """k for a k×k stratified grid of ``spp`` samples, 0 when spp is not a square."""
    k = math.isqrt(spp)
    return k if k * k == spp else 0


def hash_uniform(seed: int, index: np.ndarray, stream: int) -> np.ndarray:
    """Uniform floats in [0, 1) from SplitMix64 of (seed, index, stream) (Steele et al. 2014)."""
    index = np.ascontiguousarray(index, dtype=np.int64)
    out = np.empty(index.shape)
    _uniform_rows(seed, index.reshape(-1), stream, out.reshape(-1))
    return out


def sample_offsets(spp: int, seed: int, sample: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Positions (sx, sy) in [0, 1)² inside the pixel of global sample indices ``sample``."""
    sample = np.ascontiguousarray(sample, dtype=np.int64).reshape(-1)
    sx, sy = np.empty(len(sample)), np.empty(len(sample))
    _offset_rows(spp, grid(spp), seed, sample, sx, sy)
    return sx, sy


def camera_rays(camera: Camera, frame, start: int, stop: int, *,
                columns: RayBatch | None = None, direction: np.ndarray | None = None,
                window: tuple[int, int, int, int] | None = None) -> RayBatch:
    """Rays of samples ``start..stop-1`` (sample = pixel·spp + k, pixels counted row by row
    in the crop window (x0, y0, x1, y1), half-open, or the whole frame), from the origin: the
    scene is camera-relative. ``frame`` has the render's ``width``, ``height``, ``spp``,
    ``seed`` and ``crop`` (a :class:`raytrace.integrator.RenderOptions`; a
    :class:`raytrace.scene.RenderSettings` renders the whole frame); ``window``, where given,
    is the window traced instead of the crop (a crop widened by a filter's reach).

    ``columns``: a batch of at least ``stop − start`` rows from :func:`camera_columns` whose
    columns other than the direction are reused (views of its first rows); ``direction``: an
    (n, 3) float64 array to write the directions into. Both new when not given.
    """
    n = stop - start
    if direction is None:
        direction = np.empty((n, 3))
    camera_directions(camera, frame.width, frame.height, frame.spp, frame.seed, start,
                      direction, window if window is not None else getattr(frame, "crop", None))
    if columns is None:
        columns = camera_columns(n)
    return RayBatch(origin=columns.origin[:n], direction=direction, sample=columns.sample[:n],
                    weight=columns.weight[:n], depth=0, origin_shape=columns.origin_shape[:n],
                    kind=columns.kind[:n])


def camera_directions(camera: Camera, width: int, height: int, spp: int, seed: int,
                      start: int, out: np.ndarray,
                      window: tuple[int, int, int, int] | None = None) -> None:
    """Unit directions (n, 3) of samples ``start …`` of ``window`` (the whole frame when
    None) into ``out``."""
    tan_half = math.tan(math.radians(camera.fov) / 2.0)
    right, up, forward = (np.ascontiguousarray(v, dtype=np.float64) for v in camera.basis())
    x0, y0, x1, _ = window or (0, 0, width, height)
    _directions(start, (width, height, spp, grid(spp), seed), (tan_half, right, up, forward),
                (x0, y0, x1), out)


def directions_at(camera: Camera, width: int, height: int, x: np.ndarray,
                  y: np.ndarray) -> np.ndarray:
    """Unit directions (n, 3) through image positions ``x``, ``y`` (n,) (pixels of the
    ``width`` × ``height`` frame; :func:`direction1`)."""
    tan_half = math.tan(math.radians(camera.fov) / 2.0)
    basis = tuple(tuple(float(c) for c in v) for v in camera.basis())
    out = np.empty((len(x), 3))
    _directions_at(np.ascontiguousarray(x, np.float64), np.ascontiguousarray(y, np.float64),
                   (width, height), (tan_half, *basis), out)
    return out


def global_samples(local: np.ndarray, width: int, spp: int,
                   window: tuple[int, int, int, int] | None) -> np.ndarray:
    """Global sample indices ``pixel·spp + k`` of the full ``width``-wide frame, (n,) int64,
    of samples ``local`` (n,) numbered within ``window`` = (x0, y0, x1, y1); the same
    indices when ``window`` is None."""
    local = np.asarray(local, dtype=np.int64)
    if window is None:
        return local
    x0, y0, x1, _ = window
    pixel, cell = np.divmod(local, spp)
    row, col = np.divmod(pixel, x1 - x0)
    return ((row + y0) * width + col + x0) * spp + cell


def camera_columns(n: int) -> RayBatch:
    """The columns every pass's camera rays share, for ``n`` rays: origin 0 (the scene is
    camera-relative), sample 0…n−1 within the pass, weight 1, no start shape, kind CAMERA; the
    direction column is empty. Nothing writes into a batch's columns once it is made (each
    step writes new arrays), so the integrator keeps one of these per thread for all its
    passes instead of filling 65 bytes a ray anew."""
    return RayBatch(origin=np.zeros((n, 3)), direction=np.zeros((0, 3)),
                    sample=np.arange(n, dtype=np.int64), weight=np.ones((n, 3)), depth=0,
                    origin_shape=np.full(n, NO_SHAPE, np.int64),
                    kind=np.full(n, CAMERA, np.int8))
