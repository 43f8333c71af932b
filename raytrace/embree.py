"""Embree 4, called directly: the library the embreex wheel ships, driven through ctypes for
set-up and by address from the compiled kernels for traversal (:mod:`raytrace.kernels.embree`).

embreex stays the dependency that brings Embree (``embreex.libs/libembree4-<hash>.so.4`` on
Linux, ``embreex/.dylibs`` on macOS, ``embreex.libs`` on Windows), but its Python API is not
used: it copies meshes element by element under the GIL and traces one ray at a time
(EMBREEX_NOTES.md). Here:

* **geometry is shared**: each mesh's float32 vertices and uint32 faces are numpy arrays that
  Embree reads in place (``rtcSetSharedGeometryBuffer``); the :class:`Meshes` object that
  made the scene owns them for as long as Embree can read them;
* **the device follows the thread count** (``rtcNewDevice("threads=N")``, BVH builds
  included), one device per count, kept for the process; Embree's TBB sizes its pool to the
  largest count of the live devices, so after a render on more threads a build may use those;
* **errors and memory reach the user**: Embree's error function and memory monitor are set on
  every device; an error or an allocation beyond the memory available ends the build with one
  :class:`raytrace.errors.EngineError` line, and the BVH's bytes are counted
  (:attr:`Meshes.bytes`);
* **safety first**: traversal calls do no checks, so a wrong struct layout would crash the
  process. Before the first scene, the library's version must be one this module was checked
  against (:data:`CHECKED_VERSIONS`), and a known ray is traced through each entry point the
  kernels use to see that Embree writes where :mod:`raytrace.kernels.embree` reads
  (:func:`probe`). Either failure is one line naming the embreex release that works.

Struct layouts and the facts measured on embreex 4.4.0.post1: EMBREEX_NOTES.md, last section.
"""

from __future__ import annotations

import ctypes
import importlib.metadata
import importlib.util
import os
import sys
import threading
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import psutil

from .errors import EngineError
from .kernels import embree as ek  # the traversal kernels, which the probe checks
from .kernels.records import EmbreeHits, EmbreeRays, EmbreeScene

#: Embree releases whose struct layouts and calls this module was checked against
#: (``rtcGetDeviceProperty(device, RTC_DEVICE_PROPERTY_VERSION)``: 4.4.0 is 40400).
CHECKED_VERSIONS = range(40400, 40500)
#: The embreex release that ships such an Embree (pyproject.toml pins its range).
WORKING_EMBREEX = "embreex 4.4.0.post1 (pip install 'embreex>=4.4,<4.5')"

# Embree's enum values (rtcore_device.h, rtcore_scene.h, rtcore_geometry.h, rtcore_buffer.h,
# rtcore_common.h at 4.4.0).
DEVICE_PROPERTY_VERSION = 0
NATIVE_RAY_SUPPORTED = {4: 32, 8: 33, 16: 34}  # RTC_DEVICE_PROPERTY_NATIVE_RAY{4,8,16}_SUPPORTED
SCENE_FLAG_ROBUST = 1 << 2
GEOMETRY_TYPE_TRIANGLE = 0
BUFFER_TYPE_INDEX, BUFFER_TYPE_VERTEX = 0, 1
FORMAT_UINT3, FORMAT_FLOAT3 = 0x5003, 0x9003
QUERY_FLAG_COHERENT = 1 << 16
FEATURE_FLAG_ALL = 0xFFFFFFFF
ERROR_NAMES = {1: "unknown error", 2: "invalid argument", 3: "invalid operation",
               4: "out of memory", 5: "unsupported CPU", 6: "cancelled", 7: "level zero error"}

