"""The fast mesh readers (raytrace/meshio.py) against trimesh on the same files: the same
vertices in the same order, the same faces, the same per-corner texture coordinates and so
the same vertex normals, as ``trimesh.load(process=False)`` + ``merge_vertices(merge_tex=True,
merge_norm=True)`` give (what raytrace.Mesh read before); files it does not read go to
trimesh; a malformed file is one error line naming the file and the line."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

import raytrace
from raytrace.accel import vertex_normals
from raytrace.readers import meshio


def trimesh_reference(path):
    """What raytrace.Mesh took from trimesh before meshio: vertices, faces, texcoords, and
    the normals trimesh's loader read from the file, per corner (before the merge)."""
    loaded = trimesh.load(str(path), process=False)
    texcoords = None
    uv = getattr(loaded.visual, "uv", None)
    if uv is not None and len(uv) == len(loaded.vertices):
        texcoords = np.asarray(uv, np.float64)[np.asarray(loaded.faces)] * [1, -1] + [0, 1]
    normals = None
    if "vertex_normals" in loaded._cache:  # stored by the loader, not computed
        normals = np.asarray(loaded.vertex_normals)[np.asarray(loaded.faces)]
    loaded.merge_vertices(merge_tex=True, merge_norm=True)
    return np.asarray(loaded.vertices, np.float64), np.asarray(loaded.faces), texcoords, normals


def assert_same_as_trimesh(path):
    fast = meshio.read_mesh(path)
    assert fast is not None, "meshio fell back to trimesh"
    v, f, t, n = fast[:4]  # (and the colours: none in these files)
    rv, rf, rt, rn = trimesh_reference(path)
    assert v.dtype == np.float64 and f.dtype == np.int64
    np.testing.assert_array_equal(v, rv)
    np.testing.assert_array_equal(f, rf)
    np.testing.assert_array_equal(vertex_normals(v, f), vertex_normals(rv, rf))
    for mine, theirs in ((t, rt), (n, rn)):
        if theirs is None:
            assert mine is None
        else:
            np.testing.assert_array_equal(mine, theirs)


def knot() -> trimesh.Trimesh:
    """A torus knot (trimesh's own generator) with a few hundred vertices and faces."""
    return trimesh.creation.torus(major_radius=1.0, minor_radius=0.3, major_sections=24,
                                  minor_sections=12)


def soup(mesh: trimesh.Trimesh) -> tuple[np.ndarray, np.ndarray]:
    """The mesh as unshared triangles (every vertex repeated per face, as STL writes), plus
    two unreferenced vertices and a copy of vertex 0 off by 2e-9 (merged at 10⁻⁸)."""
    v = mesh.vertices[mesh.faces].reshape(-1, 3)
    v = np.vstack([v, [[7.0, 7.0, 7.0], [8.0, 8.0, 8.0]], v[:1] + 2e-9])
    f = np.arange(len(mesh.faces) * 3).reshape(-1, 3)
    f[5, 1] = len(v) - 1  # a corner on the near-duplicate
    return v, f


@pytest.mark.parametrize("encoding", ["binary_little_endian", "binary_big_endian"])
def test_binary_ply_matches_trimesh(tmp_path, encoding):
    m = knot()
    path = tmp_path / "knot.ply"
    path.write_bytes(trimesh.exchange.ply.export_ply(m, encoding="binary"))
    if encoding == "binary_big_endian":  # rewrite the same numbers big-endian by hand
        header = (f"ply\nformat binary_big_endian 1.0\nelement vertex {len(m.vertices)}\n"
                  "property double x\nproperty double y\nproperty double z\n"
                  f"element face {len(m.faces)}\nproperty list uchar int vertex_indices\n"
                  "end_header\n").encode()
        rec = np.zeros(len(m.faces), [("n", "u1"), ("i", ">i4", (3,))])
        rec["n"], rec["i"] = 3, m.faces
        path.write_bytes(header + m.vertices.astype(">f8").tobytes() + rec.tobytes())
    assert_same_as_trimesh(path)


