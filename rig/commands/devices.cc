// rig devices: what is plugged in — cameras, serial ports, GPIO chips and lines.
#include <cstdio>

#include "capture/devices/inventory.h"
#include "rig/backends.h"
#include "rig/commands/bringup.h"
#include "rig/commands/command.h"

namespace rig {

int RunDevices(int argc, char** argv) {
  CLI::App app{"List what the rig could use: cameras (libgphoto2 auto-detect, with their ports), "
               "serial ports (libserialport, with USB vendor:product ids), GPIO chips and lines "
               "(libgpiod: name, consumer, in use). Says so when a kind has none.",
               "rig devices"};
  bool json = false, camera = false;
  BringUpOptions o;
  app.add_flag("--json", json, "one JSON object: cameras, serial_ports, gpio_chips, errors");
  app.add_flag("--camera", camera,
               "instead: open the configured camera (--config) and show its current ISO, aperture, "
               "shutter speed, image format and battery level, as gphoto2 --get-config does");
  AddBringUpOptions(app, &o);
  if (auto rc = ParseCommandLine(app, argc, argv)) return *rc;
  if (auto rc = ApplyLogLevel(o.level)) return *rc;
  if (camera) {
    auto config = LoadBringUpConfig(o);
    if (!config.ok()) return ReportError("devices", config.error());
    auto devices = MakeDevices(*config);
    if (!devices.ok()) return ReportError("devices", devices.error());
    auto readings = ReadCameraSettings(*devices->camera);
    if (!readings.ok()) return ReportError("devices", readings.error());
    std::printf("%s", CameraReadingsToText(devices->camera->Describe(), *readings).c_str());
    return 0;
  }
  Inventory inv = FindDevices();
  if (json) {
    std::printf("%s\n", InventoryToJson(inv).dump(2).c_str());
  } else {
    std::printf("%s", InventoryToText(inv).c_str());
  }
  return 0;
}

}  // namespace rig
