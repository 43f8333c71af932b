"""The named records that cross into the compiled kernels (pbrt-v4's ``workitems.soa``).

Every structure a kernel reads or writes is one of these typed named tuples of arrays (or,
for an emitter, of floats): a kernel takes a few records, reads fields by name, and a new
property is one field in one place. numba compiles named tuples like tuples (fields by
value, attribute access resolved at compile time), so they cost nothing over positional
arguments.

==================  ==================================================================
record              what it holds (n rays or hits, M materials, T triangles)
==================  ==================================================================
:class:`Rays`       a batch's columns (``raytrace.rays.RayBatch.record``)
:class:`Hits`       closest hits (``raytrace.accel.Hits`` is this)
:class:`Surface`    what shading needs at the hits (``raytrace.accel.Surface`` is this)
:class:`Shapes`     the analytic shapes' tables (``raytrace.tables.SceneArrays.shapes``)
:class:`Materials`  the material table (``raytrace.tables.MaterialTable.record``)
:class:`Triangles`  the float64 triangle tables (``raytrace.tables.SceneArrays.triangles``)
:class:`Scene`      what every shading kernel needs of the scene: camera position,
                    materials, triangles (and a light pass's fast-Phong table)
:class:`Emitter`    one point-like light sample, 21 floats (``raytrace.lights.Emitter.record``)
:class:`Shadows`    the shadow rays a light pass spawns
:class:`Children`   each hit's reflected, refracted and see-through children
:class:`Spawned`    the next depth's batch as :func:`raytrace.kernels.shading.spawn_children`
                    writes it
==================  ==================================================================
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np


class Rays(NamedTuple):
    """A batch of ``n`` rays (camera-relative)."""

    origin: np.ndarray        #: (n, 3) float64
    direction: np.ndarray     #: (n, 3) float64, unit
    sample: np.ndarray        #: (n,) int64, the pixel sample within the pass
    weight: np.ndarray        #: (n, 3) float64, the product of the factors along the path
    origin_shape: np.ndarray  #: (n,) int64, the analytic shape it starts on, or NO_SHAPE
    kind: np.ndarray          #: (n,) int8, rays.CAMERA, REFLECTION, …


class Hits(NamedTuple):
    """Closest hits of a batch of ``n`` rays."""

    t: np.ndarray         #: (n,) float64 distance along the unit direction; inf on a miss
    shape: np.ndarray     #: (n,) int64 analytic shape index, or NO_SHAPE
    triangle: np.ndarray  #: (n,) int64 global triangle index, or −1
    uv: np.ndarray        #: (n, 2) float64 barycentrics of vertices 1 and 2

    @property
    def hit(self) -> np.ndarray:
        return np.isfinite(self.t)


class Surface(NamedTuple):
    """What the shading needs at ``n`` hit points (float64, camera-relative)."""

    point: np.ndarray      #: (n, 3)
    geometric: np.ndarray  #: (n, 3) unit outward normal
    shading: np.ndarray    #: (n, 3) unit shading normal, on the side of ``geometric``
    material: np.ndarray   #: (n,) int64 row of the material table
    offset: np.ndarray     #: (n,) spawn offset (0 for analytic shapes)
    shape: np.ndarray      #: (n,) int64 analytic shape, or NO_SHAPE
    triangle: np.ndarray   #: (n,) int64, or −1
    uv: np.ndarray         #: (n, 2) barycentrics


class Shapes(NamedTuple):
    """The analytic shapes, N of them, numbered kind by kind (``accel_kernels.SHAPE_KINDS``'
    order) and in the scene's order within a kind (``raytrace.tables.shape_tables``)."""

    kind: np.ndarray      #: (N,) int64 accel_kernels.SPHERE, PLANE, …
    rows: np.ndarray      #: (N, accel_kernels.ROW) float64 camera-relative parameters, the
                          #: scene record's ``row`` zero-padded (``Sphere.row``, …)
    material: np.ndarray  #: (N,) int64 row of the material table
    object: np.ndarray    #: (N,) int64 index in ``Scene.objects``