_void = ctypes.c_void_p
#: (name, result type, argument types) of every call made through ctypes.
_SIGNATURES = (
    ("rtcNewDevice", _void, [ctypes.c_char_p]),
    ("rtcGetDeviceProperty", ctypes.c_ssize_t, [_void, ctypes.c_int]),
    ("rtcGetDeviceError", ctypes.c_int, [_void]),
    ("rtcSetDeviceErrorFunction", None, [_void, _void, _void]),
    ("rtcSetDeviceMemoryMonitorFunction", None, [_void, _void, _void]),
    ("rtcNewScene", _void, [_void]),
    ("rtcSetSceneFlags", None, [_void, ctypes.c_int]),
    ("rtcCommitScene", None, [_void]),
    ("rtcReleaseScene", None, [_void]),
    ("rtcNewGeometry", _void, [_void, ctypes.c_int]),
    ("rtcSetSharedGeometryBuffer", None, [_void, ctypes.c_int, ctypes.c_uint, ctypes.c_int,
                                          _void, ctypes.c_size_t, ctypes.c_size_t,
                                          ctypes.c_size_t]),
    ("rtcCommitGeometry", None, [_void]),
    ("rtcAttachGeometry", ctypes.c_uint, [_void, _void]),
    ("rtcReleaseGeometry", None, [_void]),
    ("rtcIntersect1", None, [_void, _void, _void]),
)
#: The traversal entry points the kernels call by address, per packet width.
TRAVERSAL = ("rtcIntersect{n}", "rtcOccluded{n}")

_ErrorFunction = ctypes.CFUNCTYPE(None, _void, ctypes.c_int, ctypes.c_char_p)
_MemoryMonitor = ctypes.CFUNCTYPE(ctypes.c_bool, _void, ctypes.c_ssize_t, ctypes.c_bool)


def library_path() -> Path:
    """The Embree 4 library inside the installed embreex wheel (found without importing
    embreex's extension modules)."""
    spec = importlib.util.find_spec("embreex")
    if spec is None or not spec.submodule_search_locations:
        raise EngineError(f"embreex is not installed: raytrace needs {WORKING_EMBREEX}")
    package = Path(next(iter(spec.submodule_search_locations)))
    patterns = {"linux": ["embreex.libs/libembree4*.so*", "embreex/libembree4*.so*"],
                "darwin": ["embreex/.dylibs/libembree4*.dylib", "embreex/libembree4*.dylib"],
                "win32": ["embreex.libs/embree4*.dll", "embreex/embree4*.dll"]}
    for pattern in patterns.get(sys.platform, patterns["linux"]):
        found = sorted(package.parent.glob(pattern))
        if found:
            return found[0]
    raise EngineError(f"the Embree library is missing from embreex at {package}: raytrace "
                      f"needs {WORKING_EMBREEX}")


def embreex_version() -> str:
    """The installed embreex's version (the cache key and the error lines name it)."""
    try:
        return importlib.metadata.version("embreex")
    except importlib.metadata.PackageNotFoundError:
        return "not installed"


@dataclass
class Device:
    """One Embree device (``threads`` worker threads for builds) and what its callbacks saw."""

    handle: int
    threads: int
    error: str | None = None  # the first error Embree reported since it was last read
    bytes: int = 0            # what Embree holds now, every scene of this device together
    limit: int | None = None  # refuse a build's allocations beyond this (the memory available)
    build_start: int = 0      # ``bytes`` when the current build started
    #: One build at a time on a device: its error, limit and byte count are the build's.
    lock: threading.Lock = field(default_factory=threading.Lock)

    def take_error(self) -> str | None:
        error, self.error = self.error, None
        return error


