// GPhoto2Camera against a real libgphoto2 talking to its own virtual PTP camera (vusb),
// built by scripts/build-vusb-camera.sh; run through scripts/with-vusb-camera.sh, which sets
// the environment (tests/gphoto2.cmake does both as CTest fixture and wrapper).
#include <dlfcn.h>
#include <gphoto2/gphoto2-camera.h>
#include <gphoto2/gphoto2-port-result.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>

#include <chrono>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "capture/bracket.h"
#include "capture/gphoto2_camera.h"
#include "rig/session_store.h"
#include "tests/support/run_rig.h"

// Failures the virtual camera cannot produce (busy, a claimed device, a vanished one) come
// from a fake at the libgphoto2 boundary: these two calls fail as told, else forward to the
// real library underneath.
namespace fake {
int busy_captures = 0;      // the next N captures answer GP_ERROR_CAMERA_BUSY
int failing_captures = 0;   // the next N captures answer `capture_error`
int capture_error = GP_ERROR_IO;
bool claimed = false;       // gp_camera_init answers GP_ERROR_IO_USB_CLAIM
int captures_seen = 0;
}  // namespace fake

extern "C" int gp_camera_capture(::Camera* camera, CameraCaptureType type, CameraFilePath* path,
                                 GPContext* context) {
  using Fn = int (*)(::Camera*, CameraCaptureType, CameraFilePath*, GPContext*);
  static Fn real = reinterpret_cast<Fn>(dlsym(RTLD_NEXT, "gp_camera_capture"));
  ++fake::captures_seen;
  if (fake::busy_captures > 0) return --fake::busy_captures, GP_ERROR_CAMERA_BUSY;
  if (fake::failing_captures > 0) return --fake::failing_captures, fake::capture_error;
  return real(camera, type, path, context);
}

extern "C" int gp_camera_init(::Camera* camera, GPContext* context) {
  using Fn = int (*)(::Camera*, GPContext*);
  static Fn real = reinterpret_cast<Fn>(dlsym(RTLD_NEXT, "gp_camera_init"));
  if (fake::claimed) return GP_ERROR_IO_USB_CLAIM;
  return real(camera, context);
}

