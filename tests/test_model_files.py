"""docs/model_files.md stays true: every row of its glTF-extension, MTL and OBJ tables, and
the glTF-core rows with a file below, is re-run through raytrace on a tiny file, and the
state the row gives (read, warned, silent, refused) and the message it quotes are checked
against what raytrace does and says. The readers' own lists (``gltf.SUPPORTED``,
``gltf.NEUTRAL``, ``gltf.COMPRESSED``, ``mtl.IGNORED``, the statements ``mtl`` reads) must
each have their row, so a feature added to the code without its row fails too."""

from __future__ import annotations

import base64
import io
import json
import re
import warnings
from pathlib import Path

import numpy as np
import pytest
from helpers import write_gltf
from PIL import Image

import raytrace
from raytrace.errors import SceneError
from raytrace.readers import gltf, mtl

PAGE = Path(__file__).resolve().parent.parent / "docs" / "model_files.md"
STATES = ("read", "warned", "silent", "refused")
#: The square |x|, |y| ≤ 1 in z = 0, one matte material (tests/test_gltf.py's).
SQUARE = {"positions": [[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]],
          "indices": [[0, 1, 2], [0, 2, 3]], "uv": [[0, 1], [1, 1], [1, 0], [0, 0]],
          "material": 0}
MATTE = [{"pbrMetallicRoughness": {"baseColorFactor": [0.8, 0.4, 0.2, 1.0],
                                   "metallicFactor": 0.0, "roughnessFactor": 1.0}}]


def rows(section: str) -> list[tuple[str, str, str]]:
    """The rows of the table under ``## section``: (first cell, state, third cell)."""
    text = PAGE.read_text(encoding="utf-8").split(f"\n## {section}\n", 1)[1]
    out = []
    for line in text.split("\n## ", 1)[0].splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) == 3 and cells[1] in STATES:
            out.append((cells[0], cells[1], cells[2]))
    return out


def table(section: str) -> list[tuple[list[str], str, str]]:
    """The rows of the table under ``## section``, each first cell as the names it
    backticks (or its text where it has none)."""
    return [(re.findall(r"`([^`]+)`", first) or [first], state, how)
            for first, state, how in rows(section)]


def quoted(cell: str) -> list[str]:
    """The messages a row quotes (its backticked spans that name a file)."""
    return [q for q in re.findall(r"`([^`]+)`", cell) if re.match(r"\w+\.(gltf|mtl|obj): ", q)]


def run(load) -> tuple[str | None, list[str]]:
    """(the SceneError's line or None, the warning lines) of ``load()``."""
    with warnings.catch_warnings(record=True) as notes:
        warnings.simplefilter("always")
        try:
            load()
            error = None
        except SceneError as e:
            error = str(e)
    return error, [str(n.message) for n in notes]


def gltf_file(mutate=None) -> Path:
    """t.gltf in the working folder: the square, changed by ``mutate(doc)``."""
    path = write_gltf(Path("t.gltf"), [{"mesh": 0}], [dict(SQUARE)],
                      json.loads(json.dumps(MATTE)))
    doc = json.loads(path.read_text())
    if mutate is not None:
        mutate(doc)
    path.write_text(json.dumps(doc))
    return path


def mesh(path: Path):
    return lambda: raytrace.Mesh(file=path, material="from_file")


# -- glTF extensions ---------------------------------------------------------------------
EXTENSIONS = [(names[0], state, how) for names, state, how in table("glTF extensions")
              if names[0].startswith(("KHR_", "EXT_", "MSFT_"))]


def test_every_extension_the_readers_know_has_its_row():
    rows = {name: state for name, state, _ in EXTENSIONS}
    assert {n: rows.get(n) for n in gltf.SUPPORTED} == dict.fromkeys(gltf.SUPPORTED, "read")
    assert {n: rows.get(n) for n in gltf.NEUTRAL} == dict.fromkeys(gltf.NEUTRAL, "silent")
    assert {n: rows.get(n) for n in gltf.COMPRESSED} == dict.fromkeys(gltf.COMPRESSED,
                                                                      "refused")


