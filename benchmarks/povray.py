"""POV-Ray 3.7 as a peer: write a raytrace :class:`~raytrace.Scene` as a ``.pov`` file, render
it with ``povray`` and read back POV-Ray's own timings.

Functions
---------
- :func:`scene_to_pov` / :func:`write_pov`: the POV-Ray equivalent of a scene.
- :func:`run_povray`: render a ``.pov`` file without antialiasing (one ray per pixel centre,
  like ``spp = 1``), measuring wall time and peak memory of the process.
- :func:`parse_times`, :func:`parse_counts`: POV-Ray's "Render Statistics" and timing lines.
- :func:`measure_process`: run a command, return its wall time and peak resident memory.

What maps exactly and what only approximately (the workload is the same; pixel values are not
meant to match):

* Camera: POV-Ray's ``angle`` is the *horizontal* field of view, so the vertical ``fov`` of
  raytrace becomes ``2·atan(tan(fov/2)·W/H)``. raytrace's world is right-handed and POV-Ray's
  is left-handed: ``right -x·W/H`` (the POV-Ray manual's recipe for right-handed scenes) keeps
  every coordinate as it is.
* Spheres, planes (``n·x = n·p``) and triangle meshes (``mesh2``; ``smooth``/``gouraud``
  meshes carry the same vertex normals as raytrace's smooth shading, Gouraud is rendered as
  smooth) are exact geometry.
* Materials: pigment = kd (a ``checker`` pigment for a checker), ``diffuse 1``,
  ``ambient`` = ka/kd with ``ambient_light`` = the scene's ambient colour, ``phong ks
  phong_size n`` for the Phong highlight, ``specular ks roughness 1/n`` for Blinn's (POV-Ray's
  ``specular`` is Blinn's (N·H)^(1/roughness)), ``reflection kr``, ``transmit`` = mean kt with
  ``interior { ior }``. POV-Ray scales diffuse light by the pigment's non-transmitted share
  and takes one scalar for highlight and transmission: colours in ks/kt are averaged.
* Point lights: POV-Ray attenuates by ``2/(1 + (d/fade_distance)^fade_power)``. That equals
  raytrace's ``1/(a0 + a1·d + a2·d²)`` up to a colour scale ``1/(2·a0)`` when only one of a1,
  a2 is non-zero (``fade_power`` 1 or 2, ``fade_distance = a0/a1`` or ``√(a0/a2)``); with both
  non-zero the linear term is dropped, and with a0 = 0 it is matched only far from the light.
  These are approximations: POV-Ray has no exact counterpart of the general quadratic.
* Spot lights become ``spotlight`` with ``radius = falloff = cutoff`` and ``tightness =
  exponent`` (POV-Ray's cone profile differs); directional lights become ``parallel`` lights;
  area lights ``area_light`` with the same k×k grid (``jitter`` when asked).
* Recursion: ``max_trace_level = max_depth + 1`` (POV-Ray counts the camera ray as level 1),
  ``adc_bailout = min_weight``.
"""

from __future__ import annotations

import io
import math
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from raytrace.accel import vertex_normals
from raytrace.material import Checker, Material
from raytrace.scene import (
    AreaLight,
    Camera,
    DirectionalLight,
    Mesh,
    Plane,
    PointLight,
    Scene,
    Sphere,
    SpotLight,
)

POVRAY = "povray"
#: Distance of the stand-in position of a directional (``parallel``) light.
PARALLEL_DISTANCE = 1e5


# -- formatting -------------------------------------------------------------------------------
def vec(v) -> str:
    """``<x, y, z>`` with enough digits to round-trip float64 to ~1e-9 relative."""
    x, y, z = (float(c) for c in np.asarray(v, dtype=np.float64).reshape(3))
    return f"<{x:.10g}, {y:.10g}, {z:.10g}>"


def rgb(c) -> str:
    """``rgb <r, g, b>`` of a colour (3,)."""
    return f"rgb {vec(c)}"


