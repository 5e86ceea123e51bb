"""Build the AutoSCOOP extension zips, one per platform, without a Blender binary.

``python -m headless.build_extension [--out-dir DIR] [--platform P ...]``

Why it works this way:

* The extension CLI (``blender_ext.py``) ships inside the pip ``bpy`` wheel and is
  stdlib-only, so we run it with ``sys.executable``; it is found through
  ``importlib.util.find_spec("bpy")`` because importing ``bpy`` just to find a file
  would start Blender. ``--valid-tags`` points at Blender's own ``tags.py``: the
  standalone CLI skips the tag check otherwise, ``blender --command extension`` does not.
* The repository keeps the manifest at the root and the add-on in ``autoscoop_blender/``,
  which the CLI cannot build from, so the package is staged in a fresh temporary folder
  ``<tmp>/autoscoop/`` (add-on + manifest + ``wheels/``). A fresh folder each run means
  no stale files and two builds at once cannot trip over each other.
* The ``wheels = [...]`` list is written into the *staged* manifest only, never into
  the root one. ``validate`` of a folder does not check that listed wheels exist, so a
  root list would pass ``tests/packaging/test_manifest.py``, but ``build`` fails on any
  listed file that is missing, and a build of some platforms (the test builds
  ``linux-x64`` only) must list only those platforms' wheels and set ``platforms`` to
  them anyway (``--split-platforms`` builds every platform the manifest names). The
  exact filenames are an output of pip for (pin, platform tag); the pins live in one
  place, ``requirements.txt``, so bumping one needs no manifest edit.
* Bundled: scipy and shapely at the versions pinned in ``requirements.txt``. Not numpy:
  Blender ships it and ``bpy`` depends on it, and a second copy would shadow Blender's.
  Only ``cp311`` wheels: ``bpy`` 5.0.1 is Python 3.11, and Blender 5.1 moves to
  Python 3.13, so the root manifest says ``blender_version_max = "5.1.0"``.
* Platform tags: pip expands one ``--platform`` tag to the older compatible ones
  (``macosx_14_0_arm64`` also accepts ``macosx_11_0_arm64``; ``manylinux_2_28_x86_64``
  accepts ``manylinux_2_24`` and ``manylinux2014``), so one tag per platform resolves
  both packages. scipy 1.17.1 has no macOS arm64 wheel below ``macosx_14_0`` and no
  Linux wheel below ``manylinux_2_27``; shapely 2.2.0's are ``macosx_11_0`` and
  ``manylinux_2_24``. The wheels as of this writing::

      linux-x64    scipy-1.17.1-cp311-cp311-manylinux_2_27_x86_64.manylinux_2_28_x86_64.whl
                   shapely-2.2.0-cp311-cp311-manylinux_2_24_x86_64.manylinux_2_28_x86_64.whl
      windows-x64  scipy-1.17.1-cp311-cp311-win_amd64.whl
                   shapely-2.2.0-cp311-cp311-win_amd64.whl
      macos-arm64  scipy-1.17.1-cp311-cp311-macosx_14_0_arm64.whl
                   shapely-2.2.0-cp311-cp311-macosx_11_0_arm64.whl

* Wheels are downloaded once into a cache (default ``build/wheels/``, git-ignored) and
  reused while the file is there and is a readable zip. Downloads land in a temporary
  folder first and are moved in, so an interrupted download never looks cached.
* A platform whose wheels are missing still builds, silently, without them; so every
  zip is opened afterwards and must hold exactly one scipy and one shapely wheel for
  its platform and no numpy. Any failure raises ``BuildError`` with a one-line message.
* Re-running replaces the zips: the expected zips are deleted before the build, so a
  failed build never leaves an old zip that looks new.
"""

from __future__ import annotations

import argparse
import importlib.util
import re
import shutil
import subprocess
import sys
import tempfile
import tomllib
import zipfile
from collections.abc import Callable, Sequence
from pathlib import Path

from autoscoop_blender.core.errors import AutoscoopError
from headless.paths import REPO

SOURCE = REPO / "autoscoop_blender"
MANIFEST = REPO / "blender_manifest.toml"
REQUIREMENTS = REPO / "requirements.txt"
DEFAULT_WHEEL_CACHE = REPO / "build" / "wheels"

