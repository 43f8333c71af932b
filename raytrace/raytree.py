"""``raytrace explain``: the ray tree of one pixel sample, term by term.

When a pinned pixel changes, the question is which term changed. :func:`explain` answers it
for one camera sample: every ray (kind, depth, origin, direction, weight), what it hit
(object, material, distance, from outside or inside), the ambient term and each light's
unshadowed term with its shadow factor, the children spawned (or pruned, and why), and what
each ray added to the sample. Whitted's sum is linear in the rays (Whitted 1980), so the
rays' contributions add up to the sample's value.

It is not a second renderer. The sample is rendered by the integrator itself
(:class:`raytrace.integrator.WhittedIntegrator`), on a one-pixel crop (so it is the same ray,
jitter and all, as in the full render), through :meth:`~WhittedIntegrator.trace_samples`, with
a :class:`Recorder` as its ``observer``: the recorder copies the arrays the integrator
computes (the rays, the hits, each emitter's term and shadow factor, each hit's contribution
as the shading kernel wrote it, the children) and computes none of them. With ``spp = 1`` the
value is the pixel (to float32 rounding); otherwise the pixel is the mean of its samples.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from . import values
from .errors import SceneError
from .film import aov
from .integrator import WhittedIntegrator
from .kernels.kinds import KA, KEEP, KIND_NAMES, PRUNED
from .kernels.material import (
    alpha_tables1,
    palette1,
    surface_color1,
    surface_opacity1,
    texture_tables1,
)
from .kernels.records import MaterialHit
from .lights import labels
from .rendering import render_options
from .scene import Scene

#: Names of the children columns of the integrator's ``status`` (reflected, refracted,
#: see-through).
CHILD_NAMES = ("reflection", "refraction", "see_through")


class TooManyRays(SceneError):
    """The tree is larger than one batch of the integrator: not explained ray by ray."""


def _vec(a: Any) -> list[float]:
    return [float(x) for x in np.asarray(a, dtype=np.float64).reshape(-1)]


class Recorder:
    """Observes the rays of one pixel sample as the integrator traces them (the calls below
    are made by :class:`raytrace.integrator.WhittedIntegrator`, in this order for each
    batch: ``traced``, then for its hits ``hits``, ``light`` and ``shadow`` per emitter,
    ``shaded``, ``spawned``). ``rays`` is the list of records, in the order traced."""

    def __init__(self, integrator: Any):
        self.integ = integrator
        self.origin = integrator.origin  # the scene is camera-relative in the integrator
        self.rays: list[dict] = []
        self._next: list[int] = []   # records of the children just spawned, in batch order
        self._hits: list[int] = []   # records of the current batch's hits, in hit order
        self._lights: list[tuple[int, np.ndarray]] = []  # (emitter, rows of its shadow rays)
        # each emitter's label (the light's key, its part), as the lights name them
        self._labels = labels(integrator.scene.lights, self.origin, integrator.opt.seed)

    # -- the integrator's calls ---------------------------------------------------------------
    def traced(self, rays: Any, found: np.ndarray, missed: np.ndarray,
               background: np.ndarray) -> None:
        """A batch was intersected: its rays are camera rays (depth 0) or the children spawned
        last; ``missed`` rows add ``weight·background``, ``found`` rows go on to shading."""
        if rays.depth == 0:
            self._next = [self._new(rays, i, None) for i in range(len(rays))]
        if len(self._next) != len(rays):
            raise TooManyRays(f"more rays at depth {rays.depth} than one batch holds: too many "
                              "to explain ray by ray (use a lower max depth)", "pixel")
        ids = self._next
        for i in missed:
            rec = self.rays[ids[i]]
            rec["hit"] = None
            rec["background"] = _vec(background[0])
            rec["contribution"] = _vec(rays.weight[i] * background[0])  # accumulate()'s w·f
        self._hits = [ids[i] for i in found]
        self._next = []

    def hits(self, rays: Any, hits: Any, surf: Any) -> None:
        """What each ray of the batch (all hits, in hit order) hit: the AOV kernel's depth,
        facing normal, kd and object index, and the surface's material and side."""
        integ, n = self.integ, len(rays)
        names = ("depth", "normal", "albedo", "id")  # the AOV kernel's own values
        values = np.empty((n, len(aov.layout(names).miss)))
        integ.aov_hits(_rows(rays), hits, surf, aov.layout(names), values)
        cols = aov.columns(names)
        depth, normal, albedo = values[:, cols["depth"]][:, 0], values[:, cols["normal"]], \
            values[:, cols["albedo"]]
        ident = values[:, cols["id"]][:, 0].astype(np.int64)
        for j, rid in enumerate(self._hits):
            m = int(surf.material[j])
            material = integ.materials[m]
            point = surf.point[j] + self.origin
            # the kernels' own material lookup (colour, checker, texture, alpha)
            mats = integ.tables.materials
            hit = MaterialHit(tuple(float(x) for x in point), int(surf.triangle[j]),
                              *map(float, surf.uv[j]), tuple(float(x) for x in surf.point[j]),
                              tuple(float(x) for x in surf.geometric[j]))
            ka = surface_color1(palette1(integ.tables),
                                texture_tables1(integ.tables), m, KA, hit)
            opacity = float(surface_opacity1(mats.opacity, alpha_tables1(integ.tables), m,
                                             hit))
            obj = int(ident[j])
            entering = float(np.dot(rays.direction[j], surf.geometric[j])) < 0.0
            self.rays[rid]["hit"] = {
                "object": obj, "type": type(integ.scene.objects[obj]).__name__.lower(),
                "material": material.name or f"<inline material of objects[{obj}]>",
                "distance": float(depth[j]), "side": "outside" if entering else "inside",
                "point": _vec(point), "normal": _vec(normal[j]),
                **({"triangle": int(surf.triangle[j])} if surf.triangle[j] >= 0 else {}),
                "kd": _vec(albedo[j]), "ka": _vec(ka), "opacity": opacity,
            }
            self.rays[rid]["lights"] = []

    def light(self, emitter: int, term: np.ndarray, rows: np.ndarray) -> None:
        """Emitter ``emitter``'s unshadowed term at every hit; ``rows``: the hits that cast a
        shadow ray to it (the others get nothing from it)."""
        color = self.integ.emitters[emitter].color
        for j, rid in enumerate(self._hits):
            self.rays[rid]["lights"].append({
                "light": self._labels[emitter], "term": _vec(term[j]), "shadow": None,
                "color": _vec(color)})
        self._lights = (emitter, np.array(rows))

    def shadow(self, factor: np.ndarray) -> None:
        """The shadow factors S (k, 3) of the last emitter's shadow rays."""
        _, rows = self._lights
        for k, j in enumerate(rows):
            self.rays[self._hits[j]]["lights"][-1]["shadow"] = _vec(factor[k])

    def shaded(self, contribution: np.ndarray, status: np.ndarray, weights: tuple,
               tir: np.ndarray, past_max_depth: bool) -> None:
        """Each hit's contribution as the shading kernel added it, and its children's status
        (spawned, or pruned by ``max_depth`` or ``min_weight``)."""
        ambient = self.integ.ambient
        for j, rid in enumerate(self._hits):
            rec = self.rays[rid]
            w, t = np.array(rec["weight"]), rec["hit"]["opacity"]
            rec["ambient"] = _vec(w * (t * (ambient * np.array(rec["hit"]["ka"]))))
            for lt in rec["lights"]:
                s = np.zeros(3) if lt["shadow"] is None else np.array(lt["shadow"])
                lt["contribution"] = _vec(w * (t * (np.array(lt["term"]) * s
                                                    * np.array(lt["color"]))))
            rec["contribution"] = _vec(contribution[j])
            rec["tir"] = bool(tir[j])
            rec["pruned"] = []
            for c, name in enumerate(CHILD_NAMES):
                reason = ("max_depth" if status[j, c] == KEEP and past_max_depth
                          else "min_weight" if status[j, c] == PRUNED else None)
                if reason:
                    rec["pruned"].append({"kind": name, "weight": _vec(weights[c][j]),
                                          "reason": reason})

    def spawned(self, children: Any, parent: np.ndarray) -> None:
        """The next depth's rays; ``parent[i]``: the row (in hit order) of child i's hit."""
        self._next = [self._new(children, i, self._hits[int(parent[i])])
                      for i in range(len(children))]

    # -- records ------------------------------------------------------------------------------
    def _new(self, rays: Any, i: int, parent: int | None) -> int:
        rid = len(self.rays)
        self.rays.append({
            "id": rid, "parent": parent, "kind": KIND_NAMES[int(rays.kind[i])],
            "depth": int(rays.depth), "origin": _vec(rays.origin[i] + self.origin),
            "direction": _vec(rays.direction[i]), "weight": _vec(rays.weight[i]),
            "children": []})
        if parent is not None:
            self.rays[parent]["children"].append(rid)
        return rid


