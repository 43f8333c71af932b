"""Scene files: TOML (native) or JSON with the same structure, per SCENE_FORMAT.md.

Validation is strict: an unknown key, a wrong type, an out-of-range value or a missing file
raises :class:`~raytrace.errors.SceneError` naming the file, the key path and the problem.
"""

from __future__ import annotations

import dataclasses
import json
import tomllib
import warnings
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from .. import values
from ..errors import RenderWarning, SceneError
from ..lights import DirectionalLight
from ..material import Material, library, material_from_table
from ..scene import FROM_FILE, LIGHT_TYPES, OBJECT_TYPES, Camera, Mesh, RenderSettings, Scene
from .asset import COLORED_SUFFIXES, GLTF_SUFFIXES, MESH_SUFFIXES, OBJ_SUFFIXES
from .bundle import remember
from .gltf import load_gltf
from .inputs import input_file, read_text, recording
from .obj import names_mtl

TOP_KEYS = ("render", "camera", "ambient", "materials", "lights", "objects")
RENDER_KEYS = ("width", "height", "spp", "max_depth", "min_weight", "background", "seed",
               "filter", "aa", "aa_threshold", "aa_depth", "aa_min_depth", "noise_threshold",
               "min_spp", "max_spp", "texture_filter")
CAMERA_KEYS = ("position", "look_at", "up", "fov")


def _keys(cls: type) -> tuple[str, ...]:
    """A record's scene-file keys: ``type`` and its fields (those set in ``__init__`` that
    only Python can pass, such as a trimesh ``mesh``, excepted)."""
    return ("type", *(f.name for f in dataclasses.fields(cls)
                      if f.init and f.name not in PYTHON_ONLY))


def _required(cls: type) -> tuple[str, ...]:
    """A record's fields without a default."""
    return tuple(f.name for f in dataclasses.fields(cls) if f.init
                 and f.default is dataclasses.MISSING
                 and f.default_factory is dataclasses.MISSING)


#: Fields a Python caller may set that a scene file may not (a ``trimesh.Trimesh``).
PYTHON_ONLY = ("mesh",)
LIGHT_KEYS = {cls: _keys(cls) for cls in LIGHT_TYPES.values()}
OBJECT_KEYS = {cls: _keys(cls) for cls in OBJECT_TYPES.values()}
REQUIRED = {cls: _required(cls) for cls in (*LIGHT_TYPES.values(), *OBJECT_TYPES.values())}


def load_scene(path: str | Path) -> Scene:
    """Read a ``.toml`` or ``.json`` scene file into a :class:`Scene`; a model or mesh file
    alone (``.obj``, ``.gltf``, ``.glb``, ``.ply``, ``.stl``, ``.off``) becomes a scene too
    (:func:`scene_from_model`). The scene is remembered with the files read for it
    (:func:`raytrace.readers.bundle.remember`): a cluster's workers get those files' bytes
    and read them again, rather than the decoded arrays."""
    with recording() as reads:
        scene, portable = _read_scene(Path(path))
    if portable:
        remember(scene, path, reads)
    return scene


def _read_scene(path: Path) -> tuple[Scene, bool]:
    """The scene of :func:`load_scene`, and whether its files can be read again elsewhere
    from their bytes alone: not where the scene file names one by an absolute path."""
    name = str(path)
    if path.suffix.lower() in GLTF_SUFFIXES + OBJ_SUFFIXES + MESH_SUFFIXES:  # no TOML
        return scene_from_model(path), True
    text = read_text(path, "scene file", file=name)
    if not text.strip():  # (a file of only comments is a scene of defaults: no objects)
        raise SceneError("the scene file is empty", file=name)
    try:
        if path.suffix.lower() == ".json":
            data = json.loads(text)
        else:
            data = tomllib.loads(text)
    except (tomllib.TOMLDecodeError, json.JSONDecodeError) as e:
        kind = "JSON" if path.suffix.lower() == ".json" else "TOML"
        raise SceneError(f"invalid {kind}: {e}", file=name) from None
    except RecursionError:  # both parsers recurse once a level: ~1000 levels is their end
        raise SceneError(f"nested too deep to read (a scene is at most {MAX_NESTING} levels "
                         "deep)", file=name) from None
    try:
        return scene_from_dict(data, path.parent, name), not _names_absolute(data)
    except SceneError as e:
        raise SceneError(e.problem, e.key, e.file or name) from None


