"""The named records that cross into the compiled kernels (pbrt-v4's ``workitems.soa``), and
the named layouts of the rows the kernels read packed.

Every structure a kernel reads or writes is one of these typed named tuples, of arrays (a
batch's columns) or of values (one ray, one hit): a kernel takes a few records, reads fields
by name, and a new property is one field in one place. numba compiles named tuples like
tuples (fields by value, attribute access resolved at compile time), so they cost nothing
over positional arguments. Each record holds what its kernels read, no more.

=======================  ==============================================================
record                   what it holds (n rays or hits, M materials, T triangles)
=======================  ==============================================================
**batches**
:class:`Rays`            a batch's columns (``raytrace.rays.RayBatch.record``)
:class:`Hits`            closest hits (``raytrace.accel.Hits`` is this)
:class:`Surface`         what shading needs at the hits (``raytrace.accel.Surface`` is this)
:class:`Shapes`          the analytic shapes' tables (``raytrace.tables.SceneArrays.shapes``)
:class:`Materials`       the material table (``raytrace.tables.MaterialTable.record``)
:class:`Triangles`       the float64 triangle tables (``raytrace.tables.SceneArrays.triangles``)
:class:`Scene`           what every shading kernel needs of the scene: camera position,
                         materials, triangles (and a light pass's fast-Phong table)
:class:`Media`           the materials' absorbing interiors and thin walls (``Scene.media``)
:class:`Emitter`         one point-like light sample, 23 floats
                         (``raytrace.lights.Emitter.record``)
:class:`Shadows`         the shadow rays a light pass spawns
:class:`ShadowWalk`      transparent shadow rays crossing the surfaces they hit
:class:`SampleSums`      where each hit's term is added: the pass's sums, a row per hit
:class:`Children`        each hit's reflected, refracted and see-through children
:class:`Spawned`         the next depth's batch as :func:`raytrace.kernels.shading.spawn_children`
                         writes it
:class:`Objects`         which scene object each shape and mesh is (the ``id`` AOV)
:class:`AOVLayout`       the AOVs' columns
:class:`FirstHits`       the camera rays' first hits, as the AOVs read them
**queries** (:mod:`raytrace.accel`)
:class:`Query`           the rays of a closest-hit query that Embree answers
:class:`ShadowQuery`     the rays of an occlusion query
:class:`EmbreeRays`      rays as Embree takes them (float32)
:class:`EmbreeHits`      Embree's closest hits as it gives them
:class:`EmbreeScene`     an Embree scene and its traversal calls, by address
:class:`Redo`            rays traced again past a float32 artefact, and from where
**the compiled loop** (:mod:`raytrace.kernels.loop`)
:class:`Tracer`          the scene as the loop reads it
:class:`LightTable`      the emitters, their colours and fast-Phong tables
:class:`PassSettings`    the render's settings
:class:`PassIO`          a pass's sums, jitter keys, AOV table and camera packets, and the
                         render's stop flag
:class:`CameraPackets`   a pass's camera rays as Embree traces them, block by block
:class:`Tally`           a pass's counters
**camera and film**
:class:`Pinhole`         the frame as a pinhole sees it
:class:`Sampling`        how a frame's pixel samples are numbered and placed
:class:`Window`          a window of pixels (a crop, or what is traced)
:class:`RoundSamples`    a noise-driven round's samples: offsets, pixels and light keys
:class:`Moments`         the running moments of each pixel's samples (a noise-driven render)
:class:`Doublings`       a noise-driven round's doublings of samples, in order of priority;
                         :class:`DoublingPixels` the pixels, :class:`DoublingTable` what
                         each doubling gives, :class:`Aim` where they stop
:class:`FilterProfile`   a reconstruction filter
:class:`Cells`           adaptive anti-aliasing's cells of a level, :class:`Level` its rule,
                         :class:`SlotGrid` its lattice points' table
**one ray or hit, by value**
:class:`Ray`             a ray's origin and direction (an analytic shape's intersection)
:class:`SpawnPoint`      where a spawned ray leaves a surface (``core.leave1``)
:class:`MaterialHit`     a hit as a material lookup reads it
:class:`MeshHit`         a hit on a triangle as Gouraud, fast Phong and Hanika's lift read it
:class:`Finish`          what the local model reads of a material at a hit
:class:`Palette`         the material table's constant colours and checkers
:class:`SmoothTriangles` the corners and vertex normals of the triangles
:class:`Mips`            the mip-map pyramids and ray-cone footprints of trilinear lookups
:class:`Reliefs`         the normal and height maps that perturb the shading normals
=======================  ==============================================================

**Packed rows.** Where a table packs several values in a row (a shape's parameters, a
checker, a texture's size and wrap, a fast-Phong polynomial pair, an AOV's columns), each
value's column is a named constant here, beside the record whose table it lays out: the code
that packs the row and the kernel that reads it both use the name.
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
    "highlight": (np.int64, "kinds.PHONG, BLINN or BLINN_COSINE"),
    "ior": (np.float64, "relative index of refraction"),
    "opacity": (np.float64, "t of the seeds' blend"),
    "lit": (np.bool_, "takes direct light (kd or ks not zero)"),
    "reflects": (np.bool_, "kr not zero"),
    "transmits": (np.bool_, "kt not zero"),
    "emits": (np.bool_, "ke not zero"),
    "fresnel": (np.int64, "kinds.NO_FRESNEL, SCHLICK or DIELECTRIC"),
    "alpha_cutoff": (np.float64, "alpha ≥ cutoff: opaque, else clear; −1: blend"),
}
#: The columns of a row of ``Materials.checkers`` (packed by ``raytrace.tables.MaterialTable``,
#: read by ``raytrace.kernels.material.color1``): colour 0 (r, g, b), colour 1 (r, g, b), the
#: cell size s (``checker1``), 1 where it is box-filtered over the pixel's footprint
#: (``filter = "box"``, ``checker_box1``) else 0.
CHECKER_COLOR0, CHECKER_COLOR1, CHECKER_SCALE, CHECKER_FILTER = 0, 3, 6, 7
CHECKER_COLUMNS = 8
#: The columns of a row of ``Materials.tex_info`` (packed by ``raytrace.tables.MaterialTable``,
#: read by ``raytrace.kernels.core.bilinear1``): the texture's first element in ``texels``, its
#: width and height in texels, its wrap modes along s and t (``raytrace.readers.texture.WRAPS``).
TEX_OFFSET, TEX_WIDTH, TEX_HEIGHT, TEX_WRAP_S, TEX_WRAP_T = range(5)
TEX_COLUMNS = 5
#: The columns of a row of ``Materials.tex_map``, one texture use's mapping (packed by
#: ``raytrace.tables.MaterialTable`` from ``Texture.uv_set`` and ``Texture.transform``, read
#: by ``raytrace.kernels.material.texture_st1``): its texture-coordinate set (0: the mesh's
#: first, glTF TEXCOORD_0; 1: glTF TEXCOORD_1), 1.0 where it has an affine transform (0.0:
#: the identity, read with no arithmetic), then that transform's rows a b c d e f:
#: ``s' = a·s + b·t + c``, ``t' = d·s + e·t + f``.
MAP_SET, MAP_AFFINE, MAP_MATRIX = 0, 1, 2
MAP_COLUMNS = 8
#: The material table's arrays besides its per-material columns (:data:`MATERIAL_COLUMNS`).
MATERIAL_TABLES = {
    "colors": "(M, 3·C) constant colours of material.COLOR_KEYS (ka kd ks kr kt ke), three "
              "columns each",
    "pattern": "(M, C) int64 row of checkers per colour, or −1 (constant)",
    "checkers": f"(P, {CHECKER_COLUMNS}) colour 0, colour 1, scale, filter (CHECKER_COLOR0, …)",
    "texture": "(M, C) int64 image texture per colour (row of tex_info), or −1",
    "textured": "(M,) bool: some colour is an image texture, or the alpha or the occlusion is",
    "texels": "(N,) float32 every texture's RGBA rows, one after another",
    "tex_info": f"(K, {TEX_COLUMNS}) int64 offset into texels, width, height, wrap s, wrap t "
                "(TEX_OFFSET, …)",
    "alpha": "(M,) int64 texture whose alpha multiplies the opacity, or −1",
    "tex_map": f"(K, {MAP_COLUMNS}) float64 each texture's uv set and affine map (MAP_SET, …); "
               "None where every texture reads set 0 unmapped (no mapping code compiled)",
    "tinted": "(M, C) bool: the colours vertex colours multiply (material.vertex_colors); None "
              "in a scene without vertex colours",
    "occlusion": "(M,) int64 texture (its RGB 1 + strength·(occlusion − 1)) that multiplies "
                 "ka, or −1; None where no material has one",
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
    #: (T, 3, 2) the second set (glTF TEXCOORD_1; the first on a mesh without one) where some
    #: mesh has one, else None
    texcoords1: np.ndarray | None = None
    #: (T, 3, 4) linear RGBA vertex colours at the corners (glTF COLOR_0; white on a mesh
    #: without them) where some mesh has them, else None (no vertex-colour code compiled)
    colors: np.ndarray | None = None


#: The columns of a row of ``Scene.fast``, one triangle's fast-Phong polynomials for one
#: directional light (packed by ``raytrace.fast_phong.coefficients``, read by
#: ``raytrace.kernels.shading.fast_phong1``): the diffuse polynomial's coefficients T₀…T₅ of
#: ``1, du, dv, du², du·dv, dv²`` from FAST_DIFFUSE, the specular one's from FAST_SPECULAR.
FAST_DIFFUSE, FAST_SPECULAR = 0, 6
FAST_TERMS, FAST_COLUMNS = 6, 12


class Media(NamedTuple):
    """What lies behind each material's surface (``raytrace.material.Material``'s
    ``attenuation_color``, ``attenuation_distance`` and ``thin_walled``), indexed by
    ``Surface.material`` (``kernels.medium``)."""

    #: (M, 3) float64 Beer's law coefficient σ = −ln(attenuation colour)/distance per unit
    #: length, per channel; 0: a clear interior
    sigma: np.ndarray
    thin: np.ndarray   #: (M,) bool a thin wall: a transmitted ray goes straight on


class Scene(NamedTuple):
    """What the shading kernels need of the scene."""

    origin: np.ndarray       #: (3,) the camera position: world = camera-relative + origin
    materials: Materials
    triangles: Triangles
    #: (T, FAST_COLUMNS) the fast-Phong polynomials of the light of a light pass
    #: (directional, some ``fast_phong`` mesh: ``raytrace.fast_phong.tables``); no rows:
    #: exact shading
    fast: np.ndarray = np.zeros((0, FAST_COLUMNS))
    #: (T, 3, 2) the triangles' texture coordinates where some material has an image texture,
    #: else None: the material lookup's texture code (``kernels.material``) is compiled, and
    #: its tables bound, only where they are an array
    texcoords: np.ndarray | None = None
    #: the materials' interiors (:class:`Media`) where some material absorbs or is thin-walled,
    #: else None: the absorption and thin-wall code (``kernels.medium``) is compiled only then
    media: Media | None = None
    #: the mip-map pyramids and ray-cone footprints of ``texture_filter = "trilinear"``
    #: (:class:`Mips`, ``raytrace.mipmap.with_mips``), else None: no trilinear code compiled
    mips: Mips | None = None
    #: the materials' normal and height maps and the triangles' tangent frames where some
    #: material has one, else None: ``kernels.material.relief1`` is then compiled as nothing
    reliefs: Reliefs | None = None
    #: γ, a camera sample's ray-cone spread (radians, ``raytrace.mipmap.spread_angle``) where
    #: some checker is box-filtered (``filter = "box"``), else None: the filter's code
    #: (``kernels.material.checker_share1``) is then not compiled
    spread: float | None = None


class Emitter(NamedTuple):
    """One point-like light sample (camera-relative), passed by value."""

    kind: float      #: kinds.POINT, SPOT, DIRECTIONAL or SMOOTH_SPOT
    px: float        #: position (unused for a directional light)
    py: float
    pz: float
    dx: float        #: the spot's axis, or the way a directional light travels
    dy: float
    dz: float
    a0: float        #: radial attenuation 1/(a0 + a1·d + a2·d²)
    a1: float
    a2: float
    cos_cutoff: float  #: cos θ of a spot's cone (a smooth spot's outer cone)
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
    cos_inner: float  #: cos of a smooth spot's inner cone, where its falloff begins
    range: float     #: > 0: the KHR_lights_punctual window max(min(1 − (d/range)⁴, 1), 0); 0: none


#: Floats in an :class:`Emitter`: the width of a row of ``LightTable.rows``.
EMITTER_FIELDS = len(Emitter._fields)


class Shadows(NamedTuple):
    """Shadow rays of the hits a light pass lights, in hit order (the first k rows)."""

    rows: np.ndarray       #: (n,) int64 the hit each one decides
    origin: np.ndarray     #: (n, 3)
    direction: np.ndarray  #: (n, 3) unit, towards the light
    tmax: np.ndarray       #: (n,) where it stops, a little short of the light
    shape: np.ndarray      #: (n,) int64 the analytic shape it starts on, or NO_SHAPE


class ShadowWalk(NamedTuple):
    """Transparent shadow rays that hit a surface before their light, as they cross it
    (``kernels.shading.cross_surfaces``)."""

    direction: np.ndarray  #: (n, 3) unit, towards the light
    t: np.ndarray          #: (n,) distance to the surface crossed
    tmax: np.ndarray       #: (n,) where the ray stops, short of the light


class SampleSums(NamedTuple):
    """Where each hit's term is added (``kernels.shading.hit_terms``)."""

    sums: np.ndarray  #: (S, 3) float64 the pass's per-sample radiance sums
    row: np.ndarray   #: (n,) int64 each hit's row of ``sums``


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


