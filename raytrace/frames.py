"""Sequences of frames: ``raytrace.render_frames`` and ``raytrace render --frames``.

A sequence is a scene per frame, given as

* a pattern of scene files, ``shots/shot_####.toml`` (Blender's ``#`` run: the frame number
  padded with zeros to the run's length) or ``shots/shot_%04d.toml`` (printf, as ffmpeg and
  Nuke write it), read on the client; or
* a Python function of the frame number that returns a :class:`~raytrace.scene.Scene` (a
  camera path, a parameter sweep); on the command line ``anim.py:scene_at``. On a cluster it
  runs on the workers.

Each frame is written to the output pattern (``out.####.exr``) atomically, when it is finished
(:meth:`raytrace.film.Image.save`: a temporary file, then a rename), so a frame file that
exists is complete: a rerun skips the frames whose outputs all exist (resume after a crash,
like Blender's "Overwrite" turned off) unless ``overwrite``. With a Dask ``client`` the frames
are tasks on its cluster, one frame each, written by the client as they come back (no shared
filesystem); without, they render here one after another on every core.
"""

from __future__ import annotations

import os
import pickle
import re
import sys
import time
from collections.abc import Callable, Mapping, Sequence
from contextlib import closing
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from . import values
from .distributed import check_worker_timeout, gather_each
from .errors import MemoryLimitError, SceneError
from .film import writers
from .film.exr import exr_compression
from .film.image import Image
from .film.tonemap import check_exposure, check_tonemap
from .integrator import Stop
from .readers.bundle import Bundle, pack, unpack
from .readers.inputs import input_file
from .readers.scene_file import load_scene
from .rendering import memory_ceiling, memory_size, render, watch_memory
from .scene import Scene

if TYPE_CHECKING:
    from distributed import Client

#: A frame-number placeholder: a run of ``#`` (Blender), or printf's ``%d`` / ``%0Nd``.
PLACEHOLDER = re.compile(r"#+|%0?(\d*)d")
#: Most frames in one sequence.
MAX_FRAMES = 1_000_000


def parse_frames(spec: str | Sequence[int], key: str = "frames") -> list[int]:
    """Frame numbers from ``"1-24"``, ``"1..24"`` (Blender's ``-f``), ``"7"`` or a comma list
    of those (``"1-10,20,30-32"``), in the order given, each once; a sequence of whole numbers
    is taken as it is. A :class:`SceneError` naming ``key`` otherwise.

    >>> parse_frames("1-3,10,2..4")
    [1, 2, 3, 10, 4]
    """
    if not isinstance(spec, str):
        frames = [values.number(f, key, lo=0, integer=True) for f in spec]
    else:
        frames = []
        for part in spec.replace(" ", "").split(","):
            m = re.fullmatch(r"(\d+)(?:(?:-|\.\.)(\d+))?", part)
            if not m:
                raise SceneError(f"{spec!r} is not a frame list such as 1-24, 1..24 or 1,5,9-12",
                                 key)
            first, last = int(m[1]), int(m[2] if m[2] is not None else m[1])
            if last < first:
                raise SceneError(f"range {part} ends before it starts", key)
            if last - first >= MAX_FRAMES:
                raise SceneError(f"range {part} is over {MAX_FRAMES:,} frames", key)
            frames.extend(range(first, last + 1))
    frames = list(dict.fromkeys(frames))
    if not frames:
        raise SceneError("no frames", key)
    if len(frames) > MAX_FRAMES:
        raise SceneError(f"{len(frames):,} frames is over the limit of {MAX_FRAMES:,}", key)
    return frames


def format_frames(frames: Sequence[int]) -> str:
    """Frame numbers as :func:`parse_frames` reads them back, runs joined, in order.

    >>> format_frames([1, 2, 3, 10, 5, 6])
    '1-3,5-6,10'
    """
    runs: list[list[int]] = []
    for f in sorted(frames):
        if runs and f == runs[-1][1] + 1:
            runs[-1][1] = f
        else:
            runs.append([f, f])
    return ",".join(str(a) if a == b else f"{a}-{b}" for a, b in runs)


