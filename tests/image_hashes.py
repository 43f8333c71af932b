"""The image manifest: SHA-256 of every image the scenes and the test suite render, so a change
meant to leave pictures alone (a refactor) can prove it did, bit for bit.

Two parts, both written to ``tests/references/image_hashes.json``:

* ``scenes``: every file of ``scenes/`` rendered at 64×48 with 1 and 4 samples a pixel, with
  the depth, normal, albedo and id AOVs, with a Gaussian filter, with adaptive anti-aliasing
  and as a crop (:data:`SCENE_SETTINGS`);
* ``suite``: every :class:`raytrace.Image` the default test suite makes, test by test
  (recorded by this module as a pytest plugin, loaded by ``tests/conftest.py`` when
  ``RAYTRACE_IMAGE_HASHES`` names a folder). Images a second run of the same commit does not
  make again (random property examples) are left out; a check counts an image as unmoved when
  any test of its run makes that hash (a module-scoped fixture's image counts for whichever
  test asks for it first, which depends on how xdist shares the tests out).

The hashes are of the float32 bytes on this machine: numba, numpy and the CPU's instruction
set are recorded beside them, and a check on another platform is reported as such.

    python3 tests/image_hashes.py record     # at the commit pictures must not move from
    python3 tests/image_hashes.py check      # after the change: prints each image that moved
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import platform
import subprocess
import sys
import tempfile
import warnings
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
MANIFEST = ROOT / "tests" / "references" / "image_hashes.json"
#: The environment variable naming the folder the plugin writes its records to.
ENV = "RAYTRACE_IMAGE_HASHES"


def digest(image) -> str:
    """SHA-256 of an image's RGB and its AOVs (by name), as their array bytes and shapes."""
    h = hashlib.sha256()
    for name, a in (("rgb", image.rgb), *sorted(image.aovs.items())):
        a = np.ascontiguousarray(a)
        h.update(f"{name}{a.dtype}{a.shape}".encode())
        h.update(a.tobytes())
    return h.hexdigest()[:32]


# -- the pytest plugin -----------------------------------------------------------------------
class Recorder:
    """Hooks every ``raytrace.Image`` made while a test runs; writes one JSON line a test."""

    def __init__(self, folder: Path):
        import raytrace

        self.folder = folder
        self.current: str | None = None
        self.images: list[str] = []
        cls = raytrace.Image
        init = cls.__init__
        recorder = self

        def recording_init(self, *args, **kwargs):
            init(self, *args, **kwargs)
            if recorder.current is not None:
                recorder.images.append(digest(self))

        cls.__init__ = recording_init
        worker = os.environ.get("PYTEST_XDIST_WORKER", "main")
        self.out = (folder / f"{worker}-{os.getpid()}.jsonl").open("a")

    def pytest_runtest_setup(self, item) -> None:
        self.current, self.images = item.nodeid, []

    def pytest_runtest_teardown(self, item) -> None:
        if self.current is not None and self.images:
            self.out.write(json.dumps({"test": self.current, "images": self.images}) + "\n")
            self.out.flush()
        self.current = None


def plugin_from_env(config) -> None:
    """Register the :class:`Recorder` when ``RAYTRACE_IMAGE_HASHES`` names a folder."""
    folder = os.environ.get(ENV)
    if folder:
        config.pluginmanager.register(Recorder(Path(folder)), "raytrace-image-hashes")
        # hypothesis replays the examples earlier runs saved in .hypothesis/ before its own,
        # so a property test's images depended on the runs before it (16 of test_extremes'
        # 49 were not in a manifest recorded a few runs earlier); without the database a
        # derandomized test draws the same examples every run
        from hypothesis import settings

        settings.register_profile("image-hashes", database=None)
        settings.load_profile("image-hashes")


# -- the scenes ------------------------------------------------------------------------------
#: The settings every scene is rendered at (keyword arguments of ``raytrace.render``).
SCENE_SETTINGS = {
    "spp1": {"spp": 1},
    "spp4": {"spp": 4},
    "aovs": {"spp": 2, "aovs": ("depth", "normal", "albedo", "id")},
    "gaussian": {"spp": 2, "filter": "gaussian"},
    "adaptive": {"aa": "adaptive"},
    "crop": {"spp": 2, "crop": (10, 8, 41, 30)},
}