#: The material table's per-material columns, name → (dtype, what it holds); a Material's
#: value for each: ``raytrace.material.COLUMNS``.
MATERIAL_COLUMNS = {
    "shininess": (np.float64, "highlight exponent n"),
    "highlight": (np.int64, "kinds.PHONG or BLINN"),
    "ior": (np.float64, "relative index of refraction"),
    "opacity": (np.float64, "t of the seeds' blend"),
    "lit": (np.bool_, "takes direct light (kd or ks not zero)"),
    "reflects": (np.bool_, "kr not zero"),
    "transmits": (np.bool_, "kt not zero"),
    "emits": (np.bool_, "ke not zero"),
    "fresnel": (np.int64, "kinds.NO_FRESNEL, SCHLICK or DIELECTRIC"),
    "alpha_cutoff": (np.float64, "alpha ≥ cutoff: opaque, else clear; −1: blend"),
}
#: The material table's arrays besides its per-material columns (:data:`MATERIAL_COLUMNS`).
MATERIAL_TABLES = {
    "colors": "(M, 3·C) constant colours of material.COLOR_KEYS (ka kd ks kr kt ke), three "
              "columns each",
    "pattern": "(M, C) int64 row of checkers per colour, or −1 (constant)",
    "checkers": "(P, 7) colour 0, colour 1, scale",
    "texture": "(M, C) int64 image texture per colour (row of tex_info), or −1",
    "textured": "(M,) bool: some colour is an image texture, or the alpha is",
    "texels": "(N,) float32 every texture's RGBA rows, one after another",
    "tex_info": "(K, 5) int64 offset into texels, width, height, wrap s, wrap t",
    "alpha": "(M,) int64 texture whose alpha multiplies the opacity, or −1",
}
#: The material table, indexed by ``Surface.material``: the fields of
#: :data:`MATERIAL_TABLES`, then one (M,) array per entry of ``material.COLUMNS``, in its
#: order (a material input is declared once, there).
Materials = NamedTuple("Materials", [(name, np.ndarray) for name in (*MATERIAL_TABLES,
                                                                    *MATERIAL_COLUMNS)])
Materials.__doc__ = "The material table, indexed by ``Surface.material``.\n\n" + "\n".join(
    f"* ``{name}``: {what}" for name, what in (
        *MATERIAL_TABLES.items(), *((k, f"(M,) {v[1]}") for k, v in MATERIAL_COLUMNS.items())))


class Triangles(NamedTuple):
    """The float64 triangle tables, T triangles in Embree's geomID order."""

    geom_first: np.ndarray  #: (G,) int64 first triangle of each mesh (geomID)
    corners: np.ndarray     #: (T, 3, 3) camera-relative corners
    normal: np.ndarray      #: (T, 3) unit face normal (counter-clockwise winding)
    vnormals: np.ndarray    #: (T, 3, 3) unit vertex normals at the corners
    shading: np.ndarray     #: (T,) int8 core.FLAT, SMOOTH, GOURAUD or FAST_PHONG
    material: np.ndarray    #: (T,) int64 row of the material table
    band: np.ndarray        #: (T,) float64 error band: the float32 rounding scale of the
                            #: corners (accel_kernels.triangle_tables)
    #: (T, 3, 2) (s, t) at the corners; none (0, 3, 2) where no material has a texture
    texcoords: np.ndarray = np.zeros((0, 3, 2))


class Scene(NamedTuple):
    """What the shading kernels need of the scene."""

    origin: np.ndarray       #: (3,) the camera position: world = camera-relative + origin
    materials: Materials
    triangles: Triangles
    #: (T, 12) the fast-Phong polynomials of the light of a light pass (directional, some
    #: ``fast_phong`` mesh: ``raytrace.fast_phong.tables``); no rows: exact shading
    fast: np.ndarray = np.zeros((0, 12))
    #: (T, 3, 2) the triangles' texture coordinates where some material has an image texture,
    #: else None: the material lookup's texture code (``kernels.material``) is compiled, and
    #: its tables bound, only where they are an array
    texcoords: np.ndarray | None = None


