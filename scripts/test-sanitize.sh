#!/usr/bin/env bash
# The whole test suite under AddressSanitizer + UndefinedBehaviorSanitizer (clang-14), in its
# own build folder build-asan/ (the same build carries libFuzzer's instrumentation and the
# harnesses of tests/fuzz/: scripts/fuzz.sh uses it). Any sanitizer report — in a test binary
# or in a `rig` it runs — fails the run, even when the test itself passed. docs/fuzzing.md.
#
#   scripts/test-sanitize.sh [ctest arguments...]
#   RIG_ASAN_BUILD=DIR   another build folder (default build-asan)
set -euo pipefail
cd "$(dirname "$0")/.."
root=$(pwd)
build=${RIG_ASAN_BUILD:-build-asan}
bash scripts/setup.sh
cmake -S . -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=Release -DRIG_WERROR="${RIG_WERROR:-OFF}" \
  -DCMAKE_C_COMPILER=clang-14 -DCMAKE_CXX_COMPILER=clang++-14 -DRIG_FUZZ=ON \
  -DRIG_BUILD_BENCH=OFF >/dev/null
source scripts/sanitizer-env.sh "$root/$build"
cmake --build "$build" -j2
cmake --build "$build" -j2 --target fuzzers

# Tests too heavy for an instrumented build inside CI's budget carry the ctest label
# "sanitize-skip" (tests/CMakeLists.txt says which and why); they run in the plain suite.
status=0
ctest --test-dir "$build" -j2 --output-on-failure --timeout 900 -LE sanitize-skip "$@" || status=$?
if compgen -G "$RIG_SANITIZER_LOGS/*" >/dev/null; then
  echo "test-sanitize: sanitizer reports (in $RIG_SANITIZER_LOGS):" >&2
  for f in "$RIG_SANITIZER_LOGS"/*; do
    echo "---- $f" >&2
    head -n 60 "$f" >&2
  done
  status=1
fi
[ "$status" -eq 0 ] && echo "test-sanitize: the suite is clean under ASan+UBSan"
exit "$status"
