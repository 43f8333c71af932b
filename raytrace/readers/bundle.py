"""A scene read from files, sent as those files' bytes: what a Dask cluster's workers get.

A scene decoded is far bigger than its files (CesiumMilkTruck.glb is 542 kB; its 2048² texture
alone is 67 MB as float32 RGBA), so a scene that :func:`raytrace.load_scene` read travels as
its files and is read again where it renders:

* :func:`remember` (called by ``load_scene``) keeps, by the scene, the files its readers
  opened (each :class:`~raytrace.readers.inputs.Read` that
  :func:`~raytrace.readers.inputs.recording` noted) and the big objects the reading made
  (:func:`big`: :class:`~raytrace.readers.texture.Texture`\\ s, and numpy arrays of at least
  :data:`BIG` bytes), numbered in the order a pickling of the scene meets them, with each
  array's fingerprint (shape, dtype, CRC-32 of its bytes).
* :func:`pack` gives a :class:`Bundle`: the scene pickled with each big object that is still
  the one read (an array whose CRC is unchanged: no edit in place) replaced by its number
  (pickle's ``persistent_id``), so its camera, lights, settings and any other edit travel as
  they are now, plus the bytes of the files, read again and checked to be the ones read
  (same modification time and size). A scene not read from files, one whose scene file names
  a file by an absolute path (a worker would read it from its own disk), one whose files
  have changed or gone since, or one whose big objects weigh no more than its files (a TOML
  of spheres), is pickled whole (``source`` None), as before.
* :func:`unpack` (on a worker) writes the files under a folder of its own, each at its
  absolute path on the client below that folder, so that relative references (a TOML's
  ``file``, a glTF's image ``uri``, an OBJ's ``mtllib``) find them; reads the scene from
  there with the same reader; numbers its big objects the same way; checks their
  fingerprints against the client's (the same bytes through the same code give the same
  arrays; a worker with other versions of the readers is refused in one line rather than
  rendering another image); and puts them in the pickle's places. The objects read are kept
  per worker process by the files' SHA-256 (:data:`KEEP` sets), so a second tile or frame of
  the same files reads nothing, and a folder keeps a path's bytes for the process's life
  (another content for the same path goes to another folder), so a glTF file's own cache
  (:func:`raytrace.readers.gltf.load_gltf`, by path and modification time) serves the
  frames of a sequence that share a model.
"""

from __future__ import annotations

import atexit
import hashlib
import io
import os
import pickle
import shutil
import tempfile
import threading
import warnings
import weakref
import zlib
from collections import OrderedDict
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import SceneError
from .inputs import Read
from .texture import Texture

#: An array at least this big (bytes) is rebuilt from the files rather than pickled.
BIG = 1024
#: Sets of big objects read from files that a worker process keeps, most recently used last.
KEEP = 2


def big(obj: Any) -> bool:
    """Whether ``obj`` is rebuilt from the files on a worker: a texture, or a numeric array of
    at least :data:`BIG` bytes."""
    return isinstance(obj, Texture) or (isinstance(obj, np.ndarray) and obj.dtype != object
                                        and obj.nbytes >= BIG)


def fingerprint(obj: Any) -> tuple:
    """(shape, dtype, CRC-32 of the bytes) of an array, or of a texture's image: its codes
    and their colour table where it was read as codes (decoded or not), else its texels."""
    image = obj.image if isinstance(obj, Texture) else None
    if image is not None and image.codes is not None:
        return (image.shape, image.codes.dtype.str, zlib.crc32(image.codes.reshape(-1)),
                zlib.crc32(image.colour))
    a = np.ascontiguousarray(image.floats if image is not None else obj)
    return a.shape, a.dtype.str, zlib.crc32(a.view(np.uint8).reshape(-1))