@pytest.mark.parametrize(("name", "state", "how"), EXTENSIONS, ids=[e[0] for e in EXTENSIONS])
def test_each_extension_row_is_what_raytrace_does(tmp_path, monkeypatch, name, state, how):
    """Used: a warning line naming it where the row says warned (or refused: only used, a
    compressed file is warned about); required: an error naming it unless read, the row's
    quoted line exactly for a refused one."""
    monkeypatch.chdir(tmp_path)
    error, notes = run(mesh(gltf_file(lambda d: d.update(extensionsUsed=[name]))))
    assert error is None
    warned = [n for n in notes if name in n]
    if state in ("warned", "refused"):
        assert warned == [f"t.gltf: extensions that change the look, drawn without them: "
                          f"{name}"]
    else:
        assert warned == []
    error, _ = run(mesh(gltf_file(lambda d: d.update(extensionsUsed=[name],
                                                     extensionsRequired=[name]))))
    if state == "read":
        assert error is None
    elif state == "refused":
        assert error in quoted(how) and name in error
    else:
        assert error == ("t.gltf: extensionsRequired: requires extensions raytrace cannot "
                         f"read: {name}")


def test_a_compressed_primitive_without_fallback_data_is_refused_as_the_page_says(
        tmp_path, monkeypatch):
    """A Draco primitive whose accessors have no buffer view (nothing uncompressed to draw),
    its extension only in ``extensionsUsed``: the Draco line naming the primitive."""
    monkeypatch.chdir(tmp_path)

    def draco(doc):
        doc["extensionsUsed"] = ["KHR_draco_mesh_compression"]
        for a in doc["accessors"]:
            a.pop("bufferView")
        doc["meshes"][0]["primitives"][0]["extensions"] = {"KHR_draco_mesh_compression": {
            "bufferView": 0, "attributes": {"POSITION": 0}}}

    error, _ = run(mesh(gltf_file(draco)))
    how = dict((e[0], e[2]) for e in EXTENSIONS)["KHR_draco_mesh_compression"]
    assert error == ("t.gltf: meshes[0].primitives[0].extensions: KHR_draco_mesh_compression: "
                     "its meshes are Draco-compressed, which raytrace does not decode; save "
                     "the model without mesh compression")
    assert "meshes[0].primitives[0].extensions" in how


# -- glTF core ---------------------------------------------------------------------------
def _png_uri() -> str:
    buf = io.BytesIO()
    Image.fromarray(np.full((2, 2, 3), 128, np.uint8)).save(buf, "PNG")
    return "data:image/png;base64," + base64.b64encode(buf.getvalue()).decode()


def _textured(info: dict, uri: str | None = None):
    def mutate(doc):
        doc.update(images=[{"uri": uri or _png_uri()}], textures=[{"source": 0}])
        doc["materials"][0]["pbrMetallicRoughness"]["baseColorTexture"] = info
    return mutate


def _prim(change):
    return lambda doc: change(doc["meshes"][0]["primitives"][0])


def _material(change):
    return lambda doc: change(doc["materials"][0])


def _ktx2(doc):
    Path("x.ktx2").write_bytes(b"\xabKTX 20\xbb\r\n\x1a\n" + bytes(64))
    _textured({"index": 0}, "x.ktx2")(doc)


def _orthographic_camera(doc):
    """An orthographic camera on a second root node: met before any perspective one."""
    doc["cameras"] = [{"type": "orthographic", "orthographic": {
        "xmag": 1.0, "ymag": 1.0, "znear": 0.1, "zfar": 10.0}}]
    doc["nodes"].append({"camera": 0, "translation": [0.0, 0.0, 5.0]})
    doc["scenes"][0]["nodes"].append(len(doc["nodes"]) - 1)


