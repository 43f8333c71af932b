"""A deliberately slow, plainly recursive Whitted tracer, independent of the renderer: the
oracle for the wavefront.

It reads only the scene description (:mod:`raytrace.scene`'s shapes, lights and camera,
:mod:`raytrace.material`'s Material and Checker: the data) and does everything else itself,
one ray at a time in float64 with Python and numpy, written from the formulas of
/work/shared/SCENE_FORMAT.md and docs/shading.md. Nothing of the renderer's intersection,
lighting, shading, optics or camera code is imported (tests/test_reference_tracer.py checks
that in a fresh interpreter).

* **Camera** (SCENE_FORMAT.md, "Conventions", ``[camera]``): a pinhole at ``position``
  looking at ``look_at``; ``fov`` is the vertical field of view; pixel (0, 0) is the top-left
  one and its ray passes through the pixel centre: ``x = (2(col + ½)/W − 1)·tan(fov/2)·W/H``,
  ``y = (1 − 2(row + ½)/H)·tan(fov/2)`` on the image plane one unit along the view direction,
  right = forward × up. Only spp = 1 is traced (the pixel centre).
* **Intersection**, brute force in world coordinates: spheres by the quadratic
  ``t² + 2bt + c = 0`` (``b = d·(o − c)``) with its discriminant written as ``r² − |f|²``,
  ``f = (o − c) − b·d``, and the second root from Vieta (Haines et al., "Precision
  Improvements for Ray/Sphere Intersection", Ray Tracing Gems, 2019); planes by
  ``t = (p − o)·n / (d·n)``, disks as their plane's hit where ``|o + t·d − c| ≤ r``; every
  triangle of every mesh by Möller & Trumbore ("Fast,
  minimum storage ray-triangle intersection", 1997), a ray through the edge two triangles
  share counting as a hit on one of them (``EDGE``), small meshes tested together and each
  group behind a bounding sphere.
* **Leaving a surface** (this tracer's own rule; nothing is offset): a ray starts exactly at
  its parent's hit point. It skips the primitive it leaves (a straight ray leaving a plane
  or a triangle never meets it again), except that on a sphere a ray going inward takes the
  far root; every other primitive counts only beyond ``T_MIN·(1 + max|o|)``, so that a
  neighbour sharing the edge or the plane of the hit (a quad's other half) is not met again
  at a rounding-sized distance. A shadow ray from Hanika's lifted point (rule 2 below) starts
  off the surface and does meet its own triangle where it crosses it.
* **Shading**: SCENE_FORMAT.md's equation per RGB channel,
  ``I = ka·Ia + Σ_l S_l·f_radial·f_angular·I_l·[kd·max(N·L, 0) + ks·spec] + kr·I_r + kt·I_t``
  then ``I_ray = t·I + (1 − t)·I_behind``; ``spec = (V·R)^n`` with ``R = 2(N·L)N − L``
  (Phong 1975) or ``(N·H)^n`` with ``H = (L + V)/|L + V|`` (Blinn 1977), 0 where the cosine
  is ≤ 0 and where N·L ≤ 0; ka defaults to kd; N is turned to the viewer; the emission
  ``ke`` is added to I (inside the opacity blend). ``fresnel`` weights kr and kt by the
  angle of incidence, cos θ = −d·N: "schlick" ``kr + (1 − kr)(1 − cos θ)⁵`` (Schlick 1994),
  "dielectric" ``kr·F``, ``kt·(1 − F)`` with F the unpolarised Fresnel reflectance
  ``(r_s² + r_p²)/2`` of the interface (Born & Wolf), 1 under TIR. Lights:
  ``f_radial = 1/(a0 + a1·d + a2·d²)`` (1 for directional), spots ``(cos α)^exponent``
  inside the cone (``cos α ≥ cos cutoff``), 0 outside; an area light is its k×k cell
  centres, each a point light of ``color/k²`` (jittered area lights are not supported: the
  tests use ``jitter = false``). Checker patterns: ``colors[0]`` where
  ``⌊x/s + 1e-4⌋ + ⌊y/s + 1e-4⌋ + ⌊z/s + 1e-4⌋`` is even, at the world hit point; a
  ``filter = "box"`` checker's mean over the camera cone's footprint there (:func:`odd_share`).
* **Shadows**: straight rays to each light (sample) whose unshadowed term is non-zero; S is
  the product of ``t·kt + (1 − t)`` over every surface crossed before the light (0 behind an
  opaque one); a walk of more than ``MAX_CROSSINGS`` surfaces counts as blocked
  (docs/recursion.md).
* **Recursion** (docs/shading.md, "Whitted recursion"): reflection ``r = d − 2(d·N)N``;
  refraction ``T = η·d + (η·cos θᵢ − √k)·N``, ``k = cos²θᵢ − (η² − 1)·sin²θᵢ``, with the
  signed cosine ``cos θᵢ = −d·N``; total internal reflection (k < 0) sends the kt share along
  the mirror direction; η = 1/ior entering, ior leaving, decided by the outward geometric
  normal. Children have depth + 1, are traced while depth ≤ max_depth and their path weight
  (the product of the t·kr, t·kt, 1 − t factors, max over RGB) is ≥ min_weight; an untraced
  child adds nothing; a miss returns the background.
* **Smooth and Gouraud meshes**, the rules 1–5 of SCENE_FORMAT.md: vertex normals are the
  normalised sums of the unit normals of the faces sharing the vertex (the hit face's normal
  where they cancel), interpolated by the barycentrics (the face normal where that cancels);
  N = s·N_s with s the side of the face the ray arrives on; shadow rays leave from Hanika's
  lifted point ``P′ = P − Σ_k b_k·min(0, (P − V_k)·n_k)·n_k`` ("Hacking the Shadow
  Terminator", Ray Tracing Gems II, 2021), aimed from there at the light (as Blender Cycles'
  ``shadow_ray_setup`` does; the renderer keeps P's direction, see
  test_gouraud_terminator_matches_reference_tracer); reflected and refracted
  directions on the wrong side of the face are recomputed about the face normal; Gouraud
  blends the per-vertex unshadowed terms (each vertex's own L, V and f, ka kd ks at the hit)
  by the barycentrics and multiplies one shadow factor.

Under TIR the kt share leaves along the mirror direction. With min_weight 0 a TIR ray on the
reflected ray's exact path is traced once, as (kr + kt)·trace(reflected): exact, since the sum
is linear in the children and both have the same depth (docs/recursion.md); with
min_weight > 0 the two stay separate rays, each pruned by its own path weight. The ray counts
follow docs/recursion.md's definitions of the ``--stats`` keys.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from raytrace.material import Checker, Material
from raytrace.scene import Scene

#: A shadow ray crossing more surfaces than this counts as blocked (docs/recursion.md).
MAX_CROSSINGS = 64
#: Hits on primitives other than the one a ray leaves count from T_MIN·(1 + max|origin|) on:
#: far above float64 rounding of the hit point (~1e-16 relative), far below any feature of a
#: test scene.
T_MIN = 1e-9
#: Vertex and interpolated normals shorter than this fall back to the face normal (rule 4).
NORMAL_FLOOR = 1e-12
#: Barycentric slack of a triangle hit: a ray through the edge two triangles share (two walls
#: meeting at a corner) hits one of them, not the float64 rounding gap between them.
EDGE = 1e-12
#: Meshes with fewer triangles are intersected together, behind one bounding sphere.
GROUP = 256
#: The object types traced, by scene-file ``type``: spheres, the flat shapes (planes, and
#: disks: the part of their plane within their radius) and meshes. A scene with any other
#: raises NotImplementedError: the reference never skips what it does not know.
OBJECTS = ("sphere", "plane", "disk", "mesh")
#: The light types, by scene-file ``type`` (any other raises NotImplementedError).
LIGHTS = ("point", "directional", "spot", "area")


@dataclass
class Counts:
    """What the reference traced, by docs/recursion.md's definitions of the stats keys."""

    camera: int = 0
    reflection: int = 0
    refraction: int = 0
    see_through: int = 0
    shadow: int = 0
    tir: int = 0
    pruned_depth: int = 0
    pruned_weight: int = 0


