"""Fast readers for the two mesh formats large meshes come in: binary PLY and OBJ.

A mesh file of a scene (``file = "model.ply"``) used to be read by trimesh, whose parsing
and vertex merging cost 1.4 s for a 1.3 M-triangle PLY. This module reads the common cases
with whole-array numpy operations and gives exactly what trimesh's
``load(path, process=False)`` followed by ``merge_vertices(merge_tex=True, merge_norm=True)``
gives (the same vertices in the same order, the same faces, the same per-corner texture
coordinates; tests/test_meshio.py checks it on the same files):

* :func:`read_ply`: binary PLY (little- or big-endian; Turk 1994, "The PLY Polygon File
  Format") whose faces are all triangles, read with :func:`numpy.frombuffer` through one
  structured dtype per element;
* :func:`read_obj`: OBJ triangles (Wavefront, "Object Files (.obj)", Appendix B1 of the
  Advanced Visualizer manual) with ``v``, ``vt``, ``vn``, ``f`` (``v``, ``v/vt``, ``v//vn``,
  ``v/vt/vn``, negative indices), ``o``, ``g``, ``s`` and comments, each kind of statement
  parsed by one :func:`numpy.fromstring` call over the bytes of its lines. A negative index
  counts back from the file's last vertex, as trimesh counts it (the OBJ appendix counts
  back from the last vertex defined before the face: the two differ where ``v`` lines follow
  an ``f`` line with negative indices, and raytrace keeps trimesh's reading);
* :func:`merge_vertices`: trimesh's merge (positions rounded to 10⁻⁸, the first occurrence
  of each kept, in order of first occurrence among the referenced vertices) through a 64-bit
  hash of the rounded positions, checked against the positions themselves.

Where the file gives normals (OBJ ``vn`` named by the faces' corners, PLY ``nx ny nz``),
each face corner's normal comes with them (:class:`MeshFile` ``normals``, (F, 3, 3)): per
corner, so the merge of positions keeps a cube's 24 split normals (docs/scene_format.md,
"Mesh shading").

Where a PLY's vertices carry ``red green blue [alpha]`` as ``uchar``, each face corner's
colour comes with them (:class:`MeshFile` ``colors``, (F, 3, 4) linear RGBA,
:func:`vertex_colors`), per corner like the normals.

Anything else (ASCII PLY, polygons, colours of another type, ``usemtl``/``mtllib``, other OBJ
statements, texture coordinates in a PLY) returns ``None`` and the caller falls back to
trimesh, so every file trimesh reads is still read and images do not change. Malformed files
raise one
:class:`~raytrace.errors.SceneError` line naming the file (and, for OBJ, the line).
"""

from __future__ import annotations

import warnings
from pathlib import Path
from typing import NamedTuple

import numpy as np

from ..errors import SceneError
from .texture import decoding_table

#: trimesh's ``tol.merge`` (1e-8) as decimal digits: positions equal after rounding
#: ``x·10⁸`` to an integer are one vertex (trimesh.grouping.merge_vertices).
MERGE_DIGITS = 8

#: PLY scalar types (Turk 1994, and the sized aliases of later writers) as numpy codes.
PLY_TYPES = {"char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1", "short": "i2",
             "int16": "i2", "ushort": "u2", "uint16": "u2", "int": "i4", "int32": "i4",
             "uint": "u4", "uint32": "u4", "float": "f4", "float32": "f4", "double": "f8",
             "float64": "f8"}
#: Vertex properties trimesh reads as texture coordinates: such files go to trimesh.
PLY_UV = {"s", "t", "u", "v", "texture_u", "texture_v", "texture_s", "texture_t"}
#: PLY vertex colour properties (Turk 1994's red, green, blue; alpha as writers add it).
PLY_COLOR = ("red", "green", "blue", "alpha")
#: OBJ statements this reader handles; any other one sends the file to trimesh.
OBJ_STATEMENTS = ("v", "vt", "vn", "f", "o", "g", "s")

class Lines(NamedTuple):
    """An OBJ file's bytes and where each of its lines starts and ends (after its newline)."""

    data: bytes
    buf: np.ndarray      #: the bytes as uint8
    starts: np.ndarray   #: (L,) int64
    ends: np.ndarray     #: (L,) int64