#: The first cell of a glTF-core row → the change of the square that shows it (and whether
#: the whole scene is loaded, for the camera and light defaults).
CORE = {
    "node hierarchy that is not a tree": (lambda d: d["nodes"][0].update(children=[0]), False),
    "primitive `mode` 0–3, 5, 6 (points, lines, strips, fans)": (_prim(
        lambda p: p.update(mode=5)), False),
    "`TEXCOORD_1`": (_prim(lambda p: p["attributes"].update(TEXCOORD_1=1)), False),
    "`TEXCOORD_2` and higher": (_prim(lambda p: p["attributes"].update(TEXCOORD_2=1)), False),
    "`COLOR_0`": (_prim(lambda p: p["attributes"].update(COLOR_0=0)), False),
    "sparse accessors": (lambda d: d["accessors"][0].update(sparse={
        "count": 1, "indices": {"bufferView": 0, "componentType": 5125},
        "values": {"bufferView": 0}}), False),
    "no camera, no lights": (None, True),
    "images Pillow cannot open (KTX2, Basis)": (_ktx2, False),
    "a `textureInfo` with `texCoord` ≥ 2": (_textured({"index": 0, "texCoord": 2}), False),
    "`metallicRoughnessTexture`": (lambda d: (_textured({"index": 0})(d), d["materials"][0][
        "pbrMetallicRoughness"].update(metallicRoughnessTexture={"index": 0})), False),
    "`normalTexture`": (lambda d: (_textured({"index": 0})(d), d["materials"][0].update(
        normalTexture={"index": 0})), False),
    "`occlusionTexture`": (lambda d: (_textured({"index": 0})(d), d["materials"][0].update(
        occlusionTexture={"index": 0})), False),
    "`emissiveTexture`": (lambda d: (_textured({"index": 0})(d), d["materials"][0].update(
        emissiveTexture={"index": 0}, emissiveFactor=[1, 1, 1])), False),
    "`doubleSided`": (_material(lambda m: m.update(doubleSided=False)), False),
    "`orthographic` cameras": (_orthographic_camera, True),
}
CORE_ROWS = {first: (state, how) for first, state, how in rows("glTF core")}


def test_every_refused_or_warned_core_row_has_its_file_here():
    """(pygltflib's notes come from files it half-reads: tests/test_gltf.py has one.)"""
    loud = {k for k, (state, _) in CORE_ROWS.items() if state in ("refused", "warned")}
    assert loud - set(CORE) == {"pygltflib's own notes on a file it half-reads"}
    assert set(CORE) <= set(CORE_ROWS)


@pytest.mark.parametrize("row", list(CORE), ids=list(CORE))
def test_each_core_row_is_what_raytrace_does(tmp_path, monkeypatch, row):
    """Refused: the row's quoted line is the error; warned: the quoted line is the one
    warning; silent: the file loads without a word."""
    monkeypatch.chdir(tmp_path)
    mutate, whole = CORE[row]
    state, how = CORE_ROWS[row]
    path = gltf_file(mutate)
    error, notes = run((lambda: raytrace.load_scene(path)) if whole else mesh(path))
    if state == "refused":
        assert error == quoted(how)[0] and notes == []
    elif state == "warned":
        assert error is None and notes == quoted(how)[:1]
    else:
        assert error is None and notes == []


# -- MTL ---------------------------------------------------------------------------------
MTL_ROWS = [(names[0], state, how) for names, state, how in table("MTL statements")
            if len(names) == 1 and names[0] != "newmtl" and " " not in names[0]]
#: A value each statement takes (a file for the maps; 1 for the rest).
MTL_ARGS = {**dict.fromkeys(mtl.COLOR_STATEMENTS, "0.5 0.5 0.5"), "Ns": "10", "Ni": "1.5",
            "d": "1", "Tr": "0", "illum": "2", "refl": "-type sphere tex.png"}


def test_every_statement_the_mtl_reader_knows_has_its_row():
    rows = {name: state for name, state, _ in MTL_ROWS}
    known = (*mtl.COLOR_STATEMENTS, *mtl.NUMBER_STATEMENTS, *mtl.MAP_STATEMENTS)
    assert {n: rows.get(n) for n in known} == dict.fromkeys(known, "read")
    assert {n: rows.get(n) for n in mtl.IGNORED} == dict.fromkeys(mtl.IGNORED, "silent")


def _obj_with(tmp_path: Path, mtl_text: str, obj_line: str = "") -> Path:
    Image.fromarray(np.full((2, 2, 3), 128, np.uint8)).save(tmp_path / "tex.png")
    (tmp_path / "t.mtl").write_text(mtl_text, encoding="utf-8")
    (tmp_path / "t.obj").write_text("mtllib t.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\n"
                                    f"usemtl m\n{obj_line}\nf 1 2 3\n", encoding="utf-8")
    return Path("t.obj")


