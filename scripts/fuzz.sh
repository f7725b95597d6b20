#!/usr/bin/env bash
# Runs every libFuzzer harness of tests/fuzz/ for a fixed time each, on a copy of its seed
# corpus (the repository is never modified), after replaying its regression inputs; prints
# per harness the inputs executed, the corpus reached, crashes, hangs (-timeout) and leaks.
# Builds build-asan/ (scripts/test-sanitize.sh's folder) when it is not there. docs/fuzzing.md.
#
#   scripts/fuzz.sh                     8 s per harness (CI's smoke run, ~1.5 min in all)
#   scripts/fuzz.sh --minutes 30        30 min per harness
#   scripts/fuzz.sh --seconds 60 lp exr only these harnesses
#   --keep DIR                          keep the grown corpora and any crash inputs in DIR
#
# Exit 1 if any harness crashed, hung, leaked or failed a regression input.
set -euo pipefail
cd "$(dirname "$0")/.."
root=$(pwd)
build=${RIG_ASAN_BUILD:-build-asan}
seconds=8
keep=""
only=()
while [ $# -gt 0 ]; do
  case "$1" in
    --seconds) seconds=$2; shift 2 ;;
    --minutes) seconds=$(( $2 * 60 )); shift 2 ;;
    --keep) keep=$2; shift 2 ;;
    -h|--help) sed -n 2,14p "$0"; exit 0 ;;
    -*) echo "fuzz.sh: unknown option $1" >&2; exit 2 ;;
    *) only+=("$1"); shift ;;
  esac
done

if [ ! -d "$build/tests/fuzz" ]; then
  bash scripts/setup.sh
  cmake -S . -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=Release -DRIG_WERROR="${RIG_WERROR:-OFF}" \
    -DCMAKE_C_COMPILER=clang-14 -DCMAKE_CXX_COMPILER=clang++-14 -DRIG_FUZZ=ON \
    -DRIG_BUILD_BENCH=OFF -DRIG_UNITY_BUILD=ON >/dev/null
fi
cmake --build "$build" -j2 --target fuzzers

# A small quarantine: freed images would otherwise count against the 2 GB RSS limit.
export ASAN_OPTIONS="halt_on_error=1:detect_leaks=1:print_stacktrace=1:strict_string_checks=1:quarantine_size_mb=32"
export UBSAN_OPTIONS="halt_on_error=1:print_stacktrace=1:report_error_type=1:suppressions=$root/tests/fuzz/sanitizer/ubsan.supp"
export LSAN_OPTIONS="suppressions=$root/tests/fuzz/sanitizer/lsan.supp:print_suppressions=0"
command -v llvm-symbolizer-14 >/dev/null && export ASAN_SYMBOLIZER_PATH=$(command -v llvm-symbolizer-14)

work=$(mktemp -d "${TMPDIR:-/tmp}/rig-fuzz-run-XXXXXX")
trap 'rm -rf "$work"' EXIT
[ -n "$keep" ] && mkdir -p "$keep"

names=()
if [ ${#only[@]} -gt 0 ]; then
  names=("${only[@]}")
else
  for src in tests/fuzz/*_fuzz.cc; do
    names+=("$(basename "$src" _fuzz.cc)")
  done
fi

failed=0
printf '%-16s %10s %8s %10s %7s %5s %6s %s\n' harness inputs exec/s corpus cov crash hang regressions
for n in "${names[@]}"; do
  bin="$build/tests/fuzz/fuzz_$n"
  [ -x "$bin" ] || { echo "fuzz: no harness $bin" >&2; failed=1; continue; }
  corpus="$work/corpus-$n"
  artifacts="$work/artifacts-$n"
  mkdir -p "$corpus" "$artifacts"
  cp -r "tests/fuzz/corpus/$n/." "$corpus/" 2>/dev/null || true
  # Regression inputs first: each must run clean.
  reg="ok"
  if compgen -G "tests/fuzz/regressions/$n/*" >/dev/null; then
    if ! "$bin" -timeout=10 -rss_limit_mb=2048 tests/fuzz/regressions/$n/* >"$work/$n.regress.log" 2>&1; then
      reg="FAILED"
      failed=1
      tail -n 40 "$work/$n.regress.log" >&2
    else
      reg="$(ls tests/fuzz/regressions/$n | wc -l) ok"
    fi
  else
    reg="none"
  fi
  dict=()
  [ -e "tests/fuzz/dict/$n.dict" ] && dict=(-dict="tests/fuzz/dict/$n.dict")
  status=0
  "$bin" -max_total_time="$seconds" -timeout=10 -rss_limit_mb=2048 -max_len=65536 "${dict[@]}" \
    -print_final_stats=1 -artifact_prefix="$artifacts/" "$corpus" >"$work/$n.log" 2>&1 || status=$?
  runs=$(grep -o 'stat::number_of_executed_units: *[0-9]*' "$work/$n.log" | grep -o '[0-9]*$' | tail -1 || true)
  rate=$(grep -o 'stat::average_exec_per_sec: *[0-9]*' "$work/$n.log" | grep -o '[0-9]*$' | tail -1 || true)
  cov=$(grep -o 'cov: [0-9]*' "$work/$n.log" | tail -1 | grep -o '[0-9]*' || true)
  files=$(ls "$corpus" | wc -l)
  bytes=$(( $(cat "$corpus"/* 2>/dev/null | wc -c) / 1024 ))
  crashes=$(ls "$artifacts" | grep -c -E '^(crash|leak|oom|deadly)' || true)
  hangs=$(ls "$artifacts" | grep -c '^timeout' || true)
  printf '%-16s %10s %8s %10s %7s %5s %6s %s\n' "$n" "${runs:-?}" "${rate:-?}" "${files}/${bytes}K" \
    "${cov:-?}" "$crashes" "$hangs" "$reg"
  if [ "$status" -ne 0 ] || [ "$crashes" -ne 0 ] || [ "$hangs" -ne 0 ]; then
    failed=1
    echo "fuzz: $n failed (exit $status); its log:" >&2
    grep -v '^#\|^INFO\|^Done\|^MS:\|^stat::\|NEW_FUNC' "$work/$n.log" | head -n 60 >&2 || true
  fi
  if [ -n "$keep" ]; then
    mkdir -p "$keep/$n"
    cp -r "$corpus" "$keep/$n/corpus"
    cp -r "$artifacts" "$keep/$n/artifacts"
    cp "$work/$n.log" "$keep/$n/log.txt"
  fi
done
exit $failed