#: The columns of a row of ``AOVLayout.table``, one AOV (packed by
#: ``raytrace.film.aov.layout``, read by ``raytrace.kernels.aov``): its kind
#: (``kernels.aov.AOV_KINDS``), its first column in the per-sample and per-pixel tables, how
#: many columns it has, how a pixel combines its samples (``kernels.aov.NEAREST`` or ``MEAN``).
AOV_KIND, AOV_FIRST, AOV_COUNT, AOV_COMBINE = range(4)
AOV_COLUMNS = 4
#: The column of the per-sample and per-pixel AOV tables that holds the distance t of the
#: camera ray's hit (+inf on a miss), which picks a pixel's nearest sample.
AOV_DISTANCE = 0


class AOVLayout(NamedTuple):
    """The columns of the AOVs asked for in the per-sample and per-pixel tables of
    :mod:`raytrace.kernels.aov` (built by :func:`raytrace.film.aov.layout`)."""

    table: np.ndarray  #: (K, AOV_COLUMNS) int64, a row per AOV (AOV_KIND, AOV_FIRST, …)
    miss: np.ndarray   #: (C,) float64 each column where the camera ray missed (0: +inf)


class Local(NamedTuple):
    """What a hit's own light adds, besides its emission: the ambient light and the direct
    light the light passes summed (``kernels.shading.hit_terms``)."""

    ambient: np.ndarray  #: (3,) Ia
    lights: np.ndarray   #: (n, 3) Σ_l S_l·f_l·I_l·[kd·max(N·L, 0) + ks·spec]; no rows: unlit


