// Writes the binary seeds of tests/fuzz/corpus/ with the project's own writers, small (8x6
// pixels): `fuzz_make_seeds DIR` fills DIR/{jpeg,image,raw,exr,model,ptm,rti,relight}/. The text
// seeds (config, list, lp, journal, journal_resume) are written by hand; see docs/fuzzing.md.
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>

#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>

#include "process/export/convert.h"
#include "process/export/relight_files.h"
#include "process/io/exr_io.h"
#include "process/io/jpeg_io.h"
#include "process/model/light_direction.h"
#include "process/model/any/rti_fit.h"
#include "sim/dng_writer.h"
#include "tests/fuzz/fuzz_support.h"

namespace fs = std::filesystem;
using rig::fuzz::WriteFile;

namespace {

void Check(const rig::Status& st, const char* what) {
  if (!st.ok()) {
    std::fprintf(stderr, "make_seeds: %s: %s\n", what, st.error().ToString().c_str());
    std::exit(1);
  }
}
template <typename T>
T Take(rig::Result<T> r, const char* what) {
  if (!r.ok()) {
    std::fprintf(stderr, "make_seeds: %s: %s\n", what, r.error().ToString().c_str());
    std::exit(1);
  }
  return std::move(*r);
}

std::string Slurp(const fs::path& p) {
  std::ifstream f(p, std::ios::binary);
  std::ostringstream s;
  s << f.rdbuf();
  return s.str();
}

// A folder as one input: info.json, then "--8<-- <name>" and each other file.
std::string Pack(const fs::path& folder) {
  std::string out = Slurp(folder / "info.json");
  std::vector<fs::path> files;
  for (const auto& e : fs::directory_iterator(folder))
    if (e.path().filename() != "info.json") files.push_back(e.path());
  std::sort(files.begin(), files.end());
  for (const auto& f : files) out += "\n--8<-- " + f.filename().string() + "\n" + Slurp(f);
  return out;
}

// A Lambertian-ish 8x6 scene under 12 lamps: images and an .lp, for the model seeds.
fs::path MakeCapture(const fs::path& dir) {
  fs::create_directories(dir);
  std::ofstream lp(dir / "capture.lp");
  const int n = 12;
  lp << n << "\n";
  for (int i = 0; i < n; ++i) {
    const double phi = 2 * M_PI * i / n, theta = (i % 2 ? 30.0 : 60.0) * M_PI / 180;
    const rig::Vec3 l = {std::sin(theta) * std::cos(phi), std::sin(theta) * std::sin(phi),
                         std::cos(theta)};
    cv::Mat img(6, 8, CV_8UC3);
    for (int y = 0; y < 6; ++y)
      for (int x = 0; x < 8; ++x) {
        const double nx = (x - 3.5) / 8, ny = (y - 2.5) / 8, nz = std::sqrt(1 - nx * nx - ny * ny);
        const double s = std::max(0.0, nx * l[0] - ny * l[1] + nz * l[2]);
        img.at<cv::Vec3b>(y, x) = cv::Vec3b(cv::saturate_cast<uchar>(40 + 150 * s),
                                            cv::saturate_cast<uchar>(30 + 180 * s),
                                            cv::saturate_cast<uchar>(20 + 200 * s));
      }
    const std::string name = "img" + std::to_string(i) + ".png";
    cv::imwrite((dir / name).string(), img);
    lp << name << " " << l[0] << " " << l[1] << " " << l[2] << "\n";
  }
  return dir / "capture.lp";
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: fuzz_make_seeds DIR\n");
    return 2;
  }
  rig::fuzz::QuietLogs();
  const fs::path out = argv[1];
  for (const char* d : {"jpeg", "image", "raw", "exr", "model", "ptm", "rti", "relight"})
    fs::create_directories(out / d);