def test_ply_soup_merges_as_trimesh_does(tmp_path):
    v, f = soup(knot())
    path = tmp_path / "soup.ply"
    trimesh.Trimesh(v, f, process=False).export(path)
    assert_same_as_trimesh(path)
    got, faces = meshio.read_mesh(path)[:2]
    assert len(got) == len(knot().vertices)  # unreferenced dropped, duplicates merged


@pytest.mark.parametrize("form", ["v", "v/vt", "v//vn", "v/vt/vn", "negative"])
def test_obj_matches_trimesh(tmp_path, form):
    m = knot()
    uv = np.c_[np.linspace(0, 1, len(m.vertices)), np.linspace(1, 0, len(m.vertices)) ** 2]
    normals = m.vertex_normals
    lines = ["# a knot", "o knot", "g part", "s 1"]
    lines += [f"v {x!r} {y!r} {z!r}" for x, y, z in m.vertices.tolist()]
    if "vt" in form:
        lines += [f"vt {s!r} {t!r}" for s, t in uv.tolist()]
    if "vn" in form:
        lines += [f"vn {x!r} {y!r} {z!r}" for x, y, z in normals.tolist()]
    n = len(m.vertices)
    for face in (m.faces + 1).tolist():
        corner = {"v": "{i}", "v/vt": "{i}/{i}", "v//vn": "{i}//{i}",
                  "v/vt/vn": "{i}/{i}/{i}", "negative": "{j}"}[form]
        lines.append("f " + " ".join(corner.format(i=i, j=i - n - 1) for i in face))
    path = tmp_path / "knot.obj"
    path.write_text("\n".join(lines))  # no newline after the last line
    assert_same_as_trimesh(path)


def test_obj_soup_with_crlf_and_extra_blanks_matches_trimesh(tmp_path):
    v, f = soup(knot())
    text = "".join(f"v {x!r}  {y!r} {z!r}\r\n" for x, y, z in v.tolist())
    text += "".join(f"f {a + 1} {b + 1}  {c + 1}  \r\n\r\n" for a, b, c in f.tolist())
    path = tmp_path / "soup.obj"
    path.write_text(text, newline="")
    assert_same_as_trimesh(path)


@pytest.mark.parametrize("name,text,readable", [
    ("header.ply", "ply\nformat binary_little_endian 1.0\nelement vertex three\nend_header\n",
     False),
    ("ascii.ply", "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                  "property float z\nelement face 1\nproperty list uchar int vertex_indices\n"
                  "end_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n", True),
    ("quad.obj", "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n", True),
    ("material.obj", "mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl red\nf 1 2 3\n", True),
    ("colours.obj", "v 0 0 0 1 0 0\nv 1 0 0 0 1 0\nv 0 1 0 0 0 1\nf 1 2 3\n", True),
    # trimesh's own errors on these two stay as they were
    ("comment.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0 # trailing\nf 1 2 3\n", False),
    ("mixed.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nf 1/1 2/1 3\n", False),
    # trimesh reads these two (without texture coordinates): so does raytrace
    ("no_vt.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1/1 2/2 3/3\n", True),
    ("short_vt.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0.5\nvt 0.2\nvt 0.1\nf 1/1 2/2 3/3\n",
     True),
    # a bare "property" line in a PLY header: trimesh's error, not an IndexError of ours
    ("property.ply", "ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty\n"
                     "end_header\n", False),
])
def test_files_it_does_not_read_go_to_trimesh(tmp_path, name, text, readable):
    path = tmp_path / name
    path.write_text(text)
    assert meshio.read_mesh(path) is None
    if readable:  # and raytrace still reads them, through trimesh
        assert len(raytrace.Mesh(file=path).faces) >= 1


