#!/usr/bin/env bash
# Set up everything `make demo` and `make test` need, idempotently:
#   - ngspice's shared library (Debian: libngspice0-dev) through apt-get when it is missing;
#   - a virtual environment in .venv with lagrangian (editable), its test extras,
#     and the example third-party plugin under examples/plugins/cubic-spring.
set -euo pipefail
cd "$(dirname "$0")/.."

have_ngspice() { ldconfig -p 2>/dev/null | grep -q 'libngspice\.so\(\.0\)\? '; }
if ! have_ngspice; then
    echo "setup: ngspice's shared library is missing; installing libngspice0-dev with apt-get"
    sudo=""
    if [ "$(id -u)" -ne 0 ]; then sudo="sudo"; fi
    if ! command -v apt-get >/dev/null 2>&1 || { [ -n "$sudo" ] && ! command -v sudo >/dev/null 2>&1; }; then
        echo "setup: error: cannot install ngspice here (no apt-get, or no root/sudo)." >&2
        echo "setup: install ngspice's shared library with your system's package manager" >&2
        echo "setup: (Debian/Ubuntu: libngspice0-dev; Fedora: libngspice-devel; macOS: brew install libngspice) and rerun." >&2
        exit 1
    fi
    $sudo apt-get update -qq || true
    if ! DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq libngspice0-dev >/dev/null; then
        echo "setup: error: apt-get could not install libngspice0-dev; install it by hand and rerun." >&2
        exit 1
    fi
    have_ngspice || { echo "setup: error: libngspice.so still not found after installing libngspice0-dev." >&2; exit 1; }
fi

python=${PYTHON:-python3}
if [ ! -x .venv/bin/python ]; then
    echo "setup: creating .venv with $($python --version)"
    $python -m venv .venv
fi
stamp=.venv/.lagrangian-installed
if [ ! -f "$stamp" ] || [ pyproject.toml -nt "$stamp" ] || [ examples/plugins/cubic-spring/pyproject.toml -nt "$stamp" ]; then
    echo "setup: installing lagrangian, its dependencies and the example plugin into .venv"
    .venv/bin/python -m pip install -q --disable-pip-version-check -e ".[test]" -e examples/plugins/cubic-spring
    touch "$stamp"
fi
# The runtime library of compiled models (tape interpreter, stepping loops): built once per machine and cached,
# so that no model waits for the C compiler.  Without a compiler models run on NumPy: not an error.
.venv/bin/python -c "import lagrangian.codegen as c; c.runtime()" 2>/dev/null \
    || echo "setup: note: no C compiler found; models will be evaluated with NumPy (slower)"
