"""glTF 2.0 and GLB files: meshes, node hierarchy, cameras, lights and materials.

The file is read with pygltflib (Khronos glTF 2.0 specification, 2021), its JSON made into
pygltflib's objects by :func:`gltf_objects` (the objects dataclasses-json makes for
pygltflib, about twenty times faster); accessors are decoded here with numpy (componentType,
type, byteOffset, byteStride, normalized; §3.6). The scene's node tree is walked from its
roots with each node's matrix or T·R·S (§3.5.3: M = T·R·S, the rotation a unit quaternion
x, y, z, w), the parent's world matrix on the left.

* every TRIANGLES primitive of every mesh node, in world space, with its material;
* the first perspective camera met (it looks down its node's −z with +y up; ``yfov`` is the
  vertical field of view);
* ``KHR_lights_punctual`` lights (:data:`LIGHTS`);
* materials by :func:`material` (the mapping is in docs/scene_format.md).

Extensions that change the look and are not read are listed on one warning line; an
``extensionsRequired`` entry not read is an error.
"""

from __future__ import annotations

import base64
import dataclasses
import functools
import json
import math
import typing
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any
from urllib.parse import unquote

import numpy as np

from .. import values
from ..errors import RenderWarning, SceneError, located
from ..lights import DirectionalLight, PointLight, SpotLight
from ..material import Material, Relief
from .asset import Asset
from .inputs import cached_reads, input_file
from .tangents import given_tangents
from .texture import GLTF_WRAPS, Texture, uv_transform

COMPONENT = {5120: np.int8, 5121: np.uint8, 5122: np.int16, 5123: np.uint16, 5125: np.uint32,
             5126: np.float32}
WIDTH = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT2": 4, "MAT3": 9, "MAT4": 16}
#: Extensions read (the rest of ``extensionsUsed`` that changes appearance is warned about).
SUPPORTED = ("KHR_lights_punctual", "KHR_materials_ior", "KHR_materials_transmission",
             "KHR_materials_specular", "KHR_materials_emissive_strength",
             "KHR_materials_unlit", "KHR_materials_volume", "KHR_texture_transform")
#: Extensions that do not change how the scene looks (EXT_mesh_gpu_instancing does: its
#: copies are not drawn, and it is warned about).
NEUTRAL = ("KHR_mesh_quantization", "KHR_xmp_json_ld", "KHR_materials_variants")
TRIANGLES = 4


@dataclass
class GltfScene:
    """What a glTF file holds for raytrace."""

    asset: Asset
    camera: dict | None = None          #: position, look_at, up, fov, aspect, index
    lights: list = field(default_factory=list)
    #: The index in ``cameras`` of the first orthographic camera met before the camera taken
    #: (not read: raytrace's cameras are perspective), or None.
    orthographic: int | None = None


def _buffers(gltf: Any, path: Path) -> list[bytes]:
    out = []
    for i, b in enumerate(gltf.buffers):
        uri = b.uri
        if uri is None:
            blob = gltf.binary_blob()
            if blob is None:
                raise SceneError("has no uri and the file has no binary chunk",
                                 f"buffers[{i}]", str(path))
            out.append(blob)
        elif uri.startswith("data:"):
            out.append(base64.b64decode(uri.split(",", 1)[1]))
        else:
            file = input_file(path.parent / unquote(uri), "buffer file", f"buffers[{i}].uri",
                              str(path))
            out.append(file.read_bytes())
        if len(out[-1]) < (b.byteLength or 0):
            raise SceneError(f"holds {len(out[-1])} bytes, its byteLength says {b.byteLength}: "
                             "the file is truncated", f"buffers[{i}]", str(path))
    return out


def buffer_files(gltf: Any, path: Path) -> list[Path]:
    """The files beside ``path`` that its buffers name (a ``.bin``; not a data URI or the GLB
    chunk): read with the model, so no output may be written over them."""
    return [path.parent / unquote(b.uri) for b in gltf.buffers or []
            if b.uri is not None and not b.uri.startswith("data:")]


def view_bytes(gltf: Any, buffers: list[bytes], index: Any, path: Path, key: str
               ) -> tuple[bytes, int, int]:
    """Buffer view ``index`` (§3.6.1), named by ``key`` where it is referred to: its buffer's
    bytes and the view's [start, end) in them, checked to lie inside the buffer."""
    if not isinstance(index, int) or not 0 <= index < len(gltf.bufferViews or []):
        raise SceneError(f"no such bufferView {index!r}", key, str(path))
    view, where = gltf.bufferViews[index], f"bufferViews[{index}]"
    if not isinstance(view.buffer, int) or not 0 <= view.buffer < len(buffers):
        raise SceneError(f"no such buffer {view.buffer!r}", f"{where}.buffer", str(path))
    start = view.byteOffset or 0
    end = start + (view.byteLength or 0)
    if end > len(buffers[view.buffer]):
        raise SceneError(f"bytes {start}..{end} reach past the end of buffers[{view.buffer}] "
                         f"({len(buffers[view.buffer])} bytes)", where, str(path))
    return buffers[view.buffer], start, end