def _rows(rays: Any) -> Any:
    """The batch with its ``sample`` column replaced by 0 … n − 1: the AOV kernel then
    writes hit j into row j."""
    from dataclasses import replace

    return replace(rays, sample=np.arange(len(rays), dtype=np.int64))


def explain(scene: Scene, pixel: tuple[int, int], sample: int = 0, **overrides: Any) -> dict:
    """The ray tree of sample ``sample`` of pixel ``pixel`` = (x, y) (column, row; (0, 0) the
    top-left pixel), as a dictionary (what ``raytrace explain --json`` prints):

    ``value``: the sample's RGB; ``pixel_value``: the pixel as rendered (float32, the mean of
    its ``spp`` samples); ``rays``: every ray traced, in order, each with ``id``, ``parent``,
    ``kind``, ``depth``, ``origin``, ``direction``, ``weight``, ``hit`` (None on a miss, else
    object, type, material, distance, side, point, normal, kd, ka, opacity), ``background``
    (misses), ``ambient``, ``lights`` (each emitter's ``term``, ``shadow`` factor — None where
    no shadow ray was cast, ``color`` and ``contribution`` = w·t·term·S·I), ``tir``,
    ``children`` (ids), ``pruned`` and ``contribution``: what the ray itself added to the
    sample. The contributions sum to ``value``.

    ``overrides``: ``width``, ``height``, ``spp``, ``max_depth``, ``min_weight``, ``seed``,
    as for :func:`raytrace.render`.
    """
    options = render_options(scene, threads=1, **overrides)
    x, y = _pixel(pixel, options.width, options.height, scene.path)
    s = _sample(sample, options.spp, scene.path)
    options.crop = (x, y, x + 1, y + 1)
    # One uniform sample of the pixel, traced alone: no filter margin, no adaptive lattice.
    options.filter, options.aa = "box", "uniform"
    integ = WhittedIntegrator(scene, options)
    integ.observer = recorder = Recorder(integ)
    value = np.zeros((1, 3))
    integ.trace_samples(s, s + 1, value)
    integ.observer = None
    pixel_value = integ.render().rgb[0, 0]
    return {
        "scene": scene.path or "<python>", "pixel": [x, y], "sample": s,
        "width": options.width, "height": options.height, "spp": options.spp,
        "max_depth": options.max_depth, "min_weight": options.min_weight, "seed": options.seed,
        "value": _vec(value[0]), "pixel_value": _vec(pixel_value), "rays": recorder.rays,
    }