def scene_hashes() -> dict[str, str]:
    """Every scene of ``scenes/`` at 64×48 in each of :data:`SCENE_SETTINGS`."""
    import raytrace

    out = {}
    for path in sorted((ROOT / "scenes").glob("*.toml")) + sorted(
            (ROOT / "scenes").glob("*.glb")):
        scene = raytrace.load_scene(path)
        for name, kwargs in SCENE_SETTINGS.items():
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                image = raytrace.render(scene, width=64, height=48, threads=2, **kwargs)
            out[f"{path.name}:{name}"] = digest(image)
    return out


def suite_hashes(extra: list[str]) -> dict[str, list[str]]:
    """Every image of the default test suite, by test id (one run)."""
    with tempfile.TemporaryDirectory() as folder:
        env = dict(os.environ, **{ENV: folder})
        subprocess.run([sys.executable, "-m", "pytest", "-q", "-n", "2", "-p", "no:cacheprovider",
                        *extra], cwd=ROOT, env=env, check=False)
        out: dict[str, list[str]] = {}
        for f in Path(folder).glob("*.jsonl"):
            for line in f.read_text().splitlines():
                rec = json.loads(line)
                out[rec["test"]] = rec["images"]
    return dict(sorted(out.items()))


def platform_info() -> dict:
    import numba

    flags = ""
    try:
        cpuinfo = Path("/proc/cpuinfo").read_text()
        flags = next(line for line in cpuinfo.splitlines() if line.startswith("flags"))
    except (OSError, StopIteration):
        pass
    return {"machine": platform.machine(), "numpy": np.__version__, "numba": numba.__version__,
            "cpu_flags": hashlib.sha256(flags.encode()).hexdigest()[:16]}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("action", choices=("record", "check"))
    parser.add_argument("--no-suite", action="store_true", help="the scenes only")
    parser.add_argument("pytest_args", nargs="*", help="more pytest arguments")
    args = parser.parse_args(argv)
    scenes = scene_hashes()
    suite = {} if args.no_suite else suite_hashes(args.pytest_args)
    if args.action == "record":
        if not args.no_suite:  # keep only the images a second run makes again
            again = suite_hashes(args.pytest_args)
            made = {h for images in again.values() for h in images}
            suite = {k: [h for h in v if h in made] for k, v in suite.items()}
        MANIFEST.write_text(json.dumps({"platform": platform_info(), "scenes": scenes,
                                        "suite": suite}, indent=1) + "\n")
        print(f"recorded {len(scenes)} scene images and {sum(map(len, suite.values()))} images "
              f"of {len(suite)} tests in {MANIFEST.relative_to(ROOT)}")
        return 0
    manifest = json.loads(MANIFEST.read_text())
    if manifest["platform"] != platform_info():
        print(f"note: recorded on {manifest['platform']}, checked on {platform_info()}")
    moved = [k for k, v in manifest["scenes"].items() if scenes.get(k) != v]
    gone = [k for k in manifest["suite"] if k not in suite] if suite else []
    # A module-scoped fixture's image counts for whichever test asks for it first (that
    # depends on how xdist shares the tests out): an image moved when its hash is made by
    # no test of this run.
    made = {h for images in suite.values() for h in images}
    changed = [k for k, v in manifest["suite"].items() if k in suite and not set(v) <= made]
    for k in moved:
        print(f"scene image moved: {k}")
    for k in changed:
        print(f"test image moved: {k}")
    for k in gone:
        print(f"test no longer renders (renamed or removed?): {k}")
    checked = len(manifest["scenes"]) + sum(len(v) for k, v in manifest["suite"].items()
                                            if k in suite)
    print(f"{checked} images checked: {len(moved)} scene images and {len(changed)} tests' "
          f"images moved, {len(gone)} tests not found")
    return 1 if moved or changed else 0


if __name__ == "__main__":
    sys.exit(main())