namespace rig {
namespace {

using ::testing::HasSubstr;

CameraConfig VirtualBody() {
  CameraConfig c;
  c.backend = "gphoto2";
  const char* port = std::getenv("RIG_VUSB_PORT");
  const char* model = std::getenv("RIG_VUSB_MODEL");
  c.port = port ? port : "";
  c.model = model ? model : "";
  c.retries = 2;
  c.retry_backoff_s = 0.05;
  c.delete_from_card = false;  // the virtual card is a folder of this machine
  return c;
}

class GPhoto2Camera : public ::testing::Test {
 protected:
  void SetUp() override {
    ASSERT_NE(std::getenv("RIG_VUSB_PORT"), nullptr)
        << "run through scripts/with-vusb-camera.sh (ctest does)";
  }
};

TEST_F(GPhoto2Camera, OpensTheVirtualBodyAndReadsItsShutterSpeeds) {
  auto cam = MakeGPhoto2Camera(VirtualBody());
  Status st = cam->Open();
  ASSERT_TRUE(st.ok()) << st.error().ToString();
  EXPECT_THAT(cam->Describe(), HasSubstr("Nikon DSC D750"));
  auto speeds = cam->ShutterSpeeds();
  ASSERT_TRUE(speeds.ok()) << speeds.error().ToString();
  // The virtual body offers nine values from 1/10000 s to 1 s ("0.0001s" .. "1.0000s").
  ASSERT_EQ(speeds->size(), 9u);
  EXPECT_NEAR(speeds->front().count(), 0.0001, 1e-9);
  EXPECT_NEAR(speeds->back().count(), 1.0, 1e-9);
  for (size_t i = 1; i < speeds->size(); ++i) EXPECT_GT((*speeds)[i], (*speeds)[i - 1]);
  cam->Close();
}

TEST_F(GPhoto2Camera, ABracketIsChosenFromTheBodysListSetReadBackCapturedAndDownloaded) {
  auto cam = MakeGPhoto2Camera(VirtualBody());
  ASSERT_TRUE(cam->Open().ok());
  auto speeds = cam->ShutterSpeeds();
  ASSERT_TRUE(speeds.ok());
  BracketConfig b;
  b.center_s = 0.01;
  b.ev_step = 1;
  b.count = 3;
  const auto wanted = WantedExposures(b);
  auto planned = SnapToShutterSpeeds(wanted, *speeds);
  ASSERT_TRUE(planned.ok()) << planned.error().ToString();
  std::ifstream in(std::getenv("RIG_VUSB_JPEG"), std::ios::binary);
  const std::vector<uint8_t> served((std::istreambuf_iterator<char>(in)), {});
  ASSERT_FALSE(served.empty());
  for (Seconds t : *planned) {
    EXPECT_NE(std::find(speeds->begin(), speeds->end(), t), speeds->end());
    auto frame = cam->Capture(t);
    ASSERT_TRUE(frame.ok()) << frame.error().ToString();
    EXPECT_NEAR(frame->exposure.count(), t.count(), 1e-9);  // read back from the body
    ASSERT_EQ(frame->files.size(), 1u);
    EXPECT_EQ(frame->files[0].extension, "jpg");
    EXPECT_EQ(frame->files[0].bytes, served);  // byte for byte what the body holds
  }
}

TEST_F(GPhoto2Camera, SettingsTheBodyLacksAreReportedNotFaked) {
  auto cam = MakeGPhoto2Camera(VirtualBody());
  ASSERT_TRUE(cam->Open().ok());
  CameraSettings want;
  want.iso = "100";  // the virtual body has no ISO setting
  auto applied = cam->Configure(want);
  ASSERT_TRUE(applied.ok());
  EXPECT_TRUE(applied->iso.empty());
}

TEST_F(GPhoto2Camera, AnUnknownModelOrPortFailsWithLibgphoto2sMessage) {
  CameraConfig c = VirtualBody();
  c.model = "No Such Camera 9000";
  Status st = MakeGPhoto2Camera(c)->Open();
  ASSERT_FALSE(st.ok());
  EXPECT_THAT(st.error().ToString(), HasSubstr("No Such Camera 9000"));
  c = VirtualBody();
  c.port = "usb:>nothing-here";
  st = MakeGPhoto2Camera(c)->Open();
  ASSERT_FALSE(st.ok());
  EXPECT_THAT(st.error().ToString(), HasSubstr("nothing-here"));
}

TEST_F(GPhoto2Camera, ADryRunWithTheVirtualBodyAndTheSimulatedMotorCompletes) {
  const std::string dir = testing::FreshTempDir("gphoto2_session");
  const std::string cfg = testing::WriteSimConfig(dir, fmt::format(R"([camera]
backend = 'gphoto2'
model = '{}'
port = '{}'
delete_from_card = false
[bracket]
center_s = 0.01
ev_step = 1.0
count = 3
)", std::getenv("RIG_VUSB_MODEL"), std::getenv("RIG_VUSB_PORT")));
  // Not --dry-run (that would simulate the camera too): the motor and lamp are "sim".
  auto r = testing::RunRig("capture --config " + cfg + " --out " + dir + "/S --no-process --no-progress");
  ASSERT_EQ(r.status, 0) << r.output;
  auto journal = Journal::Read(fs::path(dir) / "S" / "journal.jsonl");
  ASSERT_TRUE(journal.ok());
  int frames = 0;
  for (const auto& rec : journal->records) frames += rec.value("event", "") == "frame";
  EXPECT_EQ(frames, 40 * 3);
  fs::remove_all(dir);
}

TEST_F(GPhoto2Camera, ABusyBodyIsRetriedWithBackOffThenGivesUpNamingTheError) {
  auto cam = MakeGPhoto2Camera(VirtualBody());  // retries 2, back-off 0.05 s doubling
  ASSERT_TRUE(cam->Open().ok());
  fake::busy_captures = 2;
  fake::captures_seen = 0;
  const auto t0 = std::chrono::steady_clock::now();
  auto frame = cam->Capture(Seconds(0.01));
  ASSERT_TRUE(frame.ok()) << frame.error().ToString();
  EXPECT_EQ(fake::captures_seen, 3);
  EXPECT_GE(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(), 0.15);
  fake::busy_captures = 5;
  frame = cam->Capture(Seconds(0.01));
  fake::busy_captures = 0;
  ASSERT_FALSE(frame.ok());
  EXPECT_EQ(frame.error().code, ErrorCode::kBusy);
  EXPECT_THAT(frame.error().ToString(), HasSubstr(gp_result_as_string(GP_ERROR_CAMERA_BUSY)));
}

TEST_F(GPhoto2Camera, AClaimedDeviceNamesTheUsualCulprit) {
  fake::claimed = true;
  Status st = MakeGPhoto2Camera(VirtualBody())->Open();
  fake::claimed = false;
  ASSERT_FALSE(st.ok());
  EXPECT_THAT(st.error().ToString(), HasSubstr("another program holds the camera"));
  EXPECT_THAT(st.error().ToString(), HasSubstr("gvfs"));
}

TEST_F(GPhoto2Camera, ABodyThatVanishesFailsTheCaptureAndWorksAgainAfterReopening) {
  auto cam = MakeGPhoto2Camera(VirtualBody());
  ASSERT_TRUE(cam->Open().ok());
  fake::failing_captures = 1;
  fake::capture_error = GP_ERROR_IO_USB_FIND;
  auto frame = cam->Capture(Seconds(0.01));
  ASSERT_FALSE(frame.ok());
  EXPECT_THAT(frame.error().ToString(), HasSubstr(gp_result_as_string(GP_ERROR_IO_USB_FIND)));
  // What the capture daemon does between retries: close, open again, capture.
  cam->Close();
  ASSERT_TRUE(cam->Open().ok());
  frame = cam->Capture(Seconds(0.01));
  ASSERT_TRUE(frame.ok()) << frame.error().ToString();
}

TEST(ShutterSpeedLabels, ParseByValueWhateverTheBodysNotation) {
  EXPECT_NEAR(*ParseShutterSpeed("1/100"), 0.01, 1e-12);
  EXPECT_NEAR(*ParseShutterSpeed("0.0100s"), 0.01, 1e-12);
  EXPECT_NEAR(*ParseShutterSpeed("1/4000s"), 0.00025, 1e-12);
  EXPECT_NEAR(*ParseShutterSpeed("30"), 30, 1e-12);
  EXPECT_NEAR(*ParseShutterSpeed("2.5s"), 2.5, 1e-12);
  EXPECT_FALSE(ParseShutterSpeed("Bulb"));
  EXPECT_FALSE(ParseShutterSpeed("x 1/200"));
}

}  // namespace
}  // namespace rig
