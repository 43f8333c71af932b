"""The per-sample arithmetic of noise-driven sampling (:mod:`raytrace.noise`): each pixel's
Owen-scrambled Sobol points (:func:`round_points`), each round's samples added to their
pixel's quarter sums and running moments (:func:`add_round`), the round's statistics in
one pass over the pixels each (:func:`pixel_halves`, :func:`quarter_falls`,
:func:`half_noise`) and the next round's doublings in order of priority
(:func:`rank_doublings`), so a round's planning and bookkeeping cost the main thread little
while the passes wait for it.

The sequences' integer arithmetic is 32-bit, done in int64 and masked (:data:`MASK32`; every
product stays under 2⁶³), bit for bit numpy's uint32 arithmetic.
"""

from __future__ import annotations

import math

import numpy as np

from .core import camera_uniform
from .jit import helper, kernel

#: The low 32 bits.
MASK32 = 0xFFFFFFFF
#: The sums kept of each pixel's samples, over the quarters of its sequence so far: samples
#: ``⌊iN/4⌋`` to ``⌊(i + 1)N/4⌋ − 1`` of N (:func:`add_round`). The halves' difference
#: estimates the pixel's noise, the quarters' how fast it falls (``raytrace.noise``).
QUARTERS = 4
#: A pixel's samples are numbered below this: sample k of pixel p (``row·width + col``) has
#: the light key ``p·KEY_STRIDE + k`` (:func:`round_points`).
KEY_STRIDE = 1 << 20
#: Direction numbers of Sobol's second dimension (primitive polynomial x + 1, all initial
#: m = 1): v₀ = 2³¹, v_i = v_{i−1} ⊕ (v_{i−1} >> 1) (Joe & Kuo's table, dimension 2).
SOBOL_DIRECTIONS = np.empty(32, np.int64)
SOBOL_DIRECTIONS[0] = 1 << 31
for _bit in range(1, 32):
    SOBOL_DIRECTIONS[_bit] = SOBOL_DIRECTIONS[_bit - 1] ^ (SOBOL_DIRECTIONS[_bit - 1] >> 1)
del _bit


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
    sequences' first points 4.9σ off uniform in one bin."""
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
def pixel_seed1(seed, pixel, axis):
    """The 32-bit scrambling seed of axis ``axis`` (0: x, 1: y) of the sequence of pixel
    ``pixel`` (``row·width + col``): ⌊2³²·u⌋ of the camera's draw u
    (:func:`raytrace.kernels.core.camera_uniform`) of the render's ``seed``."""
    return int(math.floor(camera_uniform(seed, pixel, axis) * 4294967296.0))


@kernel
def sobol_rows(index, x, y):
    """:func:`sobol1` of each ``index[i]``: its two 32-bit fractions (integers) into ``x``
    and ``y`` (tests)."""
    for i in range(index.shape[0]):
        x[i], y[i] = sobol1(index[i] & MASK32)


@kernel
def pixel_offset_rows(seed, pixel, k, sx, sy):
    """Positions (sx, sy) in [0, 1)² inside the pixel of sample ``k[i]`` of pixel
    ``pixel[i]``'s sequence: the Owen-scrambled (:func:`owen1`, each axis by its
    :func:`pixel_seed1`) Sobol point ``k[i]`` (:func:`sobol1`)."""
    for i in range(k.shape[0]):
        ux, uy = sobol1(k[i] & MASK32)
        sx[i] = owen1(ux, pixel_seed1(seed, pixel[i], 0)) * 2.0**-32
        sy[i] = owen1(uy, pixel_seed1(seed, pixel[i], 1)) * 2.0**-32


