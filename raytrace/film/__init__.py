"""The film: images, their writers (EXR, PNG previews), tone mapping, AOVs and metrics.

* :mod:`.image`: :class:`Image`, the rendered picture and what was rendered with it;
* :mod:`.exr`, :mod:`.png`: the file formats; :mod:`.previews`: the tone-mapped sRGB codes of
  a PNG preview; :mod:`.writers`: the output formats by suffix that ``Image.save``, the command
  line, frames and the memory check use;
* :mod:`.tonemap`: exposure and tone-mapping operators by name, the sRGB encoding;
* :mod:`.aov`: the AOVs' channels and how their samples combine;
* :mod:`.filters`: the reconstruction filters that make pixels of samples;
* :mod:`.metrics`, :mod:`.compare`: image differences; :mod:`.files`, :mod:`.outputs`: files
  written whole, and all-or-nothing outputs.

The names below are the film's public API (``from raytrace.film import read_exr``), each
loaded from its module when first asked for (PEP 562): reading an EXR or comparing two needs
no compiler, a preview does.
"""

from importlib import import_module

#: Public name → the module of this folder that defines it.
EXPORTS = {"EXR_COMPRESSIONS": "exr", "exr_compression": "exr", "read_exr": "exr",
           "write_exr": "exr", "atomic_path": "files", "Image": "image",
           "write_png_pixels": "png", "preview": "previews", "write_png": "previews"}
__all__ = sorted(EXPORTS)


def __getattr__(name: str):
    """Load a public name from its module on first use (PEP 562 module ``__getattr__``)."""
    if name not in EXPORTS:
        raise AttributeError(f"module 'raytrace.film' has no attribute {name!r}")
    value = getattr(import_module(f".{EXPORTS[name]}", __name__), name)
    globals()[name] = value
    return value
