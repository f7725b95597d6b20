# Sourced by scripts/test-sanitize.sh and scripts/fuzz.sh with the sanitizer build folder:
# every report stops the process (halt_on_error, no recovery from UB), leaks are reports, and
# each report is also written under BUILD/sanitizer-logs/ so that one in a child `rig` fails
# the run even if its test looked only at the exit code.
build_dir=$1
export RIG_SANITIZER_LOGS="$build_dir/sanitizer-logs"
rm -rf "$RIG_SANITIZER_LOGS"
mkdir -p "$RIG_SANITIZER_LOGS"
supp="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)/tests/fuzz/sanitizer"
export ASAN_OPTIONS="suppressions=$supp/asan.supp:halt_on_error=1:abort_on_error=0:detect_leaks=1:print_stacktrace=1:strict_string_checks=1:check_initialization_order=1:detect_odr_violation=2:log_path=$RIG_SANITIZER_LOGS/asan:log_exe_name=1"
export UBSAN_OPTIONS="halt_on_error=1:print_stacktrace=1:report_error_type=1:suppressions=$supp/ubsan.supp:log_path=$RIG_SANITIZER_LOGS/ubsan:log_exe_name=1"
export LSAN_OPTIONS="suppressions=$supp/lsan.supp:print_suppressions=0"
if command -v llvm-symbolizer-14 >/dev/null; then
  export ASAN_SYMBOLIZER_PATH=$(command -v llvm-symbolizer-14)
fi