# -- camera -----------------------------------------------------------------------------------
def horizontal_angle(fov: float, width: int, height: int) -> float:
    """POV-Ray's horizontal ``angle`` (degrees) for a vertical ``fov``: 2·atan(tan(fov/2)·W/H).

    >>> round(horizontal_angle(90.0, 100, 100), 9)
    90.0
    """
    return math.degrees(2.0 * math.atan(math.tan(math.radians(fov) / 2.0) * width / height))


def camera_block(camera: Camera, width: int, height: int) -> str:
    """A perspective camera; ``right -x`` keeps raytrace's right-handed coordinates."""
    aspect = width / height
    return (f"camera {{\n  perspective\n  location {vec(camera.position)}\n"
            f"  right <{-aspect:.10g}, 0, 0>\n  up <0, 1, 0>\n  sky {vec(camera.up)}\n"
            f"  angle {horizontal_angle(camera.fov, width, height):.10g}\n"
            f"  look_at {vec(camera.look_at)}\n}}\n")


# -- materials --------------------------------------------------------------------------------
def _mean(c) -> float:
    if isinstance(c, Checker):
        return float(np.mean([np.mean(x) for x in c.colors]))
    return float(np.mean(c))


def pigment_block(m: Material) -> str:
    """kd as the pigment (a POV-Ray ``checker`` for a checker), with ``transmit`` for kt and
    opacity: the share ``t·kt + (1 − t)`` that passes through."""
    transmit = m.opacity * _mean(m.kt) + (1.0 - m.opacity)
    tr = f" transmit {transmit:.10g}" if transmit > 0 else ""
    if isinstance(m.kd, Checker):
        a, b = m.kd.colors
        return (f"pigment {{ checker color {rgb(a)}{tr} color {rgb(b)}{tr} "
                f"scale {m.kd.scale:.10g} }}")
    return f"pigment {{ color {rgb(m.kd)}{tr} }}"


def _same_checker(a, b) -> bool:
    return (isinstance(a, Checker) and isinstance(b, Checker) and a.scale == b.scale
            and all(np.array_equal(x, y) for x, y in zip(a.colors, b.colors, strict=True)))


def _ambient(m: Material) -> str:
    """POV-Ray multiplies ``ambient`` by the pigment (kd): ka/kd per channel, 1 where ka
    follows kd, and ka itself (an approximation) where kd is 0 or a pattern differs."""
    ka, kd = m.ambient, m.kd
    if ka is kd or _same_checker(ka, kd):
        return "1"
    if isinstance(ka, Checker) or isinstance(kd, Checker):
        return f"{_mean(ka) / max(_mean(kd), 1e-12):.10g}"
    ratio = np.where(kd > 0, ka / np.where(kd > 0, kd, 1.0), ka)
    return rgb(ratio)


def finish_block(m: Material) -> str:
    """Ambient, diffuse, highlight and mirror reflection of a material."""
    parts = [f"ambient {_ambient(m)}", "diffuse 1"]
    ks = _mean(m.ks)
    if ks > 0:
        if m.highlight == "blinn":
            rough = 1.0 / max(m.shininess, 1e-6)
            parts.append(f"specular {ks:.10g} roughness {min(rough, 1.0):.10g}")
        else:
            parts.append(f"phong {ks:.10g} phong_size {m.shininess:.10g}")
    if m.reflects:
        kr = m.kr.max if isinstance(m.kr, Checker) else m.kr
        parts.append(f"reflection {{ {rgb(kr)} }}")
    return "finish { " + " ".join(parts) + " }"


def material_block(m: Material) -> str:
    """``pigment``, ``finish`` and, for transparent materials, ``interior { ior }``."""
    out = f"  {pigment_block(m)}\n  {finish_block(m)}\n"
    if m.transmits:
        out += f"  interior {{ ior {m.ior:.10g} }}\n"
    return out


