"""A scene rendered again keeps its acceleration structure, until its geometry changes.

Scripted use renders one scene many times (a sweep of settings, several cameras that share an
eye, a regression suite rendering one scene several ways); like Mitsuba's loaded scene, the
Embree BVH and the float64 triangle tables (:class:`raytrace.accel.Accelerator`) are then
built once per geometry:

    scene = raytrace.load_scene("scenes/mesh_model.toml")
    raytrace.render(scene, spp=1)            # builds
    raytrace.render(scene, spp=16)           # reuses: same geometry, same eye
    scene.camera = raytrace.Camera(position=scene.camera.position, look_at=[0, 0, 0], fov=30)
    raytrace.render(scene)                   # reuses: the eye did not move
    scene.objects[0].vertices[:, 1] += 0.1   # moved in place
    raytrace.render(scene)                   # rebuilds

**The key** is a fingerprint of everything the accelerator is built from, hashed afresh at
every render (BLAKE2b over the arrays' bytes, about 1 ms a MB: 3 ms for 82 k triangles against
a 0.2 s build): the camera position (the accelerator is camera-relative, docs/architecture.md,
"Precision": another eye gives other float32 vertices, so a camera path that moves the eye
rebuilds, and every image stays bit-identical to a render in a fresh process), and each
object in order: its kind, its geometry (an analytic shape's table row, ``row(origin)``, so a
new shape type is hashed by what it registers; a mesh's world-space vertices and faces,
shading, texture coordinates, file normals, per-face materials) and its materials' places
in the render's material table. A material's colours,
the lights, the camera's direction and field of view and every render setting are not part of
it. A mesh's ``translate``, ``rotate`` and ``scale`` are applied when the ``Mesh`` is made; its
``vertices`` are what is rendered and what is hashed. Hashing the bytes rather than counting
mutations catches in-place edits of the arrays, which no setter sees.

The cache holds one accelerator a scene, for as long as the scene object lives (a finalizer
drops it); :data:`builds` counts the accelerators built in this process.
"""

from __future__ import annotations

import hashlib
import threading
import weakref

import numpy as np

from .accel import Accelerator
from .kernels.accel import pack_row
from .material import COLOR_KEYS
from .readers.texture import Texture
from .scene import Mesh, Scene
from .tables import SceneArrays

#: Accelerators built in this process (a test's and a benchmark's view of the cache).
builds = 0
_lock = threading.Lock()
#: id(scene) → (fingerprint, accelerator, the arrays it was built from), each entry dropped
#: when its scene is collected.
_cache: dict[int, tuple[bytes, Accelerator, SceneArrays]] = {}


def fingerprint(scene: Scene, materials: list) -> bytes:
    """BLAKE2b digest of every input of the accelerator of ``scene`` whose materials are
    ``materials`` (module docstring)."""
    h = hashlib.blake2b(digest_size=32)

    def add(*parts) -> None:
        for p in parts:
            if p is None:
                h.update(b"\0none")
                continue
            a = np.ascontiguousarray(p)
            h.update(f"{a.dtype.str}{a.shape}".encode())
            h.update(a.data if a.size else b"")

    index = {id(m): i for i, m in enumerate(materials)}
    add(scene.camera.position)
    h.update(b"textured" if any(isinstance(getattr(m, k), Texture) for m in materials
                                for k in COLOR_KEYS) or any(m.alpha is not None
                                                            for m in materials) else b"plain")
    origin = np.asarray(scene.camera.position, np.float64)
    for o in scene.objects:
        h.update(type(o).__name__.encode())
        if isinstance(o, Mesh):
            h.update(o.shading.encode())
            add(o.vertices, o.faces, o.texcoords, o.normals, o.face_material, o.degenerate,
                o.texcoords1, o.colors,
                [index[id(m)] for m in o.materials])
        else:  # an analytic shape: its table row, as the stage makes it (tables.shape_tables)
            add(pack_row(o.type, o.row(origin)), index[id(o.material)])
    return h.digest()


def accelerator(scene: Scene, arrays: SceneArrays, threads: int = 1) -> Accelerator:
    """The accelerator of ``arrays`` (``scene``'s, :func:`raytrace.tables.scene_arrays`): the
    one built for the scene before if its :func:`fingerprint` is unchanged, whose triangle
    tables ``arrays`` then takes instead of building them again; else a new one (kept in place
    of the old), its BVH built on ``threads`` threads."""
    global builds
    key = fingerprint(scene, arrays.materials)
    with _lock:
        hit = _cache.get(id(scene))
    if hit is not None and hit[0] == key:
        arrays.share_geometry(hit[2])
        return hit[1]
    accel = Accelerator(arrays, threads)
    with _lock:
        builds += 1
        if id(scene) not in _cache:
            weakref.finalize(scene, _cache.pop, id(scene), None)
        _cache[id(scene)] = (key, accel, arrays)
    return accel


def clear() -> None:
    """Forget every kept accelerator (the next render of each scene builds again): for a
    benchmark that times the build inside each render."""
    with _lock:
        _cache.clear()