class Emitter(NamedTuple):
    """One point-like light sample (camera-relative), passed by value."""

    kind: float      #: shading_kernels.POINT, SPOT or DIRECTIONAL
    px: float        #: position (unused for a directional light)
    py: float
    pz: float
    dx: float        #: the spot's axis, or the way a directional light travels
    dy: float
    dz: float
    a0: float        #: radial attenuation 1/(a0 + a1·d + a2·d²)
    a1: float
    a2: float
    cos_cutoff: float  #: cos θ of a spot's cone
    exponent: float    #: a in (cos α)^a
    ux: float        #: a jittered area-light cell's edges
    uy: float
    uz: float
    vx: float
    vy: float
    vz: float
    stream: float    #: ≥ 0: a jittered area light's hash stream (exact below 2⁵²); −1 otherwise
    ou: float        #: a jittered cell (i, j) of k × k: its canonical offsets j/k and i/k
    ov: float        #: (shading_kernels.incidence1)


class Shadows(NamedTuple):
    """Shadow rays of the hits a light pass lights, in hit order (the first k rows)."""

    rows: np.ndarray       #: (n,) int64 the hit each one decides
    origin: np.ndarray     #: (n, 3)
    direction: np.ndarray  #: (n, 3) unit, towards the light
    tmax: np.ndarray       #: (n,) where it stops, a little short of the light
    shape: np.ndarray      #: (n,) int64 the analytic shape it starts on, or NO_SHAPE


class Children(NamedTuple):
    """Each hit's children: reflected, refracted (or TIR), see-through."""

    r_dir: np.ndarray   #: (n, 3) reflected direction
    t_dir: np.ndarray   #: (n, 3) refracted direction (the mirror one under TIR)
    w_r: np.ndarray     #: (n, 3) weights
    w_t: np.ndarray
    w_s: np.ndarray
    status: np.ndarray  #: (n, 3) int8 shading_kernels.NONE, PRUNED or KEEP per child
    tir: np.ndarray     #: (n,) bool total internal reflection


class Spawned(NamedTuple):
    """The next depth's rays as they are written, and each one's parent hit."""

    origin: np.ndarray
    direction: np.ndarray
    weight: np.ndarray
    sample: np.ndarray
    shape: np.ndarray
    kind: np.ndarray
    parent: np.ndarray  #: (k,) int64 row of the parent hit


class Objects(NamedTuple):
    """Which object of the scene's ``objects`` each analytic shape and mesh is."""

    shape_object: np.ndarray  #: (N,) int64 index in ``Scene.objects`` of each analytic shape
    geom_object: np.ndarray   #: (G,) int64 index in ``Scene.objects`` of each mesh (geomID)


class AOVLayout(NamedTuple):
    """The columns of the AOVs asked for in the per-sample and per-pixel tables of
    :mod:`raytrace.kernels.aov` (built by :func:`raytrace.film.aov.layout`)."""

    table: np.ndarray  #: (K, 4) int64 per AOV: kind (kernels.aov.AOV_KINDS), first column,
                       #: columns, combine (kernels.aov.NEAREST or MEAN)
    miss: np.ndarray   #: (C,) float64 each column where the camera ray missed (0: +inf)


class Local(NamedTuple):
    """What a hit's own light adds, besides its emission: the ambient light and the direct
    light the light passes summed (``kernels.shading.hit_terms``)."""

    ambient: np.ndarray  #: (3,) Ia
    lights: np.ndarray   #: (n, 3) Σ_l S_l·f_l·I_l·[kd·max(N·L, 0) + ks·spec]; no rows: unlit