PLATFORMS: dict[str, str] = {
    "linux-x64": "manylinux_2_28_x86_64",
    "windows-x64": "win_amd64",
    "macos-arm64": "macosx_14_0_arm64",
}
"""Blender platform -> the pip ``--platform`` tag that finds every bundled wheel."""

BUNDLED: tuple[str, ...] = ("scipy", "shapely", "highspy")
"""Packages shipped as wheels inside the zips (versions from ``requirements.txt``)."""

NOT_BUNDLED: tuple[str, ...] = ("numpy",)
"""Packages Blender itself provides; a zip holding one of them is an error."""

PYTHON_VERSION = "3.11"
PYTHON_TAG = "cp311"

Progress = Callable[[str], None]


class BuildError(AutoscoopError):
    """The extension could not be built; the message names the step and the cause."""


# --- wheels -----------------------------------------------------------------------------


def pinned_versions(requirements: Path = REQUIREMENTS) -> dict[str, str]:
    """The ``NAME==VERSION`` pins of the bundled packages in ``requirements.txt``."""
    pins: dict[str, str] = {}
    for line in requirements.read_text().splitlines():
        m = re.fullmatch(r"\s*([A-Za-z0-9_.-]+)\s*==\s*([^\s;#]+).*", line)
        if m:
            pins[m.group(1).lower()] = m.group(2)
    missing = [name for name in BUNDLED if name not in pins]
    if missing:
        raise BuildError(f"{requirements}: no '==' pin for {', '.join(missing)}")
    return {name: pins[name] for name in BUNDLED}


def wheel_fields(filename: str) -> tuple[str, str, str, tuple[str, ...]]:
    """(distribution, version, python tag, platform tags) of a wheel filename."""
    parts = Path(filename).name.removesuffix(".whl").split("-")
    if not filename.endswith(".whl") or len(parts) not in (5, 6):
        raise BuildError(f"{filename}: not a wheel filename")
    return parts[0].lower(), parts[1], parts[-3], tuple(parts[-1].split("."))


def _platform_of_tag(tag: str) -> set[str]:
    """Blender platforms a single wheel platform tag runs on (only the ones we build)."""
    if tag == "any":
        return set(PLATFORMS)
    if tag.startswith("manylinux") and tag.endswith("_x86_64"):
        return {"linux-x64"}
    if tag == "win_amd64":
        return {"windows-x64"}
    if tag.startswith("macosx_") and tag.endswith(("_arm64", "_universal2")):
        return {"macos-arm64"}
    return set()


def wheel_platforms(filename: str) -> set[str]:
    """Blender platforms a wheel runs on, judged by its filename."""
    return set().union(*(_platform_of_tag(t) for t in wheel_fields(filename)[3]))


def _is_wanted(path: Path, name: str, version: str, platform: str) -> bool:
    dist, ver, python_tag, _ = wheel_fields(path.name)
    return (
        dist == name
        and ver == version
        and PYTHON_TAG in python_tag.split(".")
        and platform in wheel_platforms(path.name)
    )


def _is_readable_zip(path: Path) -> bool:
    try:
        with zipfile.ZipFile(path) as zf:
            return bool(zf.namelist())
    except (OSError, zipfile.BadZipFile):
        return False


def cached_wheel(cache: Path, name: str, version: str, platform: str) -> Path | None:
    """The cached wheel of ``name==version`` for ``platform``, if a readable one is there."""
    for path in sorted(cache.glob(f"{name}-{version}-*.whl")):
        if _is_wanted(path, name, version, platform) and _is_readable_zip(path):
            return path
    return None


def _pip_download(name: str, version: str, tag: str, dest: Path) -> None:
    cmd = [
        sys.executable,
        "-m",
        "pip",
        "download",
        f"{name}=={version}",
        "--no-deps",
        "--only-binary=:all:",
        f"--python-version={PYTHON_VERSION}",
        f"--platform={tag}",
        "--dest",
        str(dest),
        "--quiet",
        "--disable-pip-version-check",
    ]
    proc = subprocess.run(cmd, capture_output=True, text=True)
    if proc.returncode != 0:
        errors = [ln for ln in proc.stderr.splitlines() if ln.startswith("ERROR")]
        reason = (errors or proc.stderr.strip().splitlines() or ["no output"])[-1]
        reason = reason.removeprefix("ERROR: ")
        raise BuildError(f"pip download {name}=={version} --platform={tag} failed: {reason}")


