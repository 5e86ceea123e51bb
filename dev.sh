#!/usr/bin/env bash
# AutoSCOOP developer entry: sets up .venv (Python 3.11, pinned requirements) once,
# then runs the job asked for.
#   ./dev.sh demo   the main job (optimize the bundled sample scene), results in out/
#   ./dev.sh test   the test suite (fails when no test ran)
set -euo pipefail
cd "$(dirname "$0")"

PY=${PYTHON:-python3.11}
VENV=.venv
STAMP="$VENV/.requirements-$(sha256sum requirements.txt | cut -c1-16)"

setup() {
    if [ ! -x "$VENV/bin/python" ]; then
        "$PY" -m venv "$VENV"
    fi
    if [ ! -f "$STAMP" ]; then
        "$VENV/bin/python" -m pip install --disable-pip-version-check -q -r requirements.txt
        rm -f "$VENV"/.requirements-*
        touch "$STAMP"
    fi
}

case "${1:-}" in
    demo)
        setup
        shift
        exec "$VENV/bin/python" -m headless optimize "$@"
        ;;
    test)
        setup
        shift
        set +e
        "$VENV/bin/python" -m pytest "$@"
        code=$?
        set -e
        if [ "$code" -eq 5 ]; then
            echo "error: pytest ran no tests" >&2
            exit 1
        fi
        exit "$code"
        ;;
    *)
        echo "usage: ./dev.sh demo|test [extra arguments]" >&2
        exit 2
        ;;
esac
