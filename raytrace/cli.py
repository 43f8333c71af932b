"""The ``raytrace`` command line.

    raytrace render SCENE [-o OUT.exr] [--width W] [--height H] [--spp N] [--max-depth D]
                          [--min-weight W] [--seed S] [--threads T] [--png PREVIEW.png]
                          [--exposure EV|auto] [--tonemap NAME] [--png-bits 8|16]
                          [--stats STATS.json] [--compression none|rle|zips|zip|piz|zstd]
                          [--quiet] [--aov depth,normal,albedo,id,uv,position] [--crop X0 Y0 X1 Y1]
                          [--filter box|tent|gaussian|mitchell]
                          [--aa uniform|adaptive|noise] [--aa-threshold T] [--aa-depth D]
                          [--aa-min-depth M] [--noise-threshold T] [--min-spp N]
                          [--max-spp N] [--target-error E] [--time-limit S]
                          [--texture-filter bilinear|trilinear] [--max-memory SIZE]
                          [--frames LIST [--overwrite]]
                          [--workers N | --scheduler ADDRESS
                          [--tls-ca-file CA --tls-cert CERT --tls-key KEY]] [--tile PIXELS]
                          [--worker-timeout SECONDS]
    raytrace render SCENE1 SCENE2 ... --out-dir DIR [--png] [--stats] [the flags above
                          but -o and --frames]
    raytrace explain SCENE --pixel X Y [--sample S] [--json] [--width W] [--height H]
                          [--spp N] [--max-depth D] [--min-weight W] [--seed S]
    raytrace compare TEST.exr REFERENCE.exr [--metric rmse|mae|max|relmse|psnr|flip]
                     [--threshold T] [--diff DIFF.png] [--json]
    raytrace materials
    raytrace warmup [SCENE ...] [--jobs N] [--quiet]
    raytrace --version

Exit status (docs/scene_format.md, "Exit status", has the same table)::

    0    done (compare: within the threshold)                       EXIT_DONE
    1    compare: over the threshold (under it for PSNR)            EXIT_OVER_THRESHOLD
    1    any other command: an internal error, with its traceback   EXIT_INTERNAL
    2    bad input: one line raytrace: error: FILE: KEY: problem    EXIT_BAD_INPUT
    3    the engine cannot run here (Embree missing or failing)     EXIT_ENGINE
    130  interrupted (Ctrl-C)                                       EXIT_INTERRUPTED

The metrics are :data:`raytrace.film.metrics.METRICS`. ``render`` writes all of its outputs
or none (:mod:`raytrace.film.outputs`); a render that completes but is probably not what was meant
adds a line ``raytrace: warning: FILE: problem``. With ``--out-dir`` each scene's outputs are
all or nothing on their own; a scene that fails is one error line naming its file, the next
scene is rendered, and the exit status is 2. A render over its memory ceiling (``--max-memory``)
is bad input too (exit 2); Ctrl-C ends a render within a batch of each pass with one line
``raytrace: interrupted; ...`` and exit status 130.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import sys
import time
import warnings
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from .errors import ClusterError, EngineError, RenderWarning, SceneError
from .film.outputs import Outputs

if TYPE_CHECKING:
    from .scene import Scene

EXIT_DONE = 0
#: ``compare`` only: the difference is worse than the threshold.
EXIT_OVER_THRESHOLD = 1
#: An exception raytrace did not expect: Python prints its traceback and exits 1 (a bug).
EXIT_INTERNAL = 1
EXIT_BAD_INPUT = 2
#: The engine cannot run on this install (raytrace.errors.EngineError): not the input's fault.
EXIT_ENGINE = 3
#: Ctrl-C (128 + SIGINT, as a shell reports a process the signal ended).
EXIT_INTERRUPTED = 130


class _Parser(argparse.ArgumentParser):
    """argparse, but a bad flag is one line (no usage block), like every other bad input."""

    def error(self, message: str):
        self.exit(EXIT_BAD_INPUT, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


class _Version(argparse.Action):
    """``--version``: the distribution's version, read only when asked for."""

    def __call__(self, parser, namespace, values, option_string=None):
        from . import __version__

        print(f"raytrace {__version__}")  # stdout, as argparse's own version action
        parser.exit()


def _exposure(text: str) -> float | str:
    """``--exposure``: stops in the accepted range, or ``auto`` (checked while parsing)."""
    from .film.tonemap import check_exposure

    try:
        return check_exposure(text)
    except ValueError as e:
        raise argparse.ArgumentTypeError(str(e)) from None


def _dest(writer) -> str:
    """The attribute of the parsed arguments that holds an extra writer's file
    (``--png`` → ``png``); ``-o``'s is ``output``."""
    return writer.flag.lstrip("-").replace("-", "_")


def _and(names: list[str]) -> str:
    """``["a", "b", "c"]`` → ``"a, b and c"``."""
    return names[0] if len(names) == 1 else f"{', '.join(names[:-1])} and {names[-1]}"