class MeshFile(NamedTuple):
    """A mesh file's triangles as :class:`raytrace.Mesh` takes them (object space)."""

    vertices: np.ndarray               #: (V, 3) float64, merged as trimesh merges them
    faces: np.ndarray                  #: (F, 3) int64
    texcoords: np.ndarray | None       #: (F, 3, 2) per corner (s, t), t = 0 at the top
    #: (F, 3, 3) per corner, the normals the file itself gives (None where it gives none)
    normals: np.ndarray | None = None
    #: (F, 3, 4) per corner, the linear RGBA vertex colours the file gives (PLY ``red green
    #: blue [alpha]``, COFF; :func:`vertex_colors`), or None
    colors: np.ndarray | None = None


def read_mesh(path: Path) -> MeshFile | None:
    """A binary PLY or OBJ file's :class:`MeshFile`; None where trimesh must read it."""
    suffix = path.suffix.lower()
    if suffix == ".ply":
        return read_ply(path)
    if suffix == ".obj":
        return read_obj(path)
    return None


# -- PLY ---------------------------------------------------------------------------------
def read_ply(path: Path) -> MeshFile | None:
    """A binary PLY of triangles: its vertices' x, y, z (and nx, ny, nz where given: each
    corner takes its vertex's) and its faces' vertex indices."""
    data = path.read_bytes()
    end = data.find(b"end_header")
    if not data.startswith(b"ply") or end < 0:
        return None  # trimesh says what is wrong with it
    stop = data.find(b"\n", end)
    header = data[:end].decode("ascii", errors="replace").splitlines()
    fmt = next((ln.split() for ln in header if ln.startswith("format")), [])
    order = {"binary_little_endian": "<", "binary_big_endian": ">"}.get(fmt[1] if fmt[1:]
                                                                         else "")
    if order is None or stop < 0:
        return None  # ASCII PLY
    elements: list[list] = []   # [name, count, [(property, type or (count, item))]]
    for line in header:
        words = line.split()
        if words[:1] == ["element"] and len(words) == 3:
            if not words[2].isdigit():
                return None  # a malformed header: trimesh says what is wrong
            elements.append([words[1], int(words[2]), []])
        elif words[:1] == ["property"] and elements:
            if words[1:2] == ["list"] and len(words) == 5:
                elements[-1][2].append((words[4], (words[2], words[3])))
            elif len(words) == 3:
                elements[-1][2].append((words[2], words[1]))
            else:
                return None
    offset, arrays = stop + 1, {}
    for name, count, props in elements:
        dtype = _ply_dtype(props, order)
        if dtype is None or (name != "face" and any(isinstance(t, tuple) for _, t in props)):
            return None  # a list of unknown length: no fixed stride to read it by
        size = dtype.itemsize * count
        if offset + size > len(data):
            if name == "face":  # faces of other sizes than 3 make it shorter: trimesh decides
                return None
            raise SceneError(f"cannot read mesh {path}: the file ends inside its {name} "
                             f"element ({count} expected)", "file")
        arrays[name] = np.frombuffer(data, dtype, count, offset)
        offset += size
    vertex, face = arrays.get("vertex"), arrays.get("face")
    if vertex is None or face is None or PLY_UV & set(vertex.dtype.names):
        return None
    if not {"x", "y", "z"} <= set(vertex.dtype.names):
        return None
    lists = [n for n, t in dict(elements[[e[0] for e in elements].index("face")][2]).items()
             if isinstance(t, tuple)]
    if lists not in (["vertex_indices"], ["vertex_index"]) or len(face) == 0:
        return None
    if np.any(face[lists[0] + "_n"] != 3):
        return None  # polygons: trimesh triangulates them
    vertices = np.stack([vertex[k].astype(np.float64) for k in "xyz"], axis=1)
    faces = face[lists[0]].astype(np.int64)
    _check_finite(vertices, path, lambda i: f"vertex {i + 1}")
    _check_indices(faces, len(vertices), path, lambda i: f"face {i + 1}")
    normals = colors = None
    if {"nx", "ny", "nz"} <= set(vertex.dtype.names):
        normals = np.stack([vertex[k].astype(np.float64) for k in ("nx", "ny", "nz")],
                           axis=1)[faces]
    named = [k for k in PLY_COLOR if k in vertex.dtype.names]
    if {"red", "green", "blue"} <= set(named):
        if any(vertex.dtype[k] != np.uint8 for k in named):
            return None  # colours of another type: trimesh scales them to 8-bit codes
        colors = vertex_colors(np.stack([vertex[k] for k in named], axis=1))[faces]
    return MeshFile(*merge_vertices(vertices, faces), None, normals, colors)


