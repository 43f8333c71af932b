"""The image writers by suffix: one registry that :meth:`Image.save`, the command line, frames
and the memory check all read.

======  =======  ===============================================================  ======
suffix  flag     what is written                                                  peak
                                                                                  B/px
======  =======  ===============================================================  ======
.exr    -o       float32 linear RGB, the AOVs as more channels (:mod:`.exr`)      25
.png    --png    the tone-mapped sRGB preview, 8 or 16 bits (:mod:`.previews`)    25
======  =======  ===============================================================  ======

A :class:`Writer` is one output format: its suffix, the command-line flag that asks for it and
that flag's help, the measured peak bytes a pixel of its writing step, and its function
``write(path, image, settings)``, which writes an :class:`~raytrace.film.image.Image` to
``path`` with the :class:`Settings` it reads. :data:`WRITERS` maps each suffix to its writer;
:func:`writer_for` is the dispatcher that names the valid suffixes on a bad one.

What reads the registry:

* :meth:`Image.save <raytrace.film.image.Image.save>` writes a path by its suffix's writer;
* ``raytrace render`` has a flag per writer: ``-o`` names the render's own output (the EXR,
  by default the scene's name with its suffix), every other flag (``--png [FILE]``) asks for
  one more output, named by FILE, or with ``--out-dir`` DIR/<scene name> with the suffix;
  with ``--frames`` each is a pattern;
* :func:`raytrace.render_frames` writes each frame's outputs by their suffixes' writers;
* :func:`raytrace.rendering.peak_bytes` takes the largest of the writers' figures for the
  outputs asked for (``render + exr + png`` in its error).

**Adding a format** touches this file only: a write function and one entry in
:data:`WRITERS`, e.g. Radiance RGBE through OpenImageIO::

    def _write_hdr(path, image, settings):
        import OpenImageIO as oiio  # a library's import: where it is used

        spec = oiio.ImageSpec(image.width, image.height, 3, oiio.FLOAT)
        out = oiio.ImageOutput.create("hdr")  # by name: ``path`` is a temporary file
        ...

    Writer(".hdr", "--hdr", "also write Radiance RGBE (float, linear) to FILE", 15,
           _write_hdr)

and ``raytrace render --hdr out.hdr``, ``--out-dir DIR --hdr``, ``--frames 1-9 --hdr
o.####.hdr``, ``Image.save("x.hdr")`` and the memory check follow. Write to ``path`` itself:
the callers make it a temporary file beside the target and rename it (:mod:`.outputs`), so a
writer needs no atomicity of its own. Measure the peak bytes as ``tests/test_render_api.py``'s
``test_the_peak_estimate_covers_a_measured_render`` does (``ru_maxrss`` of a 3000² render and
the write, in a fresh process). A writer that needs a setting the others do not read adds a
field to :class:`Settings` and, to set it from the command line, a flag of its own in
``cli.py`` (as ``--png-bits`` is the PNG's ``bits``).

The preview's writer is reached through the film's lazy names (``film.write_png``, PEP 562):
reading the registry, as the command line does for its flags, loads no compiler.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from .. import film
from .exr import write_exr


@dataclass(frozen=True)
class Settings:
    """What the writers read besides the image: the preview's ``exposure`` (stops or
    ``"auto"``), ``tonemap`` (a name of :data:`~raytrace.film.tonemap.TONEMAPS`) with its
    ``params``, and ``bits`` (8 or 16); the EXR's ``compression`` (a name of
    :data:`~raytrace.film.exr.EXR_COMPRESSIONS`) on ``threads`` threads. A writer ignores the
    fields it has no use for."""

    exposure: float | str = 0.0
    tonemap: str = "clip"
    bits: int = 8
    params: dict | None = None
    threads: int = 1
    compression: str = "zip"


@dataclass(frozen=True)
class Writer:
    """One output format (module docstring): ``suffix`` (lower case, with the dot), the
    command-line ``flag`` that asks for it and its ``help``, ``peak_bytes_per_pixel`` (the
    resident bytes a pixel while it writes, the rendered image included, measured), and
    ``write(path, image, settings)``."""

    suffix: str
    flag: str
    help: str
    peak_bytes_per_pixel: int
    write: Callable[[str | os.PathLike, Any, Settings], None]

    @property
    def name(self) -> str:
        """The suffix without its dot: the step's name in the memory check (``"exr"``)."""
        return self.suffix.lstrip(".")


def _write_exr(path: str | os.PathLike, image: Any, settings: Settings) -> None:
    """The float EXR with the image's AOVs, metadata and crop (:func:`.exr.write_exr`)."""
    write_exr(path, image.rgb, image.metadata, settings.threads, settings.compression,
              channels=image.channels(), crop=image.crop, frame=image.frame)


def _write_png(path: str | os.PathLike, image: Any, settings: Settings) -> None:
    """The sRGB preview (:func:`.previews.write_png`), tone-mapped band by band."""
    film.write_png(path, image.rgb, settings.exposure, settings.tonemap, bits=settings.bits,
                   params=settings.params)


#: The writers by suffix, in the order the command line writes and lists them. Peak bytes a
#: pixel measured with ``ru_maxrss`` at 3000² and 6000² pixels, 2 threads
#: (docs/robustness.md, "Memory"): the EXR holds the image and a contiguous copy of each
#: channel; the PNG preview, tone-mapped and written band by band, no more than the EXR's step
#: (23.8 B a pixel measured with both).
WRITERS: dict[str, Writer] = {w.suffix: w for w in (
    Writer(".exr", "-o", "output EXR", 25, _write_exr),
    Writer(".png", "--png", "also write a tone-mapped sRGB PNG preview to FILE", 25,
           _write_png),
)}

#: The flag of the output every render writes (the EXR's); every other writer's flag asks for
#: one more output.
MAIN_FLAG = "-o"


def suffixes() -> str:
    """The registered suffixes as a phrase: ``".exr or .png"``."""
    names = list(WRITERS)
    return names[0] if len(names) == 1 else f"{', '.join(names[:-1])} or {names[-1]}"


def writer_for(path: str | os.PathLike) -> Writer:
    """The writer of ``path``'s suffix (any case); a ValueError naming the valid suffixes
    otherwise.

    >>> writer_for("out.EXR").flag
    '-o'
    >>> writer_for("out.jpg")  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    ValueError: out.jpg: unknown image type '.jpg' (use .exr...png...)
    """
    suffix = Path(path).suffix.lower()
    if suffix not in WRITERS:
        raise ValueError(f"{path}: unknown image type {suffix!r} (use {suffixes()})")
    return WRITERS[suffix]


def named(step: str) -> Writer:
    """The writer whose :attr:`Writer.name` is ``step`` (``"exr"``); a ValueError naming the
    valid names otherwise."""
    for w in WRITERS.values():
        if w.name == step:
            return w
    raise ValueError(f"unknown output step {step!r} (choose from "
                     f"{', '.join(w.name for w in WRITERS.values())})")


def main_writer() -> Writer:
    """The writer of the render's own output, the one :data:`MAIN_FLAG` names."""
    return next(w for w in WRITERS.values() if w.flag == MAIN_FLAG)


def extra_writers() -> list[Writer]:
    """Every other writer, in registry order: each flag asks for one more output."""
    return [w for w in WRITERS.values() if w.flag != MAIN_FLAG]