def _parser() -> argparse.ArgumentParser:
    from .film.exr import EXR_COMPRESSIONS
    from .film.tonemap import EXPOSURE_RANGE, TONEMAPS
    from .film.writers import extra_writers, main_writer

    p = _Parser(prog="raytrace", description="A Whitted ray tracer on Embree.")
    p.add_argument("--version", action=_Version, nargs=0, help="show the version and exit")
    sub = p.add_subparsers(dest="command", required=True)

    r = sub.add_parser("render", help="render a scene file to a float EXR")
    r.add_argument("scenes", nargs="+", metavar="SCENE",
                   help="scene file (.toml or .json, or a model file); several with --out-dir")
    main, extras = main_writer(), extra_writers()  # the flags of the writers (film/writers.py)
    r.add_argument(main.flag, "--output",
                   help=f"{main.help} (default: SCENE's name with {main.suffix}, here)")
    r.add_argument("--out-dir", metavar="DIR",
                   help=f"render every SCENE in one process, each to DIR/<scene name>"
                        f"{main.suffix} (an existing folder; and "
                        f"{', '.join(w.suffix for w in extras)}, .json with "
                        f"{', '.join(w.flag for w in extras)}, --stats given no file name), "
                        "all or nothing scene by scene; a bad scene is one error line, the "
                        "others are rendered, and the exit status is 2")
    _overrides(r)
    r.add_argument("--threads", type=int, default=os.cpu_count() or 1,
                   help="worker threads (default: all cores)")
    r.add_argument("--max-memory", metavar="SIZE",
                   help="memory ceiling of this process, e.g. 4G or 512M (binary units) or "
                        "bytes: a render over it is refused or stopped (default: the memory "
                        "in use plus the memory available when the render starts)")
    for w in extras:
        r.add_argument(w.flag, nargs="?", const=True, metavar="FILE", dest=_dest(w),
                       help=f"{w.help} ({w.suffix}; no FILE only with --out-dir)")
    r.add_argument("--exposure", type=_exposure, default=0.0,
                   help=f"preview exposure in stops, {EXPOSURE_RANGE[0]:g} to "
                        f"{EXPOSURE_RANGE[1]:g}, or 'auto' (key 0.18 over the log-average "
                        f"luminance, Reinhard 2002)")
    r.add_argument("--tonemap", default="clip",
                   help=f"preview tone map (colour-hdri's operators): {', '.join(TONEMAPS)}")
    r.add_argument("--png-bits", type=int, choices=(8, 16), default=8,
                   help="bits per channel of the PNG preview (default 8)")
    r.add_argument("--stats", nargs="?", const=True, metavar="FILE",
                   help="write render statistics as JSON to FILE (no FILE only with "
                        "--out-dir)")
    r.add_argument("--compression", default="zip", type=str.lower,
                   choices=tuple(EXR_COMPRESSIONS),
                   help="EXR compression, all lossless (default: zip; zstd files need "
                        "OpenEXR >= 3.5 to read)")
    r.add_argument("-q", "--quiet", action="store_true",
                   help="no progress bar and no summary line (both only on a terminal)")
    r.add_argument("--aov", metavar="NAMES",
                   help="AOVs written as more channels of the EXR, comma-separated names "
                        "(depth, normal, ...; a wrong one lists them all; docs/testing.md "
                        "gives their channels)")
    r.add_argument("--crop", type=int, nargs=4, metavar=("X0", "Y0", "X1", "Y1"),
                   help="render only these pixels (half-open bounds; the EXR's data window "
                        "in the full frame's display window)")
    r.add_argument("--filter", help="pixel reconstruction filter: box (default), tent, "
                                    "gaussian or mitchell")
    r.add_argument("--aa", help="anti-aliasing: uniform (spp stratified samples, default), "
                                "adaptive (pixel corners, refined where they differ) or noise "
                                "(samples doubled where a pixel's noise is over "
                                "--noise-threshold)")
    r.add_argument("--aa-threshold", type=float,
                   help="adaptive: refine where corners differ by this or more")
    r.add_argument("--aa-depth", type=int, help="adaptive: most halvings of a pixel")
    r.add_argument("--aa-min-depth", type=int,
                   help="adaptive: halvings of every pixel whatever its corners (default 0)")
    r.add_argument("--noise-threshold", type=float,
                   help="noise: a pixel's error (Dammertz 2010, as Cycles) above which it gets "
                        "more samples (default 0.01)")
    r.add_argument("--min-spp", type=int, help="noise: samples every pixel gets first "
                   "(default 8; 4 with --target-error or --time-limit)")
    r.add_argument("--max-spp", type=int, help="noise: most samples a pixel gets (default 1024)")
    r.add_argument("--texture-filter",
                   help="image-texture lookups: bilinear (default) or trilinear (mip-mapped "
                        "by ray cones, for textures seen from afar)")
    r.add_argument("--target-error", type=float, metavar="E",
                   help="stop once the estimated relative RMSE is at most E (e.g. 0.01; "
                        "sets --aa noise unless the scene asks for another aa)")
    r.add_argument("--time-limit", type=float, metavar="S",
                   help="start no pass after S seconds (sets --aa noise likewise); with "
                        "--target-error, whichever comes first")
    f = r.add_argument_group("sequences (docs/distributed.md)")
    f.add_argument("--frames", metavar="LIST",
                   help="render frames 1-24, 1..24 or 1,5,9-12: SCENE is a pattern of scene "
                        "files (shot_####.toml, shot_%%04d.toml) or FILE.py:FUNCTION of the "
                        f"frame number; {_and([main.flag, *(w.flag for w in extras)])} "
                        f"are patterns too (out.####{main.suffix})")
    f.add_argument("--overwrite", action="store_true",
                   help="with --frames: render frames whose outputs exist (default: skip them)")
    d = r.add_argument_group("Dask cluster (pip install 'raytrace[distributed]'; "
                             "docs/distributed.md)")
    d.add_argument("--workers", type=int, metavar="N",
                   help="render tiles (frames with --frames) on a local cluster of N worker "
                        "processes, one thread each, listening on 127.0.0.1 only")
    d.add_argument("--scheduler", metavar="ADDRESS",
                   help="render on an existing Dask cluster, e.g. tls://host:8786")
    d.add_argument("--tile", type=int, metavar="PIXELS",
                   help="tile side with --workers or --scheduler (default 256)")
    d.add_argument("--worker-timeout", type=float, metavar="SECONDS",
                   help="stop when the cluster has had no worker this long (default 60)")
    d.add_argument("--tls-ca-file", metavar="CA.pem", help="with --scheduler: the CA "
                   "certificate the scheduler's certificate is checked against")
    d.add_argument("--tls-cert", metavar="CERT.pem", help="with --scheduler: this client's "
                   "TLS certificate")
    d.add_argument("--tls-key", metavar="KEY.pem", help="with --scheduler: this client's "
                   "TLS private key")

    e = sub.add_parser("explain", help="the ray tree of one pixel sample, term by term")
    e.add_argument("scene", help="scene file (.toml or .json)")
    e.add_argument("--pixel", type=int, nargs=2, required=True, metavar=("X", "Y"),
                   help="column and row; (0, 0) is the top-left pixel")
    e.add_argument("--sample", type=int, default=0, help="which of the pixel's samples "
                                                         "(0 to spp - 1; default 0)")
    e.add_argument("--json", action="store_true", help="print the tree as one JSON object")
    _overrides(e)

    c = sub.add_parser("compare", help="compare two EXR images; exit 1 when over threshold")
    c.add_argument("test")
    c.add_argument("reference")
    c.add_argument("--metric", default="rmse",
                   help="rmse, mae, max, relmse, psnr or flip (flip needs raytrace[flip])")
    c.add_argument("--threshold", type=float,
                   help="worst value that passes (default 1e-3; psnr 60 dB, flip 0.01)")
    c.add_argument("--diff", help="write a diff heatmap PNG (white: the largest difference)")
    c.add_argument("--json", action="store_true",
                   help="print the whole report (every metric, worst pixels) as JSON")

    sub.add_parser("materials", help="list the named materials of the library")

    w = sub.add_parser("warmup", help="compile the kernels scenes use before their first "
                                      "render, several scenes at a time")
    w.add_argument("scenes", nargs="*", metavar="SCENE",
                   help="scene or model files (default: the scenes shipped with raytrace)")
    w.add_argument("--jobs", type=int, help="scenes rendered at a time, each in a process of "
                                            "its own (default: the CPUs)")
    w.add_argument("-q", "--quiet", action="store_true",
                   help="no progress bar and no table; errors only")
    return p


