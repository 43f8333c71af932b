"""Scene → arrays: the tables the kernels read, built once per render.

:func:`scene_arrays` is the stage between :mod:`raytrace.scene` and both
:mod:`raytrace.accel` and :mod:`raytrace.integrator`: it recentres the geometry on the camera
in float64 and turns the scene into :class:`SceneArrays`:

* the material table, :class:`MaterialTable` (one row per material, colours per channel,
  checker patterns and image textures by reference; :class:`raytrace.kernels.records.Materials`);
* the analytic shapes, :func:`shape_tables` (:class:`raytrace.kernels.records.Shapes`: each shape
  record's ``row`` with its kind, material and object);
* the triangles, :func:`triangle_tables` (:class:`raytrace.kernels.records.Triangles`, float64,
  camera-relative) and each mesh's camera-relative vertices and faces, which the
  accelerator hands to Embree;
* :func:`scene_record`: what the shading kernels need, one :class:`raytrace.kernels.records.Scene`.

The emitters (:func:`raytrace.lights.emitters`) are the integrator's, per light pass.
"""

from __future__ import annotations

from functools import cached_property

import numpy as np

from .kernels import accel as ak  # the build kernels of the triangle tables
from .kernels.core import FAST_PHONG, FLAT, GOURAUD, SMOOTH
from .kernels.kinds import RELIEF_CODES
from .kernels.records import (
    CHECKER_COLOR0,
    CHECKER_COLOR1,
    CHECKER_COLUMNS,
    CHECKER_FILTER,
    CHECKER_SCALE,
    MAP_AFFINE,
    MAP_COLUMNS,
    MAP_MATRIX,
    MAP_SET,
    MATERIAL_COLUMNS,
    TEX_COLUMNS,
    TEX_HEIGHT,
    TEX_OFFSET,
    TEX_WIDTH,
    TEX_WRAP_S,
    TEX_WRAP_T,
    Materials,
    Media,
    Reliefs,
    Scene,
    Shapes,
    Triangles,
)
from .kernels.texels import decode_codes
from .material import CHECKER_FILTERS, COLOR_KEYS, COLUMNS, Checker, Material
from .readers.tangents import mapped_tangents, mikktspace
from .readers.texture import IDENTITY, WRAPS, Texels, Texture
from .scene import SHAPE_TYPES, Mesh, object_materials
from .scene import Scene as SceneDescription

#: A triangle's error band in float32 ulps (2⁻²³ relative) of its largest coordinate: how far
#: along its normal a ray must start for Embree never to report it again (EMBREEX_NOTES.md).
BAND_ULPS = 3.0
#: ``Triangles.shading`` of each ``Mesh.shading`` ("file": the file's normals, interpolated
#: as smooth; see :func:`shading_of`).
SHADING_CODES = {"flat": FLAT, "smooth": SMOOTH, "gouraud": GOURAUD, "fast_phong": FAST_PHONG,
                 "file": SMOOTH}


class SceneArrays:
    """A scene as arrays, camera-relative: what :func:`scene_arrays` gives the accelerator
    and the integrator (neither reads the other's). Read-only once built.

    The triangle tables (and the camera-relative meshes) are built on first use, which is
    the accelerator's build of its BVH: a profile of ``Accelerator._build_meshes`` (as
    benchmarks/bench.py takes) counts them in the build. That first use comes before any
    render thread starts.
    """

    def __init__(self, origin: np.ndarray, materials: list, shapes: Shapes, meshes: list,
                 geom_object: np.ndarray):
        #: (3,) float64 the camera position: world = camera-relative + origin
        self.origin = origin
        #: The Materials that ``material`` columns index, and their table.
        self.materials, self.table = materials, MaterialTable(materials)
        self.shapes = shapes  #: the analytic shapes
        self.geom_object = geom_object  #: (G,) int64 index in the scene's objects of each mesh
        self.degenerate = sum(m.degenerate for m in meshes)  #: zero-area faces dropped
        self._meshes = meshes

    @cached_property
    def _tables(self) -> tuple[Triangles, list]:
        index = {id(m): i for i, m in enumerate(self.materials)}
        return triangle_tables(self._meshes, self.origin, index, self.table)

    @property
    def triangles(self) -> Triangles:
        """The float64 triangle tables, in Embree's geomID order."""
        return self._tables[0]

    @property
    def meshes(self) -> list[tuple[np.ndarray, np.ndarray]]:
        """Each mesh's camera-relative float64 vertices (V, 3) and int64 faces (F, 3), in
        geomID order."""
        return self._tables[1]

    def share_geometry(self, built: SceneArrays) -> None:
        """Take the triangle tables of ``built``: the arrays of the same geometry, rendered
        before (the same :func:`raytrace.accel_cache.fingerprint`), instead of building them
        again. The materials' table stays this one's (colours may have changed)."""
        self.__dict__["_tables"] = built._tables

    @cached_property
    def record(self) -> Scene:
        """What every shading kernel needs (:func:`scene_record`)."""
        return scene_record(self.origin, self.table, self.triangles,
                            relief_tables(self.table, self.triangles, self._meshes))

    @property
    def n_triangles(self) -> int:
        return sum(len(m.faces) for m in self._meshes)


