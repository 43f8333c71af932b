"""The ``raytrace`` command line.

    raytrace render SCENE [-o OUT.exr] [--width W] [--height H] [--spp N] [--max-depth D]
                          [--min-weight W] [--seed S] [--threads T] [--png PREVIEW.png]
                          [--exposure EV|auto] [--tonemap NAME] [--png-bits 8|16]
                          [--stats STATS.json] [--compression none|rle|zips|zip|piz|zstd]
                          [--quiet]
    raytrace compare TEST.exr REFERENCE.exr [--metric rmse|mae|max|relmse] [--threshold T]
    raytrace materials

Bad input prints one line ``raytrace: error: FILE: KEY: problem`` and exits with status 2;
``compare`` exits 1 when the difference is over the threshold.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from .errors import SceneError

EXIT_BAD_INPUT = 2
EXIT_OVER_THRESHOLD = 1


class _Parser(argparse.ArgumentParser):
    """argparse, but a bad flag is one line (no usage block), like every other bad input."""

    def error(self, message: str):
        self.exit(EXIT_BAD_INPUT, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


def _exposure(text: str) -> float | str:
    """``--exposure``: stops in the accepted range, or ``auto`` (checked while parsing)."""
    from .tonemap import check_exposure

    try:
        return check_exposure(text)
    except ValueError as e:
        raise argparse.ArgumentTypeError(str(e)) from None


def _parser() -> argparse.ArgumentParser:
    from .film import EXR_COMPRESSIONS
    from .tonemap import EXPOSURE_RANGE, TONEMAPS

    p = _Parser(prog="raytrace", description="A Whitted ray tracer on Embree.")
    sub = p.add_subparsers(dest="command", required=True)

    r = sub.add_parser("render", help="render a scene file to a float EXR")
    r.add_argument("scene", help="scene file (.toml or .json)")
    r.add_argument("-o", "--output", help="output EXR (default: SCENE's name with .exr, here)")
    r.add_argument("--width", type=int)
    r.add_argument("--height", type=int)
    r.add_argument("--spp", type=int, help="samples per pixel")
    r.add_argument("--max-depth", type=int, help="reflection/refraction recursion limit")
    r.add_argument("--min-weight", type=float, help="prune rays whose weight is below this")
    r.add_argument("--seed", type=int)
    r.add_argument("--threads", type=int, default=os.cpu_count() or 1,
                   help="worker threads (default: all cores)")
    r.add_argument("--png", help="also write a tone-mapped sRGB PNG preview")
    r.add_argument("--exposure", type=_exposure, default=0.0,
                   help=f"preview exposure in stops, {EXPOSURE_RANGE[0]:g} to "
                        f"{EXPOSURE_RANGE[1]:g}, or 'auto' (key 0.18 over the log-average "
                        f"luminance, Reinhard 2002)")
    r.add_argument("--tonemap", default="clip",
                   help=f"preview tone map (colour-hdri's operators): {', '.join(TONEMAPS)}")
    r.add_argument("--png-bits", type=int, choices=(8, 16), default=8,
                   help="bits per channel of the PNG preview (default 8)")
    r.add_argument("--stats", help="write render statistics as JSON")
    r.add_argument("--compression", default="zip", type=str.lower,
                   choices=tuple(EXR_COMPRESSIONS),
                   help="EXR compression, all lossless (default: zip; zstd files need "
                        "OpenEXR >= 3.5 to read)")
    r.add_argument("-q", "--quiet", action="store_true",
                   help="no progress bar and no summary line (both only on a terminal)")

    c = sub.add_parser("compare", help="compare two EXR images; exit 1 when over threshold")
    c.add_argument("test")
    c.add_argument("reference")
    c.add_argument("--metric", default="rmse", help="rmse, mae, max or relmse")
    c.add_argument("--threshold", type=float, default=1e-3)

    sub.add_parser("materials", help="list the named materials of the library")
    return p


class Progress:
    """A one-line progress bar on a terminal; silent when stderr is not a TTY."""

    def __init__(self, enabled: bool):
        self.enabled = enabled and sys.stderr.isatty()
        self.start = time.perf_counter()

    def __call__(self, done: int, total: int) -> None:
        if not self.enabled:
            return
        frac = done / total
        bar = "#" * int(30 * frac)
        elapsed = time.perf_counter() - self.start
        sys.stderr.write(f"\r[{bar:<30}] {100 * frac:5.1f}%  {elapsed:6.1f}s")
        if done >= total:
            sys.stderr.write("\n")
        sys.stderr.flush()

    def summary(self, written: list[str], stats: dict) -> None:
        """One line after the bar: what was written, the size, the rays and the seconds
        from loading the scene to the last file written (``--stats``' ``seconds.total``)."""
        if not self.enabled:
            return
        sys.stderr.write(f"wrote {', '.join(written)}: {stats['width']}×{stats['height']}, "
                         f"{stats['spp']} spp, {stats['rays']['total'] / 1e6:.2f} M rays, "
                         f"{stats['seconds']['total']:.2f} s\n")
        sys.stderr.flush()


def _render(args: argparse.Namespace) -> int:
    from . import integrator  # noqa: F401  (the renderer and numba: imported, not timed)
    from .film import exr_compression, write_exr, write_png
    from .render import render
    from .scene_file import load_scene
    from .tonemap import check_tonemap

    try:
        args.tonemap = check_tonemap(args.tonemap)
    except ValueError as e:
        raise SceneError(str(e), "--tonemap") from None
    try:  # the binding may lack a listed one (zstd before 3.5): found now, not after the render
        exr_compression(args.compression)
    except ValueError as e:
        raise SceneError(str(e), "--compression") from None
    out = Path(args.output) if args.output else Path(Path(args.scene).stem + ".exr")
    if out.suffix.lower() != ".exr":
        raise SceneError(f"output must be an .exr file, got {str(out)!r}", "-o")
    for flag, path in (("-o", out), ("--png", args.png), ("--stats", args.stats)):
        if path and not Path(path).resolve().parent.is_dir():
            raise SceneError(f"folder does not exist: {Path(path).parent}", flag)
        if path and Path(path).is_dir():  # found now, not after the render
            raise SceneError(f"is a folder, not a file: {path}", flag)
    t0 = time.perf_counter()
    scene = load_scene(args.scene)
    load_seconds = time.perf_counter() - t0
    flags = {"width": "--width", "height": "--height", "spp": "--spp",
             "max_depth": "--max-depth", "min_weight": "--min-weight", "seed": "--seed",
             "threads": "--threads"}
    progress = Progress(not args.quiet)
    try:
        image = render(scene, width=args.width, height=args.height, spp=args.spp,
                       max_depth=args.max_depth, min_weight=args.min_weight, seed=args.seed,
                       threads=args.threads, progress=progress)
    except SceneError as e:  # a flag's value: name the flag, not the scene key
        key = (e.key or "").removeprefix("render.")
        raise SceneError(e.problem, flags.get(key, e.key)) from None
    t1 = time.perf_counter()
    write_exr(out, image.rgb, image.metadata, args.threads, args.compression)
    args.written.append(str(out))
    if args.png:
        write_png(args.png, image.rgb, args.exposure, args.tonemap, bits=args.png_bits)
        args.written.append(str(args.png))
    stats = image.stats
    stats["seconds"]["load"] = load_seconds
    stats["seconds"]["write"] = time.perf_counter() - t1
    stats["seconds"]["total"] = time.perf_counter() - t0
    stats["output"] = str(out)
    if args.stats:
        from .film import atomic_path

        with atomic_path(args.stats, ".json") as tmp:
            tmp.write_text(json.dumps(stats, indent=2) + "\n")
    progress.summary(args.written + ([args.stats] if args.stats else []), stats)
    return 0


METRICS = {
    "rmse": lambda a, b: float(np.sqrt(np.mean((a - b) ** 2))),
    "mae": lambda a, b: float(np.mean(np.abs(a - b))),
    "max": lambda a, b: float(np.max(np.abs(a - b))),
    "relmse": lambda a, b: float(np.mean((a - b) ** 2 / (b * b + 1e-2))),
}


def _compare(args: argparse.Namespace) -> int:
    from .film import read_exr

    if args.metric not in METRICS:
        raise SceneError(f"unknown metric {args.metric!r} (choose from {', '.join(METRICS)})",
                         "--metric")
    images = []
    for path in (args.test, args.reference):
        if not Path(path).is_file():
            raise SceneError("file not found", file=path)
        try:
            images.append(read_exr(path)[0].astype(np.float64))
        except Exception as e:  # the binding raises plain exceptions for bad files
            raise SceneError(f"cannot read EXR: {e}", file=path) from None
    a, b = images
    if a.shape != b.shape:
        raise SceneError(f"size {a.shape[1]}x{a.shape[0]} differs from the reference's "
                         f"{b.shape[1]}x{b.shape[0]}", file=args.test)
    value = METRICS[args.metric](a, b)
    over = not value <= args.threshold
    print(f"{args.metric} = {value:.6g} ({'over' if over else 'within'} threshold "
          f"{args.threshold:g})")
    return EXIT_OVER_THRESHOLD if over else 0


def _materials(args: argparse.Namespace) -> int:
    from .material import library

    for name in library:
        m = library[name]
        extra = f" kr={m.kr.max():g} kt={m.kt.max():g} ior={m.ior:g}" if (
            m.reflects or m.transmits) else ""
        print(f"{name:18s} {library.describe(name)['description']}{extra}")
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    args.written = []  # outputs complete so far (each is written atomically)
    handler = {"render": _render, "compare": _compare, "materials": _materials}[args.command]
    try:
        return handler(args)
    except SceneError as e:
        print(f"raytrace: error: {e}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except BrokenPipeError:  # e.g. `raytrace materials | head`
        sys.stderr.close()
        return 0
    except KeyboardInterrupt:
        end_bar = "\n" if sys.stderr.isatty() else ""  # leave the progress bar's line
        done = f"wrote {', '.join(args.written)} only" if args.written else "no output written"
        print(f"{end_bar}raytrace: interrupted; {done}", file=sys.stderr)
        return 130
    except OSError as e:  # e.g. no permission or no space left writing an output
        print(f"raytrace: error: {e.filename or ''}: {e.strerror or e}", file=sys.stderr)
        return EXIT_BAD_INPUT


if __name__ == "__main__":
    sys.exit(main())