def _overrides(p: argparse.ArgumentParser) -> None:
    """The flags that override a scene's ``[render]`` settings (render and explain)."""
    p.add_argument("--width", type=int)
    p.add_argument("--height", type=int)
    p.add_argument("--spp", type=int, help="samples per pixel")
    p.add_argument("--max-depth", type=int, help="reflection/refraction recursion limit")
    p.add_argument("--min-weight", type=float, help="prune rays whose weight is below this")
    p.add_argument("--seed", type=int)


#: The flag of each render setting, to name in an error about its value.
FLAGS = {"width": "--width", "height": "--height", "spp": "--spp", "max_depth": "--max-depth",
         "min_weight": "--min-weight", "seed": "--seed", "threads": "--threads",
         "crop": "--crop", "aovs": "--aov", "filter": "--filter", "aa": "--aa",
         "aa_threshold": "--aa-threshold", "aa_depth": "--aa-depth",
         "aa_min_depth": "--aa-min-depth", "noise_threshold": "--noise-threshold",
         "min_spp": "--min-spp", "max_spp": "--max-spp", "target_error": "--target-error",
         "texture_filter": "--texture-filter",
         "time_limit": "--time-limit", "tile": "--tile", "pixel": "--pixel",
         "sample": "--sample", "max_memory": "--max-memory", "worker_timeout": "--worker-timeout"}


def _flag_error(e: SceneError) -> SceneError:
    """A SceneError about a setting's value, naming the flag instead of the scene key (and
    the scene file where the value is checked against the scene's frame)."""
    key = (e.key or "").removeprefix("render.")
    in_frame = key in ("crop", "pixel", "sample")
    return SceneError(e.problem, FLAGS.get(key, e.key), e.file if in_frame else None)


class Progress:
    """What a render shows on stderr while it runs: on a terminal, tqdm's bar with the time
    left and the rate (:class:`raytrace.progress.ProgressBar`, imported only then), and,
    terminal or not, numba's compiles while they run (:meth:`showing`); nothing with
    ``-q``. ``unit``: what the render's ``progress(done, total)`` counts."""

    def __init__(self, enabled: bool, unit: str = "camera rays"):
        self.quiet = not enabled
        self.enabled = enabled and sys.stderr.isatty()
        self._bar = None
        if self.enabled:
            from .progress import ProgressBar

            self._bar = ProgressBar(unit, file=sys.stderr)

    @contextlib.contextmanager
    def showing(self, compiles: bool = True) -> Iterator[Callable[[int, int], None]]:
        """The block's ``progress`` callback: this bar, and with ``compiles`` numba's
        compiles in the block said while they run, unless quiet
        (:class:`raytrace.kernels.compile.CompileNotice`). A block that raises leaves the
        bar's line as it is, for the line that says why."""
        try:
            if self.quiet or not compiles:
                yield self
            else:
                from .kernels.compile import CompileNotice

                with CompileNotice(sys.stderr).listening(self) as report:
                    yield report
        except BaseException:
            if self._bar is not None:
                self._bar.abandon()
            raise

    def __call__(self, done: int, total: int) -> None:
        if self._bar is not None:
            self._bar(done, total)

    def summary(self, written: list[str], stats: dict) -> None:
        """One line after the bar: what was written, the size, the rays and the seconds
        from loading the scene to the last file written (``--stats``' ``seconds.total``)."""
        if not self.enabled:
            return
        crop = " crop {} {} {} {} of".format(*stats["crop"]) if "crop" in stats else ""
        sys.stderr.write(f"wrote {', '.join(written)}:{crop} {stats['width']}×{stats['height']}, "
                         f"{stats['spp']} spp, {stats['rays']['total'] / 1e6:.2f} M rays, "
                         f"{stats['seconds']['total']:.2f} s\n")
        sys.stderr.flush()


