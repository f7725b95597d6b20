// Device inventory through the same libraries the backends use.
#include "capture/devices/inventory.h"

#include <cerrno>
#include <cstring>

#include <fmt/format.h>

#include "build_info.h"
#if RIG_WITH_GPHOTO2
#include <gphoto2/gphoto2.h>
#endif
#if RIG_WITH_SERIALPORT
#include <libserialport.h>
#endif
#if RIG_WITH_GPIOD
#include <gpiod.h>
#endif

namespace rig {
namespace {

std::string Str(const char* s) { return s ? s : ""; }

void FindCameras(Inventory& inv) {
#if RIG_WITH_GPHOTO2
  GPContext* ctx = gp_context_new();
  CameraList* list = nullptr;
  gp_list_new(&list);
  int n = gp_camera_autodetect(list, ctx);
  if (n < GP_OK) {
    inv.cameras_error = fmt::format("libgphoto2 auto-detection failed: {}", gp_result_as_string(n));
  } else {
    for (int i = 0; i < gp_list_count(list); ++i) {
      const char *name = nullptr, *value = nullptr;
      gp_list_get_name(list, i, &name);
      gp_list_get_value(list, i, &value);
      inv.cameras.push_back({Str(name), Str(value)});
    }
  }
  gp_list_free(list);
  gp_context_unref(ctx);
#else
  inv.cameras_error = "this build has no libgphoto2 camera backend";
#endif
}

void FindSerialPorts(Inventory& inv) {
#if RIG_WITH_SERIALPORT
  sp_port** ports = nullptr;
  sp_return rc = sp_list_ports(&ports);
  if (rc != SP_OK) {
    char* msg = sp_last_error_message();
    inv.serial_error = fmt::format("libserialport cannot list ports: {}", Str(msg));
    sp_free_error_message(msg);
    return;
  }
  for (int i = 0; ports[i] != nullptr; ++i) {
    sp_port* p = ports[i];
    SerialPortFound f;
    f.name = Str(sp_get_port_name(p));
    f.description = Str(sp_get_port_description(p));
    switch (sp_get_port_transport(p)) {
      case SP_TRANSPORT_USB: f.transport = "usb"; break;
      case SP_TRANSPORT_BLUETOOTH: f.transport = "bluetooth"; break;
      default: f.transport = "native"; break;
    }
    if (f.transport == "usb") {
      int vid = -1, pid = -1;
      if (sp_get_port_usb_vid_pid(p, &vid, &pid) == SP_OK) {
        f.usb_vid = vid;
        f.usb_pid = pid;
      }
      f.manufacturer = Str(sp_get_port_usb_manufacturer(p));
      f.product = Str(sp_get_port_usb_product(p));
      f.serial = Str(sp_get_port_usb_serial(p));
    }
    inv.serial_ports.push_back(std::move(f));
  }
  sp_free_port_list(ports);
#else
  inv.serial_error = "this build has no libserialport motor backends";
#endif
}

void FindGpio(Inventory& inv) {
#if RIG_WITH_GPIOD
  gpiod_chip_iter* iter = gpiod_chip_iter_new();
  if (iter == nullptr) {
    // No /dev/gpiochip* at all is the common case on a PC: not an error.
    if (errno != ENOENT) inv.gpio_error = fmt::format("libgpiod cannot list chips: {}", std::strerror(errno));
    return;
  }
  gpiod_chip* chip = nullptr;
  gpiod_foreach_chip(iter, chip) {
    GpioChipFound c;
    c.name = Str(gpiod_chip_name(chip));
    c.label = Str(gpiod_chip_label(chip));
    const unsigned n = gpiod_chip_num_lines(chip);
    for (unsigned i = 0; i < n; ++i) {
      gpiod_line* line = gpiod_chip_get_line(chip, i);
      if (line == nullptr) continue;
      GpioLineFound l;
      l.offset = i;
      l.name = Str(gpiod_line_name(line));
      l.consumer = Str(gpiod_line_consumer(line));
      l.used = gpiod_line_is_used(line);
      l.output = gpiod_line_direction(line) == GPIOD_LINE_DIRECTION_OUTPUT;
      c.lines.push_back(std::move(l));
    }
    inv.gpio_chips.push_back(std::move(c));
  }
  gpiod_chip_iter_free(iter);
#else
  inv.gpio_error = "this build has no libgpiod lamp backend";
#endif
}

std::string Hex4(int v) { return v < 0 ? "" : fmt::format("{:04x}", v); }

}  // namespace

Inventory FindDevices() {
  Inventory inv;
  FindCameras(inv);
  FindSerialPorts(inv);
  FindGpio(inv);
  return inv;
}

nlohmann::json InventoryToJson(const Inventory& inv) {
  nlohmann::json j;
  j["cameras"] = nlohmann::json::array();
  for (const auto& c : inv.cameras) j["cameras"].push_back({{"model", c.model}, {"port", c.port}});
  j["serial_ports"] = nlohmann::json::array();
  for (const auto& p : inv.serial_ports) {
    nlohmann::json e = {{"name", p.name}, {"description", p.description}, {"transport", p.transport}};
    if (p.usb_vid >= 0) {
      e["usb_vid"] = Hex4(p.usb_vid);
      e["usb_pid"] = Hex4(p.usb_pid);
      e["manufacturer"] = p.manufacturer;
      e["product"] = p.product;
      e["serial"] = p.serial;
    }
    j["serial_ports"].push_back(e);
  }
  j["gpio_chips"] = nlohmann::json::array();
  for (const auto& c : inv.gpio_chips) {
    nlohmann::json chip = {{"name", c.name}, {"label", c.label}, {"lines", nlohmann::json::array()}};
    for (const auto& l : c.lines)
      chip["lines"].push_back({{"offset", l.offset}, {"name", l.name}, {"consumer", l.consumer},
                               {"used", l.used}, {"direction", l.output ? "output" : "input"}});
    j["gpio_chips"].push_back(chip);
  }
  nlohmann::json errors = nlohmann::json::object();
  if (!inv.cameras_error.empty()) errors["cameras"] = inv.cameras_error;
  if (!inv.serial_error.empty()) errors["serial_ports"] = inv.serial_error;
  if (!inv.gpio_error.empty()) errors["gpio_chips"] = inv.gpio_error;
  j["errors"] = errors;
  return j;
}

std::string InventoryToText(const Inventory& inv) {
  std::string s = "cameras (libgphoto2 auto-detect):\n";
  if (!inv.cameras_error.empty()) s += "  " + inv.cameras_error + "\n";
  else if (inv.cameras.empty())
    s += "  none found (is the body on, in PTP/PC mode, and not mounted by the desktop?)\n";
  for (const auto& c : inv.cameras)
    s += fmt::format("  {}  port {}  (camera.model = \"{}\", camera.port = \"{}\")\n", c.model, c.port,
                     c.model, c.port);
  s += "serial ports (libserialport):\n";
  if (!inv.serial_error.empty()) s += "  " + inv.serial_error + "\n";
  else if (inv.serial_ports.empty()) s += "  none found (is the controller plugged in? see docs/rig-setup.md)\n";
  for (const auto& p : inv.serial_ports) {
    s += fmt::format("  {}  {}", p.name, p.description);
    if (p.usb_vid >= 0)
      s += fmt::format("  usb {}:{}{}{}", Hex4(p.usb_vid), Hex4(p.usb_pid),
                       p.manufacturer.empty() ? "" : "  " + p.manufacturer,
                       p.serial.empty() ? "" : "  serial " + p.serial);
    else
      s += "  (" + p.transport + ")";
    s += "\n";
  }
  s += "GPIO chips and lines (libgpiod):\n";
  if (!inv.gpio_error.empty()) s += "  " + inv.gpio_error + "\n";
  else if (inv.gpio_chips.empty()) s += "  none found (no /dev/gpiochip*: not a board with GPIO, or no permission)\n";
  for (const auto& c : inv.gpio_chips) {
    s += fmt::format("  {} [{}] {} lines\n", c.name, c.label, c.lines.size());
    for (const auto& l : c.lines) {
      if (l.name.empty() && !l.used) continue;  // unnamed free lines: only counted
      s += fmt::format("    line {:3d} {:<16} {}{}\n", l.offset, l.name.empty() ? "-" : l.name,
                       l.used ? "in use by " + (l.consumer.empty() ? std::string("?") : l.consumer) : "free",
                       l.output ? ", output" : "");
    }
  }
  return s;
}

Result<std::vector<CameraReading>> ReadCameraSettings(Camera& camera) {
  RIG_TRY(camera.Open());
  auto readings = camera.Readings();
  camera.Close();
  if (!readings.ok()) return readings.error().Within(camera.Describe());
  return readings;
}

std::string CameraReadingsToText(const std::string& camera, const std::vector<CameraReading>& readings) {
  std::string out = camera + "\n";
  if (readings.empty()) return out + "  reports no settings (no libgphoto2 config tree)\n";
  for (const char* what : {"iso", "aperture", "shutter", "image format", "battery"}) {
    bool found = false;
    for (const auto& r : readings) {
      if (r.what != what) continue;
      out += fmt::format("  {:<13} {}  ({} '{}')\n", r.what, r.value.empty() ? "(empty)" : r.value, r.name,
                         r.label);
      found = true;
    }
    if (!found) out += fmt::format("  {:<13} not offered by this body\n", what);
  }
  return out;
}

}  // namespace rig
