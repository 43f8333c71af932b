"""About 300 bad or extreme inputs, each run in its own process the way a user would run it.

Every case is a folder of files (a scene, a mesh, a script) and a command: ``raytrace render``
with flags, or a Python script using the API. Each runs under an 8 GiB address-space limit
(``RLIMIT_AS``) and a 60 s wall-clock limit, and must end in one of two ways (issue #28):

* **rendered**: exit 0 and the output written;
* **refused**: exit 2 (3 where the engine cannot run) with exactly one error line
  (``raytrace: error: …`` from the command line, ``refused: …`` from an API script, which prints
  the one line of the ``ValueError``/``TypeError`` it caught), no output file left behind.

Anything else is a failure: a traceback, a timeout, death by signal or memory, an error of more
than one line, or an input file changed. Warning lines (``raytrace: warning: …``) are allowed.

The cases come from five groups:

* ``value``: each numeric leaf of a small scene that uses every object and light type, set to
  extreme values (±1e308, 1e-308, denormals, NaN, ±inf, huge integers, wrong types);
* ``structure``: tables of the wrong type, unknown types and keys, missing keys, deep nesting;
* ``file``: empty, binary, UTF-16, truncated, folder-for-file and missing files of every kind;
* ``flag``: out-of-range and malformed command-line flags and output collisions;
* ``api``: the Python API misused (edits after construction, wrong types, bad keywords).

    python3 tests/bad_inputs.py                 # every case, 2 at a time; exit 1 on a failure
    python3 tests/bad_inputs.py --group flag -v # one group, each case's verdict and line

``tests/test_bad_inputs.py`` runs a few of each group by default and all of them with
``-m slow``.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import math
import os
import resource
import subprocess
import sys
import tempfile
import time
from collections import Counter
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path

#: Limits each case runs under.
ADDRESS_SPACE_BYTES = 8 * 2**30
WALL_SECONDS = 60.0
#: Verdicts that pass.
GOOD = ("rendered", "refused")


@dataclass(frozen=True)
class Case:
    """A bad input: ``files`` (name → text or bytes) written to a fresh folder, then
    ``argv`` run there (``raytrace …`` or ``python script.py``)."""

    group: str
    name: str
    files: dict = field(default_factory=dict)
    argv: tuple = ()
    #: True where the input is wrong and rendering it anyway is a failure ("accepted").
    refuse: bool = False


# --- the base scene: one of each object and light type, small and fast ---------------------

def base_scene() -> dict:
    return {
        "render": {"width": 16, "height": 12, "max_depth": 3, "spp": 1, "min_weight": 0.0,
                   "background": [0.1, 0.1, 0.2], "seed": 1},
        "camera": {"position": [0.0, 1.0, 6.0], "look_at": [0.0, 0.5, 0.0], "up": [0, 1, 0],
                   "fov": 40.0},
        "ambient": {"color": 0.1},
        "materials": {"shiny": {"base": "brass", "ks": 0.5, "shininess": 40.0, "kr": 0.3},
                      "clear": {"kd": 0.1, "kt": 0.8, "ior": 1.5},
                      "checks": {"kd": {"pattern": "checker", "colors": [0.2, 0.8],
                                        "scale": 0.5}}},
        "lights": [
            {"type": "point", "position": [3.0, 4.0, 3.0], "color": 0.8,
             "attenuation": [1.0, 0.01, 0.001]},
            {"type": "directional", "direction": [-1.0, -1.0, -0.5], "color": 0.3},
            {"type": "spot", "position": [-2.0, 4.0, 2.0], "direction": [0.5, -1.0, -0.5],
             "cutoff": 30.0, "exponent": 4.0, "color": 0.5},
            {"type": "area", "position": [0.0, 5.0, 0.0], "edge_u": [1.0, 0.0, 0.0],
             "edge_v": [0.0, 0.0, 1.0], "samples": 4, "color": 0.5},
        ],
        "objects": [
            {"type": "sphere", "center": [-1.0, 0.5, 0.0], "radius": 0.5, "material": "shiny"},
            {"type": "sphere", "center": [0.3, 0.4, 1.0], "radius": 0.4, "material": "clear"},
            {"type": "plane", "point": [0.0, 0.0, 0.0], "normal": [0.0, 1.0, 0.0],
             "material": "checks"},
            {"type": "disk", "center": [1.2, 0.8, -0.5], "normal": [0.0, 0.0, 1.0],
             "radius": 0.4, "material": "matte_red"},
            {"type": "mesh", "vertices": [[0.0, 0.0, -1.0], [1.0, 0.0, -1.0],
                                          [0.5, 1.0, -1.0]],
             "faces": [[0, 1, 2]], "scale": 1.0, "rotate": [0.0, 10.0, 0.0],
             "translate": [0.5, 0.0, 0.0], "material": "matte_green"},
        ],
    }


def toml_value(v) -> str:
    """A TOML value, inline (tables as inline tables): enough for the scenes built here."""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        if math.isnan(v):
            return "nan"
        if math.isinf(v):
            return "inf" if v > 0 else "-inf"
        return repr(v)
    if isinstance(v, str):
        return json.dumps(v)
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(toml_value(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{" + ", ".join(f"{json.dumps(k)} = {toml_value(x)}" for k, x in v.items()) + "}"
    raise TypeError(type(v))


def toml(scene: dict) -> str:
    return "".join(f"{k} = {toml_value(v)}\n" for k, v in scene.items())


def numeric_leaves(node, path=()):
    """(path, value) of every number in ``node``, in document order."""
    if isinstance(node, dict):
        for k, v in node.items():
            yield from numeric_leaves(v, (*path, k))
    elif isinstance(node, list):
        for i, v in enumerate(node):
            yield from numeric_leaves(v, (*path, i))
    elif isinstance(node, (int, float)) and not isinstance(node, bool):
        yield path, node


def replaced(scene: dict, path: tuple, value) -> dict:
    out = json.loads(json.dumps(scene))
    node = out
    for k in path[:-1]:
        node = node[k]
    node[path[-1]] = value
    return out


#: Extreme values the numeric leaves take in turn (two a leaf, rotating through the list).
EXTREMES = (1e308, -1e308, 1e200, 1e-308, 5e-324, math.nan, math.inf, -math.inf, 0, -1,
            1e18, 2**64, 1e155, -1e-200, "x", [], True, 1e-12)


def render_argv(scene="scene.toml", *flags) -> tuple:
    return ("raytrace", "render", scene, "-o", "out.exr", "--threads", "2", *flags)


def value_cases() -> list[Case]:
    base, cases = base_scene(), []
    for i, (path, _) in enumerate(numeric_leaves(base)):
        for j in range(2):
            v = EXTREMES[(5 * i + j) % len(EXTREMES)]
            key = ".".join(str(p) for p in path)
            cases.append(Case("value", f"{key}={toml_value(v)}",
                              {"scene.toml": toml(replaced(base, path, v))}, render_argv()))
    return cases


def structure_cases() -> list[Case]:
    base = base_scene()
    edits = {
        "camera=3": ("camera", 3), "render=list": ("render", [1, 2]),
        "objects=table": ("objects", {"a": 1}), "lights=string": ("lights", "sun"),
        "materials=list": ("materials", [1]), "ambient=string": ("ambient", "x"),
        "object=number": ("objects", [1]), "light=number": ("lights", [1]),
        "object-type=cube": ("objects", [{"type": "cube", "size": 1}]),
        "light-type=laser": ("lights", [{"type": "laser"}]),
        "sphere-no-radius": ("objects", [{"type": "sphere", "center": [0, 0, 0]}]),
        "mesh-no-faces": ("objects", [{"type": "mesh", "vertices": [[0, 0, 0]] * 3}]),
        "mesh-face-out-of-range": ("objects", [{"type": "mesh", "vertices": [[0, 0, 0]] * 3,
                                                "faces": [[0, 1, 7]]}]),
        "mesh-negative-face": ("objects", [{"type": "mesh", "vertices": [[0, 0, 0]] * 3,
                                            "faces": [[0, -1, 2]]}]),
        "mesh-ragged-vertices": ("objects", [{"type": "mesh", "vertices": [[0, 0], [1]],
                                              "faces": [[0, 1, 2]]}]),
        "mesh-float-faces": ("objects", [{"type": "mesh", "vertices": [[0, 0, 0]] * 3,
                                          "faces": [[0.5, 1, 2]]}]),
        "mesh-file-and-vertices": ("objects", [{"type": "mesh", "file": "m.obj",
                                                "vertices": [[0, 0, 0]] * 3,
                                                "faces": [[0, 1, 2]]}]),
        "material-cycle": ("materials", {"a": {"base": "b"}, "b": {"base": "a"}}),
        "material-self-base": ("materials", {"a": {"base": "a"}}),
        "material-unknown-base": ("materials", {"a": {"base": "unobtainium"}}),
        "material-unknown-key": ("materials", {"a": {"roughness": 0.5}}),
        "pattern-unknown": ("materials", {"a": {"kd": {"pattern": "stripes"}}}),
        "pattern-one-colour": ("materials", {"a": {"kd": {"pattern": "checker",
                                                          "colors": [0.5]}}}),
        "texture-missing": ("materials", {"a": {"kd": {"texture": "nope.png"}}}),
        "unknown-top-key": ("shadows", True),
        "area-samples-10": ("lights", [{"type": "area", "position": [0, 5, 0],
                                        "edge_u": [1, 0, 0], "edge_v": [0, 0, 1],
                                        "samples": 10}]),
        "area-parallel-edges": ("lights", [{"type": "area", "position": [0, 5, 0],
                                            "edge_u": [1, 0, 0], "edge_v": [2, 0, 0]}]),
        "area-samples-huge": ("lights", [{"type": "area", "position": [0, 5, 0],
                                          "edge_u": [1, 0, 0], "edge_v": [0, 0, 1],
                                          "samples": 2**40}]),
        "up-parallel": ("camera", {"position": [0, 0, 5], "look_at": [0, 0, 0],
                                   "up": [0, 0, 1]}),
        "look-at-position": ("camera", {"position": [1, 2, 3], "look_at": [1, 2, 3]}),
        "zero-normal": ("objects", [{"type": "plane", "point": [0, 0, 0],
                                     "normal": [0, 0, 0]}]),
        "huge-normal": ("objects", [{"type": "plane", "point": [0, 0, 0],
                                     "normal": [1e308, 1e308, 0]}]),
        "tiny-normal": ("objects", [{"type": "plane", "point": [0, 0, 0],
                                     "normal": [5e-324, 0, 0]}]),
        "huge-direction": ("lights", [{"type": "directional",
                                       "direction": [1e308, -1e308, 0]}]),
        "vector-of-two": ("camera", {"position": [0, 0], "look_at": [0, 0, 0]}),
        "vector-of-strings": ("camera", {"position": ["a", "b", "c"]}),
        "no-objects": ("objects", []),
        "no-lights": ("lights", []),
        "million-lights": ("lights", [{"type": "point", "position": [0, 5, 0]}] * 3000),
    }
    cases = [Case("structure", name, {"scene.toml": toml(replaced(base, (k,), v))},
                  render_argv())
             for name, (k, v) in edits.items()]
    deep = "[" * 100_000 + "]" * 100_000
    cases += [
        Case("structure", "json-deep-list", {"scene.json": '{"objects": ' + deep + "}"},
             render_argv("scene.json")),
        Case("structure", "json-deep-table", {"scene.json": '{"a":' * 100_000 + "1" +
                                              "}" * 100_000}, render_argv("scene.json")),
        Case("structure", "toml-deep", {"scene.toml": "a = " + "[" * 5000 + "]" * 5000 + "\n"},
             render_argv()),
        Case("structure", "json-nan", {"scene.json": '{"ambient": {"color": NaN}}'},
             render_argv("scene.json")),
        Case("structure", "json-top-list", {"scene.json": "[1, 2, 3]"},
             render_argv("scene.json")),
        Case("structure", "toml-duplicate-key", {"scene.toml": "[camera]\nfov = 40\nfov = 50\n"},
             render_argv()),
        Case("structure", "toml-syntax", {"scene.toml": "[camera\nfov = 40\n"}, render_argv()),
    ]
    return cases


OBJ = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 2 3\nf 1 3 4\n"


def mesh_scene(file: str, material: str = "matte_white") -> str:
    scene = base_scene()
    scene["objects"] = [{"type": "mesh", "file": file, "material": material}]
    return toml(scene)


def file_cases() -> list[Case]:
    garbage = bytes(range(256)) * 8
    scene_text = toml(base_scene())
    cases = [
        Case("file", "scene-empty", {"scene.toml": ""}, render_argv()),
        Case("file", "scene-binary", {"scene.toml": garbage}, render_argv()),
        Case("file", "scene-utf16", {"scene.toml": scene_text.encode("utf-16")}, render_argv()),
        Case("file", "scene-latin1", {"scene.toml": "# café\n".encode("latin-1") +
                                      scene_text.encode()}, render_argv()),
        Case("file", "scene-truncated", {"scene.toml": scene_text[:len(scene_text) // 2]},
             render_argv()),
        Case("file", "scene-missing", {}, render_argv("nope.toml")),
        Case("file", "scene-folder", {"dir/x.txt": "x"}, render_argv("dir")),
        Case("file", "scene-is-obj", {"m.obj": OBJ}, render_argv("m.obj")),
        Case("file", "scene-is-ply-garbage", {"m.ply": garbage}, render_argv("m.ply")),
        Case("file", "scene-json-garbage", {"scene.json": garbage}, render_argv("scene.json")),
        Case("file", "scene-null-bytes", {"scene.toml": b"\0" * 100}, render_argv()),
    ]
    meshes = {
        "mesh-missing": {},
        "mesh-folder": {"m.obj/x": "x"},
        "mesh-empty": {"m.obj": ""},
        "mesh-binary": {"m.obj": garbage},
        "mesh-truncated-face": {"m.obj": "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2"},
        "mesh-index-out-of-range": {"m.obj": "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n"},
        "mesh-nan-vertex": {"m.obj": "v nan 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"},
        "mesh-huge-vertex": {"m.obj": "v 1e300 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"},
        "mesh-degenerate": {"m.obj": "v 0 0 0\nv 0 0 0\nv 0 0 0\nf 1 2 3\n"},
        "mesh-no-faces": {"m.obj": "v 0 0 0\nv 1 0 0\n"},
        "mtl-missing": {"m.obj": "mtllib nope.mtl\n" + OBJ},
        "mtl-binary": {"m.obj": "mtllib m.mtl\nusemtl a\n" + OBJ, "m.mtl": garbage},
        "mtl-kd-nan": {"m.obj": "mtllib m.mtl\nusemtl a\n" + OBJ,
                       "m.mtl": "newmtl a\nKd nan 0 0\n"},
        "mtl-kd-huge": {"m.obj": "mtllib m.mtl\nusemtl a\n" + OBJ,
                        "m.mtl": "newmtl a\nKd 1e308 1 1\nNs 1e308\n"},
        "mtl-ni-zero": {"m.obj": "mtllib m.mtl\nusemtl a\n" + OBJ,
                        "m.mtl": "newmtl a\nd 0.5\nNi 0\n"},
        "mtl-texture-missing": {"m.obj": "mtllib m.mtl\nusemtl a\nvt 0 0\n" + OBJ,
                                "m.mtl": "newmtl a\nmap_Kd nope.png\n"},
        "mtl-texture-garbage": {"m.obj": "mtllib m.mtl\nusemtl a\nvt 0 0\n" + OBJ,
                                "m.mtl": "newmtl a\nmap_Kd t.png\n", "t.png": garbage},
        "ply-garbage": {"m.ply": b"ply\nformat binary_little_endian 1.0\n" + garbage},
        "ply-index-out-of-range": {"m.ply": "ply\nformat ascii 1.0\nelement vertex 3\n"
                                   "property float x\nproperty float y\nproperty float z\n"
                                   "element face 1\nproperty list uchar int vertex_indices\n"
                                   "end_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 9\n"},
        "stl-truncated": {"m.stl": b"\0" * 80 + (1000).to_bytes(4, "little") + b"\0" * 50},
        "gltf-truncated": {"m.gltf": '{"asset": {"version": "2.0"}, "meshes": [{"primitives":'},
        "glb-garbage": {"m.glb": b"glTF" + garbage},
        "gltf-buffer-missing": {"m.gltf": json.dumps({
            "asset": {"version": "2.0"}, "buffers": [{"uri": "nope.bin", "byteLength": 36}],
            "bufferViews": [{"buffer": 0, "byteLength": 36}],
            "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3,
                           "type": "VEC3", "min": [0, 0, 0], "max": [1, 1, 0]}],
            "meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]}],
            "nodes": [{"mesh": 0}], "scenes": [{"nodes": [0]}], "scene": 0})},
        "gltf-node-cycle": {"m.gltf": json.dumps({
            "asset": {"version": "2.0"}, "nodes": [{"children": [1]}, {"children": [0]}],
            "scenes": [{"nodes": [0]}], "scene": 0})},
    }
    for name, files in meshes.items():
        mesh = next((f for f in files if not f.endswith((".mtl", ".png", "/x"))),
                    next(iter(files), "m.obj").split("/")[0])
        material = "from_file" if name.startswith("mtl") else "matte_white"
        cases.append(Case("file", name, {**files, "scene.toml": mesh_scene(mesh, material)},
                          render_argv()))
    cases += [Case("file", f"direct-{name}", files, render_argv(next(iter(files))))
              for name, files in meshes.items()
              if files and name in ("mesh-binary", "mesh-truncated-face", "ply-garbage",
                                    "gltf-truncated", "glb-garbage", "gltf-node-cycle")]
    return cases


def flag_cases() -> list[Case]:
    scene = {"scene.toml": toml(base_scene())}
    flags = {
        "width-0": ["--width", "0"], "width-negative": ["--width", "-5"],
        "width-huge": ["--width", "1000000000"], "width-text": ["--width", "abc"],
        "width-float": ["--width", "1.5"], "width-nan": ["--width", "nan"],
        "height-huge": ["--height", "99999999999999999999"],
        "spp-0": ["--spp", "0"], "spp-huge": ["--spp", "100000000"],
        "depth-negative": ["--max-depth", "-1"], "depth-huge": ["--max-depth", "1000000000"],
        "min-weight-nan": ["--min-weight", "nan"], "min-weight-inf": ["--min-weight", "inf"],
        "seed-negative": ["--seed", "-1"], "seed-huge": ["--seed", str(2**70)],
        "threads-0": ["--threads", "0"], "threads-huge": ["--threads", "100000"],
        "threads-negative": ["--threads", "-3"],
        "crop-inverted": ["--crop", "10", "10", "5", "5"],
        "crop-outside": ["--crop", "0", "0", "1000", "1000"],
        "crop-three": ["--crop", "0", "0", "4"],
        "tile-0": ["--tile", "0"], "tile-huge": ["--tile", "1000000000"],
        "aov-unknown": ["--aov", "shadows"], "aov-empty": ["--aov", ""],
        "filter-unknown": ["--filter", "lanczos"], "aa-unknown": ["--aa", "msaa"],
        "aa-threshold-nan": ["--aa", "adaptive", "--aa-threshold", "nan"],
        "aa-depth-huge": ["--aa", "adaptive", "--aa-depth", "64"],
        "exposure-nan": ["--png", "p.png", "--exposure", "nan"],
        "exposure-huge": ["--png", "p.png", "--exposure", "1e308"],
        "exposure-text": ["--png", "p.png", "--exposure", "bright"],
        "tonemap-unknown": ["--png", "p.png", "--tonemap", "aces"],
        "png-bits-7": ["--png", "p.png", "--png-bits", "7"],
        "compression-unknown": ["--compression", "lzma"],
        "unknown-flag": ["--turbo"],
        "workers-and-scheduler": ["--workers", "2", "--scheduler", "tcp://127.0.0.1:1"],
        "workers-0": ["--workers", "0"],
        "frames-bad-range": ["--frames", "5-1"], "frames-missing-file": ["--frames", "nope.py:f"],
        "pixel-on-render": ["--pixel", "1", "1"],
    }
    cases = [Case("flag", name, scene, render_argv("scene.toml", *f)) for name, f in
             flags.items()]
    collisions = {
        "out-is-scene": ("raytrace", "render", "scene.toml", "-o", "scene.toml"),
        "png-is-out": (*render_argv(), "--png", "out.exr"),
        "png-is-scene": (*render_argv(), "--png", "scene.toml"),
        "stats-is-out": (*render_argv(), "--stats", "out.exr"),
        "out-in-missing-folder": ("raytrace", "render", "scene.toml", "-o", "no/such/out.exr"),
        "out-is-folder": ("raytrace", "render", "scene.toml", "-o", "."),
        "out-wrong-suffix": ("raytrace", "render", "scene.toml", "-o", "out.jpg"),
        "out-is-material": ("raytrace", "render", "scene.toml", "-o", "m.toml"),
    }
    cases += [Case("flag", name, {**scene, "m.toml": "kd = 0.5\n"}, argv)
              for name, argv in collisions.items()]
    frames = "def scene_at(n):\n    raise RuntimeError('the script broke')\n"
    seq = ("-o", "out.%04d.exr", "--frames", "1..3")
    cases += [
        Case("flag", "frames-function-raises", {"f.py": frames},
             ("raytrace", "render", "f.py:scene_at", *seq)),
        Case("flag", "frames-function-returns-none", {"f.py": "def scene_at(n):\n    pass\n"},
             ("raytrace", "render", "f.py:scene_at", *seq)),
        Case("flag", "frames-script-syntax", {"f.py": "def scene_at(:\n"},
             ("raytrace", "render", "f.py:scene_at", *seq)),
        Case("flag", "frames-script-raises", {"f.py": "import no_such_module\n"},
             ("raytrace", "render", "f.py:scene_at", *seq)),
        Case("flag", "frames-function-missing", {"f.py": "x = 1\n"},
             ("raytrace", "render", "f.py:scene_at", *seq)),
        Case("flag", "frames-pattern-missing-frame",
             {"s_0001.toml": toml(base_scene()), "s_0003.toml": toml(base_scene())},
             ("raytrace", "render", "s_####.toml", *seq)),
        Case("flag", "explain-outside", scene,
             ("raytrace", "explain", "scene.toml", "--pixel", "100", "100")),
        Case("flag", "explain-negative", scene,
             ("raytrace", "explain", "scene.toml", "--pixel", "-1", "0")),
        Case("flag", "compare-missing", {}, ("raytrace", "compare", "a.exr", "b.exr")),
        Case("flag", "compare-garbage", {"a.exr": b"\x76\x2f\x31\x01" + b"\0" * 64,
                                         "b.exr": b"garbage"},
             ("raytrace", "compare", "a.exr", "b.exr")),
        Case("flag", "compare-threshold-nan", {}, ("raytrace", "compare", "a.exr", "a.exr",
                                                   "--threshold", "nan")),
    ]
    return cases


API_PROLOGUE = """\
import sys
import warnings
warnings.formatwarning = lambda message, *_, **__: f'raytrace: warning: {{message}}\\n'
import numpy as np
import raytrace
from raytrace import Scene, Sphere, Plane, Mesh, PointLight, Camera
scene = raytrace.Scene(camera=Camera(position=[0, 0, 5], look_at=[0, 0, 0]),
                       objects=[Sphere(center=[0, 0, 0], radius=1.0, material="brass")],
                       lights=[PointLight(position=[3, 3, 3])])
