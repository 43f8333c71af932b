"""Compiled passes over ray batches (:class:`raytrace.rays.RayBatch`'s columns): counting kinds,
splitting hits from misses, gathering rows, and cutting a batch into chunks of whole samples.
Serial ``nogil`` kernels (:mod:`.jit`)."""

from __future__ import annotations

import math

import numpy as np

from .jit import kernel
from .kinds import CAMERA, REFLECTION, REFRACTION, SEE_THROUGH


@kernel
def count_kinds(kind, counts):
    """``counts[k] +=`` the number of rays of kind k (``np.bincount`` of an int8 column
    first converts it to int64: 180 µs against 15 µs for 65 536 rays)."""
    camera = reflection = refraction = see_through = 0  # locals: no store-to-load chain
    for i in range(kind.shape[0]):
        k = kind[i]
        camera += k == CAMERA
        reflection += k == REFLECTION
        refraction += k == REFRACTION
        see_through += k == SEE_THROUGH
    counts[CAMERA] += camera
    counts[REFLECTION] += reflection
    counts[REFRACTION] += refraction
    counts[SEE_THROUGH] += see_through


@kernel
def split_hits(t, found, missed):
    """The rows of the rays that hit something (finite ``t``) into the first rows of
    ``found``, the others into ``missed``, each in row order; returns how many hit (one pass
    instead of ``np.flatnonzero`` twice)."""
    k = m = 0
    for i in range(t.shape[0]):
        if math.isfinite(t[i]):
            found[k] = i
            k += 1
        else:
            missed[m] = i
            m += 1
    return k


@kernel
def take_rows(a, rows):
    """``a[rows]`` for a C-contiguous float64 (n, k) array and int64 ``rows`` (numpy's fancy
    indexing of 3-element rows took 4× as long: 0.90 against 0.23 ms for 98 304 of 131 072)."""
    out = np.empty((rows.shape[0], a.shape[1]))
    for j in range(rows.shape[0]):
        for c in range(a.shape[1]):
            out[j, c] = a[rows[j], c]
    return out


@kernel
def take_hits(rows, rays, hits, rays_out, hits_out):
    """The rays ``rows`` of a batch (a :class:`raytrace.kernels.records.Rays`) together with
    their ``hits`` (a :class:`raytrace.kernels.records.Hits`), in one pass, into ``rays_out``
    and ``hits_out`` (a ``Rays`` and a ``Hits``) of ``len(rows)`` rows each (the compaction to
    the rays that hit something; row-wise, so runs of ``rows`` can go to different
    threads)."""
    origin, direction, sample, weight = rays.origin, rays.direction, rays.sample, rays.weight
    origin_shape, kind = rays.origin_shape, rays.kind
    t, shape, triangle, uv = hits.t, hits.shape, hits.triangle, hits.uv
    o, d, s, w = rays_out.origin, rays_out.direction, rays_out.sample, rays_out.weight
    os_, kd = rays_out.origin_shape, rays_out.kind
    tt, sh, tri, b = hits_out.t, hits_out.shape, hits_out.triangle, hits_out.uv
    for j in range(rows.shape[0]):
        i = rows[j]
        for c in range(3):
            o[j, c], d[j, c], w[j, c] = origin[i, c], direction[i, c], weight[i, c]
        s[j], os_[j], kd[j] = sample[i], origin_shape[i], kind[i]
        tt[j], sh[j], tri[j] = t[i], shape[i], triangle[i]
        for c in range(uv.shape[1]):
            b[j, c] = uv[i, c]


@kernel
def gather_chunks(chunk, count, rays, out):
    """The rays of a batch (a :class:`raytrace.kernels.records.Rays`) regrouped by ``chunk`` (their
    chunk, ``0 … count − 1``, from :func:`sample_chunks`) into ``out`` (a ``Rays`` of as
    many rows): chunk 0's rays first, each chunk's in batch order (a stable counting sort,
    the order of ``np.argsort(chunk, kind="stable")``); returns the ``count + 1`` bounds of
    the chunks' rows, so each chunk is a slice of ``out`` (one pass for what was a sort, a
    search and a gather of every column per chunk)."""
    origin, direction, sample, weight = rays.origin, rays.direction, rays.sample, rays.weight
    origin_shape, kind = rays.origin_shape, rays.kind
    o, d, s, w = out.origin, out.direction, out.sample, out.weight
    os_, kd = out.origin_shape, out.kind
    bounds = np.zeros(count + 1, np.int64)
    for r in range(chunk.shape[0]):
        bounds[chunk[r] + 1] += 1
    for c in range(count):
        bounds[c + 1] += bounds[c]
    at = bounds[:-1].copy()  # the next free row of each chunk
    for r in range(chunk.shape[0]):
        j = at[chunk[r]]
        at[chunk[r]] = j + 1
        for c in range(3):
            o[j, c], d[j, c], w[j, c] = origin[r, c], direction[r, c], weight[r, c]
        s[j], os_[j], kd[j] = sample[r], origin_shape[r], kind[r]
    return bounds


@kernel
def sample_chunks(sample, samples, most, chunk):
    """Cut a batch into chunks of at most ``most`` rays that keep each pixel sample's rays
    together: ``chunk[r]`` = the chunk of ray r (samples ``0 … samples − 1`` in order, a new
    chunk where the next sample's rays would overflow the current one); returns how many.
    Finished chunk by chunk, a sample then gets its contributions in the same order as from
    the whole batch (the rays of one sample keep their batch order within their chunk, and
    their descendants stay in that chunk's line), so a pixel's float sums do not depend on
    where the batch was cut, nor on which samples share its pass. Only a sample with more
    than ``most`` rays of its own is cut (into chunks of ``most``, in batch order)."""
    n = sample.shape[0]
    count = np.zeros(samples, np.int64)
    for r in range(n):
        count[sample[r]] += 1
    first = np.zeros(samples, np.int64)  # the (first) chunk of each sample
    c = size = 0
    for s in range(samples):
        k = count[s]
        if k == 0:
            continue
        if size > 0 and size + k > most:
            c += 1
            size = 0
        first[s] = c
        if k > most:  # alone over the limit: chunks of its own
            c += (k + most - 1) // most
        else:
            size += k
    seen = np.zeros(samples, np.int64)
    for r in range(n):
        s = sample[r]
        chunk[r] = first[s] + (seen[s] // most if count[s] > most else 0)
        seen[s] += 1
    return c + (1 if size > 0 else 0)
