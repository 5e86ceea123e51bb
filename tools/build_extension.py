"""Build the AutoSCOOP extension zips, one per platform, without a Blender binary.

``./dev.sh build [--out-dir DIR] [--platform P ...]``

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
  exact filenames are an output of pip for (pin, Python, platform tags); the pins live
  in one place, ``requirements-bundled.txt``, so bumping one needs no manifest edit.
* Bundled: everything in ``requirements-bundled.txt`` (scipy, shapely, highspy, pyproj
  and certifi, matplotlib and what matplotlib needs). Not numpy: Blender ships it and ``bpy``
  depends on it, and a second copy would shadow Blender's.
* Two Pythons: Blender 4.2 LTS to 5.0 run Python 3.11, Blender 5.1 and 5.2 run Python
  3.13, so each zip carries ``cp311`` and ``cp313`` wheels and Blender's installer
  unpacks the ones its Python takes. Except ``macos-x64``: Blender 4.5 LTS is the last
  release built for Intel Macs, so that zip carries ``cp311`` only (a ``cp313`` set
  would add 35 MB no Blender can load). Pure-Python wheels (``py3-none-any``) serve
  both Pythons and are stored once. fonttools is taken as its pure wheel on every
  platform: its compiled parts only speed up font subsetting, which a PNG never does,
  and the pure wheel is 1.2 MB against 5.4 MB per Python on Linux.
* Platform tags: pip matches the ``--platform`` tags given, and for macOS the older
  versions of the one given, but not older manylinux ones, so Linux passes three
  (``manylinux_2_28``, ``manylinux_2_17``, ``manylinux2014``; matplotlib's Linux wheels
  are ``manylinux_2_17``, scipy's ``manylinux_2_27``). scipy 1.17.1 has no macOS wheel
  below ``macosx_14_0``.
* ``windows-arm64`` (Blender 4.4+) is known but not built by default: highspy 1.15.1
  and matplotlib 3.10.3 publish no ``win_arm64`` wheels, and ``--platform
  windows-arm64`` fails naming the first missing one.
* Wheels are downloaded once into a cache (default ``build/wheels/``, git-ignored) and
  reused while the file is there and is a readable zip. Downloads land in a temporary
  folder first and are moved in, so an interrupted download never looks cached.
* A platform whose wheels are missing still builds, silently, without them; so every
  zip is opened afterwards and must hold, for each of its Pythons, exactly one wheel of
  every bundled package that this Python and platform can load, and no numpy. Any
  failure raises ``BuildError`` with a one-line message.
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
REQUIREMENTS = REPO / "requirements-bundled.txt"
DEFAULT_WHEEL_CACHE = REPO / "build" / "wheels"

PLATFORMS: dict[str, tuple[str, ...]] = {
    "linux-x64": ("manylinux_2_28_x86_64", "manylinux_2_17_x86_64", "manylinux2014_x86_64"),
    "windows-x64": ("win_amd64",),
    "macos-arm64": ("macosx_14_0_arm64",),
    "macos-x64": ("macosx_14_0_x86_64",),
    "windows-arm64": ("win_arm64",),
}
"""Blender platform -> the pip ``--platform`` tags that find every bundled wheel."""

DEFAULT_PLATFORMS: tuple[str, ...] = ("linux-x64", "windows-x64", "macos-arm64", "macos-x64")
"""Built unless asked otherwise (``windows-arm64`` lacks wheels, see the docstring)."""

PYTHONS: dict[str, str] = {"cp311": "3.11", "cp313": "3.13"}
"""Python tag -> version: Blender 4.2-5.0 run 3.11, Blender 5.1-5.2 run 3.13."""

PLATFORM_PYTHONS: dict[str, tuple[str, ...]] = {"macos-x64": ("cp311",)}
"""Platforms whose Blender releases run fewer Pythons than ``PYTHONS`` (Intel Macs end
with Blender 4.5 LTS)."""

PURE_ONLY: tuple[str, ...] = ("fonttools",)
"""Packages taken as their pure-Python wheel everywhere (see the docstring)."""

NOT_BUNDLED: tuple[str, ...] = ("numpy",)
"""Packages Blender itself provides; a zip holding one of them is an error."""

Progress = Callable[[str], None]


class BuildError(AutoscoopError):
    """The extension could not be built; the message names the step and the cause."""


# --- wheels -----------------------------------------------------------------------------


def normalized(name: str) -> str:
    """A distribution name as wheel filenames spell it (``python-dateutil`` -> ``python_dateutil``)."""
    return re.sub(r"[-_.]+", "_", name).lower()


def pinned_versions(requirements: Path = REQUIREMENTS) -> dict[str, str]:
    """{normalized name: version} of every ``NAME==VERSION`` pin in ``requirements``."""
    pins: dict[str, str] = {}
    for line in requirements.read_text().splitlines():
        m = re.fullmatch(r"\s*([A-Za-z0-9_.-]+)\s*==\s*([^\s;#]+).*", line)
        if m:
            pins[normalized(m.group(1))] = m.group(2)
    if not pins:
        raise BuildError(f"{requirements}: no '==' pins")
    return pins


def pythons_of(platform: str) -> tuple[str, ...]:
    """The Python tags a platform's zip carries wheels for."""
    return PLATFORM_PYTHONS.get(platform, tuple(PYTHONS))


