"""Materials: the coefficients of the seeds' local model and of Whitted's recursion.

A :class:`Material` holds per-channel colours ``ka kd ks kr kt`` (each a constant RGB or a
:class:`Checker` pattern), the highlight exponent ``shininess`` with its model (``"phong"``
(V·R)^n, Phong 1975; ``"blinn"`` (N·H)^n, Blinn 1977; ``"blinn_cosine"`` (N·H)^n·(N·L), the
lobe inside the reflectance equation, as glTF materials map), the index of refraction and the
opacity t of the blend ``I = t·I_surface + (1 − t)·I_behind`` (seed 003); what lies behind
the surface: an interior that absorbs by Beer's law (``attenuation_color`` after
``attenuation_distance``, KHR_materials_volume; POV-Ray's ``fade_color``/``fade_distance``)
or a thin wall (``thin_walled``: light passes without bending, KHR_materials_transmission),
read by :mod:`raytrace.kernels.medium`.

The named library lives in the top-level ``materials/`` folder, one TOML file per material
(its source in the file), and is shipped inside the wheel as ``raytrace/_materials``:

>>> from raytrace.material import library
>>> library["brass"].shininess
27.8974
"""

from __future__ import annotations

import dataclasses
import math
import tomllib
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from typing import Any

import numpy as np

from . import values
from .errors import SceneError
from .kernels.kinds import COLOR_KEYS, FRESNEL_CODES, HIGHLIGHT_CODES
from .kernels.records import MATERIAL_COLUMNS
from .readers.texture import WRAPS, Texture, parse_mapping, parse_texture

HIGHLIGHTS = tuple(HIGHLIGHT_CODES)
#: How kr and kt vary with the angle of incidence (``raytrace.kernels.core.fresnel_weights1``):
#: "none" constant; "schlick" kr + (1 − kr)(1 − cos θ)⁵ (Schlick 1994, F0 = kr); "dielectric"
#: kr·F and kt·(1 − F), F the exact unpolarised Fresnel reflectance for ``ior``.
FRESNELS = tuple(FRESNEL_CODES)
MATERIAL_KEYS = ("base", *COLOR_KEYS, "shininess", "highlight", "ior", "opacity", "fresnel",
                 "attenuation_color", "attenuation_distance", "thin_walled",
                 "normal_map", "bump")
LIBRARY_ONLY_KEYS = ("description", "source")


@dataclass(frozen=True, eq=False)
class Checker:
    """A 3-D world-space checker (SCENE_FORMAT.md).

    ``colors[0]`` where ``floor(x/s + 1e-4) + floor(y/s + 1e-4) + floor(z/s + 1e-4)`` is even,
    else ``colors[1]``; the 1e-4 keeps a plane lying on a cell boundary on one side. With
    ``filter = "box"`` a hit takes the mean of the pattern over the box around its camera
    sample's ray-cone footprint (pbrt-v3's closed-form filtered checkerboard;
    ``raytrace.kernels.material.color1``): cells smaller than a pixel average out instead of
    beating into moiré.
    """

    colors: tuple[np.ndarray, np.ndarray]
    scale: float = 1.0
    filter: str = "none"

    def __post_init__(self) -> None:
        # The checks of the table form (same rules, same messages), made where the value
        # enters; a kr or kt checker is checked against [0, 1] again by its Material.
        try:
            colors, scale, kind = _checker_fields(self.colors, self.scale, self.filter, "")
        except SceneError as e:
            raise e.at(key_prefix="Checker") from None
        object.__setattr__(self, "colors", colors)
        object.__setattr__(self, "scale", scale)
        object.__setattr__(self, "filter", kind)

    @property
    def max(self) -> np.ndarray:
        return np.maximum(self.colors[0], self.colors[1])


Color = np.ndarray | Checker
PATTERN_KEYS = ("pattern", "colors", "scale", "filter")
#: A checker's filters by their ``filter`` name, as ``Materials.checkers`` codes them: none
#: (the cell's colour at the point) or box (the pattern's mean over the camera sample's footprint).
CHECKER_FILTERS = {"none": 0.0, "box": 1.0}
#: The keys of a ``normal_map`` or ``bump`` table.
RELIEF_KEYS = ("texture", "scale", "wrap", "uv_set", "uv_offset", "uv_rotation",
               "uv_scale")


