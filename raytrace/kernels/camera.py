"""Compiled camera rays: a pinhole's unit directions through pixel positions
(:func:`direction1`) and the jittered samples of a window (:func:`directions`); array
versions of the camera's draws (:func:`raytrace.kernels.core.camera_uniform`,
:func:`raytrace.kernels.core.pixel_offset`). Used by :mod:`raytrace.camera`."""

from __future__ import annotations

import math

from .core import camera_uniform, pixel_offset
from .jit import helper, inline, kernel


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


@inline
def block_shape(spp, lanes):
    """The pixels (h rows, w columns) of a block of camera rays that fills a packet of
    ``lanes`` rays at ``spp`` samples a pixel: h = ⌊√p⌋ and w = ⌊p/h⌋ where p = ⌊lanes/spp⌋
    (at least 1): 2 rows of 4 pixels for 8 lanes at one sample a pixel, 4 × 4 for 16. The rays of
    a packet then look through a compact patch of the image rather than a strip of a row, the
    shape Embree's COHERENT traversal takes fastest (Wald et al. 2001 trace 2 × 2 packets for
    the same reason)."""
    per = max(1, lanes // spp)
    h = int(math.sqrt(per))
    while (h + 1) * (h + 1) <= per:  # ⌊√p⌋ exactly
        h += 1
    while h * h > per:
        h -= 1
    return h, per // h


@kernel
def frame_packets(start, stop, window, sampling, pinhole, lanes, out):
    """The camera packets of samples ``start … stop − 1`` of ``window`` (a
    :class:`raytrace.kernels.records.Window`; samples numbered pixel by pixel, row by row,
    ``spp`` a pixel, as :func:`directions` numbers them) of the frame of ``pinhole`` (a
    :class:`raytrace.kernels.records.Pinhole`; ``sampling``: a
    :class:`raytrace.kernels.records.Sampling`) into ``out`` (a
    :class:`raytrace.kernels.records.CameraPackets`); returns how many slots and packets were
    written.

    The frame is cut into blocks of h × w pixels (:func:`block_shape`) from its top-left
    corner, whatever the window, and each block's samples (its pixels row by row, a pixel's
    samples in order) into packets of at most ``lanes``: every block that holds one of the
    samples is listed whole, block by block (bands of h rows from the top, blocks from the
    left): ``out.direction`` each slot's unit direction (as :func:`directions` makes it)
    and ``out.sample`` its index within ``start … stop − 1``, or −1 for a sample outside
    them (traced with its packet, then dropped); ``out.bounds[i]`` is where packet i starts.
    A packet is then the same rays whichever crop, pass or tile traces it, so a COHERENT
    answer, which may depend on the packet's other rays, does not depend on those."""
    spp, width, height, k, seed = (sampling.spp, sampling.width, pinhole.height, sampling.k,
                                   sampling.seed)
    x0, y0, x1, y1 = window.x0, window.y0, window.x1, window.y1
    cols = x1 - x0
    h, w = block_shape(spp, lanes)
    top, bottom = y0 + start // spp // cols, y0 + (stop - 1) // spp // cols
    m = n = 0
    out.bounds[0] = 0
    for band in range(top // h, bottom // h + 1):
        for c0 in range(x0 // w * w, x1, w):
            chunk, real = m, False  # the open packet's first slot, whether it holds one
            for r in range(band * h, min(band * h + h, height)):
                for c in range(c0, min(c0 + w, width)):
                    inside = y0 <= r < y1 and x0 <= c < x1
                    first = ((r - y0) * cols + c - x0) * spp - start
                    for cell in range(spp):
                        s = first + cell
                        own = inside and 0 <= s < stop - start
                        g = (r * width + c) * spp + cell
                        sx, sy = pixel_offset(spp, k, seed, g, cell)
                        out.direction[m, 0], out.direction[m, 1], out.direction[m, 2] = (
                            direction1(c + sx, r + sy, pinhole))
                        out.sample[m] = s if own else -1
                        real = real or own
                        m += 1
                        if m - chunk == lanes:  # a packet is full: kept if one is ours
                            if real:
                                n += 1
                                out.bounds[n] = m
                            else:
                                m = chunk
                            chunk, real = m, False
            if m > chunk:  # the block's last packet
                if real:
                    n += 1
                    out.bounds[n] = m
                else:
                    m = chunk
    return m, n


@kernel
def own_rays(packets, sample, direction):
    """The pass's own rays of ``packets`` (a :class:`raytrace.kernels.records.CameraPackets`,
    :func:`frame_packets`), in packet order: each one's sample into ``sample`` and direction
    into ``direction``; returns how many."""
    j = 0
    for i in range(packets.sample.shape[0]):
        if packets.sample[i] >= 0:
            sample[j] = packets.sample[i]
            for c in range(3):
                direction[j, c] = packets.direction[i, c]
            j += 1
    return j


@kernel
def own_hits(packets, hits, out):
    """The hits ``hits`` of every slot of ``packets`` (:func:`frame_packets`) that is the
    pass's own, in order, into ``out`` (both :class:`raytrace.kernels.records.Hits`): the
    hits of the batch :func:`own_rays` made."""
    j = 0
    for i in range(packets.sample.shape[0]):
        if packets.sample[i] >= 0:
            out.t[j], out.shape[j], out.triangle[j] = hits.t[i], hits.shape[i], hits.triangle[i]
            out.uv[j, 0], out.uv[j, 1] = hits.uv[i, 0], hits.uv[i, 1]
            j += 1


@kernel
def pixel_packets(bounds, lanes, out):
    """Where each packet of at most ``lanes`` consecutive camera rays starts, for rays laid
    out pixel by pixel (``bounds`` (p + 1,) int64: where each pixel's rays start, then their
    count; a pixel may have none), into ``out`` (at least p + ⌈n/lanes⌉ + 1 rows); returns
    how many packets (``out[k]`` is then n). No packet holds two pixels' rays, so a packet is
    the same rays whichever pass holds its pixel: the samples of a noise-driven round
    (``raytrace.noise.plan``), cut into passes at pixel bounds."""
    k = 0
    for p in range(bounds.shape[0] - 1):
        for first in range(bounds[p], bounds[p + 1], lanes):
            out[k] = first
            k += 1
    out[k] = bounds[bounds.shape[0] - 1]
    return k
