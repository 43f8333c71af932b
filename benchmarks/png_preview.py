"""What a PNG preview costs: PNG libraries compared, and raytrace's preview per tone map.

    python3 benchmarks/png_preview.py                  # 4000×3000 (renders it once, ~20 s)
    python3 benchmarks/png_preview.py --size 640x480   # a smoke run
    python3 benchmarks/png_preview.py --parts preview --image my_render.exr

The image is ``scenes/whitted.toml`` rendered at ``--size`` (kept in ``--workdir``), or any EXR
(``--image``); ``--noisy`` also runs every row on it times (1 + 5 % Gaussian noise), a stand-in
for a Monte-Carlo render that zlib cannot shrink.

Every row runs in a fresh Python process that loads the image, makes one small preview (so
imports, numba's cache and the sRGB tables are loaded), resets the peak-memory mark
(``/proc/self/clear_refs``), then runs the row ``--repeat`` times: **seconds** is the fastest,
**peak MB** the largest resident memory above what the process held before (VmHWM − VmRSS).
**cold s** is a second process's first call, imports included (what ``raytrace render --png``
pays once). Bounds of issue 20: a 4000×3000 preview adds under 0.5 s and under 150 MB.

Parts (``--parts``):

``writers``
    The same 8-bit sRGB codes written by each PNG library at its default settings, where it is
    installed: Pillow, imageio (its Pillow plugin), colour-science's ``colour.io.write_image``
    (methods Imageio and OpenImageIO: it takes floats in [0, 1]), OpenImageIO itself (libpng's
    filter choice and zlib level as columns), and the hand-written encoder raytrace had before
    (no row filter, zlib level 6, on a full copy). 16-bit rows where the library can write
    16-bit RGB.
``preview``
    ``raytrace.film.write_png`` as shipped, from the float32 image: each tone map of
    :data:`raytrace.film.tonemap.TONEMAPS` at exposure 0, ``clip`` and ``reinhard2004`` with
    ``auto``, and 16-bit ``clip``.
``cli``
    ``raytrace render scenes/whitted.toml`` at ``--size`` on 2 threads, without and with
    ``--png``, twice each: whole-process seconds and peak resident memory (``ru_maxrss``).

``--checkout DIR`` measures the raytrace of another checkout (e.g. ``git worktree add
/tmp/old 6261a80``, the commit before issue 20): its ``preview`` part is then the default row
only (``clip``, exposure 0, 8-bit: all the old ``write_png`` had).
"""

from __future__ import annotations

import argparse
import json
import os
import struct
import subprocess
import sys
import tempfile
import time
import zlib
from pathlib import Path

import numpy as np
from bench_scenes import WHITTED

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
BOUND_SECONDS, BOUND_MB = 0.5, 150.0


def _memory() -> tuple[float, float]:
    """(VmRSS, VmHWM) of this process in MB."""
    fields = dict(line.split(":", 1) for line in Path("/proc/self/status").read_text().splitlines()
                  if ":" in line)
    return (int(fields["VmRSS"].split()[0]) / 1024, int(fields["VmHWM"].split()[0]) / 1024)


def _reset_peak() -> None:
    Path("/proc/self/clear_refs").write_text("5")  # VmHWM := VmRSS (Linux)


def _old_png(pixels: np.ndarray) -> bytes:
    """raytrace's encoder before issue 20 (8-bit RGB, no row filter, zlib level 6)."""
    h, w, _ = pixels.shape
    raw = np.concatenate([np.zeros((h, 1), np.uint8), pixels.reshape(h, w * 3)], axis=1)

    def chunk(kind: bytes, data: bytes) -> bytes:
        return (struct.pack(">I", len(data)) + kind + data
                + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF))

    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 2, 0, 0, 0))
            + chunk(b"IDAT", zlib.compress(raw.tobytes(), 6)) + chunk(b"IEND", b""))


def _oiio(path: str, codes: np.ndarray, png_filter: int, level: int) -> None:
    import OpenImageIO as oiio

    spec = oiio.ImageSpec(codes.shape[1], codes.shape[0], 3,
                          oiio.UINT8 if codes.dtype == np.uint8 else oiio.UINT16)
    spec.attribute("png:filter", png_filter)
    spec.attribute("png:compressionLevel", level)
    out = oiio.ImageOutput.create(path)
    assert out.open(path, spec) and out.write_image(codes) and out.close(), oiio.geterror()


