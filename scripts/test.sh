#!/usr/bin/env bash
# Sets everything up and runs the whole test suite: the README's test command, and CI's.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/build.sh
ctest --test-dir build -j2 --output-on-failure --timeout 600 "$@"
# RIG_TEST_SANITIZE=1: then the same suite under ASan+UBSan (build-asan/) and a bounded fuzz
# run of every reader (docs/fuzzing.md). Off by default until the sanitizer suite has run green
# within CI's time budget (it has not been measured yet).
if [ "${RIG_TEST_SANITIZE:-0}" != 0 ]; then
  bash scripts/test-sanitize.sh "$@"
  bash scripts/fuzz.sh --seconds "${RIG_FUZZ_SECONDS:-8}"
fi
