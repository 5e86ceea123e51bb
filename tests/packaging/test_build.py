"""The built linux-x64 zip is a valid extension that installs into the pip ``bpy`` module
and runs its own code with its own bundled wheels, with no Blender binary. The suite
runs on both test environments (bpy 5.0.1 on Python 3.11, bpy 5.2.3 on Python 3.13), so
each checks the wheels its own Python takes.

Needs PyPI the first time (the wheels of ``requirements-bundled.txt`` for both Pythons,
about 120 MB); they are cached in the repository's git-ignored ``build/wheels/``, after
which the module takes seconds.

Install and use run in fresh processes with ``BLENDER_USER_RESOURCES`` pointing at a
temporary folder, so the developer's own Blender settings are never touched, and in an
interpreter that sees bpy and what bpy needs but none of the test environment's other
packages (``python -S`` with a folder of links on ``PYTHONPATH``): no scipy, shapely or
matplotlib but the ones the zip brings, as in a real Blender.

1. ``bpy.ops.extensions.package_install_files`` works in the pip module without a
   window manager or ``--background``; it needs an absolute ``filepath`` (a bare name
   reports "Unable to install from relative path") and an explicit ``repo`` (else
   "Repository not set"). It prints ``STATUS Installed "autoscoop"`` and returns
   ``{'FINISHED'}``. ``enable_on_install=True`` makes it unpack the wheels its Python
   takes into ``extensions/.local/lib/python3.X/site-packages``; preferences are not
   saved, so
2. the next process enables the add-on itself, and imports the bundled packages from
   that folder, which the tests check.

``run_in_installed`` is the hook for further tests of the installed copy.
"""

from __future__ import annotations

import importlib.metadata
import json
import os
import platform
import subprocess
import sys
import textwrap
import zipfile
from pathlib import Path
from typing import Any, NamedTuple

import pytest
from packaging.requirements import Requirement

from tests.conftest import ROOT
from tools import build_extension as bx

ADDON = "bl_ext.user_default.autoscoop"
WHEEL_CACHE = ROOT / "build" / "wheels"
RESULT_MARK = "AUTOSCOOP-RESULT:"
THIS_PYTHON = f"cp{sys.version_info.major}{sys.version_info.minor}"

on_linux_x64 = pytest.mark.skipif(
    not (sys.platform.startswith("linux") and platform.machine() in ("x86_64", "AMD64")),
    reason="installs the linux-x64 zip",
)


@pytest.fixture(scope="module")
def linux_zip(tmp_path_factory: pytest.TempPathFactory) -> Path:
    [path] = bx.build(tmp_path_factory.mktemp("dist"), ["linux-x64"], WHEEL_CACHE)
    return path


def requirements_of(dist: str) -> list[str]:
    """Normalized names ``dist`` requires here (extras left out, markers evaluated)."""
    out = []
    for text in importlib.metadata.distribution(dist).requires or []:
        req = Requirement(text)
        if req.marker is None or req.marker.evaluate({"extra": ""}):
            out.append(bx.normalized(req.name))
    return out


def link_bpy_only(view: Path) -> Path:
    """Fill ``view`` with links to bpy and the packages it requires, nothing else."""
    todo, seen = ["bpy"], set()
    while todo:
        name = todo.pop()
        if name in seen:
            continue
        seen.add(name)
        dist = importlib.metadata.distribution(name)
        root = Path(str(dist.locate_file("")))
        for top in {Path(str(f)).parts[0] for f in dist.files or ()}:
            if top not in ("..", "__pycache__") and (root / top).exists():
                (view / top).unlink(missing_ok=True)
                (view / top).symlink_to(root / top)
        todo += requirements_of(name)
    return view


@pytest.fixture(scope="module")
def bpy_only(tmp_path_factory: pytest.TempPathFactory) -> dict[str, str]:
    """Environment of an interpreter that imports bpy but none of the bundled packages."""
    view = link_bpy_only(tmp_path_factory.mktemp("bpy_only"))
    return {**os.environ, "PYTHONPATH": str(view)}


def run_python(code: str, env: dict[str, str], cwd: Path) -> subprocess.CompletedProcess[str]:
    """Run ``code`` in a fresh interpreter (a fresh Blender session) without the site
    packages (``-S``: only ``PYTHONPATH``); fail on a non-zero exit."""
    proc = subprocess.run(
        [sys.executable, "-S", "-c", code], env=env, cwd=cwd, capture_output=True, text=True
    )
    assert proc.returncode == 0, proc.stdout + proc.stderr
    return proc