class _Numbering(pickle.Pickler):
    """A pickler that writes each object of ``numbers`` (its ``id`` → its number) as that
    number; with ``found`` (a list), it numbers every :func:`big` object it meets, in the
    order met, and appends it there."""

    def __init__(self, file: Any, numbers: dict[int, int], found: list | None = None):
        super().__init__(file, protocol=pickle.HIGHEST_PROTOCOL)
        self.numbers, self.found = numbers, found

    def persistent_id(self, obj: Any) -> int | None:
        n = self.numbers.get(id(obj))
        if n is None and self.found is not None and big(obj):
            n = self.numbers[id(obj)] = len(self.found)
            self.found.append(obj)
        return n


class _Unnumbering(pickle.Unpickler):
    """The unpickler of :class:`_Numbering`'s pickles: number n is ``made[n]``."""

    def __init__(self, file: Any, made: list):
        super().__init__(file)
        self.made = made

    def persistent_load(self, pid: Any) -> Any:
        return self.made[pid]


class _Discard:
    """A file that keeps nothing (a pickling done only to number the big objects)."""

    def write(self, data: Any) -> int:
        return len(data)


def big_objects(scene: Any) -> list:
    """The :func:`big` objects of ``scene``, each once, in the order pickling meets them."""
    found: list = []
    _Numbering(_Discard(), {}, found).dump(scene)
    return found


@dataclass(frozen=True)
class Origin:
    """What :func:`remember` keeps by a scene: the scene file's absolute path, the files read
    (each once), the big objects made and each array's load-time fingerprint (None for a
    texture: its texels are not edited after it is made)."""

    source: str
    reads: tuple[Read, ...]
    made: tuple
    arrays: tuple


#: id(scene) → (a weak reference to the scene, its Origin).
_origins: dict[int, tuple[weakref.ref, Origin]] = {}


def remember(scene: Any, source: str | os.PathLike, reads: list[Read]) -> None:
    """Keep what ``scene`` was read from (``source``, the scene or model file, and ``reads``,
    every file its readers opened), for :func:`pack`, while the scene lives."""
    made = big_objects(scene)
    arrays = tuple(None if isinstance(o, Texture) else fingerprint(o) for o in made)
    key = id(scene)
    ref = weakref.ref(scene, lambda _, key=key: _origins.pop(key, None))
    _origins[key] = ref, Origin(os.path.abspath(source), tuple(dict.fromkeys(reads)),
                                tuple(made), arrays)


def origin_of(scene: Any) -> Origin | None:
    """What ``scene`` was read from (:func:`remember`), or None."""
    entry = _origins.get(id(scene))
    return entry[1] if entry is not None and entry[0]() is scene else None


@dataclass(frozen=True)
class Bundle:
    """A scene as it travels: ``scene`` pickled, its big objects as numbers into those that
    reading ``source`` from ``files`` (absolute path → bytes) makes, whose fingerprints
    ``made`` gives; ``source`` None: ``scene`` is the whole scene pickled."""

    scene: bytes
    source: str | None = None
    files: dict[str, bytes] = field(default_factory=dict)
    made: tuple = ()

    @property
    def file_bytes(self) -> int:
        """The size of the files it carries."""
        return sum(len(b) for b in self.files.values())

    def key(self) -> str:
        """SHA-256 of the source's path and each file's path and bytes: the key of the
        objects a worker reads from them."""
        h = hashlib.sha256(str(self.source).encode())
        for path in sorted(self.files):
            h.update(b"\0" + path.encode() + b"\0" + hashlib.sha256(self.files[path]).digest())
        return h.hexdigest()


