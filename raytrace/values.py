"""Checked conversion of scene values: colours, vectors, numbers, tables.

Each function takes the raw value and its key path and either returns a clean value or raises
:class:`~raytrace.errors.SceneError` naming the key and the problem. Used by the scene-file
loader, the material library and the Python API alike, so a bad value reads the same wherever
it comes from.

Every position and length a scene holds is bounded by :data:`MAX_COORDINATE` and
:data:`MIN_LENGTH` … :data:`MAX_LENGTH` (:func:`position`, :func:`length`, :func:`edge`): the
range in which a scene renders as it does scaled to unit size (docs/robustness.md, "Bounds").
"""

from __future__ import annotations

import difflib
import math
from collections.abc import Iterable, Mapping
from typing import Any

import numpy as np

from .errors import SceneError

#: Largest |coordinate| of any point of a scene: the camera, shapes, lights, mesh vertices after
#: their transform. Embree intersects meshes in float32, where a triangle of size L met by a
#: ray from distance D is lost once L²·D nears float32's 3.4e38 (a mesh 1e13 across seen from
#: 1e13 away vanishes: docs/robustness.md, "Bounds"); any point can be a ray's origin, so every
#: position shares the range that keeps L, D ≤ 2√3·1e12 and L²·D ≤ 4.2e37.
MAX_COORDINATE = 1e12
#: Largest length given as one: a radius, an area light's edge, a checker cell. (A distance
#: between two points, such as the camera's to ``look_at``, is bounded by their coordinates.)
MAX_LENGTH = MAX_COORDINATE
#: Smallest length, the mirror of :data:`MAX_LENGTH`: a scene scaled below it loses its meshes
#: (Embree's float32 edge cross products underflow at edges of ~1e-19) and, further down, its
#: spheres and camera (float64 squares underflow below ~1e-154); a mesh at least 1e-12
#: across would need 1e7 triangles a side before its triangles got that small.
MIN_LENGTH = 1 / MAX_LENGTH
_COORDINATE_WHY = "where every ray meets every mesh in Embree's float32"
_LENGTH_WHY = "the lengths at which a scene renders as it does at unit size"


def type_name(value: Any) -> str:
    return {bool: "a boolean", str: "a string", int: "an integer", float: "a number",
            list: "a list", tuple: "a list", dict: "a table"}.get(type(value),
                                                               type(value).__name__)


def did_you_mean(word: Any, choices: Iterable[str]) -> str:
    """``" (did you mean 'brass'?)"`` for the closest of ``choices`` to a misspelt ``word``
    (:func:`difflib.get_close_matches`, Ratcliff/Obershelp similarity ≥ 0.6), else ``""``.

    >>> did_you_mean("bras", ["brass", "bronze", "glass"])
    " (did you mean 'brass'?)"
    >>> did_you_mean("teapot", ["brass"])
    ''
    """
    if not isinstance(word, str):
        return ""
    close = difflib.get_close_matches(word, list(choices), n=2)
    return f" (did you mean {' or '.join(map(repr, close))}?)" if close else ""


def check_keys(table: Mapping, allowed: Iterable[str], key: str) -> None:
    """Unknown keys are errors: a misspelt key must never be silently ignored."""
    if not isinstance(table, Mapping):
        raise SceneError(f"must be a table, got {type_name(table)}", key)
    allowed = list(allowed)
    for k in table:
        if k not in allowed:
            raise SceneError(f"unknown key{did_you_mean(k, allowed)} (valid keys: "
                             f"{', '.join(allowed)})", f"{key}.{k}" if key else k)


def _bound(x: float) -> str:
    """A range bound as written: integers in full (2**63 - 1, not 9.22337e+18), others %g."""
    return str(x) if isinstance(x, int) else f"{x:g}"


