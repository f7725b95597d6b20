// SerialPort: libserialport for finding, opening and configuring; poll() for waiting.
#include "capture/devices/serial_port.h"

#include <fcntl.h>
#include <libserialport.h>
#include <poll.h>
#include <sys/file.h>
#include <sys/ioctl.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <chrono>
#include <climits>
#include <cstdlib>
#include <cstring>

#include "config/log.h"
#include "capture/devices/signals.h"

namespace rig {
namespace {

std::atomic<bool> g_serial_interrupt{false};

// The poll tick: how long a blocked read can take to notice an interrupt.
constexpr auto kTick = std::chrono::milliseconds(20);

using Clock = std::chrono::steady_clock;

Clock::time_point DeadlineAfter(Seconds timeout) {
  return Clock::now() + std::chrono::duration_cast<Clock::duration>(timeout);
}

int MillisUntil(Clock::time_point deadline) {
  auto left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline - Clock::now());
  if (left.count() <= 0) return 0;
  return static_cast<int>(std::min<std::chrono::milliseconds>(left, kTick).count());
}

std::string SpMessage() {
  char* msg = sp_last_error_message();
  std::string s = msg != nullptr ? msg : "unknown error";
  if (msg != nullptr) sp_free_error_message(msg);
  return s;
}

// Finds the first port whose USB identity matches; kNotFound lists what was seen.
Result<std::string> FindUsbPort(const SerialSelector& sel) {
  int want_vid = -1, want_pid = -1;
  if (!sel.usb_vid_pid.empty()) {
    unsigned vid = 0, pid = 0;
    if (std::sscanf(sel.usb_vid_pid.c_str(), "%4x:%4x", &vid, &pid) != 2)
      return MakeError(ErrorCode::kInvalidInput, sel.Describe(),
                       "usb_vid_pid '{}' is not 'vvvv:pppp' in hexadecimal", sel.usb_vid_pid);
    want_vid = static_cast<int>(vid);
    want_pid = static_cast<int>(pid);
  }
  sp_port** list = nullptr;
  if (sp_list_ports(&list) != SP_OK)
    return MakeError(ErrorCode::kIo, sel.Describe(), "cannot list serial ports: {}", SpMessage());
  std::string found, seen;
  for (int i = 0; list[i] != nullptr; ++i) {
    sp_port* p = list[i];
    const char* name = sp_get_port_name(p);
    int vid = -1, pid = -1;
    const char* serial = nullptr;
    if (sp_get_port_transport(p) == SP_TRANSPORT_USB) {
      sp_get_port_usb_vid_pid(p, &vid, &pid);
      serial = sp_get_port_usb_serial(p);
    }
    seen += fmt::format("{}{} ({})", seen.empty() ? "" : ", ", name,
                        vid < 0 ? std::string("not usb")
                                : fmt::format("{:04x}:{:04x}{}{}", vid, pid, serial ? " serial " : "",
                                              serial ? serial : ""));
    if (vid < 0 || !found.empty()) continue;
    if (want_vid >= 0 && (vid != want_vid || pid != want_pid)) continue;
    if (!sel.usb_serial.empty() && (serial == nullptr || sel.usb_serial != serial)) continue;
    found = name;
  }
  sp_free_port_list(list);
  if (found.empty())
    return MakeError(ErrorCode::kNotFound, sel.Describe(), "no such USB serial device (ports seen: {})",
                     seen.empty() ? "none" : seen);
  return found;
}

}  // namespace

void RequestSerialInterrupt() { g_serial_interrupt.store(true); }
void ClearSerialInterrupt() { g_serial_interrupt.store(false); }
bool SerialInterruptRequested() { return g_serial_interrupt.load() || StopRequested(); }

SerialSelector SerialSelector::FromConfig(const MotorConfig& config) {
  SerialSelector s;
  s.path = config.port;
  s.usb_vid_pid = config.usb_vid_pid;
  s.usb_serial = config.usb_serial;
  s.baud = config.baud;
  return s;
}

