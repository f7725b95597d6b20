// A configuration as flat settings ("grid.h_step_deg" -> "10.0"), its digest, and the one
// way a stored session's configuration may change: a device setting, validated.
#pragma once

#include <map>
#include <string>
#include <utility>
#include <vector>

#include "config/config.h"
#include "config/result.h"

namespace rig {

// Every setting of the resolved configuration (ToToml's keys, dotted), its value as TOML text.
std::map<std::string, std::string> FlattenConfig(const Config& config);

// FNV-1a (64 bit) of the flattened settings, as "fnv1a64:<16 hex digits>".
std::string SettingsDigest(const std::map<std::string, std::string>& settings);

// The settings that may change in an interrupted session (how to reach a device, how long
// to wait for it): nothing that shapes a frame.
const std::vector<std::string>& DeviceSettingKeys();

// One change: key, value before ("" when unset) and after, as TOML text.
struct SettingChange {
  std::string key, old_value, new_value;
};

// `config` with `key=value` applied ("camera.port=usb:001,004"). Refused (kInvalidInput)
// unless the key is a device setting and the value has its type and passes validation.
Result<Config> ApplySetting(const Config& config, const std::string& assignment,
                            SettingChange* change);

// For a session not yet created (`rig capture --set`): any key of the resolved configuration
// (camera.iso, grid.h_step_deg, ...) with the type it has there, validated as a file is.
Result<Config> ApplyOverride(const Config& config, const std::string& assignment, SettingChange* change);
// Every assignment in turn (ApplyOverride); the result and the changes, old and new values.
Result<std::pair<Config, std::vector<SettingChange>>> ApplyOverrides(const Config& config,
                                                                     const std::vector<std::string>& assignments);

}  // namespace rig