# -- lights -----------------------------------------------------------------------------------
def fade(attenuation) -> tuple[float, str]:
    """Colour scale and POV-Ray ``fade_distance``/``fade_power`` text for raytrace's
    ``1/(a0 + a1·d + a2·d²)``; exact when a0 > 0 and at most one of a1, a2 is non-zero.

    >>> fade([1.0, 0.0, 0.0])
    (1.0, '')
    >>> fade([2.0, 0.0, 0.5])  # 1/(2 + d²/2) = (1/4)·2/(1 + (d/2)²)
    (0.25, ' fade_distance 2 fade_power 2')
    """
    a0, a1, a2 = (float(x) for x in attenuation)
    if a1 == 0 and a2 == 0:
        return 1.0 / a0, ""
    power = 2 if a2 > 0 else 1
    ap = a2 if power == 2 else a1
    if a0 > 0:
        distance = (a0 / ap) ** (1.0 / power)
        scale = 1.0 / (2.0 * a0)
    else:  # 1/(ap·d^p) ≈ 2·D^p/d^p for d ≫ D
        distance = (1.0 / (2.0 * ap)) ** (1.0 / power)
        scale = 1.0
    return scale, f" fade_distance {distance:.10g} fade_power {power}"


def light_block(light) -> str:
    """One ``light_source``."""
    if isinstance(light, DirectionalLight):
        d = np.asarray(light.direction, float)
        d = d / np.linalg.norm(d)
        return (f"light_source {{ {vec(-d * PARALLEL_DISTANCE)} color {rgb(light.color)}\n"
                f"  parallel point_at <0, 0, 0> }}\n")
    scale, fd = fade(light.attenuation)
    color = rgb(np.asarray(light.color) * scale)
    if isinstance(light, SpotLight):
        target = np.asarray(light.position) + np.asarray(light.direction)
        return (f"light_source {{ {vec(light.position)} color {color}{fd}\n"
                f"  spotlight radius {light.cutoff:.10g} falloff {light.cutoff:.10g} "
                f"tightness {light.exponent:.10g} point_at {vec(target)} }}\n")
    if isinstance(light, AreaLight):
        k = math.isqrt(light.samples)
        jitter = " jitter" if light.jitter else ""
        return (f"light_source {{ {vec(light.position)} color {color}{fd}\n"
                f"  area_light {vec(light.edge_u)}, {vec(light.edge_v)}, {k}, {k}{jitter} }}\n")
    assert isinstance(light, PointLight)
    return f"light_source {{ {vec(light.position)} color {color}{fd} }}\n"


# -- objects ----------------------------------------------------------------------------------
def _rows(fmt: str, a: np.ndarray) -> str:
    buf = io.StringIO()
    np.savetxt(buf, a, fmt=fmt, delimiter=", ", newline=",\n")
    return buf.getvalue().rstrip(",\n") + "\n"


def mesh2_block(mesh: Mesh) -> str:
    """A ``mesh2`` with the mesh's vertices and faces (and vertex normals unless flat)."""
    v, f = np.asarray(mesh.vertices, np.float64), np.asarray(mesh.faces, np.int64)
    out = [f"mesh2 {{\n  vertex_vectors {{ {len(v)},\n", _rows("<%.10g, %.10g, %.10g>", v),
           "  }\n"]
    if mesh.shading != "flat":
        n = vertex_normals(v, f)
        if np.all(np.linalg.norm(n, axis=1) > 0.5):  # POV-Ray needs a normal at every vertex
            out += [f"  normal_vectors {{ {len(n)},\n", _rows("<%.10g, %.10g, %.10g>", n),
                    "  }\n"]
    out += [f"  face_indices {{ {len(f)},\n", _rows("<%d, %d, %d>", f), "  }\n"]
    return "".join(out)


