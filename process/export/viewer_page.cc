// The page's files and data.js.
#include "process/export/viewer_page.h"
#include "config/atomic_file.h"

#include <filesystem>
#include <fstream>
#include <iterator>

#include <fmt/format.h>

namespace rig {
namespace {

namespace fs = std::filesystem;

std::string Base64(const std::string& bytes) {
  static const char* kAlphabet = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  out.reserve((bytes.size() + 2) / 3 * 4);
  size_t i = 0;
  for (; i + 2 < bytes.size(); i += 3) {
    const uint32_t v = (uint8_t(bytes[i]) << 16) | (uint8_t(bytes[i + 1]) << 8) | uint8_t(bytes[i + 2]);
    for (int k = 3; k >= 0; --k) out.push_back(kAlphabet[(v >> (6 * k)) & 63]);
  }
  if (i < bytes.size()) {
    uint32_t v = uint8_t(bytes[i]) << 16;
    if (i + 1 < bytes.size()) v |= uint8_t(bytes[i + 1]) << 8;
    out.push_back(kAlphabet[(v >> 18) & 63]);
    out.push_back(kAlphabet[(v >> 12) & 63]);
    out.push_back(i + 1 < bytes.size() ? kAlphabet[(v >> 6) & 63] : '=');
    out.push_back('=');
  }
  return out;
}

Result<std::string> ReadAll(const fs::path& path) {
  std::ifstream f(path, std::ios::binary);
  if (!f) return MakeError(ErrorCode::kIo, path.string(), "cannot open");
  return std::string(std::istreambuf_iterator<char>(f), std::istreambuf_iterator<char>());
}

Status WriteText(const fs::path& path, const std::string& text) {
  std::error_code ec;
  if (fs::exists(fs::symlink_status(path, ec)))
    return MakeError(ErrorCode::kInvalidInput, path.string(), "exists (nothing is overwritten)");
  return WriteFileAtomic(path, text, /*overwrite=*/false, /*sync=*/false);
}

}  // namespace

Status WriteViewerPage(const std::string& folder, const ViewerPage& page) {
  const fs::path dir(folder);
  RIG_ASSIGN_OR_RETURN(std::string info_text, ReadAll(dir / "info.json"));
  nlohmann::json info;
  try {
    info = nlohmann::json::parse(info_text);
  } catch (const nlohmann::json::exception& e) {
    return MakeError(ErrorCode::kInvalidInput, (dir / "info.json").string(), "not JSON: {}", e.what());
  }
  nlohmann::json data;
  data["info"] = info;
  data["source"] = page.source;
  data["default_light"] = {page.default_light[0], page.default_light[1], page.default_light[2]};
  data["display"] = page.display;
  if (page.tiles) {
    data["tiles"] = {{"tileSize", page.tile_options.tile_size},
                     {"overlap", page.tile_options.overlap},
                     {"format", "jpg"}};
  } else {
    data["tiles"] = nullptr;
  }
  nlohmann::json embedded = nlohmann::json::object();
  std::vector<std::string> names;
  if (!page.tiles) {
    for (int j = 0; fs::exists(dir / fmt::format("plane_{}.jpg", j)); ++j)
      names.push_back(fmt::format("plane_{}.jpg", j));
  }
  for (const auto& image : page.images) {
    data[fs::path(image).stem().string()] = image;
    if (!page.tiles) names.push_back(image);
  }
  for (const auto& name : names) {
    RIG_ASSIGN_OR_RETURN(std::string bytes, ReadAll(dir / name));
    embedded[name] = Base64(bytes);
  }
  data["embedded"] = embedded;
  for (const auto& [name, content] : ViewerAssets()) RIG_TRY(WriteText(dir / name, content));
  return WriteText(dir / "data.js",
                   "// Written by rig view: the model's info.json, display and (untiled) planes.\n"
                   "window.RIG_VIEW = " + data.dump() + ";\n");
}

}  // namespace rig
