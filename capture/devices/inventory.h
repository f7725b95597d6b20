// What is plugged in: cameras by libgphoto2's auto-detection, serial ports by libserialport
// (with USB vendor:product ids), GPIO chips and their lines by libgpiod. For `rig devices`.
#pragma once

#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "capture/devices/camera.h"
#include "config/result.h"

namespace rig {

struct CameraFound {
  std::string model, port;  // "Nikon DSC D750", "usb:001,004"
};

struct SerialPortFound {
  std::string name, description;  // "/dev/ttyACM0", "Arduino Uno"
  std::string transport;          // "usb", "native", "bluetooth"
  int usb_vid = -1, usb_pid = -1;  // USB ids, -1 when not a USB port
  std::string manufacturer, product, serial;
};

struct GpioLineFound {
  unsigned offset = 0;
  std::string name, consumer;  // empty when unnamed / free
  bool used = false;
  bool output = false;
};

struct GpioChipFound {
  std::string name, label;  // "gpiochip0", "pinctrl-bcm2711"
  std::vector<GpioLineFound> lines;
};

struct Inventory {
  std::vector<CameraFound> cameras;
  std::vector<SerialPortFound> serial_ports;
  std::vector<GpioChipFound> gpio_chips;
  // Per kind: why it could not be looked at ("this build has no libgpiod backend", a
  // library error), empty when it was.
  std::string cameras_error, serial_error, gpio_error;
};

// Looks at every kind; never fails as a whole (each kind's error is kept in the result).
Inventory FindDevices();

nlohmann::json InventoryToJson(const Inventory& inventory);

// `rig devices --camera`: opens `camera`, reads its current settings (Camera::Readings),
// closes it. Errors name the camera.
Result<std::vector<CameraReading>> ReadCameraSettings(Camera& camera);
// "iso (ISO Speed, iso): 100" per line; says so when the camera reports none.
std::string CameraReadingsToText(const std::string& camera, const std::vector<CameraReading>& readings);
// The report for a person: each kind, or that none was found and where to look.
std::string InventoryToText(const Inventory& inventory);

}  // namespace rig
