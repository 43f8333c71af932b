"""The scene: camera, lights, objects, materials and render settings.

These are plain, validated dataclasses. A scene file (:mod:`raytrace.readers.scene_file`) and a
Python script build the same objects, so both get the same checks and the same error text. Geometry
stays in world coordinates here; :mod:`raytrace.accel` recentres it on the camera.
"""

from __future__ import annotations

import io
import math
import warnings
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from . import values
from .errors import SceneError
from .lights import LIGHT_TYPES, AreaLight, DirectionalLight, PointLight, SpotLight  # noqa: F401
from .material import Material, library, material_from_table
from .readers.asset import COLORED_SUFFIXES, GLTF_SUFFIXES
from .readers.assets import load_with_materials
from .readers.gltf import load_gltf
from .readers.inputs import input_file, read_text
from .readers.meshio import (
    MeshFile,
    merge_vertices,
    off_vertex_colors,
    read_mesh,
    vertex_colors,
)
from .readers.tangents import given_tangents
from .sampling import TEXTURE_FILTERS, check_aa, check_filter

#: Largest accepted image, in pixels (the float32 image alone is 12 bytes a pixel).
MAX_PIXELS = 100_000_000
MAX_SIDE = 100_000


@dataclass
class RenderSettings:
    """``[render]``: image size, sampling and recursion limits."""

    width: int = 640
    height: int = 480
    spp: int = 1
    max_depth: int = 5
    min_weight: float = 0.0
    background: Any = 0.0
    seed: int = 0
    #: The pixel reconstruction filter (:data:`raytrace.film.filters.FILTERS`).
    filter: str = "box"
    #: Anti-aliasing: "uniform" (``spp`` stratified samples a pixel) or "adaptive" (pixel
    #: corners, refined where they differ: :mod:`raytrace.adaptive`).
    aa: str = "uniform"
    #: Adaptive: refine a cell whose corners differ by this or more (any RGB channel).
    aa_threshold: float = 0.05
    #: Adaptive: the most times a pixel is halved (a 2^d × 2^d grid of cells at most).
    aa_depth: int = 2
    #: Adaptive: the times every pixel is halved whatever its corners (1: each pixel starts
    #: as 2×2 cells, so detail between its corners is seen); at most ``aa_depth``.
    aa_min_depth: int = 0
    #: Noise-driven sampling (``aa = "noise"``, :mod:`raytrace.noise`): a pixel whose error
    #: (Dammertz et al. 2010, as Cycles) is above this gets more samples.
    noise_threshold: float = 0.01
    #: Noise-driven: the samples every pixel gets first (even: half to each stream); None:
    #: :data:`raytrace.sampling.MIN_SPP` (8) by threshold,
    #: :data:`raytrace.sampling.MIN_SPP_GOAL` (4) by target error or time.
    min_spp: int | None = None
    #: Noise-driven: the most samples a pixel gets (even).
    max_spp: int = 1024
    #: Image-texture lookups (:data:`raytrace.sampling.TEXTURE_FILTERS`): "bilinear", or
    #: "trilinear" (mip-mapped by ray cones, :mod:`raytrace.mipmap`).
    texture_filter: str = "bilinear"

    def __post_init__(self) -> None:
        self.width = values.number(self.width, "render.width", lo=1, hi=MAX_SIDE, integer=True)
        self.height = values.number(self.height, "render.height", lo=1, hi=MAX_SIDE,
                                    integer=True)
        if self.width * self.height > MAX_PIXELS:
            raise SceneError(f"{self.width}x{self.height} is over the limit of "
                             f"{MAX_PIXELS:,} pixels", "render.width")
        self.spp = values.number(self.spp, "render.spp", lo=1, hi=65536, integer=True)
        self.max_depth = values.number(self.max_depth, "render.max_depth", lo=0, hi=1000,
                                       integer=True)
        self.min_weight = values.number(self.min_weight, "render.min_weight", lo=0)
        self.background = values.color(self.background, "render.background")
        self.seed = values.number(self.seed, "render.seed", lo=0, hi=2**63 - 1, integer=True)
        self.filter = check_filter(self.filter)
        self.aa = check_aa(self.aa)
        self.aa_threshold = values.number(self.aa_threshold, "render.aa_threshold", lo=0)
        self.aa_depth = values.number(self.aa_depth, "render.aa_depth", lo=0, hi=8,
                                      integer=True)
        self.aa_min_depth = values.number(self.aa_min_depth, "render.aa_min_depth", lo=0,
                                          hi=self.aa_depth, integer=True)
        if self.aa == "adaptive" and self.filter != "box":
            raise SceneError(f"must be box with aa = \"adaptive\" (its pixels are the area "
                             f"average of their cells), got {self.filter!r}", "render.filter")
        self.noise_threshold = values.number(self.noise_threshold, "render.noise_threshold",
                                             lo=0)
        if self.min_spp is not None:
            self.min_spp = values.number(self.min_spp, "render.min_spp", lo=2, hi=65536,
                                         integer=True)
        self.max_spp = values.number(self.max_spp, "render.max_spp", lo=self.min_spp or 2,
                                     hi=65536, integer=True)
        self.texture_filter = values.string(self.texture_filter, "render.texture_filter",
                                            TEXTURE_FILTERS)
        for key in ("min_spp", "max_spp"):
            if (getattr(self, key) or 0) % 2:
                raise SceneError(f"must be even (half of a pixel's samples go to each of its "
                                 f"two streams), got {getattr(self, key)}", f"render.{key}")