@pytest.mark.parametrize(("stmt", "state", "how"), MTL_ROWS, ids=[r[0] for r in MTL_ROWS])
def test_each_mtl_row_is_what_raytrace_does(tmp_path, monkeypatch, stmt, state, how):
    """Read or silent: no warning; warned: the one line naming the statement."""
    monkeypatch.chdir(tmp_path)
    arg = MTL_ARGS.get(stmt, "tex.png" if stmt.startswith("map_") or stmt in (
        "bump", "norm", "disp", "decal") else "1")
    error, notes = run(mesh(_obj_with(tmp_path, f"newmtl m\n{stmt} {arg}\n")))
    assert error is None
    if state == "warned":
        assert notes == [f"t.mtl: statements not modelled, drawn without them: {stmt}"]
    else:
        assert notes == []


def test_the_mtl_lines_the_page_quotes_are_the_ones_raytrace_prints(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    text = PAGE.read_text(encoding="utf-8")
    error, notes = run(mesh(_obj_with(tmp_path, "newmtl m\nmap_Ks tex.png\ndisp tex.png\n")))
    assert error is None and len(notes) == 1 and f"`{notes[0]}`" in text
    error, notes = run(mesh(_obj_with(tmp_path, "newmtl m\nTr 1\n")))
    assert error is None and len(notes) == 1 and f"`{notes[0]}`" in text
    error, _ = run(mesh(_obj_with(tmp_path, "newmtl m\nillum 11\n")))
    assert f"`{error}`" in re.sub(r"\n", " ", text)
    error, notes = run(mesh(_obj_with(tmp_path, "newmtl m\nfrobnicate 1\n")))
    assert dict((r[0][0], r[1]) for r in table("MTL statements"))["any other statement"] == (
        "warned") and notes == ["t.mtl: statements not modelled, drawn without them: "
                                "frobnicate"]


# -- OBJ ---------------------------------------------------------------------------------
OBJ_SILENT = [name for names, state, _ in table("OBJ statements") if state == "silent"
              for name in names if " " not in name]


@pytest.mark.parametrize("stmt", OBJ_SILENT)
def test_each_silent_obj_statement_loads_without_a_word(tmp_path, monkeypatch, stmt):
    monkeypatch.chdir(tmp_path)
    line = {"l": "l 1 2", "p": "p 1", "s": "s 1", "g": "g part", "o": "o thing"}.get(
        stmt, f"{stmt} 1")
    error, notes = run(mesh(_obj_with(tmp_path, "newmtl m\nKd 1 1 1\n", line)))
    assert error is None and notes == []


def test_the_obj_lines_the_page_quotes_are_the_ones_raytrace_prints(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    text = PAGE.read_text(encoding="utf-8")
    for line in ("f 1 2 9", "usemtl nope"):
        error, _ = run(mesh(_obj_with(tmp_path, "newmtl m\n", line)))
        assert f"`{error}`" in text, error
    error, notes = run(mesh(_obj_with(tmp_path, "newmtl m\n", "l 1 2")))
    assert error is None and len(notes) == 1 and f"`{notes[0]}`" in text


OBJ_WARNED = [name for names, state, _ in table("OBJ statements") if state == "warned"
              for name in names]


@pytest.mark.parametrize("stmt", OBJ_WARNED)
def test_each_warned_obj_statement_is_named_on_one_line(tmp_path, monkeypatch, stmt):
    # geometry that is not faces (points, lines, free-form curves and surfaces) is not drawn,
    # and the file is told so, statement by statement, once (two of one kind: one name)
    monkeypatch.chdir(tmp_path)
    line = {"l": "l 1 2", "p": "p 1"}.get(stmt, f"{stmt} 0 1 1 2")
    error, notes = run(mesh(_obj_with(tmp_path, "newmtl m\nKd 1 1 1\n",
                                      f"{line}\n{line}\np 2")))
    assert error is None
    named = sorted({stmt, "p"}, key=["p", "l", "curv", "curv2", "surf"].index)
    assert notes == [f"t.obj: statements not drawn (raytrace draws faces only): "
                     f"{', '.join(named)}"]