@dataclass(frozen=True, eq=False)
class Relief:
    """A texture that perturbs the shading normal, its texels read as linear values (never
    sRGB-decoded): a tangent-space normal map (``normal_map``, glTF ``normalTexture``, MTL
    ``norm``; ``scale`` multiplies the texel's x and y, glTF's ``normalTexture.scale``) or a
    height map (``bump``, MTL ``bump``/``map_Bump``; ``scale`` the height in scene units of a
    texel value 1, MTL's ``-bm``). docs/shading.md has the formulas."""

    texture: Texture
    scale: float = 1.0

    def __post_init__(self) -> None:
        if not isinstance(self.texture, Texture):
            raise SceneError("must be a raytrace.readers.texture.Texture", "texture")
        object.__setattr__(self, "scale", values.number(self.scale, "scale"))


def parse_relief(value: Any, key: str) -> Relief | None:
    """``{ texture = "file.png", scale = 1.0, wrap = "repeat" | "clamp" | "mirror" }`` (the
    texels linear) with a colour texture's mapping keys (``uv_set``, ``uv_offset``,
    ``uv_rotation``, ``uv_scale``: :func:`raytrace.readers.texture.parse_mapping`), a
    :class:`Relief`, or None."""
    if value is None or isinstance(value, Relief):
        return value
    if not isinstance(value, Mapping) or "texture" not in value:
        raise SceneError("must be a table { texture = \"file.png\", scale = 1.0 }", key)
    values.check_keys(value, RELIEF_KEYS, key)
    wrap = values.string(value.get("wrap", "repeat"), f"{key}.wrap", WRAPS)
    file = Path(values.string(value["texture"], f"{key}.texture"))
    texture = Texture.from_file(file, f"{key}.texture", srgb=False, wrap=(wrap, wrap))
    texture = texture.mapped(*parse_mapping(value, key))
    try:
        return Relief(texture, value.get("scale", 1.0))
    except SceneError as e:
        raise SceneError(e.problem, f"{key}.{e.key}") from None


def parse_color(value: Any, key: str, *, hi: float | None = None) -> Color:
    """A colour, an inline pattern table ``{ pattern = "checker", colors, scale, filter }`` or
    an image texture ``{ texture = "file.png", wrap, srgb, scale }``
    (:mod:`raytrace.readers.texture`); a :class:`Checker` built in Python is checked by the
    same rules."""
    if isinstance(value, Checker):
        value = {"pattern": "checker", "colors": list(value.colors), "scale": value.scale,
                 "filter": value.filter}

    if isinstance(value, Texture):
        return value
    if isinstance(value, Mapping) and "texture" in value:
        texture = parse_texture(value, key)
        if hi is not None and np.any(texture.max > hi):
            raise SceneError(f"texture values must be <= {hi:g}, got up to "
                             f"{texture.max.max():g}", key)
        return texture
    if isinstance(value, Mapping):
        values.check_keys(value, PATTERN_KEYS, key)
        values.string(value.get("pattern"), f"{key}.pattern", ["checker"])
        return Checker(*_checker_fields(value.get("colors"), value.get("scale", 1.0),
                                        value.get("filter", "none"), key, hi))
    return values.color(value, key, hi=hi)


def _checker_fields(cols: Any, scale: Any, kind: Any, key: str, hi: float | None = None
                    ) -> tuple[tuple[np.ndarray, np.ndarray], float, str]:
    """A checker's two colours (each ≥ 0, and ≤ ``hi``), its cell size (a
    :func:`raytrace.values.length`) and its filter (:data:`CHECKER_FILTERS`), checked."""
    where = f"{key}." if key else ""
    if not isinstance(cols, (list, tuple)) or len(cols) != 2:
        raise SceneError("must be a list of two colours", f"{where}colors")
    pair = tuple(values.color(c, f"{where}colors[{i}]", hi=hi) for i, c in enumerate(cols))
    return (pair, values.length(scale, f"{where}scale"),
            values.string(kind, f"{where}filter", list(CHECKER_FILTERS)))


