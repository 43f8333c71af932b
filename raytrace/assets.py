"""Mesh files with their own materials: an OBJ with its MTL, a glTF/GLB file.

:func:`load_with_materials` gives an :class:`Asset`: the triangles, each face's material (an
index into the asset's materials) and, where the file has them, each face corner's texture
coordinates. A mesh object takes it with ``material = "from_file"``
(:class:`raytrace.Mesh`); ``raytrace render model.glb`` builds a whole scene from a glTF file
(:mod:`raytrace.gltf`). The OBJ is read by :func:`read_obj`, its MTL by :mod:`raytrace.mtl`.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from . import values
from .errors import RenderWarning, SceneError
from .material import Material

#: What a model file alone is rendered with: a grey world (a glTF or OBJ file has no
#: background) and a little ambient light, so the unlit sides are not black.
MODEL_BACKGROUND = 0.3
MODEL_AMBIENT = 0.1
#: Suffixes whose files carry their own materials.
OBJ_SUFFIXES = (".obj",)
GLTF_SUFFIXES = (".gltf", ".glb")


@dataclass
class Asset:
    """Triangles with per-face materials (object space)."""

    vertices: np.ndarray       #: (V, 3) float64
    faces: np.ndarray          #: (F, 3) int64
    face_material: np.ndarray  #: (F,) int64 index into ``materials``
    materials: list[Material]
    texcoords: np.ndarray | None = None  #: (F, 3, 2) per corner (s, t), t = 0 at the top
    #: Files read besides the mesh file (MTL, textures, glTF buffers): inputs no output
    #: may overwrite.
    sources: tuple[Path, ...] = ()


def load_with_materials(path: Path) -> Asset:
    """The triangles and materials of an OBJ (with its MTL) or glTF/GLB file."""
    suffix = path.suffix.lower()
    if suffix in OBJ_SUFFIXES:
        return load_obj(path)
    if suffix in GLTF_SUFFIXES:
        from .gltf import load_gltf

        return load_gltf(path).asset
    raise SceneError(f"material = \"from_file\" needs an OBJ (with its MTL) or a glTF/GLB "
                     f"file, got {path.name}", "material")


def read_obj(path: Path) -> dict:
    """The statements of an OBJ that carry triangles and materials (Wavefront, "Object Files
    (.obj)", Appendix B1 of the Advanced Visualizer manual): ``v``, ``vt``, ``f`` (polygons
    fanned into triangles; ``v``, ``v/vt``, ``v//vn``, ``v/vt/vn``; negative indices count
    back), ``usemtl``, ``mtllib``. Parsed here, not by trimesh: trimesh replaces a material
    it finds untextured by a default one and drops its name when Pillow is installed, so the
    faces could not be matched to their MTL materials.

    Returns ``vertices`` (V, 3), ``uv`` (VT, 2), ``faces`` (F, 3) and ``face_uv`` (F, 3)
    (−1: no vt) indices, ``face_name`` (F,) index into ``names`` (the usemtl names in order
    of use; "" before any usemtl), ``libs`` (the mtllib paths).
    """
    v: list = []
    vt: list = []
    faces: list = []
    fuv: list = []
    fname: list = []
    names: list[str] = []
    libs: list[Path] = []
    current = -1
    from .mtl import statements

    with open(path, encoding="utf-8", errors="replace") as f:
        for _, stmt, args, where in statements(f, path):
            try:
                if stmt == "v":
                    v.append([float(x) for x in args[:3]])
                    if len(v[-1]) != 3:
                        raise ValueError("needs x y z")
                elif stmt == "vt":
                    vt.append([float(x) for x in (args[:2] + ["0"])[:2]])
                elif stmt == "f":
                    corners = [_corner(w, len(v), len(vt)) for w in args]
                    if len(corners) < 3:
                        raise ValueError("needs at least 3 vertices")
                    if current < 0:
                        names.append("")
                        current = 0
                    for k in range(1, len(corners) - 1):  # a fan from the first corner
                        tri = (corners[0], corners[k], corners[k + 1])
                        faces.append([c[0] for c in tri])
                        fuv.append([c[1] for c in tri])
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
    return {"vertices": np.array(v, np.float64).reshape(-1, 3),
            "uv": np.array(vt, np.float64).reshape(-1, 2),
            "faces": np.array(faces, np.int64), "face_uv": np.array(fuv, np.int64),
            "face_name": np.array(fname, np.int64), "names": names, "libs": libs}


def _corner(word: str, n_v: int, n_vt: int) -> tuple[int, int]:
    """A face corner ``v[/vt[/vn]]`` as 0-based (vertex, texture vertex or −1)."""
    parts = word.split("/")

    def index(text: str, n: int, what: str) -> int:
        i = int(text)
        i = i - 1 if i > 0 else n + i
        if not 0 <= i < n:
            raise ValueError(f"{what} index {text} out of range 1..{n}")
        return i

    vi = index(parts[0], n_v, "vertex")
    ti = index(parts[1], n_vt, "texture vertex") if len(parts) > 1 and parts[1] else -1
    return vi, ti


def load_obj(path: Path) -> Asset:
    """An OBJ's faces with the materials their ``usemtl`` names in its ``mtllib`` files."""
    from .mtl import read_mtl
    from .texture import mtl_texture

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
    sources = tuple(obj["libs"]) + tuple(p for m in materials for p in m.files)
    return Asset(obj["vertices"], obj["faces"], obj["face_name"], materials, texcoords,
                 sources)


