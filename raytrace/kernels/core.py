"""The per-ray primitives every compiled kernel shares, each defined once.

Scalar functions compiled with :data:`raytrace.kernels.jit.kernel`, inlined into the kernels of
:mod:`raytrace.camera`, :mod:`raytrace.kernels.accel` and :mod:`raytrace.kernels.shading`
(numba's cache would not notice an edit here from those modules; :mod:`raytrace.kernels.jit`'s cache
guard does):

* hashing: :func:`finalize64` (SplitMix64's finalizer, Steele, Lea & Flood 2014),
  :func:`mix64` and the draws built on it, :func:`camera_uniform` (pixel-sample jitter)
  and :func:`light_word` / :func:`light_uniform` (points on jittered area-light cells), and
  :func:`path_key1` (a
  secondary ray's own key for those points);
* the camera: :func:`pixel_offset` (where a sample lies in its pixel);
* optics: :func:`reflect3` (law of reflection), :func:`refract3` (Snell, with total internal
  reflection), :func:`fresnel1` and :func:`fresnel_weights1` (angle-dependent kr, kt);
* surfaces: :func:`facing1` (the side a ray arrives on), :func:`leave1` (where a spawned ray
  starts), :func:`checker1` (the world-space checker of SCENE_FORMAT.md) and
  :func:`checker_box1` (its box-filtered share of odd cells, by :func:`wave_mean1`),
  :func:`texture1`
  (a bilinear image texture, with :func:`taps1`, :func:`blend1` and :func:`wrap1`),
  :func:`taylor1` (a fast-Phong polynomial
  at barycentrics, :mod:`raytrace.fast_phong`);
* powers: :func:`whole_power1` (``cⁿ`` for whole exponents, the highlights' cheaper form)
  and :func:`is_whole1`.

Array versions for numpy callers and tests: :func:`checker_rows`, :func:`checker_box_rows`,
:func:`leave_rows`,
:func:`texture_rows`, :func:`taylor_rows`, :func:`path_keys`.
"""

from __future__ import annotations

import math

import numpy as np

from .jit import helper, kernel
from .kinds import DIELECTRIC, FAST_PHONG, FLAT, GOURAUD, NO_FRESNEL, SCHLICK, SMOOTH  # noqa: F401
from .records import TEX_HEIGHT, TEX_OFFSET, TEX_WIDTH, TEX_WRAP_S, TEX_WRAP_T, SpawnPoint

#: SplitMix64's constants (Steele et al. 2014).
M1, M2, M3 = (np.uint64(0x9E3779B97F4A7C15), np.uint64(0xBF58476D1CE4E5B9),
              np.uint64(0x94D049BB133111EB))
_TWO = np.uint64(2)
_S11, _S27, _S30, _S31 = np.uint64(11), np.uint64(27), np.uint64(30), np.uint64(31)
_S32, _LOW32 = np.uint64(32), np.uint64(0xFFFFFFFF)
#: Mesh shading codes (``raytrace.tables.SHADING_CODES``; ``Triangles.shading``).
#: Shadow rays stop this relative fraction short of the light.
SHADOW_SHORTEN = 1e-7
#: Fresnel weighting codes (``raytrace.shading.FRESNEL_CODES``; ``Materials.fresnel``).
#: The checker's bias: ``floor(x/s + 1e-4)`` keeps a plane lying on a cell boundary on one side.
CHECKER_BIAS = 1e-4
#: The largest whole exponent :func:`whole_power1` takes: its bound (2n − 1)·2⁻⁵³ is then
#: below 1.5e-11 relative (docs/robustness.md, "Precision budget").
WHOLE_POWER_MAX = 65536.0


# -- hashing --------------------------------------------------------------------------------
@helper
def finalize64(z):
    """SplitMix64's finalizer of a uint64 ``z`` (Steele, Lea & Flood, "Fast splittable
    pseudorandom number generators", 2014): a bijection that mixes every input bit into
    every output bit."""
    z = (z ^ (z >> _S30)) * M2
    z = (z ^ (z >> _S27)) * M3
    return z ^ (z >> _S31)


@helper
def mix64(z):
    """:func:`finalize64` of a uint64 ``z`` as a uniform float in [0, 1): its top 53 bits."""
    return float(finalize64(z) >> _S11) * 2.0**-53