def wheel_fields(filename: str) -> tuple[str, str, tuple[str, ...], tuple[str, ...]]:
    """(normalized distribution, version, python tags, platform tags) of a wheel filename."""
    parts = Path(filename).name.removesuffix(".whl").split("-")
    if not filename.endswith(".whl") or len(parts) not in (5, 6):
        raise BuildError(f"{filename}: not a wheel filename")
    return normalized(parts[0]), parts[1], tuple(parts[-3].split(".")), tuple(parts[-1].split("."))


def _platform_of_tag(tag: str) -> set[str]:
    """Blender platforms a single wheel platform tag runs on (only the ones we know)."""
    if tag == "any":
        return set(PLATFORMS)
    if tag.startswith("manylinux") and tag.endswith("_x86_64"):
        return {"linux-x64"}
    if tag == "win_amd64":
        return {"windows-x64"}
    if tag == "win_arm64":
        return {"windows-arm64"}
    if tag.startswith("macosx_") and tag.endswith("_universal2"):
        return {"macos-arm64", "macos-x64"}
    if tag.startswith("macosx_") and tag.endswith("_arm64"):
        return {"macos-arm64"}
    if tag.startswith("macosx_") and tag.endswith("_x86_64"):
        return {"macos-x64"}
    return set()


def wheel_platforms(filename: str) -> set[str]:
    """Blender platforms a wheel runs on, judged by its filename."""
    return set().union(*(_platform_of_tag(t) for t in wheel_fields(filename)[3]))


def loads_on(filename: str, python: str, platform: str) -> bool:
    """Whether Blender's Python ``python`` (``cp311``) on ``platform`` can load the wheel."""
    _, _, python_tags, _ = wheel_fields(filename)
    fits_python = python in python_tags or any(t in ("py3", "py2") for t in python_tags)
    return fits_python and platform in wheel_platforms(filename)


def _is_wanted(path: Path, name: str, version: str, python: str, platform: str) -> bool:
    dist, ver, _, platform_tags = wheel_fields(path.name)
    pure = platform_tags == ("any",)
    return (
        dist == name
        and ver == version
        and loads_on(path.name, python, platform)
        and (pure or name not in PURE_ONLY)
    )


def _is_readable_zip(path: Path) -> bool:
    try:
        with zipfile.ZipFile(path) as zf:
            return bool(zf.namelist())
    except (OSError, zipfile.BadZipFile):
        return False