def off_vertex_colors(text: str) -> np.ndarray | None:
    """The vertex colours (V, 3) or (V, 4) uint8 codes of a COFF file (Geomview's OFF with
    colours: the keyword ``COFF``, the counts ``V F E``, then V lines ``x y z r g b [a]``),
    which trimesh's OFF reader drops; None for a plain OFF or vertex lines without colours.
    Values above 1 are 8-bit codes (Meshlab writes them so); values all within [0, 1] are
    Geomview's floats, taken to codes as round(255·x), as trimesh takes float colours.

    >>> off_vertex_colors("COFF\\n1 0 0\\n0 0 0 255 128 0 255\\n").tolist()
    [[255, 128, 0, 255]]
    """
    rows = [w for w in (ln.split("#", 1)[0].split() for ln in text.splitlines()) if w]
    if not rows or rows[0][0] != "COFF":
        return None
    # the counts follow the keyword on its line, or on the next
    if len(rows[0]) > 1:
        counts, body = rows[0][1:], rows[1:]
    else:
        counts, body = (rows[1:2] + [[]])[0], rows[2:]
    try:
        n = int(counts[0])
        lines = body[:n]
        width = min(len(r) for r in lines) - 3
        values = np.array([r[3:3 + min(width, 4)] for r in lines], np.float64)
    except (IndexError, ValueError):
        return None  # trimesh says what is wrong with the file
    if len(lines) < n or width < 3 or not np.isfinite(values).all():
        return None
    codes = values if values.max() > 1.0 else np.round(255.0 * values)
    return np.clip(codes, 0, 255).astype(np.uint8)


def vertex_colors(codes: np.ndarray) -> np.ndarray:
    """Linear RGBA (V, 4) float64 of vertex colours given as 8-bit codes (V, 3) or (V, 4) (a
    PLY's ``uchar red green blue [alpha]``, trimesh's ``visual.vertex_colors``): R, G and B
    decoded as sRGB (IEC 61966-2-1, :func:`raytrace.readers.texture.decoding_table`), alpha
    c / 255 (1 where there is none). The PLY format (Turk 1994) names no colour space; its
    writers (scanners, Meshlab) store display colours, and readers decode them as sRGB:
    Blender's PLY importer by default ("Import Vertex Colors: sRGB"), three.js's PLYLoader
    (mrdoob/three.js#23342).

    >>> vertex_colors(np.array([[255, 0, 0]], np.uint8)).tolist()
    [[1.0, 0.0, 0.0, 1.0]]
    """
    codes = np.asarray(codes, np.uint8)
    out = np.ones((len(codes), 4))
    out[:, :3] = decoding_table(8, True)[codes[:, :3]]
    if codes.shape[1] > 3:
        out[:, 3] = codes[:, 3] / 255.0
    return out


def _ply_dtype(props: list, order: str) -> np.dtype | None:
    """One record of an element: scalars as they are; a list as its count and, assuming
    every list holds 3 items (checked by the caller), three items."""
    fields = []
    for name, kind in props:
        if isinstance(kind, tuple):
            count, item = (PLY_TYPES.get(k) for k in kind)
            if count is None or item is None:
                return None
            fields += [(name + "_n", order + count), (name, order + item, (3,))]
        elif kind in PLY_TYPES:
            fields.append((name, order + PLY_TYPES[kind]))
        else:
            return None
    try:
        return np.dtype(fields)
    except (TypeError, ValueError):  # repeated property names
        return None