@dataclass(eq=False)
class Material:
    """Coefficients of one surface; scalars become grey colours, ``ka=None`` follows ``kd``."""

    kd: Any = 0.5
    ka: Any = None
    ks: Any = 0.0
    shininess: float = 32.0
    highlight: str = "phong"
    kr: Any = 0.0
    kt: Any = 0.0
    ior: float = 1.5
    opacity: float = 1.0
    ke: Any = 0.0
    fresnel: str = "none"
    #: A texture whose alpha channel multiplies ``opacity`` per hit (glTF alphaMode BLEND),
    #: or with ``alpha_cutoff`` ≥ 0 makes it 1 or 0 (MASK); Python and model files only.
    alpha: Any = None
    alpha_cutoff: float = -1.0
    #: Beer's law inside the surface: light keeps ``attenuation_color`` (RGB in (0, 1]) of
    #: itself per ``attenuation_distance`` travelled inside (> 0; inf: a clear interior).
    attenuation_color: Any = 1.0
    attenuation_distance: float = math.inf
    #: A thin wall: a transmitted ray goes straight on, nothing is absorbed.
    thin_walled: bool = False
    #: A tangent-space normal map or a height map (a :class:`Relief`, or its table in a scene
    #: file), or None; a material has at most one of the two.
    normal_map: Any = None
    bump: Any = None
    #: A texture whose RGB multiplies the ambient term ka per hit (glTF occlusionTexture,
    #: made by :meth:`raytrace.readers.texture.Texture.occlusion`); Python and model files only.
    occlusion: Any = None
    #: The colours a mesh's vertex colours multiply (glTF COLOR_0 multiplies the base colour:
    #: kd and the ka that follows it, and a metal's ks and kr); Python and model files only.
    vertex_colors: tuple[str, ...] = ("ka", "kd")
    name: str = field(default="", compare=False)
    #: The library files this material was read from (its own and its bases'): inputs that
    #: no output of a render may overwrite.
    sources: tuple[Path, ...] = field(default=(), compare=False, repr=False, init=False)

    @property
    def branches(self) -> int:
        """How many rays a hit on this surface can spawn (Whitted's tree, Hall & Greenberg
        1983): reflected (``kr`` not zero), refracted (``kt`` not zero) and seen through
        (``opacity`` under 1, or an alpha texture); a pattern counts as not zero."""
        def spawns(k: Any) -> bool:
            return not isinstance(k, np.ndarray) or bool(np.any(k))

        return (spawns(self.kr) + spawns(self.kt)
                + (self.opacity < 1 or self.alpha is not None))

    def __post_init__(self) -> None:
        where = f"material {self.name!r}" if self.name else "Material"
        for k in COLOR_KEYS:
            v = getattr(self, k)
            if v is None and k == "ka":
                continue
            hi = 1.0 if k in ("kr", "kt") else None
            try:
                object.__setattr__(self, k, parse_color(v, k, hi=hi))
            except SceneError as e:
                raise e.at(key_prefix=where) from None
        try:
            self.shininess = values.number(self.shininess, "shininess", lo=0)
            self.highlight = values.string(self.highlight, "highlight", HIGHLIGHTS)
            self.ior = values.number(self.ior, "ior", lo=0, lo_open=True)
            self.opacity = values.number(self.opacity, "opacity", lo=0, hi=1)
            self.fresnel = values.string(self.fresnel, "fresnel", FRESNELS)
            self.alpha_cutoff = values.number(self.alpha_cutoff, "alpha_cutoff", lo=-1, hi=1)
            self.vertex_colors = tuple(values.string(k, "vertex_colors", COLOR_KEYS)
                                       for k in self.vertex_colors)
            for k in ("alpha", "occlusion"):
                if getattr(self, k) is not None and not hasattr(getattr(self, k), "texels"):
                    raise SceneError("must be a raytrace.readers.texture.Texture or None", k)
            self._check_interior()
            for key in ("normal_map", "bump"):
                object.__setattr__(self, key, parse_relief(getattr(self, key), key))
            if self.normal_map is not None and self.bump is not None:
                raise SceneError("a material takes normal_map or bump, not both", "bump")
        except SceneError as e:
            raise e.at(key_prefix=where) from None

    def _check_interior(self) -> None:
        """``attenuation_color`` in (0, 1] per channel, ``attenuation_distance`` > 0 or inf,
        ``thin_walled`` a boolean, and no absorption in a thin wall (it has no inside)."""
        c = values.color(self.attenuation_color, "attenuation_color", hi=1.0)
        if not np.all(c > 0):
            raise SceneError("must be > 0 in every channel (the range is (0, 1]; 0 would "
                             f"absorb everything at once), got {c.tolist()}",
                             "attenuation_color")
        self.attenuation_color = c
        d = self.attenuation_distance
        if not (isinstance(d, (float, np.floating)) and d == math.inf):
            d = values.number(d, "attenuation_distance", lo=0, lo_open=True)
        self.attenuation_distance = float(d)
        self.thin_walled = values.boolean(self.thin_walled, "thin_walled")
        if self.thin_walled and self.absorbs:
            raise SceneError("a thin wall has no inside to absorb in: leave out "
                             "attenuation_color and attenuation_distance, or set "
                             "thin_walled = false", "thin_walled")

    @property
    def sigma(self) -> np.ndarray:
        """Beer's law coefficient per unit length, per channel: ``σ = −ln(attenuation_color)
        / attenuation_distance`` (KHR_materials_volume), 0 for a clear interior."""
        return -np.log(self.attenuation_color) / self.attenuation_distance + 0.0

    @property
    def absorbs(self) -> bool:
        """Its interior absorbs (some channel of attenuation_color under 1 at a finite
        distance)."""
        return math.isfinite(self.attenuation_distance) and bool(
            np.any(self.attenuation_color < 1))

    @property
    def ambient(self) -> Color:
        """ka, or kd where ka was omitted."""
        return self.kd if self.ka is None else self.ka

    def _is_zero(self, c: Color) -> bool:
        return not np.any(c.max if hasattr(c, "max") and not isinstance(c, np.ndarray) else c)

    @property
    def reflects(self) -> bool:
        return not self._is_zero(self.kr) and self.opacity > 0

    @property
    def transmits(self) -> bool:
        return not self._is_zero(self.kt) and self.opacity > 0

    @property
    def emits(self) -> bool:
        return not self._is_zero(self.ke)

    @property
    def see_through(self) -> bool:
        return self.opacity < 1 or self.alpha is not None

    @property
    def invisible(self) -> bool:
        """Not drawn at all: opacity 0 and no alpha texture (I = 0·I_surface + I_behind, and
        shadow rays pass with factor 1)."""
        return self.opacity == 0 and self.alpha is None

    @property
    def transparent(self) -> bool:
        """Lets shadow rays through (factor t·kt + 1 − t > 0 somewhere)."""
        return self.transmits or self.see_through

    @property
    def lit(self) -> bool:
        """Has a term that lights affect (kd or ks non-zero)."""
        return not (self._is_zero(self.kd) and self._is_zero(self.ks))

    @property
    def textures(self) -> list[Texture]:
        """Every image texture the material reads: its colours', its alpha's, its
        occlusion's."""
        return [t for t in (*(getattr(self, k) for k in COLOR_KEYS), self.alpha,
                            self.occlusion) if isinstance(t, Texture)]

    @property
    def files(self) -> tuple[Path, ...]:
        """The files this material was read from: its library files and its textures'."""
        read = (*self.textures, *(r.texture for r in self.reliefs))
        return (*self.sources, *(t.file for t in read if t.file is not None))

    @property
    def reliefs(self) -> tuple[Relief, ...]:
        """The normal or height map, if the material has one."""
        return tuple(r for r in (self.normal_map, self.bump) if r is not None)

    def replace(self, **changes: Any) -> Material:
        return dataclasses.replace(self, **changes)


