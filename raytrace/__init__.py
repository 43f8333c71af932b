"""raytrace: a recursive Whitted ray tracer on Intel Embree.

The pipeline, a folder or module per stage (docs/architecture.md)::

    readers/ (scene and model files) → scene → tables → camera → accel (Embree + analytic)
        → integrator → lights + shading → film/ (EXR, PNG previews) → cli

with every compiled kernel in ``kernels/``.

>>> import raytrace
>>> scene = raytrace.Scene(
...     camera=raytrace.Camera(position=[0, 0, 5], look_at=[0, 0, 0]),
...     objects=[raytrace.Sphere([0, 0, 0], 1.0, material="brass")],
...     lights=[raytrace.PointLight([5, 5, 5])], ambient=0.1)
>>> image = raytrace.render(scene, width=32, height=24)
>>> image.rgb.shape
(24, 32, 3)

The names of the API are loaded from their modules when first used (PEP 562 module
``__getattr__``), so ``import raytrace`` is quick and loads neither numba nor Embree: a script
that only loads and checks scenes never pays for the compiler.
"""

from importlib import import_module

#: Public name → (module, its name there). The light and object records are not listed: each
#: is found by its class name in its registry (:func:`records`), so a new one is exported by
#: the line that registers it.
EXPORTS = {
    "RenderWarning": ("errors", "RenderWarning"), "SceneError": ("errors", "SceneError"),
    "MemoryLimitError": ("errors", "MemoryLimitError"), "ClusterError": ("errors", "ClusterError"),
    "EngineError": ("errors", "EngineError"),
    "explain": ("raytree", "explain"), "Image": ("film.image", "Image"),
    "read_exr": ("film.exr", "read_exr"), "render_frames": ("frames", "render_frames"),
    "Checker": ("material", "Checker"), "Material": ("material", "Material"),
    "MaterialLibrary": ("material", "MaterialLibrary"), "materials": ("material", "library"),
    "render": ("rendering", "render"), "ProgressBar": ("progress", "ProgressBar"),
    "Camera": ("scene", "Camera"),
    "RenderSettings": ("scene", "RenderSettings"), "Scene": ("scene", "Scene"),
    "load_scene": ("readers.scene_file", "load_scene"),
    "scene_from_dict": ("readers.scene_file", "scene_from_dict"),
}


def records() -> dict[str, type]:
    """Every registered light and object record by its class name: ``lights.LIGHT_TYPES``
    and ``scene.OBJECT_TYPES`` (``PointLight``, ``Sphere``, ``Mesh``, …). Loads the scene
    description (no compiler) on first use."""
    lights, scene = import_module(".lights", __name__), import_module(".scene", __name__)
    return {cls.__name__: cls for cls in (*lights.LIGHT_TYPES.values(),
                                          *scene.OBJECT_TYPES.values())}


def __getattr__(name: str):
    """A public name, loaded from its module on first use (PEP 562): one of :data:`EXPORTS`,
    a registered record (:func:`records`), ``__all__`` (both, sorted); and
    ``raytrace.__version__``: the installed distribution's version (pyproject.toml), not a
    second copy of it (``importlib.metadata`` costs 20–40 ms, so only when asked for)."""
    if name == "__version__":
        from importlib import metadata

        try:
            value = metadata.version("raytrace")
        except metadata.PackageNotFoundError:  # a source tree that was never installed
            value = "0+unknown"
    elif name == "__all__":  # (not kept: a record registered later is in it too)
        return sorted({*EXPORTS, *records()})
    elif name in EXPORTS:
        module, attribute = EXPORTS[name]
        value = getattr(import_module(f".{module}", __name__), attribute)
    elif name[:1].isupper() and name in (found := records()):
        # (a class name: a lower-case one may be a submodule that ``from . import`` asks
        # for while the registries themselves are loading)
        value = found[name]
    else:
        raise AttributeError(f"module 'raytrace' has no attribute {name!r}")
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    """The module's names and the public API, records included (``dir(raytrace)``, tab
    completion)."""
    return sorted({*globals(), *__getattr__("__all__")})