def _progress_unit(aa: str, distributed: bool) -> str:
    """What a render's ``progress(done, total)`` counts: camera samples, a camera ray each,
    with uniform anti-aliasing; rows with adaptive (:mod:`raytrace.integrator`), whose
    distributed tiles count the samples a uniform render takes (:mod:`raytrace.distributed`);
    a noise-driven render's samples, a bar a round (:mod:`raytrace.noise`)."""
    if aa == "noise":
        return "samples"
    if aa != "adaptive":
        return "camera rays"
    return "samples" if distributed else "rows"


def _cluster(args: argparse.Namespace):
    """The Dask client the flags ask for, as a context manager (``nullcontext(None)``
    without ``--workers`` or ``--scheduler``); bad flags are found now, before the render."""
    from contextlib import nullcontext

    tls = (args.tls_ca_file, args.tls_cert, args.tls_key)
    if args.workers is not None and args.scheduler is not None:
        raise SceneError("give --workers (a local cluster) or --scheduler, not both",
                         "--scheduler")
    if args.workers is None and args.scheduler is None:
        for flag, value in (("--tile", args.tile), ("--worker-timeout", args.worker_timeout),
                            ("--tls-ca-file", tls[0]), ("--tls-cert", tls[1]),
                            ("--tls-key", tls[2])):
            if value is not None:
                raise SceneError("needs --workers or --scheduler", flag)
        return nullcontext(None)
    from .distributed import (
        check_tile,
        check_worker_timeout,
        connect,
        require_distributed,
        security,
    )

    require_distributed("--workers" if args.workers is not None else "--scheduler")
    check_tile(args.tile, "--tile")
    check_worker_timeout(args.worker_timeout, "--worker-timeout")
    if args.workers is not None:
        from . import values

        if any(tls):
            raise SceneError("TLS files are for --scheduler (a local cluster makes its own "
                             "certificates)", "--tls-ca-file")
        return connect(workers=values.number(args.workers, "--workers", lo=1, hi=256,
                                             integer=True))
    if "://" in args.scheduler and args.scheduler.split("://")[0] not in ("tcp", "tls"):
        raise SceneError(f"{args.scheduler!r}: use tcp://HOST:PORT or tls://HOST:PORT",
                         "--scheduler")
    from distributed.comm.addressing import parse_address, parse_host_port

    try:  # a missing or bad port: one line now, not a traceback and a stalled client
        parse_host_port(parse_address(args.scheduler)[1])
    except ValueError as e:
        raise SceneError(f"{args.scheduler!r}: {e} (use tcp://HOST:PORT or tls://HOST:PORT)",
                         "--scheduler") from None
    secure = security(*tls, flags=("--tls-ca-file", "--tls-cert", "--tls-key"))
    if secure is None and args.scheduler.startswith("tls://"):
        from distributed import Security

        if not Security().tls_client_cert:  # nor in Dask's configuration
            raise SceneError("a tls:// scheduler needs --tls-ca-file, --tls-cert and --tls-key "
                             "(or distributed.comm.tls.* in Dask's configuration)",
                             "--scheduler")
    return connect(scheduler=args.scheduler, security=secure)


def _render(args: argparse.Namespace) -> int:
    from . import (
        integrator,  # noqa: F401  (the renderer and numba: imported, not timed)
        malloc,
    )
    from .film.aov import check_aovs
    from .film.exr import exr_compression
    from .film.tonemap import check_tonemap
    from .film.writers import main_writer
    from .rendering import memory_size, render_options
    from .scene import Scene

    malloc.tune()  # this process is ours: passes reuse the blocks the passes before freed
    if args.max_memory is not None:  # bytes, found now
        args.max_memory = memory_size(args.max_memory, "--max-memory")
    try:
        args.tonemap = check_tonemap(args.tonemap)
    except ValueError as e:
        raise SceneError(str(e), "--tonemap") from None
    try:  # the binding may lack a listed one (zstd before 3.5): found now, not after the render
        exr_compression(args.compression)
    except ValueError as e:
        raise SceneError(str(e), "--compression") from None
    batch = _batch_outputs(args)  # the scenes and their outputs, or None for one scene
    cluster = _cluster(args)
    if args.frames is not None:
        return _render_frames(args, cluster)
    if args.overwrite:
        raise SceneError("is for --frames (a single render always writes its outputs)",
                         "--overwrite")
    aovs = check_aovs(args.aov, "--aov")  # found now, not after the render
    overrides = dict(width=args.width, height=args.height, spp=args.spp,
                     max_depth=args.max_depth, min_weight=args.min_weight, seed=args.seed,
                     threads=args.threads, crop=args.crop, aovs=aovs, filter=args.filter,
                     aa=args.aa, aa_threshold=args.aa_threshold, aa_depth=args.aa_depth,
                     aa_min_depth=args.aa_min_depth, noise_threshold=args.noise_threshold,
                     min_spp=args.min_spp, max_spp=args.max_spp,
                     target_error=args.target_error, time_limit=args.time_limit,
                     texture_filter=args.texture_filter)
    if batch is None:
        main = main_writer()  # -o, or the scene's name with its suffix; the others' flags
        files = {w.suffix: (args.output or Path(args.scene).stem + w.suffix) if w is main
                 else getattr(args, _dest(w)) for w in _asked_for(args)}
        with _Started(cluster) as client:
            return _render_one(args, args.outputs, (args.scene, files, args.stats), overrides,
                               client)
    try:  # the flags' values, found once for the batch (a crop: against each scene's frame)
        render_options(Scene(), **_scene_independent(overrides))
    except SceneError as e:
        raise _flag_error(e) from None
    failed = 0
    # Every scene is loaded before any is rendered, so that no scene's output overwrites a
    # file another scene of the batch reads (its scene file, meshes, textures, libraries).
    loaded, inputs = [], [(p, "a scene file of this batch") for p, *_ in batch]
    for paths in batch:
        try:
            loaded.append((paths, _load(paths[0])))
        except (SceneError, OSError) as e:
            failed += 1
            print(f"raytrace: error: {_one_line(e, paths[0])}", file=sys.stderr)
            continue
        inputs += [(f, f"{what} of {paths[0]}") for f, what in loaded[-1][1][0].input_files()]
    with _Started(cluster) as client:  # one cluster for the batch
        for paths, scene in loaded:
            with Outputs() as outputs:  # all or nothing, scene by scene
                try:
                    _render_one(args, outputs, paths, overrides, client, others=inputs,
                                scene=scene)
                except (SceneError, OSError) as e:
                    failed += 1
                    print(f"raytrace: error: {_one_line(e, paths[0])}",
                          file=sys.stderr)
                finally:
                    args.written.extend(outputs.written)
    return EXIT_BAD_INPUT if failed else 0


