#!/usr/bin/env bash
# Set-up for a fresh Debian 12 machine: the system packages the tests and validation use
# (POV-Ray with its include files and sample scenes, LLVM 19 for Mitsuba's llvm_ad_rgb variant),
# then a virtual environment with the project and its test/validation extras.
set -euo pipefail
cd "$(dirname "$0")/.."

need_apt=()
command -v povray >/dev/null 2>&1 || need_apt+=(povray)
[ -d /usr/share/povray-3.7/include ] || need_apt+=(povray-includes)
[ -d /usr/share/povray-3.7/scenes ] || need_apt+=(povray-examples)
ls /usr/lib/*/libLLVM.so.19* >/dev/null 2>&1 || need_apt+=(libllvm19)
if [ ${#need_apt[@]} -gt 0 ]; then
  if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1; then
    echo "setup: installing ${need_apt[*]}"
    apt-get update -qq
    DEBIAN_FRONTEND=noninteractive apt-get install -y -qq "${need_apt[@]}" >/dev/null
  else
    echo "setup: missing system packages (${need_apt[*]}); POV-Ray/Mitsuba comparisons will be skipped" >&2
  fi
fi

PY=${PYTHON:-python3}
if [ ! -x .venv/bin/python ]; then
  "$PY" -m venv .venv
fi
.venv/bin/python -m pip install -q --upgrade pip >/dev/null 2>&1 || true
.venv/bin/python -m pip install -q -e '.[test,validation,dev]'
# the package's bytecode, written once: where PYTHONDONTWRITEBYTECODE is set (as on the CI machines)
# every process would otherwise compile ~100 modules from source (0.35 s of a command-line render)
.venv/bin/python -m compileall -q -j 0 raytracer validation benchmarks >/dev/null || true