def scene_arrays(scene: SceneDescription) -> SceneArrays:
    """The stage: the scene's materials (each once, in the order objects first use them),
    their table, the analytic shapes and the triangles, recentred on the camera in float64
    before anything is rounded to float32 for Embree."""
    seen: dict[int, Material] = {}
    for o in scene.objects:
        for m in object_materials(o):  # a mesh's faces may use several
            seen.setdefault(id(m), m)
    materials = list(seen.values())
    origin = np.asarray(scene.camera.position, dtype=np.float64)
    index = {id(m): i for i, m in enumerate(materials)}
    meshes = [(i, o) for i, o in enumerate(scene.objects) if isinstance(o, Mesh)]
    return SceneArrays(origin, materials, shape_tables(scene.objects, origin, index),
                       [o for _, o in meshes], np.array([i for i, _ in meshes], np.int64))


def shape_tables(objects: list, origin: np.ndarray, index: dict[int, int]) -> Shapes:
    """The analytic shapes of ``objects`` (those of :data:`raytrace.scene.SHAPE_TYPES`),
    kind by kind in ``kernels.accel.SHAPE_KINDS``' order, in scene order within a kind: each
    one's kind code, its ``row(origin)`` zero-padded to ``kernels.accel.ROW`` floats, its
    material's row (``index``: ``id(material)`` → row) and its index in ``objects``."""
    kinds = tuple(SHAPE_TYPES.values())
    order = sorted((ak.SHAPE_KINDS[o.type], i) for i, o in enumerate(objects)
                   if isinstance(o, kinds))
    rows = np.zeros((len(order), ak.ROW))
    for j, (_, i) in enumerate(order):
        row = ak.pack_row(objects[i].type, objects[i].row(origin))
        rows[j, :len(row)] = row
    return Shapes(np.array([k for k, _ in order], np.int64), rows,
                  np.array([index[id(objects[i].material)] for _, i in order], np.int64),
                  np.array([i for _, i in order], np.int64))


