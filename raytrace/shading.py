"""Local shading: the seeds' ambient + diffuse + specular model, per RGB channel.

    I = ka·Ia + Σ_l S_l · f_radial · f_angular · I_l · [ kd·max(N·L, 0) + ks·spec ]

with the highlight chosen by name (:data:`HIGHLIGHT_CODES`):

* ``"phong"``: ``spec = max(V·R, 0)^n``, ``R = 2(N·L)N − L`` (Phong 1975; seed 000/001);
* ``"blinn"``: ``spec = max(N·H, 0)^n``, ``H = (L + V)/|L + V|`` (Blinn 1977; seed 001);

both zero where ``N·L <= 0``. Everything is float64.
"""

from __future__ import annotations

import numpy as np

from .kernels import core
from .kernels import material as mk
from .kernels import shading as sk  # the compiled passes of this stage
from .kernels.kinds import FRESNEL_CODES, HIGHLIGHT_CODES  # noqa: F401  (by name, as before)
from .lights import Emitter
from .material import Checker
from .optics import rows3
from .readers.texture import WRAPS, Texture

#: :func:`incidence` without keys: every jittered cell at its centre.
NO_KEY = np.zeros(0, np.int64)


def _scalars(x, n: int) -> np.ndarray:
    """``x`` as a C-contiguous float64 (n,) array (a single value broadcasts)."""
    return np.ascontiguousarray(np.broadcast_to(np.asarray(x, np.float64).reshape(-1), n))


def cosine_power(a: np.ndarray, b: np.ndarray, n: np.ndarray) -> np.ndarray:
    """``max(a·b, 0)^n`` for unit vectors, stable for huge ``n``.

    ``1 − a·b`` is taken as ``|a − b|²/2``, which keeps its relative precision near
    ``a·b = 1`` (a dot product there cancels to nothing), and the power as
    ``exp(n·log1p(−h))``, or for a whole n up to 65 536 as ``(1 − h)ⁿ`` by squaring
    (:func:`raytrace.kernels.core.whole_power1`, within 1.5e-11). So an exponent of 1e8 still gives
    the right falloff. The value is 0
    where ``a·b <= 0`` (so ``0^0`` counts as 0 here) and 1 where ``a = b``.
    (:func:`raytrace.kernels.shading.cosine_power1`, row by row.)

    >>> x = np.array([[1.0, 0.0, 0.0]]); y = np.array([[np.cos(1e-4), np.sin(1e-4), 0.0]])
    >>> float(cosine_power(x, y, np.array([1e8]))[0])  # exp(-1e8·(1e-8/2)) = exp(-0.5)
    0.6065306...
    """
    n = np.asarray(n, np.float64).reshape(-1)
    a, b = rows3(a, b, n=len(n))
    out = np.empty(len(a))
    sk.cosine_power_rows(a, b, _scalars(n, len(a)), out)
    return out


def _highlight(code: int, normal, to_light, to_eye, n) -> np.ndarray:
    """The highlight of model ``code`` row by row (:func:`raytrace.kernels.shading.highlight1`)."""
    n = np.asarray(n, np.float64).reshape(-1)
    normal, to_light, to_eye = rows3(normal, to_light, to_eye, n=len(n))
    out = np.empty(len(normal))
    sk.highlight_rows(code, normal, to_light, to_eye, _scalars(n, len(normal)), out)
    return out


def phong(normal: np.ndarray, to_light: np.ndarray, to_eye: np.ndarray, n: np.ndarray):
    """Phong's (V·R)^n with R = 2(N·L)N − L (Phong 1975)."""
    return _highlight(sk.PHONG, normal, to_light, to_eye, n)


def blinn(normal: np.ndarray, to_light: np.ndarray, to_eye: np.ndarray, n: np.ndarray):
    """Blinn's (N·H)^n with H = (L + V)/|L + V| (Blinn 1977); 0 where L = −V."""
    return _highlight(sk.BLINN, normal, to_light, to_eye, n)




def direct(normal, to_light, to_eye, kd, ks, shininess, model) -> np.ndarray:
    """``kd·max(N·L, 0) + ks·spec`` per channel, (n, 3); zero where ``N·L <= 0``.

    ``model`` (n,) holds :data:`HIGHLIGHT_CODES`; ``kd``, ``ks`` are (n, 3); ``shininess`` (n,).
    (:func:`raytrace.kernels.shading.direct1`, row by row.)
    """
    shininess = np.asarray(shininess, np.float64).reshape(-1)
    normal, to_light, to_eye, kd, ks = rows3(normal, to_light, to_eye, kd, ks,
                                             n=len(shininess))
    k = len(normal)
    model = np.ascontiguousarray(np.broadcast_to(np.asarray(model, np.int64).reshape(-1), k))
    out = np.empty((k, 3))
    sk.direct_rows(normal, to_light, to_eye, kd, ks, _scalars(shininess, k), model, out)
    return out


