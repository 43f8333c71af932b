"""Wavefront OBJ with its MTL materials: the statements that carry triangles, texture
coordinates and materials (:func:`read_obj`), read into an :class:`~.asset.Asset`
(:func:`load_obj`)."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np

from ..errors import RenderWarning, SceneError
from ..material import Material
from .asset import Asset
from .inputs import read_text
from .mtl import read_mtl, statements
from .texture import mtl_texture

#: The statements of geometry that is not faces (points, lines, free-form curves and
#: surfaces): raytrace draws none of it, and a file with any is told which.
NOT_DRAWN = ("p", "l", "curv", "curv2", "surf")


def read_obj(path: Path) -> dict:
    """The statements of an OBJ that carry triangles and materials (Wavefront, "Object Files
    (.obj)", Appendix B1 of the Advanced Visualizer manual): ``v``, ``vt``, ``vn``, ``f`` (polygons
    fanned into triangles; ``v``, ``v/vt``, ``v//vn``, ``v/vt/vn``; negative indices count
    back), ``usemtl``, ``mtllib``; one warning names the statements of geometry it holds that
    is not faces (:data:`NOT_DRAWN`). Parsed here, not by trimesh: trimesh replaces a material
    it finds untextured by a default one and drops its name when Pillow is installed, so the
    faces could not be matched to their MTL materials.

    Returns ``vertices`` (V, 3), ``uv`` (VT, 2), ``vn`` (VN, 3), ``faces`` (F, 3),
    ``face_uv`` (F, 3) (−1: no vt) and ``face_vn`` (F, 3) (−1: no vn) indices,
    ``face_name`` (F,) index into ``names`` (the usemtl names in order of use; "" before
    any usemtl), ``libs`` (the mtllib paths).
    """
    v: list = []
    vt: list = []
    vn: list = []
    faces: list = []
    fuv: list = []
    fvn: list = []
    fname: list = []
    names: list[str] = []
    libs: list[Path] = []
    current = -1
    not_drawn: set[str] = set()
    text = read_text(path, "OBJ file", file=str(path), a="an", strict=False)
    for _, stmt, args, where in statements(text.splitlines(), path):
        if stmt in NOT_DRAWN:
            not_drawn.add(stmt)
        try:
            if stmt == "v":
                v.append([float(x) for x in args[:3]])
                if len(v[-1]) != 3:
                    raise ValueError("needs x y z")
            elif stmt == "vt":
                vt.append([float(x) for x in (args[:2] + ["0"])[:2]])
            elif stmt == "vn":
                vn.append([float(x) for x in args[:3]])
                if len(vn[-1]) != 3:
                    raise ValueError("needs x y z")
            elif stmt == "f":
                corners = [_corner(w, len(v), len(vt), len(vn)) for w in args]
                if len(corners) < 3:
                    raise ValueError(f"needs at least 3 vertices, got {len(corners)}")
                if current < 0:
                    names.append("")
                    current = 0
                for k in range(1, len(corners) - 1):  # a fan from the first corner
                    tri = (corners[0], corners[k], corners[k + 1])
                    faces.append([c[0] for c in tri])
                    fuv.append([c[1] for c in tri])
                    fvn.append([c[2] for c in tri])
                    fname.append(current)
            elif stmt == "usemtl":
                name = " ".join(args)
                if name not in names:
                    names.append(name)
                current = names.index(name)
            elif stmt == "mtllib":
                libs += [path.parent / n for n in args]
        except (ValueError, IndexError) as e:
            raise SceneError(f"{e}: {' '.join([stmt, *args])!r}", stmt, where) from None
    if not faces:
        raise SceneError(f"{path} holds no faces", "file")
    if not_drawn:
        warnings.warn(f"{path}: statements not drawn (raytrace draws faces only): "
                      f"{', '.join(s for s in NOT_DRAWN if s in not_drawn)}", RenderWarning,
                      stacklevel=2)
    return {"vertices": np.array(v, np.float64).reshape(-1, 3),
            "uv": np.array(vt, np.float64).reshape(-1, 2),
            "vn": np.array(vn, np.float64).reshape(-1, 3),
            "faces": np.array(faces, np.int64), "face_uv": np.array(fuv, np.int64),
            "face_vn": np.array(fvn, np.int64),
            "face_name": np.array(fname, np.int64), "names": names, "libs": libs}


def _corner(word: str, n_v: int, n_vt: int, n_vn: int) -> tuple[int, int, int]:
    """A face corner ``v[/vt[/vn]]`` as 0-based (vertex, texture vertex or −1, normal or
    −1)."""
    parts = word.split("/")

    def index(text: str, n: int, what: str) -> int:
        i = int(text)
        i = i - 1 if i > 0 else n + i
        if not 0 <= i < n:
            raise ValueError(f"{what} index {text} out of range 1..{n}")
        return i

    vi = index(parts[0], n_v, "vertex")
    ti = index(parts[1], n_vt, "texture vertex") if len(parts) > 1 and parts[1] else -1
    ni = index(parts[2], n_vn, "normal") if len(parts) > 2 and parts[2] else -1
    return vi, ti, ni


def names_mtl(path: Path) -> bool:
    """Whether an OBJ file names an MTL library (an ``mtllib`` statement), read line by line
    without parsing the rest."""
    with open(path, encoding="utf-8", errors="replace") as f:
        return any(line.split(None, 1)[:1] == ["mtllib"] for line in f)


def load_obj(path: Path) -> Asset:
    """An OBJ's faces with the materials their ``usemtl`` names in its ``mtllib`` files."""
    obj = read_obj(path)
    if not obj["libs"]:
        raise SceneError(f"{path} names no MTL file (mtllib): no materials to take",
                         "material")
    library: dict[str, Material] = {}
    for lib in obj["libs"]:
        library.update(read_mtl(lib, mtl_texture))
    materials = []
    for name in obj["names"]:
        if name and name not in library:
            raise SceneError(f"usemtl {name!r}: no such material in "
                             f"{', '.join(map(str, obj['libs']))}", "file", str(path))
        materials.append(library[name] if name else Material(name="default"))
    texcoords = None
    if len(obj["uv"]):
        # OBJ's t runs up the image; a texture's rows run down it. No vt: (0, 0).
        uv = np.vstack([obj["uv"] * [1.0, -1.0] + [0.0, 1.0], [[0.0, 0.0]]])
        texcoords = uv[obj["face_uv"]]
    normals = None
    if (obj["face_vn"] >= 0).any():  # a corner without vn: zeros, shaded with its face's
        normals = np.vstack([obj["vn"], [[0.0, 0.0, 0.0]]])[obj["face_vn"]]
    sources = tuple(obj["libs"]) + tuple(p for m in materials for p in m.files)
    return Asset(obj["vertices"], obj["faces"], obj["face_name"], materials, texcoords,
                 sources, normals)
