"""Command-line parsing and dispatch. Exit codes: 0 done (optimize: the goal reached),
2 bad input, 3 optimize ended short of its goal (the result is still written), 130
interrupted (Ctrl-C or SIGTERM; the checkpoint keeps what was fixed).

A user mistake (``AutoscoopError``) prints one line ``error: <object>: <problem>`` on
stderr and writes nothing; warnings print as ``warning: ...`` and the job goes on.
The options that set a knob are generated from the settings schema
(``core/settings.py``: its ``flag``, type, choices and help). The users' commands run
in ``jobs`` (``import-xodr`` in ``xodr``); ``build``, ``samples`` and ``bench`` are
developer tools in ``devtools``.
"""

from __future__ import annotations

import argparse
import logging
import os
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

from autoscoop_blender.core.settings import CoverageSettings, OptimizeSettings, settings_schema
from headless import interrupts
from headless.paths import SAMPLES


class _Parser(argparse.ArgumentParser):
    """argparse that reports a bad command line as a one-line error, exit code 2."""

    def error(self, message: str) -> None:  # type: ignore[override]
        self.exit(2, f"error: {message} (see {self.prog} --help)\n")


def add_knob_options(parser: argparse.ArgumentParser, cls: type, overrides: bool = False) -> None:
    """One option per knob of the settings class ``cls`` that has a flag, from its
    schema; the option's ``dest`` is the knob's name.

    overrides: the options override a config file, so their default is None (unset).
    """
    for setting in settings_schema(cls):
        k = setting.knob
        if k.flag is None:
            continue
        kw: dict[str, Any] = {"dest": setting.path, "help": k.help}
        if k.choices:
            kw["choices"] = [c[0] for c in k.choices]
            kw["help"] += ": " + "; ".join(
                f"{value}: {text[:1].lower()}{text[1:]}" for value, _, text in k.choices
            )
        elif setting.kind is bool:  # a switch that turns the knob on
            kw["action"], kw["const"] = "store_const", True
        else:
            kw["type"] = setting.kind
        kw["default"] = None if overrides else setting.default
        if setting.default is not None and setting.kind is not bool:
            kw["help"] += f" (default {setting.default})"
        parser.add_argument(k.flag, **kw)


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="python -m headless", description=__doc__)
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)

    cov = sub.add_parser("coverage", help="coverage of a set of sensors on a scene")
    cov.add_argument("scene", nargs="?", help=".blend file (inside Blender: the open one)")
    cov.add_argument("--sensors", required=True, help="sensors JSON (see README)")
    add_knob_options(cov, CoverageSettings)
    cov.add_argument("--out", required=True, help="result JSON")
    cov.add_argument("--points-csv", help="per-target-point CSV")
    _overwrite_option(cov, "--out and --points-csv")

    opt = sub.add_parser("optimize", help="place sensors with the evolution strategy")
    opt.add_argument(
        "scene",
        nargs="?",
        help=".blend file (default: the file Blender opened, else sample_blends/two_routes)",
    )
    add_knob_options(opt, OptimizeSettings, overrides=True)
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
        help="processes that evaluate in parallel (default: one per core, one inside a Blender binary; same answer)",
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

    bld = sub.add_parser("build", help="build the extension zips (one per platform)")
    bld.add_argument("--out-dir", default="dist", help="default dist/")
    bld.add_argument(
        "--platform",
        action="append",
        help="linux-x64, windows-x64, macos-arm64, macos-x64, windows-arm64 (default all "
        "but windows-arm64)",
    )
    bld.add_argument("--wheel-cache", help="where downloaded wheels are kept (build/wheels/)")

    smp = sub.add_parser("samples", help="rebuild the sample .blend files")
    smp.add_argument("--out-dir", default=str(SAMPLES))

    bench = sub.add_parser("bench", help="benchmarks that print figures")
    bench.add_argument(
        "what",
        nargs="?",
        default="all",
        choices=("all", "coverage", "optimize", "scaling", "bound", "xodr", "constants"),
        help="all (default): speed/accuracy, optimizer runs, stability, scaling, bounds, "
        "ES vs paper -> bench/results.json and charts; scaling, bound: that section only; "
        "xodr: import and plan each OpenDRIVE file of tests/data/xodr -> bench/xodr.json; "
        "constants: ES zeta and greedy mast preference swept on two_routes, full_ground "
        "tiles and an OpenDRIVE scene -> bench/constants.json",
    )
    bench.add_argument(
        "--quick", action="store_true", help="all, scaling, bound, constants: quicker"
    )
    bench.add_argument("--scene", default=str(SAMPLES / "two_routes.blend"))
    bench.add_argument("--poses", type=int, default=12, help="coverage: poses per method")
    bench.add_argument("--seed", type=int, default=0)
    bench.add_argument("--out", help="coverage: also write the figures to this JSON file")
    bench.add_argument(
        "--preferences",
        type=_floats,
        help="constants: greedy mast preferences for the cost objective, comma-separated "
        "('' none; default 0 to 3)",
    )
    bench.add_argument(
        "--objective-preferences",
        type=_floats,
        help="constants: the few for the sensors and masts objectives (default 0,0.1,0.4,1)",
    )
    bench.add_argument(
        "--zetas", type=_floats, help="constants: ES zetas ('' none; default 0.02,0.05,0.1)"
    )
    bench.add_argument(
        "--seeds", type=int, help="constants: ES seeds per zeta, from --seed on (default 4)"
    )
    bench.add_argument(
        "--resume",
        action="store_true",
        help="constants: keep the runs of bench/constants.json, run only the missing ones",
    )
    bench.add_argument("--out-dir", default="bench", help="where figures and runs go")
    bench.add_argument(
        "--paper-dir",
        default="bench/paper_pointcloud",
        help="optimize: output folder of the paper-faithful run (reused or resumed)",
    )
    return parser


def _overwrite_option(parser: argparse.ArgumentParser, what: str) -> None:
    parser.add_argument(
        "--overwrite",
        action="store_true",
        help=f"replace {what} if it exists (without it, an existing output is refused; an "
        "output is never one of the inputs)",
    )


def _floats(text: str) -> tuple[float, ...]:
    """``0,0.1,0.4`` -> (0.0, 0.1, 0.4); ``''`` -> ()."""
    return tuple(float(t) for t in text.split(",") if t.strip())


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
        "build": _build,
        "samples": _samples,
        "bench": _bench,
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


def _build(args: argparse.Namespace) -> int:
    from headless.devtools import build_extension

    argv = ["--out-dir", args.out_dir]
    for platform in args.platform or []:
        argv += ["--platform", platform]
    if args.wheel_cache:
        argv += ["--wheel-cache", args.wheel_cache]
    return build_extension.main(argv)


def _samples(args: argparse.Namespace) -> int:
    from headless.devtools import samples

    for path in samples.build_all(Path(args.out_dir)):
        print(path)
    return 0


def _bench(args: argparse.Namespace) -> int:
    from headless.devtools import bench

    return bench.main(args)
