// The camera backend over libgphoto2 (the library itself, not the gphoto2 command line).
#pragma once

#include <memory>

#include "capture/devices/camera.h"
#include "config/config.h"

namespace rig {

// Shutter-speed labels as bodies print them, in seconds: "1/100", "0.0100s", "1.0000s",
// "30", "2.5s", "1/4000s". Nothing for "Bulb", "Time", "x 1/200" (flash sync) and the like.
std::optional<double> ParseShutterSpeed(const std::string& label);

// The ExposureTime (tag 0x829A) of a JPEG's EXIF block, in seconds; nothing when absent.
std::optional<double> JpegExifExposure(const std::vector<uint8_t>& jpeg);

// A body chosen by config.model / config.port / config.serial, or auto-detected. Errors carry
// libgphoto2's own message; "could not claim the USB device" says who usually holds it.
std::unique_ptr<Camera> MakeGPhoto2Camera(const CameraConfig& config);

}  // namespace rig