class FirstHits(NamedTuple):
    """The camera rays' first hits as the AOVs read them (``kernels.aov.aov_value1``); every
    ray hit something."""

    direction: np.ndarray  #: (n, 3) the rays' unit directions
    t: np.ndarray          #: (n,) the distances of their hits
    surface: Surface       #: the hits' surfaces


# -- the queries of the intersection stage (raytrace.accel, kernels/accel.py) ------------------
class Query(NamedTuple):
    """The rays of a closest-hit query of ``n`` rays, camera-relative, as the Embree side of
    it reads them (``kernels.accel.embree_rays``, ``refine_hits``, ``retrace_rays``)."""

    origin: np.ndarray     #: (n, 3) float64
    direction: np.ndarray  #: (n, 3) float64, unit
    tmax: np.ndarray       #: (n,) float64 far bound of each ray, read only where ``has_tmax``
    has_tmax: bool         #: whether the rays have a far bound (else only the analytic hit)


class ShadowQuery(NamedTuple):
    """The rays of an occlusion query of ``n`` rays (``kernels.accel.shadow_prepass``)."""

    origin: np.ndarray        #: (n, 3) float64
    direction: np.ndarray     #: (n, 3) float64, unit
    origin_shape: np.ndarray  #: (n,) int64 the analytic shape each starts on, or NO_SHAPE
    tmax: np.ndarray          #: (n,) float64 where each stops, a little short of its light


