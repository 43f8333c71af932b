"""raytrace: a recursive Whitted ray tracer on Intel Embree.

The pipeline, one module per stage::

    scene_file / scene  →  camera  →  accel (embreex + analytic)  →  integrator
        →  lights + shading + optics  →  film (EXR, PNG)  →  cli

>>> import raytrace
>>> scene = raytrace.Scene(
...     camera=raytrace.Camera(position=[0, 0, 5], look_at=[0, 0, 0]),
...     objects=[raytrace.Sphere([0, 0, 0], 1.0, material="brass")],
...     lights=[raytrace.PointLight([5, 5, 5])], ambient=0.1)
>>> image = raytrace.render(scene, width=32, height=24)
>>> image.rgb.shape
(24, 32, 3)
"""

from importlib import metadata as _metadata

from .errors import RenderWarning, SceneError
from .explain import explain
from .film import Image, read_exr
from .frames import render_frames
from .material import Checker, Material, MaterialLibrary
from .material import library as materials
from .render import render
from .scene import (
    AreaLight,
    Camera,
    DirectionalLight,
    Mesh,
    Plane,
    PointLight,
    RenderSettings,
    Scene,
    Sphere,
    SpotLight,
)
from .scene_file import load_scene, scene_from_dict

try:  # the installed distribution's version (pyproject.toml), not a second copy of it
    __version__ = _metadata.version("raytrace")
except _metadata.PackageNotFoundError:  # run from a source tree that was never installed
    __version__ = "0+unknown"

__all__ = [
    "AreaLight", "Camera", "Checker", "DirectionalLight", "Image", "Material", "explain",
    "MaterialLibrary", "Mesh", "Plane", "PointLight", "RenderSettings", "RenderWarning", "Scene",
    "SceneError", "Sphere", "SpotLight", "load_scene", "materials", "read_exr", "render",
    "render_frames",
    "scene_from_dict",
]
