#!/usr/bin/env bash
# AutoSCOOP developer entry: sets up .venv (Python 3.11, bpy 5.0.1, pinned requirements.txt
# and the optional Ray extra, requirements-ray.txt) once, then runs the job asked for.
#   ./dev.sh demo   the main job (optimize the bundled sample scene), results in out/
#                   (replacing an earlier demo's)
#   ./dev.sh test   the test suite on bpy 5.0.1 / Python 3.11, then the extension, core and
#                   packaging tests on bpy 5.2.3 / Python 3.13 in .venv-py313 (skipped, with
#                   a message, when no Python 3.13 is found; PYTHON313= names one).
#                   Extra arguments go to the first pytest run, and then it alone runs.
#   ./dev.sh coverage [PYTEST ARGS]
#                   the first pytest run (all tests, or PYTEST ARGS) with branch coverage of
#                   autoscoop_blender/core and autoscoop_blender/io: a table per file, then
#                   the total ("TOTAL ... %"); settings in pyproject.toml [tool.coverage].
#   ./dev.sh mutants [-j N] [--rev REV] [--only PATTERN] [FILE...]
#                   mutation testing (mutmut) of the named core modules (default: every
#                   module mapped in tools/mutants.py, long) with the tests
#                   mapped to each; ends with "killed K of M" per module and in total and
#                   the surviving mutants' changed lines. Mutants go to .mutants/ (git-
#                   ignored), never into the sources. -j: mutants run at once (default 1);
#                   --only: just the mutants whose names match (fnmatch, repeatable).
#   ./dev.sh bench [WHAT] [ARGS]
#                   benchmarks that print figures (python -m tools bench --help)
#   ./dev.sh build [ARGS]
#                   the extension zips, one per platform, in dist/ (python -m tools build)
#   ./dev.sh samples
#                   rebuild sample_blends/*.blend (python -m tools samples)
#   ./dev.sh docs   write the docs' generated reference pages and build the site with
#                   mkdocs --strict into build/site/ (open build/site/index.html)
#   Neither coverage, mutants nor bench is part of ./dev.sh test.
set -euo pipefail
cd "$(dirname "$0")"

PY=${PYTHON:-python3.11}

# The Python 3.11 venv's requirements: the pinned ones and the optional Ray extra (its
# tests run there; the Python 3.13 venv runs no test that needs it).
REQS311=(requirements.txt requirements-ray.txt)

# setup VENV PYTHON REQUIREMENTS...: create VENV with PYTHON and install REQUIREMENTS,
# once per content of the requirement files.
setup() {
    local venv=$1 py=$2
    shift 2
    local stamp
    stamp="$venv/.requirements-$(cat "$@" requirements-bundled.txt | sha256sum | cut -c1-16)"
    if [ ! -x "$venv/bin/python" ]; then
        "$py" -m venv "$venv"
    fi
    if [ ! -f "$stamp" ]; then
        local req args=()
        for req in "$@"; do args+=(-r "$req"); done
        "$venv/bin/python" -m pip install --disable-pip-version-check -q "${args[@]}"
        rm -f "$venv"/.requirements-*
        touch "$stamp"
    fi
}

# A Python 3.13: $PYTHON313, python3.13 on the PATH, or pyenv's newest 3.13.
find_python313() {
    if [ -n "${PYTHON313:-}" ]; then
        echo "$PYTHON313"
    elif python3.13 -c "" 2>/dev/null; then
        command -v python3.13
    elif command -v pyenv >/dev/null; then
        local v
        v=$(pyenv versions --bare 2>/dev/null | grep -E '^3\.13(\.[0-9]+)?$' | tail -1)
        [ -n "$v" ] && PYENV_VERSION=$v pyenv which python3.13 2>/dev/null
    fi
}

# run_pytest VENV ARGS...: pytest in VENV; "no tests ran" (exit 5) is a failure.
run_pytest() {
    local venv=$1
    shift
    set +e
    "$venv/bin/python" -m pytest "$@"
    local code=$?
    set -e
    if [ "$code" -eq 5 ]; then
        echo "error: pytest ran no tests" >&2
        return 1
    fi
    return "$code"
}

case "${1:-}" in
    demo)
        setup .venv "$PY" "${REQS311[@]}"
        shift
        # out/ is the demo's own folder: an earlier demo's results are replaced.
        exec .venv/bin/python -m headless optimize --overwrite "$@"
        ;;
    test)
        setup .venv "$PY" "${REQS311[@]}"
        shift
        first=0
        run_pytest .venv "$@" || first=$?
        second=0
        if [ "$#" -gt 0 ]; then
            echo "== bpy 5.2.3 on Python 3.13 not run: arguments given (run ./dev.sh test alone)"
        elif py313=$(find_python313) && [ -n "$py313" ]; then
            echo "== bpy 5.2.3 on Python 3.13 ($py313): extension, core and packaging tests"
            setup .venv-py313 "$py313" requirements-py313.txt
            # mypy runs in the first environment only (test_types).
            run_pytest .venv-py313 -q tests/blender/test_extension.py tests/core \
                tests/packaging --ignore=tests/core/test_types.py || second=$?
        else
            echo "== SKIPPED bpy 5.2.3 on Python 3.13: no python3.13 found (set PYTHON313=)"
        fi
        [ "$first" -eq 0 ] && [ "$second" -eq 0 ]
        ;;
    coverage)
        setup .venv "$PY" "${REQS311[@]}"
        shift
        run_pytest .venv --cov --cov-branch --cov-report=term "$@"
        ;;
    mutants)
        setup .venv "$PY" "${REQS311[@]}"
        shift
        exec .venv/bin/python -m tools.mutants "$@"
        ;;
    bench|build|samples|docs)
        setup .venv "$PY" "${REQS311[@]}"
        exec .venv/bin/python -m tools "$@"
        ;;
    *)
        echo "usage: ./dev.sh demo|test|coverage|mutants|bench|build|samples|docs [extra arguments]" >&2
        exit 2
        ;;
esac