class Installed(NamedTuple):
    env: dict[str, str]
    """Environment whose ``BLENDER_USER_RESOURCES`` holds the installed extension."""
    log: str
    """What the install process printed."""


@pytest.fixture(scope="module")
def installed(
    linux_zip: Path, bpy_only: dict[str, str], tmp_path_factory: pytest.TempPathFactory
) -> Installed:
    """The zip installed into a fresh Blender user folder, by an interpreter with bpy only."""
    user = tmp_path_factory.mktemp("blender_user")
    env = {**bpy_only, "BLENDER_USER_RESOURCES": str(user)}
    code = f"""
import importlib.util
missing = [m for m in ("scipy", "shapely", "highspy", "matplotlib")
           if importlib.util.find_spec(m) is None]
print("missing before install:", sorted(missing))
import bpy
result = bpy.ops.extensions.package_install_files(
    filepath={str(linux_zip)!r}, repo="user_default", enable_on_install=True
)
print("operator:", result)
"""
    proc = run_python(code, env, user)
    return Installed(env, proc.stdout + proc.stderr)


def run_in_installed(body: str, env: dict[str, str]) -> Any:
    """Run ``body`` in a fresh process with the installed extension enabled.

    ``body`` sees ``ext`` (the enabled ``bl_ext.user_default.autoscoop`` module) and sets
    ``result`` to anything JSON can carry, which is returned. The working directory is
    the Blender user folder, so nothing resolves to the repository's copy of the code.
    """
    code = "\n".join(
        [
            "import bpy  # first: it puts addon_utils on sys.path",
            "import json, addon_utils",
            f"ext = addon_utils.enable({ADDON!r}, default_set=True)",
            f"assert ext is not None, 'could not enable {ADDON}'",
            "result = None",
            textwrap.dedent(body),
            f"print({RESULT_MARK!r} + json.dumps(result))",
        ]
    )
    proc = run_python(code, env, Path(env["BLENDER_USER_RESOURCES"]))
    lines = [ln for ln in proc.stdout.splitlines() if ln.startswith(RESULT_MARK)]
    assert lines, proc.stdout + proc.stderr
    return json.loads(lines[-1].removeprefix(RESULT_MARK))


def test_zip_validates(linux_zip: Path) -> None:
    ext, tags = bx.extension_cli()
    proc = subprocess.run(
        [sys.executable, ext, "validate", "--valid-tags", tags, linux_zip],
        capture_output=True,
        text=True,
    )
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert linux_zip.name == "autoscoop-0.1.0-linux_x64.zip"


def test_zip_holds_the_add_on_its_manifest_and_wheels_only(linux_zip: Path) -> None:
    """The zip's files are the add-on package's own sources (as in the repository), the
    manifest and wheels: no developer tool, test, benchmark or cache."""
    with zipfile.ZipFile(linux_zip) as zf:
        names = [n for n in zf.namelist() if not n.endswith("/")]
    source = ROOT / "autoscoop_blender"
    expected = {
        p.relative_to(source).as_posix()
        for p in source.rglob("*")
        if p.is_file() and "__pycache__" not in p.parts
    }
    ours = {n for n in names if not n.startswith("wheels/")}
    assert ours == expected | {"blender_manifest.toml"}
    assert all(n.endswith(".whl") for n in names if n.startswith("wheels/"))
    assert not any(part in n for n in names for part in ("tools/", "tests/", "headless/"))


def bundled_pins() -> dict[str, str]:
    """{name: version} read from requirements-bundled.txt here, not by the build's parser."""
    pins = {}
    for line in (ROOT / "requirements-bundled.txt").read_text().splitlines():
        line = line.split("#")[0].strip()
        if line:
            name, version = line.split("==")
            pins[name.strip().lower().replace("-", "_")] = version.strip()
    return pins


