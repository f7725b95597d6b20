// A serial port over libserialport: found by path or USB id, locked, 8N1, and read through
// poll() on its descriptor with a short tick so that an interrupt is noticed promptly.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <string_view>

#include "config/config.h"
#include "config/result.h"

struct sp_port;

namespace rig {

// Interrupts every blocking serial read or write within one tick (20 ms). Set by
// RequestSerialInterrupt() or by SIGINT/SIGTERM through capture/devices/signals.h (StopRequested()).
// Async-signal-safe.
void RequestSerialInterrupt();
void ClearSerialInterrupt();
bool SerialInterruptRequested();

// Which port to open: a path (symlinks such as /dev/serial/by-id/... are resolved), else
// the first port whose USB VID:PID and/or serial number match.
struct SerialSelector {
  std::string path;
  std::string usb_vid_pid;  // "2341:0043"
  std::string usb_serial;
  int baud = 115200;
  static SerialSelector FromConfig(const MotorConfig& config);
  // "/dev/ttyACM0", or "usb 2341:0043 serial 55739323" when found by USB id.
  std::string Describe() const;
};

// One open port. Not thread-safe: one owner at a time. Every call that can block takes a
// timeout; every failure names the port. A port that went away (USB unplugged: read or
// write error, POLLHUP) fails with ErrorCode::kIo and lost() turns true; a timeout is
// kTimeout; an interrupt is kInterrupted.
class SerialPort {
 public:
  // Opens, takes an exclusive lock (flock + TIOCEXCL; kBusy if another program holds
  // it), sets 8N1 at the baud rate without flow control, and flushes stale input.
  static Result<std::unique_ptr<SerialPort>> Open(const SerialSelector& selector);
  ~SerialPort();
  SerialPort(const SerialPort&) = delete;
  SerialPort& operator=(const SerialPort&) = delete;

  // The device path that was opened (after resolving symlinks), e.g. "/dev/pts/3".
  const std::string& device() const { return device_; }
  // The name errors use: the path as configured (e.g. the by-id link), else device().
  const std::string& name() const { return name_; }
  bool lost() const { return lost_; }

  // Writes all bytes within `timeout`.
  Status Write(std::string_view bytes, Seconds timeout);
  // Reads exactly `n` bytes within `timeout`.
  Result<std::string> ReadExact(size_t n, Seconds timeout, bool interruptible = true);
  // The next line (terminator "\n", "\r\n" or "\r" stripped; empty lines skipped), or
  // nothing when none completed within `timeout`. A partial line stays buffered.
  Result<std::optional<std::string>> ReadLine(Seconds timeout, bool interruptible = true);
  // Drops buffered and pending input.
  Status FlushInput();
  // Bytes already received but not yet consumed by ReadLine/ReadExact.
  size_t buffered() const { return buffer_.size(); }

 private:
  SerialPort() = default;
  // Waits up to `timeout` for input and appends what arrives to buffer_. Returns false
  // on timeout (nothing new).
  Result<bool> Fill(Seconds timeout, bool interruptible);
  Error Lost(const std::string& what);

  sp_port* port_ = nullptr;
  int fd_ = -1;
  std::string device_, name_;
  std::string buffer_;
  bool lost_ = false;
};

// The meaning of an ASCII-or-not line for logs: printable, with \xNN escapes.
std::string EscapeForLog(std::string_view bytes);

}  // namespace rig