@dataclass
class Hit:
    """A surface point: ``prim`` (the primitive's number), ``point`` (world), ``outward``
    (unit outward geometric normal N_g), ``normal`` (unit shading normal N_s, not turned),
    and for triangles the index ``tri`` and barycentrics ``bary`` (of corners 0, 1, 2)."""

    t: float
    prim: int
    point: np.ndarray
    outward: np.ndarray
    normal: np.ndarray
    material: Material
    tri: int = -1
    bary: tuple[float, float, float] = (0.0, 0.0, 0.0)


@dataclass
class Emitter:
    """One point-like light: a point light, a spot, an area-light cell centre (``position``
    set) or a directional light (``direction`` set, the way the light travels)."""

    color: np.ndarray
    position: np.ndarray | None = None
    direction: np.ndarray | None = None
    attenuation: tuple[float, float, float] = (1.0, 0.0, 0.0)
    spot_axis: np.ndarray | None = None
    cos_cutoff: float = -1.0
    exponent: float = 0.0
    cos_inner: float | None = None  #: a smooth spot's inner cone (KHR_lights_punctual)
    range: float | None = None      #: the KHR_lights_punctual range window


def unit(v: np.ndarray) -> np.ndarray:
    return v / math.sqrt(float(v @ v))


def cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a × b of two 3-vectors (numpy's cross costs ~20× more for one pair)."""
    a0, a1, a2 = a.tolist()
    b0, b1, b2 = b.tolist()
    return np.array([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0])


def coefficient(c: np.ndarray | Checker, world: np.ndarray,
                cone: tuple[np.ndarray, np.ndarray, float] | None = None) -> np.ndarray:
    """A material colour (3,) at a world point; a checker's cell parity decides its colour
    (SCENE_FORMAT.md: colors[0] where ⌊x/s + 1e-4⌋ + ⌊y/s + 1e-4⌋ + ⌊z/s + 1e-4⌋ is even),
    or for a ``filter = "box"`` checker its mean over the camera cone's footprint ``cone``
    (the point relative to the camera, the geometric normal, the spread γ) where that
    crosses a cell boundary (:func:`odd_share`)."""
    if isinstance(c, Checker):
        cells = sum(math.floor(float(x) / c.scale + 1e-4) for x in world)
        if c.filter == "box" and cone is not None:
            f = odd_share(world, *cone, c.scale)
            if 0.0 < f < 1.0:
                return (1.0 - f) * np.asarray(c.colors[0]) + f * np.asarray(c.colors[1])
        return np.asarray(c.colors[cells % 2], dtype=np.float64)
    return np.asarray(c, dtype=np.float64)


def wave_mean(u: float, w: float) -> float:
    """The mean of s(t) = (−1)^⌊t⌋ over [u − w, u + w]: its integral F(t) = 1 − |t mod 2 − 1|
    (a triangle wave) differenced, or s(u) where no integer lies inside."""
    if math.isinf(w):
        return 0.0
    if math.floor(u - w) == math.floor(u + w):
        return 1.0 if math.floor(u) % 2 == 0 else -1.0
    return ((1.0 - abs((u + w) % 2.0 - 1.0)) - (1.0 - abs((u - w) % 2.0 - 1.0))) / (2.0 * w)


def odd_share(world: np.ndarray, view: np.ndarray, normal: np.ndarray, spread: float,
              scale: float) -> float:
    """The share of odd checker cells over a camera cone's footprint (docs/shading.md,
    "Box-filtered checkers"): the cone r = γ·|view|/2 wide on either side cuts the surface in
    an ellipse, r across the plane of incidence (t1) and R = r/c along it (t2, c = |n·d|); k =
    min(⌈1/c⌉, 16) boxes along t2, each the box around an ellipse of semi-axes r and R/k at
    its piece's centre, their shares averaged; each box's share (1 − Π mean of the axis'
    square wave)/2."""
    d, n = unit(view), unit(normal)
    dn = float(d @ n)
    c = abs(dn)
    if c == 0.0:
        return 0.5
    r = 0.5 * spread * float(np.linalg.norm(view))
    along = d - dn * n
    if float(np.linalg.norm(along)) == 0.0:  # head on: a disc
        k, t2, t1, big = 1, np.zeros(3), np.zeros(3), 0.0
        half = r * np.sqrt(np.maximum(1.0 - n * n, 0.0))
    else:
        k, t2, big = 16 if c * 16 <= 1.0 else math.ceil(1.0 / c), unit(along), r / c
        t1 = cross(n, t2)
        half = np.sqrt((r * t1) ** 2 + (big / k * t2) ** 2)
    shares = []
    for j in range(k):
        centre = world + big * ((2 * j + 1) / k - 1.0) * t2
        means = [wave_mean(float(x) / scale + 1e-4, float(h) / scale)
                 for x, h in zip(centre, half, strict=True)]
        shares.append(0.5 * (1.0 - means[0] * means[1] * means[2]))
    return sum(shares) / k


def nonzero(c: np.ndarray | Checker) -> bool:
    """Whether a colour or pattern is non-zero anywhere."""
    parts = c.colors if isinstance(c, Checker) else (c,)
    return any(np.any(np.asarray(p) > 0) for p in parts)


def mirror(d: np.ndarray, n: np.ndarray) -> np.ndarray:
    """Law of reflection: d − 2(d·n)n."""
    return d - 2.0 * float(d @ n) * n


def snell(d: np.ndarray, n: np.ndarray, eta: float) -> tuple[np.ndarray, bool]:
    """Refracted direction for η = η₁/η₂ and whether it is a total internal reflection.

    docs/shading.md, "Refraction": cos θᵢ = −d·n, signed, clipped to [−1, 1];
    k = cos²θᵢ − (η² − 1)·sin²θᵢ; T = η·d + (η·cos θᵢ − √k)·n for k ≥ 0; k < 0 is TIR, and
    the direction is then the mirror direction.
    """
    cos_i = min(max(-float(d @ n), -1.0), 1.0)
    sin2 = max(0.0, 1.0 - cos_i * cos_i)
    k = cos_i * cos_i - (eta * eta - 1.0) * sin2
    if k < 0.0:
        return mirror(d, n), True
    return eta * d + (eta * cos_i - math.sqrt(k)) * n, False


def phong(n: np.ndarray, l: np.ndarray, v: np.ndarray) -> float:
    """Phong 1975: cos = V·R with R = 2(N·L)N − L."""
    return float(v @ (2.0 * float(n @ l) * n - l))


def blinn(n: np.ndarray, l: np.ndarray, v: np.ndarray) -> float:
    """Blinn 1977: cos = N·H with H = (L + V)/|L + V|; 0 where L = −V (H undefined)."""
    h = l + v
    length = math.sqrt(float(h @ h))
    return float(n @ h) / length if length > 0.0 else 0.0


#: The highlight models by their ``highlight`` key: the cosine raised to the shininess
#: ("blinn_cosine" then times N·L, :func:`highlight`).
HIGHLIGHTS = {"phong": phong, "blinn": blinn, "blinn_cosine": blinn}


def reflectance(cos_i: float, eta: float) -> float:
    """The unpolarised Fresnel reflectance F = (r_s² + r_p²)/2 of light arriving at cos θᵢ
    (clipped to [0, 1]) on an interface of relative index η = η₁/η₂ (Born & Wolf §1.5.2):
    sin θₜ = η·sin θᵢ (Snell), r_s = (η cos θᵢ − cos θₜ)/(η cos θᵢ + cos θₜ),
    r_p = (cos θᵢ − η cos θₜ)/(cos θᵢ + η cos θₜ); 1 where sin θₜ ≥ 1 (TIR)."""
    c = min(max(cos_i, 0.0), 1.0)
    sin_t = eta * math.sqrt(max(0.0, 1.0 - c * c))
    if sin_t >= 1.0:
        return 1.0
    cos_t = math.sqrt(1.0 - sin_t * sin_t)
    rs = (eta * c - cos_t) / (eta * c + cos_t)
    rp = (c - eta * cos_t) / (c + eta * cos_t)
    return 0.5 * (rs * rs + rp * rp)


def schlick(kr: np.ndarray, kt: np.ndarray, cos_i: float, eta: float):
    """Schlick 1994 with F0 = kr: kr + (1 − kr)(1 − cos θ)⁵; kt unchanged."""
    g = (1.0 - min(max(cos_i, 0.0), 1.0)) ** 5
    return kr + (1.0 - kr) * g, kt


def dielectric(kr: np.ndarray, kt: np.ndarray, cos_i: float, eta: float):
    """The dielectric split: kr·F and kt·(1 − F), F = :func:`reflectance`."""
    f = reflectance(cos_i, eta)
    return kr * f, kt * (1.0 - f)


#: How kr and kt vary with the angle of incidence, by the ``fresnel`` key ("none": not at all).
FRESNELS = {"none": lambda kr, kt, cos_i, eta: (kr, kt), "schlick": schlick,
            "dielectric": dielectric}


def check_material(m: Material, where: str) -> None:
    """NotImplementedError for what the reference does not model: a highlight model or
    Fresnel mode it does not know, image textures (a colour that is neither a constant nor
    a checker) and texture alpha."""
    if m.highlight not in HIGHLIGHTS or m.fresnel not in FRESNELS:
        raise NotImplementedError(f"{where}: the reference tracer has no highlight "
                                  f"{m.highlight!r} or fresnel {m.fresnel!r}")
    colors = (m.ka, m.kd, m.ks, m.kr, m.kt, m.ke)
    if m.alpha is not None or any(c is not None and not isinstance(c, (np.ndarray, Checker))
                                  for c in colors):
        raise NotImplementedError(f"{where}: the reference tracer has no image textures")


def highlight(model: str, n: np.ndarray, l: np.ndarray, v: np.ndarray, power: float) -> float:
    """spec = cos^n of the model's cosine, 0 where the cosine is ≤ 0; "blinn_cosine" times
    max(N·L, 0), the reflectance equation's cosine."""
    if model not in HIGHLIGHTS:
        raise ValueError(f"unknown highlight {model!r} (valid: {', '.join(HIGHLIGHTS)})")
    cos = HIGHLIGHTS[model](n, l, v)
    spec = cos**power if cos > 0.0 else 0.0
    return spec * max(float(n @ l), 0.0) if model == "blinn_cosine" else spec


def local_term(n: np.ndarray, l: np.ndarray, v: np.ndarray, kd: np.ndarray, ks: np.ndarray,
               mat: Material) -> np.ndarray:
    """kd·max(N·L, 0) + ks·spec, both zero where N·L ≤ 0 (seed 000; docs/shading.md)."""
    ndl = float(n @ l)
    if ndl <= 0.0:
        return np.zeros(3)
    return kd * ndl + ks * highlight(mat.highlight, n, l, v, mat.shininess)


def incidence(em: Emitter, p: np.ndarray) -> tuple[np.ndarray, float, float]:
    """(L, distance, f_radial·f_angular) of one emitter at world point p (docs/shading.md,
    "Lights"): f = 1/(a0 + a1·d + a2·d²); a spot multiplies (cos α)^exponent where
    cos α = −L·axis ≥ cos θ, 0 outside; a directional light has L = −direction, d = ∞, f = 1.
    A point at the light's position gets nothing (f = 0)."""
    if em.position is None:
        return -em.direction, math.inf, 1.0
    to = em.position - p
    dist = math.sqrt(float(to @ to))
    if dist == 0.0:
        return np.zeros(3), 0.0, 0.0
    l = to / dist
    a0, a1, a2 = em.attenuation
    f = 1.0 / (a0 + a1 * dist + a2 * dist * dist)
    if em.spot_axis is not None and em.cos_inner is not None:
        # KHR_lights_punctual's recommended falloff, linear in cos α then squared
        cos_a = -float(l @ em.spot_axis)
        t = (cos_a - em.cos_cutoff) / max(0.001, em.cos_inner - em.cos_cutoff)
        f = f * min(max(t, 0.0), 1.0) ** 2
    elif em.spot_axis is not None:
        cos_a = -float(l @ em.spot_axis)
        f = f * cos_a**em.exponent if cos_a >= em.cos_cutoff else 0.0
    if em.range is not None:
        f = f * max(min(1.0 - (dist / em.range) ** 4, 1.0), 0.0)
    return l, dist, f


class ReferenceTracer:
    """Render ``scene`` pixel by pixel with the recursive definition (pixel centres)."""

    def __init__(self, scene: Scene, max_depth: int | None = None,
                 min_weight: float | None = None):
        r = scene.render
        self.max_depth = r.max_depth if max_depth is None else max_depth
        self.min_weight = r.min_weight if min_weight is None else min_weight
        self.background = np.asarray(r.background, dtype=np.float64)
        self.ambient = np.asarray(scene.ambient, dtype=np.float64)
        self.camera = scene.camera
        self.spread = 0.0  # the camera cone's spread, set by each pixel() for its image height
        self.counts = Counts()
        self._shapes(scene.objects)
        self.emitters = [e for light in scene.lights for e in self._emitters(light)]

    # -- the scene as float64 tables ------------------------------------------------------------
    def _shapes(self, objects: list) -> None:
        """Spheres, flat shapes (planes, then disks) and triangles, numbered in that order
        (``prim``)."""
        for i, o in enumerate(objects):
            if getattr(o, "type", None) not in OBJECTS:
                raise NotImplementedError(f"objects[{i}]: the reference tracer has no "
                                          f"{type(o).__name__} (it traces {', '.join(OBJECTS)})")
            for j, m in enumerate(getattr(o, "materials", [o.material])):
                check_material(m, f"objects[{i}] material {j}")
            if o.type == "mesh" and len(o.materials) > 1:
                raise NotImplementedError(f"objects[{i}]: the reference tracer has no "
                                          "per-face materials")
        spheres = [o for o in objects if o.type == "sphere"]
        flats = [o for o in objects if o.type == "plane"] + [o for o in objects
                                                             if o.type == "disk"]
        meshes = [o for o in objects if o.type == "mesh"]
        self.centers = np.array([s.center for s in spheres], np.float64).reshape(-1, 3)
        self.radii = np.array([s.radius for s in spheres], np.float64)
        self.flat_points = np.array([o.point if o.type == "plane" else o.center for o in flats],
                                    np.float64).reshape(-1, 3)
        self.flat_normals = np.array([unit(np.asarray(o.normal, np.float64)) for o in flats],
                                     np.float64).reshape(-1, 3)
        self.flat_radii = [math.inf if o.type == "plane" else float(o.radius) for o in flats]
        self.shape_materials = [o.material for o in spheres + flats]
        self.n_spheres, self.n_analytic = len(spheres), len(spheres) + len(flats)
        corners, vnormals, fnormals = [], [], []
        self.tri_materials, self.tri_shading = [], []
        for mesh in meshes:
            v = np.asarray(mesh.vertices, np.float64)
            f = np.asarray(mesh.faces, np.int64)
            tri = v[f]                                                   # (F, 3, 3)
            fn = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
            fn /= np.linalg.norm(fn, axis=1, keepdims=True)              # outward: CCW winding
            vsum = np.zeros_like(v)
            for k in range(3):
                np.add.at(vsum, f[:, k], fn)
            length = np.linalg.norm(vsum, axis=1)
            vn = vsum / np.where(length < NORMAL_FLOOR, 1.0, length)[:, None]
            corner_n = vn[f]                                             # (F, 3, 3)
            cancel = (length < NORMAL_FLOOR)[f]                          # rule 4: face normal
            corner_n[cancel] = np.repeat(fn[:, None], 3, axis=1)[cancel]
            shading = [mesh.shading] * len(f)
            if mesh.shading == "file":  # the file's normals per corner, the face's where none
                given = np.any(mesh.normals != 0, axis=2)
                corner_n = np.where(given[..., None], mesh.normals, fn[:, None])
                shading = ["file" if g else "flat" for g in given.any(axis=1)]
            below = np.einsum("fkj,fj->fk", corner_n, fn) < 0    # below its face: turned over
            corner_n = np.where(below[..., None], -corner_n, corner_n)
            corners.append(tri)
            vnormals.append(corner_n)
            fnormals.append(fn)
            self.tri_materials += [mesh.material] * len(f)
            self.tri_shading += shading
        self.corners = np.concatenate(corners) if corners else np.zeros((0, 3, 3))
        self.vertex_normals = np.concatenate(vnormals) if vnormals else np.zeros((0, 3, 3))
        self.face_normals = np.concatenate(fnormals) if fnormals else np.zeros((0, 3))
        self.e1 = self.corners[:, 1] - self.corners[:, 0]
        self.e2 = self.corners[:, 2] - self.corners[:, 0]
        a = self.corners[:, 0]
        self.tri_n = np.cross(self.e1, self.e2)                          # Möller–Trumbore terms
        self.e2_a, self.a_e1 = np.cross(self.e2, a), np.cross(a, self.e1)
        self.n_a = np.einsum("ij,ij->i", self.tri_n, a)
        # Groups of triangles tested together, each behind a bounding sphere: a mesh of
        # GROUP triangles or more alone, the smaller ones together (fewer numpy calls a ray).
        ranges, first = [], 0
        for fn in fnormals:
            if ranges and ranges[-1][1] - ranges[-1][0] + len(fn) <= GROUP:
                ranges[-1][1] += len(fn)
            else:
                ranges.append([first, first + len(fn)])
            first += len(fn)
        self.groups = []
        for first, last in ranges:
            pts = self.corners[first:last].reshape(-1, 3)
            centre = 0.5 * (pts.min(axis=0) + pts.max(axis=0))
            radius = float(np.linalg.norm(pts - centre, axis=1).max())
            self.groups.append((first, last, centre, radius))

    @staticmethod
    def _emitters(light) -> list[Emitter]:
        """A light as point-like emitters; an area light as its k×k cell centres, each with
        color/k² (SCENE_FORMAT.md)."""
        kind = getattr(light, "type", None)
        if kind not in LIGHTS:
            raise NotImplementedError(f"the reference tracer has no {type(light).__name__} "
                                      f"(it has {', '.join(LIGHTS)} lights)")
        color = np.asarray(light.color, np.float64)
        if kind == "directional":
            return [Emitter(color, direction=unit(np.asarray(light.direction, np.float64)))]
        att = tuple(float(a) for a in light.attenuation)
        window = light.range
        if kind == "spot":
            cos_cutoff = 0.0 if light.cutoff == 90.0 else math.cos(math.radians(light.cutoff))
            inner = (None if light.inner_cutoff is None else
                     0.0 if light.inner_cutoff == 90.0 else
                     math.cos(math.radians(light.inner_cutoff)))
            return [Emitter(color, np.asarray(light.position, np.float64), attenuation=att,
                            spot_axis=unit(np.asarray(light.direction, np.float64)),
                            cos_cutoff=cos_cutoff, exponent=float(light.exponent),
                            cos_inner=inner, range=window)]
        if kind == "area":
            if light.jitter:
                raise NotImplementedError("the reference tracer has no jittered area lights "
                                          "(use jitter = false)")
            k = math.isqrt(light.samples)
            c, eu, ev = (np.asarray(x, np.float64) for x in (light.position, light.edge_u,
                                                                light.edge_v))
            return [Emitter(color / (k * k), c + ((i + 0.5) / k - 0.5) * eu
                            + ((j + 0.5) / k - 0.5) * ev, attenuation=att, range=window)
                    for i in range(k) for j in range(k)]
        return [Emitter(color, np.asarray(light.position, np.float64), attenuation=att,  # point
                        range=window)]

    # -- camera ------------------------------------------------------------------------------
    def camera_ray(self, row: int, col: int, width: int, height: int, sx: float = 0.5,
                   sy: float = 0.5) -> np.ndarray:
        """Unit direction through the point (sx, sy) ∈ [0, 1)² of pixel (row, col), its centre
        by default; pixel (0, 0) is top-left."""
        cam = self.camera
        forward = unit(np.asarray(cam.look_at, np.float64) - cam.position)
        right = unit(cross(forward, np.asarray(cam.up, np.float64)))
        up = cross(right, forward)
        tan_half = math.tan(math.radians(cam.fov) / 2.0)
        x = (2.0 * (col + sx) / width - 1.0) * tan_half * width / height
        y = (1.0 - 2.0 * (row + sy) / height) * tan_half
        return unit(forward + x * right + y * up)

    def render(self, width: int, height: int) -> np.ndarray:
        """(height, width, 3) float64 linear RGB, one ray through each pixel's centre."""
        out = np.zeros((height, width, 3))
        for row in range(height):
            for col in range(width):
                out[row, col] = self.pixel(row, col, width, height)
        return out

    def pixel(self, row: int, col: int, width: int, height: int, sx: float = 0.5,
              sy: float = 0.5) -> np.ndarray:
        """The colour (3,) seen through the point (sx, sy) of pixel (row, col)."""
        self.counts.camera += 1
        # a camera sample's cone spread (one sample a pixel): Ray Tracing Gems ch. 20, eq. 30
        self.spread = math.atan(2.0 * math.tan(math.radians(self.camera.fov) / 2.0) / height)
        d = self.camera_ray(row, col, width, height, sx, sy)
        return self.trace(np.asarray(self.camera.position, np.float64), d, -1, 0, np.ones(3))

    # -- intersection ----------------------------------------------------------------------------
    def closest(self, o: np.ndarray, d: np.ndarray, leaving: int = -1,
                tmax: float = math.inf, lifted: bool = False) -> Hit | None:
        """The closest surface along the ray o + t·d (d unit) with t < tmax, or None.

        ``leaving``: the primitive the ray starts on (−1: none). ``lifted``: the ray starts
        off that primitive (a shadow ray from Hanika's point), so it may meet it again.
        """
        tmin = 0.0 if leaving < 0 else T_MIN * (1.0 + float(np.abs(o).max()))
        best_t, best = tmax, -1
        if self.n_spheres:
            t, s = self._spheres(o, d, leaving, tmin)
            if t < best_t:
                best_t, best = t, s
        if self.n_analytic > self.n_spheres:
            t, p = self._flats(o, d, leaving, tmin)
            if t < best_t:
                best_t, best = t, p
        bary = (0.0, 0.0, 0.0)
        for first, last, centre, radius in self.groups:
            oc = o - centre
            b = float(oc @ d)
            if float(oc @ oc) - b * b > radius * radius or -b - radius >= best_t or b > radius:
                continue  # the ray misses the mesh's bounding sphere (or meets it too late)
            t, tri, uv = self._triangles(o, d, first, last, leaving, tmin, best_t, lifted)
            if t < best_t:
                best_t, best, bary = t, self.n_analytic + tri, uv
        if best < 0:
            return None
        p = o + best_t * d
        if best < self.n_spheres:
            n = unit(p - self.centers[best])
            return Hit(best_t, best, p, n, n, self.shape_materials[best])
        if best < self.n_analytic:
            n = self.flat_normals[best - self.n_spheres]
            return Hit(best_t, best, p, n, n, self.shape_materials[best])
        tri = best - self.n_analytic
        ng = self.face_normals[tri]
        ns = ng
        if self.tri_shading[tri] != "flat":  # interpolated vertex normals (rule 4)
            s = bary[0] * self.vertex_normals[tri, 0] + bary[1] * self.vertex_normals[tri, 1] \
                + bary[2] * self.vertex_normals[tri, 2]
            length = math.sqrt(float(s @ s))
            ns = s / length if length >= NORMAL_FLOOR else ng
        return Hit(best_t, best, p, ng, ns, self.tri_materials[tri], tri, bary)

    def _spheres(self, o, d, leaving, tmin) -> tuple[float, int]:
        """Closest sphere hit: the roots of t² + 2bt + c = 0, b = d·(o − c), c = |o − c|² − r²,
        with disc = b² − c written as r² − |f|², f = (o − c) − b·d, and the roots as
        q = −b − sign(b)·√disc and c/q (Haines et al. 2019: neither cancels)."""
        oc = o - self.centers
        b = oc @ d
        f = oc - b[:, None] * d
        disc = self.radii**2 - np.einsum("ij,ij->i", f, f)
        best_t, best = math.inf, -1
        candidates = np.flatnonzero(disc >= 0.0).tolist()
        if 0 <= leaving < self.n_spheres and leaving not in candidates:
            candidates.append(leaving)
        for i in candidates:
            bi = float(b[i])
            q = -bi - math.copysign(math.sqrt(max(float(disc[i]), 0.0)), bi)
            if i == leaving:
                # Leaving its own sphere: outward it never meets it again, inward only at the
                # far side, the larger root q = −b + √disc (b < 0).
                t = q if bi < 0.0 else math.inf
            else:
                c = float(oc[i] @ oc[i]) - float(self.radii[i]) ** 2
                near, far = (q, c / q) if q != 0.0 else (0.0, 0.0)
                near, far = min(near, far), max(near, far)
                t = near if near > tmin else (far if far > tmin else math.inf)
            if t < best_t:
                best_t, best = t, i
        return best_t, best

    def _flats(self, o, d, leaving, tmin) -> tuple[float, int]:
        """Closest hit on a plane or disk: its plane's t = (p − o)·n / (d·n), on a disk only
        where |o + t·d − c| ≤ r; never the one the ray leaves."""
        best_t, best = math.inf, -1
        dist = np.einsum("ij,ij->i", self.flat_points - o, self.flat_normals).tolist()
        cos = (self.flat_normals @ d).tolist()
        for i in range(len(cos)):
            if cos[i] == 0.0 or self.n_spheres + i == leaving:
                continue
            t = dist[i] / cos[i]
            if not tmin < t < best_t:
                continue
            r = self.flat_radii[i]
            if r < math.inf:
                q = o + t * d - self.flat_points[i]
                if float(q @ q) > r * r:
                    continue
            best_t, best = t, self.n_spheres + i
        return best_t, best

    def _triangles(self, o, d, first, last, leaving, tmin, tmax, lifted):
        """Closest hit among triangles first..last−1 (Möller & Trumbore 1997): solves
        o + t·d = a + u·e1 + v·e2 (e1 = b − a, e2 = c − a); a hit has u, v ≥ 0, u + v ≤ 1
        (within ``EDGE``), tmin < t < tmax. Its determinants are written as triple products
        of precomputed per-triangle vectors (N = e1 × e2): det = −N·d,
        u·det = e2·(o × d) − d·(e2 × a),
        v·det = −e1·(o × d) − d·(a × e1), t·det = N·o − N·a.
        Returns (t, triangle, barycentrics of the corners (1 − u − v, u, v))."""
        sl = slice(first, last)
        od = cross(o, d)
        det = -(self.tri_n[sl] @ d)
        inv = 1.0 / np.where(det == 0.0, np.nan, det)
        u = (self.e2[sl] @ od - self.e2_a[sl] @ d) * inv
        v = (-(self.e1[sl] @ od) - self.a_e1[sl] @ d) * inv
        t = (self.tri_n[sl] @ o - self.n_a[sl]) * inv
        ok = (u >= -EDGE) & (v >= -EDGE) & (u + v <= 1.0 + EDGE) & (t > tmin) & (t < tmax)
        own = leaving - self.n_analytic - first
        if 0 <= own < last - first and not lifted:  # a ray leaving a triangle never meets it
            ok[own] = False
        if not ok.any():
            return math.inf, -1, (0.0, 0.0, 0.0)
        t = np.where(ok, t, np.inf)
        i = int(np.argmin(t))
        return float(t[i]), first + i, (1.0 - u[i] - v[i], float(u[i]), float(v[i]))

    # -- the recursion ---------------------------------------------------------------------------
    def trace(self, o: np.ndarray, d: np.ndarray, leaving: int, depth: int,
              weight: np.ndarray) -> np.ndarray:
        """Seed 003's trace(): the colour seen along one ray of path weight ``weight``."""
        hit = self.closest(o, d, leaving)
        if hit is None:
            return self.background.copy()
        return self.shade(hit, o, d, depth, weight)

    def child(self, hit: Hit, d: np.ndarray, depth: int, weight: np.ndarray,
              kind: str) -> np.ndarray:
        """trace() of a secondary ray from the hit, or 0 when the depth or weight limit stops
        it (SCENE_FORMAT.md: traced while depth ≤ max_depth and weight ≥ min_weight)."""
        big = float(weight.max())
        if not big > 0.0:
            return np.zeros(3)
        if depth > self.max_depth:
            self.counts.pruned_depth += 1
            return np.zeros(3)
        if big < self.min_weight:
            self.counts.pruned_weight += 1
            return np.zeros(3)
        setattr(self.counts, kind, getattr(self.counts, kind) + 1)
        return self.trace(hit.point, d, hit.prim, depth, weight)

    def shade(self, hit: Hit, o: np.ndarray, d: np.ndarray, depth: int,
              weight: np.ndarray) -> np.ndarray:
        """Seed 003's shade() with the opacity blend: t·I_surface + (1 − t)·I_behind."""
        mat, p = hit.material, hit.point
        v = -d
        s = 1.0 if float(hit.outward @ v) >= 0.0 else -1.0   # rule 1: the side arrived on
        n, n_face = s * hit.normal, s * hit.outward
        t = mat.opacity

        cone = (p - np.asarray(self.camera.position, np.float64), hit.outward, self.spread)
        color = self.ambient * coefficient(mat.kd if mat.ka is None else mat.ka, p, cone) \
            + coefficient(mat.ke, p, cone)
        kd, ks = coefficient(mat.kd, p, cone), coefficient(mat.ks, p, cone)
        gouraud = hit.tri >= 0 and self.tri_shading[hit.tri] == "gouraud"
        shadow_from = self.lifted(hit, s) if hit.tri >= 0 and \
            self.tri_shading[hit.tri] != "flat" else None
        for em in self.emitters:
            if gouraud:
                term = self.gouraud(hit, s, o, em, kd, ks)
            else:
                l, _, f = incidence(em, p)
                term = f * local_term(n, l, v, kd, ks, mat)
            if np.any(term > 0.0):
                color = color + term * self.shadow(hit, em, shadow_from) * em.color

        kr, kt = coefficient(mat.kr, p, cone), coefficient(mat.kt, p, cone)
        entering = float(d @ hit.outward) < 0.0
        kr, kt = FRESNELS[mat.fresnel](kr, kt, -float(d @ n), 1.0 / mat.ior if entering
                                       else mat.ior)
        r = refracted = None
        if t > 0 and nonzero(mat.kr):
            r = mirror(d, n)
            if float(r @ n_face) <= 0.0:  # rule 3: the shading normal sent it inside
                r = mirror(d, n_face)
        if t > 0 and nonzero(mat.kt):
            eta = 1.0 / mat.ior if entering else mat.ior
            refracted, tir = snell(d, n, eta)
            side = float(refracted @ n_face)
            if (side <= 0.0) if tir else (side >= 0.0):  # rule 3: wrong side of the face
                refracted, tir = snell(d, n_face, eta)
            if tir:
                if depth + 1 <= self.max_depth:
                    self.counts.tir += 1
                if (self.min_weight <= 0 and r is not None and np.array_equal(refracted, r)
                        and (weight * t * kr).max() > 0):
                    # One path, one ray of weight w·t·(kr + kt) (docs/recursion.md).
                    kr, refracted = kr + kt, None
        if r is not None:
            color = color + kr * self.child(hit, r, depth + 1, weight * t * kr, "reflection")
        if refracted is not None:
            color = color + kt * self.child(hit, refracted, depth + 1, weight * t * kt,
                                            "refraction")
        out = t * color
        if t < 1:
            out = out + (1.0 - t) * self.child(hit, d, depth + 1, weight * (1.0 - t),
                                               "see_through")
        return out

    # -- smooth and Gouraud meshes ---------------------------------------------------------------
    def lifted(self, hit: Hit, s: float) -> np.ndarray:
        """Rule 2, Hanika's point P′ = P − Σ_k b_k·min(0, (P − V_k)·n_k)·n_k, n_k = s·N_k."""
        p, out = hit.point, hit.point.copy()
        for k in range(3):
            nk = s * self.vertex_normals[hit.tri, k]
            out = out - hit.bary[k] * min(0.0, float((p - self.corners[hit.tri, k]) @ nk)) * nk
        return out

    def gouraud(self, hit: Hit, s: float, eye: np.ndarray, em: Emitter, kd: np.ndarray,
                ks: np.ndarray) -> np.ndarray:
        """Rule 5: Σ_k b_k·f_k·[kd·max(N_k·L_k, 0) + ks·spec_k], each vertex V_k with its own
        L, V (towards the ray's origin) and f, its normal turned by s; kd, ks at the hit."""
        term = np.zeros(3)
        for k in range(3):
            corner = self.corners[hit.tri, k]
            l, _, f = incidence(em, corner)
            term += hit.bary[k] * f * local_term(s * self.vertex_normals[hit.tri, k], l,
                                                 unit(eye - corner), kd, ks, hit.material)
        return term

    # -- shadows ---------------------------------------------------------------------------------
    def shadow(self, hit: Hit, em: Emitter, start: np.ndarray | None) -> np.ndarray:
        """S_l: the product of ``t·kt + (1 − t)`` over every surface between the hit (or
        ``start``, its lifted point) and the emitter; 0 after MAX_CROSSINGS surfaces."""
        origin = hit.point if start is None else start
        l, remaining, _ = incidence(em, origin)
        factor, leaving, lifted = np.ones(3), hit.prim, start is not None
        for _ in range(MAX_CROSSINGS):
            self.counts.shadow += 1
            blocker = self.closest(origin, l, leaving, remaining, lifted)
            if blocker is None:
                return factor
            m = blocker.material
            cone = (blocker.point - np.asarray(self.camera.position, np.float64),
                    blocker.outward, self.spread)
            factor = factor * (m.opacity * coefficient(m.kt, blocker.point, cone)
                               + (1.0 - m.opacity))
            if not np.any(factor > 0.0):
                return factor
            origin, leaving, lifted = blocker.point, blocker.prim, False
            remaining -= blocker.t
        return np.zeros(3)
