"""Local shading: the seeds' ambient + diffuse + specular model, per RGB channel.

    I = ka·Ia + Σ_l S_l · f_radial · f_angular · I_l · [ kd·max(N·L, 0) + ks·spec ]

with the highlight chosen by name (:data:`HIGHLIGHT_CODES`):

* ``"phong"``: ``spec = max(V·R, 0)^n``, ``R = 2(N·L)N − L`` (Phong 1975; seed 000/001);
* ``"blinn"``: ``spec = max(N·H, 0)^n``, ``H = (L + V)/|L + V|`` (Blinn 1977; seed 001);

both zero where ``N·L <= 0``. Everything is float64.
"""

from __future__ import annotations

import numpy as np

from . import shading_kernels as sk  # the compiled passes of this stage
from .core import DIELECTRIC, NO_FRESNEL, SCHLICK
from .optics import rows3


def _scalars(x, n: int) -> np.ndarray:
    """``x`` as a C-contiguous float64 (n,) array (a single value broadcasts)."""
    return np.ascontiguousarray(np.broadcast_to(np.asarray(x, np.float64).reshape(-1), n))


def cosine_power(a: np.ndarray, b: np.ndarray, n: np.ndarray) -> np.ndarray:
    """``max(a·b, 0)^n`` for unit vectors, stable for huge ``n``.

    ``1 − a·b`` is taken as ``|a − b|²/2``, which keeps its relative precision near
    ``a·b = 1`` (a dot product there cancels to nothing), and the power as
    ``exp(n·log1p(−h))``, or for a whole n up to 65 536 as ``(1 − h)ⁿ`` by squaring
    (:func:`raytrace.core.whole_power1`, within 1.5e-11). So an exponent of 1e8 still gives
    the right falloff. The value is 0
    where ``a·b <= 0`` (so ``0^0`` counts as 0 here) and 1 where ``a = b``.
    (:func:`raytrace.shading_kernels.cosine_power1`, row by row.)

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
    """The highlight of model ``code`` row by row (:func:`raytrace.shading_kernels.highlight1`)."""
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


#: The highlight models' kernel codes by name (``Material.highlight``; the names are
#: ``raytrace.material.HIGHLIGHTS``).
HIGHLIGHT_CODES = {"phong": sk.PHONG, "blinn": sk.BLINN}
#: Fresnel weightings of kr and kt by name (``raytrace.material.FRESNELS``), the codes the
#: kernels read (:func:`raytrace.core.fresnel_weights1`).
FRESNEL_CODES = {"none": NO_FRESNEL, "schlick": SCHLICK, "dielectric": DIELECTRIC}


def direct(normal, to_light, to_eye, kd, ks, shininess, model) -> np.ndarray:
    """``kd·max(N·L, 0) + ks·spec`` per channel, (n, 3); zero where ``N·L <= 0``.

    ``model`` (n,) holds :data:`HIGHLIGHT_CODES`; ``kd``, ``ks`` are (n, 3); ``shininess`` (n,).
    (:func:`raytrace.shading_kernels.direct1`, row by row.)
    """
    shininess = np.asarray(shininess, np.float64).reshape(-1)
    normal, to_light, to_eye, kd, ks = rows3(normal, to_light, to_eye, kd, ks,
                                             n=len(shininess))
    k = len(normal)
    model = np.ascontiguousarray(np.broadcast_to(np.asarray(model, np.int64).reshape(-1), k))
    out = np.empty((k, 3))
    sk.direct_rows(normal, to_light, to_eye, kd, ks, _scalars(shininess, k), model, out)
    return out
