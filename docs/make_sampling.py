"""The pictures of docs/sampling.md: each filter, and uniform against adaptive sampling, on a
crop of the Whitted scene's checker floor at the horizon, enlarged 4× (nearest neighbour).

    python3 docs/make_sampling.py

Prints each render's camera samples and seconds (one thread).
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))  # run from a checkout without installing

import raytrace  # noqa: E402
from raytrace.film import write_png  # noqa: E402

OUT = ROOT / "docs" / "sampling"
W, H = 640, 480
CROP = (40, 200, 200, 300)  # the floor's far edge and the mirror sphere's reflection
ZOOM = 4


def render(name: str, **kw) -> None:
    scene = raytrace.load_scene(ROOT / "scenes" / "whitted.toml")
    t0 = time.perf_counter()
    image = raytrace.render(scene, width=W, height=H, crop=CROP, threads=1, **kw)
    seconds = time.perf_counter() - t0
    big = np.repeat(np.repeat(image.rgb, ZOOM, axis=0), ZOOM, axis=1)
    write_png(OUT / f"{name}.png", big)
    print(f"{name}: {image.stats['rays']['camera']} camera samples, {seconds:.2f} s")


if __name__ == "__main__":
    OUT.mkdir(exist_ok=True)
    render("filter_box_1spp", spp=1)
    for f in ("box", "tent", "gaussian", "mitchell"):
        render(f"filter_{f}_4spp", spp=4, filter=f)
    render("uniform_16spp", spp=16)
    render("adaptive_t0.05_d2", aa="adaptive", aa_threshold=0.05, aa_depth=2)