@pytest.mark.parametrize("python", ["cp311", "cp313"])
def test_zip_carries_every_pinned_wheel_for_both_pythons(linux_zip: Path, python: str) -> None:
    wheels = bx.zip_wheels(linux_zip)
    mine = [w for w in wheels if bx.loads_on(w, python, "linux-x64")]
    fields = [bx.wheel_fields(w) for w in mine]
    assert sorted(f[0] for f in fields) == sorted(bundled_pins()), mine
    assert {f[0]: f[1] for f in fields} == bundled_pins()
    assert {"matplotlib", "scipy", "shapely", "highspy", "pillow", "pyproj"} <= set(bundled_pins())
    for w, (_, _, python_tags, platform_tags) in zip(mine, fields):
        assert python_tags in ((python,), ("py3",), ("py2", "py3")), w
        assert platform_tags == ("any",) or all(
            t.startswith("manylinux") and t.endswith("x86_64") for t in platform_tags
        ), w
    assert [f for f in fields if f[0] == "fonttools"][0][3] == ("any",)  # the pure one
    assert not any(w.startswith("numpy") for w in wheels)
    # Nothing for another Python or platform: every wheel serves cp311 or cp313 here.
    assert all(
        bx.loads_on(w, "cp311", "linux-x64") or bx.loads_on(w, "cp313", "linux-x64") for w in wheels
    )


def test_bundled_packages_need_nothing_else() -> None:
    """Every requirement of a bundled package (as installed in this environment) is
    bundled too, or is numpy, which Blender brings: a zip never lacks a dependency."""
    pins = bundled_pins()
    for name in pins:
        assert importlib.metadata.version(name) == pins[name], name
        missing = set(requirements_of(name)) - set(pins) - {"numpy"}
        assert not missing, f"{name} needs {missing}"


@pytest.mark.parametrize(
    "wheel, python, platform, loads",
    [
        ("scipy-1.17.1-cp313-cp313-macosx_14_0_arm64.whl", "cp311", "macos-arm64", False),
        ("scipy-1.17.1-cp313-cp313-macosx_14_0_arm64.whl", "cp313", "macos-arm64", True),
        ("scipy-1.17.1-cp313-cp313-macosx_14_0_arm64.whl", "cp313", "macos-x64", False),
        ("fonttools-4.68.0-cp311-cp311-macosx_10_9_universal2.whl", "cp311", "macos-x64", True),
        ("fonttools-4.68.0-cp311-cp311-macosx_10_9_universal2.whl", "cp311", "macos-arm64", True),
        ("tzdata-2026.6-py2.py3-none-any.whl", "cp313", "windows-arm64", True),
        ("pillow-13.0.0-cp311-cp311-win_arm64.whl", "cp311", "windows-x64", False),
        ("pillow-13.0.0-cp311-cp311-win_arm64.whl", "cp311", "windows-arm64", True),
        ("kiwisolver-1.5.1-cp313-cp313-manylinux2014_x86_64.manylinux_2_17_x86_64.whl",
         "cp313", "linux-x64", True),
    ],
)  # fmt: skip
def test_which_wheel_loads_where(wheel: str, python: str, platform: str, loads: bool) -> None:
    assert bx.loads_on(wheel, python, platform) is loads


def _zip_of(path: Path, wheels: list[str]) -> Path:
    with zipfile.ZipFile(path, "w") as zf:
        zf.writestr("blender_manifest.toml", "")
        for w in wheels:
            zf.writestr(f"wheels/{w}", "")
    return path


def test_zip_without_wheels_is_an_error(tmp_path: Path) -> None:
    empty = _zip_of(tmp_path / "autoscoop-0.1.0-linux_x64.zip", [])
    with pytest.raises(bx.BuildError, match="0 scipy wheels for cp311 on linux-x64"):
        bx.check_zip(empty, "linux-x64")


def test_zip_lacking_one_python_is_an_error(linux_zip: Path, tmp_path: Path) -> None:
    """The real zip's wheels pass; without the cp313 scipy the check names what is missing,
    and a macos-x64 zip needs no cp313 at all."""
    wheels = bx.zip_wheels(linux_zip)
    assert bx.check_zip(_zip_of(tmp_path / "all.zip", wheels), "linux-x64") == wheels
    no_313 = [w for w in wheels if not (w.startswith("scipy-") and "cp313" in w)]
    with pytest.raises(bx.BuildError, match="0 scipy wheels for cp313 on linux-x64"):
        bx.check_zip(_zip_of(tmp_path / "no313.zip", no_313), "linux-x64")
    mac = [w.replace("manylinux_2_27_x86_64.manylinux_2_28_x86_64", "macosx_14_0_x86_64")
           .replace("manylinux_2_24_x86_64.manylinux_2_28_x86_64", "macosx_10_9_x86_64")
           .replace("manylinux_2_17_x86_64.manylinux2014_x86_64", "macosx_10_12_x86_64")
           .replace("manylinux2014_x86_64.manylinux_2_17_x86_64", "macosx_10_9_x86_64")
           .replace("manylinux_2_28_x86_64", "macosx_13_0_x86_64")  # pyproj
           for w in wheels if "cp313" not in w]  # fmt: skip
    assert bx.check_zip(_zip_of(tmp_path / "mac.zip", mac), "macos-x64") == sorted(mac)
    with pytest.raises(bx.BuildError, match="loads on none of cp311"):
        linux_313 = next(w for w in no_313 if "cp313" in w)
        bx.check_zip(_zip_of(tmp_path / "mac313.zip", [*mac, linux_313]), "macos-x64")


