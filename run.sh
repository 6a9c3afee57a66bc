#!/usr/bin/env bash
# One entry point for a fresh machine (Python 3.11, pip, gcc):
#   bash run.sh demo   - the main job on the embedded default example
#   bash run.sh test   - the test suite
# Each command creates/refreshes the virtual environment .venv first.
set -euo pipefail
cd "$(dirname "$0")"
VENV="${EBB_VENV:-.venv}"
PY="$VENV/bin/python"

setup() {
    if [ ! -x "$PY" ]; then
        python3 -m venv "$VENV"
    fi
    local stamp="$VENV/.ebb-installed"
    if [ ! -f "$stamp" ] || [ pyproject.toml -nt "$stamp" ]; then
        "$PY" -m pip install --quiet --upgrade pip
        "$PY" -m pip install --quiet -e ".[test]"
        touch "$stamp"
    fi
}

cmd="${1:-}"
case "$cmd" in
    demo)
        setup
        # synthetic data with a withheld effect -> identify -> export FMU + StateSpace -> diagnose
        rm -rf demo-out
        "$VENV/bin/ebb" demo --out demo-out
        ;;
    test)
        setup
        shift || true
        "$PY" -m pytest -q "$@"
        ;;
    *)
        echo "usage: bash run.sh demo|test [pytest args]" >&2
        exit 2
        ;;
esac