def _names_absolute(data: Any) -> bool:
    """Whether a scene file's tables name a file (``file``, ``texture``) by an absolute
    path, at any depth."""
    if isinstance(data, Mapping):
        return any((k in ("file", "texture") and isinstance(v, str) and Path(v).is_absolute())
                   or _names_absolute(v) for k, v in data.items())
    return isinstance(data, list) and any(_names_absolute(v) for v in data)


def scene_from_dict(data: Mapping, folder: str | Path = ".", name: str | None = None) -> Scene:
    """A :class:`Scene` from the parsed structure of a scene file (also for Python dicts)."""
    folder = Path(folder)
    _check_nesting(data)
    values.check_keys(data, TOP_KEYS, "")
    render_table = _table(data, "render")
    values.check_keys(render_table, RENDER_KEYS, "render")
    render = RenderSettings(**render_table)
    cam_table = _table(data, "camera")
    values.check_keys(cam_table, CAMERA_KEYS, "camera")
    camera = Camera(**cam_table)
    amb = _table(data, "ambient")
    values.check_keys(amb, ("color",), "ambient")
    materials = _materials(_in_folder(_table(data, "materials"), folder))
    lights = [_light(t, f"lights[{i}]") for i, t in enumerate(_array(data, "lights"))]
    objects = [_object(t, f"objects[{i}]", folder) for i, t in enumerate(_array(data, "objects"))]
    return Scene(camera=camera, objects=objects, lights=lights, materials=materials,
                 ambient=amb.get("color", 0.0), render=render, path=name)


#: The most levels of tables and arrays a scene may nest: a checker colour of an object's
#: inline material is 7 (the file, objects, the object, material, kd, colors, a colour).
MAX_NESTING = 32


def _check_nesting(data: Any) -> None:
    """Refuse tables and arrays nested more than :data:`MAX_NESTING` deep (or a Python dict
    that contains itself), naming the top-level entry that holds them (``objects[3]``),
    before anything recursive (reading, copying, printing a value) meets them. A walk with a
    stack of its own, not recursion."""
    stack = [(data, "", 1)]
    while stack:
        value, key, depth = stack.pop()
        if isinstance(value, Mapping):
            items = [(f"{key}.{k}" if key else str(k), v) for k, v in value.items()]
        elif isinstance(value, (list, tuple)):
            items = [(f"{key}[{i}]", v) for i, v in enumerate(value)]
        else:
            continue
        if depth > MAX_NESTING:
            raise SceneError(f"nested more than {MAX_NESTING} levels deep", key)
        # (keys below an entry such as objects[3] stay its key: a deep one is no help)
        stack.extend((v, k if depth < 3 else key, depth + 1) for k, v in items)


def _table(data: Mapping, key: str) -> Mapping:
    value = data.get(key, {})
    if not isinstance(value, Mapping):
        raise SceneError(f"must be a table, got {values.type_name(value)}", key)
    return value


def _array(data: Mapping, key: str) -> list:
    value = data.get(key, [])
    if not isinstance(value, list) or not all(isinstance(t, Mapping) for t in value):
        raise SceneError(f"must be an array of tables ([[{key}]]), got "
                         f"{values.type_name(value)}", key)
    return value