def triangle_tables(meshes: list[Mesh], origin: np.ndarray, index: dict[int, int],
                    table: MaterialTable) -> tuple[Triangles, list]:
    """The float64 triangle tables of ``meshes`` (T, …) in their order (Embree's geomIDs),
    camera-relative, and each mesh's camera-relative vertices and faces for Embree. The
    per-triangle work is the build kernels' (``accel_kernels.vertex_normals``,
    ``accel_kernels.triangle_tables``); texture coordinates only where a material has a
    texture."""
    sizes = [len(m.faces) for m in meshes]
    t = sum(sizes)
    geom_first = np.cumsum([0, *sizes[:-1]], dtype=np.int64) if meshes else np.zeros(0, np.int64)
    corners, vnormals = np.empty((t, 3, 3)), np.empty((t, 3, 3))
    normal, band = np.empty((t, 3)), np.empty(t)
    material = np.concatenate([
        np.array([index[id(x)] for x in m.file_materials], np.int64)[m.face_material]
        if m.file_materials else np.full(len(m.faces), index[id(m.material)], np.int64)
        for m in meshes]) if meshes else np.zeros(0, np.int64)
    shading = np.repeat(np.array([SHADING_CODES[m.shading] for m in meshes], np.int8), sizes)
    relative = []
    for m, first in zip(meshes, geom_first, strict=True):
        v = np.ascontiguousarray(m.vertices - origin, dtype=np.float64)
        faces = np.ascontiguousarray(m.faces, dtype=np.int64)
        s = slice(first, first + len(faces))
        shading_of(m, v, faces, Triangles(geom_first, corners[s], normal[s], vnormals[s],
                                          shading[s], material[s], band[s]))
        relative.append((v, faces))
    # the texture coordinates of every triangle where some mesh's file gives them (image
    # textures and the uv AOV read them; zeros for the faces of a mesh without them)
    texcoords = corner_table(meshes, "texcoords", np.zeros(2))
    if texcoords is None:
        texcoords = np.zeros((0, 3, 2))
    # the second set where some mesh's file gives one (glTF TEXCOORD_1), the first set's
    # coordinates on a mesh whose file gives no second
    texcoords1 = corner_table(meshes, "texcoords1", np.zeros(2), "texcoords")
    colors = corner_table(meshes, "colors", np.ones(4))
    return Triangles(geom_first, corners, normal, vnormals, shading, material, band,
                     texcoords, texcoords1, colors), relative


def corner_table(meshes: list[Mesh], name: str, default: np.ndarray,
                 fallback: str | None = None) -> np.ndarray | None:
    """The per-corner array ``name`` of every mesh (F, 3, k) concatenated, where some mesh has
    one: a mesh without it gives its ``fallback`` array, else ``default`` (k,) at every
    corner; None where none has it."""
    if not any(getattr(m, name) is not None for m in meshes):
        return None

    def rows(m: Mesh) -> np.ndarray:
        for a in (getattr(m, name), getattr(m, fallback) if fallback else None):
            if a is not None:
                return np.asarray(a, np.float64)
        return np.broadcast_to(default, (len(m.faces), 3, len(default)))
    return np.ascontiguousarray(np.concatenate([rows(m) for m in meshes]))


def shading_of(mesh: Mesh, v: np.ndarray, faces: np.ndarray, out: Triangles) -> None:
    """The one place that decides the normals a mesh is shaded with, written with its
    corners, face normals and error bands into ``out`` (the mesh's rows of the scene's
    :class:`~raytrace.kernels.records.Triangles`; ``v`` its camera-relative vertices):

    * ``"file"`` (the default where the file gives normals): each corner's normal as the file
      gives it (:attr:`raytrace.Mesh.normals`, per corner, so split normals stay split), the
      face normal at a corner without one; interpolated as ``"smooth"`` (Phong 1975). A
      triangle none of whose corners has one is flat (glTF 2.0 §3.7.2.1: "client
      implementations MUST calculate flat normals");
    * ``"smooth"``, ``"gouraud"``, ``"fast_phong"``: the normalised sum of the unit face
      normals at each vertex (seed 000; ``kernels.accel.vertex_normals``), whatever the file
      gives;
    * ``"flat"``: the face normal.

    **Below the surface.** A corner normal that points below its face (``n_k·N_g < 0``, N_g
    the outward face normal of the winding) is turned over, ``−n_k``: a file whose normals
    and winding disagree then shades as its winding says (a normal only slightly below its
    face has its tilt reversed too: a choice, docs/shading.md), and an interpolated normal
    ``Σ b_k·n_k`` never points below the face (each term is above it), nor do the normals
    that Gouraud shading and Hanika's lift read at the corners (docs/shading.md, "Shading
    normals below the surface").
    """
    vn = np.zeros_like(v)  # a zero vertex normal: its corners take the face normal
    if mesh.shading != "file":
        ak.vertex_normals(v, faces, vn)
    ak.triangle_tables(v, faces, vn, BAND_ULPS * 2.0**-23, out.corners, out.normal,
                       out.vnormals, out.band)
    if mesh.shading == "file":
        given = np.any(mesh.normals != 0.0, axis=2)  # (F, 3)
        out.vnormals[given] = mesh.normals[given]
        out.shading[~given.any(axis=1)] = FLAT
    below = np.einsum("fkj,fj->fk", out.vnormals, out.normal) < 0.0
    out.vnormals[below] *= -1.0