def pack(scene: Any) -> Bundle:
    """``scene`` as a :class:`Bundle`: its files' bytes and the rest pickled, where it was
    read from files that are still as they were read; else pickled whole."""
    origin = origin_of(scene)
    files = _files(origin) if origin is not None else None
    if files is None:
        return Bundle(pickle.dumps(scene, protocol=pickle.HIGHEST_PROTOCOL))
    now = [fingerprint(o) if a is not None else None for o, a in zip(origin.made, origin.arrays,
                                                                     strict=True)]
    numbers = {id(o): n for n, (o, a, b) in enumerate(zip(origin.made, origin.arrays, now,
                                                           strict=True)) if a == b}
    decoded = sum(o.image.nbytes if isinstance(o, Texture) else o.nbytes
                  for o in origin.made if id(o) in numbers)
    if decoded <= sum(map(len, files.values())):  # the objects are no bigger than the files
        return Bundle(pickle.dumps(scene, protocol=pickle.HIGHEST_PROTOCOL))
    out = io.BytesIO()
    _Numbering(out, numbers).dump(scene)
    made = tuple(a if a is not None else fingerprint(o) for o, a in zip(origin.made,
                                                                         origin.arrays,
                                                                         strict=True))
    return Bundle(out.getvalue(), origin.source, files, made)


def _files(origin: Origin) -> dict[str, bytes] | None:
    """The bytes of the files ``origin`` read, or None where one has changed (modification
    time or size) or cannot be read."""
    files = {}
    for read in origin.reads:
        try:
            data = Path(read.path).read_bytes()
            st = os.stat(read.path)
        except OSError:
            return None
        if (st.st_mtime_ns, st.st_size, len(data)) != (read.mtime_ns, read.size, read.size):
            return None
        files[read.path] = data
    return files


_lock = threading.Lock()
#: The big objects read from a bundle's files, by :meth:`Bundle.key`.
_read: OrderedDict[str, list] = OrderedDict()
#: The folders files are written to: each with its files' SHA-256 by their client path.
_folders: list[tuple[Path, dict[str, bytes]]] = []


def unpack(bundle: Bundle, load: Callable[[Path], Any]) -> Any:
    """The scene of ``bundle``, its big objects read with ``load`` (``raytrace.load_scene``)
    from its files once per process (:data:`KEEP` sets kept). A :class:`SceneError` naming
    the scene file when what this process reads is not what the client read."""
    if bundle.source is None:
        return pickle.loads(bundle.scene)
    return _Unnumbering(io.BytesIO(bundle.scene), _made(bundle, load)).load()


def _made(bundle: Bundle, load: Callable[[Path], Any]) -> list:
    key = bundle.key()
    with _lock:  # the threads of a worker wait for one read rather than read twice
        if key in _read:
            _read.move_to_end(key)
            return _read[key]
        folder = _folder(bundle.files)
        with warnings.catch_warnings():  # the client has said them
            warnings.simplefilter("ignore")
            made = big_objects(load(_below(folder, bundle.source)))
        if tuple(fingerprint(o) for o in made) != bundle.made:
            raise SceneError("this worker read its files into other arrays than the client did "
                             "(other versions of raytrace or its readers, or a file named by "
                             "an absolute path that differs here?)", file=bundle.source)
        _read[key] = made
        while len(_read) > KEEP:
            _read.popitem(last=False)
        return made


def _below(folder: Path, path: str) -> Path:
    """The absolute ``path`` (the client's) at the same place below ``folder``."""
    return folder.joinpath(*Path(path).parts[1:])


def _folder(files: dict[str, bytes]) -> Path:
    """A folder of this process holding ``files``, each at :func:`_below` its path: the
    first whose files at those paths have the same bytes (written now where missing), or a
    new one. A path's bytes never change in a folder, so readers' caches by path stay
    true."""
    digests = {p: hashlib.sha256(b).digest() for p, b in files.items()}
    same = (f for f in _folders if all(f[1].get(p, d) == d for p, d in digests.items()))
    folder, held = next(same, (None, None))
    if folder is None:
        folder, held = Path(tempfile.mkdtemp(prefix="raytrace-files-")), {}
        atexit.register(shutil.rmtree, folder, ignore_errors=True)
        _folders.append((folder, held))
    for path, data in files.items():
        if path not in held:
            target = _below(folder, path)
            target.parent.mkdir(parents=True, exist_ok=True)
            target.write_bytes(data)
            held[path] = digests[path]
    return folder