def _materials(tables: Mapping) -> dict[str, Material]:
    """Scene-local materials; ``base`` may name another scene material or a library one."""
    done: dict[str, Material] = {}
    busy: list[str] = []

    def get(name: str, key: str) -> Material:
        if busy and name == busy[-1] and name in library:
            # `[materials.brass] base = "brass"`: the scene's brass refines the library's
            # (scene materials shadow library ones of the same name everywhere else).
            return library[name]
        if name in done:
            return done[name]
        if name in tables:
            if name in busy:
                own = (f" (a material may take only the library material of its own name as "
                       f"its base, and the library has no {name!r})" if name == busy[-1]
                       else "")
                raise SceneError(f"materials form a cycle: {' -> '.join([*busy, name])}{own}",
                                 key)
            busy.append(name)
            table = tables[name]
            if not isinstance(table, Mapping):
                raise SceneError(f"must be a table, got {values.type_name(table)}",
                                 f"materials.{name}")
            done[name] = material_from_table(table, f"materials.{name}", get, name)
            busy.pop()
            return done[name]
        if name in library:
            return library[name]
        raise SceneError(f"unknown material {name!r}"
                         f"{values.did_you_mean(name, [*tables, *library])} (not in this "
                         "scene's materials nor the library; see `raytrace materials`)", key)

    for name in tables:
        get(name, f"materials.{name}")
    return done


def _in_folder(table: Any, folder: Path) -> Any:
    """A copy of ``table`` with every ``{ texture = "file" }`` relative to ``folder`` (the scene
    file's), at any depth."""
    if not isinstance(table, Mapping):
        return table
    out = {k: _in_folder(v, folder) for k, v in table.items()}
    if isinstance(out.get("texture"), str):
        out["texture"] = str(folder / out["texture"])
    return out


def _construct(cls: type, table: Mapping, key: str, **extra: Any):
    for req in REQUIRED.get(cls, ()):
        if req not in table:
            raise SceneError("is required", f"{key}.{req}")
    kwargs = {k: v for k, v in table.items() if k != "type"}
    kwargs.update(extra)
    try:
        return cls(**kwargs)
    except SceneError as e:  # an error located in another file (an MTL, a glTF) keeps its key
        raise (e if e.file else e.at(key_prefix=key)) from None


def _light(table: Mapping, key: str):
    kind = values.string(table.get("type", "point"), f"{key}.type", LIGHT_TYPES)
    cls = LIGHT_TYPES[kind]
    values.check_keys(table, LIGHT_KEYS[cls], key)
    return _construct(cls, table, key)


def _object(table: Mapping, key: str, folder: Path):
    if "type" not in table:
        raise SceneError(f"is required (one of {', '.join(map(repr, OBJECT_TYPES))})",
                         f"{key}.type")
    kind = values.string(table["type"], f"{key}.type", OBJECT_TYPES)
    cls = OBJECT_TYPES[kind]
    values.check_keys(table, OBJECT_KEYS[cls], key)
    extra = {}
    if isinstance(table.get("material"), Mapping):
        extra["material"] = _in_folder(table["material"], folder)
    if cls is Mesh and "file" in table:
        extra["file"] = folder / values.string(table["file"], f"{key}.file")
    return _construct(cls, table, key, **extra)


#: What a model file alone is rendered with: a grey world (a glTF or OBJ file has no
#: background) and a little ambient light, so the unlit sides are not black.
MODEL_BACKGROUND = 0.3
MODEL_AMBIENT = 0.1


