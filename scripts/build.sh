#!/usr/bin/env bash
# Installs the dependencies (scripts/setup.sh) and builds rig into build/ (Release, -j2).
# RIG_WERROR=ON turns warnings into errors (CI does).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=Release -DRIG_WERROR="${RIG_WERROR:-OFF}" >/dev/null
cmake --build build -j2