def check_pattern(pattern: str | os.PathLike, key: str) -> str:
    """``pattern`` as a string, checked to hold exactly one frame placeholder in its file
    name (:data:`PLACEHOLDER`)."""
    text = str(pattern)
    found = PLACEHOLDER.findall(Path(text).name)
    if len(found) != 1 or PLACEHOLDER.search(str(Path(text).parent)):
        raise SceneError(f"{text!r} needs one frame number in its file name: #### (Blender) or "
                         "%04d (printf), e.g. out.####.exr", key)
    return text


def check_outputs(patterns: Mapping[str, str | os.PathLike | None],
                  keys: Mapping[str, str]) -> dict[str, str]:
    """The output patterns by suffix (``{".exr": "out.####.exr", ".png": None}``), checked:
    one frame number each (:func:`check_pattern`), that suffix, an existing folder; a
    :class:`SceneError` naming the suffix's key in ``keys`` otherwise. Those given (not None),
    in the order of :data:`~raytrace.film.writers.WRITERS`."""
    checked = {}
    for suffix in sorted(patterns, key=list(writers.WRITERS).index):
        pattern, key = patterns[suffix], keys[suffix]
        if pattern is None:
            continue
        text = check_pattern(pattern, key)
        if Path(text).suffix.lower() != suffix:
            raise SceneError(f"must end in {suffix}, got {text!r}", key)
        if not Path(text).resolve().parent.is_dir():
            raise SceneError(f"folder does not exist: {Path(text).parent}", key)
        checked[suffix] = text
    return checked


def frame_path(pattern: str, frame: int) -> Path:
    """``pattern`` with its placeholder replaced by ``frame``.

    >>> str(frame_path("out.####.exr", 7)), str(frame_path("out_%03d.exr", 12))
    ('out.0007.exr', 'out_012.exr')
    """
    def number(m: re.Match) -> str:
        width = len(m[0]) if m[0].startswith("#") else int(m[1] or 0)
        return f"{frame:0{width}d}"

    return Path(PLACEHOLDER.sub(number, pattern, count=1))


@dataclass
class SceneSource:
    """Where each frame's scene comes from: ``files`` (a pattern, read on the client) or
    ``function`` (frame → Scene, run where the frame renders). ``name`` locates errors."""

    name: str
    files: str | None = None
    function: Callable[[int], Scene] | None = None

    def scene(self, frame: int) -> Scene:
        """The scene of ``frame``; a :class:`SceneError` naming the function and the frame
        when the function raises (the user's exception named in the one line, with the first
        line of its message, and chained) or returns something else than a Scene."""
        if self.files is not None:
            return load_scene(frame_path(self.files, frame))
        where = f"{self.name}({frame})"
        try:
            scene = self.function(frame)
        except SceneError as e:
            raise SceneError(e.problem, e.key, e.file or where) from None
        except Exception as e:  # the user's code: one line, not its traceback
            first = next(iter(str(e).splitlines()), "")
            raise SceneError(f"raised {type(e).__name__}: {first}", file=where) from e
        if not isinstance(scene, Scene):
            raise SceneError(f"returned {type(scene).__name__}, not a raytrace.Scene",
                             file=where)
        return scene


def scene_source(scenes: str | os.PathLike | Callable[[int], Scene] | SceneSource,
                 key: str = "scenes") -> SceneSource:
    """A :class:`SceneSource` from a callable, a pattern of scene files, or (the command
    line's form) ``path/to/anim.py:function``, whose module is run to find the function."""
    if isinstance(scenes, SceneSource):
        return scenes
    if callable(scenes):
        return SceneSource(getattr(scenes, "__qualname__", repr(scenes)), function=scenes)
    text = str(scenes)
    module, sep, name = text.rpartition(":")
    if sep and module.endswith(".py"):
        return SceneSource(text, function=load_function(module, name, key))
    return SceneSource(text, files=check_pattern(text, key))


