"""Render every scene in scenes/ into docs/gallery/ and write docs/gallery.md.

    python3 docs/make_gallery.py

One script, so that the pictures always match the code: run it after any change that alters a
picture. Each scene is rendered ``WIDTH`` pixels wide (the height keeps the scene's aspect
ratio) with the recommended final-quality settings ``SETTINGS`` (docs/knobs.md#adaptive-or-
uniform-anti-aliasing), and saved as an sRGB PNG preview (clip tone map, exposure 0) of the
linear render. The page shows each picture with the scene's own header comment, the command
that renders it at full size, deterministic numbers from the render (size, ray counts) and
the render's wall seconds on this run (with the load average, since other processes change
them).
"""

from __future__ import annotations

import os
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))  # run from a checkout without installing

import raytrace  # noqa: E402
from raytrace.film import write_png  # noqa: E402
from raytrace.scene import Sphere  # noqa: E402

SCENES = ROOT / "scenes"
OUT = ROOT / "docs" / "gallery"
PAGE = ROOT / "docs" / "gallery.md"
WIDTH = 400
#: The recommended settings for final images (docs/knobs.md): uniform stratified samples.
SETTINGS = {"spp": 16}
SETTINGS_TEXT = "16 samples per pixel (a 4×4 stratified grid, box filter)"
#: Scenes shown first, in this order; the rest follow alphabetically.
FIRST = ("whitted", "cornell_box", "materials_showcase")


def scene_files() -> list[Path]:
    """Every scene file in scenes/ (TOML, JSON or a GLB alone), the FIRST ones first."""
    files = sorted(p for p in SCENES.iterdir() if p.suffix in (".toml", ".json", ".glb"))
    rank = {name: i for i, name in enumerate(FIRST)}
    return sorted(files, key=lambda p: (rank.get(p.stem, len(rank)), p.stem))


def header_comment(path: Path) -> list[str]:
    """The scene file's leading comment block, without the ``#``; a GLB's
    ``asset.extras.description`` lines."""
    if path.suffix == ".glb":
        import pygltflib

        extras = pygltflib.GLTF2().load(str(path)).asset.extras or {}
        return list(extras.get("description", []))
    lines = []
    for line in path.read_text(encoding="utf-8").splitlines():
        if not line.startswith("#"):
            break
        lines.append(line[1:].removeprefix(" "))
    return lines


def size_for(scene: raytrace.Scene) -> tuple[int, int]:
    """WIDTH wide, with the aspect ratio of the scene's own [render] size."""
    r = scene.render
    return WIDTH, max(1, round(WIDTH * r.height / r.width))


def sphere_grid(scene: raytrace.Scene) -> list[list[str]]:
    """Material names of the scene's spheres as rows (top first) of columns (left first)."""
    spheres = [o for o in scene.objects if isinstance(o, Sphere)]
    rows: dict[float, list[Sphere]] = {}
    for s in spheres:
        rows.setdefault(round(float(s.center[1]), 6), []).append(s)
    return [[s.material.name for s in sorted(rows[y], key=lambda s: s.center[0])]
            for y in sorted(rows, reverse=True)]


def grid_table(grid: list[list[str]]) -> list[str]:
    width = max(len(r) for r in grid)
    head = "| row | " + " | ".join(str(c + 1) for c in range(width)) + " |"
    rule = "|---|" + "---|" * width
    body = [f"| {i + 1} | " + " | ".join(f"`{n}`" for n in row) + " |" * (width - len(row) + 1)
            for i, row in enumerate(grid)]
    return [head, rule, *body]


def render_one(path: Path, threads: int) -> tuple[raytrace.Scene, dict]:
    """Render one scene file to docs/gallery/<name>.png; the scene and the render stats."""
    scene = raytrace.load_scene(path)
    w, h = size_for(scene)
    # untimed: the scene's kernels compiled (or loaded) and its BVH built, so the seconds
    # under each picture are the render's, not numba's
    raytrace.render(scene, width=16, height=max(1, round(16 * h / w)), threads=threads,
                    **SETTINGS)
    t0 = time.perf_counter()
    image = raytrace.render(scene, width=w, height=h, threads=threads, **SETTINGS)
    image.stats["wall"] = time.perf_counter() - t0
    if image.stats["nonfinite_pixels"]:
        raise RuntimeError(f"{path.name}: {image.stats['nonfinite_pixels']} non-finite pixels")
    OUT.mkdir(parents=True, exist_ok=True)
    write_png(OUT / f"{path.stem}.png", image.rgb)
    return scene, image.stats