def number(value: Any, key: str, *, lo: float | None = None, hi: float | None = None,
           lo_open: bool = False, hi_open: bool = False, integer: bool = False) -> float:
    """A finite real number (an integer if ``integer``) within optional bounds."""
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise SceneError(f"must be a number, got {type_name(value)}", key)
    try:
        v = float(value)
    except OverflowError:  # a Python int (a JSON integer) of more than 309 digits
        raise SceneError("must be within float64's range (±1.8e308), got an integer of "
                         f"{value.bit_length()} bits", key) from None
    if integer and not v.is_integer():
        raise SceneError(f"must be a whole number, got {value!r}", key)
    if not math.isfinite(v):
        raise SceneError(f"must be finite, got {value!r}", key)
    shown = v if isinstance(value, (np.integer, np.floating)) else value  # not np.float64(…)
    both = "" if lo is None or hi is None else (f" (the range is {'(' if lo_open else '['}"
                                                f"{_bound(lo)}, {_bound(hi)}"
                                                f"{')' if hi_open else ']'})")
    if lo is not None and (v <= lo if lo_open else v < lo):
        raise SceneError(f"must be {'>' if lo_open else '>='} {_bound(lo)}{both}, "
                         f"got {shown!r}", key)
    if hi is not None and (v >= hi if hi_open else v > hi):
        raise SceneError(f"must be {'<' if hi_open else '<='} {_bound(hi)}{both}, "
                         f"got {shown!r}", key)
    return int(v) if integer else v


def vector(value: Any, key: str, n: int = 3, *, nonzero: bool = False) -> np.ndarray:
    """A list of ``n`` finite numbers as a float64 array."""
    if isinstance(value, np.ndarray):
        value = value.tolist()
    if not isinstance(value, (list, tuple)) or len(value) != n:
        raise SceneError(f"must be a list of {n} numbers, got {value!r}", key)
    out = np.array([number(x, f"{key}[{i}]") for i, x in enumerate(value)], dtype=np.float64)
    if nonzero and not np.any(out):
        raise SceneError("must not be the zero vector", key)
    with np.errstate(over="ignore", under="ignore"):  # the cases refused here
        squared = np.dot(out, out)
    if nonzero and not np.isfinite(squared):
        raise SceneError(f"is too long to normalise, got {value!r}", key)
    if nonzero and squared < np.finfo(np.float64).tiny:
        raise SceneError(f"is too short to normalise (its squared length underflows float64), "
                         f"got {value!r}", key)
    return out


def position(value: Any, key: str) -> np.ndarray:
    """A point: a list of 3 numbers, each within ±:data:`MAX_COORDINATE`.

    >>> position([0, 1e12, -5], "center").tolist()
    [0.0, 1000000000000.0, -5.0]
    >>> position([1e200, 0, 0], "center")  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    raytrace.errors.SceneError: center[0]: must be within ±1e+12 (...), got 1e+200
    """
    out = vector(value, key)
    for i, x in enumerate(out):
        if abs(x) > MAX_COORDINATE:
            raise SceneError(f"must be within ±{_bound(MAX_COORDINATE)} ({_COORDINATE_WHY}), "
                             f"got {float(x)!r}", f"{key}[{i}]")
    return out


def check_points(points: np.ndarray, key: str, what: str) -> None:
    """Refuse an array of points (a mesh's vertices, ``what``) with a coordinate that is not
    finite or beyond ±:data:`MAX_COORDINATE`, as :func:`position` refuses one point.

    >>> check_points(np.array([[0.0, 2e12, 0.0]]), "scale", "transformed vertices")
    ... # doctest: +ELLIPSIS
    Traceback (most recent call last):
    raytrace.errors.SceneError: scale: transformed vertices exceed ±1e+12 (where every ray ...)
    """
    with np.errstate(invalid="ignore"):
        largest = np.abs(points).max(initial=0.0)
    if not largest <= MAX_COORDINATE:  # (NaN too)
        raise SceneError(f"{what} exceed ±{_bound(MAX_COORDINATE)} ({_COORDINATE_WHY})", key)


def span(points: np.ndarray) -> float:
    """The longest side of the bounding box of ``points`` (n, 3), NaN where a coordinate is:
    each column's peak to peak, a strided 1-D reduction (7× faster than
    ``np.ptp(points, axis=0)``, whose reduction along rows of three is slow: 7 against
    52 ms at 655 k vertices, measured).

    >>> span(np.array([[0.0, 1.0, 2.0], [3.0, -1.0, 2.5]]))
    3.0
    """
    return float(np.array([np.ptp(points[:, k]) for k in range(points.shape[1])]).max())