class EmbreeRays(NamedTuple):
    """``k`` rays as Embree takes them."""

    origin: np.ndarray     #: (k, 3) float32
    direction: np.ndarray  #: (k, 3) float32
    far: np.ndarray        #: (k,) float32 tfar, the bound of each (float32 max: none)


class EmbreeHits(NamedTuple):
    """Embree's closest hits of ``k`` rays, as it gives them (``output=1``)."""

    geom_id: np.ndarray  #: (k,) int32 the mesh (attach order), −1 on a miss
    prim_id: np.ndarray  #: (k,) int32 the triangle within it
    u: np.ndarray        #: (k,) float32 barycentrics of vertices 1 and 2
    v: np.ndarray


class EmbreeScene(NamedTuple):
    """An Embree scene as the traversal kernels call it (``raytrace.embree.Meshes.record``):
    handles and addresses as integers, so no address is compiled into cached code."""

    scene: int       #: the RTCScene
    intersect: int   #: the address of rtcIntersectN (N = ``width``)
    occluded: int    #: the address of rtcOccludedN
    width: int       #: N, the packet width: 4, 8 or 16
    coherent: int    #: the address of an RTCIntersectArguments with the COHERENT flag
    incoherent: int  #: the address of one without it


# -- the compiled loop (kernels/loop.py) ------------------------------------------------------
class Tracer(NamedTuple):
    """What the compiled loop needs of the scene, built once per render
    (``raytrace.integrator.WhittedIntegrator``)."""

    shapes: Shapes          #: the analytic shapes
    scene: Scene            #: what the shading kernels read (``fast`` empty: each light's own
                            #: table is in :class:`LightTable`)
    embree: EmbreeScene | None  #: Embree's scene; None without meshes (no Embree code)
    meshes: bool            #: whether there are meshes (Embree is called)
    objects: Objects        #: the id AOV's objects
    aov_layout: AOVLayout   #: the AOVs' columns
    #: True where some light and some lit material make light passes run, else None
    lit: bool | None
    #: True where shadow rays walk through transparent surfaces, else None (occlusion)
    transparent: bool | None
    #: True, or None where nothing reflects or transmits (no child code is compiled)
    children: bool | None
    #: True, or None without triangles and image textures (light_pass's ``depth`` None)
    shaded: bool | None