class MaterialTable:
    """Per-material coefficients, looked up by material index at the hits.

    ``colors`` (M, 18) holds the constant colours ka kd ks kr kt ke, three columns each
    (``shading_kernels.KA`` …); where colour k of material m is a :class:`Checker`,
    ``pattern[m, k]`` indexes its row of ``checkers`` (colour 0, colour 1, scale, filter, at the
    columns ``CHECKER_COLOR0``, … of ``kernels.records``), evaluated at the world points of
    the hits; −1 means constant; ``texture[m, k]`` likewise names an image texture, its row
    of ``tex_info`` (``TEX_OFFSET``, …) where its texels start in ``texels``, its size and
    wrap modes. Each entry of :data:`raytrace.material.COLUMNS` is an (M,) attribute
    of its name. :attr:`record` is the whole table as the kernels take it
    (:class:`raytrace.kernels.records.Materials`).
    """

    def __init__(self, materials: list[Material]):
        self.materials = materials
        self.colors = np.zeros((len(materials), 3 * len(COLOR_KEYS)))
        self.pattern = np.full((len(materials), len(COLOR_KEYS)), -1, np.int64)
        self.texture = np.full((len(materials), len(COLOR_KEYS)), -1, np.int64)
        checkers, textures = [], []
        for i, m in enumerate(materials):
            for k, key in enumerate(COLOR_KEYS):
                c = m.ambient if key == "ka" else getattr(m, key)
                if isinstance(c, Checker):
                    self.pattern[i, k] = len(checkers)
                    row = np.zeros(CHECKER_COLUMNS)
                    row[CHECKER_COLOR0:CHECKER_COLOR0 + 3] = c.colors[0]
                    row[CHECKER_COLOR1:CHECKER_COLOR1 + 3] = c.colors[1]
                    row[CHECKER_SCALE] = c.scale
                    row[CHECKER_FILTER] = CHECKER_FILTERS[c.filter]
                    checkers.append(row)
                elif isinstance(c, Texture):
                    if c not in textures:
                        textures.append(c)
                    self.texture[i, k] = textures.index(c)
                else:
                    self.colors[i, 3 * k:3 * k + 3] = c
        for name in ("alpha", "occlusion"):  # a material's per-hit factors' textures
            rows = np.full(len(materials), -1, np.int64)
            for i, m in enumerate(materials):
                t = getattr(m, name)
                if t is not None:
                    if t not in textures:
                        textures.append(t)
                    rows[i] = textures.index(t)
            setattr(self, name, rows)
        # normal and height maps (Material.normal_map, bump): their texture, kind and scale
        self.relief = np.full(len(materials), -1, np.int64)
        self.relief_kind = np.zeros(len(materials), np.int64)
        self.relief_scale = np.ones(len(materials))
        for i, m in enumerate(materials):
            for kind in RELIEF_CODES:
                r = getattr(m, kind)
                if r is not None:
                    if r.texture not in textures:
                        textures.append(r.texture)
                    self.relief[i], self.relief_kind[i] = (textures.index(r.texture),
                                                           RELIEF_CODES[kind])
                    self.relief_scale[i] = r.scale
        self.tinted = np.array([[k in m.vertex_colors for k in COLOR_KEYS] for m in materials],
                               bool).reshape(len(materials), len(COLOR_KEYS))
        self.textured = ((self.texture >= 0).any(axis=1) | (self.alpha >= 0)
                         | (self.occlusion >= 0))
        if not (self.occlusion >= 0).any():  # no occlusion code compiled
            self.occlusion = None
        #: The image textures (``raytrace.readers.texture.Texture``), in ``tex_info``'s rows.
        self.textures = textures
        # only scenes with textures pay for them: one float a texture channel, else none;
        # an image used with two mappings (two Textures sharing texels) is stored once
        images = list({id(t.image): t.image for t in textures}.values())
        offsets = dict(zip((id(x) for x in images),
                           np.cumsum([0, *(np.prod(x.shape) for x in images)])[:-1],
                           strict=True))
        self.tex_info = np.zeros((len(textures), TEX_COLUMNS), np.int64)
        self.tex_map = np.zeros((len(textures), MAP_COLUMNS))
        for info, row, t in zip(self.tex_info, self.tex_map, textures, strict=True):
            info[TEX_OFFSET], info[TEX_WIDTH], info[TEX_HEIGHT] = (
                offsets[id(t.image)], t.image.shape[1], t.image.shape[0])
            info[TEX_WRAP_S], info[TEX_WRAP_T] = WRAPS[t.wrap[0]], WRAPS[t.wrap[1]]
            row[MAP_SET] = t.uv_set
            if t.transform is not None:
                row[MAP_AFFINE] = 1.0
                row[MAP_MATRIX:MAP_MATRIX + 6] = np.reshape(t.transform, 6)
        if not self.tex_map[:, MAP_SET:MAP_AFFINE + 1].any():  # every use set 0, unmapped:
            self.tex_map = None  # the texture code reads as it would without mappings
        self.texels = texel_array(images)
        self.checkers = np.array(checkers, dtype=np.float64).reshape(-1, CHECKER_COLUMNS)
        for name, (dtype, _) in MATERIAL_COLUMNS.items():  # one declaration, records'
            value = COLUMNS[name]
            setattr(self, name, np.array([value(m) for m in materials], dtype))
        self.transparent = np.array([m.transparent for m in materials], dtype=bool)
        # (tinted is bound by scene_record where the scene has vertex colours)
        self.record = Materials(**{name: getattr(self, name) for name in Materials._fields
                                   if name != "tinted"}, tinted=None)