@kernel
def round_points(window, width, seed, old, new, order, out):
    """The samples ``old[p]`` to ``new[p] − 1`` of the sequence of each pixel p of ``window``
    (a :class:`raytrace.kernels.records.Window`: its pixels numbered row by row from (x0,
    y0), in a ``width``-wide frame), pixel after pixel in ``order`` (the pixels' numbers,
    each once), in sample order, into ``out`` (a
    :class:`raytrace.kernels.records.RoundSamples`): each sample's offset in the pixel (as
    :func:`pixel_offset_rows`, the pixel's two seeds hashed once), its pixel's frame column
    and row, and its light key ``(row·width + col)·KEY_STRIDE + k``."""
    x0, y0 = window.x0, window.y0
    cols = window.x1 - x0
    j = 0
    for q in range(order.shape[0]):
        p = order[q]
        c, r = x0 + p % cols, y0 + p // cols
        pixel = r * width + c
        seed_x, seed_y = pixel_seed1(seed, pixel, 0), pixel_seed1(seed, pixel, 1)
        for k in range(old[p], new[p]):
            ux, uy = sobol1(k & MASK32)
            out.sx[j] = owen1(ux, seed_x) * 2.0**-32
            out.sy[j] = owen1(uy, seed_y) * 2.0**-32
            out.col[j], out.row[j], out.keys[j] = c, r, pixel * KEY_STRIDE + k
            j += 1


@kernel
def add_round(values, old, new, order, sums, moments, done):
    """Add a round's traced samples to their pixels' quarter sums. ``values`` (m, 3) are
    samples in :func:`round_points`' order: pixel after pixel in ``order``, the samples
    ``old[p]`` to ``new[p] − 1`` of pixel p, where ``new[p]`` is ``old[p]`` or ``old[p]``
    times a power of two (or ``old[p]`` is 0). ``sums`` (:data:`QUARTERS`, k, 3) hold each
    pixel's sums over the quarters of its samples, ``⌊iN/4⌋`` to ``⌊(i + 1)N/4⌋ − 1`` of N: a
    pixel's samples doubled, its old halves are its new first two quarters; grown more, its
    old samples all lie in its new first quarter. Each sample is added in order. With
    ``moments`` (a :class:`raytrace.kernels.records.Moments`; None where nothing reads them)
    the pixel's block also updates its running moments by Chan, Golub & LeVeque's pairwise
    update ("Algorithms for computing the sample variance", The American Statistician 37(3),
    1983, eq. 2.1): n₀ samples of mean μ and a block of k of mean μ_b make n₀ + k samples of
    mean ``μ + δ·k/(n₀ + k)``, δ = μ_b − μ, and summed squared deviations ``m2 + m2_b +
    δ²·n₀·k/(n₀ + k)``: no difference of large sums, so a bright pixel's small spread is not
    lost to cancellation. Each pixel of ``order`` is marked ``done``."""
    j = 0
    for q in range(order.shape[0]):
        p = order[q]
        n0, n1 = old[p], new[p]
        k = n1 - n0
        done[p] = True
        if k == 0:
            continue
        b1, b2, b3 = n1 // 4, n1 // 2, (3 * n1) // 4
        for c in range(3):
            if n0 == 0:
                s0, s1 = 0.0, 0.0
            elif b1 >= n0:  # grown fourfold or more: the old samples are the first quarter's
                s0 = sums[0, p, c] + sums[1, p, c] + sums[2, p, c] + sums[3, p, c]
                s1 = 0.0
            else:  # doubled: the old halves are the first two quarters
                s0, s1 = sums[0, p, c] + sums[1, p, c], sums[2, p, c] + sums[3, p, c]
            s2, s3 = 0.0, 0.0
            for i in range(k):
                x, at = values[j + i, c], n0 + i
                if at < b1:
                    s0 += x
                elif at < b2:
                    s1 += x
                elif at < b3:
                    s2 += x
                else:
                    s3 += x
            sums[0, p, c], sums[1, p, c], sums[2, p, c], sums[3, p, c] = s0, s1, s2, s3
            if moments is not None:
                total = values[j, c]
                for i in range(j + 1, j + k):
                    total += values[i, c]
                mu = total / k
                m2 = 0.0
                for i in range(j, j + k):
                    d = values[i, c] - mu
                    m2 += d * d
                delta = mu - moments.mean[p, c]
                moments.mean[p, c] += delta * (k / n1)
                moments.m2[p, c] += m2 + delta * delta * (n0 * (k / n1))
        if moments is not None:
            moments.count[p] = n1
        j += k


