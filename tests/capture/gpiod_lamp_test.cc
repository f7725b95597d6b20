// GpiodLamp through a fake at the libgpiod boundary (this machine's kernel has no GPIO): the
// fake defines the few libgpiod 1.6 functions the lamp calls, and records what it was told.
#include <gpiod.h>

#include <cerrno>
#include <cstring>
#include <string>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "capture/devices/gpiod_lamp.h"
#include "capture/devices/signals.h"

struct gpiod_chip {
  std::string name;
};
struct gpiod_line {
  unsigned offset = 0;
  std::string name;
  bool requested = false;
  int flags = 0;
  int value = -1;
};

namespace {
struct FakeGpio {
  gpiod_chip chip{"gpiochip0"};
  std::vector<gpiod_line> lines = {{0, "RELAY", false, 0, -1}, {1, "LED", false, 0, -1}, {17, "", false, 0, -1}};
  std::vector<std::pair<std::string, int>> log;  // (line, value) every write
  bool held_elsewhere = false, write_fails = false;
  int open_chips = 0;
} g;
}  // namespace

extern "C" {
gpiod_chip* gpiod_chip_open_lookup(const char* desc) {
  if (std::string(desc) != "gpiochip0" && std::string(desc) != "0" && std::string(desc) != "/dev/gpiochip0") {
    errno = ENOENT;
    return nullptr;
  }
  ++g.open_chips;
  return &g.chip;
}
void gpiod_chip_close(gpiod_chip*) { --g.open_chips; }
gpiod_line* gpiod_chip_find_line(gpiod_chip*, const char* name) {
  for (auto& l : g.lines)
    if (!l.name.empty() && l.name == name) return &l;
  errno = ENOENT;
  return nullptr;
}
gpiod_line* gpiod_chip_get_line(gpiod_chip*, unsigned int offset) {
  for (auto& l : g.lines)
    if (l.offset == offset) return &l;
  errno = EINVAL;
  return nullptr;
}
int gpiod_line_request_output_flags(gpiod_line* line, const char*, int flags, int default_val) {
  if (g.held_elsewhere) {
    errno = EBUSY;
    return -1;
  }
  line->requested = true;
  line->flags = flags;
  line->value = default_val;
  g.log.push_back({line->name.empty() ? std::to_string(line->offset) : line->name, default_val});
  return 0;
}
int gpiod_line_set_value(gpiod_line* line, int value) {
  if (!line->requested || g.write_fails) {
    errno = EIO;
    return -1;
  }
  line->value = value;
  g.log.push_back({line->name.empty() ? std::to_string(line->offset) : line->name, value});
  return 0;
}
void gpiod_line_release(gpiod_line* line) { line->requested = false; }
}

namespace rig {
namespace {

using ::testing::HasSubstr;

LampConfig Config(const std::string& line, bool active_low = false) {
  LampConfig c;
  c.backend = "gpiod";
  c.chip = "gpiochip0";
  c.line = line;
  c.active_low = active_low;
  c.warmup_s = 0.05;
  return c;
}

void Reset() {
  g = FakeGpio{};
}

TEST(GpiodLamp, OffOnOpenOnAndOffThenOffAndReleasedOnClose) {
  Reset();
  auto lamp = MakeGpiodLamp(Config("RELAY"));
  ASSERT_TRUE(lamp->Open().ok());
  EXPECT_TRUE(g.lines[0].requested);
  EXPECT_EQ(g.lines[0].value, 0);  // requested as an output driven off
  ASSERT_TRUE(lamp->On().ok());
  EXPECT_EQ(g.lines[0].value, 1);
  ASSERT_TRUE(lamp->Off().ok());
  EXPECT_EQ(g.lines[0].value, 0);
  ASSERT_TRUE(lamp->On().ok());
  lamp->Close();  // on exit, fault or Ctrl-C: off first, then released
  EXPECT_EQ(g.lines[0].value, 0);
  EXPECT_FALSE(g.lines[0].requested);
  EXPECT_EQ(g.open_chips, 0);
  EXPECT_EQ(g.log.back(), (std::pair<std::string, int>{"RELAY", 0}));
}

TEST(GpiodLamp, ActiveLowIsLibgpiodsFlagAndALineByNumberWorks) {
  Reset();
  auto lamp = MakeGpiodLamp(Config("17", /*active_low=*/true));
  ASSERT_TRUE(lamp->Open().ok());
  EXPECT_EQ(g.lines[2].flags, GPIOD_LINE_REQUEST_FLAG_ACTIVE_LOW);
  ASSERT_TRUE(lamp->On().ok());
  EXPECT_EQ(g.lines[2].value, 1);  // logical on; libgpiod inverts it on the wire
}

TEST(GpiodLamp, WarmUpIsWaitedOutAndCtrlCCutsItShort) {
  Reset();
  LampConfig c = Config("RELAY");
  c.warmup_s = 0.3;
  auto lamp = MakeGpiodLamp(c);
  ASSERT_TRUE(lamp->Open().ok());
  auto t0 = std::chrono::steady_clock::now();
  ASSERT_TRUE(lamp->On().ok());
  EXPECT_GE(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(), 0.29);
  ClearStopForTesting();
  RequestStop(2);
  t0 = std::chrono::steady_clock::now();
  Status st = lamp->On();
  ClearStopForTesting();
  EXPECT_EQ(st.error().code, ErrorCode::kInterrupted);
  EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(), 0.2);
}

TEST(GpiodLamp, MissingChipOrLineAndABusyLineAreClearErrors) {
  Reset();
  LampConfig c = Config("RELAY");
  c.chip = "gpiochip9";
  Status st = MakeGpiodLamp(c)->Open();
  ASSERT_FALSE(st.ok());
  EXPECT_THAT(st.error().ToString(), HasSubstr("gpiochip9"));
  EXPECT_EQ(st.error().code, ErrorCode::kNotFound);
  st = MakeGpiodLamp(Config("NOPE"))->Open();
  ASSERT_FALSE(st.ok());
  EXPECT_THAT(st.error().ToString(), HasSubstr("NOPE"));
  g.held_elsewhere = true;
  st = MakeGpiodLamp(Config("RELAY"))->Open();
  ASSERT_FALSE(st.ok());
  EXPECT_THAT(st.error().ToString(), HasSubstr("another program"));
  EXPECT_EQ(g.open_chips, 0);  // nothing left open after a failed open
}

TEST(GpiodLamp, AFailedSwitchIsReportedNamingTheLine) {
  Reset();
  auto lamp = MakeGpiodLamp(Config("RELAY"));
  ASSERT_TRUE(lamp->Open().ok());
  g.write_fails = true;
  Status st = lamp->On();
  ASSERT_FALSE(st.ok());
  EXPECT_THAT(st.error().ToString(), HasSubstr("RELAY"));
  EXPECT_THAT(st.error().ToString(), HasSubstr("cannot switch on"));
}

}  // namespace
}  // namespace rig