def object_block(obj) -> str:
    """A sphere, plane or mesh2 with its material."""
    mat = material_block(obj.material)
    if isinstance(obj, Sphere):
        return f"sphere {{ {vec(obj.center)}, {float(obj.radius):.10g}\n{mat}}}\n"
    if isinstance(obj, Plane):
        n = np.asarray(obj.normal, float)
        return f"plane {{ {vec(n)}, {float(n @ np.asarray(obj.point, float)):.10g}\n{mat}}}\n"
    if isinstance(obj, Mesh):
        return mesh2_block(obj) + mat + "}\n"
    raise TypeError(f"cannot write {type(obj).__name__} for POV-Ray")


def scene_to_pov(scene: Scene, width: int, height: int, max_depth: int | None = None,
                 min_weight: float | None = None) -> str:
    """The whole ``.pov`` text of ``scene`` rendered at ``width``×``height``."""
    r = scene.render
    depth = r.max_depth if max_depth is None else max_depth
    bailout = r.min_weight if min_weight is None else min_weight
    head = (f"// Written by benchmarks/povray.py from {scene.path or '<python>'}\n"
            "#version 3.7;\n"
            f"global_settings {{\n  assumed_gamma 1.0\n  max_trace_level {depth + 1}\n"
            f"  adc_bailout {bailout:.10g}\n  ambient_light {rgb(scene.ambient)}\n}}\n"
            f"background {{ color {rgb(r.background)} }}\n")
    parts = [head, camera_block(scene.camera, width, height)]
    parts += [light_block(light) for light in scene.lights]
    parts += [object_block(o) for o in scene.objects]
    return "".join(parts)


def write_pov(scene: Scene, path: str | os.PathLike, width: int, height: int,
              max_depth: int | None = None, min_weight: float | None = None) -> Path:
    """Write :func:`scene_to_pov` to ``path``; returns the path."""
    path = Path(path)
    path.write_text(scene_to_pov(scene, width, height, max_depth, min_weight))
    return path


# -- running ----------------------------------------------------------------------------------
def _vm_hwm_kib(pid: int) -> int | None:
    """The process's peak resident set (VmHWM, KiB) so far, or None once it is gone."""
    try:
        with open(f"/proc/{pid}/status") as f:
            for line in f:
                if line.startswith("VmHWM:"):
                    return int(line.split()[1])
    except (OSError, ValueError):
        pass
    return None


def measure_process(cmd: list[str], cwd: str | os.PathLike | None = None,
                    timeout: float | None = None, poll: float = 0.001) -> dict:
    """Run ``cmd``; return ``returncode``, ``wall_seconds``, ``peak_rss_mib``, ``stdout`` and
    ``stderr``.

    The peak is the child's ``VmHWM`` from ``/proc/PID/status``, read every ``poll`` seconds
    until it exits (it only grows, so the last reading is the peak up to the last ``poll``).
    ``wait4``'s ``ru_maxrss`` would be wrong here: Linux carries the parent's high-water mark
    across fork/vfork and exec, so every child would report at least this process's size.
    """
    peak = 0
    with tempfile.TemporaryFile() as fo, tempfile.TemporaryFile() as fe:
        t0 = time.perf_counter()
        proc = subprocess.Popen(cmd, cwd=cwd, stdout=fo, stderr=fe, stdin=subprocess.DEVNULL)
        deadline = None if timeout is None else t0 + timeout
        while True:
            pid, status = os.waitpid(proc.pid, os.WNOHANG)
            if pid:
                break
            peak = max(peak, _vm_hwm_kib(proc.pid) or 0)
            if deadline is not None and time.perf_counter() > deadline:
                proc.kill()
                pid, status = os.waitpid(proc.pid, 0)
                break
            time.sleep(poll)
        wall = time.perf_counter() - t0
        proc.returncode = os.waitstatus_to_exitcode(status)
        fo.seek(0)
        fe.seek(0)
        stdout, stderr = fo.read().decode(errors="replace"), fe.read().decode(errors="replace")
    return {"returncode": proc.returncode, "wall_seconds": wall, "peak_rss_mib": peak / 1024.0,
            "stdout": stdout, "stderr": stderr}