try:
{body}
except (ValueError, TypeError, OSError) as e:
    lines = str(e).splitlines() or ['']
    print('refused:', *lines, sep='\\n' if len(lines) > 1 else ' ', file=sys.stderr)
    sys.exit(2)
"""

API_BODIES = {
    "string-material-appended": "scene.objects.append(Sphere(center=[1, 0, 0], radius=0.5, "
                                "material='emerald'))\nimg = raytrace.render(scene, width=8, "
                                "height=6)",
    "number-appended": "scene.objects.append(3)\nraytrace.render(scene, width=8, height=6)",
    "light-appended-to-objects": "scene.objects.append(PointLight(position=[0, 1, 0]))\n"
                                 "raytrace.render(scene, width=8, height=6)",
    "lights-none": "scene.lights = None\nraytrace.render(scene, width=8, height=6)",
    "objects-none": "scene.objects = None\nraytrace.render(scene, width=8, height=6)",
    "center-string": "scene.objects[0].center = 'x'\nraytrace.render(scene, width=8, height=6)",
    "radius-negative": "scene.objects[0].radius = -1\nraytrace.render(scene, width=8, height=6)",
    "radius-nan": "scene.objects[0].radius = float('nan')\n"
                  "raytrace.render(scene, width=8, height=6)",
    "radius-huge": "scene.objects[0].radius = 1e300\nraytrace.render(scene, width=8, height=6)",
    "camera-position-huge": "scene.camera.position = np.array([1e200, 0, 5.0])\n"
                            "raytrace.render(scene, width=8, height=6)",
    "camera-none": "scene.camera = None\nraytrace.render(scene, width=8, height=6)",
    "mesh-nan-edit": "m = Mesh(vertices=[[0, 0, -1], [1, 0, -1], [0, 1, -1]], "
                     "faces=[[0, 1, 2]])\nscene.objects.append(m)\nscene.resolve_materials()\n"
                     "m.vertices[0, 0] = np.nan\nraytrace.render(scene, width=8, height=6)",
    "light-position-nan": "scene.lights[0].position = np.array([np.nan, 0, 0])\n"
                          "raytrace.render(scene, width=8, height=6)",
    "pass-samples-0": "raytrace.render(scene, width=8, height=6, pass_samples=0)",
    "threads-0": "raytrace.render(scene, width=8, height=6, threads=0)",
    "width-float": "raytrace.render(scene, width=8.5, height=6)",
    "width-string": "raytrace.render(scene, width='8', height=6)",
    "spp-huge": "raytrace.render(scene, width=8, height=6, spp=10**9)",
    "crop-bad": "raytrace.render(scene, width=8, height=6, crop=(5, 5, 1, 1))",
    "aovs-unknown": "raytrace.render(scene, width=8, height=6, aovs='shadows')",
    "progress-not-callable": "raytrace.render(scene, width=8, height=6, progress=3)",
    "explain-string-pixel": "raytrace.explain(scene, 'a')",
    "explain-outside": "raytrace.explain(scene, (100, 100), width=8, height=6)",
    "from-exr-corrupt": "open('bad.exr', 'wb').write(b'\\x76\\x2f\\x31\\x01' + bytes(64))\n"
                        "raytrace.Image.from_exr('bad.exr')",
    "from-exr-missing": "raytrace.Image.from_exr('nope.exr')",
    "scene-from-dict-deep": "x = []\nfor _ in range(100000):\n    x = [x]\n"
                            "raytrace.scene_from_dict({'objects': x})",
    "scene-from-dict-list": "raytrace.scene_from_dict([1, 2])",
    "material-unknown": "Sphere(center=[0, 0, 0], radius=1, material='unobtainium')\n"
                        "scene.objects.append(Sphere(center=[0, 0, 0], radius=1, "
                        "material='unobtainium'))\nscene.resolve_materials()",
    "save-bad-suffix": "raytrace.render(scene, width=8, height=6).save('a.txt')",
    "save-into-missing-folder": "raytrace.render(scene, width=8, height=6).save('x/a.exr')",
    "save-exposure-nan": "raytrace.render(scene, width=8, height=6).save('a.png', "
                         "exposure=float('nan'))",
}


#: API misuses that must be refused, not rendered (the rest may do either: a material named
#: after construction, say, is resolved at render as at construction).
API_REFUSED = {"number-appended", "light-appended-to-objects", "lights-none", "objects-none",
               "center-string", "radius-negative", "radius-nan", "radius-huge",
               "camera-position-huge", "camera-none", "mesh-nan-edit", "light-position-nan",
               "pass-samples-0", "save-bad-suffix", "save-exposure-nan"}


def api_cases() -> list[Case]:
    return [Case("api", name, {"script.py": API_PROLOGUE.format(
        body="\n".join("    " + line for line in body.splitlines()))},
        (sys.executable, "script.py"), refuse=name in API_REFUSED)
        for name, body in API_BODIES.items()]


GROUPS = {"value": value_cases, "structure": structure_cases, "file": file_cases,
          "flag": flag_cases, "api": api_cases}


def cases(groups=None) -> list[Case]:
    return [c for g, make in GROUPS.items() if groups is None or g in groups for c in make()]


# --- running a case ------------------------------------------------------------------------

@dataclass
class Outcome:
    case: Case
    verdict: str
    status: int | None
    seconds: float
    line: str


def _limits() -> None:
    resource.setrlimit(resource.RLIMIT_AS, (ADDRESS_SPACE_BYTES, ADDRESS_SPACE_BYTES))
    os.setsid()


def _digest(folder: Path) -> dict:
    return {p.relative_to(folder).as_posix(): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(folder.rglob("*")) if p.is_file()}


def run(case: Case) -> Outcome:
    """Run ``case`` in a fresh folder under the limits; its :class:`Outcome`."""
    with tempfile.TemporaryDirectory(prefix="raytrace-bad-") as tmp:
        folder = Path(tmp)
        for name, data in case.files.items():
            path = folder / name
            path.parent.mkdir(parents=True, exist_ok=True)
            (path.write_bytes if isinstance(data, bytes) else path.write_text)(data)
        before = _digest(folder)
        argv = list(case.argv)
        if argv[0] == "raytrace":
            argv = [sys.executable, "-m", "raytrace", *argv[1:]]
        env = {**os.environ, "PYTHONUNBUFFERED": "1"}
        start = time.perf_counter()
        try:
            done = subprocess.run(argv, cwd=folder, env=env, capture_output=True, text=True,
                                  errors="replace", timeout=WALL_SECONDS,
                                  preexec_fn=_limits)
        except subprocess.TimeoutExpired:
            return Outcome(case, "timeout", None, time.perf_counter() - start, "")
        seconds = time.perf_counter() - start
        after = _digest(folder)
    errors = [ln for ln in done.stderr.splitlines()
              if ln.strip() and not ln.startswith("raytrace: warning:")]
    line = errors[0] if errors else ""
    changed = [k for k in before if after.get(k) != before[k]]
    new = sorted(set(after) - set(before))
    if "Traceback (most recent call last)" in done.stderr:
        verdict = "traceback"
        line = next((ln for ln in reversed(errors) if ln and not ln.startswith(" ")), line)
    elif done.returncode < 0 or done.returncode in (137, 139) or "MemoryError" in done.stderr:
        verdict = "killed"
    elif changed:
        verdict, line = "input-changed", f"changed: {', '.join(changed)}"
    elif done.returncode == 0:
        verdict = "accepted" if case.refuse else ("rendered" if new or case.group == "api"
                                                  else "no-output")
    elif done.returncode in (2, 3) and len(errors) == 1 and (
            line.startswith(("raytrace: error:", "raytrace render: error:", "refused: "))):
        verdict = "refused" if not [n for n in new if n not in ("bad.exr",)] else "left-output"
    else:
        verdict = "unclear"
    return Outcome(case, verdict, done.returncode, seconds, line)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--group", action="append", choices=sorted(GROUPS))
    parser.add_argument("--jobs", type=int, default=2)
    parser.add_argument("-v", "--verbose", action="store_true", help="every case's verdict")
    parser.add_argument("--json", type=Path, help="write each case's outcome here")
    args = parser.parse_args(argv)
    todo = cases(args.group)
    start = time.perf_counter()
    with ThreadPoolExecutor(args.jobs) as pool:
        outcomes = list(pool.map(run, todo))
    wall = time.perf_counter() - start
    by_group = Counter((o.case.group, o.verdict) for o in outcomes)
    verdicts = sorted({v for _, v in by_group})
    print(f"{'group':<10}" + "".join(f"{v:>14}" for v in verdicts) + f"{'cases':>8}")
    for g in GROUPS:
        n = sum(c for (gg, _), c in by_group.items() if gg == g)
        if n:
            print(f"{g:<10}" + "".join(f"{by_group[g, v]:>14}" for v in verdicts) + f"{n:>8}")
    bad = [o for o in outcomes if o.verdict not in GOOD]
    for o in outcomes if args.verbose else bad:
        print(f"{o.verdict:>13} {o.case.group}/{o.case.name} "
              f"[{o.status}, {o.seconds:.1f} s]: {o.line[:200]}")
    slowest = max(outcomes, key=lambda o: o.seconds)
    print(f"{len(outcomes)} cases in {wall:.0f} s, {len(bad)} failed; slowest "
          f"{slowest.case.group}/{slowest.case.name} {slowest.seconds:.1f} s; load "
          f"{os.getloadavg()[0]:.2f}")
    if args.json:
        args.json.write_text(json.dumps([{"group": o.case.group, "name": o.case.name,
                                          "verdict": o.verdict, "status": o.status,
                                          "seconds": round(o.seconds, 2), "line": o.line}
                                         for o in outcomes], indent=1))
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
