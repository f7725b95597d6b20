// Test support: a small synthetic multi-light RTI capture written as JPEGs with an .lp file
// (36 lights on rings at 25..70°, a textured matte plane with bumps and a glossy stripe), for
// `rig fit --lp` and what reads its models.
#pragma once

#include <algorithm>
#include <cmath>
#include <fstream>
#include <string>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "process/model/harmonic/fit.h"

namespace rig::testing {

// Writes the images and `dir`/dirs.lp; returns the .lp's path.
inline std::string WriteLpCapture(const std::string& dir, int width, int height) {
  std::ofstream lp(dir + "/dirs.lp");
  lp << "# a synthetic capture\n36\n";
  int index = 0;
  for (double elev : {25.0, 40.0, 55.0, 70.0}) {
    for (int i = 0; i < 9; ++i, ++index) {
      const double az = (i + 0.3 * index) * 2 * M_PI / 9, e = elev * M_PI / 180;
      const double l[3] = {std::cos(e) * std::cos(az), std::cos(e) * std::sin(az), std::sin(e)};
      cv::Mat img(height, width, CV_8UC3);
      for (int y = 0; y < height; ++y)
        for (int x = 0; x < width; ++x) {
          const double u = x / double(width) - 0.5, v = y / double(height) - 0.5;
          double n[3] = {0.4 * std::sin(9 * u), 0.3 * std::cos(7 * v), 1};
          const double nn = std::sqrt(n[0] * n[0] + n[1] * n[1] + 1);
          for (auto& q : n) q /= nn;
          const double ndl = std::max(0.0, n[0] * l[0] + n[1] * l[1] + n[2] * l[2]);
          const double rz = 2 * ndl * n[2] - l[2];
          const double spec = (y / 10) % 3 == 0 ? 0.5 * std::pow(std::max(0.0, rz), 15) : 0;
          for (int c = 0; c < 3; ++c) {
            const double albedo = (0.3 + 0.3 * ((x / 6) % 2)) * (1.0 - 0.2 * c);
            img.at<cv::Vec3b>(y, x)[c] = static_cast<uint8_t>(std::clamp(
                255.0 * SrgbEncode(static_cast<float>(albedo * ndl + spec)), 0.0, 255.0));
          }
        }
      const std::string name = "img" + std::to_string(index) + ".jpg";
      cv::imwrite(dir + "/" + name, img, {cv::IMWRITE_JPEG_QUALITY, 95});
      lp << name << " " << l[0] << " " << l[1] << " " << l[2] << "\n";
    }
  }
  return dir + "/dirs.lp";
}

}  // namespace rig::testing
