"""The files an input names (raytrace/readers/inputs.py): a folder given where a file is
expected is reported as a folder wherever the path comes from (a scene file, a model, a mesh,
an MTL library, a texture, a frames function's Python file, an EXR to compare), and a scene
file that is not UTF-8 says so, naming the encoding its byte-order mark gives. Each through the
command line: status 2, one exact line."""

from __future__ import annotations

import os

import numpy as np
import pytest
from helpers import write_gltf, write_png, write_text

from raytrace import cli
from raytrace.readers.gltf import load_gltf
from raytrace.readers.inputs import recording

CAMERA = "[camera]\nposition = [0, 0, 5]\nlook_at = [0, 0, 0]\n"
TRIANGLE = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"


def run(tmp_path, monkeypatch, capsys, args: list[str]) -> tuple[int, str]:
    monkeypatch.chdir(tmp_path)
    rc = cli.main(args)
    return rc, capsys.readouterr().err


def scene_with(tmp_path, body: str) -> None:
    write_text(tmp_path / "s.toml", CAMERA + body)


#: name: (files to write besides the folders d, d.obj, d.py and d.exr; the command; the one
#: line expected)
FOLDERS = {
    "scene file": ({}, ["render", "d"], "d: is a folder, not a scene file"),
    "model file": ({}, ["render", "d.obj"], "d.obj: is a folder, not a model file"),
    "mesh file": ({"s.toml": CAMERA + '[[objects]]\ntype = "mesh"\nfile = "d"\n'},
                  ["render", "s.toml"], "s.toml: objects[0].file: is a folder, not a mesh file: d"),
    "texture": ({"s.toml": CAMERA + '[[objects]]\ntype = "sphere"\ncenter = [0, 0, 0]\n'
                 'radius = 1\nmaterial = { kd = { texture = "d" } }\n'}, ["render", "s.toml"],
                "s.toml: objects[0].material.kd.texture: is a folder, not a texture file: d"),
    "MTL file": ({"m.obj": "mtllib d\n" + TRIANGLE}, ["render", "m.obj"],
                 "d: mtllib: is a folder, not an MTL file"),
    "MTL texture": ({"m.obj": "mtllib m.mtl\nusemtl a\n" + TRIANGLE,
                     "m.mtl": "newmtl a\nmap_Kd d\n"}, ["render", "m.obj"],
                    "m.mtl: material 'a': map_Kd: is a folder, not a texture file: d"),
    "frames file": ({}, ["render", "d.py:f", "--frames", "1"],
                    "SCENE: is a folder, not a Python file: d.py"),
    "EXR to compare": ({}, ["compare", "d.exr", "d.exr"], "d.exr: is a folder, not an EXR file"),
}


@pytest.mark.parametrize("case", list(FOLDERS))
def test_a_folder_where_a_file_is_expected_is_named_a_folder(tmp_path, monkeypatch, capsys,
                                                              case):
    files, args, line = FOLDERS[case]
    for folder in ("d", "d.obj", "d.py", "d.exr"):
        (tmp_path / folder).mkdir()
    for name, text in files.items():
        write_text(tmp_path / name, text)
    rc, err = run(tmp_path, monkeypatch, capsys, args)
    assert (rc, err) == (2, f"raytrace: error: {line}\n")


SCENE = CAMERA + '[[objects]]\ntype = "sphere"\ncenter = [0, 0, 0]\nradius = 1\n'


@pytest.mark.parametrize(("encode", "line"), [
    (lambda t: t.encode("utf-16"), "is UTF-16 text (its byte-order mark says so): a scene file "
                                   "must be UTF-8 text"),
    (lambda t: t.encode("utf-32"), "is UTF-32 text (its byte-order mark says so): a scene file "
                                   "must be UTF-8 text"),
    (lambda t: t.encode("utf-16-be"), "byte 0x00 on line 1 is not text (UTF-16 or UTF-32 text "
                                      "without a byte-order mark, or a binary file): a scene "
                                      "file must be UTF-8 text"),
    (lambda t: t.replace("sphere", "sph\xe8re").encode("latin-1"),
     "byte 0xe8 on line 5 is not UTF-8 (Latin-1 or another encoding?): a scene file must be "
     "UTF-8 text"),
], ids=["utf-16", "utf-32", "utf-16 without a BOM", "latin-1"])
def test_a_scene_file_that_is_not_utf8_says_so(tmp_path, monkeypatch, capsys, encode, line):
    (tmp_path / "s.toml").write_bytes(encode(SCENE))
    rc, err = run(tmp_path, monkeypatch, capsys, ["render", "s.toml"])
    assert (rc, err) == (2, f"raytrace: error: s.toml: {line}\n")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s.toml"]


def test_a_utf8_byte_order_mark_is_read_as_utf8(tmp_path):
    import raytrace

    (tmp_path / "s.toml").write_bytes(SCENE.encode("utf-8-sig"))
    assert raytrace.load_scene(tmp_path / "s.toml").objects[0].radius == 1.0


def test_the_doctests():
    import doctest

    from raytrace.readers import inputs

    assert doctest.testmod(inputs).failed == 0


def test_recording_lists_every_file_read_even_from_a_cached_gltf(tmp_path):
    # A .gltf naming its buffer and image files: the reader opens three files; the second
    # load comes from load_gltf's cache, and must list the same three (what a cluster's
    # workers are sent: raytrace/readers/bundle.py).
    square = {"positions": [[0, 0, 0], [1, 0, 0], [0, 1, 0]], "indices": [[0, 1, 2]],
              "uv": [[0, 0], [1, 0], [0, 1]], "material": 0}
    mat = [{"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}]
    path = write_gltf(tmp_path / "m.gltf", [{"mesh": 0}], [square], mat, extra={
        "textures": [{"source": 0}], "images": [{"uri": "t.png"}]}, buffer_file="m.bin")
    write_png(tmp_path / "t.png", np.zeros((2, 2, 3), np.uint8))
    want = [str(tmp_path / n) for n in ("m.gltf", "m.bin", "t.png")]
    for _ in range(2):
        with recording() as reads, recording() as inner:
            load_gltf(path)
        assert [r.path for r in reads] == [r.path for r in inner] == want
        assert [r.size for r in reads] == [os.path.getsize(p) for p in want]
