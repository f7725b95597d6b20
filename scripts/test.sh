#!/usr/bin/env bash
# Sets everything up and runs the whole test suite: the README's test command, and CI's.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/build.sh
ctest --test-dir build -j2 --output-on-failure --timeout 600 "$@"