def accessor(gltf: Any, buffers: list[bytes], index: int, path: Path) -> np.ndarray:
    """Accessor ``index`` as an (count, width) array (§3.6.2), normalised integers as floats
    in [0, 1] (unsigned) or [−1, 1] (signed)."""
    key = f"accessors[{index}]"
    try:
        a = gltf.accessors[index]
    except (IndexError, TypeError):
        raise SceneError("no such accessor", key, str(path)) from None
    if a.sparse is not None:
        raise SceneError("sparse accessors are not supported", key, str(path))
    if a.componentType not in COMPONENT or a.type not in WIDTH:
        raise SceneError(f"unknown componentType {a.componentType} or type {a.type!r}", key,
                         str(path))
    dtype, width = np.dtype(COMPONENT[a.componentType]).newbyteorder("<"), WIDTH[a.type]
    if a.bufferView is None:
        return np.zeros((a.count, width), np.float64)
    data, view_start, view_end = view_bytes(gltf, buffers, a.bufferView, path,
                                            f"{key}.bufferView")
    start = view_start + (a.byteOffset or 0)
    stride = gltf.bufferViews[a.bufferView].byteStride or dtype.itemsize * width
    end = start + stride * (a.count - 1) + dtype.itemsize * width
    if a.count < 0 or a.count and end > view_end:
        raise SceneError(f"reaches past the end of bufferViews[{a.bufferView}] "
                         f"({view_end - view_start} bytes): count {a.count} from byteOffset "
                         f"{a.byteOffset or 0}", key, str(path))
    rows = np.ndarray((a.count, width), dtype, data, start, (stride, dtype.itemsize))
    out = rows.astype(np.float64 if a.componentType == 5126 or a.normalized else np.int64)
    if a.normalized and a.componentType != 5126:
        info = np.iinfo(COMPONENT[a.componentType])
        out = np.maximum(out / info.max, -1.0)
    return out