class LightTable(NamedTuple):
    """The emitters, a row each (:class:`Emitter`'s fields in order), their colours and their
    fast-Phong tables (rows ``fast_first[e]`` to ``fast_first[e + 1]`` of ``fast``)."""

    rows: np.ndarray        #: (E, EMITTER_FIELDS) float64
    color: np.ndarray       #: (E, 3) float64 I_l
    fast: np.ndarray        #: (R, FAST_COLUMNS) float64
    fast_first: np.ndarray  #: (E + 1,) int64


class PassSettings(NamedTuple):
    """A render's settings as the compiled loop reads them."""

    per_pass: int            #: most rays a batch holds before it is cut into chunks
    max_depth: int
    min_weight: float
    any_background: bool     #: missed rays add the background
    background: np.ndarray   #: (1, 3) float64
    ambient: np.ndarray      #: (3,) float64 Ia
    clock: int               #: the address of ``clock_gettime`` (0: no timing)
    clock_id: int            #: its monotonic clock's id


class CameraPackets(NamedTuple):
    """A pass's camera rays as Embree traces them: every sample of each block of the frame
    that holds one of the pass's, a slot each, in COHERENT packets
    (``kernels.camera.frame_packets``); or a noise-driven round's, each pixel's samples in
    packets of their own (``kernels.camera.pixel_packets``), every slot the pass's."""

    direction: np.ndarray  #: (m, 3) float64 each slot's unit direction (origin 0)
    sample: np.ndarray     #: (m,) int64 its sample within the pass, or −1: not the pass's
    bounds: np.ndarray     #: (k + 1,) int64 where each packet starts, then m


class PassIO(NamedTuple):
    """What one pass writes and the rays and keys it reads, a row per pass sample, and the
    render's stop flag, which the loop reads between batches and lights
    (``raytrace.integrator.Stop``)."""

    samples: np.ndarray       #: (S, 3) float64 radiance sums
    keys: np.ndarray | None   #: (S,) int64 jitter keys of a jittered area light, or None
    aov: np.ndarray | None    #: (S, C) float64 the per-sample AOV table, or None
    stop: np.ndarray          #: (1,) int64, not 0: end the pass at the next batch or light
    #: the camera rays' packets (:class:`CameraPackets`), or None: plain packets
    packets: CameraPackets | None