def scene_from_model(path: Path) -> Any:
    """A whole scene from a model file alone (``raytrace render model.glb``): the file's
    meshes with their own materials; its camera and lights (glTF) where it has them, else a
    camera framing the bounding box (:func:`framing_camera`) and a light over the camera's
    shoulder, both reported as a :class:`~raytrace.errors.RenderWarning` line."""
    from .scene import FROM_FILE, Camera, DirectionalLight, Mesh, RenderSettings, Scene

    path = Path(path)
    if not path.is_file():
        raise SceneError("model file not found", file=str(path))
    found = None
    if path.suffix.lower() in GLTF_SUFFIXES:
        from .gltf import load_gltf

        found = load_gltf(path)
    try:
        mesh = Mesh(file=path, material=FROM_FILE)
    except SceneError as e:
        raise SceneError(e.problem, e.key if e.file else None, e.file or str(path)) from None
    render = RenderSettings()
    notes = []
    if found is not None and found.camera is not None:
        cam = found.camera
        camera = Camera(cam["position"], cam["look_at"], cam["up"], cam["fov"])
        if cam["aspect"]:
            render = RenderSettings(height=max(1, round(640 / cam["aspect"])))
    else:
        camera = framing_camera(mesh.vertices)
        notes.append(f"no camera in the file: camera at {_vec(camera.position)} looking at "
                     f"{_vec(camera.look_at)}, fov {camera.fov:g}")
    lights = list(found.lights) if found is not None else []
    if not lights:
        right, up, forward = camera.basis()
        lights = [DirectionalLight(direction=forward - 0.5 * up + 0.5 * right, color=1.0)]
        notes.append(f"no lights in the file: a directional light travelling "
                     f"{_vec(lights[0].direction)}")
    if notes:
        warnings.warn(f"{path}: " + "; ".join(notes), RenderWarning, stacklevel=2)
    render.background = values.color(MODEL_BACKGROUND, "background")
    return Scene(camera=camera, objects=[mesh], lights=lights, ambient=MODEL_AMBIENT,
                 render=render, path=str(path))


def framing_camera(vertices: np.ndarray, fov: float = 40.0) -> Any:
    """A camera that sees the whole bounding sphere of ``vertices``: looking at the box's
    centre from the front (+z), a little right and above, at the distance where the sphere
    of the box's half-diagonal r fills the vertical field of view, r / sin(fov/2)."""
    from .scene import Camera

    lo, hi = vertices.min(axis=0), vertices.max(axis=0)
    centre, r = (lo + hi) / 2, max(float(np.linalg.norm(hi - lo)) / 2, 1e-9)
    view = np.array([0.35, 0.3, 1.0]) / np.linalg.norm([0.35, 0.3, 1.0])
    return Camera(centre + view * r / np.sin(np.radians(fov / 2)), centre, (0, 1, 0), fov)


def _vec(v: np.ndarray) -> str:
    return "[" + ", ".join(f"{x:.4g}" for x in v) + "]"