def cached_wheel(cache: Path, name: str, version: str, python: str, platform: str) -> Path | None:
    """The cached wheel of ``name==version`` for ``python`` on ``platform``, if readable."""
    for path in sorted(cache.glob("*.whl")):
        if _is_wanted(path, name, version, python, platform) and _is_readable_zip(path):
            return path
    return None


def _pip_download(name: str, version: str, python: str, tags: Sequence[str], dest: Path) -> None:
    cmd = [
        sys.executable,
        "-m",
        "pip",
        "download",
        f"{name}=={version}",
        "--no-deps",
        "--only-binary=:all:",
        f"--python-version={PYTHONS[python]}",
        *(f"--platform={tag}" for tag in tags),
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
        raise BuildError(f"pip download {name}=={version} for {python} {tags[0]} failed: {reason}")


def fetch_wheel(name: str, version: str, python: str, platform: str, cache: Path) -> Path:
    """The wheel of ``name==version`` for ``python`` on ``platform``, downloaded if needed."""
    if (hit := cached_wheel(cache, name, version, python, platform)) is not None:
        return hit
    cache.mkdir(parents=True, exist_ok=True)
    tags = ("any",) if name in PURE_ONLY else PLATFORMS[platform]
    with tempfile.TemporaryDirectory(dir=cache, prefix=".download-") as tmp:
        _pip_download(name, version, python, tags, Path(tmp))
        for path in Path(tmp).glob("*.whl"):
            path.replace(cache / path.name)
    if (hit := cached_wheel(cache, name, version, python, platform)) is None:
        raise BuildError(f"pip download {name}=={version} found no {python} wheel for {platform}")
    return hit


def fetch_wheels(platforms: Sequence[str], cache: Path) -> dict[str, list[Path]]:
    """Every bundled wheel for each platform, each Python of it, once per file."""
    pins = pinned_versions()
    return {
        p: list(
            dict.fromkeys(
                fetch_wheel(name, version, python, p, cache)
                for python in pythons_of(p)
                for name, version in pins.items()
            )
        )
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
    files = list(dict.fromkeys(w for p in platforms for w in wheels[p]))  # pure ones once
    for wheel in files:
        shutil.copy2(wheel, folder / "wheels" / wheel.name)
    names = [f"./wheels/{wheel.name}" for wheel in files]
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
    """Raise unless the zip holds, for each of the platform's Pythons, one loadable wheel
    of every bundled package and nothing else; and no numpy. Returns the wheel names."""
    wheels = zip_wheels(path)
    for name in NOT_BUNDLED:
        if any(wheel_fields(w)[0] == name for w in wheels):
            raise BuildError(f"{path.name}: bundles {name}, which Blender provides")
    pythons = pythons_of(platform)
    for w in wheels:
        if not any(loads_on(w, python, platform) for python in pythons):
            raise BuildError(f"{path.name}: wheel {w} loads on none of {', '.join(pythons)}")
    for python in pythons:
        for name in pinned_versions():
            count = sum(
                wheel_fields(w)[0] == name and loads_on(w, python, platform) for w in wheels
            )
            if count != 1:
                raise BuildError(
                    f"{path.name}: {count} {name} wheels for {python} on {platform}, expected 1"
                )
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
    platforms: Sequence[str] = DEFAULT_PLATFORMS,
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
        prog="python -m tools build",
        description="Build the AutoSCOOP extension zips, one per platform.",
    )
    parser.add_argument("--out-dir", type=Path, default=Path("dist"), help="default dist/")
    parser.add_argument(
        "--platform",
        action="append",
        choices=tuple(PLATFORMS),
        help=f"build only this platform (repeatable; default {', '.join(DEFAULT_PLATFORMS)})",
    )
    parser.add_argument("--wheel-cache", type=Path, help=f"default {DEFAULT_WHEEL_CACHE}")
    args = parser.parse_args(argv)
    try:
        zips = build(
            args.out_dir,
            args.platform or DEFAULT_PLATFORMS,
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