@dataclass
class Camera(values.Checked):
    """A pinhole camera; ``fov`` is the vertical field of view in degrees."""

    position: Any = (0.0, 0.0, 0.0)
    look_at: Any = (0.0, 0.0, -1.0)
    up: Any = (0.0, 1.0, 0.0)
    fov: float = 40.0

    def check(self) -> None:
        self.position = values.position(self.position, "camera.position")
        self.look_at = values.position(self.look_at, "camera.look_at")
        self.up = values.vector(self.up, "camera.up", nonzero=True)
        self.fov = values.number(self.fov, "camera.fov", lo=0, hi=180, lo_open=True,
                                 hi_open=True)
        forward = self.look_at - self.position
        if not np.any(forward):
            raise SceneError("must differ from camera.position", "camera.look_at")
        values.check_length(math.hypot(*forward), "camera.look_at",
                            "its distance to camera.position", longest=False)
        f = forward / np.linalg.norm(forward)
        u = self.up / np.linalg.norm(self.up)
        if np.linalg.norm(np.cross(f, u)) < 1e-9:
            raise SceneError("must not be parallel to the view direction "
                             "(look_at − position)", "camera.up")

    def basis(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Right, true-up and forward unit vectors (right-handed, forward = −w)."""
        w = self.position - self.look_at
        w = w / np.linalg.norm(w)
        right = np.cross(self.up, w)
        right /= np.linalg.norm(right)
        up = np.cross(w, right)
        return right, up, -w


@dataclass
class Sphere(values.Checked):
    """An analytic sphere, intersected in float64."""

    center: Any
    radius: float
    material: Any = None
    type = "sphere"

    def check(self) -> None:
        self.center = values.position(self.center, "center")
        self.radius = values.length(self.radius, "radius")

    def row(self, origin: np.ndarray) -> dict:
        """Its parameters as ``kernels.accel.sphere_t`` reads them, camera-relative, by the
        names of ``kernels.accel.SHAPE_COLUMNS``: the centre, the radius and the centre's
        largest absolute coordinate (its rounding scale)."""
        c = self.center - origin
        return {"centre": c, "radius": self.radius, "scale": np.abs(c).max()}


@dataclass
class Plane(values.Checked):
    """An infinite analytic plane through ``point``; ``normal`` is its outward side."""

    point: Any
    normal: Any
    material: Any = None
    type = "plane"

    def check(self) -> None:
        self.point = values.position(self.point, "point")
        self.normal = values.unit(self.normal, "normal")

    def row(self, origin: np.ndarray) -> dict:
        """Its parameters as ``kernels.accel.plane_t`` reads them, camera-relative, by the
        names of ``kernels.accel.SHAPE_COLUMNS``: the point, the unit normal and the point's
        largest absolute coordinate."""
        p = self.point - origin
        return {"point": p, "normal": self.normal, "scale": np.abs(p).max()}


@dataclass
class Disk(values.Checked):
    """A flat round analytic shape: the points of the plane through ``center`` with unit
    ``normal`` (its outward side) within ``radius`` of the centre; a lamp or a table top."""

    center: Any
    normal: Any
    radius: float
    material: Any = None
    type = "disk"

    def check(self) -> None:
        self.center = values.position(self.center, "center")
        self.normal = values.unit(self.normal, "normal")
        self.radius = values.length(self.radius, "radius")

    def row(self, origin: np.ndarray) -> dict:
        """Its parameters as ``kernels.accel.disk_t`` reads them, camera-relative, by the
        names of ``kernels.accel.SHAPE_COLUMNS``: a plane's (the centre, the unit normal, the
        centre's largest absolute coordinate) and the radius."""
        c = self.center - origin
        return {"centre": c, "normal": self.normal, "scale": np.abs(c).max(),
                "radius": self.radius}


#: The analytic shapes by their scene-file ``type``: a shape is one record (its fields are
#: its scene-file keys, ``row`` its parameters for the kernels) plus one line here, and its
#: kind, intersection and surface in ``kernels/accel.py`` (docs/architecture.md).
SHAPE_TYPES = {"sphere": Sphere, "plane": Plane, "disk": Disk}


#: ``shading`` names; "file": the normals the mesh file gives, interpolated as "smooth" (the
#: default where the file gives normals, "flat" where it gives none).
SHADINGS = ("flat", "smooth", "gouraud", "fast_phong", "file")
#: ``material = "from_file"``: a mesh file's own materials (OBJ + MTL, glTF), per face.
FROM_FILE = "from_file"


def rotation_matrix(degrees: np.ndarray) -> np.ndarray:
    """Rotation about the fixed world x, then y, then z axes: R = Rz·Ry·Rx."""
    ax, ay, az = np.radians(degrees)
    cx, sx, cy, sy, cz, sz = np.cos(ax), np.sin(ax), np.cos(ay), np.sin(ay), np.cos(az), np.sin(az)
    rx = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    ry = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    rz = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
    return rz @ ry @ rx


#: A mesh's per-corner arrays that follow its faces (reversed with a mirroring scale, dropped
#: with a zero-area face); the normals, which the transform changes too, are apart.
CORNER_ARRAYS = ("texcoords", "texcoords1", "colors")


@dataclass
class Mesh(values.Checked):
    """Triangles intersected by Embree.

    Give ``file`` (anything trimesh loads: OBJ, PLY, STL, glTF...), or ``vertices`` (V, 3) and
    ``faces`` (F, 3), or a ``trimesh.Trimesh`` as ``mesh``. The transform is
    scale → rotate → translate. Faces with zero area are dropped (and counted in the stats).

    After construction ``vertices`` (float64, world space, transformed) and ``faces`` (int64)
    hold the triangles; ``degenerate`` counts the dropped faces; ``normals`` the normals the
    file gives (OBJ ``vn``, glTF ``NORMAL``, PLY ``nx ny nz``) per face corner, and
    ``shading``, unless given, is ``"file"`` where the file gives normals, else ``"flat"``.
    """

    file: Any = None
    vertices: Any = None
    faces: Any = None
    mesh: Any = None
    shading: Any = None
    translate: Any = (0.0, 0.0, 0.0)
    rotate: Any = (0.0, 0.0, 0.0)
    scale: Any = 1.0
    material: Any = None
    degenerate: int = field(default=0, init=False)
    #: With ``material = "from_file"``: the file's own materials, each face's index into
    #: them, each face corner's texture coordinates (F, 3, 2) where the file has them, and
    #: the files read besides the mesh file (:class:`raytrace.readers.assets.Asset`).
    file_materials: list = field(default_factory=list, init=False, repr=False)
    face_material: Any = field(default=None, init=False, repr=False)
    texcoords: Any = field(default=None, init=False, repr=False)
    #: (F, 3, 3) unit world-space normals per face corner, as the file gives them (None where
    #: it gives none; a corner without one: zeros, shaded with its face's normal).
    normals: Any = field(default=None, init=False, repr=False)
    #: (F, 3, 4) unit world-space tangents and signs w per face corner, as the file gives
    #: them (glTF ``TANGENT``; None where it gives none; a corner without one: zeros, which
    #: takes MikkTSpace's, ``raytrace.tables.relief_tables``).
    tangents: Any = field(default=None, init=False, repr=False)
    #: With ``material = "from_file"``, per face corner where the file gives them: a second
    #: set of texture coordinates (F, 3, 2) (glTF TEXCOORD_1) and linear RGBA vertex colours
    #: (F, 3, 4) (glTF COLOR_0, which multiply kd and ka).
    texcoords1: Any = field(default=None, init=False, repr=False)
    colors: Any = field(default=None, init=False, repr=False)
    sources: tuple = field(default=(), init=False, repr=False)
    #: What the vertices were made from (file, mesh, and translate, rotate, scale as a 3×3
    #: array), for :meth:`check` to refuse a change of them that would not be seen.
    _made_from: tuple = field(default=(), init=False, repr=False, compare=False)
    type = "mesh"

    def __post_init__(self) -> None:
        given = [k for k in ("file", "vertices", "mesh") if getattr(self, k) is not None]
        if len(given) != 1:
            raise SceneError("give exactly one of file, vertices (with faces) or mesh",
                             "file" if not given else given[1])
        translate = values.position(self.translate, "translate")
        rotate = values.vector(self.rotate, "rotate")
        if isinstance(self.scale, (list, tuple, np.ndarray)):
            scale = values.vector(self.scale, "scale")
        else:
            scale = np.full(3, values.number(self.scale, "scale"))
        if not np.all(scale != 0):
            raise SceneError(f"must be non-zero, got {np.asarray(self.scale).tolist()}", "scale")
        self.translate, self.rotate, self.scale = translate, rotate, scale
        self._made_from = (self.file, self.mesh, np.stack([translate, rotate, scale]))

        from_file = isinstance(self.material, str) and self.material == FROM_FILE
        if from_file and self.file is None:
            raise SceneError(f'"{FROM_FILE}" needs a mesh file (file = ...)', "material")
        if from_file:
            verts, faces = self._load_with_materials(Path(self.file))
        elif self.file is not None:
            # (the file's vertex colours tint its own material only, as glTF COLOR_0's do)
            verts, faces, self.texcoords, self.normals = _load_mesh_file(Path(self.file))[:4]
        elif self.mesh is not None:
            verts, faces = _from_trimesh(self.mesh, "mesh")
        else:
            if self.faces is None:
                raise SceneError("is required with vertices", "faces")
            verts, faces = self.vertices, self.faces
        try:
            verts, faces = _check_arrays(verts, faces)
        except SceneError as e:  # name the key the user wrote: file or mesh, not vertices
            if self.file is not None:
                raise SceneError(f"{self.file}: {e.problem}", "file") from None
            if self.mesh is not None:
                raise SceneError(e.problem, "mesh") from None
            raise
        with np.errstate(over="ignore", invalid="ignore"):  # refused just below
            world = (verts * scale) @ rotation_matrix(rotate).T + translate
        values.check_points(world, "scale", "transformed vertices")
        values.check_length(values.span(world), "scale",
                            "the transformed mesh's size (its bounding box's longest side)",
                            longest=False)
        if self.normals is not None:  # numbered as the file's faces, before any is dropped
            check_normals(self.normals, self.file)
        if np.prod(np.sign(scale)) < 0:
            # A mirroring scale turns counter-clockwise into clockwise: reverse each face so
            # the winding still gives the outward normal (entering vs leaving for refraction).
            faces = faces[:, ::-1]
            for name in CORNER_ARRAYS:
                if getattr(self, name) is not None:
                    setattr(self, name, getattr(self, name)[:, ::-1])
            if self.normals is not None:
                self.normals = self.normals[:, ::-1]
            if self.tangents is not None:
                self.tangents = self.tangents[:, ::-1]
        keep = _nonzero_area(world, faces)
        self.degenerate = int((~keep).sum())
        if not keep.any():
            raise SceneError("has no triangle with non-zero area", "faces")
        self.vertices, self.faces = world, faces[keep]
        if from_file:
            self.face_material = self.face_material[keep]
        for name in CORNER_ARRAYS:
            if getattr(self, name) is not None:
                setattr(self, name, np.ascontiguousarray(getattr(self, name)[keep]))
        if self.normals is not None:
            self.normals = world_normals(self.normals[keep], rotate, scale)
        if self.tangents is not None:  # directions along the surface: through R·S
            self.tangents = given_tangents(self.tangents[keep],
                                           rotation_matrix(rotate) * scale)
        self.check()

    def check(self) -> None:
        """The triangles as a render reads them, checked when the mesh is made and again
        before every render (:meth:`Scene.check`), so that an edit in place (NaN written into
        ``vertices``, a face index past the end) is refused like one at construction:
        ``shading``, the world-space ``vertices`` and ``faces`` (:func:`_check_arrays`,
        vectorised: 50 ms for a million vertices and two million faces, docs/api.md) and a
        model file's per-face arrays, one row a face. ``file``, ``mesh``, ``translate``,
        ``rotate`` and ``scale`` made the vertices when the mesh was made: a change of them
        since, which the render would not see, is refused."""
        file, mesh, transform = self._made_from
        if self.file != file or self.mesh is not mesh:
            raise SceneError("was read when the mesh was made; make a new Mesh to change it",
                             "file" if self.file != file else "mesh")
        for name, made in zip(("translate", "rotate", "scale"), transform, strict=True):
            now = getattr(self, name)
            try:
                same = np.array_equal(np.broadcast_to(np.asarray(now, np.float64), 3), made)
            except (TypeError, ValueError):
                same = False
            if not same:
                shown = now.tolist() if isinstance(now, np.ndarray) else now
                raise SceneError(f"was applied to the vertices when the mesh was made (then "
                                 f"{made.tolist()}, now {shown!r}); transform the vertices, "
                                 "or make a new Mesh", name)
        if self.shading is None:  # the file's normals where it gives them (glTF's rule)
            self.shading = "flat" if self.normals is None else "file"
        self.shading = values.string(self.shading, "shading", SHADINGS)
        if self.shading == "file" and self.normals is None:
            raise SceneError("\"file\" needs a mesh file that gives normals (OBJ vn, glTF "
                             "NORMAL, PLY nx ny nz); this mesh has none", "shading")
        self.vertices, self.faces = _check_arrays(self.vertices, self.faces)
        values.check_length(values.span(self.vertices), "vertices",
                            "the mesh's size (its bounding box's longest side)", longest=False)
        rows = len(self.faces)
        for name, shape in (("face_material", (rows,)), ("texcoords", (rows, 3, 2)),
                            ("normals", (rows, 3, 3)), ("tangents", (rows, 3, 4)),
                            ("texcoords1", (rows, 3, 2)), ("colors", (rows, 3, 4))):
            if getattr(self, name) is not None and np.shape(getattr(self, name)) != shape:
                raise SceneError(f"must have the shape {shape} (one row a face), got "
                                 f"{np.shape(getattr(self, name))}", name)

    def _load_with_materials(self, path: Path) -> tuple[np.ndarray, np.ndarray]:
        """The file's triangles; its materials, faces' materials and texture coordinates
        kept on the mesh (:func:`raytrace.readers.assets.load_with_materials`). A PLY or OFF
        file's material is the default one, tinted by the file's vertex colours where it has
        them (:data:`raytrace.readers.asset.COLORED_SUFFIXES`)."""
        if path.suffix.lower() in COLORED_SUFFIXES:
            read = _load_mesh_file(path)
            self.file_materials = [Material(name="default")]
            self.face_material = np.zeros(len(read.faces), np.int64)
            self.texcoords, self.normals, self.colors = read.texcoords, read.normals, read.colors
            self.material = self.file_materials[0]
            return read.vertices, read.faces
        asset = load_with_materials(input_file(path, "mesh file", "file"))
        self.file_materials, self.face_material = asset.materials, asset.face_material
        self.texcoords, self.sources = asset.texcoords, asset.sources
        self.normals, self.tangents = asset.normals, asset.tangents
        self.texcoords1, self.colors = asset.texcoords1, asset.colors
        self.material = asset.materials[0]
        return asset.vertices, asset.faces

    @property
    def materials(self) -> list:
        """Every material the mesh's faces use."""
        return self.file_materials or [self.material]


#: Every object type by its scene-file ``type``.
OBJECT_TYPES = {**SHAPE_TYPES, "mesh": Mesh}


def object_materials(obj: Any) -> list[Material]:
    """The materials an object's surface uses: a mesh's (several where a model file gives its
    faces their own), any other object's one."""
    return obj.materials if isinstance(obj, Mesh) else [obj.material]


def _nonzero_area(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Where |(b − a) × (c − a)|² > 0 for the corners a, b, c of each face: the cross product
    and the sum of squares term by term as ``np.cross`` and ``np.linalg.norm`` order them (so
    the same faces are kept), on contiguous columns (half the time at a million faces)."""
    w, f = np.ascontiguousarray(vertices.T), np.ascontiguousarray(faces.T)
    (ax, bx, cx), (ay, by, cy), (az, bz, cz) = (w[k][f] for k in range(3))
    ux, uy, uz, vx, vy, vz = bx - ax, by - ay, bz - az, cx - ax, cy - ay, cz - az
    nx, ny, nz = uy * vz - uz * vy, uz * vx - ux * vz, ux * vy - uy * vx
    with np.errstate(over="ignore", under="ignore"):
        return nx * nx + ny * ny + nz * nz > 0


def _check_arrays(verts: Any, faces: Any) -> tuple[np.ndarray, np.ndarray]:
    try:
        v = np.asarray(verts, dtype=np.float64)
    except (TypeError, ValueError):
        raise SceneError("must be a list of [x, y, z] numbers", "vertices") from None
    if v.ndim != 2 or v.shape[1] != 3 or len(v) < 3:
        raise SceneError(f"must be an (n >= 3, 3) array of points, got shape {v.shape}",
                         "vertices")
    if not np.isfinite(v).all():  # (a row-wise .all(axis=1) is 17× slower: only to say where)
        bad = ~np.isfinite(v).all(axis=1)
        raise SceneError(f"vertex {int(np.argmax(bad))} is not finite ({v[bad][0].tolist()}); "
                         "Embree would silently drop its triangles", "vertices")
    values.check_points(v, "vertices", "coordinates")
    try:
        f = np.asarray(faces)
    except (TypeError, ValueError):
        raise SceneError("must be a list of [i, j, k] vertex indices", "faces") from None
    if f.ndim != 2 or f.shape[1] != 3 or len(f) == 0:
        raise SceneError(f"must be an (n >= 1, 3) array of vertex indices (triangles only), "
                         f"got shape {f.shape}", "faces")
    if not np.issubdtype(f.dtype, np.integer):
        if (not np.issubdtype(f.dtype, np.floating) or not np.isfinite(f).all()
                or not np.all(np.mod(f, 1) == 0)):
            raise SceneError("must hold whole vertex indices", "faces")
    if f.min() < 0 or f.max() >= len(v):  # before the cast: 1e308 has no int64
        raise SceneError(f"index out of range 0..{len(v) - 1}", "faces")
    f = f.astype(np.int64, copy=False)  # (an int64 array checked again stays the same one)
    return v, f


def _from_trimesh(mesh: Any, key: str) -> tuple[np.ndarray, np.ndarray]:
    import trimesh

    if isinstance(mesh, trimesh.Scene):
        mesh = mesh.dump(concatenate=True)
    if not isinstance(mesh, trimesh.Trimesh):
        raise SceneError(f"must be a triangle mesh (trimesh.Trimesh), got {type(mesh).__name__}",
                         key)
    return np.asarray(mesh.vertices, dtype=np.float64), np.asarray(mesh.faces)


def check_normals(normals: np.ndarray, file: Any) -> None:
    """Refuse a file's normals (F, 3, 3) where one is not finite, naming the file, the face
    (counted from 1 in the order read) and the corner."""
    bad = ~np.isfinite(np.asarray(normals, np.float64)).all(axis=2)
    if bad.any():
        face, corner = np.argwhere(bad)[0]
        raise SceneError(f"{file}: the normal of face {face + 1}, corner {corner + 1} is not "
                         f"finite ({np.asarray(normals)[face, corner].tolist()})", "file")


def world_normals(normals: np.ndarray, rotate: np.ndarray,
                  scale: np.ndarray) -> np.ndarray:
    """A file's normals (F, 3, 3), finite (:func:`check_normals`), in world space, unit:
    transformed by the inverse transpose of the linear part ``M = R·S`` of the mesh's
    transform, ``n' = R·S⁻¹·n / |R·S⁻¹·n|`` (normals stay perpendicular to the transformed
    surface; pbrt-v4 ``Transform::operator()(Normal3)``). A zero normal stays zero (its
    corner is shaded with its face's normal)."""
    n = (np.asarray(normals, np.float64) / scale) @ rotation_matrix(rotate).T
    length = np.linalg.norm(n, axis=2, keepdims=True)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.ascontiguousarray(np.where(length > 0, n / length, 0.0))


#: Mesh formats that are text (STL where it is not binary): raytrace decodes them
#: (:func:`~.readers.inputs.read_text`) and hands trimesh UTF-8, so trimesh never guesses an
#: encoding (with charset_normalizer, an optional dependency of trimesh raytrace does not need).
TEXT_MESH_SUFFIXES = (".obj", ".off", ".stl")


def _binary_stl_size(path: Path) -> int | None:
    """The size a binary STL file has by its header: an 80-byte header, a uint32 triangle
    count n, then n records of 50 bytes, so 84 + 50·n bytes in all (the rule trimesh's reader
    applies: a file of another size is ASCII); None where it is shorter than the header."""
    with open(path, "rb") as f:
        head = f.read(84)
    return 84 + 50 * int.from_bytes(head[80:], "little") if len(head) == 84 else None


def _load_mesh_file(path: Path) -> MeshFile:
    """Vertices, faces and, for a single textured mesh, texture coordinates (F, 3, 2), and the
    normals the file gives (F, 3, 3): a glTF from :func:`raytrace.readers.gltf.load_gltf`
    (the reader ``material = "from_file"`` uses, so one file gets one verdict; positions
    merged as trimesh merges them), binary PLY and OBJ triangles from
    :func:`raytrace.readers.meshio.read_mesh`, anything else from trimesh
    (:func:`_trimesh_normals`)."""
    input_file(path, "mesh file", "file")
    if path.suffix.lower() in GLTF_SUFFIXES:  # raytrace's glTF reader: its NORMALs kept
        asset = load_gltf(path).asset
        return MeshFile(*merge_vertices(asset.vertices, asset.faces), asset.texcoords,
                        asset.normals)
    fast = read_mesh(path)  # binary PLY and OBJ triangles: as trimesh reads and merges them
    if fast is not None:
        return fast
    import trimesh

    source, kind, off_codes = str(path), {}, None
    suffix = path.suffix.lower()
    binary = _binary_stl_size(path) if suffix == ".stl" else None
    if suffix in TEXT_MESH_SUFFIXES and binary != path.stat().st_size:
        # binary bytes in a text format: one line naming the byte
        what = f"{suffix[1:].upper()} file"
        if binary is not None:  # (a binary STL cut short, or random bytes)
            what = (f"ASCII STL file (a binary one of {(binary - 84) // 50} triangles, as its "
                    f"header says, has {binary} bytes, not {path.stat().st_size})")
        try:
            text = read_text(path, what, a="an", strict=False)
        except SceneError as e:
            raise SceneError(f"cannot read mesh {path}: {e.problem}", "file") from None
        source = io.BytesIO(text.encode("utf-8"))
        kind = {"file_type": suffix[1:], "skip_materials": True}
        off_codes = off_vertex_colors(text) if suffix == ".off" else None  # (trimesh drops them)
    # trimesh warns on stderr about NaN while merging: the error below says it in one line.
    with warnings.catch_warnings(), np.errstate(invalid="ignore", over="ignore"):
        warnings.simplefilter("ignore")
        try:
            loaded = trimesh.load(source, process=False, **kind)
        except Exception as e:  # trimesh raises many types for unreadable files
            # (the exception alone can mislead: random bytes in an .stl fail on a text codec)
            raise SceneError(f"cannot read mesh {path}: not a mesh file trimesh can load "
                             f"({type(e).__name__}: {e})", "file") from None
        texcoords = None
        if isinstance(loaded, trimesh.Scene):
            if not loaded.geometry:
                raise SceneError(f"{path} holds no triangles", "file")
            loaded = loaded.dump(concatenate=True)  # (its uv would be an atlas's: not kept)
        else:
            uv = getattr(loaded.visual, "uv", None)
            if uv is not None and len(uv) == len(loaded.vertices):
                # per face corner, t = 0 at the image's top row (trimesh's t runs up)
                texcoords = np.asarray(uv, np.float64)[np.asarray(loaded.faces)] * [1, -1] + [
                    0, 1]
        if not isinstance(loaded, trimesh.Trimesh) or len(loaded.faces) == 0:
            kind = ("" if isinstance(loaded, trimesh.Trimesh) else
                    f" (trimesh reads it as a {type(loaded).__name__}: points or lines only)")
            raise SceneError(f"{path} holds no triangles{kind}", "file")
        bad = ~np.isfinite(np.asarray(loaded.vertices, dtype=np.float64)).all(axis=1)
        if bad.any():
            raise SceneError(f"{path}: vertex {int(np.argmax(bad)) + 1} is not finite "
                             f"({np.asarray(loaded.vertices)[bad][0].tolist()}); Embree would "
                             "silently drop its triangles", "file")
        faces = np.asarray(loaded.faces)
        outside = (faces < 0) | (faces >= len(loaded.vertices))
        if outside.any():  # (trimesh's merge below would end in an IndexError)
            face, corner = divmod(int(np.argmax(outside)), 3)
            raise SceneError(f"{path}: face {face} names vertex {int(faces[face, corner])}, "
                             f"out of range 0..{len(loaded.vertices) - 1}", "file")
        normals = _trimesh_normals(loaded)  # per corner, before the merge drops them
        colors = None  # per corner too: a PLY's vertex colours (trimesh's 8-bit codes), COFF's
        if suffix == ".ply" and getattr(loaded.visual, "kind", None) == "vertex":
            colors = vertex_colors(np.asarray(loaded.visual.vertex_colors))[faces]
        elif off_codes is not None and len(off_codes) == len(loaded.vertices):
            colors = vertex_colors(off_codes)[faces]
        # Merge coincident vertices so smooth shading can average across faces (STL repeats).
        loaded.merge_vertices(merge_tex=True, merge_norm=True)
    return MeshFile(np.asarray(loaded.vertices, dtype=np.float64), np.asarray(loaded.faces),
                    texcoords, normals, colors)


def _trimesh_normals(loaded: Any) -> np.ndarray | None:
    """The per-corner normals (F, 3, 3) a mesh trimesh loaded was given by its file, or None.
    trimesh computes ``vertex_normals`` on first access when none were given: only normals a
    loader stored (in its cache, before anything computed them) are the file's."""
    if "vertex_normals" not in loaded._cache:
        return None
    return np.asarray(loaded.vertex_normals, np.float64)[np.asarray(loaded.faces)]


def _check_record(record: Any, key: str | None, path: str | None) -> None:
    """``record.check()``, its error located below ``key`` in the scene file ``path``."""
    try:
        record.check()
    except SceneError as e:
        raise e.at(path, key) from None


@dataclass
class Scene(values.Checked):
    """Everything a render needs. ``materials`` are the scene-local named materials.

    Object and light ``material`` fields may be a :class:`Material`, a name (scene-local first,
    then the library) or an inline table; :meth:`resolve_materials` turns them into Materials,
    when the scene is made and again before every render (:meth:`check`).
    """

    camera: Camera = field(default_factory=Camera)
    objects: list = field(default_factory=list)
    lights: list = field(default_factory=list)
    materials: dict = field(default_factory=dict)
    ambient: Any = 0.0
    render: RenderSettings = field(default_factory=RenderSettings)
    path: str | None = None

    def check(self) -> None:
        """The whole scene checked as at construction, by each record's own ``check`` (a
        SceneError naming the file, the record and the field: ``objects[2].radius: must be >
        0, got -1``), and its materials resolved (:meth:`resolve_materials`). Run when the
        scene is made and again before every render (``raytrace.rendering.render_options``:
        ``render``, ``render_frames``, ``explain`` and the command line), so an object
        appended, a field set or an array edited in place since is refused or resolved like
        one given at construction. The ``[render]`` settings are checked there too, with the
        render's overrides applied."""
        for name, cls in (("camera", Camera), ("render", RenderSettings)):
            if not isinstance(getattr(self, name), cls):
                raise SceneError(f"must be a raytrace.{cls.__name__}, got "
                                 f"{values.type_name(getattr(self, name))}", name, self.path)
        for name in ("objects", "lights"):
            if not isinstance(getattr(self, name), (list, tuple)):
                raise SceneError(f"must be a list, got {values.type_name(getattr(self, name))}"
                                 f" (a single one goes in a list: {name}=[...])", name, self.path)
            if isinstance(getattr(self, name), tuple):  # a list given stays the same object
                setattr(self, name, list(getattr(self, name)))
        if not isinstance(self.materials, Mapping):
            raise SceneError(f"must be a dict of name → Material, got "
                             f"{values.type_name(self.materials)}", "materials", self.path)
        if self.path is not None and not isinstance(self.path, (str, Path)):
            raise SceneError(f"must be a file name, got {values.type_name(self.path)}", "path")
        try:
            self.ambient = values.color(self.ambient, "ambient.color")
        except SceneError as e:
            raise e.at(self.path) from None
        _check_record(self.camera, None, self.path)
        for i, o in enumerate(self.objects):
            if not isinstance(o, tuple(OBJECT_TYPES.values())):
                names = [c.__name__ for c in OBJECT_TYPES.values()]
                raise SceneError(f"must be a {', '.join(names[:-1])} or {names[-1]}, got "
                                 f"{type(o).__name__}", f"objects[{i}]", self.path)
            _check_record(o, f"objects[{i}]", self.path)
        for i, light in enumerate(self.lights):
            if not isinstance(light, tuple(LIGHT_TYPES.values())):
                raise SceneError(f"must be a light, got {type(light).__name__}",
                                 f"lights[{i}]", self.path)
            _check_record(light, f"lights[{i}]", self.path)
        self.resolve_materials()

    def material(self, name: str, key: str = "material") -> Material:
        """A scene-local material by name, else a library one."""
        if name in self.materials:
            return self.materials[name]
        if name in library:
            return library[name]
        known = sorted(set(self.materials) | set(library))
        raise SceneError(f"unknown material {name!r}{values.did_you_mean(name, known)} (scene "
                         f"materials and library: {', '.join(known)})", key, self.path)

    def resolve_materials(self) -> None:
        for name, m in list(self.materials.items()):
            if not isinstance(m, Material):
                raise SceneError("must be a Material", f"materials.{name}", self.path)
        for i, o in enumerate(self.objects):
            if isinstance(o, Mesh) and o.file_materials:
                # a scene material of the same name as one of the file's replaces it
                o.file_materials = [self.materials.get(m.name, m) for m in o.file_materials]
                o.material = o.file_materials[0]
                continue
            o.material = self._resolve(o.material, f"objects[{i}].material")

    def _resolve(self, m: Any, key: str) -> Material:
        if m is None:
            return Material(name="default")
        if isinstance(m, Material):
            return m
        if isinstance(m, str):
            return self.material(m, key)
        if isinstance(m, Mapping):
            try:
                return material_from_table(m, key, lambda n, k: self.material(n, k))
            except SceneError as e:
                raise SceneError(e.problem, e.key, self.path) from None
        raise SceneError(f"must be a material name or table, got {values.type_name(m)}", key,
                         self.path)

    def input_files(self) -> list[tuple[Path, str]]:
        """The files this scene was read from, as (path, what it is): the scene file, the
        mesh files, the library material files (each material's and its bases')."""
        files = [(Path(self.path), "the scene file")] if self.path else []
        files += [(Path(o.file), f"the mesh file of objects[{i}]")
                  for i, o in enumerate(self.objects) if isinstance(o, Mesh) and o.file]
        files += [(p, f"a file read by the mesh of objects[{i}]")
                  for i, o in enumerate(self.objects) if isinstance(o, Mesh) for p in o.sources]
        owned = [(m, f"material {m.name!r}") for m in self.materials.values()]
        owned += [(m, f"material {m.name!r}" if m.name else f"the material of objects[{i}]")
                  for i, o in enumerate(self.objects)
                  for m in object_materials(o)]  # inline ones have no name
        for m, owner in owned:
            files += [(p, f"the file of {owner}") for p in m.files]
        return files