def _scene_independent(overrides: dict) -> dict:
    """The flags' values that can be checked before a scene is known: all but ``--crop``
    (checked against each scene's frame) and ``--aa-min-depth`` without ``--aa-depth``
    (bounded by each scene's ``aa_depth``)."""
    checked = {**overrides, "crop": None}
    if checked.get("aa_min_depth") is not None and checked.get("aa_depth") is None:
        checked["aa_min_depth"] = None
    return checked


def _load(scene_path: str) -> tuple[Scene, float]:
    """A scene file loaded (its model files' notes printed as warning lines), and seconds."""
    from .readers.scene_file import load_scene

    t0 = time.perf_counter()
    with _warnings_as_lines():  # a model file's notes
        scene = load_scene(scene_path)
    return scene, time.perf_counter() - t0


class _Started(contextlib.ExitStack):
    """The cluster of ``--workers`` / ``--scheduler`` (a context manager giving a client or
    None), started on the first render that needs it, not before the scene is loaded and its
    outputs checked, and kept for every scene of a batch; closed with this block."""

    def __init__(self, cluster):
        super().__init__()
        self._cluster, self._client, self._started = cluster, None, False

    def __enter__(self) -> _Started:
        super().__enter__()
        return self

    def __call__(self):
        if not self._started:
            self._client, self._started = self.enter_context(self._cluster), True
        return self._client


def _asked_for(args: argparse.Namespace) -> list:
    """The writers of the images to write: ``-o``'s (always) and those whose flag is given,
    in registry order."""
    from .film.writers import MAIN_FLAG, WRITERS

    return [w for w in WRITERS.values() if w.flag == MAIN_FLAG or getattr(args, _dest(w))]


def _batch_outputs(args: argparse.Namespace
                   ) -> list[tuple[str, dict[str, str], str | None]] | None:
    """``render A.toml B.toml … --out-dir DIR``: each scene's (scene, images, stats) paths
    in DIR, named after the scene (DIR/A.exr, DIR/A.png, DIR/A.json), the images by suffix
    (:data:`raytrace.film.writers.WRITERS`), checked before any render: DIR is a folder, no
    two scenes share a name. None for the one-scene form (``SCENE [-o OUT.exr] [--png P.png]
    [--stats S.json]``), whose ``--png`` and ``--stats`` need a file name."""
    from .film.writers import extra_writers, main_writer

    scenes, out_dir = args.scenes, args.out_dir
    main = main_writer()
    # The flags that ask for one more file each: the extra writers' and --stats.
    more = [(w.flag, getattr(args, _dest(w)), w.suffix) for w in extra_writers()]
    more.append(("--stats", args.stats, ".json"))
    if out_dir is None:
        if len(scenes) > 1:
            raise SceneError(f"{len(scenes)} scenes need --out-dir DIR (each is written to "
                             f"DIR/<scene name>{main.suffix}); {main.flag} names one scene's "
                             "output", "SCENE")
        for flag, value, _ in more:
            if value is True:
                raise SceneError("needs a file name (or --out-dir DIR, which names each "
                                 "scene's file)", flag)
        args.scene = scenes[0]
        return None
    for flag, value in ((main.flag, args.output), ("--frames", args.frames)):
        if value is not None:
            raise SceneError("is not used with --out-dir (each scene is written to "
                             f"DIR/<scene name>{main.suffix})", flag)
    for flag, value, suffix in more:
        if isinstance(value, str):
            raise SceneError(f"takes no file name with --out-dir (each scene's goes to "
                             f"DIR/<scene name>{suffix}), got {value!r}", flag)
    if not Path(out_dir).is_dir():
        raise SceneError(f"is not an existing folder: {out_dir}", "--out-dir")
    seen: dict[str, str] = {}
    batch = []
    for scene in scenes:
        stem = Path(scene).stem
        if stem in seen:
            raise SceneError(f"{seen[stem]} and {scene} would both be written to "
                             f"{Path(out_dir) / stem}{main.suffix}: give each scene a name of "
                             "its own", "--out-dir")
        seen[stem] = scene
        batch.append((scene, {w.suffix: str(Path(out_dir) / f"{stem}{w.suffix}")
                              for w in _asked_for(args)},
                      str(Path(out_dir) / f"{stem}.json") if args.stats else None))
    return batch