def _pixel(pixel: Any, width: int, height: int, path: str | None) -> tuple[int, int]:
    try:
        if isinstance(pixel, str) or len(pixel) != 2:
            raise SceneError(f"must be two numbers (x, y), got {pixel!r}", "pixel")
        x, y = (values.number(v, "pixel", integer=True) for v in pixel)
    except TypeError:
        raise SceneError(f"must be two numbers (x, y), got {pixel!r}", "pixel", path) from None
    except SceneError as e:
        raise SceneError(e.problem, e.key, path) from None
    if not (0 <= x < width and 0 <= y < height):
        raise SceneError(f"({x}, {y}) is outside the {width}x{height} image (0 <= X < "
                         f"{width}, 0 <= Y < {height})", "pixel", path)
    return x, y


def _sample(sample: Any, spp: int, path: str | None) -> int:
    try:
        return values.number(sample, "sample", lo=0, hi=spp - 1, integer=True)
    except SceneError as e:
        raise SceneError(f"{e.problem} (the pixel has {spp} sample{'s' * (spp > 1)})",
                         "sample", path) from None


def _fmt(v: list[float]) -> str:
    return " ".join(f"{x:.6g}" for x in v)


def format_tree(report: dict) -> str:
    """The report of :func:`explain` as an indented tree, one ray per block, children
    indented under their parent."""
    lines = [f"{report['scene']}: pixel ({report['pixel'][0]}, {report['pixel'][1]}) sample "
             f"{report['sample']} of {report['spp']} ({report['width']}x{report['height']}, "
             f"max depth {report['max_depth']}, min weight {report['min_weight']:g})",
             f"value        {_fmt(report['value'])}   (the sum of the contributions below)",
             f"pixel        {_fmt(report['pixel_value'])}   (as rendered: the mean of "
             f"{report['spp']} sample{'s' * (report['spp'] > 1)}, float32)"]
    rays = report["rays"]

    def block(rec: dict, pad: str) -> None:
        lines.append(f"{pad}#{rec['id']} {rec['kind']} ray, depth {rec['depth']}, "
                     f"weight {_fmt(rec['weight'])}")
        more = pad + "   "
        lines.append(f"{more}from {_fmt(rec['origin'])} along {_fmt(rec['direction'])}")
        hit = rec.get("hit")
        if hit is None:
            lines.append(f"{more}misses: background {_fmt(rec['background'])}")
        else:
            tri = f", triangle {hit['triangle']}" if "triangle" in hit else ""
            lines.append(f"{more}hits objects[{hit['object']}] ({hit['type']}{tri}), material "
                         f"{hit['material']!r}, distance {hit['distance']:.6g}, from "
                         f"{hit['side']}")
            lines.append(f"{more}at {_fmt(hit['point'])}, normal {_fmt(hit['normal'])}, "
                         f"opacity {hit['opacity']:g}")
            lines.append(f"{more}ambient  ka {_fmt(hit['ka'])} -> {_fmt(rec['ambient'])}")
            for lt in rec["lights"]:
                shadow = "no shadow ray" if lt["shadow"] is None else (
                    f"shadow {_fmt(lt['shadow'])}")
                lines.append(f"{more}{lt['light']}  term {_fmt(lt['term'])}, {shadow}, "
                             f"I {_fmt(lt['color'])} -> {_fmt(lt['contribution'])}")
            for pr in rec["pruned"]:
                lines.append(f"{more}{pr['kind']} child of weight {_fmt(pr['weight'])} pruned "
                             f"by {pr['reason']}")
            if rec["tir"]:
                lines.append(f"{more}total internal reflection: the kt share is reflected")
        lines.append(f"{more}contribution {_fmt(rec['contribution'])}")
        for child in rec.get("children", []):
            block(rays[child], pad + "  ")

    for rec in rays:
        if rec["parent"] is None:
            block(rec, "")
    total = np.sum([r["contribution"] for r in rays], axis=0) if rays else np.zeros(3)
    lines.append(f"sum of the {len(rays)} contributions {_fmt(_vec(total))}")
    if not all(math.isfinite(v) for v in report["value"]):
        lines.append("(the value is not finite: the pixel is stored as 0)")
    return "\n".join(lines)
