#!/usr/bin/env bash
# The whole test suite under AddressSanitizer + UndefinedBehaviorSanitizer (clang-14), in its
# own build folder build-asan/ (the same build carries libFuzzer's instrumentation and the
# harnesses of tests/fuzz/: scripts/fuzz.sh uses it). Any sanitizer report — in a test binary
# or in a `rig` it runs — fails the run, even when the test itself passed. docs/fuzzing.md.
#
#   scripts/test-sanitize.sh [--ci] [ctest arguments...]
#   --ci                 only what CI runs: the tests labelled sanitize-ci (every reader of
#                        untrusted input, the session store, the commands that read them:
#                        tests/CMakeLists.txt RIG_SANITIZE_CI_TESTS) and every harness's seeds
#                        and regression inputs (label fuzz); builds only what those need
#   RIG_ASAN_BUILD=DIR   another build folder (default build-asan)
set -euo pipefail
cd "$(dirname "$0")/.."
root=$(pwd)
ci=0
if [ "${1:-}" = "--ci" ]; then
  ci=1
  shift
fi
build=${RIG_ASAN_BUILD:-build-asan}
bash scripts/setup.sh
cmake -S . -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=Release -DRIG_WERROR="${RIG_WERROR:-OFF}" \
  -DCMAKE_C_COMPILER=clang-14 -DCMAKE_CXX_COMPILER=clang++-14 -DRIG_FUZZ=ON \
  -DRIG_BUILD_BENCH=OFF -DRIG_UNITY_BUILD=ON >/dev/null
source scripts/sanitizer-env.sh "$root/$build"
if [ "$ci" = 1 ]; then
  cmake --build "$build" -j2 --target sanitize_ci_tests fuzzers
else
  cmake --build "$build" -j2
  cmake --build "$build" -j2 --target fuzzers
fi

# Left out here (they run in the plain suite), each for a fault in third-party code, found by
# this suite on 2 December 2026:
# - gphoto2.* (libgphoto2 2.5.30's virtual USB camera, built from Debian's source as a test
#   fixture): vcamera.c's trace of a read fwrite()s 1024 bytes past a shorter buffer
#   (vcam_read, line 1931) and segfaults under ASan; its ptp_shutterspeed_getdesc leaks.
# - DevicesCommand.* (`rig devices`): libgphoto2's usb1 port library, loaded and unloaded
#   inside gp_camera_autodetect, leaks libusb's device list from a module LeakSanitizer can no
#   longer name, so no suppression can match it.
skip='^(gphoto2\.|DevicesCommand\.)'
status=0
select=()
if [ "$ci" = 1 ]; then
  select=(-L 'sanitize-ci|fuzz')
  # Two long fits over the full-size real capture in the selected binaries (2.3 min and 0.8 min
  # of the selection's 4.4 under ASan): numerical work, no reader, run by the whole suite.
  skip="$skip|^(EvaluateLpCommand\.EveryFamilyIsRefittedPerHeldOutImageAndCharted|FitLpCommand\.RealCaptureDefaultFitsWithinTheByteBudget)$"
fi
ctest --test-dir "$build" -j2 --output-on-failure --timeout 900 -E "$skip" "${select[@]}" "$@" \
  || status=$?
if compgen -G "$RIG_SANITIZER_LOGS/*" >/dev/null; then
  echo "test-sanitize: sanitizer reports (in $RIG_SANITIZER_LOGS):" >&2
  for f in "$RIG_SANITIZER_LOGS"/*; do
    echo "---- $f" >&2
    head -n 60 "$f" >&2
  done
  status=1
fi
if [ "$status" -eq 0 ]; then
  if [ "$ci" = 1 ]; then
    echo "test-sanitize: CI's selection (sanitize-ci, fuzz) is clean under ASan+UBSan"
  else
    echo "test-sanitize: the suite is clean under ASan+UBSan"
  fi
fi
exit "$status"