class Library:
    """The Embree library: loaded once, checked (:func:`check_version`, :func:`probe`), with
    its devices and the addresses of its traversal calls."""

    def __init__(self, path: Path):
        self.path = path
        try:
            if sys.platform == "win32":  # the wheel's DLLs (Embree's TBB) beside it
                os.add_dll_directory(str(path.parent))
            self.lib = ctypes.CDLL(str(path))
            for name, result, arguments in _SIGNATURES:
                f = getattr(self.lib, name)
                f.restype, f.argtypes = result, arguments
        except (OSError, AttributeError) as e:  # not loadable, or not the calls we make
            raise EngineError(f"the Embree library of embreex {embreex_version()} cannot be "
                              f"used ({e}): install {WORKING_EMBREEX}") from None
        self._devices: dict[int, Device] = {}  # by thread count
        self._handles: dict[int, Device] = {}  # by handle, for the callbacks
        self._lock = threading.Lock()
        # ctypes callbacks must outlive every device that may call them
        self._on_error = _ErrorFunction(self._error)
        self._on_memory = _MemoryMonitor(self._memory)
        first = self.device(1)
        self.version = int(self.lib.rtcGetDeviceProperty(first.handle, DEVICE_PROPERTY_VERSION))
        check_version(self.version)
        #: The packet width the kernels use: the widest the CPU runs natively (16 with
        #: AVX-512, 8 with AVX2, else 4).
        self.width = next((n for n in (16, 8, 4) if self.lib.rtcGetDeviceProperty(
            first.handle, NATIVE_RAY_SUPPORTED[n])), 4)
        self.addresses = {name.format(n=n): ctypes.cast(getattr(self.lib, name.format(n=n)),
                                                        _void).value
                          for name in TRAVERSAL for n in (4, 8, 16)}
        probe(self)

    def device(self, threads: int) -> Device:
        """The device with ``threads`` build threads (made once, kept for the process)."""
        with self._lock:
            device = self._devices.get(threads)
            if device is None:
                handle = self.lib.rtcNewDevice(f"threads={threads},set_affinity=0".encode())
                if not handle:
                    raise EngineError(f"Embree could not start a device ({self.path.name})")
                device = Device(handle, threads)
                self._handles[handle] = device
                self._devices[threads] = device
                self.lib.rtcSetDeviceErrorFunction(handle, ctypes.cast(self._on_error, _void),
                                                   _void(handle))
                self.lib.rtcSetDeviceMemoryMonitorFunction(
                    handle, ctypes.cast(self._on_memory, _void), _void(handle))
            return device

    def _error(self, handle: int | None, code: int, message: bytes | None) -> None:
        device = self._handles.get(handle or 0)
        if device is not None and device.error is None:
            text = message.decode("utf-8", "replace") if message else ""
            device.error = f"{ERROR_NAMES.get(code, f'error {code}')}" + (
                f" ({text})" if text else "")

    def _memory(self, handle: int | None, change: int, post: bool) -> bool:
        device = self._handles.get(handle or 0)
        if device is None:
            return True
        if (change > 0 and device.limit is not None
                and device.bytes - device.build_start + change > device.limit):
            return False  # Embree reports RTC_ERROR_OUT_OF_MEMORY and ends the build
        device.bytes += change
        return True

    def check(self, device: Device, doing: str) -> None:
        """Raise the error Embree reported on ``device`` while ``doing``, as one line."""
        code = self.lib.rtcGetDeviceError(device.handle)  # read (and so reset) in any case
        error = device.take_error() or (ERROR_NAMES.get(code, f"error {code}") if code else None)
        if error:
            raise EngineError(f"Embree {format_version(self.version)} failed {doing}: {error}")

    def traversal(self) -> tuple[int, int]:
        """Addresses of the intersect and occluded calls of this library's packet width."""
        return (self.addresses[f"rtcIntersect{self.width}"],
                self.addresses[f"rtcOccluded{self.width}"])


def format_version(version: int) -> str:
    return f"{version // 10000}.{version // 100 % 100}.{version % 100}"


def check_version(version: int) -> None:
    """Refuse a library whose struct layouts were not checked (:data:`CHECKED_VERSIONS`)."""
    if version not in CHECKED_VERSIONS:
        raise EngineError(
            f"embreex {embreex_version()} ships Embree {format_version(version)}, but raytrace "
            f"calls Embree {format_version(CHECKED_VERSIONS.start)} directly and was checked "
            f"against that only: install {WORKING_EMBREEX}")


_library: Library | None = None
_library_lock = threading.Lock()


def library() -> Library:
    """The process's :class:`Library`, loaded and checked on first use."""
    global _library
    with _library_lock:
        if _library is None:
            _library = Library(library_path())
        return _library