_TIME = re.compile(r"(Parse|Bounding|Photon|Radiosity|Trace) Time:.*?\(\s*([\d.]+) seconds\)")
_COUNTS = {"rays": r"^Rays:\s+(\d+)", "shadow_tests": r"Shadow Ray Tests:\s+(\d+)",
           "reflected": r"Reflected Rays:\s+(\d+)", "refracted": r"Refracted Rays:\s+(\d+)"}


def parse_times(text: str) -> dict:
    """Seconds per phase from POV-Ray's output, e.g. ``{"parse": 0.1, "trace": 2.3}``.

    >>> parse_times("  Trace Time:  0 hours  0 minutes  1 seconds (1.234 seconds)")
    {'trace': 1.234}
    """
    return {m.group(1).lower(): float(m.group(2)) for m in _TIME.finditer(text)}


def parse_counts(text: str) -> dict:
    """POV-Ray's ray counters (its own definitions: "Rays" counts camera and secondary rays,
    not shadow tests)."""
    out = {}
    for key, pattern in _COUNTS.items():
        m = re.search(pattern, text, re.MULTILINE)
        if m:
            out[key] = int(m.group(1))
    return out


def available() -> bool:
    return shutil.which(POVRAY) is not None


def version() -> str | None:
    """POV-Ray's version line, or None when it is not installed."""
    if not available():
        return None
    p = subprocess.run([POVRAY, "--version"], capture_output=True, text=True, timeout=30)
    m = re.search(r"POV-Ray \S+", p.stdout + p.stderr)
    return m.group(0) if m else None


def run_povray(pov: str | os.PathLike, width: int, height: int, threads: int,
               output: str | os.PathLike | None = None, timeout: float | None = None) -> dict:
    """Render ``pov`` to an EXR (``+FE``) with no antialiasing (``-A``), no display, on
    ``threads`` threads; returns :func:`measure_process`'s fields plus ``seconds`` (POV-Ray's
    own phase times) and ``counts``. POV-Ray runs in the file's folder (its default I/O
    restrictions allow writing there)."""
    pov = Path(pov).resolve()
    out = Path(output).resolve() if output else pov.with_suffix(".exr")
    cmd = [POVRAY, f"+I{pov.name}", f"+O{out.name}", f"+W{width}", f"+H{height}", "-D", "-A",
           "-P", "+FE", f"+WT{threads}", "-GR"]
    res = measure_process(cmd, cwd=pov.parent, timeout=timeout)
    text = res["stdout"] + res["stderr"]
    res["seconds"] = parse_times(text)
    res["counts"] = parse_counts(text)
    res["command"] = " ".join(cmd)
    res["output"] = str(out)
    if out.parent != pov.parent:
        shutil.move(str(pov.parent / out.name), out)
    log = res.pop("stdout") + res.pop("stderr")
    res["log_tail"] = log[-2000:] if res["returncode"] else ""
    return res


def main(argv: list[str] | None = None) -> int:
    import argparse

    from raytrace import load_scene

    p = argparse.ArgumentParser(description="Write a raytrace scene as POV-Ray 3.7 and render it.")
    p.add_argument("scene")
    p.add_argument("-o", "--output", help=".pov file (default: SCENE's name with .pov)")
    p.add_argument("--width", type=int)
    p.add_argument("--height", type=int)
    p.add_argument("--threads", type=int, default=os.cpu_count() or 1)
    p.add_argument("--render", action="store_true", help="also run povray and print its times")
    a = p.parse_args(argv)
    scene = load_scene(a.scene)
    w, h = a.width or scene.render.width, a.height or scene.render.height
    pov = write_pov(scene, a.output or Path(a.scene).with_suffix(".pov").name, w, h)
    print(pov)
    if a.render:
        res = run_povray(pov, w, h, a.threads)
        print({k: v for k, v in res.items() if k != "log_tail"})
        return res["returncode"]
    return 0


if __name__ == "__main__":
    sys.exit(main())