def test_rebuild_replaces_zip(tmp_path: Path) -> None:
    [first] = bx.build(tmp_path, ["linux-x64"], WHEEL_CACHE)
    first.write_bytes(b"stale")
    [second] = bx.build(tmp_path, ["linux-x64"], WHEEL_CACHE)
    assert second == first and zipfile.is_zipfile(second)
    assert sorted(p.name for p in tmp_path.iterdir()) == [first.name]


@on_linux_x64
def test_install_reports_success(installed: Installed) -> None:
    log = installed.log
    # The interpreter had none of the bundled packages before the install.
    assert "missing before install: ['highspy', 'matplotlib', 'scipy', 'shapely']" in log, log
    assert 'Installed "autoscoop"' in log and "operator: {'FINISHED'}" in log, log
    assert "error" not in log.lower(), log


@on_linux_x64
def test_installed_copy_imports_bundled_wheels(installed: Installed) -> None:
    bundled = ("scipy", "shapely", "highspy", "matplotlib", "PIL", "contourpy", "kiwisolver",
               "pyproj")  # fmt: skip
    paths = run_in_installed(
        f"""
        import importlib, numpy
        mods = [ext, numpy] + [importlib.import_module(m) for m in {bundled!r}]
        result = {{m.__name__: m.__file__ for m in mods}}
        """,
        installed.env,
    )
    user = installed.env["BLENDER_USER_RESOURCES"]
    site = f"/extensions/.local/lib/python{sys.version_info.major}.{sys.version_info.minor}/"
    assert paths["bl_ext.user_default.autoscoop"].startswith(user)
    for name in bundled:
        assert paths[name].startswith(user) and site in paths[name], paths
    assert "/extensions/.local/" not in paths["numpy"], paths


@on_linux_x64
def test_installed_core_computes_coverage(installed: Installed) -> None:
    footprint = run_in_installed(
        """
        from bl_ext.user_default.autoscoop.core.coverage.reference import reference_footprint_m2
        from bl_ext.user_default.autoscoop.core.model.sensors import PAPER_CAMERA
        result = reference_footprint_m2(PAPER_CAMERA)
        """,
        installed.env,
    )
    assert footprint == pytest.approx(1230.0, abs=5.0)


@on_linux_x64
def test_installed_copy_optimizes_and_draws_its_map(installed: Installed) -> None:
    """One small optimization through the installed extension's operator, and its map
    drawn by the bundled matplotlib."""
    flat_wall = Path(__file__).resolve().parents[2] / "sample_blends" / "flat_wall.blend"
    out = Path(installed.env["BLENDER_USER_RESOURCES"]) / "export"
    result = run_in_installed(
        f"""
        import json as _json, sys
        bpy.ops.wm.open_mainfile(filepath={str(flat_wall)!r})
        props = bpy.context.scene.autoscoop
        props.rho, props.es_mu, props.es_lam, props.es_max_epochs = 0.6, 8, 4, 4
        assert bpy.ops.autoscoop.optimize() == {{"FINISHED"}}
        doc = _json.loads(props.result_json)
        cams = [o for o in bpy.data.collections["AutoSCOOP Results"].all_objects
                if o.type == "CAMERA"]
        props.export_dir = {str(out)!r}
        assert bpy.ops.autoscoop.export(kind="PNG") == {{"FINISHED"}}
        result = [doc["metrics"]["coverage_fraction"], doc["metrics"]["sensors"], len(cams),
                  bpy.types.AUTOSCOOP_OT_optimize.__module__,
                  sys.modules["matplotlib"].__file__, bpy.app.version_string]
        """,
        installed.env,
    )
    coverage, sensors, cameras, module, matplotlib_file, version = result
    assert coverage >= 0.6 and sensors == cameras >= 1
    assert module.startswith("bl_ext.user_default.autoscoop")
    assert "/extensions/.local/" in matplotlib_file
    assert (out / "coverage.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert version.startswith({"cp311": "5.0", "cp313": "5.2"}[THIS_PYTHON])
