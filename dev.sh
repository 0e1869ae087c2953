#!/usr/bin/env bash
# Run a command inside the project's virtual environment, creating and
# filling it first when it is missing or pyproject.toml has changed.
#   ./dev.sh parc render -o parc.png     render the built-in volume
#   ./dev.sh test                        run the test suite
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
venv="$root/.venv"
stamp="$venv/.installed"
python="${PYTHON:-python3}"

if [ ! -x "$venv/bin/python" ] || [ ! -f "$stamp" ] || [ "$root/pyproject.toml" -nt "$stamp" ]; then
    if ! command -v "$python" >/dev/null 2>&1; then
        echo "dev.sh: no Python at '$python'; set PYTHON to a Python 3.10 or newer" >&2
        exit 2
    fi
    echo "dev.sh: setting up $venv (first run only)" >&2
    # A venv made by another Python (an earlier try with PYTHON too old) is made
    # again: python -m venv keeps an existing venv's interpreter.
    version='import sys; print(sys.version_info[:2])'
    clear=()
    if [ -x "$venv/bin/python" ] && [ "$("$venv/bin/python" -c "$version" 2>/dev/null)" != "$("$python" -c "$version")" ]; then
        clear=(--clear)
    fi
    "$python" -m venv ${clear[@]+"${clear[@]}"} "$venv"
    # pip's notes (the build backend's warnings, a machine's index settings) go to a log,
    # shown only when the install fails; --no-input, so that a question pip would ask
    # (an index's password) fails there rather than waiting unseen.
    log="$venv/install.log"
    if ! { "$venv/bin/python" -m pip install --quiet --no-input --upgrade pip \
           && "$venv/bin/python" -m pip install --quiet --no-input -e "$root[test]"; } >"$log" 2>&1; then
        cat "$log" >&2
        echo "dev.sh: installing into $venv failed (the log above is kept in $log)" >&2
        exit 1
    fi
    touch "$stamp"
fi

export PATH="$venv/bin:$PATH"

if [ "${1:-}" = "test" ]; then
    shift
    cd "$root"
    # The test files are shared among one worker process per CPU, up to four
    # (pytest-xdist): most of a first run is compiling kernels, one process at
    # a time each, and two workers halved that run on two cores. `-n 0` after
    # `test` runs everything in this process (for `-s` or `--pdb`).
    cpus="$(python -c 'import os; print(len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1)')"
    workers=$(( cpus < 4 ? cpus : 4 ))
    exec python -m pytest -n "$workers" --dist loadfile "$@"
fi
exec "$@"