# -- OBJ ---------------------------------------------------------------------------------
def read_obj(path: Path) -> MeshFile | None:
    """An OBJ of triangles: ``v`` positions, ``f`` corners, ``vt`` and ``vn`` per corner where
    the corners name them."""
    data = path.read_bytes()
    if b"\r" in data:
        data = data.replace(b"\r\n", b"\n").replace(b"\r", b"\n")
    if b"\\\n" in data:
        return None  # line continuations
    buf = np.frombuffer(data, np.uint8)
    starts = np.concatenate([[0], np.flatnonzero(buf == 10) + 1])
    starts = starts[starts < len(buf)]
    ends = np.append(starts[1:], len(buf))
    lines = Lines(data, buf, starts, ends)
    kinds, plain = _statements(lines)
    # (checked for every file: trimesh would drop a face cut short without a word)
    words = _face_words(lines, kinds[b"f"], path) if kinds[b"f"].any() else None
    if not plain or data.count(b"#") != int((buf[starts] == ord("#")).sum()):
        # (a comment after a statement, or one of the statements trimesh reads)
        return None  # usemtl, mtllib, l, p, curves, indented lines: trimesh's reading stands
    if words is None:
        raise SceneError(f"{path} holds no faces", "file")
    v = _numbers(lines, kinds[b"v"], b"v", 3, path)
    vt = _numbers(lines, kinds[b"vt"], b"vt", 2, path)
    vn = _numbers(lines, kinds[b"vn"], b"vn", 3, path)
    if v is None or vt is None or vn is None:
        return None
    corners = _face_corners(words, kinds[b"f"], path, (len(v), len(vt), len(vn)))
    if corners is None:
        return None
    faces, face_vt, face_vn = corners
    _check_finite(v, path, lambda i: f"line {_line_of(kinds[b'v'], i)}")
    vertices, merged = merge_vertices(v, faces)
    texcoords = None
    if face_vt is not None and len(vt):
        texcoords = vt[face_vt] * [1.0, -1.0] + [0.0, 1.0]  # t = 0 at the image's top row
    return MeshFile(vertices, merged, texcoords, vn[face_vn] if face_vn is not None else None)


def _statements(lines: Lines) -> tuple[dict[bytes, np.ndarray], bool]:
    """Which lines are ``v``, ``vt`` and ``f`` statements, from their first three bytes, and
    whether every line is one of :data:`OBJ_STATEMENTS` or blank."""
    _, buf, starts, ends = lines

    def at(k: int) -> np.ndarray:
        out = np.full(len(starts), 10, np.uint8)
        inside = starts + k < ends
        out[inside] = buf[starts[inside] + k]
        return out

    c0, c1, c2 = at(0), at(1), at(2)
    blank1, blank2 = _blank(c1), _blank(c2)
    kinds = {b"v": (c0 == ord("v")) & blank1, b"vt": (c0 == ord("v")) & (c1 == ord("t")) & blank2,
             b"vn": (c0 == ord("v")) & (c1 == ord("n")) & blank2, b"f": (c0 == ord("f")) & blank1}
    known = np.isin(c0, tuple(map(ord, "ogs"))) & blank1 | (c0 == 10) | (c0 == ord("#"))
    for mask in kinds.values():
        known |= mask
    return kinds, bool(known.all())


def _blank(chars: np.ndarray) -> np.ndarray:
    """Where bytes are a blank, a tab or a newline."""
    return (chars == 32) | (chars == 10) | (chars == 9)


def _line_of(mask: np.ndarray, i: int) -> int:
    """The 1-based line number of the i-th line where ``mask`` holds."""
    return int(np.flatnonzero(mask)[i]) + 1


