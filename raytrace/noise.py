"""Adaptive sampling to a noise threshold (``aa = "noise"``): samples go where the error is.

Each pixel is sampled by its own sequence: the first N points of an Owen-scrambled
(0, 2)-sequence (Sobol's first two dimensions with Burley's hash-based nested uniform
scrambling: B. Burley, "Practical Hash-based Owen Scrambling", JCGT 9(4), 2020,
:func:`raytrace.kernels.noise.owen1`), scrambled by a seed hashed from the render's seed and
the pixel. So:

* every sample is a true sample of the pixel filter: uniform over the pixel for the box, and
  for the others drawn from the filter around the pixel's centre with its weight ``f/p``
  (1 for a positive filter; filter importance sampling,
  :func:`raytrace.film.filters.importance`), so the pixel's value, the mean of its N
  weighted samples, is an unbiased estimate of the filtered image for any N fixed in
  advance (counts chosen from the samples add a selection bias, which vanishes as
  ``min_spp`` grows; tests/test_noise.py bounds it over 64 seeds), and depends on the
  pixel's own samples alone;
* the first ``2^m`` points of the sequence are a (0, m, 2)-net, and so is each later block of
  ``2^m``: a pixel's samples are stratified as a whole at every power of two, and so are
  their halves and quarters. The mean of a scrambled net's N points varies as ``N^−β``, β
  above 1 (Owen 1997: up to N^−3 within a logarithm for a smooth integrand, N^−1.5 across an
  edge), so one sequence of N points varies less than two independent ones of N/2: 0.62–0.74×
  the MSE on the benchmark's scenes at 4 and 16 samples a pixel (docs/sampling.md);
* the noise is read from the pixel's halves, A (samples 0 … N/2 − 1) and B (N/2 … N − 1). With
  ``V_k`` the variance of the mean of k points, A and B each vary by ``V_{N/2}`` and their
  mean by ``V_N``, so ``E[(A − B)²/4] = V_{N/2} − V_N`` (:func:`half_difference`), which is
  ``(2^β − 1)·V_N`` where V falls as ``k^−β``: the halves' difference overstates the pixel's
  variance by ``2^β − 1`` (1 for independent samples, 1.7 at β = 1.45). The quarters'
  differences give ``V_{N/4} − V_{N/2}`` the same way, so the ratio of the image's two sums
  is ``2^−β``: β is read from the image each round (:func:`convergence_rate`; Richardson's
  extrapolation of the error's fall, L. F. Richardson 1911), and the image's variance is
  ``Σ(A − B)²/4 / (2^β − 1)`` (:func:`relative_rmse`).

**By threshold** (:func:`pixel_error`, :func:`next_counts`): a pixel starts with ``min_spp``
samples; after each round, a pixel whose error, or a neighbour's (3×3), is above the noise
threshold doubles its samples, up to ``max_spp``; the error is

    e = Σ_c |A_c − B_c|/2 / (10⁻⁴ + √(Σ_c I_c))

(Dammertz et al. 2010, "A hierarchical automatic stopping condition for Monte Carlo global
illumination", §2.1, as Cycles computes it in ``film_adaptive_sampling_convergence_check``
from its half buffer of every other sample, with ``|I − A| = |A − B|/2``). A pixel that stops
stays stopped, so a pixel depends on pixels at most :func:`margin` away: a crop that traces
that margin has the full frame's pixels.

**By target error or time** (:func:`relative_rmse`, :func:`neyman_counts`): the image's
relative RMSE is estimated as the root of its estimated variance over the mean of its pixels
and channels. Between rounds the pixels double their samples, up to :data:`MAX_DOUBLINGS`
times a round, in order of what each doubling takes off the summed variance per sample
(:func:`neyman_counts`), judged by each pixel's sample variance (all its samples pooled round
by round, :func:`raytrace.kernels.noise.add_round`: ``N − 1`` degrees of freedom where the
halves' difference has one, so the first round can be small: 4 samples a pixel by default,
:data:`raytrace.sampling.MIN_SPP_GOAL`), its neighbourhood's (by time, moderated by the
pixel's own: :data:`TIME_PRIOR`) and the image's β. A round adds as many samples as
were spent, or near a target what the target needs (:func:`variance_shrink`). The render
stops after the first round whose estimate is at most the target, once the deadline has
passed (no pass starts after it, so each pixel keeps whole rounds; the round before it is
sized to the time left, :func:`time_share`), or when every noisy pixel has its most samples.

A pixel's samples only ever double (or grow by a higher power of two), so its old halves
become its new quarters: its most is ``min_spp`` times the highest power of two within
``max_spp`` (:func:`most_samples`).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from .film.filters import importance
from .kernels.noise import (
    QUARTERS,
    add_round,
    half_noise,
    pixel_halves,
    pixel_offset_rows,
    quarter_falls,
    rank_doublings,
    round_points,
    sobol_rows,
)
from .kernels.records import (
    Aim,
    DoublingPixels,
    Doublings,
    DoublingTable,
    Moments,
    RoundSamples,
    Window,
)

#: The most a round by target error or time adds, as a share of the samples spent so far: a
#: round at most doubles them (half as much took a round more, and its fixed cost, on the
#: Whitted and mesh scenes; twice as much overshot the target: docs/sampling.md).
ROUND_SHARE = 1.0
#: The most times a pixel's samples double in one round by target error or time
#: (:func:`neyman_counts`): 16×, so that one chance estimate from the first round's 4 samples
#: cannot send a pixel to ``max_spp`` at once.
MAX_DOUBLINGS = 4
#: The least a round by target error adds (:func:`neyman_counts`)…
MIN_ROUND_SHARE = 0.1
#: …and how far past the target it aims, so that the estimate's own noise rarely needs one
#: more round.
TARGET_MARGIN = 1.1
#: The degrees of freedom a render by time gives the neighbourhood's variance in a pixel's
#: moderated variance, which it ranks pixels by (:func:`neyman_counts`): at equal samples
#: 0.88–1.00× the RMSE of the neighbourhood's alone (``benchmarks/noise_budget.py``). A
#: render by target ranks by the neighbourhood's alone, with which its rounds fall short of
#: their aim less often (docs/decisions.md, "Sampling").
TIME_PRIOR = 8.0
#: The error's guard against division by zero in black pixels (Cycles' 0.0001).
ERROR_EPSILON = 1e-4


def sobol2(index: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The points ``index`` (n,) of the (0, 2)-sequence of Sobol's first two dimensions, as
    32-bit fractions (int64 in [0, 2³²)): :func:`raytrace.kernels.noise.sobol1`."""
    index = np.ascontiguousarray(index, np.int64).reshape(-1)
    x, y = np.empty(len(index), np.int64), np.empty(len(index), np.int64)
    sobol_rows(index, x, y)
    return x, y


