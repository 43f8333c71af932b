"""The codes every stage shares with the kernels: kinds of ray, emitter, highlight, Fresnel
weighting, mesh shading and filter, the colour slots and a child ray's status. (The analytic
shape kinds live beside their kernels, in :mod:`raytrace.kernels.accel`.)

Plain Python (and numpy integers), no numba: the scene, the material table and the command line
read them without loading the compiler. Each list of names is the one place its codes come
from, so a name and its code cannot drift apart.
"""

from __future__ import annotations

import numpy as np

# -- rays -------------------------------------------------------------------------------------
#: Kinds of ray, for ``RayBatch.kind`` and the statistics, in code order.
KIND_NAMES = ("camera", "reflection", "refraction", "see_through")
CAMERA, REFLECTION, REFRACTION, SEE_THROUGH = range(len(KIND_NAMES))
#: ``RayBatch.origin_shape`` of a ray that starts on no analytic shape (camera rays, meshes).
NO_SHAPE = -1
#: A child ray's status (``Children.status``): none, pruned by its weight, traced.
NONE, PRUNED, KEEP = 0, 1, 2

# -- lights -----------------------------------------------------------------------------------
#: Emission laws (``Emitter.kind``), each one branch of ``kernels.shading.incidence1``.
#: "spot" is seed 000's (cos α)^a inside a hard cone; "smooth_spot" KHR_lights_punctual's falloff
#: between an inner and an outer cone.
EMITTER_KINDS = {"point": 0, "spot": 1, "directional": 2, "smooth_spot": 3}
POINT, SPOT, DIRECTIONAL, SMOOTH_SPOT = EMITTER_KINDS.values()

# -- materials --------------------------------------------------------------------------------
#: Highlight models by name: Phong's (V·R)^n (Phong 1975), Blinn's (N·H)^n (Blinn 1977), and
#: Blinn's times N·L, the cosine of the reflectance equation that a microfacet lobe (a glTF
#: roughness) sits in (Akenine-Möller et al., Real-Time Rendering, 4th ed., §9.3).
HIGHLIGHT_CODES = {"phong": 0, "blinn": 1, "blinn_cosine": 2}
PHONG, BLINN, BLINN_COSINE = HIGHLIGHT_CODES.values()
#: How kr and kt vary with the angle of incidence (``kernels.core.fresnel_weights1``).
FRESNEL_CODES = {"none": 0, "schlick": 1, "dielectric": 2}
NO_FRESNEL, SCHLICK, DIELECTRIC = FRESNEL_CODES.values()
#: The colour slots of a material; ``ke`` is emission.
COLOR_KEYS = ("ka", "kd", "ks", "kr", "kt", "ke")
#: First column of each colour in a material's row of colours (``Materials.colors``): three
#: per slot, in :data:`COLOR_KEYS`' order. numpy integers, not Python ones: numba types a
#: Python int constant passed to another kernel as its literal value and compiles that kernel
#: once per value.
KA, KD, KS, KR, KT, KE = (np.int64(3 * i) for i in range(len(COLOR_KEYS)))
#: What a material's relief texture holds (``Reliefs.kind``): a tangent-space normal map
#: (glTF ``normalTexture``, MTL ``norm``) or a height map (MTL ``bump``: Blinn 1978).
RELIEF_CODES = {"normal_map": 1, "bump": 2}
NORMAL_MAP, HEIGHT_MAP = RELIEF_CODES.values()

# -- meshes -----------------------------------------------------------------------------------
#: Mesh shading by ``shading =`` name (``Triangles.shading``).
SHADING_CODES = {"flat": 0, "smooth": 1, "gouraud": 2, "fast_phong": 3}
FLAT, SMOOTH, GOURAUD, FAST_PHONG = SHADING_CODES.values()

# -- film -------------------------------------------------------------------------------------
#: Pixel reconstruction filters by ``[render] filter`` name (``kernels.filters.profile1``).
FILTER_CODES = {"box": 0, "tent": 1, "gaussian": 2, "mitchell": 3}
BOX, TENT, GAUSSIAN, MITCHELL = FILTER_CODES.values()
