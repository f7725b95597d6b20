// The session's log file: every line is in the file the moment it is logged (a live view with
// `tail -f`, nothing lost to a crash), whatever its level and whenever its logger was made.
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "config/log.h"
#include "tests/support/run_rig.h"

namespace rig {
namespace {

using ::testing::HasSubstr;

std::string Slurp(const std::string& path) {
  std::ifstream in(path);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

TEST(LogFile, EveryLineIsInTheFileAsSoonAsItIsLoggedWithoutAFlush) {
  const std::string dir = testing::FreshTempDir("log_line_buffered");
  const std::string path = dir + "/log.txt";
  ASSERT_TRUE(SetLogLevel("debug"));
  auto before = Log("logtest_before");  // made before the file was added
  ASSERT_TRUE(AddLogFile(path));
  auto after = Log("logtest_after");    // made after
  before->debug("event=first key={}", 1);
  EXPECT_THAT(Slurp(path), HasSubstr("event=first key=1"));
  after->info("event=second key={}", 2);
  EXPECT_THAT(Slurp(path), HasSubstr("event=second key=2"));
  after->debug("event=third key={}", 3);
  EXPECT_THAT(Slurp(path), HasSubstr("event=third key=3"));
  ASSERT_TRUE(SetLogLevel("info"));
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace rig