class Tally(NamedTuple):
    """A pass's counters (kernels/loop.py's ``COUNTERS`` and ``SECONDS`` columns)."""

    counters: np.ndarray  #: (COUNTERS,) int64
    seconds: np.ndarray   #: (SECONDS,) float64
    timespec: np.ndarray  #: (2,) int64, the clock's scratch


class Redo(NamedTuple):
    """Rays traced again from beyond a float32 artefact (``kernels.accel.refine_hits``), and
    a second pass's map back to its batch (``retrace_rays``); no rows: the first pass, ray j
    at row j from its origin."""

    rows: np.ndarray  #: (k,) int64 the ray's row in its batch
    adv: np.ndarray   #: (k,) float64 how far along the ray its pass starts


# -- camera and film (kernels/camera.py, kernels/filters.py, kernels/adaptive.py) --------------
class Pinhole(NamedTuple):
    """The frame as a pinhole camera sees it (``kernels.camera.direction1``): the image plane
    one unit along ``forward``."""

    width: int         #: the frame's size in pixels
    height: int
    tan_half: float    #: tan(fov/2), fov the vertical field of view
    right: tuple       #: (x, y, z) the camera's unit axes
    up: tuple
    forward: tuple


class Sampling(NamedTuple):
    """How a frame's pixel samples are numbered and placed: sample ``cell`` of pixel (col,
    row) is global sample ``(row·width + col)·spp + cell``, at ``core.pixel_offset`` in its
    pixel (the camera and the filters both read it)."""

    width: int  #: the frame's width in pixels
    spp: int    #: samples per pixel
    k: int      #: the side of the stratification grid (``raytrace.camera.grid``), 0: none
    seed: int   #: the render's seed of the jitter


class Window(NamedTuple):
    """A window of pixels of the frame, half-open: columns ``x0 … x1 − 1``, rows ``y0 …
    y1 − 1`` (a crop, or what is traced)."""

    x0: int
    y0: int
    x1: int
    y1: int


class RoundSamples(NamedTuple):
    """The ``m`` samples of a noise-driven round (``kernels.noise.round_points``), in the
    round's order."""

    sx: np.ndarray    #: (m,) float64 the offset in [0, 1) inside the pixel, x
    sy: np.ndarray    #: (m,) float64 and y
    col: np.ndarray   #: (m,) int64 the pixel's column of the frame
    row: np.ndarray   #: (m,) int64 and row
    keys: np.ndarray  #: (m,) int64 the light key of its area-light points


class Moments(NamedTuple):
    """The running moments of each pixel's samples, all of them pooled
    (``kernels.noise.add_round``): a render by target error or time ranks pixels by them."""

    count: np.ndarray  #: (k,) int64 the pixel's samples
    mean: np.ndarray   #: (k, 3) float64 their mean
    m2: np.ndarray     #: (k, 3) float64 their summed squared deviations from it


class DoublingPixels(NamedTuple):
    """The pixels a noise-driven round's doublings are ranked over
    (``kernels.noise.rank_doublings``), in window order."""

    n: np.ndarray      #: (k,) int64 the pixel's samples a half
    sigma: np.ndarray  #: (k,) float64 σ̃, the standard deviation it is ranked by
    s2: np.ndarray     #: (k,) float64 s², its per-sample variance (0 where not finite)
    kind: np.ndarray   #: (k,) int64 its count's row of the :class:`DoublingTable`


class DoublingTable(NamedTuple):
    """What a pixel's j-th doubling of a round gives, by its count (a row of J columns):
    from m = count·2^j samples a half to m' = min(2m, ``most``)."""

    scale: np.ndarray  #: (kinds, J) float64 its priority over σ̃, m^−(1+β)/2
    #: (kinds, J) float64 the variance it takes off over s², (2m)^−β − (2m')^−β
    drop: np.ndarray
    most: int          #: the most samples a half a pixel reaches


class Aim(NamedTuple):
    """Where a round's doublings stop (``kernels.noise.rank_doublings``): at the first that
    has added ``goal`` samples a half, or sooner, at the first that has added ``least`` and
    whose summed drops of the variance reach ``need`` (``need`` and ``least`` inf: no such
    stop; a ``need`` that is NaN never reached)."""

    goal: float
    need: float
    least: float


class Doublings(NamedTuple):
    """Pixels' doublings of samples in order of priority (``kernels.noise.rank_doublings``):
    the j-th takes pixel ``pixel[j]``'s samples a half from ``n·2^step[j]`` to twice that
    (at most the most a pixel reaches)."""

    pixel: np.ndarray  #: (k,) int64 the pixel (window order)
    step: np.ndarray   #: (k,) int64 the doubling's number in the round, from 0