  cv::Mat rgb(6, 8, CV_8UC3), grey(6, 8, CV_8UC1), deep(6, 8, CV_16UC3);
  cv::randu(rgb, 0, 255);
  cv::randu(grey, 0, 255);
  cv::randu(deep, 0, 65535);
  auto bytes = [](const std::vector<uint8_t>& v) {
    return std::string_view(reinterpret_cast<const char*>(v.data()), v.size());
  };
  // JPEG: the three colour modes of jpeg_io.
  WriteFile(out / "jpeg/rgb.jpg", bytes(Take(rig::EncodeJpeg(rgb, rig::JpegColor::kRgb, 90), "jpeg")));
  WriteFile(out / "jpeg/ycbcr.jpg", bytes(Take(rig::EncodeJpeg(rgb, rig::JpegColor::kYcbcr, 90), "jpeg")));
  WriteFile(out / "jpeg/grey.jpg", bytes(Take(rig::EncodeJpeg(grey, rig::JpegColor::kGray, 90), "jpeg")));
  // Camera files: JPEG, 8- and 16-bit PNG, 16-bit TIFF, grey PNG.
  std::vector<uchar> buf;
  auto encode = [&](const char* ext, const cv::Mat& m, const char* name) {
    if (!cv::imencode(ext, m, buf)) std::exit(1);
    WriteFile(out / "image" / name, std::string_view(reinterpret_cast<const char*>(buf.data()), buf.size()));
  };
  encode(".jpg", rgb, "frame.jpg");
  encode(".png", rgb, "frame8.png");
  encode(".png", deep, "frame16.png");
  encode(".tif", deep, "frame16.tif");
  encode(".png", grey, "grey.png");
  // RAW: DNG as the simulated camera writes it, a Bayer mosaic and LinearRaw, with levels.
  rig::DngOptions dng;
  dng.black = 512;
  dng.white = 15000;
  dng.exposure_s = 0.01;
  dng.as_shot_neutral[0] = 0.5;
  dng.as_shot_neutral[2] = 0.7;
  cv::Mat sensor(6, 8, CV_16UC3);
  cv::randu(sensor, 512, 16000);
  WriteFile(out / "raw/bayer.dng", bytes(Take(rig::EncodeDng(sensor, dng), "dng")));
  dng.mosaic = false;
  WriteFile(out / "raw/linear.dng", bytes(Take(rig::EncodeDng(sensor, dng), "dng")));
  // EXR: a radiance map in float and half, and a multi-channel file with attributes.
  cv::Mat radiance(6, 8, CV_32FC3);
  cv::randu(radiance, 0.0f, 8.0f);
  Check(rig::WriteRgbExr((out / "exr/float.exr").string(), radiance, {{"pose", "h030_v10"}}), "exr");
  Check(rig::WriteRgbExr((out / "exr/half.exr").string(), radiance, {{"exposures_s", "0.01 0.02"}},
                         rig::ExrPixelType::kHalf),
        "exr");
  rig::ExrImage multi;
  multi.width = 8;
  multi.height = 6;
  for (const char* c : {"c00.R", "c00.G", "c00.B", "valid"}) {
    multi.channel_names.push_back(c);
    cv::Mat plane(6, 8, CV_32FC1);
    cv::randu(plane, 0.0f, 1.0f);
    multi.channels.push_back(plane);
  }
  multi.attributes = {{"basis", "sh"}, {"order", "0"}};
  Check(rig::WriteExr((out / "exr/multi.exr").string(), multi), "exr");

  // Models fitted to a small synthetic capture, in each family and format.
  const fs::path scratch = rig::fuzz::Scratch();
  const auto capture = Take(rig::LoadRtiCapture(MakeCapture(scratch / "capture").string()), "capture");
  auto fit = [&](const char* family) {
    rig::RtiFitRequest req;
    req.family = family;
    if (std::string(family) != "auto") req.harmonic.order = 2;
    return Take(rig::FitRti(capture, req), family).model;
  };
  auto sh = fit("sh");
  Check(sh->Save((out / "model/sh.exr").string()), "sh");
  auto hsh = fit("hsh");
  Check(hsh->Save((out / "model/hsh.exr").string()), "hsh");
  auto ptm = fit("ptm");
  Check(ptm->Save((out / "model/ptm.exr").string()), "ptm");

