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


def __getattr__(name: str) -> str:
    """``raytrace.__version__``: the installed distribution's version (pyproject.toml), not a
    second copy of it, read when first asked for (``importlib.metadata`` costs 20–40 ms of
    every start-up otherwise; PEP 562 module ``__getattr__``)."""
    if name != "__version__":
        raise AttributeError(f"module 'raytrace' has no attribute {name!r}")
    from importlib import metadata

    try:
        version = metadata.version("raytrace")
    except metadata.PackageNotFoundError:  # run from a source tree that was never installed
        version = "0+unknown"
    globals()["__version__"] = version
    return version

__all__ = [
    "AreaLight", "Camera", "Checker", "DirectionalLight", "Image", "Material", "explain",
    "MaterialLibrary", "Mesh", "Plane", "PointLight", "RenderSettings", "RenderWarning", "Scene",
    "SceneError", "Sphere", "SpotLight", "load_scene", "materials", "read_exr", "render",
    "render_frames",
    "scene_from_dict",
]