class FilterProfile(NamedTuple):
    """A reconstruction filter as ``kernels.filters.filter_pixels`` reads it."""

    code: int      #: kinds.BOX, TENT, GAUSSIAN or MITCHELL
    radius: float  #: in pixels
    reach: int     #: the whole pixels its footprint spans each way


class Cells(NamedTuple):
    """The cells of one level of adaptive refinement (``kernels.adaptive.judge_cells``)."""

    ci: np.ndarray     #: (n,) int64 lattice column of each cell's top-left point
    cj: np.ndarray     #: (n,) int64 lattice row
    pixel: np.ndarray  #: (n,) int64 its pixel's row of the output


class Level(NamedTuple):
    """How one level of adaptive refinement judges its cells."""

    size: int          #: a cell's side in lattice steps
    threshold: float   #: the corners' spread from which a cell is cut
    everywhere: bool   #: cut every cell, whatever its corners
    last: bool         #: the deepest level: cut none
    weight: float      #: 4^−level, an uncut cell's share of its pixel


class SlotGrid(NamedTuple):
    """Where a pass's slot table puts lattice point (i, j): ``slot[(j − j0)·stride + (i −
    i0)]`` (``kernels.adaptive.corners1``)."""

    stride: int  #: lattice points a row of the table
    i0: int      #: the lattice point of its first entry
    j0: int


# -- one ray or hit, by value (scalars and 3-tuples: no reference counts) -------------------
class Ray(NamedTuple):
    """One ray, camera-relative float64, as an analytic shape's intersection reads it
    (``kernels.accel.sphere_t``, …)."""

    origin: tuple     #: (x, y, z)
    direction: tuple  #: (x, y, z), unit


class SpawnPoint(NamedTuple):
    """Where a spawned ray leaves a surface (``kernels.core.leave1``)."""

    point: tuple      #: (x, y, z) the hit point, camera-relative
    geometric: tuple  #: (x, y, z) the unit geometric normal (either side)
    offset: float     #: how far off the surface it starts (0 on an analytic shape)


class Footprint(NamedTuple):
    """A camera sample's ray-cone footprint on a surface as a box filter reads it
    (``kernels.mip.cone_footprint1``): ``probes`` boxes of half-widths ``extent`` along the
    world axes, centred along the footprint's major axis."""

    major: tuple    #: (x, y, z) the ellipse's major semi-axis, a world vector
    probes: int     #: boxes along it (1 where the footprint is round)
    extent: tuple   #: (ex, ey, ez) each box's half-widths along the world axes


class MaterialHit(NamedTuple):
    """A hit as a material's colours and opacity are looked up at it
    (``kernels.material.surface_color1``)."""

    world: tuple    #: (x, y, z) the world point (a checker is a function of it)
    triangle: int   #: the triangle hit, −1 off a mesh
    u: float        #: its barycentrics (where an image texture is read)
    v: float
    #: the camera-relative point (the axis of the camera's ray cone to it) and the geometric
    #: normal (any length): a box-filtered checker's footprint (``kernels.mip.cone_footprint1``)
    axis: tuple
    normal: tuple


class MeshHit(NamedTuple):
    """A hit on a triangle as Gouraud shading, fast Phong and Hanika's lift read it
    (``kernels.shading.gouraud1``, ``fast_phong1``, ``bulge1``)."""

    triangle: int  #: global triangle index
    u: float       #: barycentrics of vertices 1 and 2
    v: float
    side: float    #: +1 seen from the side of the normals (outward), −1 from the other


class Finish(NamedTuple):
    """What the local model reads of a material at a hit (``kernels.shading.direct1``)."""

    kd: tuple          #: (r, g, b) diffuse colour
    ks: tuple          #: (r, g, b) specular colour
    shininess: float   #: the highlight's exponent n
    highlight: int     #: kinds.PHONG, BLINN or BLINN_COSINE


class Palette(NamedTuple):
    """The material table's constant colours and checkers (``kernels.material.color1``)."""

    colors: np.ndarray    #: ``Materials.colors``
    pattern: np.ndarray   #: ``Materials.pattern``
    checkers: np.ndarray  #: ``Materials.checkers``
    spread: float | None  #: ``Scene.spread``: a box-filtered checker's cone spread, or None