std::string SerialSelector::Describe() const {
  if (!path.empty()) return path;
  std::string d = "usb";
  if (!usb_vid_pid.empty()) d += " " + usb_vid_pid;
  if (!usb_serial.empty()) d += " serial " + usb_serial;
  return d;
}

std::string EscapeForLog(std::string_view bytes) {
  std::string out;
  for (unsigned char c : bytes) {
    if (c >= 0x20 && c < 0x7f) {
      out += static_cast<char>(c);
    } else if (c == '\r') {
      out += "\\r";
    } else if (c == '\n') {
      out += "\\n";
    } else {
      out += fmt::format("\\x{:02x}", c);
    }
  }
  return out;
}

Result<std::unique_ptr<SerialPort>> SerialPort::Open(const SerialSelector& sel) {
  std::string name = sel.Describe();
  std::string device;
  if (!sel.path.empty()) {
    // libserialport 0.1.1 derives the sysfs name from the path text, so a symlink such as
    // /dev/serial/by-id/usb-... must be resolved first.
    char resolved[PATH_MAX];
    if (realpath(sel.path.c_str(), resolved) == nullptr) {
      int err = errno;
      return MakeError(err == ENOENT ? ErrorCode::kNotFound : ErrorCode::kIo, name,
                       "cannot open serial port: {}", std::strerror(err));
    }
    device = resolved;
  } else {
    RIG_ASSIGN_OR_RETURN(device, FindUsbPort(sel));
  }

  std::unique_ptr<SerialPort> port(new SerialPort());
  port->device_ = device;
  port->name_ = name;
  if (sp_get_port_by_name(device.c_str(), &port->port_) != SP_OK) {
    port->port_ = nullptr;
    return MakeError(ErrorCode::kNotFound, name, "not a serial port ({}): {}", device, SpMessage());
  }
  if (sp_open(port->port_, SP_MODE_READ_WRITE) != SP_OK) {
    int err = sp_last_error_code();
    std::string msg = SpMessage();
    if (err == EACCES)
      return MakeError(ErrorCode::kIo, name,
                       "permission denied opening {} (add the user to the 'dialout' group)", device);
    if (err == EBUSY) return MakeError(ErrorCode::kBusy, name, "{} is busy: {}", device, msg);
    return MakeError(err == ENOENT ? ErrorCode::kNotFound : ErrorCode::kIo, name, "cannot open {}: {}",
                     device, msg);
  }
  if (sp_get_port_handle(port->port_, &port->fd_) != SP_OK || port->fd_ < 0)
    return MakeError(ErrorCode::kIo, name, "no file descriptor for {}", device);
  // Exclusive: flock keeps out other cooperating programs (and holds even for root);
  // TIOCEXCL makes further open()s of the tty fail with EBUSY.
  if (flock(port->fd_, LOCK_EX | LOCK_NB) != 0) {
    int err = errno;
    if (err == EWOULDBLOCK)
      return MakeError(ErrorCode::kBusy, name, "{} is in use by another program", device);
    return MakeError(ErrorCode::kIo, name, "cannot lock {}: {}", device, std::strerror(err));
  }
  if (ioctl(port->fd_, TIOCEXCL) != 0)
    Log("motion")->debug("serial port={} TIOCEXCL failed: {}", device, std::strerror(errno));

  if (sp_set_baudrate(port->port_, sel.baud) != SP_OK || sp_set_bits(port->port_, 8) != SP_OK ||
      sp_set_parity(port->port_, SP_PARITY_NONE) != SP_OK ||
      sp_set_stopbits(port->port_, 1) != SP_OK ||
      sp_set_flowcontrol(port->port_, SP_FLOWCONTROL_NONE) != SP_OK)
    return MakeError(ErrorCode::kIo, name, "cannot set {} baud 8N1 on {}: {}", sel.baud, device,
                     SpMessage());
  RIG_TRY(port->FlushInput());
  Log("motion")->debug("serial opened port={} device={} baud={}", name, device, sel.baud);
  return port;
}

SerialPort::~SerialPort() {
  if (port_ != nullptr) {
    if (fd_ >= 0) flock(fd_, LOCK_UN);
    sp_close(port_);
    sp_free_port(port_);
  }
}