def local_matrix(node: Any) -> np.ndarray:
    """A node's 4×4 local transform: its column-major ``matrix``, or T·R·S (§3.5.3)."""
    if node.matrix is not None:
        return np.array(node.matrix, np.float64).reshape(4, 4).T
    t = np.eye(4)
    t[:3, 3] = node.translation or (0.0, 0.0, 0.0)
    x, y, z, w = node.rotation or (0.0, 0.0, 0.0, 1.0)
    r = np.eye(4)
    r[:3, :3] = [[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                 [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                 [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]]
    s = np.diag([*(node.scale or (1.0, 1.0, 1.0)), 1.0])
    return t @ r @ s


def world_matrices(gltf: Any) -> list[tuple[int, np.ndarray]]:
    """(node, world matrix) for every node of the default scene, parents before children. A
    node met twice (a cycle, or a child of two parents: not a tree, against the glTF spec) is
    an error."""
    scene = gltf.scenes[gltf.scene or 0] if gltf.scenes else None
    # no scene: the nodes that are no node's child (a child listed as a root too is met twice)
    children = {c for node in gltf.nodes for c in node.children or []}
    roots = (scene.nodes if scene is not None else
             [n for n in range(len(gltf.nodes)) if n not in children])
    out, stack = [], [(n, np.eye(4)) for n in reversed(roots or [])]
    seen: set[int] = set()
    while stack:
        n, parent = stack.pop()
        if n in seen:
            raise SceneError("is reached twice: the node hierarchy is not a tree", f"nodes[{n}]")
        seen.add(n)
        m = parent @ local_matrix(gltf.nodes[n])
        out.append((n, m))
        stack += [(c, m) for c in reversed(gltf.nodes[n].children or [])]
    return out


def _ext(obj: Any, name: str) -> dict:
    return (obj.extensions or {}).get(name) or {} if obj is not None else {}


def roughness_exponent(roughness: float) -> float:
    """Blinn–Phong exponent of a GGX/Beckmann roughness: n = 2/α² − 2 with α = roughness²
    (Walter et al. 2007, eq. 30; Karis 2013's α), capped at 10 000."""
    alpha2 = max(roughness, 1e-3) ** 4
    return min(max(2.0 / alpha2 - 2.0, 0.0), 10_000.0)


def volume(ext: dict, key: str, path: Path | None) -> dict[str, Any]:
    """The :class:`Material` fields of a transmitting glTF material's
    ``KHR_materials_volume`` (``ext``, {} where absent), by the Khronos extension specs: no
    volume, or ``thicknessFactor`` 0, is a thin wall (KHR_materials_transmission: "the
    material is thin-walled", light passes without refraction); a thickness > 0 is a closed
    volume, refracting with ior, absorbing by Beer's law with ``attenuationColor`` (default
    white) after ``attenuationDistance`` (world units, default +∞: no absorption). The
    thickness itself (and ``thicknessTexture``) is a rasteriser's stand-in for the distance
    through the mesh, which a ray tracer measures: only whether it is 0 is read. A colour
    channel of 0 (all absorbed) is read as the smallest normal float64 (σ = 708/distance).

    >>> volume({}, "v", None)
    {'thin_walled': True}
    >>> volume({"thicknessFactor": 1.0, "attenuationDistance": 2.0}, "v", None)["thin_walled"]
    False
    """
    def number(value: Any, field: str, **bounds: Any) -> float:
        with located(path):
            return values.number(value, f"{key}.{field}", **bounds)

    if not number(ext.get("thicknessFactor", 0.0), "thicknessFactor", lo=0) > 0:
        return {"thin_walled": True}
    out: dict[str, Any] = {"thin_walled": False}
    if "attenuationDistance" in ext:
        out["attenuation_distance"] = number(ext["attenuationDistance"], "attenuationDistance",
                                             lo=0, lo_open=True)
    color = ext.get("attenuationColor", [1.0, 1.0, 1.0])
    if not isinstance(color, list) or len(color) != 3:
        raise SceneError("must be a list of three numbers", f"{key}.attenuationColor",
                         str(path))
    out["attenuation_color"] = np.maximum(
        [number(x, f"attenuationColor[{i}]", lo=0, hi=1) for i, x in enumerate(color)],
        np.finfo(np.float64).tiny)
    return out


def material(gltf: Any, index: int | None, texture: Any = None, path: Path | None = None
             ) -> Material:
    """A glTF material as a raytrace :class:`Material` (docs/scene_format.md has the table):
    ``kd = baseColor·(1 − metallic)·(1 − transmission)``, specular colour
    ``F0 = mix(((ior − 1)/(ior + 1))²·specularColor·specular, baseColor, metallic)``,
    ``shininess`` = :func:`roughness_exponent`, ``ks = F0·(n + 8)/8`` with ``highlight =
    "blinn_cosine"``, ``ks·(N·H)^n·(N·L)`` (normalised Blinn–Phong inside the reflectance
    equation, Akenine-Möller et al., Real-Time Rendering 4th ed., eq. 7.48 and §9.3, times π
    as the seeds' kd is: a rough material stays matte, roughness 1 a Lambertian F0·(N·L)),
    ``kr = F0·(1 − roughness)²``; transmission t: ``kt = t·baseColor·(1 −
    metallic)``, ``kr = 1`` and the dielectric Fresnel split, a thin wall (no bending, no
    absorption) unless ``KHR_materials_volume`` gives a thicknessFactor > 0, then a closed
    volume refracting with ior and absorbing by Beer's law (:func:`volume`);
    ``ke = emissive·strength``;
    BLEND alpha as opacity, MASK as 0 or 1 by the cutoff; unlit: ``ke = baseColor`` (its
    texture times the factor), nothing else."""
    if index is None:
        m = None
        name = "default"
    else:
        m = gltf.materials[index]
        name = m.name or f"materials[{index}]"
    pbr = m.pbrMetallicRoughness if m is not None else None
    key = f"materials[{index}]"

    def factor(value: Any, default: Any, field: str, hi: float | None = 1.0) -> Any:
        """A factor checked against the glTF schema's range, named by its key."""
        value = default if value is None else value
        with located(path):
            if isinstance(default, list):
                return np.array([values.number(x, f"{key}.{field}[{i}]", lo=0, hi=hi)
                                 for i, x in enumerate(value)], np.float64)
            return values.number(value, f"{key}.{field}", lo=0, hi=hi)

    rgba = factor(pbr.baseColorFactor if pbr else None, [1.0] * 4,
                  "pbrMetallicRoughness.baseColorFactor")
    base, alpha = rgba[:3], rgba[3]
    metallic = factor(pbr.metallicFactor if pbr else None, 1.0,
                      "pbrMetallicRoughness.metallicFactor")
    rough = factor(pbr.roughnessFactor if pbr else None, 1.0,
                   "pbrMetallicRoughness.roughnessFactor")
    ior = factor(_ext(m, "KHR_materials_ior").get("ior"), 1.5,
                 "extensions.KHR_materials_ior.ior", None)
    spec = _ext(m, "KHR_materials_specular")
    trans = factor(_ext(m, "KHR_materials_transmission").get("transmissionFactor"), 0.0,
                   "extensions.KHR_materials_transmission.transmissionFactor")
    strength = factor(_ext(m, "KHR_materials_emissive_strength").get("emissiveStrength"),
                      1.0, "extensions.KHR_materials_emissive_strength.emissiveStrength",
                      None)
    f0_dielectric = (((ior - 1) / (ior + 1)) ** 2 if ior > 0 else 0.04) * np.minimum(
        np.array(spec.get("specularColorFactor", [1, 1, 1]), np.float64)
        * spec.get("specularFactor", 1.0), 1.0)
    f0 = f0_dielectric * (1 - metallic) + base * metallic
    n = roughness_exponent(rough)
    fields: dict[str, Any] = {
        "kd": base * (1 - metallic) * (1 - trans), "ks": f0 * (n + 8) / 8, "shininess": n,
        "highlight": "blinn_cosine", "kr": np.clip(f0 * (1 - rough) ** 2, 0, 1),
        "ior": ior if ior > 0 else 1.5,
        "ke": np.array(m.emissiveFactor if m is not None and m.emissiveFactor else [0, 0, 0],
                       np.float64) * strength}
    if trans > 0:
        fields.update(kt=np.clip(trans * base * (1 - metallic), 0, 1), kr=1.0,
                      fresnel="dielectric", **volume(_ext(m, "KHR_materials_volume"),
                                                     f"{key}.extensions.KHR_materials_volume",
                                                     path))
    mode = (m.alphaMode if m is not None else None) or "OPAQUE"
    if mode == "BLEND":
        fields["opacity"] = alpha
    elif mode == "MASK":
        cutoff = m.alphaCutoff if m.alphaCutoff is not None else 0.5
        fields["opacity"] = 1.0 if alpha >= cutoff else 0.0
    # COLOR_0 multiplies the base colour: kd and the ka that follows it, kt, and F0 (so ks
    # and kr) where it is the base colour (metallic 1; between 0 and 1 F0 keeps its share of
    # the base colour untinted)
    fields["vertex_colors"] = ("ka", "kd", *(("ks", "kr") if metallic == 1 else ()),
                               *(("kt",) if trans > 0 else ()))
    unlit = m is not None and "KHR_materials_unlit" in (m.extensions or {})
    if unlit:
        fields.update(ke=base, kd=0.0, ks=0.0, kr=0.0, ka=0.0, vertex_colors=("ke",))
    tex = pbr.baseColorTexture if pbr is not None else None
    if tex is not None and texture is not None:
        t = texture(gltf, tex, path, f"materials[{index}].pbrMetallicRoughness."
                    "baseColorTexture", mode)
        scale = base * (1 - metallic) * (1 - trans)
        if unlit:  # the textured base colour is the colour seen, unlit
            fields["ke"] = t.scaled(base)
        else:
            fields["kd"] = t.scaled(scale) if np.any(scale) else 0.0  # metallic: no 0s copied
        if mode in ("BLEND", "MASK"):  # the texture's alpha times the factor's
            fields["alpha"] = t
            fields["opacity"] = alpha
            fields["alpha_cutoff"] = (m.alphaCutoff if m.alphaCutoff is not None else 0.5
                                      ) if mode == "MASK" else -1.0
    if pbr is not None and pbr.metallicRoughnessTexture is not None and not unlit:
        named = f' ("{m.name}")' if m.name else ""
        warnings.warn(f"{path}: {key}{named}: metallicRoughnessTexture is not read: metallic "
                      f"{metallic:g}, roughness {rough:g} (the factors) are used over the "
                      "whole surface", RenderWarning, stacklevel=3)
    normal = m.normalTexture if m is not None else None
    if normal is not None and texture is not None:  # linear texels (glTF 2.0 §3.9.3)
        fields["normal_map"] = Relief(
            texture(gltf, normal, path, f"materials[{index}].normalTexture", mode, srgb=False),
            _number(normal.scale, 1.0, f"materials[{index}].normalTexture.scale", path))
    if m is not None and texture is not None and not unlit:
        fields.update(_emissive_occlusion(gltf, m, index, texture, path, fields["ke"]))
    try:
        out = Material(**fields, name=name)
    except SceneError as e:
        raise SceneError(e.problem, f"materials[{index}].{e.key}", str(path)) from None
    return out


def _number(value: Any, default: float, key: str, path: Path | None) -> float:
    """A finite number of the file (``default`` where absent), named by its key."""
    with located(path):
        return values.number(default if value is None else value, key)


def _emissive_occlusion(gltf: Any, m: Any, index: int, texture: Any, path: Path | None,
                        ke: np.ndarray) -> dict:
    """A lit material's ``emissiveTexture`` (sRGB, glTF 2.0 §3.9.4: texture × emissiveFactor,
    times KHR_materials_emissive_strength, already in ``ke``) as its ke, and its
    ``occlusionTexture`` (linear, R channel, §3.9.3: ambient × (1 + strength·(R − 1))) as
    its occlusion: the Material fields they give."""
    out: dict[str, Any] = {}
    key = f"materials[{index}]"
    if m.emissiveTexture is not None and np.any(ke):
        out["ke"] = texture(gltf, m.emissiveTexture, path, f"{key}.emissiveTexture",
                            "OPAQUE").scaled(ke)
    occ = m.occlusionTexture
    if occ is not None:
        strength = 1.0 if occ.strength is None else occ.strength
        with located(path):
            strength = values.number(strength, f"{key}.occlusionTexture.strength", lo=0, hi=1)
        out["occlusion"] = texture(gltf, occ, path, f"{key}.occlusionTexture", "OPAQUE",
                                   srgb=False).occlusion(strength)
    return out


def _light(spec: dict, world: np.ndarray, where: str, path: Path):
    """A KHR_lights_punctual light at its node (:data:`LIGHTS`): colour × intensity as its
    ``color``; point and spot (candela) at the inverse square, attenuation (0, 0, 1), with the
    spec's ``range`` window; a spot with the spec's falloff between ``innerConeAngle`` and
    ``outerConeAngle`` (``inner_cutoff`` and ``cutoff``, in degrees); directional (lux) as it
    is. The light shines down its node's −z."""
    kind = spec.get("type")
    color = np.array(spec.get("color", [1, 1, 1]), np.float64) * spec.get("intensity", 1.0)
    position = world[:3, 3]
    axis = world[:3, :3] @ [0.0, 0.0, -1.0]
    local = {"position": position, "color": color, "attenuation": (0, 0, 1),
             "range": spec.get("range")}
    try:
        if kind == "point":
            return PointLight(**local)
        if kind == "directional":
            return DirectionalLight(direction=axis, color=color)
        if kind == "spot":
            cone = spec.get("spot", {})
            outer = values.number(cone.get("outerConeAngle", math.pi / 4),
                                  "spot.outerConeAngle", lo=0, hi=math.pi / 2, lo_open=True)
            inner = values.number(cone.get("innerConeAngle", 0.0), "spot.innerConeAngle",
                                  lo=0, hi=outer)
            return SpotLight(**local, direction=axis, cutoff=math.degrees(outer),
                             inner_cutoff=math.degrees(inner))
    except SceneError as e:
        raise SceneError(e.problem, f"{where}.{e.key}", str(path)) from None
    raise SceneError(f"type must be point, spot or directional, got {kind!r}", where,
                     str(path))


#: KHR_lights_punctual: light type → what it becomes (intensity times colour as the light's
#: colour; candela for point and spot at an inverse-square attenuation (0, 0, 1) with the
#: spec's ``range`` window, the spot with the spec's cone falloff; lux for directional).
LIGHTS = {"point": "PointLight", "spot": "SpotLight", "directional": "DirectionalLight"}


#: Mesh compression extensions: their meshes are not decoded.
COMPRESSED = {"KHR_draco_mesh_compression": "Draco", "EXT_meshopt_compression": "meshopt",
              "KHR_meshopt_compression": "meshopt"}


def _compressed(name: str, key: str, path: Path) -> SceneError:
    return SceneError(f"{name}: its meshes are {COMPRESSED[name]}-compressed, which raytrace "
                      "does not decode; save the model without mesh compression", key,
                      str(path))


def _check_uncompressed(gltf: Any, prim: Any, key: str, path: Path) -> None:
    """A primitive compressed with an extension only in ``extensionsUsed`` may carry its
    uncompressed data as a fallback (KHR_draco_mesh_compression, "Conformance"); one whose
    POSITION has no buffer view has none, and is refused as a required one is."""
    for name in COMPRESSED:
        if name in (prim.extensions or {}) and (
                gltf.accessors[prim.attributes.POSITION].bufferView is None):
            raise _compressed(name, f"{key}.extensions", path)


def _check_extensions(gltf: Any, path: Path) -> None:
    for name in gltf.extensionsRequired or []:
        if name in COMPRESSED:
            raise _compressed(name, "extensionsRequired", path)
    required = [e for e in (gltf.extensionsRequired or []) if e not in SUPPORTED]
    if required:
        raise SceneError(f"requires extensions raytrace cannot read: {', '.join(required)}",
                         "extensionsRequired", str(path))
    dropped = [e for e in (gltf.extensionsUsed or []) if e not in SUPPORTED + NEUTRAL]
    if dropped:
        warnings.warn(f"{path}: extensions that change the look, drawn without them: "
                      f"{', '.join(dropped)}", RenderWarning, stacklevel=3)


@cached_reads(maxsize=4)
def _load_cached(path: str, resolved: str, stamp: tuple) -> GltfScene:
    """:func:`_load` of ``path`` (as the user wrote it, named by its errors and warnings),
    kept while the file at ``resolved`` keeps its ``stamp`` (modification time, size)."""
    try:
        return _load(Path(path))
    except SceneError as e:
        raise e.at(file=path) from None
    except (IndexError, KeyError, TypeError, ValueError, AttributeError) as e:
        # an index or a field that the file gets wrong, wherever it is read: one line
        raise SceneError(f"malformed glTF: {type(e).__name__}: {e}", file=path) from None


def load_gltf(path: Path) -> GltfScene:
    """The meshes, materials, first camera and lights of a .gltf or .glb file."""
    path = Path(path)
    input_file(path, "glTF file", file=str(path))
    st = path.stat()
    return _load_cached(str(path), str(path.resolve()), (st.st_mtime_ns, st.st_size))


@functools.cache
def _field_types(cls: type) -> dict[str, Any]:
    """A dataclass's field names → their types, its ``init`` fields only."""
    hints = typing.get_type_hints(cls)
    return {f.name: hints[f.name] for f in dataclasses.fields(cls) if f.init}


def gltf_objects(cls: Any, value: Any) -> Any:
    """``value`` (parsed JSON) as a ``cls``: for a pygltflib dataclass, the instance of the
    JSON object's known keys (each converted by its field's type; a key the class does not
    have dropped, a key the JSON lacks at the field's default), for ``List[X]`` and
    ``Optional[X]`` element by element, else the value itself. That is what
    dataclasses-json's ``_decode_dataclass`` with ``infer_missing`` makes of pygltflib's
    classes (tests/test_gltf.py compares the two objects on every glTF it has), without its
    per-value schema work: CesiumMilkTruck.glb's JSON in 0.002 s of CPU instead of 0.044 s
    (docs/performance.md, "Model files")."""
    if value is None:
        return None
    origin = typing.get_origin(cls)
    if origin is typing.Union:  # Optional[X]
        (inner,) = [a for a in typing.get_args(cls) if a is not type(None)]
        return gltf_objects(inner, value)
    if origin is list and isinstance(value, list):
        (inner,) = typing.get_args(cls)
        return [gltf_objects(inner, v) for v in value]
    if dataclasses.is_dataclass(cls) and isinstance(value, dict):
        types = _field_types(cls)
        return cls(**{k: gltf_objects(types[k], v) for k, v in value.items() if k in types})
    return value


@functools.cache
def _reader() -> type:
    """pygltflib's ``GLTF2`` (its GLB chunks, buffers and notes) with its JSON made into
    objects by :func:`gltf_objects`; pygltflib is imported here, where a glTF is read."""
    import pygltflib

    class Gltf(pygltflib.GLTF2):
        @classmethod
        def from_json(cls, s: str, *, infer_missing: bool = False, **kw: Any) -> Any:
            gltf = gltf_objects(cls, json.loads(s, **kw))
            if not isinstance(gltf, cls):
                raise ValueError("the JSON is not a glTF object")
            for mesh in gltf.meshes:  # as pygltflib's from_json: custom attributes kept
                for primitive in mesh.primitives:
                    if primitive.attributes:
                        primitive.attributes = pygltflib.Attributes(**primitive.attributes)
            return gltf
    return Gltf


def _load(path: Path) -> GltfScene:
    # pygltflib warns in paragraphs (asking for issues on its tracker) where a file is not one
    # it reads: its first note is the one line of a failure, or a RenderWarning line each.
    with warnings.catch_warnings(record=True) as notes:
        warnings.simplefilter("always")
        try:
            gltf = _reader()().load(str(path))
            failure = None if gltf is not None else "pygltflib read nothing"
        except Exception as e:  # pygltflib raises what json, struct or its own code raise
            gltf, failure = None, f"{type(e).__name__}: {e}"
    said = [str(n.message).split(" Please open an issue")[0].rstrip(". ") for n in notes]
    if gltf is None:
        raise SceneError(f"cannot read glTF: {said[0] if said else failure}", file=str(path))
    for note in said:
        warnings.warn(f"{path}: {note}", RenderWarning, stacklevel=2)
    _check_extensions(gltf, path)
    buffers = _buffers(gltf, path)
    # each image decoded once, from the buffers read once
    texture = functools.partial(gltf_texture, buffers=buffers, decoded={})
    materials: dict = {}
    verts, faces, face_mat, uvs, normals = [], [], [], [], []
    sources = buffer_files(gltf, path)
    tangents = []
    uvs1, colors = [], []  # per primitive: TEXCOORD_1 and COLOR_0 (None where it has none)
    camera, lights, offset, orthographic = None, [], 0, None
    light_specs = _ext(gltf, "KHR_lights_punctual").get("lights", [])
    for n, world in world_matrices(gltf):
        node = gltf.nodes[n]
        where = f"nodes[{n}]"
        if node.camera is not None and camera is None:
            cam = gltf.cameras[node.camera]
            if cam.type == "perspective" and cam.perspective is not None:
                r = world[:3, :3]
                camera = {"position": world[:3, 3], "look_at": world[:3, 3] + r @ [0, 0, -1.0],
                          "up": r @ [0, 1.0, 0], "fov": math.degrees(cam.perspective.yfov),
                          "aspect": cam.perspective.aspectRatio, "index": node.camera}
            elif cam.type == "orthographic" and orthographic is None:
                orthographic = node.camera
        light_ref = _ext(node, "KHR_lights_punctual").get("light")
        if light_ref is not None:
            if not 0 <= light_ref < len(light_specs):
                raise SceneError(f"no such light {light_ref}",
                                 f"{where}.extensions.KHR_lights_punctual.light", str(path))
            lights.append(_light(light_specs[light_ref], world, f"KHR_lights_punctual.lights"
                                 f"[{light_ref}]", path))
        if node.mesh is None:
            continue
        for p, prim in enumerate(gltf.meshes[node.mesh].primitives):
            if (prim.mode if prim.mode is not None else TRIANGLES) != TRIANGLES:
                raise SceneError("only TRIANGLES (mode 4) primitives are supported, got mode "
                                 f"{prim.mode}", f"meshes[{node.mesh}].primitives[{p}].mode",
                                 str(path))
            if prim.attributes.POSITION is None:
                continue
            _check_uncompressed(gltf, prim, f"meshes[{node.mesh}].primitives[{p}]", path)
            pos = accessor(gltf, buffers, prim.attributes.POSITION, path)
            idx = (accessor(gltf, buffers, prim.indices, path).reshape(-1, 3)
                   if prim.indices is not None else np.arange(len(pos)).reshape(-1, 3))
            uv = (accessor(gltf, buffers, prim.attributes.TEXCOORD_0, path)
                  if prim.attributes.TEXCOORD_0 is not None else None)
            normal = (accessor(gltf, buffers, prim.attributes.NORMAL, path)
                      if prim.attributes.NORMAL is not None else None)
            if normal is not None and normal.shape != pos.shape:
                raise SceneError(f"NORMAL has {normal.shape}, POSITION {pos.shape}: one "
                                 "3-vector a vertex", f"meshes[{node.mesh}].primitives[{p}]."
                                 "attributes.NORMAL", str(path))
            tangent = (accessor(gltf, buffers, prim.attributes.TANGENT, path)
                       if prim.attributes.TANGENT is not None else None)
            if tangent is not None and tangent.shape != (len(pos), 4):
                raise SceneError(f"TANGENT has {tangent.shape}, POSITION {pos.shape}: one "
                                 "4-vector a vertex", f"meshes[{node.mesh}].primitives[{p}]."
                                 "attributes.TANGENT", str(path))
            if idx.size and (idx.min() < 0 or idx.max() >= len(pos)):
                raise SceneError(f"index out of range 0..{len(pos) - 1}",
                                 f"meshes[{node.mesh}].primitives[{p}].indices", str(path))
            w = pos @ world[:3, :3].T + world[:3, 3]
            if np.linalg.det(world[:3, :3]) < 0:  # a mirroring transform flips the winding
                idx = idx[:, ::-1]
            if prim.material not in materials:
                materials[prim.material] = material(gltf, prim.material, texture, path)
            verts.append(w)
            faces.append(idx + offset)
            face_mat.append(np.full(len(idx), list(materials).index(prim.material)))
            uvs.append(uv[:, :2][idx] if uv is not None else np.zeros((len(idx), 3, 2)))
            uv1, color = _second_set_and_colors(gltf, buffers, prim, len(pos), path,
                                                f"meshes[{node.mesh}].primitives[{p}]",
                                                materials[prim.material])
            uvs1.append(uv1[idx] if uv1 is not None else None)
            colors.append(color[idx] if color is not None else None)
            # normals by the inverse transpose of the node's matrix (they stay perpendicular
            # to the transformed surface); none: zeros, flat (glTF 2.0 §3.7.2.1: "client
            # implementations MUST calculate flat normals")
            normals.append((normal @ normal_matrix(world[:3, :3]))[idx] if normal is not None
                           else np.zeros((len(idx), 3, 3)))
            # tangents along the surface: through the node's linear part (none: zeros,
            # MikkTSpace's where a normal map needs them, glTF 2.0 §3.7.2.1)
            tangents.append(given_tangents(tangent, world[:3, :3])[idx] if tangent is not None
                            else np.zeros((len(idx), 3, 4)))
            offset += len(pos)
    if not faces:
        raise SceneError("holds no triangles", "meshes", str(path))
    mats = list(materials.values())
    sources += [p for m in mats for p in m.sources]
    asset = Asset(np.concatenate(verts), np.concatenate(faces).astype(np.int64),
                  np.concatenate(face_mat).astype(np.int64), mats,
                  np.concatenate(uvs) if any(len(u) for u in uvs) else None, tuple(sources),
                  np.concatenate(normals) if any(n.any() for n in normals) else None,
                  np.concatenate(tangents) if any(t.any() for t in tangents) else None,
                  _corners(uvs1, uvs),
                  _corners(colors, [np.ones((len(f), 3, 4)) for f in faces]))
    return GltfScene(asset, camera, lights, orthographic)


def _corners(arrays: list, fallback: list) -> np.ndarray | None:
    """Per-primitive corner arrays concatenated where some primitive has one (a primitive
    without: its ``fallback``), else None."""
    if all(a is None for a in arrays):
        return None
    return np.concatenate([f if a is None else a for a, f in zip(arrays, fallback, strict=True)])


def _second_set_and_colors(gltf: Any, buffers: list[bytes], prim: Any, n: int, path: Path,
                           key: str, mat: Material) -> tuple[Any, Any]:
    """A primitive's TEXCOORD_1 (n, 2) and COLOR_0 (n, 4) as linear RGBA (§3.7.2.1: VEC3 or
    VEC4, float or normalised unsigned byte / short, which :func:`accessor` makes floats;
    alpha 1 for VEC3), each None where it has none; a material that reads TEXCOORD_1 on a
    primitive without it is an error."""
    attrs, out = prim.attributes, []
    for name, width in (("TEXCOORD_1", (2,)), ("COLOR_0", (3, 4))):
        index = getattr(attrs, name, None)
        a = accessor(gltf, buffers, index, path) if index is not None else None
        if a is not None and (len(a) != n or a.shape[1] not in width):
            raise SceneError(f"has {a.shape}, POSITION {n} rows: one "
                             f"{' or '.join(f'{w}-vector' for w in width)} a vertex",
                             f"{key}.attributes.{name}", str(path))
        out.append(a)
    uv1, color = out
    if uv1 is None and any(getattr(t, "uv_set", 0) == 1 for t in mat.textures):
        raise SceneError(f"material {mat.name!r} reads TEXCOORD_1 (texCoord 1), which this "
                         "primitive does not have", f"{key}.attributes", str(path))
    if color is not None and color.shape[1] == 3:
        color = np.concatenate([color, np.ones((n, 1))], axis=1)
    return uv1, color


def gltf_texture(gltf: Any, info: Any, path: Path, key: str, alpha_mode: str, *,
                 buffers: list[bytes] | None = None, decoded: dict | None = None,
                 srgb: bool = True) -> Texture:
    """A glTF ``textureInfo``: its image (a file, a data URI or a buffer view) decoded as sRGB
    (or linear: ``srgb`` False, as occlusion is), its sampler's wrapS / wrapT, and its mapping
    (:func:`texture_mapping`). ``buffers``: the file's buffers, where read already;
    ``decoded``: the images decoded so far by (image, wrap, sRGB), shared by the materials
    that use the same image the same way (whatever their mappings)."""
    where = str(path)
    try:
        tex = gltf.textures[info.index]
        gltf.images[tex.source]  # noqa: B018 (that it exists)
    except (IndexError, TypeError):
        raise SceneError("names no texture with an image", f"{key}.index", where) from None
    uv_set, transform = texture_mapping(info, key, path)
    wrap = ("repeat", "repeat")
    if tex.sampler is not None:
        s = gltf.samplers[tex.sampler]
        wrap = (GLTF_WRAPS.get(s.wrapS or 10497, "repeat"),
                GLTF_WRAPS.get(s.wrapT or 10497, "repeat"))
    decoded = {} if decoded is None else decoded
    if (tex.source, wrap, srgb) not in decoded:
        decoded[tex.source, wrap, srgb] = _image(gltf, tex.source, path, key, wrap, buffers,
                                                 srgb)
    return decoded[tex.source, wrap, srgb].mapped(uv_set, transform)


def texture_mapping(info: Any, key: str, path: Path) -> tuple[int, np.ndarray | None]:
    """A ``textureInfo``'s texture-coordinate set (``texCoord``: 0 or 1; a
    ``KHR_texture_transform.texCoord`` overrides it) and its KHR_texture_transform as a (2, 3)
    affine map of (s, t) (:func:`raytrace.readers.texture.uv_transform`, the extension's
    T·R·S), or None without one."""
    ext = _ext(info, "KHR_texture_transform")
    uv_set = ext.get("texCoord", info.texCoord or 0)
    if uv_set not in (0, 1):
        field = "extensions.KHR_texture_transform.texCoord" if "texCoord" in ext else "texCoord"
        raise SceneError(f"only TEXCOORD_0 and TEXCOORD_1 are supported, got {uv_set!r}",
                         f"{key}.{field}", str(path))
    if not ext.keys() - {"texCoord"}:
        return uv_set, None
    where = f"{key}.extensions.KHR_texture_transform"
    with located(path):
        ox, oy = values.vector(ext.get("offset", [0.0, 0.0]), f"{where}.offset", 2)
        kx, ky = values.vector(ext.get("scale", [1.0, 1.0]), f"{where}.scale", 2)
        r = values.number(ext.get("rotation", 0.0), f"{where}.rotation")
    return uv_set, uv_transform((ox, oy), r, (kx, ky))


def _image(gltf: Any, index: int, path: Path, key: str, wrap: tuple[str, str],
           buffers: list[bytes] | None, srgb: bool = True) -> Texture:
    """Image ``index`` (a file, a data URI or a buffer view) decoded as sRGB (or linear)."""
    image, where = gltf.images[index], str(path)
    if image.bufferView is not None:
        data, start, end = view_bytes(gltf, buffers or _buffers(gltf, path), image.bufferView,
                                      path, f"images[{index}].bufferView")
        return Texture.from_file(Path(f"{path.name}#images[{index}]"), key, wrap=wrap,
                                 where=where, data=data[start:end], srgb=srgb)
    uri = image.uri or ""
    if uri.startswith("data:"):
        return Texture.from_file(Path(f"{path.name}#images[{index}]"), key, wrap=wrap,
                                 where=where, data=base64.b64decode(uri.split(",", 1)[1]),
                                 srgb=srgb)
    return Texture.from_file(path.parent / unquote(uri), f"images[{index}].uri",
                             wrap=wrap, where=where, srgb=srgb)


def normal_matrix(linear: np.ndarray) -> np.ndarray:
    """The matrix that takes row normals through a node's linear part ``linear`` (3×3):
    its inverse (rows times M⁻¹ are M⁻ᵀ·n, the inverse transpose), or zeros where it is
    singular (a node scaled by 0, which glTF allows to hide a part: its faces have no area
    and are dropped, and their normals with them)."""
    if np.linalg.det(linear) == 0.0:
        return np.zeros((3, 3))
    return np.linalg.inv(linear)