@pytest.mark.parametrize("text,message", [
    ("v 0 0 0\nv 1 0 0\nv 0 1 x\nf 1 2 3\n", "line 3: v needs numbers, got 'v 0 1 x'"),
    ("v 0 0 0\nv 1 0 0\nv 0 1\nf 1 2 3\n", "line 3: v needs 3 numbers, got 2"),
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\n\nf 1 2 3\nf 1 2 4\n", "line 6: vertex index 4 out of range 1..3"),
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 0\n", "line 4: vertex index 0 out of range 1..3"),
    ("v 0 0 0\nv 1 0 0\nv 0 nan 0\nf 1 2 3\n", "line 3: vertex is not finite"),
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\n", "holds no faces"),
])
def test_a_malformed_obj_is_one_line_naming_file_and_line(tmp_path, text, message):
    path = tmp_path / "bad.obj"
    path.write_text(text)
    with pytest.raises(raytrace.SceneError) as e:
        raytrace.Mesh(file=path)
    line = str(e.value)
    assert "\n" not in line and str(path) in line and message in line
    assert line.startswith("file: ")


TRIANGLES = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nf 1 2 3\n"


@pytest.mark.parametrize(("text", "line"), [
    (TRIANGLES + "f 2 4", 6),                    # the fast reader's file, cut in a face
    (TRIANGLES + "f 2 4 ", 6),
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2", 4),     # its only face cut short
    ("mtllib m.mtl\n" + TRIANGLES + "f 2", 7),   # a file trimesh reads: it drops the face
], ids=["last face", "last face and a blank", "only face", "trimesh's file"])
def test_an_obj_cut_short_in_a_face_says_so(tmp_path, text, line):
    path = tmp_path / "cut.obj"
    path.write_text(text)
    with pytest.raises(raytrace.SceneError) as e:
        raytrace.Mesh(file=path)
    got = len(text.rsplit("f ", 1)[1].split())
    assert str(e.value) == (f"file: cannot read mesh {path}: line {line}: f needs at least 3 "
                            f"vertices, got {got} (is the file cut short?)")


def test_a_mesh_file_of_points_only_says_it_holds_no_triangles(tmp_path):
    path = tmp_path / "points.ply"
    path.write_text("ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\n"
                    "property float y\nproperty float z\nend_header\n0 0 0\n1 0 0\n0 1 0\n")
    with pytest.raises(raytrace.SceneError) as e:
        raytrace.Mesh(file=path)
    assert str(e.value) == (f"file: {path} holds no triangles (trimesh reads it as a "
                            "PointCloud: points or lines only)")

def test_a_truncated_or_out_of_range_ply_is_one_line(tmp_path):
    m = knot()
    good = trimesh.exchange.ply.export_ply(m, encoding="binary")
    path = tmp_path / "cut.ply"
    start = good.index(b"end_header\n") + len(b"end_header\n")
    path.write_bytes(good[:start + 100])  # inside the vertices
    with pytest.raises(raytrace.SceneError) as e:
        raytrace.Mesh(file=path)
    assert str(e.value) == (f"file: cannot read mesh {path}: the file ends inside its vertex "
                            f"element ({len(m.vertices)} expected)")
    path.write_bytes(good[:-7])  # inside the faces: maybe faces of other sizes, so trimesh's
    with pytest.raises(raytrace.SceneError) as e:  # reading says what it finds
        raytrace.Mesh(file=path)
    assert "\n" not in str(e.value) and str(e.value).startswith(f"file: cannot read mesh {path}")
    bad = trimesh.Trimesh(m.vertices, np.where(m.faces == 5, len(m.vertices) + 2, m.faces),
                          process=False)
    path = tmp_path / "range.ply"
    path.write_bytes(trimesh.exchange.ply.export_ply(bad, encoding="binary"))
    with pytest.raises(raytrace.SceneError) as e:
        raytrace.Mesh(file=path)
    first = int(np.argmax((m.faces == 5).any(axis=1)))
    assert str(e.value) == (f"file: {path}: face {first + 1}: vertex index "
                            f"{len(m.vertices) + 2} out of range 0..{len(m.vertices) - 1}")


