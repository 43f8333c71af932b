"""Wavefront MTL materials: the statements of an ``.mtl`` file mapped onto :class:`Material`.

The MTL illumination models (Wavefront, "MTL material format", Lewis 1995 revision, the
``illum`` statement) are this renderer's model: a Phong/Blinn highlight, ray-traced reflection
and ray-traced refraction. :data:`ILLUM` maps each of ``illum 0``–``10`` onto ka, kd, ks,
shininess, kr, kt, ior, opacity and the Fresnel weighting; docs/scene_format.md has the table.

The file is parsed here, line by line (trimesh's OBJ loader reads MTL files too, but keeps
``Ni``, ``d``, ``Tf`` and ``illum`` only as unchecked strings, with no line numbers for an
error): ``newmtl``, ``Ka``, ``Kd``, ``Ks``, ``Ke``, ``Ns``, ``Ni``, ``d``, ``Tr``, ``Tf``,
``illum``, ``map_Kd`` and ``map_Ke`` (with ``-clamp on``, ``-o`` and ``-s``), ``map_d``
(an alpha texture), ``norm`` (a tangent-space normal map) and ``bump``/``map_Bump`` (a
height map, with ``-bm``). Statements that change the appearance but are not modelled
(``map_Ks``, ``refl``, ``sharpness``, …) are listed on one warning
line; a bad value is one :class:`~raytrace.errors.SceneError` naming the file, the line and
the statement.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from .. import values
from ..errors import RenderWarning, SceneError
from ..material import Material, Relief
from .inputs import read_text

#: Statements read as colours: ``Ka r [g b]``.
COLOR_STATEMENTS = ("Ka", "Kd", "Ks", "Ke", "Tf")
#: Statements read as one number, with their range.
NUMBER_STATEMENTS = {"Ns": (0.0, None), "Ni": (0.0, None), "d": (0.0, 1.0), "Tr": (0.0, 1.0)}
#: Statements that carry no appearance (or only for other renderers' features).
IGNORED = ("Pr", "Pm", "Ps", "Pc", "Pcr", "aniso", "anisor")
#: Defaults where a material omits a statement (Ka omitted follows Kd, as in scene files).
DEFAULTS: dict[str, Any] = {"Ka": None, "Kd": np.full(3, 0.8), "Ks": np.zeros(3),
                            "Ke": np.zeros(3), "Tf": np.ones(3), "Ns": 32.0, "Ni": 1.0,
                            "d": 1.0, "illum": 2, "map_Kd": None, "map_Ke": None,
                            "map_d": None, "norm": None, "bump": None}
#: Texture statements, each to the key its map is kept under (``map_Bump`` is ``bump``).
MAP_STATEMENTS = {"map_Kd": "map_Kd", "map_Ke": "map_Ke", "map_d": "map_d", "norm": "norm",
                  "bump": "bump", "map_Bump": "bump"}
#: Texture statements read: the image as the colour (map_Kd; map_Ke times Ke where given) or
#: as the dissolve (map_d, a scalar texture: its alpha, or its luminance where it has none).
MAPS = ("map_Kd", "map_Ke", "map_d")


#: The least highlight exponent: ``Ns`` below 1 is read as 1. The spec's ``Ks·(N·H)^Ns`` has no
#: N·L factor, so ``Ns 0`` (what exporters write for their roughest material) adds the whole
#: of ``Ks·I`` at every lit point: a flat white model. With the light at the eye (H = L) a
#: Blinn lobe weighted by the reflectance equation's N·L is ``(N·H)^(Ns + 1)``: exponent 1 at
#: Ns = 0, which the floor gives, falling off as Lambert's cosine (docs/scene_format.md,
#: "Rough materials stay matte").
MATTE_NS = 1.0


def _base(f: dict) -> dict:
    """ka, kd, Ke and the dissolve every model shares: ``Ka·Ia + Kd·Σ(N·L)I`` (illum 1); the
    highlight exponent for the models that have one (:data:`MATTE_NS`)."""
    return {"ka": f["Ka"], "kd": f["Kd"], "ke": f["Ke"], "opacity": f["d"], "ks": 0.0,
            "shininess": max(f["Ns"], MATTE_NS), "highlight": "blinn",
            "ior": max(f["Ni"], 1e-6)}


def _illum0(f: dict) -> dict:
    """Colour on, ambient off: the constant colour Kd, no lighting (as emission)."""
    return {**_base(f), "ka": 0.0, "kd": 0.0, "ke": f["Kd"] + f["Ke"]}


def _illum2(f: dict) -> dict:
    """+ Ks·Σ(N·H)^Ns·I: the Blinn highlight (the spec's H is the half vector)."""
    return {**_base(f), "ks": f["Ks"]}


def _illum3(f: dict) -> dict:
    """+ Ks·I_R: ray-traced reflection, kr = Ks."""
    return {**_illum2(f), "kr": np.clip(f["Ks"], 0, 1)}


def _illum5(f: dict) -> dict:
    """Fresnel reflection: kr = Ks rising to 1 at grazing (Schlick, F0 = Ks)."""
    return {**_illum3(f), "fresnel": "schlick"}


def _illum6(f: dict) -> dict:
    """+ (1 − Ks)·Tf·I_T: ray-traced refraction with ior Ni."""
    return {**_illum3(f), "kt": np.clip((1.0 - np.clip(f["Ks"], 0, 1)) * f["Tf"], 0, 1)}


def _illum7(f: dict) -> dict:
    """Refraction with Fresnel: reflected F, transmitted (1 − F)·Tf, F the dielectric Fresnel
    reflectance for Ni (the spec's Fr has no published formula); Ks drives the highlight."""
    return {**_illum2(f), "kr": 1.0, "kt": np.clip(f["Tf"], 0, 1), "fresnel": "dielectric"}


#: illum → the material of that model (Wavefront MTL, "Illumination models"). 4 and 9
#: ("glass on") dissolve with ``d`` as every model does; 8 has no reflection map to read and
#: is 2; 10 (shadow matte) is drawn as 2.
ILLUM: dict[int, Callable[[dict], dict]] = {
    0: _illum0, 1: _base, 2: _illum2, 3: _illum3, 4: _illum3, 5: _illum5, 6: _illum6,
    7: _illum7, 8: _illum2, 9: _illum2, 10: _illum2,
}


def _number(word: str, where: str, stmt: str, lo: float | None, hi: float | None) -> float:
    """A statement's number, checked as every scene value is (:func:`raytrace.values.number`)."""
    try:
        return values.number(float(word), stmt, lo=lo, hi=hi)
    except ValueError as e:  # (a SceneError is one)
        problem = e.problem if isinstance(e, SceneError) else f"must be a number, got {word!r}"
        raise SceneError(problem, stmt, where) from None


def _color(words: list[str], where: str, stmt: str) -> np.ndarray:
    if not words or words[0] in ("spectral", "xyz"):
        raise SceneError("needs r [g b] (spectral and xyz colours are not supported)", stmt,
                         where)
    if len(words) not in (1, 3):
        raise SceneError(f"needs 1 or 3 numbers, got {len(words)}", stmt, where)
    c = np.array([_number(w, where, stmt, 0.0, None) for w in words])
    return np.repeat(c, 3) if len(c) == 1 else c


def statements(lines, path: Path):
    """The statements of a Wavefront OBJ or MTL text, one a line: ``(number, stmt, args,
    where)`` for each line that is not blank or a comment (``#`` to the end of a line),
    ``where`` naming the file and the line ``number`` for error messages."""
    for number, line in enumerate(lines, 1):
        words = line.split("#", 1)[0].split()
        if words:
            yield number, words[0], words[1:], f"{path}: line {number}"


def read_mtl(path: Path, texture: Callable[[Path, dict, str, str], Any] | None = None
             ) -> dict[str, Material]:
    """The materials of an MTL file by name. ``texture(file, options, key, where)`` builds a
    ``map_Kd`` texture (none given: the map is an error)."""
    path = Path(path)
    lines = read_text(path, "MTL file", "mtllib", str(path), a="an",
                      strict=False).splitlines()
    tables: dict[str, dict] = {}
    unsupported: set[str] = set()
    current: dict | None = None
    for number, stmt, args, where in statements(lines, path):
        if stmt == "newmtl":
            if not args:
                raise SceneError("needs a material name", stmt, where)
            current = tables[" ".join(args)] = {"line": number}
            continue
        if current is None:
            raise SceneError("comes before any newmtl", stmt, where)
        if stmt in COLOR_STATEMENTS:
            current[stmt] = _color(args, where, stmt)
        elif stmt in NUMBER_STATEMENTS:
            if len(args) != 1:
                raise SceneError(f"needs one number, got {len(args)}", stmt, where)
            current[stmt] = _number(args[0], where, stmt, *NUMBER_STATEMENTS[stmt])
        elif stmt == "illum":
            if len(args) != 1 or not args[0].isdigit() or int(args[0]) not in ILLUM:
                raise SceneError(f"must be one of 0..10, got {' '.join(args)!r}", stmt, where)
            current[stmt] = int(args[0])
        elif stmt in MAP_STATEMENTS:
            current[MAP_STATEMENTS[stmt]] = _map_options(args, path.parent, where, stmt)
        elif stmt not in IGNORED:
            unsupported.add(stmt)
    if unsupported:
        warnings.warn(f"{path}: statements not modelled, drawn without them: "
                      f"{', '.join(sorted(unsupported))}", RenderWarning, stacklevel=2)
    out = {}
    for name, table in tables.items():
        f = {**DEFAULTS, **table}
        if "d" not in table and "Tr" in table:
            f["d"] = 1.0 - table["Tr"]
            if f["d"] == 0.0:
                warnings.warn(f"{path}: material {name!r} (line {table['line']}): Tr 1 makes it "
                              "fully transparent (Tr = 1 − d by the MTL spec), so it is not "
                              "drawn; Meshlab writes Tr 1 meaning opaque: write d 1 or Tr 0 "
                              "there to see it", RenderWarning, stacklevel=2)
        fields = ILLUM[f["illum"]](f)
        maps = {k: f[k] for k in MAPS if f[k] is not None}
        if maps and texture is None:
            raise SceneError("textures are not supported here", next(iter(maps)), str(path))
        read = {k: texture(*maps[k], k, f"{path}: material {name!r}") for k in maps}
        if "map_Kd" in read:
            fields["kd"] = read["map_Kd"]
            if f["Ka"] is None:
                fields["ka"] = None
        fields.update(_reliefs(f, texture, path, name))
        if "map_Ke" in read:  # the map times Ke where Ke is given (as map_Ka is, by the spec)
            fields["ke"] = read["map_Ke"].scaled(table["Ke"]) if "Ke" in table else read[
                "map_Ke"]
        if "map_d" in read:  # the map's alpha times d, blended (glTF BLEND's machinery)
            fields["alpha"] = read["map_d"]
        try:
            out[name] = Material(**fields, name=name)
        except SceneError as e:
            raise SceneError(e.problem, e.key, f"{path}: material {name!r} "
                             f"(line {table['line']})") from None
    return out


def _reliefs(f: dict, texture: Callable | None, path: Path, name: str) -> dict:
    """A material's ``norm`` (a tangent-space normal map) or ``bump``/``map_Bump`` (a height
    map, its values times ``-bm``: Blinn 1978) as ``normal_map`` or ``bump`` (a
    :class:`~raytrace.material.Relief`), their texels linear; ``norm`` where it has both
    (warned: a material takes one)."""
    out = {}
    for stmt, key in (("norm", "normal_map"), ("bump", "bump")):
        if f[stmt] is None:
            continue
        if texture is None:
            raise SceneError("textures are not supported here", stmt, str(path))
        if out:
            warnings.warn(f"{path}: material {name!r}: both norm and bump; drawn with norm "
                          "(a material takes one)", RenderWarning, stacklevel=3)
            break
        file, options = f[stmt]
        where = f"{path}: material {name!r}"
        out[key] = Relief(texture(file, {**options, "srgb": False}, stmt, where),
                          options.get("bm", 1.0))
    return out

def _map_options(args: list[str], folder: Path, where: str, stmt: str = "map_Kd"
                 ) -> tuple[Path, dict]:
    """``map_Kd [-clamp on|off] [-bm mult] [-o u [v [w]]] [-s u [v [w]]] file`` (and
    ``map_Ke``, ``map_d``, ``norm``, ``bump``, ``map_Bump``): the file (relative to the MTL
    file) and the options kept (``wrap`` from ``-clamp``; ``bm``; ``offset`` and ``scale``,
    (u, v), from ``-o`` and ``-s``, whose omitted v is 0 and 1 as the spec's defaults; w, a
    3-D texture's, is not read); other options are skipped with their values."""
    takes = {"-blendu": 1, "-blendv": 1, "-bm": 1, "-boost": 1, "-cc": 1, "-clamp": 1,
             "-imfchan": 1, "-mm": 2, "-o": 3, "-s": 3, "-t": 3, "-texres": 1}
    options: dict = {}
    i = 0
    while i < len(args) and args[i].startswith("-") and args[i] in takes:
        opt, n = args[i], takes[args[i]]
        vals = args[i + 1:i + 1 + n]
        if opt == "-clamp":
            options["wrap"] = "clamp" if vals and vals[0] == "on" else "repeat"
        if opt == "-bm":
            options["bm"] = _number(vals[0] if vals else "", where, f"{stmt} -bm", None, None)
        i += 1
        # -o/-s/-t take 1 to 3 numbers: read the ones present
        given = []
        while n and i < len(args) - 1 and _is_number(args[i]):
            given.append(args[i])
            i += 1
            n -= 1
        if opt in ("-o", "-s"):
            uv = [_number(w, where, f"{stmt} {opt}", None, None) for w in given[:2]]
            default = 0.0 if opt == "-o" else 1.0
            options["offset" if opt == "-o" else "scale"] = (*uv, *[default] * (2 - len(uv)))
    if i >= len(args):
        raise SceneError("needs a file name", stmt, where)
    return folder / " ".join(args[i:]), options


def _is_number(word: str) -> bool:
    try:
        float(word)
    except ValueError:
        return word in ("on", "off")
    return True
