"""Compiled camera rays: a pinhole's unit directions through pixel positions
(:func:`direction1`) and the jittered samples of a window (:func:`directions`); array
versions of the camera's draws (:func:`raytrace.kernels.core.camera_uniform`,
:func:`raytrace.kernels.core.pixel_offset`); the Owen-scrambled Sobol points of noise-driven
sampling's streams (:func:`stream_offset_rows`). Used by :mod:`raytrace.camera` and
:mod:`raytrace.noise`."""

from __future__ import annotations

import math

import numpy as np

from .core import camera_uniform, pixel_offset
from .jit import helper, kernel

#: The low 32 bits: the stream points' integer arithmetic is 32-bit, done in int64 and masked
#: (every product below stays under 2⁶³).
MASK32 = 0xFFFFFFFF
#: Direction numbers of Sobol's second dimension (primitive polynomial x + 1, all initial
#: m = 1): v₀ = 2³¹, v_i = v_{i−1} ⊕ (v_{i−1} >> 1) (Joe & Kuo's table, dimension 2).
SOBOL_DIRECTIONS = np.empty(32, np.int64)
SOBOL_DIRECTIONS[0] = 1 << 31
for _bit in range(1, 32):
    SOBOL_DIRECTIONS[_bit] = SOBOL_DIRECTIONS[_bit - 1] ^ (SOBOL_DIRECTIONS[_bit - 1] >> 1)
del _bit


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


# -- noise-driven sampling's streams -------------------------------------------------------
@helper
def reverse_bits1(x):
    """The 32 bits of ``x`` (an integer in [0, 2³²)) in reverse order."""
    x = ((x >> 1) & 0x55555555) | ((x & 0x55555555) << 1)
    x = ((x >> 2) & 0x33333333) | ((x & 0x33333333) << 2)
    x = ((x >> 4) & 0x0F0F0F0F) | ((x & 0x0F0F0F0F) << 4)
    x = ((x >> 8) & 0x00FF00FF) | ((x & 0x00FF00FF) << 8)
    return ((x >> 16) | (x << 16)) & MASK32


@helper
def owen1(x, seed):
    """A nested uniform (Owen) scramble of the 32-bit fraction ``x`` by ``seed`` (both in
    [0, 2³²)), Burley's way ("Practical Hash-based Owen Scrambling", JCGT 9(4), 2020, listing
    3): the bits reversed, a hash in which each bit is flipped by a function of the bits below
    it, reversed back, so each bit of ``x`` is flipped by a hash of the bits above it. The
    hash is Vegdahl's improvement of Laine and Karras's ("Building a Better LK Hash", 2021:
    xor-multiplies by even constants and a multiply by an odd one, each of which moves
    information only upward); Burley's original constants left a 10×10 histogram of 20 000
    streams' first points 4.9σ off uniform in one bin."""
    v = reverse_bits1(x)
    v ^= (v * 0x3D20ADEA) & MASK32
    v = (v + seed) & MASK32
    v = (v * ((seed >> 16) | 1)) & MASK32
    v ^= (v * 0x05526C56) & MASK32
    v ^= (v * 0x53A22864) & MASK32
    return reverse_bits1(v)


@helper
def sobol1(index):
    """Point ``index`` (in [0, 2³²)) of the (0, 2)-sequence of Sobol's first two dimensions,
    as 32-bit fractions: van der Corput's radical inverse and the XOR of
    :data:`SOBOL_DIRECTIONS` over ``index``'s set bits."""
    y, bits, bit = 0, index, 0
    while bits:
        if bits & 1:
            y ^= SOBOL_DIRECTIONS[bit]
        bits >>= 1
        bit += 1
    return reverse_bits1(index), y


@helper
def stream_seed1(seed, stream_id, axis):
    """The 32-bit scrambling seed of axis ``axis`` (0: x, 1: y) of stream ``stream_id``:
    ⌊2³²·u⌋ of the camera's draw u (:func:`raytrace.kernels.core.camera_uniform`) of the
    render's ``seed``."""
    return int(math.floor(camera_uniform(seed, stream_id, axis) * 4294967296.0))


@kernel
def stream_offset_rows(seed, stream_id, k, sx, sy):
    """Positions (sx, sy) in [0, 1)² inside the pixel of sample ``k[i]`` of stream
    ``stream_id[i]``: the Owen-scrambled (:func:`owen1`, each axis by its
    :func:`stream_seed1`) Sobol point ``k[i]`` (:func:`sobol1`)."""
    for i in range(k.shape[0]):
        ux, uy = sobol1(k[i] & MASK32)
        sid = stream_id[i]
        sx[i] = owen1(ux, stream_seed1(seed, sid, 0)) * 2.0**-32
        sy[i] = owen1(uy, stream_seed1(seed, sid, 1)) * 2.0**-32


@kernel
def sobol_rows(index, x, y):
    """:func:`sobol1` of each ``index[i]``: its two 32-bit fractions (integers) into ``x``
    and ``y`` (tests)."""
    for i in range(index.shape[0]):
        x[i], y[i] = sobol1(index[i] & MASK32)