@kernel
def pixel_halves(sums, n, a, b):
    """Each pixel's halves' means into ``a`` and ``b`` (pixels, 3): its first two quarter
    ``sums`` (:data:`QUARTERS`, pixels, 3) and its last two, each over its ``n`` samples a
    half (``raytrace.noise.halves``); a pixel of no samples is not finite."""
    for p in range(n.shape[0]):
        for c in range(3):
            a[p, c] = (sums[0, p, c] + sums[1, p, c]) / n[p]
            b[p, c] = (sums[2, p, c] + sums[3, p, c]) / n[p]


@kernel
def quarter_falls(sums, n):
    """Over the pixels whose samples ``2·n`` split into four equal quarters (n even, above 0)
    and whose differences are finite in every channel: the sums of ``(2/n)²·(Q₀ + Q₁ − Q₂ −
    Q₃)²`` (the halves' difference, the sums being the quarters' ``sums``) and of
    ``(2/n)²·((Q₀ − Q₁)² + (Q₂ − Q₃)²)`` (the quarters'), over the channels too
    (``raytrace.noise.convergence_rate``)."""
    halves_sum, quarters_sum = 0.0, 0.0
    for p in range(n.shape[0]):
        if n[p] <= 0 or n[p] % 2 != 0:
            continue
        scale = (2.0 / n[p]) ** 2
        h0, q0 = 0.0, 0.0
        finite = True
        for c in range(3):
            s0, s1, s2, s3 = sums[0, p, c], sums[1, p, c], sums[2, p, c], sums[3, p, c]
            both, first, second = s0 + s1 - s2 - s3, s0 - s1, s2 - s3
            h, q = both * both, first * first + second * second
            finite = finite and math.isfinite(h) and math.isfinite(q)
            h0 += scale * h
            q0 += scale * q
        if finite:
            halves_sum += h0
            quarters_sum += q0
    return halves_sum, quarters_sum


@kernel
def half_noise(a, b):
    """Over the pixels whose halves' means ``a`` and ``b`` (pixels, 3) give a finite
    ``(A − B)²/4`` and mean ``(A + B)/2`` in every channel: the sum of the one and of the
    other over pixels and channels, and how many pixels (``raytrace.noise.relative_rmse``)."""
    noise_sum, level_sum, pixels = 0.0, 0.0, 0
    for p in range(a.shape[0]):
        v0, m0 = 0.0, 0.0
        finite = True
        for c in range(3):
            d = a[p, c] - b[p, c]
            v, m = 0.25 * (d * d), 0.5 * (a[p, c] + b[p, c])
            finite = finite and math.isfinite(v) and math.isfinite(m)
            v0 += v
            m0 += m
        if finite:
            noise_sum += v0
            level_sum += m0
            pixels += 1
    return noise_sum, level_sum, pixels


@helper
def sift_down(values, lo, root, end):
    """Move ``values[lo + root]`` down the max-heap ``values[lo:lo + end]`` to its place."""
    while 2 * root + 1 < end:
        child = 2 * root + 1
        if child + 1 < end and values[lo + child + 1] > values[lo + child]:
            child += 1
        if values[lo + root] >= values[lo + child]:
            return
        values[lo + root], values[lo + child] = values[lo + child], values[lo + root]
        root = child