def _one_line(e: SceneError | OSError, scene: str) -> str:
    """A batch scene's failure as one line naming its file (a failed write says what it left
    unwritten: :meth:`Outputs.summary`)."""
    if isinstance(e, SceneError):
        return str(e) if e.file else f"{scene}: {e}"
    where = ": ".join(str(p) for p in (e.filename, getattr(e, "key", None)) if p)
    return f"{scene}: {where + ': ' if where else ''}{e.strerror or e}"


def _render_one(args: argparse.Namespace, outputs: Outputs,
                paths: tuple[str, dict[str, str], str | None], overrides: dict,
                client, others: list[tuple[str, str]] = (),
                scene: tuple[Scene, float] | None = None) -> int:
    """Render one scene file to its EXR (and PNG, stats), all or nothing through ``outputs``.

    ``paths``: the scene file, the images to write by suffix (the EXR's first, then those of
    the other writers asked for, :data:`raytrace.film.writers.WRITERS`) and the stats file
    (None: not written); ``client()``: the Dask client or None (:class:`_Started`);
    ``others``: more files no output may overwrite (the batch's scene files and every file its
    scenes read); ``scene``: the scene already loaded, and its load seconds (:func:`_load`),
    or None to load it here."""
    from .film.writers import WRITERS, Settings, main_writer
    from .kernels.compile import load_registries
    from .rendering import check_memory, memory_ceiling, render, render_options

    scene_path, files, stats_path = paths
    # Every output is checked before anything is rendered (outputs.py): its suffix and that it
    # is no other output and not the scene file now; after loading, that it is no mesh or
    # material file the scene reads and that its folder takes a new file.
    images = [(WRITERS[suffix], outputs.add(path, WRITERS[suffix].flag, suffix))
              for suffix, path in files.items()]
    stats_file = outputs.add(stats_path, "--stats") if stats_path else None
    outputs.refuse_inputs([(scene_path, "the scene file"), *others])
    t0 = time.perf_counter()
    scene, load_seconds = scene or _load(scene_path)
    outputs.refuse_inputs(scene.input_files())
    outputs.preflight()
    try:
        o = render_options(scene, **overrides)
        progress = Progress(not args.quiet, _progress_unit(
            o.aa, distributed=args.workers is not None or args.scheduler is not None))
        x0, y0, x1, y1 = o.crop or (0, 0, o.width, o.height)
        check_memory(x1 - x0, y1 - y0, tuple(w.name for w, _ in images),
                     ceiling=memory_ceiling(args.max_memory))
        load_registries(lean=True)  # this process runs no numba code but ours (jit.py)
        with _warnings_as_lines(), progress.showing() as report:
            image = render(scene, progress=report, client=client(), tile=args.tile,
                           max_memory=args.max_memory, worker_timeout=args.worker_timeout,
                           **overrides)
    except SceneError as e:  # a flag's value: name the flag, not the scene key
        raise _flag_error(e) from None
    t1 = time.perf_counter()
    settings = Settings(exposure=args.exposure, tonemap=args.tonemap, bits=args.png_bits,
                        threads=args.threads, compression=args.compression)
    for writer, out in images:
        with outputs.stage(out) as tmp:
            writer.write(tmp, image, settings)
    stats = image.stats
    stats["seconds"]["load"] = load_seconds
    stats["seconds"]["write"] = time.perf_counter() - t1
    stats["seconds"]["total"] = time.perf_counter() - t0
    stats["output"] = files[main_writer().suffix]
    if stats_file:
        with outputs.stage(stats_file) as tmp:
            tmp.write_text(json.dumps(stats, indent=2) + "\n")
    outputs.commit()  # the renames, only now that every output is complete
    progress.summary(outputs.written, stats)
    return 0


@contextlib.contextmanager
def _warnings_as_lines():
    """Print the :class:`RenderWarning` s raised in the block as one line each
    (``raytrace: warning: FILE: problem``), terminal or not, once it ends; other warnings as
    Python would. They are shown after the recording ends: shown inside it, a warning would be
    recorded again, and the loop over the record would never end."""
    caught: list[warnings.WarningMessage] = []
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", RenderWarning)
            yield
    finally:
        for w in caught:
            if issubclass(w.category, RenderWarning):
                print(f"raytrace: warning: {w.message}", file=sys.stderr)
            else:
                warnings.showwarning(w.message, w.category, w.filename, w.lineno)