# -- the scene's colours and lights at points, as the kernels see them ------------------------
def checker(pattern: Checker, points: np.ndarray) -> np.ndarray:
    """Colours (n, 3) of a :class:`~raytrace.material.Checker` at world points (n, 3): the
    renderer's own rule, :func:`raytrace.kernels.core.checker1` (whatever the checker's
    ``filter``; :func:`filtered_checker` for ``"box"``)."""
    points = np.ascontiguousarray(np.asarray(points, np.float64).reshape(-1, 3))
    odd = np.empty(len(points), np.int64)
    core.checker_rows(points, float(pattern.scale), odd)
    return np.where(odd[:, None] == 1, pattern.colors[1], pattern.colors[0])


def filtered_checker(pattern: Checker, points: np.ndarray, view: np.ndarray,
                     normal: np.ndarray, spread: float) -> np.ndarray:
    """Colours (n, 3) of a :class:`~raytrace.material.Checker` box-filtered as a
    ``filter = "box"`` checker is shaded: at world points ``points`` (n, 3), seen at the
    camera-relative points ``view`` (n, 3) on surfaces of normals ``normal`` (n, 3) by ray
    cones of spread ``spread`` (radians, :func:`raytrace.mipmap.spread_angle`): the mean of
    the pattern over each footprint, and :func:`checker`'s colour where no cell boundary
    crosses it: the kernels' own :func:`raytrace.kernels.material.box_color1`."""
    points, view, normal = rows3(points, view, normal)
    out = np.ascontiguousarray(checker(pattern, points), np.float64)
    pair = tuple(tuple(float(x) for x in c) for c in pattern.colors)
    mk.box_color_rows(points, view, normal, float(spread), float(pattern.scale), pair, out)
    return out


def texture(image: Texture, st: np.ndarray) -> np.ndarray:
    """Bilinear RGB (n, 3) of a :class:`~raytrace.readers.texture.Texture` at texture
    coordinates (n, 2): the renderer's own rule, :func:`raytrace.kernels.core.texture1`."""
    st = np.ascontiguousarray(np.asarray(st, np.float64).reshape(-1, 2))
    out = np.empty((len(st), 3))
    h, w = image.texels.shape[:2]
    info = np.array([[0, w, h, WRAPS[image.wrap[0]], WRAPS[image.wrap[1]]]], np.int64)
    core.texture_rows(image.texels.reshape(-1), info, st, out)
    return out


def incidence(emitter: Emitter, points: np.ndarray, key: np.ndarray | None = None,
              depth: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Unit vectors to the light L (n, 3), distances (n,) (inf for directional) and the
    attenuation ``f_radial · f_angular`` (n,) of one ``emitter`` at ``points`` (n, 3).

    A point exactly at the light's position gets factor 0 (no direction is defined). A
    jittered area-light cell is taken at the point drawn for each ``key`` (n,) (the global
    camera sample of the hit the point belongs to, :func:`path_keys` of it below the camera
    rays) and ``depth``, the point the integrator's shadow rays of that hit aim at; without
    ``key``, at the cell centre (:func:`raytrace.kernels.shading.incidence_rows`).
    """
    points = np.ascontiguousarray(np.asarray(points, np.float64).reshape(-1, 3))
    n = len(points)
    words = NO_KEY if key is None else light_words(key, emitter.stream, depth)
    to_light, dist, factor = np.empty((n, 3)), np.empty(n), np.empty(n)
    sk.incidence_rows(points, emitter.record, words, to_light, dist, factor)
    return to_light, dist, factor


def light_words(key: np.ndarray, stream: int, depth: int) -> np.ndarray:
    """The draws (n,) int64 of a jittered area light (its ``stream``) at hits of camera-sample
    or path ``key`` (n,) and ``depth``: :func:`raytrace.kernels.core.light_word` of each, one
    per hit for all the light's cells (no rows for an unjittered emitter, stream < 0)."""
    if stream < 0:
        return NO_KEY
    out = np.empty(len(key), np.int64)
    core.light_words(np.ascontiguousarray(key, np.int64), np.int64(stream), np.int64(depth),
                     out)
    return out


def path_keys(key: np.ndarray, origin: np.ndarray, direction: np.ndarray) -> np.ndarray:
    """The jitter keys (n,) int64 of the hits of secondary rays: each ray's camera-sample
    ``key`` (n,) hashed with its ``origin`` and ``direction`` (n, 3) float64
    (:func:`raytrace.kernels.core.path_key1`), so that the children of one hit, and every path
    of a camera sample, draw their own points on a jittered area light."""
    out = np.empty(len(key), np.int64)
    core.path_keys(np.ascontiguousarray(key, np.int64),
                   np.ascontiguousarray(origin, np.float64).view(np.uint64),
                   np.ascontiguousarray(direction, np.float64).view(np.uint64), out)
    return out