def arguments(coherent: bool) -> np.ndarray:
    """An ``RTCIntersectArguments`` (= ``RTCOccludedArguments``, 32 bytes): the query flags
    (COHERENT or none), every feature, and NULL context, filter and intersect callbacks, as
    ``rtcInitIntersectArguments`` sets them."""
    args = np.zeros(8, np.uint32)
    args[0] = QUERY_FLAG_COHERENT if coherent else 0
    args[1] = FEATURE_FLAG_ALL
    return args


class Meshes:
    """An Embree scene of triangle meshes, robust flag as embreex's, each mesh a geometry
    whose geomID is its place in ``meshes`` (attach order), sharing float32 vertex and uint32
    index arrays with Embree, and committed (the BVH built) on ``threads`` threads.

    The record the kernels take is :attr:`record` (:class:`raytrace.kernels.records.EmbreeScene`);
    this object must outlive every call made with it (it owns the arrays and the scene)."""

    def __init__(self, meshes: list[tuple[np.ndarray, np.ndarray]], threads: int = 1):
        lib = self.library = library()
        self.device = lib.device(max(1, int(threads)))
        self.handle = None
        self._arrays: list[np.ndarray] = []
        with self.device.lock:  # one build at a time on a device
            device = self.device
            device.take_error()  # an earlier operation's error is not this build's
            lib.lib.rtcGetDeviceError(device.handle)
            device.build_start, device.limit = device.bytes, available_bytes()
            try:
                self._build(meshes)
            except BaseException:
                self.close()
                raise
            finally:
                device.limit = None
            #: What the BVH and Embree's copies of the scene hold, bytes (its memory monitor).
            self.bytes = device.bytes - device.build_start
        intersect, occluded = lib.traversal()
        self._coherent, self._incoherent = arguments(True), arguments(False)
        self.record = EmbreeScene(self.handle, intersect, occluded, lib.width,
                                  self._coherent.ctypes.data, self._incoherent.ctypes.data)

    def _build(self, meshes: list[tuple[np.ndarray, np.ndarray]]) -> None:
        """Make the scene, attach the meshes over arrays of their own, commit (the BVH)."""
        lib, api = self.library, self.library.lib
        self.handle = api.rtcNewScene(self.device.handle)
        lib.check(self.device, "making a scene")
        api.rtcSetSceneFlags(self.handle, SCENE_FLAG_ROBUST)
        for vertices, faces in meshes:
            n = len(vertices)
            # one more row: Embree reads 16 bytes for the last vertex's 12
            v = np.zeros((n + 1, 3), np.float32)
            v[:n] = vertices
            f = np.ascontiguousarray(faces, np.uint32)
            self._arrays += [v, f]
            geometry = api.rtcNewGeometry(self.device.handle, GEOMETRY_TYPE_TRIANGLE)
            api.rtcSetSharedGeometryBuffer(geometry, BUFFER_TYPE_VERTEX, 0, FORMAT_FLOAT3,
                                           v.ctypes.data, 0, 12, n)
            api.rtcSetSharedGeometryBuffer(geometry, BUFFER_TYPE_INDEX, 0, FORMAT_UINT3,
                                           f.ctypes.data, 0, 12, len(f))
            api.rtcCommitGeometry(geometry)
            api.rtcAttachGeometry(self.handle, geometry)
            api.rtcReleaseGeometry(geometry)
            lib.check(self.device, "attaching a mesh")
        api.rtcCommitScene(self.handle)  # the BVH build, on the device's threads
        lib.check(self.device, "building the BVH")

    def close(self) -> None:
        """Release Embree's scene (idempotent); the record is no more."""
        if getattr(self, "handle", None):
            self.library.lib.rtcReleaseScene(self.handle)
            self.handle = None
            self.record = None

    def __del__(self):
        self.close()


def available_bytes() -> int | None:
    """Memory this machine can give now (psutil's ``available``), or None where unknown."""
    try:
        return int(psutil.virtual_memory().available)
    except (OSError, NotImplementedError, AttributeError):
        return None