def test_merge_matches_trimesh_on_random_near_duplicates():
    rng = np.random.default_rng(5)
    base = rng.normal(size=(300, 3))
    # exact repeats, repeats within the rounding, values on a rounding boundary
    v = np.vstack([base, base[::3], base[::5] + 3e-9, np.round(base[:40], 8) + 0.5e-8])
    f = rng.integers(0, len(v), size=(900, 3))
    mesh = trimesh.Trimesh(v.copy(), f.copy(), process=False)
    mesh.merge_vertices(merge_tex=True, merge_norm=True)
    got_v, got_f = meshio.merge_vertices(v, f)
    np.testing.assert_array_equal(got_v, mesh.vertices)
    np.testing.assert_array_equal(got_f, mesh.faces)


@pytest.mark.parametrize("scale", [1e-200, 1e-160, 1e-5, 1.0, 1e17])
def test_nonzero_area_keeps_the_faces_cross_and_norm_keep(scale):
    """raytrace.scene._nonzero_area drops exactly the faces np.cross + np.linalg.norm drop
    (raytrace.Mesh's test before), underflow to zero area included."""
    from raytrace.scene import _nonzero_area

    rng = np.random.default_rng(7)
    v = rng.normal(size=(2000, 3)) * scale
    v[:100, 2] = 0.0  # flat and collinear corners
    v[100:150] = v[150:200] * 2.0
    f = rng.integers(0, 2000, size=(6000, 3))
    f[:40, 1] = f[:40, 0]  # repeated corners
    f[40:80] = rng.integers(0, 100, size=(40, 3))
    a, b, c = v[f[:, 0]], v[f[:, 1]], v[f[:, 2]]
    with np.errstate(over="ignore", under="ignore"):
        expected = np.linalg.norm(np.cross(b - a, c - a), axis=1) > 0
    np.testing.assert_array_equal(_nonzero_area(v, f), expected)
    assert 0 < expected.sum() < len(f) or scale < 1e-150  # both outcomes occur


@pytest.mark.parametrize("suffix", [".ply", ".obj"])
def test_a_ply_or_obj_mesh_scene_never_imports_trimesh(tmp_path, suffix):
    """Reading the file is meshio's: a scene of binary PLY or OBJ meshes loads without
    trimesh's import (about 0.3 s of a fresh process)."""
    import subprocess
    import sys

    mesh = tmp_path / f"knot{suffix}"
    knot().export(mesh)
    scene = tmp_path / "scene.toml"
    scene.write_text(f'[[objects]]\ntype = "mesh"\nfile = "{mesh.name}"\nshading = "smooth"\n')
    code = ("import sys, raytrace; s = raytrace.load_scene(sys.argv[1]); "
            "print(len(s.objects[0].faces), 'trimesh' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code, str(scene)], capture_output=True,
                         text=True, check=True).stdout.split()
    assert out == [str(len(knot().faces)), "False"]


def _ply_with_normals(path, encoding: str):
    """Two triangles over 4 vertices whose ``nx ny nz`` are made-up unit vectors, one a vertex
    (the shared vertices 0 and 2 give both triangles the same corner normal)."""
    v = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], float)
    n = np.array([[0, 0, 1], [0.6, 0, 0.8], [0, 0.6, 0.8], [-0.6, 0, 0.8]], float)
    f = np.array([[0, 1, 2], [0, 2, 3]])
    header = (f"ply\nformat {encoding} 1.0\nelement vertex 4\nproperty float x\n"
              "property float y\nproperty float z\nproperty float nx\nproperty float ny\n"
              "property float nz\nelement face 2\nproperty list uchar int vertex_indices\n"
              "end_header\n")
    if encoding == "ascii":
        body = "".join(" ".join(map(str, row)) + "\n" for row in np.c_[v, n].tolist())
        body += "".join(f"3 {a} {b} {c}\n" for a, b, c in f.tolist())
        path.write_text(header + body)
    else:
        rec = np.zeros(2, [("n", "u1"), ("i", "<i4", (3,))])
        rec["n"], rec["i"] = 3, f
        path.write_bytes(header.encode() + np.c_[v, n].astype("<f4").tobytes() + rec.tobytes())
    return n[f]  # (2, 3, 3): each corner its vertex's normal


