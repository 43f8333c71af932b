"""Mesh files with their own materials: an OBJ with its MTL, a glTF/GLB file.

:func:`load_with_materials` gives an :class:`~.asset.Asset`: the triangles, each face's
material (an index into the asset's materials) and, where the file has them, each face corner's
texture coordinates. A mesh object takes it with ``material = "from_file"``
(:class:`raytrace.Mesh`). The OBJ is read by :mod:`.obj`, its MTL by :mod:`.mtl`, glTF by
:mod:`.gltf`.
"""

from __future__ import annotations

from pathlib import Path

from ..errors import SceneError
from .asset import GLTF_SUFFIXES, OBJ_SUFFIXES, Asset
from .gltf import load_gltf
from .obj import load_obj


def load_with_materials(path: Path) -> Asset:
    """The triangles and materials of an OBJ (with its MTL) or glTF/GLB file."""
    suffix = path.suffix.lower()
    if suffix in OBJ_SUFFIXES:
        return load_obj(path)
    if suffix in GLTF_SUFFIXES:
        return load_gltf(path).asset
    raise SceneError(f"material = \"from_file\" needs an OBJ (with its MTL) or a glTF/GLB "
                     f"file (or a PLY or OFF, whose vertex colours tint the default material), "
                     f"got {path.name}", "material")