def scene_record(origin: np.ndarray, table: MaterialTable, triangles: Triangles,
                 reliefs: Reliefs | None = None) -> Scene:
    """What every shading kernel needs of the scene, as one record: the texture coordinates
    only where some material has an image texture or some mesh vertex colours, the
    materials' ``tinted`` only where some mesh has vertex colours, the materials' interiors
    only where some material absorbs or is thin-walled, the normal and height maps
    (:func:`relief_tables`) only where some material has one (the kernels' texture, medium
    and relief code is compiled only then)."""
    textured = bool(table.textured.any()) if len(table.materials) else False
    colored = triangles.colors is not None
    materials = table.record._replace(tinted=table.tinted) if colored else table.record
    return Scene(np.ascontiguousarray(origin, dtype=np.float64), materials, triangles,
                 texcoords=triangles.texcoords if textured or colored else None,
                 media=media_table(table.materials), reliefs=reliefs)


def media_table(materials: list[Material]) -> Media | None:
    """The materials' interiors (:class:`raytrace.kernels.records.Media`: Beer's σ per
    channel, thin walls), or None where no material absorbs or is thin-walled."""
    if not any(m.absorbs or m.thin_walled for m in materials):
        return None
    sigma = np.array([m.sigma for m in materials], np.float64).reshape(-1, 3)
    return Media(np.ascontiguousarray(sigma), np.array([m.thin_walled for m in materials],
                                                       np.bool_))


def texel_array(images: list[Texels]) -> np.ndarray:
    """The images' RGBA texels one after another, flat float32 (the material table's
    ``texels``): float texels copied, an image kept as its codes decoded into its place by
    :func:`raytrace.kernels.texels.decode_codes` (the values :attr:`Texels.floats` gives,
    without widening each code to an index first: docs/performance.md, "Model files")."""
    out = np.empty(sum(int(np.prod(x.shape)) for x in images), np.float32)
    at = 0
    for x in images:
        place = out[at:at + int(np.prod(x.shape))].reshape(x.shape)
        if x.decoded:
            place[...] = x.floats
        else:
            decode_codes(x.colour, x.alpha, x.codes, place)
        at += place.size
    return out