def fetch_wheel(name: str, version: str, platform: str, cache: Path) -> Path:
    """The wheel of ``name==version`` for ``platform``, downloaded into ``cache`` if needed."""
    if (hit := cached_wheel(cache, name, version, platform)) is not None:
        return hit
    cache.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(dir=cache, prefix=".download-") as tmp:
        _pip_download(name, version, PLATFORMS[platform], Path(tmp))
        for path in Path(tmp).glob("*.whl"):
            path.replace(cache / path.name)
    if (hit := cached_wheel(cache, name, version, platform)) is None:
        raise BuildError(
            f"pip download {name}=={version} found no {PYTHON_TAG} wheel for {platform}"
        )
    return hit


def fetch_wheels(platforms: Sequence[str], cache: Path) -> dict[str, list[Path]]:
    """Every bundled wheel for each platform: {platform: [scipy wheel, shapely wheel]}."""
    pins = pinned_versions()
    return {
        p: [fetch_wheel(name, version, p, cache) for name, version in pins.items()]
        for p in platforms
    }


# --- staging ----------------------------------------------------------------------------


def _toml_list(items: Sequence[str]) -> str:
    return "[" + ", ".join(f'"{item}"' for item in items) + "]"


def staged_manifest(text: str, platforms: Sequence[str], wheels: Sequence[str]) -> str:
    """The root manifest narrowed to ``platforms`` and listing ``wheels`` (``./wheels/...``)."""
    root = tomllib.loads(text)
    if "wheels" in root:
        raise BuildError(f"{MANIFEST.name}: remove 'wheels'; the build writes the list")
    if not set(platforms) <= set(root.get("platforms", ())):
        raise BuildError(f"{MANIFEST.name}: 'platforms' lacks some of {', '.join(platforms)}")
    lines = f"platforms = {_toml_list(platforms)}\nwheels = {_toml_list(wheels)}"
    new, count = re.subn(r"(?m)^platforms\s*=.*$", lambda _: lines, text)
    staged = tomllib.loads(new) if count == 1 else {}
    if staged.get("platforms") != list(platforms) or staged.get("wheels") != list(wheels):
        raise BuildError(f"{MANIFEST.name}: 'platforms' must be a one-line top-level list")
    return new


def stage(dest: Path, platforms: Sequence[str], wheels: dict[str, list[Path]]) -> Path:
    """Lay out ``dest/autoscoop/``: the add-on, its manifest and ``wheels/``."""
    folder = dest / "autoscoop"
    shutil.copytree(SOURCE, folder, ignore=shutil.ignore_patterns("__pycache__", "*.pyc"))
    (folder / "wheels").mkdir()
    names: list[str] = []
    for p in platforms:
        for wheel in wheels[p]:
            shutil.copy2(wheel, folder / "wheels" / wheel.name)
            names.append(f"./wheels/{wheel.name}")
    manifest = staged_manifest(MANIFEST.read_text(), platforms, names)
    (folder / "blender_manifest.toml").write_text(manifest)
    return folder


# --- Blender's extension CLI ------------------------------------------------------------


def extension_cli() -> tuple[Path, Path]:
    """(``blender_ext.py``, ``tags.py``) inside the installed bpy wheel, without importing it."""
    spec = importlib.util.find_spec("bpy")
    if spec is None or spec.origin is None:
        raise BuildError("bpy is not installed; pip install -r requirements.txt")
    root = Path(spec.origin).parent
    ext = next(root.glob("*/scripts/addons_core/bl_pkg/cli/blender_ext.py"), None)
    tags = next(root.glob("*/scripts/modules/_bpy_internal/extensions/tags.py"), None)
    if ext is None or tags is None:
        raise BuildError(f"{root}: no blender_ext.py or tags.py in this bpy")
    return ext, tags


def run_cli(*args: str | Path) -> str:
    """Run ``blender_ext.py`` with ``args``; its output, or ``BuildError`` on failure."""
    ext, _ = extension_cli()
    cmd = [sys.executable, str(ext), *map(str, args)]
    proc = subprocess.run(cmd, capture_output=True, text=True)
    output = (proc.stdout + proc.stderr).strip()
    if proc.returncode != 0:
        lines = output.splitlines()
        reason = next((ln for ln in lines if "error" in ln.lower()), lines[-1] if lines else "")
        raise BuildError(f"blender_ext {args[0]} failed: {reason.strip() or 'no output'}")
    return output