#: The material table's per-material columns (:class:`raytrace.kernels.records.Materials` has one
#: field each, declared with its dtype in ``records.MATERIAL_COLUMNS``;
#: :class:`raytrace.tables.MaterialTable` fills them): name → its value for a Material. A
#: scalar input is its Material field (with its check and its MATERIAL_KEYS entry for scene
#: files), one line here, one in ``MATERIAL_COLUMNS`` and its use in the shading kernels
#: (docs/architecture.md); a colour input is a COLOR_KEYS entry instead.
COLUMNS: dict[str, Callable[[Material], Any]] = {
    "shininess": lambda m: m.shininess,
    "highlight": lambda m: HIGHLIGHT_CODES[m.highlight],
    "ior": lambda m: m.ior,
    "opacity": lambda m: m.opacity,
    "lit": lambda m: m.lit,
    "reflects": lambda m: m.reflects,
    "transmits": lambda m: m.transmits,
    "emits": lambda m: m.emits,
    "fresnel": lambda m: FRESNEL_CODES[m.fresnel],
    "alpha_cutoff": lambda m: m.alpha_cutoff,
}
assert tuple(COLUMNS) == tuple(MATERIAL_COLUMNS), "one column list: records.MATERIAL_COLUMNS"


def material_from_table(table: Mapping, key: str,
                        resolve: Callable[[str, str], Material] | None = None,
                        name: str = "", extra_keys: tuple[str, ...] = ()) -> Material:
    """A material from a scene/library table, starting from ``base`` when given.

    ``resolve(name, key)`` looks up a base material by name.
    """
    values.check_keys(table, (*MATERIAL_KEYS, *extra_keys), key)
    fields: dict[str, Any] = {k: table[k] for k in MATERIAL_KEYS if k in table and k != "base"}
    if "base" in table:
        base_name = values.string(table["base"], f"{key}.base")
        if resolve is None:
            raise SceneError("no materials to take a base from", f"{key}.base")
        base = resolve(base_name, f"{key}.base")
        fields = {**{f.name: getattr(base, f.name) for f in dataclasses.fields(base) if f.init},
                  **fields}
    fields["name"] = name
    try:
        material = Material(**fields)
    except SceneError as e:
        # Material() names the key as "Material.kd" etc.; re-root it at the table's key.
        k = e.key or ""
        k = k.split(".", 1)[1] if k.startswith(("Material.", "material ")) and "." in k else k
        raise SceneError(e.problem, f"{key}.{k}" if k else key) from None
    if "base" in table:
        material.sources = base.sources
    return material