def probe(lib: Library) -> None:
    """Trace a known ray through every entry point the kernels use and check that Embree
    wrote where :mod:`raytrace.kernels.embree` reads: a ray straight down onto the triangle
    (0,0,0), (1,0,0), (0,1,0) at (0.25, 0.5) from height 1 must report t, u, v ≈ 1, 0.25,
    0.5 (to 1e-6), primID 0, geomID 0 and the normal +z through ``rtcIntersect1``, the same hit
    through each packet width's closest-hit kernel, and "blocked" through its occlusion
    kernel. A mismatch means another layout: one line, before any render's traversal."""
    scene = _ProbeScene(lib)
    origin = np.array([[0.25, 0.5, 1.0]], np.float32)
    direction = np.array([[0.0, 0.0, -1.0]], np.float32)
    single = np.zeros(ek.RAYHIT1_WORDS, np.float32)
    words = single.view(np.int32)
    single[ek.ORG:ek.ORG + 3], single[ek.DIR:ek.DIR + 3] = origin[0], direction[0]
    single[ek.TFAR], words[ek.MASK], words[ek.GEOM_ID], words[ek.INST_ID] = np.inf, -1, -1, -1
    lib.lib.rtcIntersect1(scene.handle, single.ctypes.data, None)
    ok = (near(single[ek.TFAR], 1.0) and near(single[ek.U], 0.25) and near(single[ek.V], 0.5)
          and words[ek.PRIM_ID] == 0 and words[ek.GEOM_ID] == 0 and single[ek.NG + 2] > 0)
    for width in (4, 8, 16):
        record = EmbreeScene(scene.handle, lib.addresses[f"rtcIntersect{width}"],
                             lib.addresses[f"rtcOccluded{width}"], width,
                             scene.coherent.ctypes.data, scene.coherent.ctypes.data)
        hits = EmbreeHits(np.empty(1, np.int32), np.empty(1, np.int32),
                          np.empty(1, np.float32), np.empty(1, np.float32))
        ek.closest_hits(record, EmbreeRays(origin, direction, np.full(1, np.inf, np.float32)),
                        np.array([0, 1]), hits)  # one COHERENT packet of the ray
        blocked = np.empty(1, np.int32)
        ek.any_hits(record, EmbreeRays(origin, direction, np.full(1, np.inf, np.float32)),
                    True, blocked)
        ok = (ok and (hits.geom_id[0], hits.prim_id[0], blocked[0]) == (0, 0, ek.BLOCKED)
              and near(hits.u[0], 0.25) and near(hits.v[0], 0.5))
    if not ok:
        raise EngineError(f"Embree {format_version(lib.version)} from embreex "
                          f"{embreex_version()} did not answer a known ray as raytrace reads "
                          f"its results (another struct layout): install {WORKING_EMBREEX}")


def near(value: float, expected: float) -> bool:
    """Whether a float32 result is ``expected`` to a few float32 ulps."""
    return abs(float(value) - expected) <= 1e-6


class _ProbeScene:
    """One triangle, (0,0,0), (1,0,0), (0,1,0), for :func:`probe`."""

    def __init__(self, lib: Library):
        api, device = lib.lib, lib.device(1)
        self.vertices = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 0]], np.float32)
        self.faces = np.array([[0, 1, 2]], np.uint32)
        self.coherent = arguments(True)
        self.api = api
        self.handle = api.rtcNewScene(device.handle)
        api.rtcSetSceneFlags(self.handle, SCENE_FLAG_ROBUST)
        g = api.rtcNewGeometry(device.handle, GEOMETRY_TYPE_TRIANGLE)
        api.rtcSetSharedGeometryBuffer(g, BUFFER_TYPE_VERTEX, 0, FORMAT_FLOAT3,
                                       self.vertices.ctypes.data, 0, 12, 3)
        api.rtcSetSharedGeometryBuffer(g, BUFFER_TYPE_INDEX, 0, FORMAT_UINT3,
                                       self.faces.ctypes.data, 0, 12, 1)
        api.rtcCommitGeometry(g)
        api.rtcAttachGeometry(self.handle, g)
        api.rtcReleaseGeometry(g)
        api.rtcCommitScene(self.handle)
        lib.check(device, "building the probe scene")

    def __del__(self):
        self.api.rtcReleaseScene(self.handle)
