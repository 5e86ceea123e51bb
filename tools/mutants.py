"""Mutation testing of the core modules with mutmut: ``./dev.sh mutants [FILE...]``.

For each module named (default: every module in ``TESTS_FOR``), a fresh copy of the
project goes to ``.mutants/<module>/`` (git-ignored): the working tree's tracked and
untracked-but-not-ignored files, or ``--rev REV``'s files. mutmut runs inside that copy
and writes its mutants to ``.mutants/<module>/mutants/``. The real sources are only
read, so neither a finished run nor a Ctrl-C can leave a mutant in them. Never run
``mutmut apply`` in the repository itself: it writes a mutant into the source.

mutmut runs only the tests in ``TESTS_FOR[module]`` (its stats pass maps each mutated
function to the tests that call it; each mutant then runs just those, stopping at the
first failure). The run ends with ``killed K of M`` per module and in total, and each
survivor's name and changed lines. A timeout counts as killed (a test noticed); a
mutant no test reaches counts as survived ("no tests").

``--only PATTERN`` (repeatable; fnmatch against mutmut's names, such as
``'*bound.x_cover_lp__mutmut_*'``) runs a part of a module's mutants: the rest are not
checked, and the score counts only those run (``killed K of M run, N not run``).

To look at a survivor more closely: ``cd .mutants/<module> && ../../.venv/bin/mutmut
show NAME`` (or ``browse``).
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tarfile
from dataclasses import dataclass, field
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
WORK = ROOT / ".mutants"

# Module under mutation -> the test files that exercise it. Keep each list to the tests
# that check the module's answers; the per-function selection inside mutmut narrows it
# further.
TESTS_FOR: dict[str, list[str]] = {
    # test_masts.py holds the grouping's own cases and the invariants of whole plans;
    # test_optimize.py also reaches it, but runs ~10x longer per surviving mutant.
    "autoscoop_blender/core/masts.py": ["tests/core/test_masts.py"],
    # test_sites.py builds scenes from numpy boxes (no Blender): a run of seconds.
    "autoscoop_blender/core/model/sites.py": ["tests/core/test_sites.py"],
    "autoscoop_blender/core/candidates.py": [
        "tests/core/test_candidates.py",
        "tests/core/test_optimize.py",
        "tests/core/test_lp.py",
        "tests/core/test_budget.py",
    ],
    # test_evaluate_layout.py: heights, warnings and the ray limit on hand-made scenes.
    "autoscoop_blender/core/evaluate.py": [
        "tests/core/test_evaluate_layout.py",
        "tests/core/test_layout_metrics.py",
        "tests/core/test_coverage_map.py",
    ],
    # test_coverage_base.py checks base.py's pieces one at a time on hand-made input.
    "autoscoop_blender/core/coverage/base.py": [
        "tests/core/test_coverage_base.py",
        "tests/core/test_coverage.py",
        "tests/core/test_fitness.py",
        "tests/core/test_footprint.py",
        "tests/core/test_cached.py",
    ],
    # test_dori.py checks both evaluators' pixel-density answers against the closed form
    # (and cover_many against single evaluations): ~25 s.
    "autoscoop_blender/core/coverage/targeted.py": [
        "tests/core/test_coverage.py",
        "tests/core/test_cached.py",
        "tests/core/test_footprint.py",
        "tests/core/test_optimize.py",
        "tests/core/test_dori.py",
    ],
    "autoscoop_blender/core/coverage/cached.py": [
        "tests/core/test_cached.py",
        "tests/core/test_coverage.py",
        "tests/core/test_dori.py",
    ],
    # test_pointcloud_parts.py works the method's parts out by hand on a few hits;
    # test_dori.py holds the pixel-density answers of a camera with a resolution.
    "autoscoop_blender/core/coverage/pointcloud.py": [
        "tests/core/test_pointcloud_parts.py",
        "tests/core/test_coverage.py",
        "tests/core/test_footprint.py",
        "tests/core/test_dori.py",
    ],
    # test_mixed_pack.py holds the per-model costs and the sensors-per-mast cap that
    # greedy, the cover moves, the bound's rows and the lp pipeline all take.
    "autoscoop_blender/core/optimize/greedy.py": [
        "tests/core/test_greedy.py",
        "tests/core/test_optimize.py",
        "tests/core/test_mixed_pack.py",
    ],
    # test_lp_planner.py checks each step of lp.py on hand-made candidate sets in ~3 s.
    "autoscoop_blender/core/optimize/lp.py": [
        "tests/core/test_lp_planner.py",
        "tests/core/test_lp.py",
        "tests/core/test_mixed_pack.py",
        "tests/core/test_k_coverage.py",
    ],
    "autoscoop_blender/core/optimize/cover.py": [
        "tests/core/test_lp.py",
        "tests/core/test_mixed_pack.py",
    ],
    # test_joint.py checks the joint bound against brute-force optima (hypothesis), ~7 s.
    "autoscoop_blender/core/optimize/joint.py": ["tests/core/test_joint.py"],
    # test_neighbourhoods.py: windows on hand-made grounds against brute-force optima, ~2 s.
    "autoscoop_blender/core/optimize/neighbourhoods.py": ["tests/core/test_neighbourhoods.py"],
    # test_restricted.py checks the merged restricted LP against linprog and a partition
    # worked out point by point (~8 s).
    "autoscoop_blender/core/optimize/bound.py": [
        "tests/core/test_restricted.py",
        "tests/core/test_bound.py",
        "tests/core/test_lp.py",
        "tests/core/test_mixed_pack.py",
        "tests/core/test_k_coverage.py",
    ],
    # test_es_steps.py works each mutation and epoch out by hand (scripted draws);
    # test_optimize.py holds whole ES runs: worker processes, resumes (~30 s).
    "autoscoop_blender/core/optimize/es.py": [
        "tests/core/test_es_steps.py",
        "tests/core/test_es.py",
        "tests/core/test_es_stops.py",
        "tests/core/test_optimize.py",
    ],
}

# What the tests import besides the package under mutation (copied into mutmut's folder).
ALSO_COPY = ["headless", "sample_blends", "blender_manifest.toml", "requirements-bundled.txt"]

# mutmut's exit codes (mutmut.stats.status_by_exit_code, 3.8): what counts as killed.
KILLED = {"killed", "timeout", "caught by type check"}
NOT_RUN = "not checked"  # generated, but left out by --only (or the run was stopped)


@dataclass
class Score:
    module: str
    status: dict[str, str] = field(default_factory=dict)  # mutant name -> mutmut status
    diffs: dict[str, list[str]] = field(default_factory=dict)

    @property
    def killed(self) -> int:
        return sum(s in KILLED for s in self.status.values())

    @property
    def total(self) -> int:
        """Mutants run (those ``--only`` left out are not counted)."""
        return len(self.status) - self.not_run

    @property
    def not_run(self) -> int:
        return sum(s == NOT_RUN for s in self.status.values())

    def survivors(self) -> list[str]:
        return sorted(
            (n for n, s in self.status.items() if s not in KILLED and s != NOT_RUN),
            key=_mutant_key,
        )

    def summary(self) -> str:
        """``killed K of M``, and ``run, N not run`` when ``--only`` left some out."""
        text = f"killed {self.killed} of {self.total}"
        return text + (f" run, {self.not_run} not run" if self.not_run else "")


def _mutant_key(name: str) -> tuple[str, int]:
    stem, _, number = name.rpartition("_")
    return (stem, int(number) if number.isdigit() else 0)


def parse_args(argv: list[str]) -> argparse.Namespace:
    parser = argparse.ArgumentParser(
        prog="./dev.sh mutants",
        description="Mutation testing (mutmut) of core modules; ends with 'killed K of M'.",
    )
    parser.add_argument(
        "files",
        nargs="*",
        metavar="FILE",
        help="modules to mutate (default: all of: " + ", ".join(TESTS_FOR) + ")",
    )
    parser.add_argument("-j", "--jobs", type=int, default=1, help="mutants run at once (1)")
    parser.add_argument(
        "--rev", help="mutate this git revision's files instead of the working tree"
    )
    parser.add_argument(
        "--only",
        action="append",
        default=[],
        metavar="PATTERN",
        help="run only the mutants whose mutmut names match (fnmatch; repeatable)",
    )
    args = parser.parse_args(argv)
    modules = []
    for f in args.files:
        rel = _relative(f)
        if rel not in TESTS_FOR:
            parser.error(
                f"{f}: no tests mapped for it in tools/mutants.py (known: {', '.join(TESTS_FOR)})"
            )
        if rel not in modules:
            modules.append(rel)
    if args.jobs < 1:
        parser.error("--jobs must be at least 1")
    args.modules = modules or list(TESTS_FOR)
    return args


def _relative(path: str) -> str:
    p = Path(path)
    if p.is_absolute():
        try:
            p = p.resolve().relative_to(ROOT)
        except ValueError:
            return path
    return p.as_posix().removeprefix("./")


def mutmut_config(module: str) -> str:
    """The [tool.mutmut] table for one module's run (appended to the copy's pyproject)."""
    settings: dict[str, object] = {
        "source_paths": ["autoscoop_blender"],
        "only_mutate": [module],
        "also_copy": ALSO_COPY,
        "pytest_add_cli_args": ["-p", "no:cacheprovider"],
        "pytest_add_cli_args_test_selection": TESTS_FOR[module],
        # The copy sits inside this repository: git would answer for the real tree.
        "use_git_change_detection": False,
        # A mutant's CPU-time limit is 2 x this x its tests' clean time: mutmut's 15
        # gave an endless pass loop in close_sites 20 CPU minutes; 5 still leaves a
        # mutant that only slows the tests (a prefilter gone) 10 x their time.
        "timeout_multiplier": 5.0,
    }
    lines = ["", "[tool.mutmut]"]
    lines += [f"{key} = {json.dumps(value)}" for key, value in settings.items()]
    return "\n".join(lines) + "\n"


def _git(*args: str) -> bytes:
    return subprocess.run(["git", *args], cwd=ROOT, check=True, capture_output=True).stdout


def make_copy(dest: Path, rev: str | None) -> None:
    """A fresh copy of the project in ``dest``: REV's files, or the working tree's."""
    if dest.exists():
        shutil.rmtree(dest)
    dest.mkdir(parents=True)
    if rev is not None:
        archive = dest / ".rev.tar"
        archive.write_bytes(_git("archive", "--format=tar", rev))
        with tarfile.open(archive) as tar:
            tar.extractall(dest, filter="data")
        archive.unlink()
        return
    names = _git("ls-files", "-z", "--cached", "--others", "--exclude-standard").split(b"\0")
    for raw in names:
        if not raw:
            continue
        rel = raw.decode()
        src = ROOT / rel
        if not src.is_file():  # deleted in the working tree
            continue
        (dest / rel).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(src, dest / rel)


def run_module(module: str, jobs: int, rev: str | None, only: list[str]) -> Score | None:
    """Run mutmut on one module in its own copy; None when mutmut failed."""
    work = WORK / module.removesuffix(".py").replace("/", ".")
    make_copy(work, rev)
    pyproject = work / "pyproject.toml"
    text = pyproject.read_text()
    if "[tool.mutmut]" in text:
        raise SystemExit("pyproject.toml already has [tool.mutmut]: the settings live here")
    pyproject.write_text(text + mutmut_config(module))
    print(f"== mutants of {module} (tests: {' '.join(TESTS_FOR[module])}) in {work}", flush=True)
    mutmut = [sys.executable, "-m", "mutmut"]
    env = dict(os.environ, PYTHONDONTWRITEBYTECODE="1")
    code = subprocess.run([*mutmut, "run", "--max-children", str(jobs), *only], cwd=work, env=env)
    if code.returncode != 0:
        print(f"error: mutmut failed on {module} (exit {code.returncode})", file=sys.stderr)
        return None
    return read_score(module, work)


def read_score(module: str, work: Path) -> Score:
    """Statuses from mutmut's result file, diffs of the survivors from ``mutmut show``."""
    meta = work / "mutants" / (module + ".meta")
    data = json.loads(meta.read_text())
    from mutmut.stats import status_by_exit_code

    score = Score(module)
    for name, code in data["exit_code_by_key"].items():
        score.status[name] = status_by_exit_code[code]
    for name in score.survivors():
        shown = subprocess.run(
            [sys.executable, "-m", "mutmut", "show", name],
            cwd=work,
            capture_output=True,
            text=True,
        ).stdout
        score.diffs[name] = [
            line
            for line in shown.splitlines()
            if line[:1] in "+-" and not line.startswith(("+++", "---"))
        ]
    return score


