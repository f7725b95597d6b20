// A small JSON file from a folder someone else made (a model's info.json): a regular file of
// bounded size, opened without blocking (a FIFO named info.json never hangs the reader), parsed
// as one JSON object. Errors name the file.
#pragma once

#include <cstdint>
#include <string>

#include <nlohmann/json.hpp>

#include "config/result.h"

namespace rig {

inline constexpr uint64_t kMaxJsonFileBytes = uint64_t{64} << 20;  // 64 MiB: far above any model's

// kNotFound when the file is not there; kInvalidInput when it is not a regular file, is larger
// than max_bytes, is not JSON or not a JSON object.
Result<nlohmann::json> ReadJsonObjectFile(const std::string& path,
                                          uint64_t max_bytes = kMaxJsonFileBytes);

// A JSON value that must be an integer within [lo, hi]. nlohmann's get<int>() of a float past
// int's range (1e70) is undefined behaviour, so every integer field of a file someone else made is
// taken through this; the error names the file and the field.
Result<int> JsonIntegerIn(const nlohmann::json& v, int lo, int hi, const std::string& path,
                          const std::string& field);
// A JSON value that must be a finite number; the error names the file and the field.
Result<double> JsonNumber(const nlohmann::json& v, const std::string& path, const std::string& field);

}  // namespace rig