def _library_folder() -> Path:
    """``raytrace/_materials`` in a wheel, else the checkout's top-level ``materials/``."""
    here = Path(__file__).resolve().parent
    packaged = here / "_materials"
    return packaged if packaged.is_dir() else here.parent / "materials"


class MaterialLibrary(Mapping):
    """The named materials: ``library["brass"]``; iterating gives the names, sorted."""

    def __init__(self, folder: Path | None = None):
        self.folder = Path(folder) if folder is not None else _library_folder()
        self._cache: dict[str, Material] = {}

    @cached_property
    def _files(self) -> dict[str, Path]:
        if not self.folder.is_dir():
            return {}
        return {p.stem: p for p in sorted(self.folder.glob("*.toml"))}

    def __getitem__(self, name: str) -> Material:
        if name not in self._cache:
            path = self._files.get(name)
            if path is None:
                raise KeyError(name)
            self._cache[name] = self._load(name, path)
        return self._cache[name]

    def _load(self, name: str, path: Path) -> Material:
        try:
            table = tomllib.loads(path.read_text())
        except (OSError, tomllib.TOMLDecodeError) as e:
            raise SceneError(f"cannot read material: {e}", file=str(path)) from None
        try:
            material = material_from_table(table, "", self._resolve, name, LIBRARY_ONLY_KEYS)
        except SceneError as e:
            raise SceneError(e.problem, (e.key or "").lstrip("."), str(path)) from None
        material.sources = (path, *material.sources)
        return material

    def _resolve(self, name: str, key: str) -> Material:
        if name not in self:
            raise SceneError(f"unknown material {name!r}{values.did_you_mean(name, self)}", key)
        return self[name]

    def describe(self, name: str) -> dict[str, str]:
        """The ``description`` and ``source`` strings of a library material."""
        table = tomllib.loads(self._files[name].read_text())
        return {k: str(table.get(k, "")) for k in LIBRARY_ONLY_KEYS}

    def __contains__(self, name: object) -> bool:
        return name in self._files

    def __iter__(self) -> Iterator[str]:
        return iter(self._files)

    def __len__(self) -> int:
        return len(self._files)


#: The library of named materials shipped with raytrace.
library = MaterialLibrary()