def relief_tables(table: MaterialTable, triangles: Triangles, meshes: list[Mesh]
                  ) -> Reliefs | None:
    """The normal and height maps as the kernels read them (``Scene.reliefs``), or None where
    no material has one or no mesh has texture coordinates (a scene then compiles no relief
    code: bit for bit the image it had without). Each triangle's texture coordinates as its
    material's map reads them (:func:`relief_texcoords`: the map's uv set through its
    transform, so the kernels read a map as every other texture is read). Each corner's
    tangent frame follows those coordinates: the file's (glTF ``TANGENT``,
    :attr:`raytrace.Mesh.tangents`) where it gives one, turned by the map's transform
    (:func:`raytrace.readers.tangents.mapped_tangents`), else MikkTSpace's rule
    (:func:`raytrace.readers.tangents.mikktspace`) over the normals the corners are shaded
    with (the face normal on a flat triangle) and the coordinates the map reads (glTF 2.0
    §3.7.2.1: "the specified vertex positions, normals, and texture coordinates associated
    with the normal texture"; §3.9.3: the map's +X is right, +Y up, on the image as read)."""
    if not len(table.materials) or not (table.relief >= 0).any() or not len(
            triangles.texcoords):
        return None
    texcoords, linear = relief_texcoords(table, triangles)
    tangents = np.zeros((len(triangles.material), 3, 4))
    for m, first in zip(meshes, triangles.geom_first, strict=True):
        rows = slice(first, first + len(m.faces))
        if m.texcoords is None or not (table.relief[triangles.material[rows]] >= 0).any():
            continue
        flat = (triangles.shading[rows] == FLAT)[:, None, None]
        normals = np.where(flat, triangles.normal[rows][:, None, :], triangles.vnormals[rows])
        tangents[rows] = mikktspace(triangles.corners[rows], normals, texcoords[rows])
        if m.tangents is not None:
            given = np.any(m.tangents != 0.0, axis=2)
            if linear is not None:
                tangents[rows][given] = mapped_tangents(m.tangents, normals,
                                                        linear[rows])[given]
            else:
                tangents[rows][given] = m.tangents[given]
    return Reliefs(table.relief, table.relief_kind, table.relief_scale, table.texels,
                   table.tex_info, triangles.corners, texcoords,
                   np.ascontiguousarray(tangents))


def relief_texcoords(table: MaterialTable, triangles: Triangles
                     ) -> tuple[np.ndarray, np.ndarray | None]:
    """Each triangle's corner coordinates (T, 3, 2) as its material's normal or height map
    reads them, and each triangle's linear part L (T, 2, 2) of that map's transform (None
    where no map has a mapping): the map's uv set (``Triangles.texcoords1`` for set 1) through
    its affine transform ``(s', t') = L·(s, t) + c`` (:class:`raytrace.readers.texture.Texture`
    ``uv_set``, ``transform``: glTF ``texCoord`` and KHR_texture_transform, MTL ``-o``/``-s``).
    An affine map of the corners is the map of the interpolated coordinates, so the kernels
    read the mapped corners as they read unmapped ones. ``Triangles.texcoords`` itself (no
    copy) where every map reads set 0 unmapped."""
    maps = [table.textures[q] if q >= 0 else None for q in table.relief]
    if all(t is None or (t.uv_set == 0 and t.transform is None) for t in maps):
        return triangles.texcoords, None
    affine = np.tile(IDENTITY, (len(maps), 1, 1))
    second = np.zeros(len(maps), bool)
    for i, t in enumerate(maps):
        if t is not None:
            second[i] = t.uv_set == 1
            if t.transform is not None:
                affine[i] = t.transform
    face = affine[triangles.material]  # (T, 2, 3)
    st = triangles.texcoords
    if second.any() and triangles.texcoords1 is not None:  # (set 0 where a mesh has no set 1)
        st = np.where(second[triangles.material][:, None, None], triangles.texcoords1, st)
    mapped = np.einsum("tij,tkj->tki", face[:, :, :2], st) + face[:, None, :, 2]
    return np.ascontiguousarray(mapped), np.ascontiguousarray(face[:, :, :2])