@helper
def path_key1(key, origin_bits, direction_bits):
    """The jitter key of a secondary ray's hits: its camera sample's ``key`` (≥ 0) hashed
    with the bit patterns (3-tuples of uint64) of the ray's origin and direction, which
    tell apart the paths of one camera sample (a hit's reflected and refracted children
    leave along different directions, its see-through child from another point), so each
    path draws its own light points. A chain of :func:`finalize64` over the seven words;
    the top 63 bits, so the key is ≥ 0 (an int64)."""
    z = finalize64(np.uint64(key) * M1 + M3)
    for w in (origin_bits[0], origin_bits[1], origin_bits[2], direction_bits[0],
              direction_bits[1], direction_bits[2]):
        z = finalize64((z ^ w) + M1)
    return np.int64(z >> np.uint64(1))


@helper
def camera_uniform(seed, index, stream):
    """A uniform float in [0, 1) for camera sample ``index`` (global), ``stream`` 0 or 1 (x or
    y) and the render's ``seed``: :func:`mix64` of ``(2·index + stream)·M1 + seed·M3``."""
    return mix64((np.uint64(index) * _TWO + np.uint64(stream)) * M1 + np.uint64(seed) * M3)


@helper
def light_word(key, stream, depth):
    """The draw of a jittered area light at one hit, a 63-bit int64 ≥ 0: :func:`finalize64`
    of ``key·M1 + stream·M3 + depth·M2`` (``key`` the hit's global camera sample, or
    :func:`path_key1` of it for a secondary ray's; ``stream`` the light's) shifted right by
    one. One hash per (hit, light), shared by the light's cells (made once per hit for all
    of them by :func:`light_words`); :func:`light_uniform` reads it."""
    return np.int64(finalize64(np.uint64(key) * M1 + np.uint64(stream) * M3
                               + np.uint64(depth) * M2) >> np.uint64(1))


@helper
def light_uniform(word):
    """Two uniform floats (w₁, w₂) in [0, 1) from a :func:`light_word`: its top 31 bits times
    2⁻³¹ and its bottom 32 bits times 2⁻³²."""
    return float(word >> 32) * 2.0**-31, float(word & 0xFFFFFFFF) * 2.0**-32


@kernel
def light_words(key, stream, depth, out):
    """:func:`light_word` of each row of ``key`` (n,) int64 into ``out`` (n,) int64."""
    for i in range(key.shape[0]):
        out[i] = light_word(key[i], stream, depth)


