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

from .kernels.camera import (
    block_shape,
    directions,
    directions_at_rows,
    frame_packets,
    offset_rows,
    own_rays,
    uniform_rows,
)
from .kernels.records import CameraPackets, Pinhole, Sampling, Window
from .rays import CAMERA, NO_SHAPE, RayBatch
from .scene import Camera


def grid(spp: int) -> int:
    """k for a k×k stratified grid of ``spp`` samples, 0 when spp is not a square."""
    k = math.isqrt(spp)
    return k if k * k == spp else 0


def hash_uniform(seed: int, index: np.ndarray, stream: int) -> np.ndarray:
    """Uniform floats in [0, 1) from SplitMix64 of (seed, index, stream) (Steele et al. 2014)."""
    index = np.ascontiguousarray(index, dtype=np.int64)
    out = np.empty(index.shape)
    uniform_rows(seed, index.reshape(-1), stream, out.reshape(-1))
    return out


def sample_offsets(spp: int, seed: int, sample: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Positions (sx, sy) in [0, 1)² inside the pixel of global sample indices ``sample``."""
    sample = np.ascontiguousarray(sample, dtype=np.int64).reshape(-1)
    sx, sy = np.empty(len(sample)), np.empty(len(sample))
    offset_rows(spp, grid(spp), seed, sample, sx, sy)
    return sx, sy


def camera_rays(camera: Camera | Pinhole, frame, start: int, stop: int, *,
                columns: RayBatch | None = None, direction: np.ndarray | None = None,
                window: tuple[int, int, int, int] | None = None,
                lanes: int = 0) -> RayBatch:
    """Rays of samples ``start..stop-1`` (sample = pixel·spp + k, pixels counted row by row
    in the crop window (x0, y0, x1, y1), half-open, or the whole frame), from the origin: the
    scene is camera-relative. ``frame`` has the render's ``width``, ``height``, ``spp``,
    ``seed`` and ``crop`` (a :class:`raytrace.integrator.RenderOptions`; a
    :class:`raytrace.scene.RenderSettings` renders the whole frame); ``window``, where given,
    is the window traced instead of the crop (a crop widened by a filter's reach).

    ``camera``: the scene's camera, or the frame as it sees it (:func:`pinhole`), made once
    by a caller that traces many passes. ``columns``: a batch of at least ``stop − start``
    rows from :func:`camera_columns` whose columns other than the direction are reused
    (views of its first rows); ``direction``: an (n, 3) float64 array to write the
    directions into. Both new when not given.

    ``lanes``: the rays go in packets of that many, blocks of the frame's pixels
    (:func:`packets`), in the order of their packets, each ray's ``sample`` its sample's
    index (every sum is kept by sample, so the order changes no pixel); where every slot
    of the packets is the range's own (whole blocks), the batch takes the packets'
    directions and samples themselves and ``direction`` is left unwritten; 0: in sample
    order, in plain packets.
    """
    n = stop - start
    if direction is None:
        direction = np.empty((n, 3))
    window = window if window is not None else getattr(frame, "crop", None)
    if columns is None:
        columns = camera_columns(n)
    sample, found = columns.sample[:n], None
    if lanes and n:
        found = packets(camera, frame, start, stop, window, lanes)
        if len(found.sample) == n:  # (whole blocks, as a pass of whole bands holds) all ours
            sample, direction = found.sample, found.direction
        else:
            sample = np.empty(n, np.int64)
            own_rays(found, sample, direction)
    else:
        camera_directions(camera, frame.width, frame.height, frame.spp, frame.seed, start,
                          direction, window)
    return RayBatch(origin=columns.origin[:n], direction=direction, sample=sample,
                    weight=columns.weight[:n], depth=0, origin_shape=columns.origin_shape[:n],
                    kind=columns.kind[:n], packets=found)


def packets(camera: Camera | Pinhole, frame, start: int, stop: int,
            window: tuple[int, int, int, int] | None, lanes: int) -> CameraPackets:
    """The COHERENT packets of ``lanes`` rays that samples ``start..stop-1`` of ``window``
    (None: the frame) go in (:func:`raytrace.kernels.camera.frame_packets`): each a block of
    the frame's pixels, the same rays whichever crop, pass or tile traces it, the samples of
    a block outside the range included; ``camera`` and ``frame`` as :func:`camera_rays`
    takes them."""
    x0, y0, x1, y1 = window or (0, 0, frame.width, frame.height)
    h, w = block_shape(frame.spp, lanes)
    per_row = x1 - x0
    bands = ((y0 + (stop - 1) // frame.spp // per_row) // h
             - (y0 + start // frame.spp // per_row) // h + 1)
    blocks = bands * ((x1 - 1) // w - x0 // w + 1)
    slots = h * w * frame.spp  # a block's
    room = CameraPackets(np.empty((blocks * slots, 3)), np.empty(blocks * slots, np.int64),
                         np.empty(blocks * -(-slots // lanes) + 1, np.int64))
    m, k = frame_packets(start, stop, Window(x0, y0, x1, y1),
                         Sampling(frame.width, frame.spp, grid(frame.spp), frame.seed),
                         pinhole(camera, frame.width, frame.height), lanes, room)
    return CameraPackets(room.direction[:m], room.sample[:m], room.bounds[:k + 1])


def camera_directions(camera: Camera | Pinhole, width: int, height: int, spp: int, seed: int,
                      start: int, out: np.ndarray,
                      window: tuple[int, int, int, int] | None = None) -> None:
    """Unit directions (n, 3) of samples ``start …`` of ``window`` (the whole frame when
    None) into ``out``; ``camera`` as :func:`camera_rays` takes it."""
    directions(start, Sampling(width, spp, grid(spp), seed), pinhole(camera, width, height),
               Window(*(window or (0, 0, width, height))), out)


def directions_at(camera: Camera | Pinhole, width: int, height: int, x: np.ndarray,
                  y: np.ndarray) -> np.ndarray:
    """Unit directions (n, 3) through image positions ``x``, ``y`` (n,) (pixels of the
    ``width`` × ``height`` frame; :func:`raytrace.kernels.camera.direction1`); ``camera`` as
    :func:`camera_rays` takes it."""
    out = np.empty((len(x), 3))
    directions_at_rows(np.ascontiguousarray(x, np.float64), np.ascontiguousarray(y, np.float64),
                       pinhole(camera, width, height), out)
    return out


def pinhole(camera: Camera | Pinhole, width: int, height: int) -> Pinhole:
    """The ``width`` × ``height`` frame as ``camera`` sees it, as the kernels take it:
    tan(fov/2) and the camera's unit axes (:meth:`raytrace.scene.Camera.basis`); a
    :class:`Pinhole` is that already (made by a caller for every pass of a frame)."""
    if isinstance(camera, Pinhole):
        return camera
    right, up, forward = (tuple(float(c) for c in v) for v in camera.basis())
    return Pinhole(width, height, math.tan(math.radians(camera.fov) / 2.0), right, up, forward)


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
