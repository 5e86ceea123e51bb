"""Command-line parsing and dispatch (``python -m headless``): the users' commands
``optimize``, ``coverage`` and ``import-xodr``; their options that set a knob are
generated from the settings schema (``core/settings.py``). A user mistake
(``AutoscoopError``) prints one line ``error: <object>: <problem>`` on stderr and writes
nothing. The jobs run in ``jobs`` (``import-xodr`` in ``xodr``); the developer tools are
apart, in the top-level ``tools`` package.
"""

from __future__ import annotations

import argparse
import logging
import os
import sys
from collections.abc import Callable
from typing import Any

from autoscoop_blender.core.model.sensors import PRESETS
from autoscoop_blender.core.settings import (
    CoverageSettings,
    OptimizeSettings,
    Setting,
    settings_schema,
)
from headless import interrupts

DESCRIPTION = """\
AutoSCOOP plans road-side sensors (cameras, lidars, radars on masts) that cover the
target areas of a proving ground modelled in Blender, despite what occludes them.
'python -m headless COMMAND --help' tells each command's options."""

# What each exit code of the users' commands means (the help's epilog, the reference).
EXIT_CODES: dict[int, str] = {
    0: "done (optimize: the coverage goal reached)",
    2: "bad input: one line 'error: <object>: <problem>' on stderr, nothing written",
    3: "optimize ended short of its goal; its result is written, and its stop reason says why",
    130: "interrupted by Ctrl-C or SIGTERM: optimize writes its best plan so far, marked "
    '"interrupted", once it has one; --resume goes on',
}


class _Parser(argparse.ArgumentParser):
    """argparse that reports a bad command line as a one-line error, exit code 2."""

    def error(self, message: str) -> None:  # type: ignore[override]
        self.exit(2, f"error: {message} (see {self.prog} --help)\n")


def add_knob_options(parser: argparse.ArgumentParser, cls: type, overrides: bool = False) -> None:
    """One option per knob of the settings class ``cls`` (``Setting.flag``), from its
    schema: its type, choices, default and help; the option's ``dest`` is the knob's
    path (``rho``, ``es.mu``).

    overrides: the options override a config file, so their default is None (unset).
    """
    for setting in settings_schema(cls):
        k = setting.knob
        kw: dict[str, Any] = {"dest": setting.path, "help": k.help}
        if k.choices:
            kw["choices"] = [c[0] for c in k.choices]
            kw["help"] += ": " + "; ".join(
                f"{value}: {text[:1].lower()}{text[1:]}" for value, _, text in k.choices
            )
        elif setting.kind is bool:  # --knob / --no-knob
            kw["action"] = argparse.BooleanOptionalAction
        else:
            kw["type"] = setting.kind
            kw["metavar"] = setting.kind.__name__.upper()
        kw["default"] = None if overrides else setting.default
        kw["help"] += _default_text(setting)
        parser.add_argument(setting.flag, **kw)


