// The journal entry points the journal harnesses call, in one place: the reader as a session
// uses it (Journal::Read / Journal::Open in capture/session/session_store.cc, every record
// through the guarded ParseJournal of journal_reader.h) and resume (Session::OpenExisting,
// then the capture daemon's verification of what the journal says is stored).
#pragma once

#include <cmath>
#include <filesystem>
#include <string>

#include "capture/daemon/daemon.h"
#include "capture/session/session_store.h"
#include "config/result.h"

namespace rig::fuzz {

// Reads a journal as resume reads it, and opens it for appending (which cuts a torn tail) —
// on `path`, which the caller may let be changed.
inline Status ReadJournalFile(const std::filesystem::path& path) {
  RIG_ASSIGN_OR_RETURN(JournalContents contents, Journal::Read(path));
  if (contents.valid_bytes > std::filesystem::file_size(path)) __builtin_trap();
  RIG_ASSIGN_OR_RETURN(Journal journal, Journal::Open(path));
  (void)journal;
  return Ok();
}

// A camera that opens and offers shutter speeds but captures nothing (not retryable): the
// daemon verifies the stored frames against the journal, checks the journal's plan, homes, and
// stops at the first frame it would capture.
class RefusingCamera final : public Camera {
 public:
  std::string Describe() const override { return "fuzz camera"; }
  Status Open() override { return Ok(); }
  void Close() override {}
  Result<std::vector<Seconds>> ShutterSpeeds() override {
    std::vector<Seconds> s;
    for (double t = 1.0 / 4000; t < 31; t *= std::cbrt(2.0)) s.push_back(Seconds(t));
    return s;
  }
  Result<CameraSettings> Configure(const CameraSettings& wanted) override { return wanted; }
  Result<CapturedFrame> Capture(Seconds) override {
    return MakeError(ErrorCode::kUnsupported, "fuzz camera", "captures nothing");
  }
};
class IdleMotor final : public Motor {
 public:
  std::string Describe() const override { return "fuzz motor"; }
  Status Open() override { return Ok(); }
  void Close() override {}
  Status Home() override { return Ok(); }
  Status MoveTo(const Pose&) override { return Ok(); }
  Result<Pose> Position() override { return Pose{}; }
  Status Stop() override { return Ok(); }
  Status Reconnect() override { return Ok(); }
};
class IdleLamp final : public Lamp {
 public:
  std::string Describe() const override { return "fuzz lamp"; }
  Status Open() override { return Ok(); }
  Status On() override { return Ok(); }
  Status Off() override { return Ok(); }
  void Close() override {}
};

// `rig resume SESSION` up to the devices: open the session (lock, session.toml, journal), and
// let the daemon read the journal and verify the frames it names.
inline Status ResumeUpToDevices(const std::filesystem::path& session_dir) {
  RIG_ASSIGN_OR_RETURN(Session session, Session::OpenExisting(session_dir));
  RefusingCamera camera;
  IdleMotor motor;
  IdleLamp lamp;
  CaptureOptions options;
  options.process = false;
  options.progress = false;
  CaptureDaemon daemon(session, camera, motor, lamp, options);
  CaptureSummary summary;
  return daemon.Run(&summary);
}

}  // namespace rig::fuzz
