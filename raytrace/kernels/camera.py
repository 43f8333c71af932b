"""Compiled camera rays: a pinhole's unit directions through pixel positions
(:func:`direction1`) and the jittered samples of a window (:func:`directions`); array
versions of the camera's draws (:func:`raytrace.kernels.core.camera_uniform`,
:func:`raytrace.kernels.core.pixel_offset`). Used by :mod:`raytrace.camera`."""

from __future__ import annotations

import math

from .core import camera_uniform, pixel_offset
from .jit import kernel


@kernel
def uniform_rows(seed, index, stream, out):
    for i in range(index.shape[0]):
        out[i] = camera_uniform(seed, index[i], stream)


@kernel
def offset_rows(spp, k, seed, sample, sx, sy):
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
def directions_at_rows(x, y, size, view, out):
    for j in range(out.shape[0]):
        out[j, 0], out[j, 1], out[j, 2] = direction1(x[j], y[j], size, view)


@kernel
def directions(start, frame, view, window, out):
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