def report(scores: list[Score]) -> str:
    out = []
    for s in scores:
        out.append(f"{s.module}: {s.summary()}")
        for name in s.survivors():
            out.append(f"  {s.status[name]}: {name}")
            out += [f"      {line.strip()}" for line in s.diffs.get(name, [])]
    killed = sum(s.killed for s in scores)
    total = sum(s.total for s in scores)
    out.append(f"killed {killed} of {total}")
    return "\n".join(out)


def main(argv: list[str] | None = None) -> int:
    args = parse_args(sys.argv[1:] if argv is None else argv)
    if args.rev is not None:
        args.rev = _git("rev-parse", "--verify", args.rev + "^{commit}").decode().strip()
        print(f"== mutating the files of commit {args.rev}")
    scores: list[Score] = []
    failed = []
    try:
        for module in args.modules:
            score = run_module(module, args.jobs, args.rev, args.only)
            if score is None:
                failed.append(module)
            else:
                scores.append(score)
                print(f"{module}: {score.summary()}", flush=True)
    except KeyboardInterrupt:
        print("\ninterrupted: the sources were never touched (mutants live in .mutants/)")
        if scores:
            print(report(scores))
        return 130
    print("== mutation scores")
    print(report(scores))
    if failed:
        print("not scored (mutmut failed): " + ", ".join(failed), file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