@pytest.mark.parametrize("encoding", ["binary_little_endian", "ascii"])
def test_ply_normals_are_the_files_per_corner(tmp_path, encoding):
    # Binary: raytrace's reader; ASCII: trimesh's, whose stored normals are taken before the
    # merge. Either way each corner has its vertex's nx ny nz exactly (0.6, 0.8 as float32).
    path = tmp_path / "quad.ply"
    want = _ply_with_normals(path, encoding)
    assert (meshio.read_mesh(path) is None) == (encoding == "ascii")
    mesh = raytrace.Mesh(file=path)
    assert mesh.shading == "file"
    np.testing.assert_allclose(mesh.normals, want, rtol=1e-7)


def test_normals_trimesh_computes_are_not_the_files(tmp_path):
    # An ASCII PLY (trimesh's reader) and an STL without vertex normals: trimesh would compute
    # vertex normals on first access; the mesh takes none and is flat (glTF's rule).
    ply = tmp_path / "tri.ply"
    ply.write_text("ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y"
                   "\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices"
                   "\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n")
    stl = tmp_path / "tri.stl"
    trimesh.Trimesh([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]]).export(stl)
    for path in (ply, stl):
        mesh = raytrace.Mesh(file=path)
        assert mesh.normals is None and mesh.shading == "flat", path.name


def test_obj_split_normals_stay_split_through_the_merge(tmp_path):
    # Two triangles sharing an edge by position (6 v lines merged to 4 positions), each
    # triangle's corners naming its own vn: the merged mesh keeps each corner's normal (a
    # hard edge stays hard).
    text = ("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 0 0\nv 1 1 0.5\nv 0 1 0\n"
            "vn 0 0 1\nvn 0 -0.6 0.8\n"
            "f 1//1 2//1 3//1\nf 4//2 5//2 6//2\n")
    path = tmp_path / "hinge.obj"
    path.write_text(text)
    got = meshio.read_mesh(path)
    assert len(got.vertices) == 4
    np.testing.assert_array_equal(got.normals, [[[0, 0, 1]] * 3, [[0, -0.6, 0.8]] * 3])


# -- vertex colours: PLY red green blue [alpha], COFF -----------------------------------------
#: The triangle (−1, −1, 0), (1, −1, 0), (0, 1, 0), counter-clockwise from +z (normal +z).
TRIANGLE = np.array([[-1, -1, 0], [1, -1, 0], [0, 1, 0]], float)


def _colored_ply(path, encoding: str, codes) -> None:
    """TRIANGLE with its vertices' ``uchar red green blue`` ``codes`` (3, 3)."""
    header = (f"ply\nformat {encoding} 1.0\nelement vertex 3\nproperty float x\n"
              "property float y\nproperty float z\nproperty uchar red\nproperty uchar green\n"
              "property uchar blue\nelement face 1\nproperty list uchar int vertex_indices\n"
              "end_header\n")
    if encoding == "ascii":
        body = "".join(f"{x:g} {y:g} {z:g} {r} {g} {b}\n"
                       for (x, y, z), (r, g, b) in zip(TRIANGLE, codes, strict=True))
        path.write_text(header + body + "3 0 1 2\n")
    else:
        vertex = np.zeros(3, [("p", "<f4", (3,)), ("c", "u1", (3,))])
        vertex["p"], vertex["c"] = TRIANGLE, codes
        face = np.zeros(1, [("n", "u1"), ("i", "<i4", (3,))])
        face["n"], face["i"] = 3, [0, 1, 2]
        path.write_bytes(header.encode() + vertex.tobytes() + face.tobytes())


#: sRGB code 128 decoded (IEC 61966-2-1): ((128/255 + 0.055)/1.055)^2.4 = 0.2158605.
SRGB_128 = ((128 / 255 + 0.055) / 1.055) ** 2.4
#: A directional light from 60° off the normal (N·L = cos 60° = 0.5), intensity 1.
SIDE_LIGHT = raytrace.DirectionalLight(direction=[-np.sin(np.pi / 3), 0.0, -np.cos(np.pi / 3)])