def load_function(path: str, name: str, key: str) -> Callable[[int], Scene]:
    """The function ``name`` of the Python file ``path`` (run as a module of its own). On a
    cluster it is pickled by value (cloudpickle), so the workers need not have the file."""
    import importlib.util

    input_file(path, "Python file", key)
    name_here = f"raytrace_frames_{Path(path).stem}"
    spec = importlib.util.spec_from_file_location(name_here, path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[name_here] = module  # for pickle (cloudpickle) to find it
    try:
        spec.loader.exec_module(module)
    except Exception as e:  # the user's file: one line, not its traceback
        raise SceneError(f"cannot run {path}: {type(e).__name__}: {e}", key) from None
    function = getattr(module, name, None)
    if not callable(function):
        raise SceneError(f"{path} has no function {name!r}", key)
    return function


def render_frame(source: SceneSource | bytes, frame: int, overrides: dict) -> Image:
    """One frame: its scene (from the source, or ``source`` pickled: a SceneSource, or a
    scene as :func:`raytrace.readers.bundle.pack` sends it, read again here from its files'
    bytes) rendered with ``overrides`` (keywords of :func:`raytrace.render`). A worker task,
    and the local loop's step, so both raise the same errors."""
    if isinstance(source, bytes):
        source = pickle.loads(source)
    if isinstance(source, Bundle):
        source = unpack(source, load_scene)
    scene = source if isinstance(source, Scene) else source.scene(frame)
    return render(scene, **overrides)


@dataclass
class FramesResult:
    """What :func:`render_frames` did: the frames rendered and skipped (their outputs were
    there), each rendered frame's ``--stats`` dictionary, and the outputs by frame."""

    rendered: list[int] = field(default_factory=list)
    skipped: list[int] = field(default_factory=list)
    stats: dict[int, dict] = field(default_factory=dict)
    outputs: dict[int, list[str]] = field(default_factory=dict)
    seconds: float = 0.0


def render_frames(scenes: str | os.PathLike | Callable[[int], Scene] | SceneSource,
                  output: str | os.PathLike,
                  frames: str | Sequence[int], *, png: str | os.PathLike | None = None,
                  client: Client | None = None, overwrite: bool = False,
                  progress: Callable[[int, int], None] | None = None,
                  on_frame: Callable[[int, list[str]], None] | None = None,
                  compression: str = "zip", exposure: float = 0.0, tonemap: str = "clip",
                  extras: Mapping[str, str | os.PathLike] | None = None,
                  max_memory: int | str | None = None, worker_timeout: float | None = None,
                  **overrides: Any) -> FramesResult:
    """Render ``frames`` of a sequence to ``output`` (a pattern, ``out.####.exr``) and, with
    ``png``, previews (``preview.####.png``), each written atomically as it is finished.
    ``extras``: more output patterns by suffix, each written by its writer
    (:data:`raytrace.film.writers.WRITERS`; ``png`` is ``extras={".png": png}``).

    ``scenes``: a function of the frame number returning a Scene, or a pattern of scene
    files (module docstring). ``frames``: ``"1-24"`` and the like (:func:`parse_frames`) or
    numbers. Frames whose outputs all exist are skipped unless ``overwrite``. ``client``: a
    Dask client whose workers render one frame per task; otherwise frames render here in
    turn. ``progress(done, total)`` counts the frames rendered of those to render;
    ``on_frame(frame, paths)`` is called after each frame's files are written. ``exposure``
    and ``tonemap`` are the previews'; ``compression`` the EXRs'.
    ``max_memory``: the memory ceiling of this process (:func:`raytrace.render`'s): each
    frame's render here; with a ``client``, this process while it gathers and writes the
    frames (checked as each comes back), each frame on a worker having the default ceiling
    (:func:`raytrace.rendering.memory_ceiling`) and Dask's ``memory_limit``.
    ``worker_timeout``: with a ``client``, the seconds the frames wait on a cluster without
    workers (:func:`raytrace.distributed.gather_each`). Errors in these two name the keyword,
    not a frame's scene file.
    ``overrides``: :func:`raytrace.render`'s keywords (width, spp, crop, aovs, threads...).
    """
    t0 = time.perf_counter()
    if max_memory is not None:
        max_memory = memory_size(max_memory)
    if client is None and worker_timeout is not None:
        raise SceneError("a worker timeout needs a client: render_frames(..., client=..., "
                         "worker_timeout=...)", "worker_timeout")
    if client is not None:
        worker_timeout = check_worker_timeout(worker_timeout)
    source = scene_source(scenes)
    numbers = parse_frames(frames)
    given = {writers.main_writer().suffix: output, ".png": png}
    for suffix, pattern in (extras or {}).items():
        if suffix not in writers.WRITERS:
            raise SceneError(f"unknown image type {suffix!r} (use {writers.suffixes()})",
                             "extras")
        if given.get(suffix) is not None:
            raise SceneError(f"{suffix} is given twice, in extras and as its own argument",
                             "extras")
        given[suffix] = pattern
    keys = {w.suffix: w.name for w in writers.WRITERS.values()}
    patterns = check_outputs(given, {**keys, writers.main_writer().suffix: "output"})

    exr_compression(compression)  # bad names and values now, not after the first frame
    exposure, tonemap = check_exposure(exposure), check_tonemap(tonemap)
    result = FramesResult()
    todo = []
    for frame in numbers:
        paths = [str(frame_path(p, frame)) for p in patterns.values()]
        result.outputs[frame] = paths
        if not overwrite and all(Path(p).is_file() for p in paths):
            result.skipped.append(frame)
        else:
            todo.append(frame)
    if source.files is not None:  # a gap in the sequence: found before any frame is written
        for frame in todo:
            name = str(frame_path(source.files, frame))
            input_file(name, "scene file", file=name)

    def write(frame: int, image: Image) -> None:
        threads = overrides.get("threads") or os.cpu_count() or 1
        for pattern in patterns.values():  # each by its suffix's writer
            image.save(frame_path(pattern, frame), exposure, tonemap, threads, compression)
        result.rendered.append(frame)
        result.stats[frame] = image.stats
        if on_frame is not None:
            on_frame(frame, result.outputs[frame])
        if progress is not None:
            progress(len(result.rendered), len(todo))

    if client is None:
        for frame in todo:
            try:
                image = render_frame(source, frame, {**overrides, "max_memory": max_memory})
            except MemoryLimitError as e:  # over the keyword's ceiling: not the frame file's
                if e.key != "max_memory":
                    raise
                raise MemoryLimitError(e.problem, e.key) from None
            write(frame, image)
    else:
        remote = {**overrides, "threads": 1}  # a worker thread a frame; max_memory stays here
        token = time.time_ns()
        futures = []
        for frame in todo:
            # Scene files are read here (no shared filesystem) and sent as their bytes;
            # functions run on the workers.
            what = (pickle.dumps(pack(source.scene(frame)), protocol=pickle.HIGHEST_PROTOCOL)
                    if source.files is not None else by_value(source))
            futures.append(client.submit(framed, what, frame, remote, pure=False,
                                         key=f"raytrace-frame-{frame}-{token}"))
        stop = Stop()  # asked by the memory watch of this process, which writes the frames
        with (watch_memory(memory_ceiling(max_memory), stop),
              closing(gather_each(client, futures, worker_timeout)) as results):
            for frame, image in results:
                stop.check()
                write(frame, image)
            stop.check()
    result.seconds = time.perf_counter() - t0
    return result


def framed(source: SceneSource | bytes, frame: int, overrides: dict) -> tuple[int, Image]:
    """:func:`render_frame`, with its frame number (a worker task)."""
    return frame, render_frame(source, frame, overrides)


def by_value(source: SceneSource) -> bytes:
    """``source`` pickled by cloudpickle, with the module of a function loaded from a file
    (:func:`load_function`) pickled by value: the workers need not have the file."""
    import cloudpickle

    module = sys.modules.get(getattr(source.function, "__module__", "") or "")
    if module is not None and module.__name__.startswith("raytrace_frames_"):
        cloudpickle.register_pickle_by_value(module)
    return cloudpickle.dumps(source, protocol=pickle.HIGHEST_PROTOCOL)