def _default_text(setting: Setting) -> str:
    """`` (default X)`` for the help of a knob's option; nothing where the default is
    None (the help says what is derived then)."""
    if setting.default is None:
        return ""
    if setting.kind is bool:
        return f" (default {'on' if setting.default else 'off'})"
    return (
        f" (default {setting.default:g})"
        if setting.kind is float
        else f" (default {setting.default})"
    )


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(
        prog="python -m headless",
        description=DESCRIPTION,
        epilog="exit codes:\n" + "\n".join(f"  {c:>3}  {t}" for c, t in EXIT_CODES.items()),
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)

    cov = sub.add_parser(
        "coverage", help="count the coverage of given sensors on a scene (a plan, edited or not)"
    )
    cov.add_argument("scene", nargs="?", help=".blend file (inside Blender: the open one)")
    cov.add_argument("--sensors", required=True, help="sensors JSON (see README)")
    add_knob_options(cov, CoverageSettings)
    cov.add_argument(
        "--out", required=True, help="result JSON; its coverage map goes beside it (OUT.png)"
    )
    cov.add_argument("--points-csv", help="per-target-point CSV")
    _overwrite_option(cov, "--out, its map and --points-csv")

    opt = sub.add_parser(
        "optimize",
        help="plan sensors and masts that cover the target areas (lp by default: a plan "
        "and a proven lower bound on its cost)",
    )
    opt.add_argument(
        "scene",
        nargs="?",
        help=".blend file (default: the file Blender opened, else sample_blends/two_routes)",
    )
    add_knob_options(opt, OptimizeSettings, overrides=True)
    opt.add_argument(
        "--model",
        choices=sorted(PRESETS),
        help="the sensor model, a preset (default: the config file's, else paper_camera; "
        "a model of your own or a mixed pack: in --config)",
    )
    opt.add_argument(
        "--config", help="TOML file of settings and model (the options above override it)"
    )
    opt.add_argument("--out-dir", default="out", help="output folder (default out/)")
    opt.add_argument(
        "--existing",
        metavar="FILE.json",
        help="sensors that stand already (a sensors file, or a result.json): kept as "
        "given, counted toward coverage, at no cost; the plan adds to them",
    )
    opt.add_argument("--resume", action="store_true", help="go on from the checkpoint")
    _overwrite_option(opt, "an earlier run's files in --out-dir (its checkpoint too)")
    opt.add_argument(
        "--repair",
        action="store_true",
        help="with --resume: keep the records before a damaged checkpoint line (the whole "
        "file is kept as checkpoint.jsonl.damaged)",
    )
    opt.add_argument(
        "--workers",
        type=int,
        default=None,
        help="es: processes that score each population at once (default: one per core, one "
        "inside a Blender binary; the same answer); with --engine ray: the CPUs of a local Ray",
    )
    opt.add_argument(
        "--engine",
        choices=("local", "ray"),
        default="local",
        help="where lp builds the candidates of a ground it plans in parts: here (local, "
        "the default) or on Ray (RAY_ADDRESS, else a local Ray of --workers CPUs; needs "
        "pip install -r requirements-ray.txt); the same plan",
    )
    opt.add_argument(
        "--render",
        action="store_true",
        help="also write result_view.png: an oblique view of result.blend rendered by "
        "Blender (Workbench, a few seconds)",
    )

    imp = sub.add_parser(
        "import-xodr", help="an OpenDRIVE file -> a .blend with roads, target and sensor areas"
    )
    imp.add_argument("file", help="OpenDRIVE file (.xodr)")
    imp.add_argument("--out", required=True, help="the .blend to write")
    _overwrite_option(imp, "--out")
    imp.add_argument(
        "--lanes",
        default="driving",
        help="lane types that become target areas, comma-separated (default driving)",
    )
    imp.add_argument(
        "--band",
        default="1:6",
        help="sensor areas: INNER:OUTER metres outside the outermost lane border (default 1:6)",
    )
    imp.add_argument(
        "--terrain",
        choices=("flat", "none"),
        default="flat",
        help="flat: a ground just below the lowest road (default); none: roads only",
    )

    return parser


def _overwrite_option(parser: argparse.ArgumentParser, what: str) -> None:
    parser.add_argument(
        "--overwrite",
        action="store_true",
        help=f"replace {what} if it exists (without it, an existing output is refused; an "
        "output is never one of the inputs)",
    )


def main(argv: list[str] | None = None) -> int:
    try:
        args = build_parser().parse_args(argv)
    except KeyboardInterrupt:
        return _interrupted()
    # AUTOSCOOP_LOG=info (or debug): the stages' own figures on stderr, for developers.
    level = os.environ.get("AUTOSCOOP_LOG", "warning").upper()
    logging.basicConfig(
        level=getattr(logging, level, logging.WARNING), format="%(levelname)s: %(message)s"
    )
    handlers: dict[str, Callable[[argparse.Namespace], int]] = {
        "coverage": _coverage,
        "optimize": _optimize,
        "import-xodr": _import_xodr,
    }
    from autoscoop_blender.core.errors import AutoscoopError

    try:
        if args.command in ("coverage", "optimize", "import-xodr"):
            with interrupts.held():  # bpy runs Blender's start-up scripts (``interrupts``)
                import bpy  # noqa: F401
        return handlers[args.command](args)
    except AutoscoopError as e:
        if interrupts.signalled():  # a fault of the interrupted work, not the user's
            return _interrupted()
        print(f"error: {e}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        return _interrupted()
    except Exception:
        if interrupts.signalled():  # e.g. a worker ended by the same Ctrl-C
            return _interrupted()
        raise


def _interrupted() -> int:
    """The last line says what was kept (``interrupts.keep``); exit code 130."""
    interrupts.last_line()
    return interrupts.EXIT_INTERRUPTED


def _coverage(args: argparse.Namespace) -> int:
    from headless import jobs

    return jobs.coverage(args)


def _optimize(args: argparse.Namespace) -> int:
    from headless import jobs

    return jobs.optimize(args)


def _import_xodr(args: argparse.Namespace) -> int:
    from headless import xodr

    return xodr.import_xodr(args)
