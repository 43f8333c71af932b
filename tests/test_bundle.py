"""A scene read from files, sent as those files' bytes (raytrace/readers/bundle.py).

The invariants: what travels is the files' bytes (each file the readers opened, byte for byte)
and a small pickle, not the decoded textures; the scene read back from those bytes alone, with
the original folders gone, renders bit-identical to the scene on the client, edits made after
loading included; it is read once per process; what cannot travel as files travels pickled
whole; and a process that reads the files into other arrays is refused in one line.
"""

from __future__ import annotations

import os
import pickle
from pathlib import Path

import numpy as np
import pytest
from helpers import write_gltf, write_png

import raytrace
from raytrace.readers import bundle
from raytrace.readers.scene_file import load_scene

ROOT = Path(__file__).resolve().parents[1]
KW = {"width": 32, "height": 24, "threads": 1}


def noise(n: int, seed: int) -> np.ndarray:
    """n×n 8-bit RGB noise: a PNG of it barely compresses, and decoded it is 16 bytes a texel
    (float32 RGBA) against about 3 in the file."""
    return np.random.default_rng(seed).integers(0, 256, (n, n, 3), dtype=np.uint8)


def shot(tmp_path: Path, absolute: bool = False) -> Path:
    """shot/scene.toml naming ../assets/model.gltf (its buffer in model.bin, its image
    tex/t.png) and a sphere textured with wood.png beside the TOML: five files, found by
    relative paths (or the model by its absolute one)."""
    assets, folder = tmp_path / "assets", tmp_path / "shot"
    (assets / "tex").mkdir(parents=True)
    folder.mkdir()
    square = {"positions": [[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]],
              "indices": [[0, 1, 2], [0, 2, 3]], "uv": [[0, 1], [1, 1], [1, 0], [0, 0]],
              "material": 0}
    mat = [{"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}, "metallicFactor": 0,
                                     "roughnessFactor": 1}}]
    model = write_gltf(assets / "model.gltf", [{"mesh": 0}], [square], mat, extra={
        "textures": [{"source": 0}], "images": [{"uri": "tex/t.png"}]}, buffer_file="model.bin")
    write_png(assets / "tex" / "t.png", noise(64, 1))
    write_png(folder / "wood.png", noise(64, 2))
    name = str(model) if absolute else "../assets/model.gltf"
    (folder / "scene.toml").write_text(
        '[camera]\nposition = [0, 0, 4]\nlook_at = [0, 0, 0]\n'
        '[[lights]]\ntype = "point"\nposition = [0, 1, 4]\n'
        f'[[objects]]\ntype = "mesh"\nfile = "{name}"\nmaterial = "from_file"\n'
        '[[objects]]\ntype = "sphere"\ncenter = [1.2, 0.4, 0.5]\nradius = 0.5\n'
        'material = { kd = { texture = "wood.png" } }\n')
    return folder / "scene.toml"


def same_bits(a: np.ndarray, b: np.ndarray) -> bool:
    return a.dtype == b.dtype and np.array_equal(a.view(np.uint8), b.view(np.uint8))


def test_a_scene_travels_as_its_files_and_reads_back_the_same_without_them(tmp_path):
    path = shot(tmp_path)
    scene = load_scene(path)
    reference = raytrace.render(scene, **KW).rgb
    assert np.ptp(reference) > 0.1  # textures, lights: not a flat image
    b = bundle.pack(scene)
    names = ["shot/scene.toml", "assets/model.gltf", "assets/model.bin", "assets/tex/t.png",
             "shot/wood.png"]
    assert b.source == str(tmp_path / "shot" / "scene.toml")
    assert sorted(b.files) == sorted(str(tmp_path / n) for n in names)
    assert all(b.files[str(tmp_path / n)] == (tmp_path / n).read_bytes() for n in names)
    # two 64×64 textures are 2 × 16 KB of 8-bit codes; the files are ~25 kB and the rest a
    # few kB: the files and the rest travel in less than the scene pickled whole
    sent = len(pickle.dumps(b))
    assert sent <= 2 * b.file_bytes, (sent, b.file_bytes)
    assert sent < len(pickle.dumps(scene))

    for n in ("shot", "assets"):  # the client's files are gone: only the bytes remain
        (tmp_path / n).rename(tmp_path / f"gone_{n}")
    given = []

    def load(p: Path):
        given.append(p)
        return load_scene(p)

    back = bundle.unpack(pickle.loads(pickle.dumps(b)), load)
    assert given[0] != path and str(given[0]).endswith(str(path))
    assert back.path == scene.path  # the client's names, in metadata and errors
    assert same_bits(raytrace.render(back, **KW).rgb, reference)
    bundle.unpack(b, load)  # a second tile or frame of the same files reads nothing
    assert len(given) == 1