  const auto ptm_rgb = Take(rig::ConvertToRelight(*ptm, {rig::RelightType::kPtm, 6, false}), "ptm rgb");
  const auto ptm_lrgb = Take(rig::ConvertToRelight(*ptm, {rig::RelightType::kPtm, 6, true}), "ptm lrgb");
  const auto hsh9 = Take(rig::ConvertToRelight(*hsh, {rig::RelightType::kHsh, 9, false}), "hsh 9");
  const auto hsh4 = Take(rig::ConvertToRelight(*hsh, {rig::RelightType::kHsh, 4, false}), "hsh 4");
  const auto hsh16 = Take(rig::ConvertToRelight(*hsh, {rig::RelightType::kHsh, 16, false}), "hsh 16");
  Check(rig::WritePtm((out / "ptm/rgb.ptm").string(), ptm_rgb.coefficients), "ptm");
  Check(rig::WritePtm((out / "ptm/lrgb.ptm").string(), ptm_lrgb.coefficients), "ptm");
  Check(rig::WriteRti((out / "rti/hsh9.rti").string(), hsh9.coefficients), "rti");
  Check(rig::WriteRti((out / "rti/hsh4.rti").string(), hsh4.coefficients), "rti");
  Check(rig::WriteRti((out / "rti/hsh16.rti").string(), hsh16.coefficients), "rti");

  auto web = [&](const char* name, const rig::RelightCoefficients& c, bool ycbcr) {
    const fs::path folder = scratch / "web" / name;
    rig::WebWriteOptions o;
    o.ycbcr = ycbcr;
    Check(rig::WriteRelightWeb(folder.string(), c, o), name);
    WriteFile(out / "relight" / (std::string(name) + ".txt"), Pack(folder));
  };
  web("ptm-rgb", ptm_rgb.coefficients, true);
  web("ptm-lrgb", ptm_lrgb.coefficients, false);
  web("hsh", hsh4.coefficients, true);
  auto pca = fit("auto");
  const fs::path pca_folder = scratch / "pca";
  Check(pca->Save(pca_folder.string()), "pca");
  WriteFile(out / "relight/pca.txt", Pack(pca_folder));
  // relight's own PCA types, which rig reads but does not fit: rbf (relight's default) and the
  // mycc forms yrbf and ybilinear, 8x6, one plane file, four nodes (four lights, or a 2x2 grid).
  auto relight_pca = [&](const char* name, bool rbf, bool ycc) {
    const fs::path folder = scratch / "web" / name;
    fs::create_directories(folder);
    const int k = 3, nodes = 4;
    nlohmann::ordered_json info = {{"width", 8}, {"height", 6}, {"format", "jpg"},
                                   {"type", rbf ? "rbf" : "bilinear"}};
    if (!rbf) info["resolution"] = 2;
    info["colorspace"] = ycc ? "mycc" : "mrgb";
    if (rbf) info["sigma"] = 0.125;
    info["lights"] = {0.5, 0.0, 0.866, -0.5, 0.0, 0.866, 0.0, 0.5, 0.866, 0.0, -0.5, 0.866};
    if (ycc)
      info["yccplanes"] = {1, 1, 1};
    else
      info["nplanes"] = k;
    info["quality"] = 95;
    std::vector<int> basis;
    for (int i = 0; i < (k + 1) * nodes * 3; ++i) basis.push_back(i < nodes * 3 ? 100 + 7 * i : 60 + 11 * i % 130);
    info["basis"] = basis;
    info["materials"] = {{{"scale", {0.3, 0.25, 0.2}}, {"bias", {0.5, 0.45, 0.4}}, {"range", {180.0, 200.0, 220.0}}}};
    std::ofstream(folder / "info.json") << info.dump();
    cv::Mat rgb(6, 8, CV_8UC3);
    for (int y = 0; y < 6; ++y)
      for (int x = 0; x < 8; ++x) rgb.at<cv::Vec3b>(y, x) = cv::Vec3b(20 * x, 30 * y, 100 + x * y);
    Check(rig::WriteJpeg((folder / "plane_0.jpg").string(), rgb, rig::JpegColor::kRgb, 95), name);
    WriteFile(out / "relight" / (std::string(name) + ".txt"), Pack(folder));
  };
  relight_pca("rbf", true, false);
  relight_pca("yrbf", true, true);
  relight_pca("ybilinear", false, true);
  std::printf("seeds written to %s\n", out.c_str());
  return 0;
}
