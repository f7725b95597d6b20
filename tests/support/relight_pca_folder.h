// Test support: hand-made folders of relight's PCA types (rbf, bilinear; mrgb, mycc) with seeded
// bases and smooth planes, and relight's renderer written out as it loops (Rti::render,
// Rti::lightWeightsRbf/Bilinear, Color3::toRgb; ../shared/docs/rti-formats.md) — the expected
// values against which rig's reader and page are checked.
#pragma once

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>

#include "process/io/jpeg_io.h"
#include "process/model/light_direction.h"

namespace rig::testing {

inline constexpr int kW = 24, kH = 16;

struct Folder {
  std::string dir;
  nlohmann::json info;
  std::vector<cv::Mat> planes;  // nplanes × CV_8U as decoded from the files
  std::vector<Vec3> lights;
  int nodes = 0, nplanes = 0, nc = 0;
  bool rbf = false, ycc = false;
};


inline std::vector<Vec3> DomeLights() {
  std::vector<Vec3> l;
  for (double el : {20.0, 45.0, 70.0})
    for (double az = 0; az < 360; az += 45) {
      const double t = (90 - el) * M_PI / 180, p = az * M_PI / 180;
      // printed with 3 decimals, as relight writes them
      l.push_back({std::round(1000 * std::sin(t) * std::cos(p)) / 1000,
                   std::round(1000 * std::sin(t) * std::sin(p)) / 1000,
                   std::round(1000 * std::cos(t)) / 1000});
    }
  return l;
}

// A folder of type rbf or bilinear, colour space mrgb or mycc, with seeded bases and planes.
inline Folder MakeRelightPcaFolder(const std::string& dir, bool rbf, bool ycc, uint32_t seed) {
  Folder f;
  f.dir = dir;
  std::filesystem::create_directories(f.dir);
  f.rbf = rbf;
  f.ycc = ycc;
  f.lights = DomeLights();
  const int res = 6;
  f.nodes = rbf ? static_cast<int>(f.lights.size()) : res * res;
  const int ny = 4;
  f.nc = ycc ? 2 : 0;
  f.nplanes = ycc ? ny + 2 * f.nc : 7;
  std::mt19937 rng(seed);
  std::uniform_int_distribution<int> mean(60, 200), eig(20, 234), byte(0, 255);
  std::vector<int> basis;
  std::vector<double> scale, bias, range;
  for (int p = 0; p <= f.nplanes; ++p)
    for (int n = 0; n < f.nodes; ++n)
      for (int c = 0; c < 3; ++c) {
        // mycc: the chroma means near the middle (Co, Cg around 0 would clamp at 0 in relight's
        // builder; any byte is a valid file)
        basis.push_back(p == 0 ? (ycc && c > 0 ? mean(rng) / 8 : mean(rng)) : eig(rng));
      }
  for (int p = 0; p < f.nplanes; ++p) {
    scale.push_back(0.2 + 0.05 * p);
    bias.push_back(0.5 - 0.03 * p);
    range.push_back(200.0 + 10 * p);
  }
  f.info = {{"width", kW},       {"height", kH},   {"format", "jpg"},
            {"type", rbf ? "rbf" : "bilinear"},     {"colorspace", ycc ? "mycc" : "mrgb"},
            {"quality", 95},     {"basis", basis}};
  if (rbf) f.info["sigma"] = 0.35;
  if (!rbf) f.info["resolution"] = res;
  std::vector<double> flat;
  for (const auto& l : f.lights) flat.insert(flat.end(), l.begin(), l.end());
  f.info["lights"] = flat;
  if (ycc)
    f.info["yccplanes"] = {ny, f.nc, f.nc};
  else
    f.info["nplanes"] = f.nplanes;
  f.info["materials"] = nlohmann::json::array({{{"scale", scale}, {"bias", bias}, {"range", range}}});
  std::ofstream(f.dir + "/info.json") << f.info.dump();
  // Smooth planes (a ramp plus a seeded offset per plane), as a real model's coefficients are.
  for (int j = 0; 3 * j < f.nplanes; ++j) {
    cv::Mat rgb(kH, kW, CV_8UC3, cv::Scalar(0, 0, 0));
    for (int c = 0; c < 3 && 3 * j + c < f.nplanes; ++c) {
      const int offset = byte(rng) / 2;
      for (int y = 0; y < kH; ++y)
        for (int x = 0; x < kW; ++x) rgb.at<cv::Vec3b>(y, x)[c] = static_cast<uint8_t>(offset + 3 * x + 2 * y);
    }
    const std::string plane = f.dir + "/plane_" + std::to_string(j) + ".jpg";
    EXPECT_TRUE(WriteJpeg(plane, rgb, JpegColor::kRgb, 95).ok());
    auto back = ReadJpeg(plane);
    EXPECT_TRUE(back.ok());
    std::vector<cv::Mat> ch(3);
    cv::split(*back, ch);
    for (int c = 0; c < 3 && 3 * j + c < f.nplanes; ++c) f.planes.push_back(ch[c]);
  }
  return f;
}

// relight's renderer, written out as it loops: the light weights over the basis, then per
// pixel the mean plus each plane's dequantised value times its weight, then YCoCg → RGB.
inline cv::Vec3d RelightRender(const Folder& f, const Vec3& dir, int x, int y) {
  const double n = std::sqrt(dir[0] * dir[0] + dir[1] * dir[1] + dir[2] * dir[2]);
  const double lx = dir[0] / n, ly = dir[1] / n, lz = std::sqrt(1 - lx * lx - ly * ly);
  const auto& stored = f.info["basis"];
  const auto& mat = f.info["materials"][0];
  auto value = [&](int p, int node, int k) {
    const double b = stored[(static_cast<size_t>(p) * f.nodes + node) * 3 + k].get<int>();
    return p == 0 ? b : (b - 127.0) / mat["range"][p - 1].get<double>();
  };
  std::vector<double> lw((f.nplanes + 1) * 3, 0.0);
  if (f.rbf) {
    const double radius = 1 / (0.35 * 0.35);
    std::vector<double> w;
    double total = 0;
    for (const auto& L : f.lights) {
      const double d2 = (lx - L[0]) * (lx - L[0]) + (ly - L[1]) * (ly - L[1]) + (lz - L[2]) * (lz - L[2]);
      w.push_back(std::exp(-radius * d2));
      total += w.back();
    }
    double kept = 0;
    for (double& v : w) {
      v /= total;
      if (v > 0.001)
        kept += v;
      else
        v = 0;
    }
    for (int p = 0; p <= f.nplanes; ++p)
      for (int k = 0; k < 3; ++k)
        for (size_t i = 0; i < w.size(); ++i) lw[3 * p + k] += w[i] / kept * value(p, static_cast<int>(i), k);
  } else {
    const int res = f.info["resolution"].get<int>();
    const double s = std::abs(lx) + std::abs(ly) + std::abs(lz);
    const double u = ((lx + ly) / s + 1) / 2 * (res - 1), v = ((ly - lx) / s + 1) / 2 * (res - 1);
    const int sx = std::min(res - 2, std::max(0, static_cast<int>(std::floor(u))));
    const int sy = std::min(res - 2, std::max(0, static_cast<int>(std::floor(v))));
    const double dx = u - sx, dy = v - sy;
    for (int p = 0; p <= f.nplanes; ++p)
      for (int k = 0; k < 3; ++k)
        lw[3 * p + k] = (1 - dx) * (1 - dy) * value(p, sx + sy * res, k) +
                        dx * (1 - dy) * value(p, sx + 1 + sy * res, k) +
                        (1 - dx) * dy * value(p, sx + (sy + 1) * res, k) +
                        dx * dy * value(p, sx + 1 + (sy + 1) * res, k);
  }
  auto dequantise = [&](int p) {
    const double byte = f.planes[p].at<uint8_t>(y, x);
    return 255 * (byte / 255 - mat["bias"][p].get<double>()) * mat["scale"][p].get<double>();
  };
  double c[3] = {lw[0], lw[1], lw[2]};
  if (!f.ycc) {
    for (int p = 0; p < f.nplanes; ++p)
      for (int k = 0; k < 3; ++k) c[k] += dequantise(p) * lw[3 * (p + 1) + k];
    return {c[0], c[1], c[2]};
  }
  for (int p = 0; p < f.nc; ++p)
    for (int k = 0; k < 3; ++k) c[k] += dequantise(p * 3 + k) * lw[3 * (p * 3 + k + 1) + k];
  for (int p = 3 * f.nc; p < f.nplanes; ++p) c[0] += dequantise(p) * lw[3 * (p + 1)];
  // Color3::toRgb (r = Y, g = Co, b = Cg)
  const double tmp = c[0] - c[2] / 2, g = c[2] + tmp, b = tmp - c[1] / 2, r = b + c[1];
  return {r, g, b};
}

}  // namespace rig::testing
