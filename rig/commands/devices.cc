// rig devices: what is plugged in — cameras, serial ports, GPIO chips and lines.
#include <cstdio>

#include "capture/devices/inventory.h"
#include "rig/commands/command.h"

namespace rig {

int RunDevices(int argc, char** argv) {
  CLI::App app{"List what the rig could use: cameras (libgphoto2 auto-detect, with their ports), "
               "serial ports (libserialport, with USB vendor:product ids), GPIO chips and lines "
               "(libgpiod: name, consumer, in use). Says so when a kind has none.",
               "rig devices"};
  bool json = false;
  std::string level;
  app.add_flag("--json", json, "one JSON object: cameras, serial_ports, gpio_chips, errors");
  AddLogLevelOption(app, &level);
  if (auto rc = ParseCommandLine(app, argc, argv)) return *rc;
  if (auto rc = ApplyLogLevel(level)) return *rc;
  Inventory inv = FindDevices();
  if (json) {
    std::printf("%s\n", InventoryToJson(inv).dump(2).c_str());
  } else {
    std::printf("%s", InventoryToText(inv).c_str());
  }
  return 0;
}

}  // namespace rig