def test_edits_made_after_loading_travel_with_the_scene(tmp_path):
    scene = raytrace.load_scene(ROOT / "scenes" / "gltf_scene.glb")
    mesh = scene.objects[0]
    scene.camera = raytrace.Camera(position=[0.5, 2.5, 6.0], look_at=[0, 0.5, 0], fov=35)
    mesh.vertices[:, 1] += 0.25  # in place: an array read from the file, edited
    mesh.file_materials[1] = raytrace.Material(kd=[0.2, 0.6, 0.3])
    b = bundle.pack(scene)
    assert b.source is not None
    back = bundle.unpack(b, load_scene)
    np.testing.assert_array_equal(back.objects[0].vertices, mesh.vertices)
    assert same_bits(raytrace.render(back, **KW).rgb, raytrace.render(scene, **KW).rgb)


def test_what_cannot_travel_as_files_is_pickled_whole(tmp_path):
    made_in_python = raytrace.Scene(objects=[raytrace.Sphere([0, 0, -3], 1)])
    spheres_only = raytrace.load_scene(ROOT / "scenes" / "whitted.toml")  # nothing decoded
    absolute = load_scene(shot(tmp_path / "a", absolute=True))
    changed = load_scene(shot(tmp_path / "c"))
    png = tmp_path / "c" / "shot" / "wood.png"
    os.utime(png, ns=(png.stat().st_atime_ns, png.stat().st_mtime_ns + 10**9))
    for scene in (made_in_python, spheres_only, absolute, changed):
        b = bundle.pack(scene)
        assert (b.source, b.files, b.made) == (None, {}, ())
        assert b.scene == pickle.dumps(scene, protocol=pickle.HIGHEST_PROTOCOL)
    assert bundle.pack(load_scene(shot(tmp_path / "r"))).source is not None


def test_a_process_that_reads_other_arrays_is_refused_in_one_line(tmp_path):
    b = bundle.pack(load_scene(shot(tmp_path)))

    def other(p: Path):  # as a worker with another image decoder would read it
        scene = load_scene(p)
        image = scene.objects[1].material.kd.image
        image.codes = image.codes.copy()
        image.codes[0, 0, 0] ^= 1
        return scene

    with pytest.raises(raytrace.SceneError, match=r"^.*/shot/scene\.toml: this worker read "
                       r"its files into other arrays than the client did \(") as e:
        bundle.unpack(b, other)
    assert e.value.file == b.source


def test_frames_that_share_a_gltf_decode_it_once_per_process(tmp_path):
    # Two frames' scene files naming one model: on a worker the model's bytes land at one
    # path in one folder, so the second frame's read is load_gltf's cache hit.
    from raytrace.readers.gltf import _load_cached

    first = load_scene(shot(tmp_path))
    second_file = tmp_path / "shot" / "second.toml"
    second_file.write_text((tmp_path / "shot" / "scene.toml").read_text().replace(
        "position = [0, 0, 4]", "position = [0.5, 0, 4]"))
    second = load_scene(second_file)
    bundles = [bundle.pack(s) for s in (first, second)]
    assert bundles[0].key() != bundles[1].key()
    bundle.unpack(bundles[0], load_scene)
    hits = _load_cached.cache_info().hits
    back = bundle.unpack(bundles[1], load_scene)
    assert _load_cached.cache_info().hits == hits + 1
    assert same_bits(raytrace.render(back, **KW).rgb, raytrace.render(second, **KW).rgb)
