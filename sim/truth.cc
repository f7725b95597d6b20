// Writing and reading the simulator's ground truth.
#include "sim/truth.h"

#include <filesystem>
#include <fstream>
#include <sstream>

#include <fmt/format.h>

#include "process/io/exr_io.h"
#include "process/model/light_direction.h"
#include "capture/session/session_store.h"

namespace rig {
namespace {

namespace fs = std::filesystem;

nlohmann::json SimJson(const SimConfig& sim) {
  const auto& k = sim.camera;
  nlohmann::json out = {{"seed", sim.seed},
          {"scene", sim.scene},
          {"width", sim.width},
          {"height", sim.height},
          {"camera",
           {{"gain", k.gain},
            {"full_well", k.full_well},
            {"read_noise_e", k.read_noise_e},
            {"shot_noise", k.shot_noise},
            {"response", k.response},
            {"response_gamma_rgb", k.response_gamma_rgb},
            {"format", k.format},
            {"jpeg_quality", k.jpeg_quality},
            {"shutter_min_s", k.shutter_min_s},
            {"shutter_max_s", k.shutter_max_s}}}};
  // Calibration targets and the near lamp (docs/lights.md), only when used: the truth of a
  // session without them is unchanged.
  if (sim.chrome_spheres > 0) out["chrome_spheres"] = sim.chrome_spheres;
  if (sim.matte_sphere) out["matte_sphere"] = true;
  if (sim.lamp_distance_mm > 0) {
    out["lamp_distance_mm"] = sim.lamp_distance_mm;
    out["field_height_mm"] = sim.field_height_mm;
  }
  return out;
}

std::string Fmt3(const std::array<double, 3>& v) {
  return fmt::format("{:.9g} {:.9g} {:.9g}", v[0], v[1], v[2]);
}

}  // namespace

Status WriteTruth(const std::string& truth_dir, const SimConfig& sim, const SimScene& scene,
                  const SimResponse& response, const std::vector<Pose>& poses,
                  const LightFrameConfig& light_frame,
                  const std::array<double, 3>& lamp_radiance_rgb) {
  std::error_code ec;
  fs::create_directories(fs::path(truth_dir) / "radiance", ec);
  if (ec)
    return MakeError(ErrorCode::kIo, truth_dir, "cannot create the truth folder: {}", ec.message());

  nlohmann::json pose_list = nlohmann::json::array();
  for (const Pose& p : poses) {
    const Vec3 l = LightDirection(p.h_deg, p.v_deg, light_frame);
    const std::string rel = "radiance/" + p.Name() + ".exr";
    cv::Mat radiance = scene.Radiance(l, lamp_radiance_rgb);
    std::map<std::string, std::string> attrs = {
        {"pose", p.Name()},
        {"h_deg", fmt::format("{:.9g}", p.h_deg)},
        {"v_deg", fmt::format("{:.9g}", p.v_deg)},
        {"light_dir", Fmt3(l)},
        {"lamp_radiance_rgb", Fmt3(lamp_radiance_rgb)},
        {"units", "sim scene radiance: radiance * seconds * gain = electrons"},
        {"source", "rig simulator ground truth"}};
    RIG_TRY(WriteRgbExr((fs::path(truth_dir) / rel).string(), radiance, attrs));
    pose_list.push_back({{"name", p.Name()},
                         {"h_deg", p.h_deg},
                         {"v_deg", p.v_deg},
                         {"light_dir", {l[0], l[1], l[2]}},
                         {"radiance", rel}});
  }

  std::string csv = "level,g_B,g_G,g_R\n";
  for (int z = 0; z < 256; ++z)
    csv += fmt::format("{},{:.9g},{:.9g},{:.9g}\n", z, response.LogExposure(0, z),
                       response.LogExposure(1, z), response.LogExposure(2, z));
  RIG_TRY(WriteFileAtomic(fs::path(truth_dir) / "response.csv", csv));

  nlohmann::json j = {
      {"format", "rig sim truth"},
      {"version", 1},
      {"sim", SimJson(sim)},
      {"scene", scene.Describe()},
      {"response", response.ToJson()},
      {"light_frame",
       {{"h_offset_deg", light_frame.h_offset_deg},
        {"v_offset_deg", light_frame.v_offset_deg},
        {"h_sign", light_frame.h_sign},
        {"v_sign", light_frame.v_sign}}},
      {"lamp_radiance_rgb", lamp_radiance_rgb},
      {"poses", pose_list},
      {"files",
       {{"response", "response.csv: level,g_B,g_G,g_R; g = ln(radiance * seconds)"},
        {"radiance", "radiance/<pose>.exr: exact scene radiance, float R, G, B"}}}};
  // A near lamp: the [light_frame] surface_depth_mm that states where the scene's plane lies.
  if (scene.lamp_distance() > 0) j["surface_depth_mm"] = scene.plane_depth_mm();
  return WriteFileAtomic(fs::path(truth_dir) / "scene.json", j.dump(2) + "\n");
}

Status WriteTruth(const std::string& truth_dir, const Config& config) {
  RIG_ASSIGN_OR_RETURN(SimScene scene, SimScene::Create(config.sim));
  RIG_ASSIGN_OR_RETURN(SimResponse response, SimResponse::Create(config.sim.camera));
  return WriteTruth(truth_dir, config.sim, scene, response, PlanGrid(config.grid),
                    config.light_frame, config.lamp.radiance_rgb);
}

cv::Mat SimTruth::BrdfAtAngles(double h_deg, double v_deg) const {
  return scene.Brdf(LightDirection(h_deg, v_deg, light_frame));
}

Result<SimTruth> LoadTruth(const std::string& truth_dir) {
  const std::string path = (fs::path(truth_dir) / "scene.json").string();
  std::ifstream in(path, std::ios::binary);
  if (!in) return MakeError(ErrorCode::kNotFound, path, "cannot open the simulator's truth");
  std::stringstream ss;
  ss << in.rdbuf();
  try {
    nlohmann::json j = nlohmann::json::parse(ss.str());
    if (j.value("format", "") != "rig sim truth")
      return MakeError(ErrorCode::kCorrupt, path, "not a simulator truth file");
    SimConfig sim;
    const auto& s = j.at("sim");
    sim.seed = s.at("seed").get<int>();
    sim.scene = s.at("scene").get<std::string>();
    sim.width = s.at("width").get<int>();
    sim.height = s.at("height").get<int>();
    sim.chrome_spheres = s.value("chrome_spheres", 0);
    sim.matte_sphere = s.value("matte_sphere", false);
    sim.lamp_distance_mm = s.value("lamp_distance_mm", 0.0);
    sim.field_height_mm = s.value("field_height_mm", sim.field_height_mm);
    const auto& k = s.at("camera");
    sim.camera.gain = k.at("gain").get<double>();
    sim.camera.full_well = k.at("full_well").get<double>();
    sim.camera.read_noise_e = k.at("read_noise_e").get<double>();
    sim.camera.shot_noise = k.at("shot_noise").get<bool>();
    sim.camera.response = k.at("response").get<std::string>();
    sim.camera.response_gamma_rgb = k.at("response_gamma_rgb").get<std::array<double, 3>>();
    auto scene = SimScene::Create(sim);
    if (!scene.ok()) return scene.error().Within(path);
    if (scene->Describe() != j.at("scene"))
      return MakeError(ErrorCode::kCorrupt, path,
                       "the scene re-created from [sim] differs from the stored description "
                       "(written by another simulator version)");
    auto response = SimResponse::FromJson(j.at("response"));
    if (!response.ok()) return response.error().Within(path);
    LightFrameConfig frame;
    const auto& f = j.at("light_frame");
    frame.h_offset_deg = f.at("h_offset_deg").get<double>();
    frame.v_offset_deg = f.at("v_offset_deg").get<double>();
    frame.h_sign = f.at("h_sign").get<int>();
    frame.v_sign = f.at("v_sign").get<int>();
    std::vector<Pose> poses;
    for (const auto& p : j.at("poses"))
      poses.push_back(Pose{p.at("h_deg").get<double>(), p.at("v_deg").get<double>()});
    auto lamp = j.at("lamp_radiance_rgb").get<std::array<double, 3>>();
    return SimTruth{std::move(scene).value(), std::move(response).value(), std::move(poses), frame,
                    lamp, std::move(j)};
  } catch (const nlohmann::json::exception& e) {
    return MakeError(ErrorCode::kCorrupt, path, "{}", e.what());
  }
}

Result<SimScene> LoadTruthScene(const std::string& truth_dir) {
  RIG_ASSIGN_OR_RETURN(SimTruth truth, LoadTruth(truth_dir));
  return std::move(truth.scene);
}

}  // namespace rig