def _numbers(lines: Lines, mask: np.ndarray, stmt: bytes, width: int, path: Path
             ) -> np.ndarray | None:
    """The numbers of the lines where ``mask`` holds, ``width`` a line, as one (n, width)
    float64 array: their text gathered and parsed by one ``np.fromstring``; None where some
    line has more numbers (a ``w``, vertex colours: trimesh decides what they mean)."""
    buf, starts, ends = lines.buf, lines.starts, lines.ends
    n = int(mask.sum())
    if n == 0:
        return np.zeros((0, width))
    values = _parse(_gather(lines, mask, stmt), float)
    if values.size != n * width:
        # a line with more or fewer numbers (w, vertex colours) or a malformed one: find it
        for k, (a, b) in enumerate(zip(starts[mask], ends[mask], strict=True)):
            words = bytes(buf[a:b]).split()[1:]
            try:
                [float(w) for w in words]
            except ValueError:
                raise SceneError(f"cannot read mesh {path}: line {_line_of(mask, k)}: "
                                 f"{stmt.decode()} needs numbers, got "
                                 f"{bytes(buf[a:b]).strip().decode(errors='replace')!r}",
                                 "file") from None
            if len(words) < width and stmt != b"vt":  # trimesh reads a 1-number vt
                raise SceneError(f"cannot read mesh {path}: line {_line_of(mask, k)}: "
                                 f"{stmt.decode()} needs {width} numbers, got {len(words)}",
                                 "file")
        return None  # extra numbers on some lines: trimesh decides what they mean
    return values.reshape(n, width)