def length(value: Any, key: str) -> float:
    """A length (a radius, a cell size): a number > 0 within [:data:`MIN_LENGTH`,
    :data:`MAX_LENGTH`].

    >>> length(0.5, "radius")
    0.5
    >>> length(1e155, "radius")  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    raytrace.errors.SceneError: radius: must be within [1e-12, 1e+12] (...), got 1e+155
    """
    v = number(value, key, lo=0, lo_open=True)
    check_length(v, key)
    return v


def check_length(v: float, key: str, what: str = "", *, longest: bool = True) -> None:
    """Refuse a length ``v`` outside [:data:`MIN_LENGTH`, :data:`MAX_LENGTH`] (only below it
    where not ``longest``: a distance between two points, bounded by their coordinates);
    ``what`` names a derived one ("its length", "its distance to camera.position")."""
    if v < MIN_LENGTH or (longest and v > MAX_LENGTH):
        bounds = (f"within [{_bound(MIN_LENGTH)}, {_bound(MAX_LENGTH)}]" if longest else
                  f"at least {_bound(MIN_LENGTH)}")
        raise SceneError(f"{what + ' ' if what else ''}must be {bounds} ({_LENGTH_WHY}), "
                         f"got {float(v)!r}", key)


def edge(value: Any, key: str) -> np.ndarray:
    """A non-zero vector whose length is a :func:`length` (an area light's edge)."""
    out = vector(value, key)
    if not np.any(out):
        raise SceneError("must not be the zero vector", key)
    check_length(math.hypot(*out), key, "its length")
    return out


#: How far from 1 the length of a direction already normalised may be (a few ulps: v/|v| has
#: a length an ulp off 1 for about a third of directions, 6628 of 20 000 random ones, so
#: normalising it again would move it).
UNIT_TOLERANCE = 4 * np.finfo(np.float64).eps


def unit(value: Any, key: str) -> np.ndarray:
    """A non-zero direction, normalised; one whose length is already 1 within
    :data:`UNIT_TOLERANCE` is kept as it is, so that checking a record again (its ``check``
    at every render) never moves its directions.

    >>> unit([0, 3, 4], "normal").tolist()
    [0.0, 0.6, 0.8]
    >>> u = unit([1, 1, 0], "normal"); unit(u, "normal").tolist() == u.tolist()
    True
    """
    v = vector(value, key, nonzero=True)
    length = np.linalg.norm(v)
    return v if abs(length - 1.0) <= UNIT_TOLERANCE else v / length


def color(value: Any, key: str, *, lo: float | None = 0.0, hi: float | None = None
          ) -> np.ndarray:
    """A colour: a scalar (grey) or ``[r, g, b]``; float64 (3,)."""
    if isinstance(value, (list, tuple, np.ndarray)):
        c = vector(value, key)
        for i, x in enumerate(c):
            number(x, f"{key}[{i}]", lo=lo, hi=hi)
        return c
    return np.full(3, number(value, key, lo=lo, hi=hi))


def boolean(value: Any, key: str) -> bool:
    if not isinstance(value, bool):
        raise SceneError(f"must be true or false, got {value!r}", key)
    return value


def string(value: Any, key: str, choices: Iterable[str] | None = None) -> str:
    if not isinstance(value, str):
        raise SceneError(f"must be a string, got {type_name(value)}", key)
    if choices is not None:
        choices = list(choices)
        if value not in choices:
            raise SceneError(f"must be one of {', '.join(map(repr, choices))}, got {value!r}"
                             f"{did_you_mean(value, choices)}", key)
    return value


class Checked:
    """A record whose fields are checked by its own ``check()``: when it is made (dataclass
    ``__post_init__``) and again before every render (:meth:`raytrace.scene.Scene.check`), so
    that a field set or edited in place afterwards is refused as it would be at construction,
    by the same code and with the same message."""

    def __post_init__(self) -> None:
        self.check()

    def check(self) -> None:
        raise NotImplementedError
