// The lamp's relay on a GPIO line through libgpiod.
#include "capture/devices/gpiod_lamp.h"

#include <gpiod.h>

#include <cerrno>
#include <cstdlib>
#include <cstring>

#include <fmt/format.h>

#include "config/log.h"
#include "capture/devices/signals.h"

namespace rig {
namespace {

class GpiodLamp final : public Lamp {
 public:
  explicit GpiodLamp(LampConfig config) : config_(std::move(config)) {}
  ~GpiodLamp() override { Close(); }

  std::string Describe() const override {
    return fmt::format("gpiod lamp {} line {}{}", config_.chip, config_.line,
                       config_.active_low ? " (active low)" : "");
  }

  Status Open() override {
    Close();
    chip_ = gpiod_chip_open_lookup(config_.chip.c_str());
    if (!chip_) return Errno("cannot open the GPIO chip");
    // A line by name, or by offset when the name is a number.
    line_ = gpiod_chip_find_line(chip_, config_.line.c_str());
    if (!line_) {
      char* end = nullptr;
      const long offset = std::strtol(config_.line.c_str(), &end, 10);
      if (end && *end == '\0' && !config_.line.empty() && offset >= 0)
        line_ = gpiod_chip_get_line(chip_, static_cast<unsigned>(offset));
    }
    if (!line_) {
      Error e = Errno("no such GPIO line");
      Close();
      return e;
    }
    const int flags = config_.active_low ? GPIOD_LINE_REQUEST_FLAG_ACTIVE_LOW : 0;
    if (gpiod_line_request_output_flags(line_, "rig lamp", flags, 0) < 0) {
      Error e = Errno("cannot request the line as an output (another program holds it?)");
      line_ = nullptr;
      Close();
      return e;
    }
    requested_ = true;
    return Ok();
  }

  Status On() override {
    RIG_TRY(Set(1));
    // Warm-up before the first exposure; Ctrl-C cuts it short (the daemon then parks).
    if (!SleepUnlessStopped(Seconds(config_.warmup_s)))
      return MakeError(ErrorCode::kInterrupted, Describe(), "interrupted during the warm-up");
    return Ok();
  }

  Status Off() override { return Set(0); }

  void Close() override {
    if (line_ && requested_) {
      if (gpiod_line_set_value(line_, 0) < 0)
        Log("lamp")->error("{}: cannot switch off on close: {}", Describe(), std::strerror(errno));
      gpiod_line_release(line_);
    }
    requested_ = false;
    line_ = nullptr;
    if (chip_) gpiod_chip_close(chip_);
    chip_ = nullptr;
  }

 private:
  Status Set(int value) {
    if (!line_ || !requested_) return MakeError(ErrorCode::kFault, Describe(), "not open");
    if (gpiod_line_set_value(line_, value) < 0) return Errno(value ? "cannot switch on" : "cannot switch off");
    return Ok();
  }

  Error Errno(const std::string& what) const {
    const int e = errno;
    return MakeError(e == ENOENT || e == ENODEV ? ErrorCode::kNotFound : ErrorCode::kDevice, Describe(),
                     "{}: {}", what, std::strerror(e));
  }

  LampConfig config_;
  gpiod_chip* chip_ = nullptr;
  gpiod_line* line_ = nullptr;
  bool requested_ = false;
};

}  // namespace

std::unique_ptr<Lamp> MakeGpiodLamp(const LampConfig& config) { return std::make_unique<GpiodLamp>(config); }

}  // namespace rig