def _parse(text: bytes, dtype: type) -> np.ndarray:
    """Blank-separated numbers; none where a word is not one (the caller compares the count
    and finds the line)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)  # "could not be read to its end"
        try:
            return np.fromstring(text, dtype=dtype, sep=" ")
        except ValueError:
            return np.zeros(0, dtype)


def _gather(lines: Lines, mask: np.ndarray, word: bytes) -> bytes:
    """The lines where ``mask`` holds, each with its statement ``word`` blanked out, as one
    text: runs of consecutive such lines are sliced out whole (files write each kind of
    statement in a few long runs), then the word after each newline is replaced."""
    data, _, starts, ends = lines
    edges = np.diff(np.concatenate([[False], mask, [False]]).astype(np.int8))
    first, last = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1) - 1
    text = b"\n" + b"".join(data[a:b] for a, b in zip(starts[first].tolist(),
                                                     ends[last].tolist(), strict=True))
    if not text.endswith(b"\n"):  # the file's last line
        text += b"\n"
    return text.replace(b"\n" + word, b"\n" + b" " * len(word))


def _face_words(lines: Lines, mask: np.ndarray, path: Path
                ) -> tuple[bytes, np.ndarray, np.ndarray]:
    """The ``f`` lines' text (:func:`_gather`), where each corner starts in it, and how many
    corners each line has; a :class:`SceneError` naming the first line with fewer than 3 (a
    face is a polygon: a file cut short in a face, say)."""
    text = _gather(lines, mask, b"f")
    chars = np.frombuffer(text, np.uint8)
    blank = _blank(chars)
    word_starts = np.flatnonzero(~blank[1:] & blank[:-1]) + 1
    line = np.searchsorted(np.flatnonzero(chars == 10), word_starts) - 1  # its f line
    counts = np.bincount(line, minlength=int(mask.sum()))
    if np.any(counts < 3):
        k = int(np.argmax(counts < 3))
        raise SceneError(f"cannot read mesh {path}: line {_line_of(mask, k)}: f needs at least "
                         f"3 vertices, got {int(counts[k])} (is the file cut short?)", "file")
    return text, word_starts, counts


def _face_corners(words: tuple[bytes, np.ndarray, np.ndarray], mask: np.ndarray, path: Path,
                  sizes: tuple[int, int, int]) -> tuple | None:
    """(F, 3) vertex indices, (F, 3) texture-vertex and (F, 3) normal indices (each None where
    the corners name none) of triangle-only ``f`` lines (their :func:`_face_words`) written
    all in one corner form; None for polygons or mixed forms. ``sizes``: how many ``v``,
    ``vt`` and ``vn`` lines the file has."""
    n_v, n_vt, n_vn = sizes
    text, word_starts, counts = words
    n = len(counts)
    if np.any(counts != 3):
        return None  # polygons: trimesh triangulates them
    sample = text[word_starts[0]:].split(maxsplit=1)[0]
    slashes = sample.count(b"/")
    double = b"//" in sample
    if text.count(b"/") != slashes * 3 * n or text.count(b"//") != (3 * n if double else 0):
        return None  # mixed corner forms
    numbers = _parse(text.replace(b"/", b" "), np.int64)
    per = 1 + slashes - (1 if double else 0)
    if numbers.size != per * 3 * n:
        return None
    numbers = numbers.reshape(n, 3, per)

    def absolute(i: np.ndarray, count: int, what: str) -> np.ndarray:
        out = np.where(i > 0, i - 1, count + i)
        bad = (i == 0) | (out < 0) | (out >= count)
        if bad.any():
            k = int(np.argmax(bad.any(axis=1)))
            raise SceneError(f"cannot read mesh {path}: line {_line_of(mask, k)}: {what} "
                             f"index {int(i[bad][0])} out of range 1..{count}", "file")
        return out

    faces = absolute(numbers[:, :, 0], n_v, "vertex")
    if slashes and not double and n_vt == 0:
        return None  # f v/vt with no vt lines: trimesh reads it without texture coordinates
    face_vt = absolute(numbers[:, :, 1], n_vt, "texture vertex") if slashes and not double \
        else None
    face_vn = absolute(numbers[:, :, -1], n_vn, "normal") if slashes == 2 else None
    return faces, face_vt, face_vn


# -- shared ------------------------------------------------------------------------------
def _check_finite(vertices: np.ndarray, path: Path, where) -> None:
    bad = ~np.isfinite(vertices).all(axis=1)
    if bad.any():
        i = int(np.argmax(bad))
        raise SceneError(f"{path}: {where(i)}: vertex is not finite ({vertices[i].tolist()}); "
                         "Embree would silently drop its triangles", "file")


def _check_indices(faces: np.ndarray, n: int, path: Path, where) -> None:
    bad = (faces < 0) | (faces >= n)
    if bad.any():
        i = int(np.argmax(bad.any(axis=1)))
        raise SceneError(f"{path}: {where(i)}: vertex index {int(faces[bad][0])} out of "
                         f"range 0..{n - 1}", "file")


def merge_vertices(vertices: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """trimesh's ``merge_vertices(merge_tex=True, merge_norm=True)`` (trimesh.grouping):
    referenced vertices whose positions round to the same integers ``x·10⁸`` become one, the
    first occurrence kept, in order of first occurrence; unreferenced vertices are dropped.

    The rounded rows are hashed to one uint64 each (a multiply-xor mix), so the grouping
    sorts one integer column instead of three; the groups are then checked against the rows
    themselves, and a hash collision (never seen) falls back to grouping the rows.
    """
    referenced = np.zeros(len(vertices), dtype=bool)
    referenced[faces] = True
    with np.errstate(invalid="ignore", over="ignore"):
        keys = (vertices * (10**MERGE_DIGITS)).round().astype(np.int64)[referenced]
    mixed = keys.view(np.uint64) * np.array([0x9E3779B97F4A7C15, 0xC2B2AE3D27D4EB4F,
                                             0x165667B19E3779F9], np.uint64)
    hashed = mixed[:, 0] ^ (mixed[:, 1] >> np.uint64(17)) ^ mixed[:, 1] ^ (
        mixed[:, 2] << np.uint64(23)) ^ (mixed[:, 2] >> np.uint64(29))
    if len(hashed) == 0 or np.all(np.diff(np.sort(hashed)) != 0):
        # no two positions alike (the usual indexed file): the referenced vertices, in order
        remap = np.cumsum(referenced) - 1
        return (vertices if referenced.all() else vertices[referenced]), remap[faces]
    _, index, inverse = np.unique(hashed, return_index=True, return_inverse=True)
    if not np.array_equal(keys[index][inverse.ravel()], keys):
        rows = np.ascontiguousarray(keys).view(np.dtype((np.void, 24))).ravel()
        _, index, inverse = np.unique(rows, return_index=True, return_inverse=True)
    order = index.argsort()
    kept = np.nonzero(referenced)[0][index[order]]
    remap = np.zeros(len(vertices), dtype=np.int64)
    remap[referenced] = order.argsort()[inverse.ravel()]
    return vertices[kept], remap[faces]
