#include "capture/session/session_lp.h"

#include <algorithm>
#include <cmath>
#include <optional>
#include <vector>

#include <fmt/format.h>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "capture/plan/pose.h"
#include "capture/session/session_store.h"
#include "config/console.h"
#include "process/export/relight_files.h"
#include "process/io/exr_io.h"
#include "process/io/image_io.h"
#include "process/model/light_direction.h"
#include "process/model/lp.h"
#include "process/model/samples.h"

namespace rig {

namespace fs = std::filesystem;

Result<SessionLpExport> ExportSessionLp(const fs::path& session, const std::string& out,
                                        LpImageFormat format) {
  const SessionLayout layout{session};
  std::error_code ec;
  if (!fs::is_directory(layout.hdr(), ec)) {
    return MakeError(ErrorCode::kNotFound, layout.hdr().string(),
                                           "no radiance maps (--format lp needs a session)");
  }
  LightFrameConfig frame;
  if (fs::exists(layout.config(), ec)) {
    auto config = LoadConfigOrError(layout.config().string());
    if (!config.ok()) return config.error();
    frame = config->light_frame;
  }
  std::vector<std::pair<std::string, Pose>> poses;
  for (const auto& e : fs::directory_iterator(layout.hdr(), ec)) {
    if (e.path().extension() != ".exr") continue;
    auto pose = ParsePoseName(e.path().stem().string());
    if (!pose.ok()) return pose.error().Within(e.path().string());
    poses.emplace_back(e.path().string(), *pose);
  }
  if (poses.empty()) {
    return MakeError(ErrorCode::kNotFound, layout.hdr().string(), "no radiance maps");
  }
  std::sort(poses.begin(), poses.end(), [](const auto& x, const auto& y) { return x.first < y.first; });
  std::vector<cv::Mat> maps;
  std::vector<float> sample;
  std::optional<ProgressTask> reading(std::in_place, "reading radiance maps",
                                      static_cast<int64_t>(poses.size()));
  for (const auto& [path, pose] : poses) {
    reading->Advance(1, pose.Name());
    auto m = ReadRgbExr(path);
    if (!m.ok()) return m.error();
    if (!maps.empty() && m->size() != maps[0].size()) {
      return MakeError(ErrorCode::kInvalidInput, path, "{}x{}, the first map is {}x{}",
                                             m->cols, m->rows, maps[0].cols, maps[0].rows);
    }
    const float* p = m->ptr<float>();
    const size_t n = m->total() * 3, stride = std::max<size_t>(1, n / 20000);
    for (size_t i = 0; i < n; i += stride) sample.push_back(p[i]);
    maps.push_back(*m);
  }
  reading.reset();
  const size_t q = static_cast<size_t>(0.995 * (sample.size() - 1));
  std::nth_element(sample.begin(), sample.begin() + q, sample.end());
  const float white = sample[q] > 0 ? sample[q] : 1.0f;
  fs::create_directories(out, ec);
  if (ec) return MakeError(ErrorCode::kIo, out, "cannot create: {}", ec.message());
  std::vector<std::string> names;
  std::vector<Vec3> dirs;
  std::vector<std::string> lifted;
  for (size_t i = 0; i < maps.size(); ++i) {
    cv::Mat picture(maps[i].size(), CV_8UC3);
    const float* in = maps[i].ptr<float>();
    uint8_t* o = picture.ptr<uint8_t>();
    for (size_t k = 0; k < maps[i].total() * 3; ++k)
      o[k] = static_cast<uint8_t>(std::lround(255.0f * SrgbEncode(std::clamp(in[k] / white, 0.0f, 1.0f))));
    const bool jpeg = format == LpImageFormat::kJpeg;
    const std::string name = poses[i].second.Name() + (jpeg ? ".jpg" : ".png");
    const std::string path = (fs::path(out) / name).string();
    const std::vector<int> params =
        jpeg ? std::vector<int>{cv::IMWRITE_JPEG_QUALITY, 95} : std::vector<int>{};
    if (Status st = WriteImageFile(path, picture, params); !st.ok()) return st.error();
    names.push_back(name);
    Vec3 d = LightDirection(poses[i].second.h_deg, poses[i].second.v_deg, frame);
    if (auto before = LiftToLowestElevation(&d))
      lifted.push_back(fmt::format("{} ({:.3f} deg)", poses[i].second.Name(), *before));
    dirs.push_back(d);
  }
  const std::string lp = (fs::path(out) / "dirs.lp").string();
  if (Status st = WriteLp(lp, names, dirs); !st.ok()) return st.error();
  SessionLpExport r;
  r.lp = lp;
  r.images = names.size();
  r.width = maps[0].cols;
  r.height = maps[0].rows;
  r.white = white;
  r.lifted = std::move(lifted);
  return r;
}

}  // namespace rig