@helper
def sort_run(values, lo, hi):
    """``values[lo:hi]`` (int64) in ascending order, in place: a heapsort (J. W. J. Williams,
    "Algorithm 232: Heapsort", CACM 7(6), 1964), O(r log r) for a run of r, in plain loops
    (numba's ``np.sort`` lengthens a kernel's first compile by seconds)."""
    size = hi - lo
    for root in range(size // 2 - 1, -1, -1):
        sift_down(values, lo, root, size)
    for end in range(size - 1, 0, -1):
        values[lo], values[lo + end] = values[lo + end], values[lo]
        sift_down(values, lo, 0, end)


@kernel
def rank_doublings(pixels, ranked, table, aim, out):
    """A round's doublings of samples in order of priority (``raytrace.noise.neyman_counts``),
    into ``out`` (a :class:`~raytrace.kernels.records.Doublings` with room for every pixel's
    every doubling), until they have added ``aim.goal`` samples a half, or sooner, once they
    have added ``aim.least``, where the variance they take off reaches ``aim.need`` (at least
    one is taken, all where none of these is reached); returns how many.

    Pixel p of ``pixels`` (a :class:`~raytrace.kernels.records.DoublingPixels`), with ``n``
    samples a half, has doublings j = 0 … J − 1 while ``n·2^j < table.most`` (``table``: a
    :class:`~raytrace.kernels.records.DoublingTable` of (kinds, J), each row one count), the
    j-th of priority ``σ·table.scale[kind, j]``, adding ``min(2m, most) − m`` samples at ``m
    = n·2^j`` and taking ``s²·table.drop[kind, j]`` off the summed variance. They are taken
    highest priority first, equal ones by the lower j and then the lower pixel. ``ranked``
    holds the pixels that can double (``n < most``, ``σ > 0``) in order of falling σ, equal
    ones in any order.

    The pixels of one kind in that order give, for each j, a stream of doublings of falling
    priority (a factor times σ), whose runs of equal priority (equal σ, or a tie that rounding
    makes) are put in pixel order (:func:`sort_run`), so the doublings' order is a merge of
    the kinds × J streams (a k-way merge, each stream's head compared at every step)."""
    kinds, steps = table.scale.shape
    n, kind = pixels.n, pixels.kind
    bounds = np.zeros(kinds + 1, np.int64)  # kind k's pixels: bounds[k] … bounds[k + 1] − 1
    for p in ranked:
        bounds[kind[p] + 1] += 1
    for k in range(kinds):  # (a loop: np.cumsum lengthens the kernel's first compile)
        bounds[k + 1] += bounds[k]
    order = np.empty(len(ranked), np.int64)
    fill = bounds[:kinds].copy()
    for p in ranked:
        order[fill[kind[p]]] = p
        fill[kind[p]] += 1
    # stream (k, j): row j of ``stream`` and ``priority`` over kind k's columns; ``head`` its
    # next, ``bounds[k + 1]`` once spent (or where the kind's count cannot double j times)
    stream = np.empty((steps, len(order)), np.int64)
    priority = np.empty((steps, len(order)))
    head = np.empty((kinds, steps), np.int64)
    for k in range(kinds):
        lo, hi = bounds[k], bounds[k + 1]
        for j in range(steps):
            head[k, j] = lo if hi > lo and (n[order[lo]] << j) < table.most else hi
            for i in range(lo, hi):
                stream[j, i] = order[i]
                priority[j, i] = pixels.sigma[order[i]] * table.scale[k, j]
            i = lo
            while i < hi:
                e = i + 1
                while e < hi and priority[j, e] == priority[j, i]:
                    e += 1
                if e - i > 1:
                    sort_run(stream[j], i, e)
                i = e
    taken, added, fall = 0, 0, 0.0
    while True:
        best_k, best_j, best_i = -1, -1, -1
        for k in range(kinds):
            for j in range(steps):
                i = head[k, j]
                if i == bounds[k + 1]:
                    continue
                if best_k < 0 or priority[j, i] > priority[best_j, best_i] or (
                        priority[j, i] == priority[best_j, best_i] and (
                            j < best_j or (j == best_j
                                           and stream[j, i] < stream[best_j, best_i]))):
                    best_k, best_j, best_i = k, j, i
        if best_k < 0:
            break
        p = stream[best_j, best_i]
        out.pixel[taken], out.step[taken] = p, best_j
        taken += 1
        head[best_k, best_j] += 1
        m = n[p] << best_j
        added += min(2 * m, table.most) - m
        fall += pixels.s2[p] * table.drop[best_k, best_j]
        if added >= aim.goal or (fall >= aim.need and added >= aim.least):
            break
    return taken