def scene_from_model(path: Path) -> Any:
    """A whole scene from a model file alone (``raytrace render model.glb``): the file's
    meshes with their own materials; its camera and lights (glTF) where it has them, else a
    camera framing the bounding box (:func:`framing_camera`) and a light over the camera's
    shoulder, both reported as a :class:`~raytrace.errors.RenderWarning` line."""
    path = Path(path)
    input_file(path, "model file", file=str(path))
    found = None
    if path.suffix.lower() in GLTF_SUFFIXES:
        found = load_gltf(path)
    # the file's own materials where it has them (a glTF, an OBJ naming an MTL library; a PLY
    # or an OFF: the default material tinted by its vertex colours), else the default material
    # (an STL, an OBJ alone)
    own = found is not None or (path.suffix.lower() in OBJ_SUFFIXES and names_mtl(path)) or (
        path.suffix.lower() in COLORED_SUFFIXES)
    try:
        mesh = Mesh(file=path, material=FROM_FILE if own else None)
    except SceneError as e:
        raise SceneError(e.problem, e.key if e.file else None, e.file or str(path)) from None
    render = RenderSettings()
    notes = []
    # an orthographic camera met first is not read (raytrace's cameras are perspective)
    skipped = (f"cameras[{found.orthographic}] is orthographic: not read; "
               if found is not None and found.orthographic is not None else None)
    if found is not None and found.camera is not None:
        cam = found.camera
        camera = Camera(cam["position"], cam["look_at"], cam["up"], cam["fov"])
        if cam["aspect"]:
            render = RenderSettings(height=max(1, round(640 / cam["aspect"])))
        if skipped:
            notes.append(f"{skipped}cameras[{cam['index']}], the first perspective camera, "
                         "is used")
    else:
        camera = framing_camera(mesh.vertices, aspect=render.width / render.height)
        notes.append(f"{skipped or 'no camera in the file: '}camera at "
                     f"{_vec(camera.position)} looking at {_vec(camera.look_at)}, fov "
                     f"{camera.fov:g}{' instead' if skipped else ''}")
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


#: The share of the field of view (across or up, whichever binds) that a framed model's
#: bounding box fills.
FILL = 0.9
#: The camera's elevation over a model lying flat (its height under :data:`FLAT` of its
#: depth), which a view along the horizon would see edge-on.
FLAT, FLAT_ELEVATION = 0.1, 30.0


def framing_camera(vertices: np.ndarray, fov: float = 40.0, aspect: float = 4 / 3) -> Any:
    """A camera in front of the model, framing its bounding box, as the Khronos glTF Sample
    Viewer places its default camera: the front of a model faces +z (glTF 2.0 §3.4, "the
    front of a glTF asset faces +Z"), so the camera looks at the box's centre from the +z
    side with +y up, outside the box; it is level with the centre, or raised by
    :data:`FLAT_ELEVATION` over a flat model.

    With w the unit vector from the centre to the camera, right r and up u, a corner p
    (relative to the centre) is at depth D − p·w from a camera at distance D, and fills no
    more than :data:`FILL` of the view when |p·r| ≤ FILL·aspect·tan(fov/2)·(D − p·w) and
    |p·u| ≤ FILL·tan(fov/2)·(D − p·w) (``fov`` vertical, ``aspect`` = width / height); D is
    the least distance where all eight corners do, so the box fills FILL of the view across
    or up. Level (w = +z), that is D = hz + max(hx / (FILL·aspect·tan(fov/2)),
    hy / (FILL·tan(fov/2))) for half extents (hx, hy, hz)."""
    lo, hi = vertices.min(axis=0), vertices.max(axis=0)
    centre, half = (lo + hi) / 2, (hi - lo) / 2
    e = np.radians(FLAT_ELEVATION) if half[1] < FLAT * half[2] else 0.0
    w, u = np.array([0, np.sin(e), np.cos(e)]), np.array([0, np.cos(e), -np.sin(e)])
    corners = half * np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)])
    tan_up = FILL * np.tan(np.radians(fov / 2))
    depth = corners @ w
    d = np.maximum(depth + np.abs(corners[:, 0]) / (tan_up * aspect),
                   depth + np.abs(corners @ u) / tan_up).max()
    d = max(d, depth.max() + 1e-9 * (1 + np.abs(lo).max()))  # a point: just outside it
    return Camera(centre + d * w, centre, (0, 1, 0), fov)


def _vec(v: np.ndarray) -> str:
    return "[" + ", ".join(f"{x:.4g}" for x in v) + "]"