def _render_frames(args: argparse.Namespace, cluster) -> int:
    """``render --frames``: a sequence (:func:`raytrace.frames.render_frames`), each frame
    written when it is finished, the frames already written skipped unless ``--overwrite``."""
    from .film.aov import check_aovs
    from .film.writers import WRITERS, main_writer
    from .frames import (
        PLACEHOLDER,
        check_outputs,
        frame_path,
        parse_frames,
        render_frames,
        scene_source,
    )
    from .rendering import render_options
    from .scene import Scene

    for flag, value, default in (("--tile", args.tile, None), ("--png-bits", args.png_bits, 8)):
        if value != default:  # frames are rendered whole, their previews at 8 bits
            raise SceneError("is not used with --frames", flag)
    frames = parse_frames(args.frames, "--frames")
    source = scene_source(args.scene, "SCENE")
    stem = Path(source.files or source.name.rpartition(":")[0]).stem
    stem = PLACEHOLDER.sub("", stem).rstrip("._-") or "frame"  # shot_####.toml → shot
    main = main_writer()  # -o's pattern, or the scene's name with #### and its suffix
    patterns = check_outputs({w.suffix: (args.output or f"{stem}.####{w.suffix}") if w is main
                              else getattr(args, _dest(w)) for w in WRITERS.values()},
                             {w.suffix: w.flag for w in WRITERS.values()})
    out = patterns.pop(main.suffix)
    if args.stats and not Path(args.stats).resolve().parent.is_dir():
        raise SceneError(f"folder does not exist: {Path(args.stats).parent}", "--stats")
    if args.stats and source.files and any(
            Path(args.stats).resolve() == frame_path(source.files, f).resolve() for f in frames):
        raise SceneError(f"would overwrite the input {args.stats}", "--stats")
    stats_file = args.outputs.add(args.stats, "--stats") if args.stats else None
    args.outputs.preflight()  # (all or nothing, as a single render's --stats: outputs.py)
    aovs = check_aovs(args.aov, "--aov")
    overrides = {"width": args.width, "height": args.height, "spp": args.spp,
                 "max_depth": args.max_depth, "min_weight": args.min_weight, "seed": args.seed,
                 "threads": args.threads, "aovs": aovs, "filter": args.filter, "aa": args.aa,
                 "aa_threshold": args.aa_threshold, "aa_depth": args.aa_depth,
                 "aa_min_depth": args.aa_min_depth, "texture_filter": args.texture_filter}
    try:  # the flags' values, found now (the crop is checked against each frame's size)
        render_options(Scene(), **_scene_independent(overrides))
    except SceneError as e:
        raise _flag_error(e) from None
    progress = Progress(not args.quiet, "frames")

    def written(frame: int, paths: list[str]) -> None:
        args.written.extend(paths)
        args.frames_written.append(frame)

    with _warnings_as_lines(), cluster as client, progress.showing(compiles=False) as report:
        try:
            result = render_frames(source, out, frames, extras=patterns, client=client,
                                   overwrite=args.overwrite, progress=report,
                                   compression=args.compression, exposure=args.exposure,
                                   tonemap=args.tonemap, on_frame=written, crop=args.crop,
                                   max_memory=args.max_memory,
                                   worker_timeout=args.worker_timeout, **overrides)
        except SceneError as e:  # the keys only flags set: name the flag
            flag = e.key in ("crop", "max_memory", "worker_timeout")
            raise (_flag_error(e) if flag else e) from None
    rays = sum(st["rays"]["total"] for st in result.stats.values())
    if stats_file:
        summary = {"frames": {str(f): st for f, st in sorted(result.stats.items())},
                   "rendered": sorted(result.rendered), "skipped": result.skipped,
                   "rays": {"total": rays}, "seconds": {"total": result.seconds}}
        with args.outputs.stage(stats_file) as tmp:
            tmp.write_text(json.dumps(summary, indent=2) + "\n")
        args.outputs.commit()
    if progress.enabled:
        done = sorted(result.rendered)
        span = f"{result.outputs[done[0]][0]} … {result.outputs[done[-1]][0]}" if done else ""
        skipped = f", {len(result.skipped)} skipped (already written)" if result.skipped else ""
        sys.stderr.write(f"wrote {len(done)} frames {span}{skipped}: {rays / 1e6:.2f} M rays, "
                         f"{result.seconds:.2f} s\n")
    return 0


def _explain(args: argparse.Namespace) -> int:
    from .raytree import explain, format_tree
    from .readers.scene_file import load_scene

    scene = load_scene(args.scene)
    try:
        report = explain(scene, tuple(args.pixel), args.sample, width=args.width,
                         height=args.height, spp=args.spp, max_depth=args.max_depth,
                         min_weight=args.min_weight, seed=args.seed)
    except SceneError as e:
        raise _flag_error(e) from None
    print(json.dumps(report, indent=1) if args.json else format_tree(report))
    return 0


def _compare(args: argparse.Namespace) -> int:
    from .film import metrics
    from .film.compare import compare_images, write_diff
    from .film.exr import read_exr
    from .readers.inputs import input_file

    try:
        metric = metrics.get(args.metric)
    except ValueError as e:
        raise SceneError(str(e), "--metric") from None
    threshold = metric.default_threshold if args.threshold is None else args.threshold
    try:
        threshold = metrics.check_threshold(threshold)
    except ValueError as e:
        raise SceneError(str(e), "--threshold") from None
    inputs = (args.test, args.reference)
    if args.diff:
        diff = Path(args.diff)
        if diff.suffix.lower() != ".png":
            raise SceneError(f"must be a .png file, got {args.diff!r}", "--diff")
        if not diff.resolve().parent.is_dir():
            raise SceneError(f"folder does not exist: {diff.parent}", "--diff")
        if diff.is_dir():
            raise SceneError(f"is a folder, not a file: {args.diff}", "--diff")
        if any(diff.resolve() == Path(p).resolve() for p in inputs):
            raise SceneError(f"would overwrite the input {args.diff}", "--diff")
    images = []
    for path in inputs:
        input_file(path, "EXR file", file=path, a="an")
        try:
            images.append(read_exr(path)[0].astype(np.float64))
        except Exception as e:  # the binding raises plain exceptions for bad files
            raise SceneError(f"cannot read EXR: {e}", file=path) from None
    a, b = images
    if a.shape != b.shape:
        raise SceneError(f"size {a.shape[1]}x{a.shape[0]} differs from the reference's "
                         f"{b.shape[1]}x{b.shape[0]}", file=args.test)
    names = [*metrics.BASIC, *([metric.name] if metric.name not in metrics.BASIC else [])]
    try:
        report = compare_images(a, b, metrics=names)
    except (ImportError, ValueError) as e:  # FLIP: not installed, or undefined here
        raise SceneError(str(e), "--metric") from None
    value = report.metrics[metric.name]
    within = metric.within(value, threshold)
    if args.diff:  # through the outputs' transaction: errors name --diff's path, not a temp
        out = args.outputs.add(args.diff, "--diff", ".png")
        args.outputs.preflight()
        with args.outputs.stage(out) as tmp:
            write_diff(tmp, a, b)
        args.outputs.commit()
    if args.json:
        d = report.to_dict()
        print(json.dumps({"test": args.test, "reference": args.reference,
                          "metric": metric.name, "value": d["metrics"][metric.name],
                          "threshold": threshold, "within": within, "diff": args.diff, **d},
                         indent=2))
    else:
        verdict = "within" if within else ("below" if metric.higher_is_better else "over")
        print(f"{metric.name} = {value:.6g}{metric.unit} ({verdict} threshold "
              f"{threshold:g}{metric.unit})")
    return 0 if within else EXIT_OVER_THRESHOLD


