// The Camera interface: every camera backend (libgphoto2, the simulator) behind one shape.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "config/config.h"
#include "config/result.h"

namespace rig {

// Settings held fixed for a whole session. Empty: leave as the body has it.
struct CameraSettings {
  std::string iso, aperture, white_balance;
  std::string capture_target = "ram";  // "ram" | "card"
  bool capture_raw = false;
};

// One file as the camera delivered it, byte for byte.
struct CapturedFile {
  std::string extension;  // "jpg", "png", "nef", "cr2" ... (lower case, no dot)
  std::vector<uint8_t> bytes;
};

// One exposure: the files it produced (JPEG, and RAW when asked) and what was applied.
struct CapturedFrame {
  Seconds exposure{0};                 // the exposure the body applied (read back)
  std::optional<Seconds> exif_exposure;  // from the file's EXIF, where present
  std::vector<CapturedFile> files;
};

// One setting as the body reports it now, as `gphoto2 --get-config NAME` prints it: the
// libgphoto2 config tree's name ("f-number"), its label ("F-Number") and current value.
struct CameraReading {
  std::string what;  // "iso", "aperture", "shutter", "image format", "battery"
  std::string name, label, value;
};

class Camera {
 public:
  virtual ~Camera() = default;

  // "gphoto2 Nikon DSC D750 on usb:001,004", "sim camera 320x240 seed 1".
  virtual std::string Describe() const = 0;

  // Opens the body (auto-detects or selects it as configured).
  virtual Status Open() = 0;
  virtual void Close() = 0;

  // The shutter speeds the body offers, ascending. Brackets are planned from this list.
  virtual Result<std::vector<Seconds>> ShutterSpeeds() = 0;

  // Applies what the body supports and returns what it actually applied.
  virtual Result<CameraSettings> Configure(const CameraSettings& wanted) = 0;

  // Sets the exposure (one of ShutterSpeeds()), captures, downloads to memory.
  // The returned frame carries the exposure actually applied, read back from the body.
  virtual Result<CapturedFrame> Capture(Seconds exposure) = 0;

  // The body's current ISO, aperture, shutter speed, image format and battery level, each
  // that it has (after Open). A camera without a settings tree (the simulator) has none.
  virtual Result<std::vector<CameraReading>> Readings() { return std::vector<CameraReading>{}; }

  // One live-view frame for framing and focus, as `gphoto2 --capture-preview` takes it: a
  // small JPEG at the body's own exposure, not stored on the card, not one of the session's
  // frames (after Open). A body without live view answers kUnsupported, naming itself.
  virtual Result<CapturedFile> CapturePreview() {
    return MakeError(ErrorCode::kUnsupported, Describe(), "this camera has no preview (live view)");
  }
};

}  // namespace rig
