"""Compiled camera rays: a pinhole's unit directions through pixel positions
(:func:`direction1`) and the jittered samples of a window (:func:`directions`); array
versions of the camera's draws (:func:`raytrace.kernels.core.camera_uniform`,
:func:`raytrace.kernels.core.pixel_offset`). Used by :mod:`raytrace.camera`."""

from __future__ import annotations

import math

from .core import camera_uniform, pixel_offset
from .jit import helper, kernel


@kernel
def uniform_rows(seed, index, stream, out):
    for i in range(index.shape[0]):
        out[i] = camera_uniform(seed, index[i], stream)


@kernel
def offset_rows(spp, k, seed, sample, sx, sy):
    for i in range(sample.shape[0]):
        sx[i], sy[i] = pixel_offset(spp, k, seed, sample[i], sample[i] % spp)


@helper
def direction1(x, y, pinhole):
    """The unit direction through image position (x, y) (pixels, (0, 0) the frame's top-left
    corner) of the frame of ``pinhole`` (a :class:`raytrace.kernels.records.Pinhole`: W × H
    pixels, tan(fov/2), the axes right, up, forward):
    ``(2x/W − 1)·tan(fov/2)·W/H·right + (1 − 2y/H)·tan(fov/2)·up + forward``, normalised (the
    image plane one unit along ``forward``)."""
    width, height, tan_half = pinhole.width, pinhole.height, pinhole.tan_half
    rx, ry, rz = pinhole.right
    ux, uy, uz = pinhole.up
    fx, fy, fz = pinhole.forward
    a = (2.0 * x / width - 1.0) * tan_half * (width / height)
    b = (1.0 - 2.0 * y / height) * tan_half
    dx = a * rx + b * ux + fx
    dy = a * ry + b * uy + fy
    dz = a * rz + b * uz + fz
    length = math.sqrt(dx * dx + dy * dy + dz * dz)
    return dx / length, dy / length, dz / length


@kernel
def directions_at_rows(x, y, pinhole, out):
    for j in range(out.shape[0]):
        out[j, 0], out[j, 1], out[j, 2] = direction1(x[j], y[j], pinhole)


@kernel
def directions(start, sampling, pinhole, window, out):
    """Unit directions of the samples ``start …`` of ``window`` (a
    :class:`raytrace.kernels.records.Window`: its columns ``x0 … x1 − 1`` from row ``y0`` on;
    the whole frame: 0, 0, ``width``) into ``out`` (n, 3): through
    ``x = (2(col + sx)/W − 1)·tan(fov/2)·W/H``, ``y = (1 − 2(row + sy)/H)·tan(fov/2)`` on the
    image plane one unit along ``forward`` (:func:`direction1` of ``pinhole``, a
    :class:`raytrace.kernels.records.Pinhole`), jittered by the sample's global index ``g``
    (``sampling``: a :class:`raytrace.kernels.records.Sampling`). The pixel (row, col), the
    sample's cell within it and ``g`` are counted along, not divided out of the sample index
    for every sample."""
    width, spp, k, seed = sampling.width, sampling.spp, sampling.k, sampling.seed
    x0, y0, x1 = window.x0, window.y0, window.x1
    cols = x1 - x0
    pixel, cell = start // spp, start % spp
    row, col = y0 + pixel // cols, x0 + pixel % cols
    g = (row * width + col) * spp + cell
    for j in range(out.shape[0]):
        sx, sy = pixel_offset(spp, k, seed, g, cell)
        out[j, 0], out[j, 1], out[j, 2] = direction1(col + sx, row + sy, pinhole)
        cell += 1
        g += 1
        if cell == spp:
            cell = 0
            col += 1
            if col == x1:
                col = x0
                row += 1
                g += (width - cols) * spp


@kernel
def tile_order(first, pixels, cols, spp, lanes, order):
    """The samples of pixels ``first … first + pixels − 1`` of a window ``cols`` wide
    (pixels counted row by row, ``spp`` samples each, a pixel's samples together) listed
    block by block into ``order`` (pass-local sample indices): blocks of h × w pixels, h =
    ⌊√p⌋ rows and w = ⌊p/h⌋ columns where p = ⌊lanes/spp⌋ pixels fill a packet of ``lanes``
    rays (4 × 2 pixels for 8 lanes at one sample a pixel, 4 × 4 for 16), bands of h rows from
    the window's top, blocks from the left. The rays of a packet then look through a compact
    patch of the image rather than a strip of a row, the shape Embree's COHERENT traversal
    takes fastest (Wald et al. 2001 trace 2 × 2 packets for the same reason). Where h is 1
    the order is the samples' own."""
    per = max(1, lanes // spp)
    h = int(math.sqrt(per))
    while (h + 1) * (h + 1) <= per:  # ⌊√p⌋ exactly
        h += 1
    w = per // h
    n = pixels * spp
    if h == 1:
        for j in range(n):
            order[j] = j
        return
    last = first + pixels
    j = 0
    for band in range(first // cols // h, (last - 1) // cols // h + 1):
        for c0 in range(0, cols, w):
            for r in range(band * h, band * h + h):
                for c in range(c0, min(c0 + w, cols)):
                    p = r * cols + c
                    if first <= p < last:
                        for k in range(spp):
                            order[j] = (p - first) * spp + k
                            j += 1
