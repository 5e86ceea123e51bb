"""The built linux-x64 zip is a valid extension that installs into the pip ``bpy`` module
and runs its own code with its own bundled wheels, with no Blender binary.

Needs PyPI the first time (scipy, shapely and highspy wheels, about 43 MB); they are cached in
the repository's git-ignored ``build/wheels/``, after which the module takes seconds.

Install and use run in two fresh processes with ``BLENDER_USER_RESOURCES`` pointing at
a temporary folder, so the developer's own Blender settings are never touched:

1. ``bpy.ops.extensions.package_install_files`` works in the pip module without a
   window manager or ``--background``; it needs an absolute ``filepath`` (a bare name
   reports "Unable to install from relative path") and an explicit ``repo`` (else
   "Repository not set"). It prints ``STATUS Installed "autoscoop"`` and returns
   ``{'FINISHED'}``. ``enable_on_install=True`` makes it unpack the wheels into
   ``extensions/.local/lib/python3.11/site-packages``; preferences are not saved, so
2. the second process enables the add-on itself. There the extensions' ``.local``
   site-packages comes before the venv's on ``sys.path``, so the bundled scipy,
   shapely and highspy are the ones imported, which the tests check.

``run_in_installed`` is the hook for further tests of the installed copy.
"""

from __future__ import annotations

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

from headless.devtools import build_extension as bx
from tests.conftest import ROOT

ADDON = "bl_ext.user_default.autoscoop"
WHEEL_CACHE = ROOT / "build" / "wheels"
RESULT_MARK = "AUTOSCOOP-RESULT:"

on_linux_x64 = pytest.mark.skipif(
    not (sys.platform.startswith("linux") and platform.machine() in ("x86_64", "AMD64")),
    reason="installs the linux-x64 zip",
)


@pytest.fixture(scope="module")
def linux_zip(tmp_path_factory: pytest.TempPathFactory) -> Path:
    [path] = bx.build(tmp_path_factory.mktemp("dist"), ["linux-x64"], WHEEL_CACHE)
    return path


def run_python(code: str, env: dict[str, str], cwd: Path) -> subprocess.CompletedProcess[str]:
    """Run ``code`` in a fresh interpreter (a fresh Blender session); fail on a non-zero exit."""
    proc = subprocess.run(
        [sys.executable, "-c", code], env=env, cwd=cwd, capture_output=True, text=True
    )
    assert proc.returncode == 0, proc.stdout + proc.stderr
    return proc


class Installed(NamedTuple):
    env: dict[str, str]
    """Environment whose ``BLENDER_USER_RESOURCES`` holds the installed extension."""
    log: str
    """What the install process printed."""


@pytest.fixture(scope="module")
def installed(linux_zip: Path, tmp_path_factory: pytest.TempPathFactory) -> Installed:
    """The zip installed into a fresh Blender user folder."""
    user = tmp_path_factory.mktemp("blender_user")
    env = {**os.environ, "BLENDER_USER_RESOURCES": str(user)}
    code = f"""
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


def test_zip_bundles_pinned_scipy_shapely_and_highspy_only(linux_zip: Path) -> None:
    wheels = bx.zip_wheels(linux_zip)
    fields = [bx.wheel_fields(w) for w in wheels]
    assert sorted(f[0] for f in fields) == ["highspy", "scipy", "shapely"], wheels
    assert {f[0]: f[1] for f in fields} == bx.pinned_versions()
    for w, (_, _, python_tag, platform_tags) in zip(wheels, fields):
        assert python_tag == "cp311", w
        assert all(t.startswith("manylinux") and t.endswith("x86_64") for t in platform_tags), w
    assert not any(w.startswith("numpy") for w in wheels)


def test_zip_without_wheels_is_an_error(tmp_path: Path) -> None:
    empty = tmp_path / "autoscoop-0.1.0-linux_x64.zip"
    with zipfile.ZipFile(empty, "w") as zf:
        zf.writestr("blender_manifest.toml", "")
    with pytest.raises(bx.BuildError, match="0 scipy wheels for linux-x64"):
        bx.check_zip(empty, "linux-x64")


def test_rebuild_replaces_zip(tmp_path: Path) -> None:
    [first] = bx.build(tmp_path, ["linux-x64"], WHEEL_CACHE)
    first.write_bytes(b"stale")
    [second] = bx.build(tmp_path, ["linux-x64"], WHEEL_CACHE)
    assert second == first and zipfile.is_zipfile(second)
    assert sorted(p.name for p in tmp_path.iterdir()) == [first.name]


@on_linux_x64
def test_install_reports_success(installed: Installed) -> None:
    log = installed.log
    assert 'Installed "autoscoop"' in log and "operator: {'FINISHED'}" in log, log
    assert "error" not in log.lower(), log


@on_linux_x64
def test_installed_copy_imports_bundled_wheels(installed: Installed) -> None:
    paths = run_in_installed(
        """
        import highspy, numpy, scipy, shapely
        result = {m.__name__: m.__file__ for m in (ext, numpy, scipy, shapely, highspy)}
        """,
        installed.env,
    )
    user = installed.env["BLENDER_USER_RESOURCES"]
    assert paths["bl_ext.user_default.autoscoop"].startswith(user)
    for name in ("scipy", "shapely", "highspy"):
        assert paths[name].startswith(user) and "/extensions/.local/" in paths[name], paths
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


def test_installed_copy_optimizes_through_its_operator(installed: Installed) -> None:
    """One small optimization through the installed extension's operator."""
    flat_wall = Path(__file__).resolve().parents[2] / "sample_blends" / "flat_wall.blend"
    result = run_in_installed(
        f"""
        import json as _json
        bpy.ops.wm.open_mainfile(filepath={str(flat_wall)!r})
        props = bpy.context.scene.autoscoop
        props.rho, props.es_mu, props.es_lam, props.es_max_epochs = 0.6, 8, 4, 4
        assert bpy.ops.autoscoop.optimize() == {{"FINISHED"}}
        doc = _json.loads(props.result_json)
        cams = [o for o in bpy.data.collections["AutoSCOOP Results"].all_objects
                if o.type == "CAMERA"]
        result = [doc["metrics"]["coverage_fraction"], doc["metrics"]["sensors"], len(cams),
                  bpy.types.AUTOSCOOP_OT_optimize.__module__]
        """,
        installed.env,
    )
    coverage, sensors, cameras, module = result
    assert coverage >= 0.6 and sensors == cameras >= 1
    assert module.startswith("bl_ext.user_default.autoscoop")