def _materials(args: argparse.Namespace) -> int:
    from .material import library

    for name in library:
        m = library[name]
        extra = f" kr={m.kr.max():g} kt={m.kt.max():g} ior={m.ior:g}" if (
            m.reflects or m.transmits) else ""
        print(f"{name:18s} {library.describe(name)['description']}{extra}")
    return 0


def _warmup(args: argparse.Namespace) -> int:
    from .warmup import SIZE, shipped_folder, shipped_scenes, warmup

    if args.jobs is not None and args.jobs < 1:
        raise SceneError(f"must be at least 1, got {args.jobs}", "--jobs")
    scenes = [Path(s) for s in args.scenes] or shipped_scenes()
    if not scenes:
        raise SceneError(f"no SCENE given, and this install ships none ({shipped_folder()} "
                         "is not there)", "warmup")
    progress = Progress(not args.quiet, "scenes")
    t0 = time.perf_counter()
    with progress.showing(compiles=False) as report:
        warmed = warmup(scenes, args.jobs, report)
    failed = [w for w in warmed if w.error]
    if not args.quiet:
        width = max(len(str(w.scene)) for w in warmed)
        print(f"{'scene':{width}s}  seconds  compiling  ({SIZE[0]}x{SIZE[1]}, "
              f"a process each)")
        for w in warmed:
            print(f"{str(w.scene):{width}s}  {w.seconds:7.1f}  {w.compile_seconds:9.1f}"
                  f"{'  failed' if w.error else ''}")
        print(f"warmed {len(warmed) - len(failed)} of {len(warmed)} scenes in "
              f"{time.perf_counter() - t0:.1f} s")
    for w in failed:
        print(f"raytrace: error: {w.error}", file=sys.stderr)
    # a render's own status (3 the engine over 2 bad input), else 1: it crashed
    return max((w.returncode if w.returncode in (EXIT_BAD_INPUT, EXIT_ENGINE) else EXIT_INTERNAL
                for w in failed), default=EXIT_DONE)


def _frames_written(args: argparse.Namespace) -> str:
    """With ``--frames``, the frames written before a failure (each complete, and skipped
    by a rerun): `` (written before it: frames 1-3, ...)``, or ``""`` when none was."""
    if not args.frames_written:
        return ""
    from .frames import format_frames

    many = len(args.frames_written) > 1
    return (f" (written before it: frame{'s' * many} {format_frames(args.frames_written)}, "
            f"complete; a rerun without --overwrite skips {'them' if many else 'it'})")


def main(argv: Sequence[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    args.written = []  # frames of a sequence written so far (each is written atomically)
    args.frames_written = []  # and their numbers
    handler = {"render": _render, "explain": _explain, "compare": _compare,
               "materials": _materials, "warmup": _warmup}[args.command]
    with Outputs() as args.outputs:  # all or nothing (outputs.py); temporary files removed
        try:
            return handler(args)
        except (SceneError, ClusterError) as e:
            print(f"raytrace: error: {e}{_frames_written(args)}", file=sys.stderr)
            return EXIT_BAD_INPUT
        except EngineError as e:  # the install, not the input: Embree missing or unchecked
            print(f"raytrace: error: {e}{_frames_written(args)}", file=sys.stderr)
            return EXIT_ENGINE
        except BrokenPipeError:  # e.g. `raytrace materials | head`
            sys.stderr.close()
            return EXIT_DONE
        except KeyboardInterrupt:
            end_bar = "\n" if sys.stderr.isatty() else ""  # leave the progress bar's line
            done = (f"wrote {', '.join(args.written)} only" if args.written  # frames
                    else args.outputs.summary())
            print(f"{end_bar}raytrace: interrupted; {done}", file=sys.stderr)
            return EXIT_INTERRUPTED
        except OSError as e:  # e.g. no permission or no space left writing an output
            # (a failed write says what was written: Outputs.summary)
            where = ": ".join(str(p) for p in (e.filename, getattr(e, "key", None)) if p)
            print(f"raytrace: error: {where + ': ' if where else ''}{e.strerror or e}"
                  f"{_frames_written(args)}", file=sys.stderr)
            return EXIT_BAD_INPUT


if __name__ == "__main__":
    sys.exit(main())