class SmoothTriangles(NamedTuple):
    """The two triangle tables a smooth or Gouraud hit's helpers read (a per-hit helper
    handed the whole :class:`Triangles` pays reference counts for every array of it)."""

    corners: np.ndarray   #: ``Triangles.corners``
    vnormals: np.ndarray  #: ``Triangles.vnormals``


class TextureTables(NamedTuple):
    """What the material lookup reads of image textures (``kernels.material.texture_tables1``),
    bound once a kernel."""

    textured: np.ndarray   #: ``Materials.textured``
    texture: np.ndarray    #: ``Materials.texture``
    texels: np.ndarray     #: ``Materials.texels``
    tex_info: np.ndarray   #: ``Materials.tex_info``
    texcoords: np.ndarray  #: ``Triangles.texcoords``
    #: ``Triangles.texcoords1``, ``Materials.tex_map``, ``.occlusion``, ``.tinted`` and
    #: ``Triangles.colors``: each None compiles none of its code (kernels.material)
    texcoords1: np.ndarray | None
    tex_map: np.ndarray | None
    occlusion: np.ndarray | None
    tinted: np.ndarray | None
    colors: np.ndarray | None
    mips: Mips | None = None  #: ``Scene.mips``: None, bilinear lookups


class Mips(NamedTuple):
    """What a trilinear lookup reads besides the textures' level 0 (``raytrace.mipmap``,
    ``kernels.mip``): every texture's box-filtered levels 1 … L, each triangle's
    texel-to-world ratio Δ and the camera's pixel spread angle (ray cones, Akenine-Möller et
    al. 2019)."""

    texels: np.ndarray  #: (N,) float32 the levels ≥ 1 of every texture, RGBA rows, flat
    levels: np.ndarray  #: (R, TEX_COLUMNS) int64 each level's offset into ``texels``, width,
                        #: height and wrap modes (``tex_info``'s columns)
    first: np.ndarray   #: (K,) int64 row of ``levels`` of texture q's level 1
    count: np.ndarray   #: (K,) int64 levels of texture q beyond level 0 (0 for a 1 × 1 one)
    size_lod: np.ndarray  #: (K,) float64 ½·log₂(w·h) of texture q's level 0 (w × h texels)
    delta: np.ndarray   #: (T,) float64 Δ = ½·log₂(t_a/p_a) per triangle (−inf: no UV area)
    normal: np.ndarray  #: (T, 3) float64 ``Triangles.normal``
    origin: tuple       #: (x, y, z) the camera's world position (cones start there)
    spread: float       #: γ, the cone's spread angle per camera sample (radians)


class AlphaTables(NamedTuple):
    """What the material lookup reads of alpha textures (``kernels.material.alpha_tables1``),
    bound once a kernel."""

    alpha: np.ndarray         #: ``Materials.alpha``
    alpha_cutoff: np.ndarray  #: ``Materials.alpha_cutoff``
    texels: np.ndarray        #: ``Materials.texels``
    tex_info: np.ndarray      #: ``Materials.tex_info``
    texcoords: np.ndarray     #: ``Triangles.texcoords``
    texcoords1: np.ndarray | None  #: ``Triangles.texcoords1``
    tex_map: np.ndarray | None     #: ``Materials.tex_map``


class Reliefs(NamedTuple):
    """What perturbs a triangle hit's shading normal (``kernels.material.relief1``): each
    material's normal or height map, and the triangles' texture coordinates and tangent
    frames (``raytrace.tables.relief_tables``)."""

    texture: np.ndarray    #: (M,) int64 row of ``tex_info`` of the material's map, or −1
    kind: np.ndarray       #: (M,) int64 kinds.NORMAL_MAP or HEIGHT_MAP
    scale: np.ndarray      #: (M,) float64 the normal map's scale, the height map's bm
    texels: np.ndarray     #: ``Materials.texels``
    tex_info: np.ndarray   #: ``Materials.tex_info``
    corners: np.ndarray    #: ``Triangles.corners``
    #: (T, 3, 2) the corners' (s, t) as the material's map reads them: its uv set through its
    #: transform (``raytrace.tables.relief_texcoords``; ``Triangles.texcoords`` unmapped)
    texcoords: np.ndarray
    tangents: np.ndarray   #: (T, 3, 4) unit tangent and sign w at the corners (glTF TANGENT)
