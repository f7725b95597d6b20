#!/usr/bin/env bash
# Sets everything up and runs the whole test suite: the README's test command, and CI's.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/build.sh
ctest --test-dir build -j2 --output-on-failure --timeout 600 "$@"
# Then the sanitizer stage (docs/fuzzing.md), also in CI: an ASan+UBSan build (build-asan/, clang)
# runs the tests of every reader of untrusted input and of the session store, every fuzz
# harness's seeds and regression inputs, and a bounded fuzz run of every reader.
#   RIG_TEST_SANITIZE=ci   (default) that selection;  =all  the whole suite under the
#                          sanitizers instead;  =0  the plain suite only
#   RIG_FUZZ_SECONDS=N     seconds per harness in the fuzz run (default 6)
case "${RIG_TEST_SANITIZE:-ci}" in
  0) ;;
  all) bash scripts/test-sanitize.sh "$@"
       bash scripts/fuzz.sh --seconds "${RIG_FUZZ_SECONDS:-6}" ;;
  *) bash scripts/test-sanitize.sh --ci "$@"
     bash scripts/fuzz.sh --seconds "${RIG_FUZZ_SECONDS:-6}" ;;
esac
