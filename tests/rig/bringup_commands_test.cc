// The bring-up commands on the simulated rig, and the installed rig reaching the GRBL
// emulator's pseudo-terminal through the installed pty shim.
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <regex>
#include <string>
#include <thread>

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "sim/grbl_emulator.h"
#include "tests/support/run_rig.h"

namespace rig {
namespace {

using ::testing::HasSubstr;
using ::testing::Not;
using testing::RunRig;

double Number(const std::string& text, const std::string& re) {
  std::smatch m;
  if (!std::regex_search(text, m, std::regex(re))) return -1;
  return std::stod(m[1]);
}

TEST(DevicesCommand, JsonListsEveryKindAndTheTextSaysWhenOneHasNone) {
  auto j = RunRig("devices --json");
  ASSERT_EQ(j.status, 0) << j.output;
  auto inv = nlohmann::json::parse(j.output.substr(j.output.find('{')), nullptr, false);
  ASSERT_FALSE(inv.is_discarded()) << j.output;
  for (const char* k : {"cameras", "serial_ports", "gpio_chips"}) ASSERT_TRUE(inv[k].is_array()) << k;
  auto t = RunRig("devices");
  ASSERT_EQ(t.status, 0) << t.output;
  EXPECT_THAT(t.output, HasSubstr("cameras (libgphoto2 auto-detect):"));
  EXPECT_THAT(t.output, HasSubstr("serial ports (libserialport):"));
  EXPECT_THAT(t.output, HasSubstr("GPIO chips and lines (libgpiod):"));
  // The two forms agree: each kind with none found says so, each found one is named.
  if (inv["cameras"].empty() && !inv["errors"].contains("cameras")) {
    EXPECT_THAT(t.output, HasSubstr("none found (is the body on"));
  }
  for (const auto& c : inv["cameras"]) EXPECT_THAT(t.output, HasSubstr(c["port"].get<std::string>()));
  if (inv["serial_ports"].empty() && !inv["errors"].contains("serial_ports")) {
    EXPECT_THAT(t.output, HasSubstr("none found (is the controller plugged in?"));
  }
  for (const auto& p : inv["serial_ports"]) EXPECT_THAT(t.output, HasSubstr(p["name"].get<std::string>()));
  if (inv["gpio_chips"].empty() && !inv["errors"].contains("gpio_chips")) {
    EXPECT_THAT(t.output, HasSubstr("none found (no /dev/gpiochip*"));
  }
  for (const auto& c : inv["gpio_chips"]) EXPECT_THAT(t.output, HasSubstr(c["name"].get<std::string>()));
}

TEST(JogCommand, MovesTheSimulatedArmAndRefusesPosesOutsideTheSoftLimits) {
  auto r = RunRig("jog --dry-run --to 30,10");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_THAT(r.output, HasSubstr("at h 30.000 v 10.000 deg"));
  auto out = RunRig("jog --dry-run --to 30,95");
  EXPECT_EQ(out.status, 2) << out.output;
  EXPECT_THAT(out.output, HasSubstr("--to 30,95"));
  EXPECT_THAT(out.output, Not(HasSubstr("at h")));
  auto bad = RunRig("jog --dry-run --to 30");
  EXPECT_EQ(bad.status, 2);
  EXPECT_THAT(bad.output, HasSubstr("is not H,V"));
  auto home = RunRig("home --dry-run");
  ASSERT_EQ(home.status, 0) << home.output;
  EXPECT_THAT(home.output, HasSubstr("homed; at h 0.000 v 0.000 deg"));
}

TEST(LampCommand, BlinksAndIsLeftOffAlsoOnCtrlC) {
  auto r = RunRig("lamp blink --dry-run --times 2 --on-s 0 --off-s 0");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_THAT(r.output, HasSubstr("on (1 of 2)"));
  EXPECT_THAT(r.output, HasSubstr("on (2 of 2)"));
  EXPECT_THAT(r.output, Not(HasSubstr("on (3 of 2)")));
  EXPECT_THAT(r.output.substr(r.output.rfind("sim lamp")), HasSubstr("off"));

  const std::string dir = testing::FreshTempDir("lamp_ctrl_c");
  const std::string log = dir + "/log.txt";
  pid_t pid = testing::SpawnRig({"lamp", "on", "--dry-run"}, log);  // on until Ctrl-C
  std::string text;
  for (int i = 0; i < 200 && text.find("Ctrl-C switches it off") == std::string::npos; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
    std::ifstream in(log);
    text.assign(std::istreambuf_iterator<char>(in), {});
  }
  ASSERT_THAT(text, HasSubstr("on (Ctrl-C switches it off)"));
  kill(pid, SIGINT);
  EXPECT_EQ(testing::WaitRig(pid), 130);
  std::ifstream in(log);
  text.assign(std::istreambuf_iterator<char>(in), {});
  EXPECT_THAT(text.substr(text.rfind("sim lamp")), HasSubstr(": off"));
  std::filesystem::remove_all(dir);
}

// The simulated scene has a specular highlight and a shadow: a long exposure clips and asks
// for shorter ones, a very short one is dark and asks for longer ones.
TEST(ShotCommand, ReportsClippingAndDarknessAndSuggestsABracketThatCoversThem) {
  auto longer = RunRig("shot --dry-run --exposure 0.5");
  ASSERT_EQ(longer.status, 0) << longer.output;
  const double clipped = Number(longer.output, "clipped \\(a channel >= 250\\): ([0-9.]+)%");
  EXPECT_GT(clipped, 1.0) << longer.output;
  const double shortest = Number(longer.output, "suggested bracket: ([0-9.e-]+) s");
  EXPECT_GT(shortest, 0);
  EXPECT_LT(shortest, 0.5 / 4) << longer.output;
  EXPECT_THAT(longer.output, HasSubstr("[bracket]\ncenter_s = "));
  EXPECT_THAT(longer.output, HasSubstr("on this body:"));

  auto shorter = RunRig("shot --dry-run --exposure 0.0002");
  ASSERT_EQ(shorter.status, 0) << shorter.output;
  const double dark = Number(shorter.output, "dark \\(<= 5\\): ([0-9.]+)%");
  EXPECT_GT(dark, 10.0) << shorter.output;
  const double longest = Number(shorter.output, "suggested bracket: [0-9.e-]+ s \\.\\. ([0-9.e-]+) s");
  EXPECT_GT(longest, 0.0002 * 4) << shorter.output;
  EXPECT_EQ(Number(shorter.output, "clipped \\(a channel >= 250\\): ([0-9.]+)%"), 0);
}

// Live view for framing and focus: previews at the body's exposure, each with its sharpness;
// the last one saved (never over a file); Ctrl-C ends an endless preview cleanly.
TEST(ShotCommand, PreviewsPrintTheirSharpnessSaveTheLastAndEndOnCtrlC) {
  const std::string dir = testing::FreshTempDir("shot_preview");
  auto r = RunRig("shot --dry-run --preview --repeat 2 --every 0.05 --save " + dir + "/p.jpg");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_THAT(r.output, HasSubstr("preview 1: 320x240  focus "));
  EXPECT_THAT(r.output, HasSubstr("preview 2: 320x240  focus "));
  EXPECT_THAT(r.output, Not(HasSubstr("preview 3:")));
  EXPECT_GT(Number(r.output, "preview 2: 320x240  focus ([0-9.]+)"), 10) << r.output;
  std::ifstream jpeg(dir + "/p.jpg", std::ios::binary);
  std::string bytes((std::istreambuf_iterator<char>(jpeg)), {});
  ASSERT_GE(bytes.size(), 3u);
  EXPECT_EQ(bytes.substr(0, 3), "\xFF\xD8\xFF");
  auto again = RunRig("shot --dry-run --preview --save " + dir + "/p.jpg");
  EXPECT_NE(again.status, 0);
  EXPECT_THAT(again.output, HasSubstr("exists"));
  auto both = RunRig("shot --dry-run --preview --exposure 0.1");
  EXPECT_EQ(both.status, 2);
  auto neither = RunRig("shot --dry-run");
  EXPECT_EQ(neither.status, 2);
  EXPECT_THAT(neither.output, HasSubstr("--exposure S or --preview is required"));
  // Ambient only: far darker than lit.
  auto unlit = RunRig("shot --dry-run --preview --no-lamp");
  ASSERT_EQ(unlit.status, 0) << unlit.output;
  EXPECT_GT(Number(unlit.output, "dark ([0-9.]+)%"), 20) << unlit.output;
  EXPECT_LT(Number(r.output, "dark ([0-9.]+)%"), 5) << r.output;

  const std::string log = dir + "/log.txt";
  pid_t pid = testing::SpawnRig({"shot", "--dry-run", "--preview", "--repeat", "0", "--every", "0.05"}, log);
  std::string text;
  for (int i = 0; i < 500 && text.find("preview 3:") == std::string::npos; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
    std::ifstream in(log);
    text.assign(std::istreambuf_iterator<char>(in), {});
  }
  ASSERT_THAT(text, HasSubstr("preview 3:"));
  kill(pid, SIGINT);
  EXPECT_EQ(testing::WaitRig(pid), 130);
  std::filesystem::remove_all(dir);
}

// `cmake --install` into a fresh prefix; the installed rig homes and jogs the GRBL emulator
// through the installed shim (without it, libserialport refuses the pseudo-terminal).
TEST(PtyShim, TheInstalledRigReachesTheGrblEmulatorThroughTheInstalledShim) {
  const char* build = std::getenv("RIG_BINARY_DIR");
  ASSERT_NE(build, nullptr);
  const std::string prefix = testing::FreshTempDir("install_prefix");
  ASSERT_EQ(std::system(("cmake --install '" + std::string(build) + "' --prefix '" + prefix +
                         "' > '" + prefix + "/install.log' 2>&1")
                            .c_str()),
            0);
  const std::string rig = prefix + "/bin/rig", shim = prefix + "/lib/rig/librig_pty_shim.so";
  ASSERT_TRUE(std::filesystem::exists(rig));
  ASSERT_TRUE(std::filesystem::exists(shim));

  GrblEmulatorOptions o;
  o.time_scale = 200;
  o.banner_delay_s = 0.05;
  auto emu = StartGrblEmulator(o);
  ASSERT_TRUE(emu.ok()) << emu.error().ToString();
  const std::string cfg = testing::WriteSimConfig(
      prefix, "[motor]\nbackend = \"grbl\"\nport = \"" + (*emu)->path() +
                  "\"\nspeed_deg_per_s = 30\naccel_deg_per_s2 = 60\nreply_timeout_s = 0.5\n"
                  "move_timeout_s = 2.0\nretries = 0\n[motor.grbl]\nbanner_timeout_s = 0.5\n");
  auto run = [&](const std::string& env, const std::string& args) {
    std::string cmd = env + " '" + rig + "' " + args + " 2>&1";
    testing::CommandResult r;
    FILE* p = popen(cmd.c_str(), "r");
    char buf[4096];
    while (size_t n = fread(buf, 1, sizeof buf, p)) r.output.append(buf, n);
    int st = pclose(p);
    r.status = WIFEXITED(st) ? WEXITSTATUS(st) : -1;
    return r;
  };
  auto without = run("", "home --config " + cfg);
  EXPECT_NE(without.status, 0) << without.output;
  EXPECT_THAT(without.output, HasSubstr((*emu)->path()));
  EXPECT_EQ((*emu)->homings(), 0);

  const std::string preload = "LD_PRELOAD='" + shim + "'";
  auto home = run(preload, "home --config " + cfg);
  ASSERT_EQ(home.status, 0) << home.output;
  EXPECT_THAT(home.output, HasSubstr("homed"));
  EXPECT_EQ((*emu)->homings(), 1);
  // Opening the port resets the emulated Arduino (DTR) into its alarm lock: home, then jog.
  auto jog = run(preload, "jog --config " + cfg + " --home --to 20,10");
  ASSERT_EQ(jog.status, 0) << jog.output;
  EXPECT_THAT(jog.output, HasSubstr("at h 20.000 v 10.000 deg"));
  EXPECT_NEAR((*emu)->WorkPosition()[0], 20, 0.01);
  EXPECT_NEAR((*emu)->WorkPosition()[1], 10, 0.01);
  std::filesystem::remove_all(prefix);
}

}  // namespace
}  // namespace rig
