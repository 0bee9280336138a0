#!/usr/bin/env bash
# Bootstrap everything sparselt needs on a fresh Debian 12 machine (run as root for apt):
#   1. a libLLVM >= 17 for Dr.Jit's LLVM backend (Debian 12's default LLVM 14/15 crash
#      with "Cannot select: fminimum"): Debian's libllvm19, or PyPI's karellen-llvm-core;
#   2. the virtualenv .venv with sparselt installed (editable) and its test extras.
set -euo pipefail
cd "$(dirname "$0")/.."

PYTHON=${PYTHON:-python3}
VENV=${VENV:-.venv}

have_llvm() {
    ls /usr/lib/*/libLLVM*.so* /usr/lib/llvm-*/lib/libLLVM*.so* 2>/dev/null \
        | grep -Eq 'libLLVM(-|\.so\.)(1[7-9]|[2-9][0-9])'
}

as_root() { if [ "$(id -u)" = 0 ]; then "$@"; elif command -v sudo >/dev/null; then sudo "$@"; else return 1; fi; }

llvm_from_pypi=0
if ! have_llvm; then
    echo "bootstrap: installing libllvm19 for Dr.Jit"
    if command -v apt-get >/dev/null && { as_root apt-get install -y libllvm19 || { as_root apt-get update && as_root apt-get install -y libllvm19; }; }; then
        :
    else
        echo "bootstrap: apt-get could not install libllvm19; falling back to PyPI's karellen-llvm-core"
        llvm_from_pypi=1
    fi
fi

if [ ! -x "$VENV/bin/python" ]; then
    if ! "$PYTHON" -m venv "$VENV" 2>/dev/null; then
        echo "bootstrap: python venv module missing; installing python3-venv"
        rm -rf "$VENV"
        as_root apt-get install -y python3-venv || { as_root apt-get update && as_root apt-get install -y python3-venv; }
        "$PYTHON" -m venv "$VENV"
    fi
fi

"$VENV/bin/python" -m pip install --quiet --upgrade pip
"$VENV/bin/python" -m pip install --quiet -e '.[test]'
if [ "$llvm_from_pypi" = 1 ]; then
    "$VENV/bin/python" -m pip install --quiet karellen-llvm-core
fi

# Fail here, with the fix, rather than in the middle of a test run.
"$VENV/bin/python" -c "from sparselt.rendering import mitsuba as b; b.initialize(); print('bootstrap: Mitsuba', b.versions()['mitsuba'], 'on', __import__('os').environ['DRJIT_LIBLLVM_PATH'])"
