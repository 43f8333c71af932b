"""Local shading: the seeds' ambient + diffuse + specular model, per RGB channel.

    I = ka·Ia + Σ_l S_l · f_radial · f_angular · I_l · [ kd·max(N·L, 0) + ks·spec ]

with the highlight chosen from :data:`HIGHLIGHTS`:

* ``"phong"``: ``spec = max(V·R, 0)^n``, ``R = 2(N·L)N − L`` (Phong 1975; seed 000/001);
* ``"blinn"``: ``spec = max(N·H, 0)^n``, ``H = (L + V)/|L + V|`` (Blinn 1977; seed 001);

both zero where ``N·L <= 0``. Everything is float64.
"""

from __future__ import annotations

import numpy as np

from .optics import dot


def cosine_power(a: np.ndarray, b: np.ndarray, n: np.ndarray) -> np.ndarray:
    """``max(a·b, 0)^n`` for unit vectors, stable for huge ``n``.

    ``1 − a·b`` is taken as ``|a − b|²/2``, which keeps its relative precision near
    ``a·b = 1`` (a dot product there cancels to nothing), and the power as
    ``exp(n·log1p(−h))``. So an exponent of 1e8 still gives the right falloff. The value is 0
    where ``a·b <= 0`` (so ``0^0`` counts as 0 here) and 1 where ``a = b``.

    >>> x = np.array([[1.0, 0.0, 0.0]]); y = np.array([[np.cos(1e-4), np.sin(1e-4), 0.0]])
    >>> float(cosine_power(x, y, np.array([1e8]))[0])  # exp(-1e8·(1e-8/2)) = exp(-0.5)
    0.6065306...
    """
    diff = a - b
    h = 0.5 * dot(diff, diff)  # 1 − cos
    # h < 1 alone lets a·b = 0 through when |a − b|² rounds just below 2 (then 0^0 gave 1).
    positive = (h < 1.0) & (dot(a, b) > 0)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        p = np.exp(n * np.log1p(-np.minimum(h, 1.0)))
    p = np.where(n == 0, 1.0, p)
    return np.where(positive, p, 0.0)


def phong(normal: np.ndarray, to_light: np.ndarray, to_eye: np.ndarray, n: np.ndarray):
    """Phong's (V·R)^n with R = 2(N·L)N − L (Phong 1975)."""
    r = 2.0 * dot(normal, to_light)[:, None] * normal - to_light
    r /= np.maximum(np.linalg.norm(r, axis=1, keepdims=True), 1e-300)
    return cosine_power(to_eye, r, n)


def blinn(normal: np.ndarray, to_light: np.ndarray, to_eye: np.ndarray, n: np.ndarray):
    """Blinn's (N·H)^n with H = (L + V)/|L + V| (Blinn 1977); 0 where L = −V."""
    h = to_light + to_eye
    length = np.linalg.norm(h, axis=1, keepdims=True)
    ok = length[:, 0] > 1e-12
    h = np.where(ok[:, None], h / np.where(ok[:, None], length, 1.0), normal)
    return np.where(ok, cosine_power(normal, h, n), 0.0)


#: Highlight models by name (a registry, not a class hierarchy).
HIGHLIGHTS = {"phong": phong, "blinn": blinn}
HIGHLIGHT_CODES = {name: i for i, name in enumerate(HIGHLIGHTS)}


def direct(normal, to_light, to_eye, kd, ks, shininess, model) -> np.ndarray:
    """``kd·max(N·L, 0) + ks·spec`` per channel, (n, 3); zero where ``N·L <= 0``.

    ``model`` (n,) holds :data:`HIGHLIGHT_CODES`; ``kd``, ``ks`` are (n, 3); ``shininess`` (n,).
    """
    ndl = dot(normal, to_light)
    lit = ndl > 0
    spec = np.zeros(len(ndl))
    for name, code in HIGHLIGHT_CODES.items():
        m = lit & (model == code)
        if m.any():
            spec[m] = HIGHLIGHTS[name](normal[m], to_light[m], to_eye[m], shininess[m])
    return np.where(lit[:, None], kd * np.maximum(ndl, 0.0)[:, None] + ks * spec[:, None], 0.0)