#: name → (module that must be importable, function(path, codes)): codes (H, W, 3) uint8|16.
WRITERS = {
    "Pillow": ("PIL", lambda p, c: __import__("PIL.Image").Image.fromarray(c).save(p)),
    "imageio (Pillow)": ("imageio", lambda p, c: __import__("imageio.v3").v3.imwrite(p, c)),
    "colour.io Imageio": ("imageio", lambda p, c: _colour_io(p, c, "Imageio")),
    "colour.io OpenImageIO": ("OpenImageIO", lambda p, c: _colour_io(p, c, "OpenImageIO")),
    "hand-written (before)": ("zlib", lambda p, c: Path(p).write_bytes(_old_png(c))),
}
for _filter, _fname in ((0x08, "none"), (0x20, "up"), (0x80, "paeth"), (0xF8, "adaptive")):
    for _level in (1, 6):
        WRITERS[f"OpenImageIO {_fname} z{_level}"] = (
            "OpenImageIO", lambda p, c, f=_filter, z=_level: _oiio(p, c, f, z))


def _colour_io(path: str, codes: np.ndarray, method: str) -> None:
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        import colour
    top = np.iinfo(codes.dtype).max
    colour.io.write_image(codes / np.float32(top), path, str(codes.dtype), method=method)


def _load(args: dict) -> np.ndarray:
    from raytrace.film import read_exr

    rgb = read_exr(args["image"])[0]
    if args["noisy"]:
        noise = np.random.default_rng(0).standard_normal(rgb.shape, dtype=np.float32)
        rgb *= 1.0 + 0.05 * noise
    return rgb


def child(args: dict) -> dict:
    """One row, in this (fresh) process: see the module docstring."""
    rgb = _load(args)
    folder = tempfile.mkdtemp()
    path = os.path.join(folder, "p.png")
    if args["kind"] == "preview":
        from raytrace.film import write_png

        extra = {"bits": args["bits"]} if args["bits"] != 8 else {}  # the old one had no bits

        def run(target):
            write_png(target, rgb, args["exposure"], args["tonemap"], **extra)
    else:
        from raytrace.film import preview

        codes = preview(rgb, bits=args["bits"])
        fn = WRITERS[args["writer"]][1]

        def run(target):
            fn(target, codes)
    if args["cold"]:
        t = time.perf_counter()
        run(path)
        return {"cold": time.perf_counter() - t}
    run(os.path.join(folder, "warm.png")) if args["kind"] == "writer" else _warm(args)
    rss, _ = _memory()
    _reset_peak()
    best = float("inf")
    for _ in range(args["repeat"]):
        t = time.perf_counter()
        run(path)
        best = min(best, time.perf_counter() - t)
    return {"seconds": best, "peak_mb": _memory()[1] - rss, "file_mb": os.path.getsize(path) / 1e6}


def _warm(args: dict) -> None:
    from raytrace.film import write_png

    small = np.random.default_rng(1).random((16, 16, 3), dtype=np.float32)
    extra = {"bits": args["bits"]} if args["bits"] != 8 else {}
    write_png(os.path.join(tempfile.mkdtemp(), "w.png"), small, args["exposure"],
              args["tonemap"], **extra)


def _spawn(args: dict) -> dict:
    checkout = args.get("checkout") or str(ROOT)
    env = {**os.environ, "PYTHONPATH": checkout}  # ahead of the installed raytrace
    out = subprocess.run([sys.executable, __file__, "--child", json.dumps(args)],
                         capture_output=True, text=True, cwd=checkout, env=env)
    if out.returncode:
        return {"error": out.stderr.strip().splitlines()[-1]}
    return json.loads(out.stdout.strip().splitlines()[-1])


def measure(kind: str, image: str, *, writer: str = "", tonemap: str = "clip",
            exposure: float | str = 0.0, bits: int = 8, noisy: bool = False, repeat: int = 3,
            cold: bool = True, checkout: str | None = None) -> dict:
    """One row: warm seconds and peak MB (and cold seconds), each in a fresh process."""
    args = {"kind": kind, "image": str(image), "writer": writer, "tonemap": tonemap,
            "exposure": exposure, "bits": bits, "noisy": noisy, "repeat": repeat, "cold": False,
            "checkout": checkout}
    row = _spawn(args)
    if cold and "error" not in row:
        row.update(_spawn({**args, "cold": True}))
    return row