def validate(path: Path) -> str:
    """Validate a package folder or zip with Blender's tag list; the CLI's output."""
    _, tags = extension_cli()
    return run_cli("validate", "--valid-tags", tags, path)


# --- zips -------------------------------------------------------------------------------


def zip_name(platform: str) -> str:
    """``autoscoop-<version>-<platform>.zip``, as ``blender_ext build --split-platforms``."""
    manifest = tomllib.loads(MANIFEST.read_text())
    return f"{manifest['id']}-{manifest['version']}-{platform.replace('-', '_')}.zip"


def zip_wheels(path: Path) -> list[str]:
    """Filenames of the wheels inside an extension zip."""
    with zipfile.ZipFile(path) as zf:
        return sorted(Path(n).name for n in zf.namelist() if n.endswith(".whl"))


def check_zip(path: Path, platform: str) -> list[str]:
    """Raise unless the zip holds one wheel per bundled package for ``platform``, no numpy."""
    wheels = zip_wheels(path)
    for name in NOT_BUNDLED:
        if any(wheel_fields(w)[0] == name for w in wheels):
            raise BuildError(f"{path.name}: bundles {name}, which Blender provides")
    for w in wheels:
        if platform not in wheel_platforms(w) or PYTHON_TAG not in wheel_fields(w)[2]:
            raise BuildError(f"{path.name}: wheel {w} is not {PYTHON_TAG} for {platform}")
    for name in BUNDLED:
        count = sum(wheel_fields(w)[0] == name for w in wheels)
        if count != 1:
            raise BuildError(f"{path.name}: {count} {name} wheels for {platform}, expected 1")
    return wheels


def _platform_list(platforms: Sequence[str]) -> list[str]:
    unknown = [p for p in platforms if p not in PLATFORMS]
    if unknown or not platforms:
        raise BuildError(
            f"unknown platform {', '.join(unknown) or '(none)'}; known: {', '.join(PLATFORMS)}"
        )
    return list(dict.fromkeys(platforms))


def build(
    out_dir: Path = Path("dist"),
    platforms: Sequence[str] = tuple(PLATFORMS),
    wheel_cache: Path | None = None,
    *,
    progress: Progress | None = None,
) -> list[Path]:
    """Stage, fetch wheels, validate and build one zip per platform; return the zips."""
    say = progress or (lambda _: None)
    chosen = _platform_list(platforms)
    cache = wheel_cache or DEFAULT_WHEEL_CACHE
    pins = ", ".join(f"{name}=={version}" for name, version in pinned_versions().items())
    say(f"wheels: {pins} (cache {cache})")
    wheels = fetch_wheels(chosen, cache)
    out_dir.mkdir(parents=True, exist_ok=True)
    zips = [out_dir / zip_name(p) for p in chosen]
    for z in zips:
        z.unlink(missing_ok=True)
    _, tags = extension_cli()
    with tempfile.TemporaryDirectory(prefix="autoscoop-build-") as tmp:
        folder = stage(Path(tmp), chosen, wheels)
        say(f"validate {folder}")
        validate(folder)
        say(f"build {', '.join(chosen)} -> {out_dir}")
        run_cli(
            "build",
            "--source-dir",
            folder,
            "--output-dir",
            out_dir,
            "--split-platforms",
            "--valid-tags",
            tags,
        )
    for z, p in zip(zips, chosen):
        if not z.is_file():
            raise BuildError(f"blender_ext build made no {z.name}")
        validate(z)
        say(f"{z}: {', '.join(check_zip(z, p))}")
    return zips


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m headless.build_extension",
        description="Build the AutoSCOOP extension zips, one per platform.",
    )
    parser.add_argument("--out-dir", type=Path, default=Path("dist"), help="default dist/")
    parser.add_argument(
        "--platform",
        action="append",
        choices=tuple(PLATFORMS),
        help="build only this platform (repeatable; default all)",
    )
    parser.add_argument("--wheel-cache", type=Path, help=f"default {DEFAULT_WHEEL_CACHE}")
    args = parser.parse_args(argv)
    try:
        zips = build(
            args.out_dir,
            args.platform or tuple(PLATFORMS),
            args.wheel_cache,
            progress=lambda line: print(line, flush=True),
        )
    except BuildError as e:
        raise SystemExit(f"error: {e}") from None
    for z in zips:
        print(f"{z} {z.stat().st_size / 1e6:.1f} MB")
    return 0


if __name__ == "__main__":
    sys.exit(main())