def _centroid_pixel(mesh) -> np.ndarray:
    """The pixel seen at TRIANGLE's centroid (0, −1/3, 0) from (0, −1/3, 3), lit by
    SIDE_LIGHT, no ambient."""
    from helpers import aimed_camera, make_scene, pixel

    return pixel(make_scene([mesh], [SIDE_LIGHT], aimed_camera([0, -1 / 3, 3], [0, -1 / 3, 0])))


@pytest.mark.parametrize("encoding", ["binary_little_endian", "ascii"])
def test_a_ply_coloured_by_its_vertices_renders_in_their_colour(tmp_path, encoding):
    """Each vertex the codes (255, 128, 0): c = (1, 0.2158605, 0) linear (sRGB-decoded).
    With the file's material (``from_file``: the default material, kd 0.5, ks 0, its kd and
    ka times the vertex colour, as glTF COLOR_0's), one directional light of 1 at N·L = 0.5,
    no ambient: kd·c·(N·L)·I = 0.5·c·0.5 = (0.25, 0.0539651, 0). Binary: raytrace's reader;
    ASCII: trimesh's. Given a scene material instead (here the default one), the colours are
    not applied (COLOR_0's rule): 0.25 in every channel."""
    path = tmp_path / "t.ply"
    _colored_ply(path, encoding, [[255, 128, 0]] * 3)
    assert (meshio.read_mesh(path) is None) == (encoding == "ascii")
    want = 0.25 * np.array([1.0, SRGB_128, 0.0])
    assert abs(want[1] - 0.0539651) < 1e-7
    got = _centroid_pixel(raytrace.Mesh(file=path, material="from_file"))
    np.testing.assert_allclose(got, want, rtol=1e-6, atol=1e-9)
    np.testing.assert_allclose(_centroid_pixel(raytrace.Mesh(file=path)), 0.25, rtol=1e-6)


def test_vertex_colours_are_interpolated_and_a_ply_rendered_alone_takes_them(tmp_path):
    """Red, green and blue vertices (codes 255 on one channel): at the centroid (barycentrics
    ⅓ each) the colour is (⅓, ⅓, ⅓), kd·c·(N·L) = 0.5·⅓·0.5 = 0.0833333 per channel. The
    PLY rendered alone (``raytrace.load_scene``: its own material, as ``from_file``) carries
    the colours too: its mesh with this test's camera and light gives the same pixel."""
    path = tmp_path / "rgb.ply"
    _colored_ply(path, "binary_little_endian", np.eye(3, dtype=np.uint8) * 255)
    np.testing.assert_allclose(_centroid_pixel(raytrace.Mesh(file=path, material="from_file")),
                               0.5 / 3 * 0.5, rtol=1e-6)
    with pytest.warns(raytrace.RenderWarning):  # (no camera, no light in the file)
        alone = raytrace.load_scene(path)
    np.testing.assert_allclose(alone.objects[0].colors[0, :, :3], np.eye(3))
    np.testing.assert_allclose(_centroid_pixel(alone.objects[0]), 0.5 / 3 * 0.5, rtol=1e-6)


def test_coff_vertex_colours_are_read_as_codes_or_floats(tmp_path):
    """A COFF triangle (trimesh's OFF reader drops the colours): ints above 1 are 8-bit codes,
    floats in [0, 1] are Geomview's colours, code = round(255·x): 0.5 → 128. Both give
    c = (1, 0.2158605, 0): the pixel of the PLY test."""
    want = 0.25 * np.array([1.0, SRGB_128, 0.0])
    for name, color in (("codes", "255 128 0 255"), ("floats", "1 0.5 0 1")):
        path = tmp_path / f"{name}.off"
        path.write_text("COFF\n3 1 0\n" + "".join(f"{x:g} {y:g} {z:g} {color}\n"
                                                  for x, y, z in TRIANGLE) + "3 0 1 2\n")
        got = _centroid_pixel(raytrace.Mesh(file=path, material="from_file"))
        np.testing.assert_allclose(got, want, rtol=1e-6, atol=1e-9)
