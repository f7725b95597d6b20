#!/usr/bin/env bash
# Installs the dependencies (scripts/setup.sh) and builds rig into build/ (Release, -j2).
#   scripts/build.sh            everything: the rig executable, every test and benchmark
#   scripts/build.sh rig        only what is named (the demo builds only the rig executable)
# RIG_WERROR=ON turns warnings into errors (CI does). ccache is used when it is installed.
# Ninja prints one line per step ("[41/136 1m32s] Building ..."), so a build is never silent.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
launcher=()
if command -v ccache >/dev/null 2>&1; then
  launcher=(-DCMAKE_C_COMPILER_LAUNCHER=ccache -DCMAKE_CXX_COMPILER_LAUNCHER=ccache)
fi
cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=Release -DRIG_WERROR="${RIG_WERROR:-OFF}" \
  "${launcher[@]}" >/dev/null
export NINJA_STATUS="${NINJA_STATUS:-[%f/%t %es] }"
if [ $# -gt 0 ]; then
  cmake --build build -j2 --target "$@"
else
  cmake --build build -j2
fi