def render_cli(checkout: str, size: tuple[str, str], png: bool, workdir: str) -> dict:
    """``raytrace render`` of the Whitted scene in a fresh process: seconds, peak MB."""
    code = ("import resource, subprocess, sys, time\n"
            "t = time.perf_counter()\n"
            "subprocess.run(sys.argv[1:], check=True)\n"
            "print(time.perf_counter() - t, "
            "resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024)")
    cmd = [sys.executable, "-m", "raytrace", "render", str(WHITTED), "-o",
           os.path.join(workdir, "cli.exr"), "--width", size[0], "--height", size[1],
           "--threads", "2", "-q"] + (["--png", os.path.join(workdir, "cli.png")] if png else [])
    out = subprocess.run([sys.executable, "-c", code, *cmd], capture_output=True, text=True,
                         cwd=checkout, env={**os.environ, "PYTHONPATH": checkout}, check=True)
    seconds, mb = map(float, out.stdout.split())
    return {"seconds": seconds, "peak_mb": mb}


def _cells(row: dict) -> list[str]:
    if "error" in row:
        return ["error: " + row["error"][:60], "", "", "", ""]
    ok = row["seconds"] < BOUND_SECONDS and row["peak_mb"] < BOUND_MB
    return [f"{row['seconds']:.3f}", f"{row['peak_mb']:.0f}", f"{row['file_mb']:.2f}",
            f"{row.get('cold', float('nan')):.2f}", "yes" if ok else "no"]


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--size", default="4000x3000", help="WxH of the Whitted render")
    p.add_argument("--image", help="an EXR to use instead of rendering")
    p.add_argument("--parts", default="writers,preview,cli")
    p.add_argument("--noisy", action="store_true", help="also the noisy variant")
    p.add_argument("--repeat", type=int, default=3, help="runs per row (fastest kept)")
    p.add_argument("--workdir", default=tempfile.gettempdir())
    p.add_argument("--checkout", default=str(ROOT), help="the raytrace checkout to measure")
    p.add_argument("--child", help=argparse.SUPPRESS)
    a = p.parse_args(argv)
    if a.child:
        print(json.dumps(child(json.loads(a.child))))
        return 0
    image = a.image
    if not image:
        w, h = a.size.lower().split("x")
        image = str(Path(a.workdir) / f"whitted_{w}x{h}.exr")
        if not Path(image).exists():
            subprocess.run([sys.executable, "-m", "raytrace", "render",
                            str(WHITTED), "-o", image, "--width", w,
                            "--height", h, "-q"], check=True)
    from bench import table  # the table layout of the other benchmarks

    from raytrace.film import read_exr

    h, w = read_exr(image)[0].shape[:2]
    checkout = str(Path(a.checkout).resolve())
    print(f"image {image}: {w}×{h}; load average {os.getloadavg()[0]:.2f}; "
          f"{os.cpu_count()} cores; bounds {BOUND_SECONDS} s, {BOUND_MB:.0f} MB; "
          f"raytrace from {checkout}")
    heads = ["seconds", "peak MB", "file MB", "cold s", "in bounds"]
    for noisy in (False, True) if a.noisy else (False,):
        label = "noisy" if noisy else "render"
        if "writers" in a.parts:
            rows = []
            for name, (module, _) in WRITERS.items():
                try:
                    __import__(module)
                except ImportError:
                    continue
                for bits in (8,) if name.startswith("hand-written") else (8, 16):
                    r = measure("writer", image, writer=name, bits=bits, noisy=noisy,
                                repeat=a.repeat, cold=False)
                    if bits == 16 and "error" in r:
                        continue  # this library cannot write 16-bit RGB PNG
                    rows.append([name, str(bits), *_cells(r)[:3]])
            print(f"\nPNG writers, {label}: the same sRGB codes\n")
            print(table(["writer", "bits", *heads[:3]], rows))
        if "preview" in a.parts:
            from raytrace.film.tonemap import TONEMAPS

            cases = [(t, 0.0, 8) for t in TONEMAPS] + [("clip", "auto", 8),
                                                       ("reinhard2004", "auto", 8),
                                                       ("clip", 0.0, 16)]
            if checkout != str(ROOT):
                cases = [("clip", 0.0, 8)]
            rows = [[t, str(e), str(b),
                     *_cells(measure("preview", image, tonemap=t, exposure=e, bits=b,
                                     noisy=noisy, repeat=a.repeat, checkout=checkout))]
                    for t, e, b in cases]
            print(f"\nraytrace.film.write_png, {label}\n")
            print(table(["tonemap", "exposure", "bits", *heads], rows))
    if "cli" in a.parts:
        rows = []
        for png in (False, True, False, True):
            r = render_cli(checkout, (str(w), str(h)), png, a.workdir)
            rows.append(["with --png" if png else "EXR only", f"{r['seconds']:.2f}",
                         f"{r['peak_mb']:.0f}"])
        print(f"\nraytrace render scenes/whitted.toml at {w}×{h}, 2 threads\n")
        print(table(["render", "seconds", "peak MB"], rows))
    return 0


if __name__ == "__main__":
    sys.exit(main())
