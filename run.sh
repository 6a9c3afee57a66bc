#!/usr/bin/env bash
# One entry point for a fresh machine (Python 3.11, pip, gcc):
#   bash run.sh demo   - the main job on the embedded default example
#   bash run.sh test   - the test suite
#   bash run.sh lint   - ruff and the type check of the whole project (configured in pyproject.toml)
#   bash run.sh lock   - refresh requirements.lock (the exact versions installed by demo and test)
# Each command creates/refreshes the virtual environment .venv first.
set -euo pipefail
cd "$(dirname "$0")"
VENV="${EBB_VENV:-.venv}"
PY="$VENV/bin/python"

LOCK=requirements.lock

setup() {
    if [ ! -x "$PY" ]; then
        python3 -m venv "$VENV"
    fi
    local stamp="$VENV/.ebb-installed"
    if [ ! -f "$stamp" ] || [ pyproject.toml -nt "$stamp" ] || [ "$LOCK" -nt "$stamp" ]; then
        # the exact versions the suite was last run with (pyproject.toml keeps the open lower bounds)
        "$PY" -m pip install --quiet -c "$LOCK" pip
        "$PY" -m pip install --quiet -c "$LOCK" -e ".[test]"
        touch "$stamp"
    fi
}

# Refresh the lock: resolve the newest versions allowed by pyproject.toml in a scratch environment.
# Run the suite with the new lock before committing it (bash run.sh lock && bash run.sh test).
lock() {
    local tmp
    tmp=$(mktemp -d)
    python3 -m venv "$tmp/venv"
    "$tmp/venv/bin/python" -m pip install --quiet --upgrade pip
    "$tmp/venv/bin/python" -m pip install --quiet ".[test]"
    {
        echo "# Exact versions for 'bash run.sh demo|test' (pip constraints). Refresh: bash run.sh lock"
        echo "# Python $("$tmp/venv/bin/python" -c 'import platform; print(platform.python_version())'), resolved $(date -u +%Y-%m-%d)"
        "$tmp/venv/bin/python" -m pip freeze --all | grep -v -i -E '^(ebb-ident|setuptools|wheel)[=@ ]'
    } > "$LOCK"
    rm -rf "$tmp"
    echo "wrote $LOCK"
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
        # the HTML reports are checked in a real headless browser (Playwright drives it): whichever is there
        # (tests/browser.py), else Debian's chromium where apt-get can install it; without any, the page tests are
        # reported as skipped (not run) and everything else runs
        if ! "$PY" tests/browser.py >/dev/null 2>&1; then
            if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1; then
                echo "run.sh: installing Debian's chromium for the HTML report tests"
                apt-get install -y -q chromium >/dev/null 2>&1 \
                    || { apt-get update -q >/dev/null 2>&1 && apt-get install -y -q chromium >/dev/null 2>&1; } || true
            fi
            "$PY" tests/browser.py >/dev/null 2>&1 \
                || echo "run.sh: no browser here and none could be installed: the HTML page tests will be skipped (not run)" >&2
        fi
        shift || true
        # one test process per core, each taking the next test when it is free (the blind diagnoses are long and
        # uneven); -n 0 runs them in this process; the 25 slowest tests are listed at the end
        "$PY" -m pytest -q -n auto --dist worksteal --durations=25 "$@"
        ;;
    lint)
        setup
        "$VENV/bin/ruff" check .
        "$VENV/bin/mypy"
        ;;
    lock)
        lock
        ;;
    *)
        echo "usage: bash run.sh demo|test [pytest args]|lint|lock" >&2
        exit 2
        ;;
esac
