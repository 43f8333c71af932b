"""A mesh file with its own materials, as the readers give it (:class:`Asset`), and the file
suffixes that carry their own materials."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..material import Material

#: Suffixes whose files carry their own materials.
OBJ_SUFFIXES = (".obj",)
GLTF_SUFFIXES = (".gltf", ".glb")
#: Mesh files without materials (read by trimesh, or raytrace.readers.meshio for binary PLY)
#: that a scene may name, or the command line render alone with the default material.
MESH_SUFFIXES = (".ply", ".stl", ".off")
#: Of those, the ones that may colour their vertices (PLY ``red green blue``, COFF): their
#: material is the default one, its ``kd`` and ``ka`` times the vertex colours, with
#: ``material = "from_file"`` and when the file is rendered alone (glTF COLOR_0's rule).
COLORED_SUFFIXES = (".ply", ".off")


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
    #: (F, 3, 3) per corner, the normals the file gives (OBJ ``vn``, glTF ``NORMAL``); None
    #: where it gives none, a zero row for a corner without one (glTF: a primitive without)
    normals: np.ndarray | None = None
    #: (F, 3, 4) per corner, the tangents the file gives (glTF ``TANGENT``: xyz and the
    #: bitangent's sign w); None where it gives none, a zero row for a corner without one
    tangents: np.ndarray | None = None
    #: (F, 3, 2) per corner, a second set of texture coordinates (glTF TEXCOORD_1), or None
    texcoords1: np.ndarray | None = None
    #: (F, 3, 4) per corner, linear RGBA vertex colours (glTF COLOR_0), or None
    colors: np.ndarray | None = None