def section(path: Path, stats: dict, scene: raytrace.Scene) -> list[str]:
    """The page's part for one scene: picture, header comment, command, numbers."""
    full = (scene.render.width, scene.render.height)
    rel = path.relative_to(ROOT).as_posix()
    comment = header_comment(path)
    # The "Render:" line (and its indented continuation lines) is shown as a command block
    # below; keep the prose.
    prose, command, in_render = [], [], False
    for line in comment:
        in_render = line.startswith("Render:") or (in_render and line[:1].isspace())
        if in_render:
            command.append(line.removeprefix("Render:").strip())
        else:
            prose.append(line)
    command_line = " ".join(command) or (
        f"raytrace render {rel} -o {path.stem}.exr --png {path.stem}.png")
    rays = stats["rays"]
    out = [f"## {path.stem}", "", f"![{path.stem}](gallery/{path.stem}.png)", ""]
    if prose:
        out += ["```text", *prose, "```", ""]
    out += [
        f"Scene file: [`{rel}`](../{rel}). Full size ({full[0]}×{full[1]}):",
        "",
        "```sh",
        command_line,
        "```",
        "",
        f"This picture: {stats['width']}×{stats['height']}, spp {stats['spp']}, "
        f"max_depth {stats['max_depth']}; {rays['total']:,} rays ({rays['camera']:,} camera, "
        f"{rays['shadow']:,} shadow, {rays['reflection']:,} reflection, "
        f"{rays['refraction']:,} refraction"
        + (f", {rays['see_through']:,} see-through" if rays.get("see_through") else "")
        + ")"
        + (f"; {stats['triangles']:,} triangles" if stats.get("triangles") else "")
        + (f"; {stats['total_internal_reflections']:,} total internal reflections"
           if stats.get("total_internal_reflections") else "")
        + f"; rendered in {stats['wall']:.1f} s.",
        "",
    ]
    if path.stem == "materials_showcase":
        out += ["The spheres by grid position (row 1 is the top row, column 1 the left "
                "column):", "", *grid_table(sphere_grid(scene)), ""]
    return out


def main() -> int:
    threads = os.cpu_count() or 1
    files = scene_files()
    page = [
        "# Gallery",
        "",
        "Every scene in [`scenes/`](../scenes) as a picture, with what it shows and the "
        "command that renders it. The facts that matter most:",
        "",
        f"* {len(files)} scenes: "
        + ", ".join(f"[{p.stem}](#{p.stem})" for p in files) + ".",
        "* The text under each picture is the scene file's own header comment: the file is "
        "the worked example to copy (the format: [scene_format.md](scene_format.md); the "
        "shading model: [shading.md](shading.md)).",
        f"* Each picture is {WIDTH} pixels wide with {SETTINGS_TEXT}, the recommended "
        "final-quality setting ([knobs.md](knobs.md#adaptive-or-uniform-anti-aliasing)), an "
        "sRGB preview of the linear render (clipped at 1, no exposure change); the full size "
        "is given beside each command.",
        "* The ray counts under each picture are exact and deterministic. The whole gallery "
        "rendered in {total} s of wall time on {threads} threads (load average {load} from "
        "other processes at the start; each picture's seconds are under it; measured "
        "performance: [performance.md](performance.md)).",
        "",
        "This page and its pictures are written by [`docs/make_gallery.py`](make_gallery.py); "
        "regenerate them after any change that alters a picture:",
        "",
        "```sh",
        "python3 docs/make_gallery.py",
        "```",
        "",
    ]
    load = os.getloadavg()[0]
    total = time.perf_counter()
    for path in files:
        t0 = time.perf_counter()
        scene, stats = render_one(path, threads)
        print(f"{path.stem:24s} {stats['width']}x{stats['height']}  "
              f"{time.perf_counter() - t0:6.1f} s  {stats['rays']['total']:>10,} rays")
        page += section(path, stats, scene)
    seconds = time.perf_counter() - total
    text = "\n".join(page).rstrip() + "\n"
    text = text.replace("{total}", f"{seconds:.0f}").replace("{threads}", str(threads)).replace(
        "{load}", f"{load:.1f}")
    PAGE.write_text(text, encoding="utf-8")
    print(f"wrote {len(files)} pictures to {OUT.relative_to(ROOT)}/ and "
          f"{PAGE.relative_to(ROOT)} in {time.perf_counter() - total:.1f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