def offsets(seed: int, pixel: np.ndarray, k: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Positions (x, y) in [0, 1)² inside the pixel of sample ``k`` of the sequences of
    ``pixel`` (global pixel numbers, ``row·width + col``): the Owen-scrambled Sobol point
    ``k``, each axis scrambled by a seed hashed from the render's ``seed`` and the pixel
    (:func:`raytrace.kernels.noise.pixel_offset_rows`)."""
    pixel = np.ascontiguousarray(pixel, np.int64).reshape(-1)
    k = np.ascontiguousarray(k, np.int64).reshape(-1)
    x, y = np.empty(len(k)), np.empty(len(k))
    pixel_offset_rows(seed, pixel, k, x, y)
    return x, y


def check_pixels(sums: np.ndarray, n: np.ndarray) -> None:
    """That quarter ``sums`` are (:data:`raytrace.kernels.noise.QUARTERS`, pixels, 3) and
    ``n`` (pixels,): the kernels that read them check no bounds."""
    if sums.shape[0] != QUARTERS or sums.ndim != 3 or sums.shape[2] != 3 or \
            np.shape(n) != sums.shape[1:2]:
        raise ValueError(f"quarter sums of shape {sums.shape} and counts of shape "
                         f"{np.shape(n)}: ({QUARTERS}, pixels, 3) and (pixels,)")


def halves(sums: np.ndarray, n: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Each pixel's halves' means A and B (pixels, 3) from its quarter ``sums``
    (:data:`raytrace.kernels.noise.QUARTERS`, pixels, 3) and its ``n`` (pixels,) samples a
    half (:func:`raytrace.kernels.noise.pixel_halves`)."""
    check_pixels(sums, n)
    a, b = np.empty(sums.shape[1:]), np.empty(sums.shape[1:])
    pixel_halves(sums, np.ascontiguousarray(n, np.int64), a, b)
    return a, b


def half_difference(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``(A − B)²/4`` (…, 3) of each pixel's halves' means ``a`` and ``b``: in expectation
    ``V_{N/2} − V_N``, ``(2^β − 1)`` times the variance of the pixel's value (module
    docstring)."""
    return 0.25 * (a - b) ** 2


def pixel_error(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Each pixel's noise (n,): Dammertz et al.'s §2.1 error as Cycles computes it,
    ``Σ_c |I_c − A_c| / (10⁻⁴ + √(Σ_c I_c))`` with ``I = (A + B)/2``; NaN where a sample was
    not finite (such a pixel is not sampled further)."""
    mean = 0.5 * (a + b)
    with np.errstate(invalid="ignore"):
        return 0.5 * np.abs(a - b).sum(-1) / (ERROR_EPSILON
                                              + np.sqrt(np.maximum(mean.sum(-1), 0.0)))


def relative_rmse(a: np.ndarray, b: np.ndarray, rate: float) -> float:
    """The image's estimated relative RMSE, ``√(mean_{p,c} (A − B)²/4 / (2^β − 1)) /
    mean_{p,c} I`` over its finite pixels (:func:`half_difference`; ``rate`` is β,
    :func:`convergence_rate`); 0 for an image without noise, inf for a noisy image whose mean
    is not positive (the sums in one pass: :func:`raytrace.kernels.noise.half_noise`)."""
    if a.shape != b.shape or a.ndim != 2 or a.shape[1] != 3:
        raise ValueError(f"halves of shapes {a.shape} and {b.shape}: (pixels, 3) each")
    noise_sum, level_sum, pixels = half_noise(a, b)
    mse = noise_sum / (3 * pixels) / (2.0 ** rate - 1.0) if pixels else 0.0
    level = level_sum / (3 * pixels) if pixels else 0.0
    if mse == 0.0:
        return 0.0
    return float(np.sqrt(mse) / level) if level > 0 else float("inf")


def dilate(mask: np.ndarray, cols: int) -> np.ndarray:
    """``mask`` (rows·cols,) bool, row by row, or'd with its 8 neighbours' (3×3)."""
    m = mask.reshape(-1, cols)
    out = m.copy()
    out[1:] |= m[:-1]
    out[:-1] |= m[1:]
    grown = out.copy()
    out[:, 1:] |= grown[:, :-1]
    out[:, :-1] |= grown[:, 1:]
    return out.reshape(-1)


def next_counts(n: np.ndarray, error: np.ndarray, threshold: float, most: int,
                cols: int, active: np.ndarray | bool = True) -> np.ndarray:
    """Each pixel's samples a half after the next round: twice ``n`` (at most ``most``)
    where it is ``active`` and its ``error`` or a neighbour's (3×3, :func:`dilate`; rows of
    ``cols`` pixels) is above ``threshold``, else ``n``. The neighbours' say is Cycles' (its
    convergence filter marks the neighbours of an unconverged pixel unconverged): a thin
    stripe or an edge that a pixel's few first samples all missed, so that its two halves
    agree, is seen by a neighbour along it."""
    grow = dilate(error > threshold, cols) & (n < most) & active
    return np.where(grow, np.minimum(2 * n, most), n)


def most_samples(min_spp: int, max_spp: int) -> int:
    """The most samples a pixel reaches: ``min_spp`` doubled while it stays within
    ``max_spp``. A pixel's samples only double (module docstring), so ``max_spp`` = 100 from
    ``min_spp`` = 4 gives 64."""
    most = min_spp
    while 2 * most <= max_spp:
        most *= 2
    return most


def margin(min_spp: int, max_spp: int) -> int:
    """Pixels around a crop or tile that a noise-driven render by threshold traces too, so
    that its pixels are the full frame's: a pixel's counts after the r-th doubling depend on
    pixels up to r away (:func:`next_counts`' 3×3), and a pixel that stops stays stopped, so
    there are at most ``⌊log2(max/min)⌋`` doublings (:func:`most_samples`)."""
    return (most_samples(min_spp, max_spp) // min_spp).bit_length() - 1


class Points(NamedTuple):
    """Samples of a round (:meth:`Round.points`): ``x``, ``y`` (m,) image positions (pixels
    of the frame), ``keys`` (m,) light keys, and ``weight`` (m,), each sample's filter weight
    ``f/p`` (None where all are 1)."""

    x: np.ndarray
    y: np.ndarray
    keys: np.ndarray
    weight: np.ndarray | None


@dataclass
class Round:
    """The samples of one round, and the sums they go to. The samples ``old[p]`` to ``new[p]
    − 1`` of each pixel p (window order) of ``window`` = (x0, y0, x1, y1) in a ``width``-wide
    frame, pixel by pixel in ``order`` (the pixels' numbers in the window, row by row,
    :func:`spread_order`), each pixel's in sequence order; ``bounds``, the first sample of
    each pixel in that order (and the round's size at the end), where passes may be cut.
    Each pass draws its own samples (:meth:`points`) and adds what it traced into ``sums``,
    ``moments`` and ``done`` (:meth:`add`): its pixels are its own, so passes on several
    threads touch none of the same."""

    window: tuple[int, int, int, int]
    width: int
    seed: int
    filter: str
    old: np.ndarray
    new: np.ndarray
    order: np.ndarray
    bounds: np.ndarray
    #: each pixel's quarter sums (:func:`raytrace.kernels.noise.add_round`)
    sums: np.ndarray | None = None
    moments: Moments | None = None
    #: whether each pixel has its round (it had none, or its pass added it)
    done: np.ndarray | None = None

    @property
    def size(self) -> int:
        """The round's samples."""
        return int(self.bounds[-1])

    def pixels(self, start: int, stop: int) -> np.ndarray:
        """The pixels (window numbers, in ``order``) whose samples are ``start`` to ``stop``,
        both pixel bounds."""
        return self.order[np.searchsorted(self.bounds, start):
                          np.searchsorted(self.bounds, stop)]

    def points(self, start: int, stop: int) -> Points:
        """The samples ``start`` to ``stop`` (pixel bounds): each the pixel's Owen-scrambled
        Sobol point (:func:`offsets`, :func:`raytrace.kernels.noise.round_points`), uniform
        over the pixel for the box ``filter``, else mapped through the filter around the
        pixel's centre (:func:`raytrace.film.filters.importance`)."""
        m = stop - start
        out = RoundSamples(np.empty(m), np.empty(m), *(np.empty(m, np.int64) for _ in range(3)))
        round_points(Window(*self.window), self.width, self.seed, self.old, self.new,
                     self.pixels(start, stop), out)
        sx, sy = out.sx, out.sy
        weight = None
        if self.filter != "box":
            (dx, wx), (dy, wy) = importance(self.filter, sx), importance(self.filter, sy)
            sx, sy = 0.5 + dx, 0.5 + dy
            if (wx != 1.0).any() or (wy != 1.0).any():  # a filter with negative lobes
                weight = wx * wy
        return Points(out.col + sx, out.row + sy, out.keys, weight)

    def add(self, start: int, stop: int, values: np.ndarray,
            weight: np.ndarray | None = None) -> None:
        """Add the radiance ``values`` (stop − start, 3) of the samples ``start`` to ``stop``
        (pixel bounds), each times its ``weight`` (:meth:`points`), to their pixels' sums and
        moments, and mark the pixels done (:func:`raytrace.kernels.noise.add_round`: each
        pixel's samples summed in sequence order, whatever the pass)."""
        if weight is not None:
            values = values * weight[:, None]
        add_round(values, self.old, self.new, self.pixels(start, stop), self.sums,
                  self.moments, self.done)


def spread_order(window: tuple[int, int, int, int]) -> np.ndarray:
    """The pixels of ``window`` = (x0, y0, x1, y1), numbered row by row, in the order a
    round traces them: row after row in the bit-reversed order of their index (van der
    Corput's radical inverse: 0, 64, 32, 96, 16, … of 128 rows), each row's pixels from the
    left. Any run of rows in that order spreads over the window's height, so the passes a
    round is cut into (runs of pixels) each hold a like share of sky and of geometry and
    finish together on the threads; a pixel's value depends on its own samples alone,
    whatever the order."""
    x0, y0, x1, y1 = window
    rows, cols = y1 - y0, x1 - x0
    bits = max(1, (rows - 1).bit_length())
    index = np.arange(1 << bits)
    reverse = np.zeros_like(index)
    for b in range(bits):
        reverse |= ((index >> b) & 1) << (bits - 1 - b)
    row = reverse[reverse < rows]
    return (row[:, None] * cols + np.arange(cols)).reshape(-1)


def plan(window: tuple[int, int, int, int], width: int, seed: int, old: np.ndarray,
         new: np.ndarray, filter: str = "box", sums: np.ndarray | None = None,
         moments: Moments | None = None, done: np.ndarray | None = None) -> Round:
    """The :class:`Round` of the samples ``old[p]`` to ``new[p] − 1`` of each pixel p (window
    order) of ``window`` = (x0, y0, x1, y1) in a ``width``-wide frame, the pixels in
    :func:`spread_order`, adding into ``sums``, ``moments`` and ``done``."""
    order = spread_order(window)
    bounds = np.concatenate([[0], np.cumsum((new - old)[order])])
    return Round(window, width, seed, filter, old, new, order, bounds, sums, moments, done)


def passes(bounds: np.ndarray, size: int) -> list[tuple[int, int]]:
    """A round's samples cut into passes of about ``size`` samples at pixel ``bounds``
    (:class:`Round`), empty pixels skipped."""
    total = int(bounds[-1])
    cuts = np.unique(bounds[np.searchsorted(bounds, np.arange(0, total, size))])
    cuts = [int(c) for c in cuts if c < total] + [total]
    return [(a, b) for a, b in zip(cuts[:-1], cuts[1:], strict=True) if b > a]


@dataclass(frozen=True)
class Budget:
    """What a noise-driven render may spend: ``min_spp`` and ``max_spp`` samples a pixel
    (even: a pixel's noise is read from its halves), the noise ``threshold``
    (:func:`pixel_error`), and the optional ``target_error`` (relative RMSE,
    :func:`relative_rmse`) and ``deadline`` (``time.perf_counter()`` seconds), either of which
    makes the rounds follow :func:`neyman_counts` instead of the threshold."""

    min_spp: int
    max_spp: int
    threshold: float
    target_error: float | None = None
    deadline: float | None = None


@dataclass
class Result:
    """A noise-driven render: ``pixels`` (n, 3) float64, the mean of each pixel's samples,
    ``counts`` (n,) its samples, the ``estimate`` of the relative RMSE
    (:func:`relative_rmse`), the ``rounds`` traced and why it stopped (``stopped``:
    "threshold", "target_error", "time_limit", "max_spp" (every pixel whose variance
    estimate is not 0 has ``max_spp``) or "converged" (every pixel's variance estimate
    is 0))."""

    pixels: np.ndarray
    counts: np.ndarray
    estimate: float
    rounds: int
    stopped: str


#: ``trace(round, first)``: trace a :class:`Round`'s samples, each pass adding what it traced
#: (:meth:`Round.add`), and return how many were traced (all of them when ``first``; a
#: deadline may leave passes out).
RoundTracer = Callable[[Round, bool], int]


def box3(values: np.ndarray, cols: int) -> np.ndarray:
    """The mean of each pixel's 3×3 neighbourhood of ``values`` (rows·cols,), row by row
    (the neighbours inside the window): sums along the columns, then along the rows, over the
    count of neighbours, itself a product of the two directions' counts."""
    v = values.reshape(-1, cols)
    down = v.copy()
    down[1:] += v[:-1]
    down[:-1] += v[1:]
    total = down.copy()
    total[:, 1:] += down[:, :-1]
    total[:, :-1] += down[:, 1:]
    rows, across = np.ones(v.shape[0]), np.ones(v.shape[1])
    for side in (rows, across):
        side[1:] += 1.0
        side[:-1] += 1.0
    return (total / (rows[:, None] * across)).reshape(-1)


def variance_shrink(estimate: float, target: float | None) -> float:
    """The factor by which a round by target error aims to shrink the summed variance of
    the pixels' means (:func:`neyman_counts`): ``(target/(TARGET_MARGIN·estimate))²``, the
    relative RMSE being the root of that variance over the image's mean, at most 1 (an
    estimate at or below the target asks for nothing more); 0 (no aim: the round's share
    alone sizes it) where there is no target or no finite estimate above 0."""
    if target is None or not 0.0 < estimate < math.inf:
        return 0.0
    return min(1.0, target / (TARGET_MARGIN * estimate)) ** 2


def round_cost(samples: list[int], seconds: list[float]) -> tuple[float, float]:
    """A round's wall seconds as ``fixed + per_sample·samples`` (the estimate, allocation and
    planning before it and its passes' start, then its samples), fitted by least squares to
    the rounds traced so far (``samples``, ``seconds``); from one round, or rounds of one
    size, no fixed part and their seconds per sample. Neither part is below 0."""
    n = np.asarray(samples, np.float64)
    t = np.asarray(seconds, np.float64)
    if len(n) < 2 or np.ptp(n) == 0:
        return 0.0, float(t.sum() / max(n.sum(), 1.0))
    per_sample, fixed = np.polyfit(n, t, 1)
    if per_sample <= 0.0 or fixed < 0.0:
        return 0.0, float(t.sum() / n.sum())
    return float(fixed), float(per_sample)


def time_share(seconds_left: float, cost: tuple[float, float], spent: float) -> float:
    """The share of the ``spent`` samples that a round can add in ``seconds_left`` at
    ``cost`` (:func:`round_cost`: its fixed seconds and seconds a sample), at most
    :data:`ROUND_SHARE`; 0 where not even the fixed part fits. A render by time sizes its last
    round to its deadline, and the allocation spends it on the pixels of highest priority,
    not on those a cut round would reach first."""
    fixed, per_sample = cost
    if seconds_left <= fixed or spent <= 0.0:
        return 0.0
    if per_sample <= 0.0:
        return ROUND_SHARE
    return min(ROUND_SHARE, (seconds_left - fixed) / per_sample / spent)


def convergence_rate(sums: np.ndarray, n: np.ndarray) -> float:
    """The rate β at which the variance ``V_N`` of a pixel's mean of N samples falls, as
    ``N^−β``, read from the image (module docstring): β = 1 for independent samples, and
    Owen-scrambled nets converge faster, up to N^−3 (within a logarithm) for a smooth
    integrand (Owen 1997, "Scrambled net variance for integrals of smooth functions"; less
    fast across an edge). The halves' difference estimates ``V_{N/2} − V_N`` and the
    quarters' (each half's two) ``V_{N/4} − V_{N/2}``, so the ratio of their sums over the
    image is ``2^−β`` (Richardson's extrapolation of the error's fall with the samples, L. F.
    Richardson 1911), summed over the finite pixels whose N = 2n is a multiple of 4 (equal
    quarters). ``sums`` (:data:`raytrace.kernels.noise.QUARTERS`, pixels, 3) are each pixel's
    quarter sums, ``n`` its samples a half. Held within [1, 2]; 1 (the largest estimate of
    the variance) where the quarters show none. (The sums in one pass:
    :func:`raytrace.kernels.noise.quarter_falls`.)"""
    check_pixels(sums, n)
    half_sum, quarter_sum = quarter_falls(sums, np.ascontiguousarray(n, np.int64))
    fall_half, fall_quarter = half_sum / 16.0, quarter_sum / 8.0
    if not fall_quarter > 0.0:
        return 1.0
    if not fall_half > 0.0:
        return 2.0
    return min(2.0, max(1.0, math.log2(fall_quarter / fall_half)))


def ranking_sigma(n: np.ndarray, variance: np.ndarray, cols: int,
                  prior: float = math.inf) -> tuple[np.ndarray, np.ndarray]:
    """Each pixel's s², its per-sample ``variance`` where finite (else 0), and σ̃, the root of
    the moderated variance :func:`neyman_counts` ranks it by, ``(d₀·s̄² + d·s²)/(d₀ + d)``:
    s̄² the 3×3 mean of s² (:func:`box3`, rows of ``cols`` pixels), ``d₀ = prior``, ``d = 2n −
    1`` (``n`` its samples a half); with ``prior`` infinite, s̄² alone."""
    s2 = np.where(np.isfinite(variance), variance, 0.0)
    sigma = box3(s2, cols)
    if prior < math.inf:
        dof = 2.0 * n - 1.0
        sigma = (prior * sigma + dof * s2) / (prior + dof)
    return s2, np.sqrt(sigma)


def neyman_counts(n: np.ndarray, variance: np.ndarray, most: int, cols: int,
                  share: float = ROUND_SHARE, shrink: float = 0.0,
                  rate: float = 1.0, prior: float = math.inf) -> np.ndarray:
    """Each pixel's samples a half (``n``: half its samples) after the next round of a render
    by target error or time: the doublings of highest priority ``σ̃·m^−(1+β)/2`` are taken, a
    pixel's j-th doubling of the round taking it from ``m = n·2^j`` to ``2m`` a half (at most
    ``most``, and at most :data:`MAX_DOUBLINGS` a round), until the round adds ``share`` of
    the samples spent, or sooner, once it has added :data:`MIN_ROUND_SHARE` of them, where
    the summed variance of the pixels' means is predicted to fall to ``shrink`` times its
    present value. A pixel's mean varies by ``s²·(2n)^−β`` (:func:`convergence_rate`: β is
    ``rate``), s² its per-sample variance ``variance`` (the sample variance of all its
    samples pooled, averaged over the channels; not finite: 0, the pixel then
    ranked by its neighbours'), and σ̃² is its moderated variance (:func:`ranking_sigma`)
    ``(d₀·s̄² + d·s²)/(d₀ + d)``: the 3×3 mean of s² (:func:`box3`), s̄², taken as a prior
    worth ``d₀ = prior`` degrees of freedom, and the pixel's own, worth its ``d = 2n − 1``
    (the posterior variance of Smyth 2004, "Linear models and empirical Bayes methods for
    assessing differential expression in microarray experiments", whose prior is fitted
    where this one is the neighbourhood). The neighbourhood steadies the ranking of a pixel
    whose few samples missed its edge, and the pixel's own samples count the more the more
    it has. With ``prior`` infinite (the default) σ̃² is the neighbourhood's alone.

    Taking the doublings in order of what each takes off the summed variance per sample,
    ``∝ σ̃²·m^−(1+β)`` (a doubling cut short by ``most`` ranked as a whole one), is the
    greedy (marginal) allocation that tends to the optimum for a given number of samples,
    ``n ∝ σ^(2/(1+β))``: Neyman's ``n ∝ σ`` for independent samples (J. Neyman 1934, "On the
    two different aspects of the representative method", §5; with σ estimated from the
    samples, and sized to a variance asked for, as Cochran's "Sampling Techniques", 3rd ed.,
    §5.5 and §5.9, allocates strata), where equal per-pixel errors (a threshold) give no
    lower RMSE than uniform sampling save where σ = 0. A pixel's doublings are taken in order
    (its priority falls with each), so the few pixels that hold an image's error (a
    penumbra) reach their share in one round instead of one doubling a
    round. Ties go to the lower doubling, then the earlier pixel
    (:func:`raytrace.kernels.noise.rank_doublings` merges the doublings in that order)."""
    s2, sigma = ranking_sigma(n, variance, cols, prior)
    # each doubling's start m = n·2^j, per distinct count (the pixels' counts take a few
    # values, ``kind``) and doubling j: its powers taken once each
    present = np.bincount(n) > 0
    counts, kind = np.flatnonzero(present), (np.cumsum(present) - 1)[n]
    start = (counts[:, None] << np.arange(MAX_DOUBLINGS)).astype(np.float64)
    before = (2.0 * start) ** -rate  # a pixel's mean's variance over s², before and after
    table = DoublingTable(start ** (-0.5 * (1.0 + rate)),
                          before - (2.0 * np.minimum(2 * start, most)) ** -rate, most)
    goal = share * n.sum()
    aim = Aim(goal, (1.0 - shrink) * (s2 * before[kind, 0]).sum(),
              MIN_ROUND_SHARE * n.sum()) if shrink > 0.0 else Aim(goal, math.inf, math.inf)
    open_ = np.flatnonzero((n < most) & (sigma > 0))
    taken = Doublings(*(np.empty(MAX_DOUBLINGS * len(n), np.int64) for _ in range(2)))
    count = rank_doublings(DoublingPixels(n, sigma, s2, kind), open_[np.argsort(-sigma[open_])],
                           table, aim, taken)
    doublings = np.bincount(taken.pixel[:count], minlength=len(n))
    return np.minimum(n << doublings, np.maximum(n, most))


def sample(window: tuple[int, int, int, int], width: int, seed: int, budget: Budget,
           trace: RoundTracer, filter: str = "box") -> Result:
    """Adaptive sampling of the pixels of ``window`` (module docstring): a first round of
    ``min_spp`` samples each, then rounds that double some pixels' samples: by threshold,
    those whose error or a neighbour's is over it (:func:`next_counts`, a pixel that stopped
    stays stopped); by target error or time, the pixels of highest priority
    (:func:`neyman_counts`). Each pixel's quarters are summed sample after sample, so its
    value depends on its own samples only; each sample weighted by its ``filter``'s ``f/p``
    (:func:`plan`). Counts are kept a half (``n``: half a pixel's samples)."""
    most = most_samples(budget.min_spp, budget.max_spp) // 2
    cols = window[2] - window[0]
    n_pixels = cols * (window[3] - window[1])
    n = np.zeros(n_pixels, np.int64)
    new = np.full(n_pixels, budget.min_spp // 2, np.int64)
    sums = np.zeros((QUARTERS, n_pixels, 3))  # each pixel's quarter sums
    goal = budget.target_error is not None or budget.deadline is not None
    # every sample of a pixel: count, mean, Σ(x − mean)²
    moments = Moments(np.zeros(n_pixels, np.int64), np.zeros((n_pixels, 3)),
                      np.zeros((n_pixels, 3))) if goal else None
    done = np.empty(n_pixels, bool)
    rounds, stopped = 0, ""
    grew = np.ones(n_pixels, bool)  # the pixels the last round sampled
    # each round's samples and seconds, for the time it leaves: its seconds from the end of
    # the round before, its allocation and planning included
    round_samples, round_seconds = [], []
    t0 = time.perf_counter()
    while True:
        # each pass adds its pixels' samples, each pixel's summed in sequence order; a
        # deadline leaves out whole pixels (passes are cut at pixel bounds), not done
        done[:] = new == n
        round_samples.append(trace(plan(window, width, seed, 2 * n, 2 * new, filter, sums,
                                        moments, done), rounds == 0))
        round_seconds.append(time.perf_counter() - t0)
        t0 += round_seconds[-1]
        n = np.where(done, new, n)
        rounds += 1
        a, b = halves(sums, n)
        rate = convergence_rate(sums, n)
        estimate = relative_rmse(a, b, rate)
        if not done.all() or (budget.deadline is not None
                              and time.perf_counter() >= budget.deadline):
            stopped = "time_limit"
            break
        if budget.target_error is not None and estimate <= budget.target_error:
            stopped = "target_error"
            break
        if goal:
            with np.errstate(invalid="ignore", divide="ignore"):
                variance = (moments.m2 / (moments.count - 1.0)[:, None]).mean(-1)
            share = ROUND_SHARE
            if budget.deadline is not None:
                # (the first round left out once two others are known: on a cold kernel
                # cache its seconds are mostly compiling)
                fit = slice(1, None) if len(round_samples) > 2 else slice(None)
                share = min(share, time_share(budget.deadline - time.perf_counter(),
                                              round_cost(round_samples[fit], round_seconds[fit]),
                                              2 * n.sum()))
            if share <= 0.0:
                stopped = "time_limit"
                break
            new = neyman_counts(n, variance, most, cols, share,
                                variance_shrink(estimate, budget.target_error), rate,
                                math.inf if budget.target_error is not None else TIME_PRIOR)
        else:
            new = next_counts(n, pixel_error(a, b), budget.threshold, most, cols, grew)
        grew = new > n
        if not (new > n).any():  # by target or time: every noisy pixel has the most
            stopped = "threshold" if not goal else "max_spp" if (
                half_difference(a, b).sum(-1) > 0).any() else "converged"
            break
    return Result(0.5 * (a + b), 2 * n, estimate, rounds, stopped)

