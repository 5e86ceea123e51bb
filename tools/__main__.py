"""Developer tools: ``python -m tools build|samples|bench|docs`` (``./dev.sh build``,
``./dev.sh samples``, ``./dev.sh bench``, ``./dev.sh docs``). Exit codes as the users'
commands'.

The users' package (``headless``) never imports this one; nor does the extension.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from headless.paths import SAMPLES


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="python -m tools", description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", required=True)

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
    bench.add_argument(
        "--scenes",
        help="bound: measure only these of its scenes, separated by ';' (e.g. 'Town01; "
        "two_routes, coverage_k = 2'), keeping the others' figures",
    )
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
        "--charts-dir", default="docs/img", help="where the charts go (not --quick's)"
    )
    bench.add_argument(
        "--paper-dir",
        default="bench/paper_pointcloud",
        help="optimize: output folder of the paper-faithful run (reused or resumed)",
    )
    docs = sub.add_parser(
        "docs", help="write the docs' generated reference pages, then build the site (strict)"
    )
    docs.add_argument("--site-dir", default="build/site", help="default build/site/")
    docs.add_argument(
        "--pictures",
        action="store_true",
        help="also make the guide's pictures again with the users' commands (about a minute)",
    )
    return parser


def _floats(text: str) -> tuple[float, ...]:
    """``0,0.1,0.4`` -> (0.0, 0.1, 0.4); ``''`` -> ()."""
    return tuple(float(t) for t in text.split(",") if t.strip())


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    jobs = {"build": _build, "samples": _samples, "bench": _bench, "docs": _docs}
    return jobs[args.command](args)


def _build(args: argparse.Namespace) -> int:
    from tools import build_extension

    argv = ["--out-dir", args.out_dir]
    for platform in args.platform or []:
        argv += ["--platform", platform]
    if args.wheel_cache:
        argv += ["--wheel-cache", args.wheel_cache]
    return build_extension.main(argv)


def _samples(args: argparse.Namespace) -> int:
    from tools import samples

    for path in samples.build_all(Path(args.out_dir)):
        print(path)
    return 0


def _bench(args: argparse.Namespace) -> int:
    from tools import bench

    return bench.main(args)


def _docs(args: argparse.Namespace) -> int:
    import subprocess

    from headless.paths import REPO
    from tools import docs

    made = docs.write() + (docs.pictures() if args.pictures else [])
    for path in made:
        print(path.relative_to(REPO))
    cmd = [sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir", args.site_dir]
    return subprocess.run(cmd, cwd=REPO).returncode


if __name__ == "__main__":
    sys.exit(main())