# -- the camera -----------------------------------------------------------------------------
@helper
def pixel_offset(spp, k, seed, sample, cell):
    """Position (sx, sy) in [0, 1)² inside its pixel of global sample ``sample``, the
    ``cell``-th (``sample mod spp``) of its pixel: the centre for spp = 1, jittered in cell
    (cell mod k, cell div k) of a k×k grid for spp = k², jittered over the whole pixel
    otherwise (k = 0). The jitter is :func:`camera_uniform` of the sample, so an image does
    not depend on passes, threads or crops."""
    if spp == 1:
        return 0.5, 0.5
    u1, u2 = camera_uniform(seed, sample, 0), camera_uniform(seed, sample, 1)
    if k == 0:
        return u1, u2
    return (cell % k + u1) / k, (cell // k + u2) / k


# -- vectors --------------------------------------------------------------------------------
@helper
def cross3(a, b):
    """The cross product ``a × b`` of two 3-tuples."""
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


# -- optics ---------------------------------------------------------------------------------
@helper
def reflect3(dx, dy, dz, nx, ny, nz):
    """Mirror direction ``r = d − 2(d·n)n`` (law of reflection)."""
    k = 2.0 * (dx * nx + dy * ny + dz * nz)
    return dx - k * nx, dy - k * ny, dz - k * nz


@helper
def refract3(dx, dy, dz, nx, ny, nz, eta):
    """Snell refraction ``η₁ sin θ₁ = η₂ sin θ₂`` with ``eta = η₁/η₂`` of a unit ``d`` at the
    unit normal ``n``; returns ``(tx, ty, tz, tir)``.

    ``cos θᵢ = −d·n`` (clipped to [−1, 1] against rounding), radicand
    ``k = cos²θᵢ − (η² − 1)·sin²θᵢ`` (so η = 1 leaves exactly undeviated),
    ``t = η·d + (η·cos θᵢ − √k)·n``; ``k < 0`` is total internal reflection, where ``t`` is
    the mirror direction instead. ``|t|² = η²·sin²θᵢ + k = 1`` for either sign of the cosine,
    so ``t`` is a unit vector also where ``n`` faces away from the ray (an interpolated normal
    at a smooth mesh's silhouette, docs/shading.md): the cosine keeps its sign, and the
    integrator then checks the side ``t`` leaves on against the face normal.
    """
    cos_i = min(max(-(dx * nx + dy * ny + dz * nz), -1.0), 1.0)
    sin2 = max(0.0, (1.0 - cos_i) * (1.0 + cos_i))
    k = cos_i * cos_i - (eta - 1.0) * (eta + 1.0) * sin2
    if k < 0.0:
        rx, ry, rz = reflect3(dx, dy, dz, nx, ny, nz)
        return rx, ry, rz, True
    c = eta * cos_i - math.sqrt(k)
    return eta * dx + c * nx, eta * dy + c * ny, eta * dz + c * nz, False


@kernel
def fresnel1(cos_i, eta):
    """The exact unpolarised Fresnel reflectance of a dielectric interface, ``eta = η₁/η₂``,
    ``cos_i`` the cosine of incidence (≥ 0): ``F = (R_s + R_p)/2`` with
    ``R_s = ((η cos θᵢ − cos θₜ)/(η cos θᵢ + cos θₜ))²``,
    ``R_p = ((η cos θₜ − cos θᵢ)/(η cos θₜ + cos θᵢ))²`` and ``cos θₜ = √(1 − η² sin² θᵢ)``
    (Born & Wolf §1.5; pbrt-v4 ``FrDielectric``); 1 under total internal reflection.
    At normal incidence on glass (η = 1/1.5) F = ((1 − 1.5)/(1 + 1.5))² = 0.04."""
    c = min(max(cos_i, 0.0), 1.0)
    sin2_t = eta * eta * (1.0 - c) * (1.0 + c)
    if sin2_t >= 1.0:
        return 1.0
    cos_t = math.sqrt(1.0 - sin2_t)
    rs = (eta * c - cos_t) / (eta * c + cos_t)
    rp = (eta * cos_t - c) / (eta * cos_t + c)
    return 0.5 * (rs * rs + rp * rp)


@helper
def fresnel_weights1(model, cos_i, eta, kr, kt):
    """kr and kt (3-tuples) weighted for the angle of incidence by ``model``:
    NO_FRESNEL leaves them; SCHLICK gives ``kr + (1 − kr)(1 − cos θ)⁵`` (Schlick 1994 with
    F0 = kr; the MTL ``illum 5`` "Fresnel reflection", which rises from Ks to 1 at grazing)
    and leaves kt; DIELECTRIC gives ``kr·F`` and ``kt·(1 − F)`` with F = :func:`fresnel1`
    (``illum 7``; glTF transmission)."""
    if model == SCHLICK:
        g = (1.0 - min(max(cos_i, 0.0), 1.0)) ** 5
        return ((kr[0] + (1.0 - kr[0]) * g, kr[1] + (1.0 - kr[1]) * g,
                 kr[2] + (1.0 - kr[2]) * g), kt)
    if model == DIELECTRIC:
        f = fresnel1(cos_i, eta)
        return ((kr[0] * f, kr[1] * f, kr[2] * f),
                (kt[0] * (1.0 - f), kt[1] * (1.0 - f), kt[2] * (1.0 - f)))
    return kr, kt


# -- surfaces -------------------------------------------------------------------------------
@helper
def facing1(gx, gy, gz, dx, dy, dz):
    """+1 where the geometric normal faces the viewer (``N_g·(−d) >= 0``), else −1: surfaces
    are two-sided, normals turn to the side the ray comes from."""
    return -1.0 if gx * -dx + gy * -dy + gz * -dz < 0.0 else 1.0


@helper
def leave1(at, d):
    """Start of a ray leaving a surface point along ``d`` (a 3-tuple): ``at.offset`` off the
    surface along the geometric normal, on the side it leaves on (the sign of ``d·N_g``, +1
    where it is 0; a NaN direction gives a NaN start, which no query hits). ``at``: a
    :class:`raytrace.kernels.records.SpawnPoint`, the hit point, its geometric normal N_g and
    the offset. Analytic shapes have offset 0: their rays carry their shape instead
    (:mod:`raytrace.analytic`)."""
    px, py, pz = at.point
    gx, gy, gz = at.geometric
    dx, dy, dz = d
    dot = dx * gx + dy * gy + dz * gz
    side = 1.0 if dot >= 0.0 else (-1.0 if dot < 0.0 else math.nan)  # sign, +1 at 0
    step = side * at.offset
    return px + step * gx, py + step * gy, pz + step * gz


# -- powers ---------------------------------------------------------------------------------
@helper
def is_whole1(n):
    """True where ``n`` is a whole number in ``[1, WHOLE_POWER_MAX]``: the exponents
    :func:`whole_power1` takes."""
    return 1.0 <= n <= WHOLE_POWER_MAX and n == math.floor(n)


@kernel
def whole_power1(c, n):
    """``cⁿ`` for a whole ``n`` in ``[1, WHOLE_POWER_MAX]`` (:func:`is_whole1`) by binary
    exponentiation (square and multiply; Knuth, TAOCP vol. 2, §4.6.3, Algorithm A): at most
    2·(⌊log₂ n⌋ + 1) multiplications in place of ``exp(n·log c)``'s two library calls (the
    highlight's ``exp``/``log1p`` were 52 of a Whitted frame's 182 ms of ``light_pass``).

    Error (u = 2⁻⁵³, first order): ``c^(2^j)`` after j squarings carries at most (2ʲ − 1)·u,
    and the product of the factors of n's bits adds one rounding each, so the result is within
    (n − 1)·u of the exact cⁿ of the float64 ``c``; an error ε in ``c`` itself becomes n·ε.
    The highlight's ``c = 1 − h`` (h ∈ [0, 1)) is exact for h ≥ ½ (Sterbenz) and within u
    relative below, so ``(1 − h)ⁿ`` is within (2n − 1)·u ≤ 1.5e-11 of exact: the
    precision budget's term bound (docs/robustness.md). Squares that underflow give 0, as
    exp does. Returns ``c`` unchanged for n = 1.

    >>> whole_power1(0.5, 10.0)
    0.0009765625
    """
    k = int(n)
    result = 1.0
    while k:  # this form, not one that skips the last square: 4 ms less of light_pass (mesh)
        if k & 1:
            result *= c
        c *= c
        k >>= 1
    return result


@helper
def checker1(x, y, z, scale):
    """1 where ``floor(x/s + 1e-4) + floor(y/s + 1e-4) + floor(z/s + 1e-4)`` is odd, else 0
    (SCENE_FORMAT.md; :data:`CHECKER_BIAS`). numba's ``math.floor`` gives int64 cell
    indices (one beyond int64's range, an infinity or NaN converts as the CPU converts it:
    −2⁶³, even, on x86-64); their sum is taken back to float64 for the parity, so a sum
    beyond 2⁵³ counts as even."""
    cells = (math.floor(x / scale + CHECKER_BIAS) + math.floor(y / scale + CHECKER_BIAS)
             + math.floor(z / scale + CHECKER_BIAS))
    half = 0.5 * cells
    return 1 if half - math.floor(half) == 0.5 else 0


#: Half-widths (in cells) from which a box holds so many cells that its mean of the square
#: wave is 0 to within 1/WAVE_WIDEST (:func:`wave_mean1`).
WAVE_WIDEST = 1e15


@helper
def wave_mean1(u, w):
    """Mean of the square wave s(t) = (−1)^⌊t⌋ over [u − w, u + w] (w ≥ 0): s(u) itself,
    ±1 exactly, where the interval holds no integer; else (−1)^k·(F(b) − F(a))/(b − a) with
    k = ⌊u − w⌋, a, b the ends less k (small numbers, whatever u) and F(t) = 1 − |t mod 2 − 1|
    the integral of s from 0, a triangle wave (pbrt-v3's closed-form box-filtered checkerboard,
    ``Checkerboard2DTexture``, one axis at a time); 0 from :data:`WAVE_WIDEST` (and for an
    infinite w). NaN where u is NaN."""
    if not w < WAVE_WIDEST:
        return 0.0
    lo, hi = u - w, u + w
    k = np.floor(lo)
    sign = 1.0 if np.floor(0.5 * k) == 0.5 * k else -1.0
    if np.floor(hi) == k:
        return sign
    a, b = lo - k, hi - k
    fa = 1.0 - abs(a - 2.0 * np.floor(0.5 * a) - 1.0)
    fb = 1.0 - abs(b - 2.0 * np.floor(0.5 * b) - 1.0)
    return sign * (fb - fa) / (b - a)


@helper
def checker_box1(x, y, z, extent, scale):
    """The share of :func:`checker1`'s odd cells in the box of half-widths ``extent``
    (ex, ey, ez) about (x, y, z): the checker is the product of one square wave per axis,
    odd = (1 − sx·sy·sz)/2, so its box average is (1 − mx·my·mz)/2 with each m the axis'
    :func:`wave_mean1` (a separable box filter). Exactly 0 or 1 where the box crosses no
    cell boundary (the caller then keeps :func:`checker1`'s parity bit for bit); NaN at a
    NaN point."""
    mx = wave_mean1(x / scale + CHECKER_BIAS, extent[0] / scale)
    my = wave_mean1(y / scale + CHECKER_BIAS, extent[1] / scale)
    mz = wave_mean1(z / scale + CHECKER_BIAS, extent[2] / scale)
    return 0.5 * (1.0 - mx * my * mz)


@helper
def wrap1(i, n, mode):
    """Texel index ``i`` of a row of ``n`` wrapped by ``mode`` (``raytrace.readers.texture.WRAPS``):
    0 repeat (i mod n), 1 clamp to the edge, 2 mirrored repeat (period 2n)."""
    if mode == 1:
        return min(max(i, 0), n - 1)
    if mode == 2:
        k = i % (2 * n)
        return k if k < n else 2 * n - 1 - k
    return i % n


#: Texel channels for :func:`bilinear1`, numpy integers: a Python int constant would make numba
#: compile :func:`bilinear1` once per channel value (it types constants passed to a kernel as
#: literals).
RED, GREEN, BLUE, ALPHA = (np.int64(c) for c in range(4))


@helper
def taps1(info, q, s, t):
    """Where texture ``q`` is read at (s, t) bilinearly: ``(a, b, c, d, ax, ay)``, the first
    elements in ``texels`` of texels (i₀, j₀), (i₁, j₀), (i₀, j₁), (i₁, j₁) around
    ``x = s·W − ½``, ``y = t·H − ½`` (wrapped, :func:`wrap1`) and the fractions
    ``ax = x − ⌊x⌋``, ``ay = y − ⌊y⌋`` (texel (i, j)'s centre is at ((i + ½)/W, (j + ½)/H)).
    ``info[q]``: its offset into the texels, W, H and wrap modes (``Materials.tex_info``, at
    ``TEX_OFFSET``, …)."""
    off, w, h = info[q, TEX_OFFSET], info[q, TEX_WIDTH], info[q, TEX_HEIGHT]
    x, y = s * w - 0.5, t * h - 0.5
    fx, fy = math.floor(x), math.floor(y)
    wrap_s, wrap_t = info[q, TEX_WRAP_S], info[q, TEX_WRAP_T]
    i0, i1 = wrap1(int(fx), w, wrap_s), wrap1(int(fx) + 1, w, wrap_s)
    j0, j1 = wrap1(int(fy), h, wrap_t), wrap1(int(fy) + 1, h, wrap_t)
    return (off + 4 * (j0 * w + i0), off + 4 * (j0 * w + i1), off + 4 * (j1 * w + i0),
            off + 4 * (j1 * w + i1), x - fx, y - fy)


@helper
def blend1(texels, taps, channel):
    """Channel ``channel`` of the four texels of ``taps`` (:func:`taps1`) weighted by their
    distances: ``(1 − ay)·((1 − ax)·T_a + ax·T_b) + ay·((1 − ax)·T_c + ax·T_d)``."""
    a, b, c, d, ax, ay = taps
    return (1.0 - ay) * ((1.0 - ax) * texels[a + channel] + ax * texels[b + channel]) + ay * (
        (1.0 - ax) * texels[c + channel] + ax * texels[d + channel])


@helper
def bilinear1(texels, info, q, s, t, channel):
    """Channel ``channel`` (0 … 3: R, G, B, A) of texture ``q`` bilinearly filtered at (s, t):
    the four texels around it (:func:`taps1`) weighted by their distances (:func:`blend1`), so
    at a texel's centre that texel exactly. ``texels``: every texture's RGBA rows, flat
    float32; ``info``: ``Materials.tex_info``."""
    return blend1(texels, taps1(info, q, s, t), channel)


@helper
def texture1(texels, info, q, s, t):
    """The RGB of texture ``q`` at (s, t), each channel :func:`bilinear1`'s, with the texels'
    indices and weights found once for the three (a random lookup in a 1024² texture: 500 ns
    in place of 800 on benchmarks/minification.py's machine)."""
    taps = taps1(info, q, s, t)
    return blend1(texels, taps, RED), blend1(texels, taps, GREEN), blend1(texels, taps, BLUE)


@helper
def taylor1(table, row, first, u, v):
    """The second-order polynomial in columns ``first … first + 5`` of row ``row`` of
    ``table`` at barycentrics (u, v): ``T₀ + du·(T₁ + T₃·du + T₄·dv) + dv·(T₂ + T₅·dv)`` with
    ``du = u − ⅓``, ``dv = v − ⅓`` (Bishop & Weimer 1986's Taylor expansion about the
    centroid, :mod:`raytrace.fast_phong`): five multiply-adds."""
    du, dv = u - 1.0 / 3.0, v - 1.0 / 3.0
    return table[row, first] + du * (table[row, first + 1] + table[row, first + 3] * du
                                      + table[row, first + 4] * dv) + dv * (
        table[row, first + 2] + table[row, first + 5] * dv)


# -- array versions -------------------------------------------------------------------------
@kernel
def path_keys(key, origin_bits, direction_bits, out):
    """:func:`path_key1` of each row: camera-sample keys ``key`` (n,), the rays' origins and
    directions as uint64 bit patterns (n, 3) (float64 arrays viewed as uint64), into ``out``
    (n,) int64."""
    for i in range(key.shape[0]):
        out[i] = path_key1(key[i], (origin_bits[i, 0], origin_bits[i, 1], origin_bits[i, 2]),
                           (direction_bits[i, 0], direction_bits[i, 1], direction_bits[i, 2]))


@kernel
def taylor_rows(table, rows, first, uv, out):
    """:func:`taylor1` of row ``rows[i]`` at barycentrics ``uv[i]`` into ``out`` (n,)."""
    for i in range(rows.shape[0]):
        out[i] = taylor1(table, rows[i], first, uv[i, 0], uv[i, 1])


@kernel
def texture_rows(texels, info, st, out):
    """:func:`texture1` of texture 0 at each (s, t) row of ``st`` into ``out`` (n, 3)."""
    for i in range(st.shape[0]):
        out[i, 0], out[i, 1], out[i, 2] = texture1(texels, info, 0, st[i, 0], st[i, 1])


@kernel
def checker_rows(points, scale, out):
    """:func:`checker1` at each world point (n, 3) into ``out`` (n,) int64."""
    for i in range(points.shape[0]):
        out[i] = checker1(points[i, 0], points[i, 1], points[i, 2], scale)


@kernel
def checker_box_rows(points, extents, scale, out):
    """:func:`checker_box1` at each world point (n, 3) with its half-widths ``extents``
    (n, 3) into ``out`` (n,) float64."""
    for i in range(points.shape[0]):
        out[i] = checker_box1(points[i, 0], points[i, 1], points[i, 2],
                              (extents[i, 0], extents[i, 1], extents[i, 2]), scale)


@kernel
def leave_rows(point, geometric, offset, direction, out):
    """:func:`leave1` for each row: the start points (n, 3) of rays leaving ``point`` along
    ``direction``."""
    for i in range(point.shape[0]):
        at = SpawnPoint(point=(point[i, 0], point[i, 1], point[i, 2]),
                        geometric=(geometric[i, 0], geometric[i, 1], geometric[i, 2]),
                        offset=offset[i])
        out[i, 0], out[i, 1], out[i, 2] = leave1(
            at, (direction[i, 0], direction[i, 1], direction[i, 2]))
