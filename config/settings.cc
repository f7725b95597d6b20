// Flat settings, their digest, and validated changes of device settings.
#include "config/settings.h"

#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <sstream>

#define TOML_EXCEPTIONS 1
#include <toml++/toml.h>

namespace rig {
namespace {

enum class Kind { kString, kInt, kFloat, kBool };

struct DeviceKey {
  const char* key;
  Kind kind;
};

// How to reach each device and how long to wait for it. Nothing here changes a frame:
// grid, bracket, camera exposure settings, the light frame and the simulator stay fixed.
const DeviceKey kDeviceKeys[] = {
    {"camera.model", Kind::kString},          {"camera.port", Kind::kString},
    {"camera.serial", Kind::kString},         {"camera.retries", Kind::kInt},
    {"camera.retry_backoff_s", Kind::kFloat}, {"camera.call_timeout_s", Kind::kFloat},
    {"camera.capture_deadline_s", Kind::kFloat},
    {"motor.port", Kind::kString},            {"motor.usb_vid_pid", Kind::kString},
    {"motor.usb_serial", Kind::kString},      {"motor.baud", Kind::kInt},
    {"motor.home_on_start", Kind::kBool},     {"motor.reply_timeout_s", Kind::kFloat},
    {"motor.move_timeout_s", Kind::kFloat},   {"motor.retries", Kind::kInt},
    {"motor.retry_backoff_s", Kind::kFloat},  {"motor.grbl.banner_timeout_s", Kind::kFloat},
    {"lamp.chip", Kind::kString},             {"lamp.line", Kind::kString},
};

void Flatten(const toml::table& t, const std::string& prefix,
             std::map<std::string, std::string>* out) {
  for (const auto& [k, node] : t) {
    const std::string key = prefix.empty() ? std::string(k.str()) : prefix + "." + std::string(k.str());
    if (const toml::table* sub = node.as_table()) {
      Flatten(*sub, key, out);
      continue;
    }
    std::ostringstream os;
    node.visit([&](const auto& n) { os << n; });
    (*out)[key] = os.str();
  }
}

std::string ValueText(const toml::table& root, const std::string& key) {
  std::map<std::string, std::string> flat;
  Flatten(root, "", &flat);
  auto it = flat.find(key);
  return it == flat.end() ? "" : it->second;
}

}  // namespace

std::map<std::string, std::string> FlattenConfig(const Config& config) {
  std::map<std::string, std::string> out;
  const std::string text = ToToml(config);
  const toml::table root = toml::parse(std::string_view(text), std::string_view("resolved"));  // our own text: valid
  Flatten(root, "", &out);
  return out;
}

std::string SettingsDigest(const std::map<std::string, std::string>& settings) {
  uint64_t h = 1469598103934665603ull;
  auto feed = [&](const std::string& s) {
    for (unsigned char c : s) h = (h ^ c) * 1099511628211ull;
    h = (h ^ 0xff) * 1099511628211ull;  // separator no text contains
  };
  for (const auto& [k, v] : settings) {
    feed(k);
    feed(v);
  }
  return fmt::format("fnv1a64:{:016x}", h);
}

const std::vector<std::string>& DeviceSettingKeys() {
  static const std::vector<std::string> keys = [] {
    std::vector<std::string> k;
    for (const auto& d : kDeviceKeys) k.push_back(d.key);
    return k;
  }();
  return keys;
}

Result<std::pair<Config, std::vector<SettingChange>>> ApplyOverrides(
    const Config& config, const std::vector<std::string>& assignments) {
  std::pair<Config, std::vector<SettingChange>> out{config, {}};
  for (const auto& a : assignments) {
    SettingChange c;
    RIG_ASSIGN_OR_RETURN(out.first, ApplyOverride(out.first, a, &c));
    out.second.push_back(c);
  }
  return out;
}

namespace {

// `key` set to `value` of type `kind` in the resolved configuration, validated as a file is.
Result<Config> Assign(const Config& config, const std::string& key, const std::string& value, Kind kind,
                      SettingChange* change);

bool SplitAssignment(const std::string& assignment, std::string* key, std::string* value) {
  const auto eq = assignment.find('=');
  if (eq == std::string::npos || eq == 0) return false;
  *key = assignment.substr(0, eq);
  *value = assignment.substr(eq + 1);
  return true;
}

Error NotAnAssignment(const std::string& assignment) {
  return MakeError(ErrorCode::kInvalidInput, "--set " + assignment,
                   "expected KEY=VALUE, e.g. camera.port=usb:001,004");
}

}  // namespace

Result<Config> ApplySetting(const Config& config, const std::string& assignment,
                            SettingChange* change) {
  std::string key, value;
  if (!SplitAssignment(assignment, &key, &value)) return NotAnAssignment(assignment);
  const DeviceKey* dk = nullptr;
  for (const auto& d : kDeviceKeys)
    if (key == d.key) dk = &d;
  if (!dk) {
    std::string allowed;
    for (const auto& d : kDeviceKeys) allowed += (allowed.empty() ? "" : ", ") + std::string(d.key);
    return MakeError(ErrorCode::kInvalidInput, "--set " + key,
                     "not a device setting; only these may change in a stored session (the "
                     "grid, bracket, camera exposure settings and the scene never do): {}",
                     allowed);
  }
  return Assign(config, key, value, dk->kind, change);
}

Result<Config> ApplyOverride(const Config& config, const std::string& assignment, SettingChange* change) {
  std::string key, value;
  if (!SplitAssignment(assignment, &key, &value)) return NotAnAssignment(assignment);
  for (const auto& d : kDeviceKeys)
    if (key == d.key) return Assign(config, key, value, d.kind, change);
  // Any other key of the resolved configuration, with the type it has there.
  const std::string text = ToToml(config);
  const toml::table root = toml::parse(std::string_view(text), std::string_view("resolved"));
  const toml::node_view<const toml::node> node = root.at_path(key);
  if (node.is_table())
    return MakeError(ErrorCode::kInvalidInput, "--set " + key, "a table, not a setting");
  // A key the resolved text leaves out (an empty camera.iso) goes in as text; the schema
  // then refuses an unknown key or a wrong type, as it does in a file.
  Kind kind;
  if (!node || node.is_string()) kind = Kind::kString;
  else if (node.is_integer()) kind = Kind::kInt;
  else if (node.is_floating_point()) kind = Kind::kFloat;
  else if (node.is_boolean()) kind = Kind::kBool;
  else
    return MakeError(ErrorCode::kInvalidInput, "--set " + key,
                     "a list; set it in the configuration file instead");
  return Assign(config, key, value, kind, change);
}

namespace {

Result<Config> Assign(const Config& config, const std::string& key, const std::string& value, Kind kind,
                      SettingChange* change) {
  const std::string text = ToToml(config);
  toml::table root = toml::parse(std::string_view(text), std::string_view("resolved"));
  // The table holding the key (created if the resolved text leaves it out, e.g. an empty port).
  toml::table* t = &root;
  std::string rest = key;
  for (auto dot = rest.find('.'); dot != std::string::npos; dot = rest.find('.')) {
    const std::string part = rest.substr(0, dot);
    rest = rest.substr(dot + 1);
    if (!t->contains(part)) t->insert_or_assign(part, toml::table{});
    t = t->get(part)->as_table();
    if (!t) return MakeError(ErrorCode::kInternal, key, "not a table");
  }
  const std::string before = ValueText(root, key);
  char* end = nullptr;
  errno = 0;
  switch (kind) {
    case Kind::kString:
      t->insert_or_assign(rest, value);
      break;
    case Kind::kInt: {
      const long long v = std::strtoll(value.c_str(), &end, 10);
      if (value.empty() || *end != '\0' || errno == ERANGE)
        return MakeError(ErrorCode::kInvalidInput, "--set " + key, "'{}' is not an integer", value);
      t->insert_or_assign(rest, static_cast<int64_t>(v));
      break;
    }
    case Kind::kFloat: {
      const double v = std::strtod(value.c_str(), &end);
      if (value.empty() || *end != '\0' || !std::isfinite(v))
        return MakeError(ErrorCode::kInvalidInput, "--set " + key, "'{}' is not a finite number", value);
      t->insert_or_assign(rest, v);
      break;
    }
    case Kind::kBool:
      if (value != "true" && value != "false")
        return MakeError(ErrorCode::kInvalidInput, "--set " + key, "'{}' is not true or false", value);
      t->insert_or_assign(rest, value == "true");
      break;
  }
  std::ostringstream os;
  os << root;
  ConfigResult r = ParseConfig(os.str(), "--set " + key);
  if (!r.ok()) return r.AsError();
  r.config.source = config.source;
  if (change) {
    const std::string after_text = ToToml(r.config);
    change->key = key;
    change->old_value = before;
    change->new_value =
        ValueText(toml::parse(std::string_view(after_text), std::string_view("resolved")), key);
  }
  return r.config;
}

}  // namespace

}  // namespace rig
