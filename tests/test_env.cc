// Linked into every test binary: sets RIG_SOURCE_DIR, RIG_SHARED_DIR, RIG_BINARY and
// RIG_BINARY_DIR to the paths of this build (and progress lines off) (unless the environment already sets them), so
// a test binary runs the same under ctest, run by hand, or under a debugger.
#include <cstdlib>

namespace {

struct TestEnvironment {
  TestEnvironment() {
    setenv("RIG_SOURCE_DIR", RIG_TEST_SOURCE_DIR, 0);
    setenv("RIG_SHARED_DIR", RIG_TEST_SHARED_DIR, 0);
    setenv("RIG_BINARY", RIG_TEST_BINARY, 0);
    setenv("RIG_BINARY_DIR", RIG_TEST_BINARY_DIR, 0);
    // Off a terminal rig prints a progress line every 5 s; in the suite, whose tests compare
    // the output of runs, only the console test asks for them (RIG_PROGRESS_EVERY_S there).
    setenv("RIG_PROGRESS_EVERY_S", "100000", 0);
  }
};

const TestEnvironment kTestEnvironment;

}  // namespace