Error SerialPort::Lost(const std::string& what) {
  lost_ = true;
  return MakeError(ErrorCode::kIo, name_, "port lost ({}): the device went away", what);
}

Status SerialPort::FlushInput() {
  buffer_.clear();
  if (sp_flush(port_, SP_BUF_INPUT) != SP_OK) return Lost("flush failed: " + SpMessage());
  return Ok();
}

Status SerialPort::Write(std::string_view bytes, Seconds timeout) {
  if (lost_) return Lost("earlier failure");
  auto deadline = DeadlineAfter(timeout);
  size_t done = 0;
  while (done < bytes.size()) {
    int n = sp_nonblocking_write(port_, bytes.data() + done, bytes.size() - done);
    if (n < 0) return Lost("write: " + SpMessage());
    done += static_cast<size_t>(n);
    if (done == bytes.size()) break;
    if (Clock::now() >= deadline)
      return MakeError(ErrorCode::kTimeout, name_, "write timed out after {:.2f} s ({} of {} bytes)",
                       timeout.count(), done, bytes.size());
    pollfd pfd{fd_, POLLOUT, 0};
    int rc = poll(&pfd, 1, MillisUntil(deadline));
    if (rc < 0 && errno != EINTR) return Lost(std::string("poll: ") + std::strerror(errno));
    if (rc > 0 && (pfd.revents & (POLLERR | POLLHUP | POLLNVAL))) return Lost("hang-up on write");
  }
  return Ok();
}

Result<bool> SerialPort::Fill(Seconds timeout, bool interruptible) {
  if (lost_) return Lost("earlier failure");
  auto deadline = DeadlineAfter(timeout);
  for (;;) {
    if (interruptible && SerialInterruptRequested())
      return MakeError(ErrorCode::kInterrupted, name_, "interrupted while waiting for the device");
    pollfd pfd{fd_, POLLIN, 0};
    int rc = poll(&pfd, 1, MillisUntil(deadline));
    if (rc < 0) {
      if (errno == EINTR) continue;
      return Lost(std::string("poll: ") + std::strerror(errno));
    }
    if (rc > 0) {
      if (pfd.revents & POLLIN) {
        char buf[4096];
        int n = sp_nonblocking_read(port_, buf, sizeof(buf));
        if (n < 0) return Lost("read: " + SpMessage());
        if (n > 0) {
          buffer_.append(buf, static_cast<size_t>(n));
          return true;
        }
        if (pfd.revents & (POLLHUP | POLLERR)) return Lost("hang-up");
      } else if (pfd.revents & (POLLERR | POLLHUP | POLLNVAL)) {
        return Lost("hang-up");
      }
    }
    if (Clock::now() >= deadline) return false;
  }
}

Result<std::string> SerialPort::ReadExact(size_t n, Seconds timeout, bool interruptible) {
  auto deadline = DeadlineAfter(timeout);
  while (buffer_.size() < n) {
    auto left = std::chrono::duration<double>(deadline - Clock::now());
    if (left.count() <= 0)
      return MakeError(ErrorCode::kTimeout, name_, "no reply within {:.2f} s ({} of {} bytes)",
                       timeout.count(), buffer_.size(), n);
    RIG_ASSIGN_OR_RETURN(bool got, Fill(left, interruptible));
    (void)got;
  }
  std::string out = buffer_.substr(0, n);
  buffer_.erase(0, n);
  return out;
}

Result<std::optional<std::string>> SerialPort::ReadLine(Seconds timeout, bool interruptible) {
  auto deadline = DeadlineAfter(timeout);
  for (;;) {
    for (;;) {
      size_t end = buffer_.find_first_of("\r\n");
      if (end == std::string::npos) break;
      std::string line = buffer_.substr(0, end);
      buffer_.erase(0, end + 1);
      if (!line.empty()) return std::optional<std::string>(std::move(line));
    }
    auto left = std::chrono::duration<double>(deadline - Clock::now());
    if (left.count() <= 0) return std::optional<std::string>();
    RIG_ASSIGN_OR_RETURN(bool got, Fill(left, interruptible));
    if (!got) return std::optional<std::string>();
  }
}

}  // namespace rig
