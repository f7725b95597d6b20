// rig render: relights a reflectance model with one or more lamps (direction, colour,
// intensity), summed in linear radiance, and writes EXR (radiance) or PNG (sRGB, clipped).
#include <cstdio>
#include <filesystem>
#include <sstream>

#include <opencv2/imgcodecs.hpp>

#include "process/exr_io.h"
#include "process/fit.h"
#include "process/light_direction.h"
#include "process/model.h"
#include "rig/commands/command.h"

namespace rig {
namespace {

struct LampSpec {
  double h_deg = 0, v_deg = 0;
  std::array<double, 3> rgb = {1, 1, 1};
  double intensity = 1;
};

// "H,V[,R,G,B[,I]]"
Result<LampSpec> ParseLamp(const std::string& text) {
  std::vector<double> v;
  std::stringstream ss(text);
  std::string item;
  while (std::getline(ss, item, ',')) {
    try {
      size_t used = 0;
      v.push_back(std::stod(item, &used));
      if (used != item.size()) throw std::invalid_argument(item);
    } catch (const std::exception&) {
      return MakeError(ErrorCode::kInvalidInput, "--light " + text, "'{}' is not a number", item);
    }
  }
  if (v.size() != 2 && v.size() != 5 && v.size() != 6) {
    return MakeError(ErrorCode::kInvalidInput, "--light " + text,
                     "expected H,V or H,V,R,G,B or H,V,R,G,B,I");
  }
  LampSpec l;
  l.h_deg = v[0];
  l.v_deg = v[1];
  if (v.size() >= 5) l.rgb = {v[2], v[3], v[4]};
  if (v.size() == 6) l.intensity = v[5];
  return l;
}

}  // namespace

int RunRender(int argc, char** argv) {
  CLI::App app{"Relight a reflectance model: the sum over lamps of rho(direction) x lamp radiance "
               "x colour x intensity, in linear radiance.",
               "rig render"};
  std::string model_path, out, log_level;
  std::vector<std::string> lights;
  app.add_option("MODEL", model_path, "model EXR written by rig fit")->required();
  app.add_option("--light", lights,
                 "lamp H,V[,R,G,B[,I]]: rig angles (deg), colour relative to the capture lamp, "
                 "intensity; repeat for several lamps")
      ->required();
  app.add_option("--out", out, "output: .exr (linear radiance) or .png (sRGB, clipped)")
      ->required();
  AddLogLevelOption(app, &log_level);
  if (auto rc = ParseCommandLine(app, argc, argv)) return *rc;
  if (auto rc = ApplyLogLevel(log_level)) return *rc;

  std::vector<LampSpec> lamps;
  for (const auto& text : lights) {
    auto l = ParseLamp(text);
    if (!l.ok()) return ReportError("render", l.error());
    lamps.push_back(*l);
  }
  const std::string ext = std::filesystem::path(out).extension().string();
  if (ext != ".exr" && ext != ".png") {
    return ReportError("render", MakeError(ErrorCode::kInvalidInput, out,
                                           "output must end in .exr or .png"));
  }
  auto model = LoadModel(model_path);
  if (!model.ok()) return ReportError("render", model.error());

  cv::Mat sum;
  for (const auto& l : lamps) {
    // The model's own light frame turns rig angles into its object-frame direction.
    const Vec3 dir = LightDirection(l.h_deg, l.v_deg, model->info().light_frame);
    const RegionCheck region = model->CheckRegion(dir);
    if (!region.inside) {
      std::fprintf(stderr,
                   "rig render: warning: lamp %g,%g is outside the sampled lamp region (%.1f deg "
                   "from the nearest sampled lamp; sampling spacing %.1f deg): extrapolated\n",
                   l.h_deg, l.v_deg, region.nearest_deg, model->info().sample_spacing_deg);
    }
    model->AddLamp(dir, {l.rgb[0] * l.intensity, l.rgb[1] * l.intensity, l.rgb[2] * l.intensity},
                   &sum);
  }
  Status s;
  if (ext == ".exr") {
    s = WriteRgbExr(out, sum, {{"rig.render", "relit radiance (linear)"}});
  } else {
    cv::Mat enc = sum.clone();
    enc.forEach<cv::Vec3f>([](cv::Vec3f& p, const int*) {
      for (int c = 0; c < 3; ++c) p[c] = SrgbEncode(std::clamp(p[c], 0.0f, 1.0f));
    });
    cv::Mat png;
    enc.convertTo(png, CV_8UC3, 255.0);
    try {
      if (!cv::imwrite(out, png)) s = MakeError(ErrorCode::kIo, out, "cannot write the PNG");
    } catch (const cv::Exception& e) {
      s = MakeError(ErrorCode::kIo, out, "cannot write the PNG: {}", e.what());
    }
  }
  if (!s.ok()) return ReportError("render", s.error());
  std::printf("rig render: wrote %s (%zu lamp%s)\n", out.c_str(), lamps.size(),
              lamps.size() == 1 ? "" : "s");
  return 0;
}

}  // namespace rig
