// RTI .lp reading, image loading and the exact leave-one-out evaluation in 8-bit sRGB.
#include "process/model/rti.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <sstream>

#include <fmt/format.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

namespace rig {

Result<std::vector<LpEntry>> ReadLp(const std::string& path) {
  std::ifstream f(path);
  if (!f) return MakeError(ErrorCode::kNotFound, path, "cannot open the light file");
  const std::filesystem::path folder = std::filesystem::path(path).parent_path();
  std::string line;
  int lineno = 0;
  long count = -1;
  std::vector<LpEntry> out;
  while (std::getline(f, line)) {
    ++lineno;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    const auto first = line.find_first_not_of(" \t");
    if (first == std::string::npos || line[first] == '#') continue;  // blank, or a comment
    std::istringstream is(line);
    const std::string where = fmt::format("{}:{}", path, lineno);
    if (count < 0) {
      std::string token, extra;
      size_t used = 0;
      try {
        if (!(is >> token) || (is >> extra)) throw std::invalid_argument("count");
        count = std::stol(token, &used);
      } catch (const std::exception&) {
        used = 0;
      }
      if (used == 0 || used != token.size() || count <= 0 || count > 100000) {
        return MakeError(ErrorCode::kInvalidInput, where,
                         "expected the image count (a whole number from 1 to 100000), got '{}'",
                         line);
      }
      continue;
    }
    LpEntry e;
    e.line = lineno;
    std::string extra;
    if (!(is >> e.image >> e.direction[0] >> e.direction[1] >> e.direction[2]) || (is >> extra) ||
        !std::isfinite(e.direction[0]) || !std::isfinite(e.direction[1]) ||
        !std::isfinite(e.direction[2])) {
      return MakeError(ErrorCode::kInvalidInput, where, "expected '<image> <x> <y> <z>', got '{}'",
                       line);
    }
    const double n = std::sqrt(e.direction[0] * e.direction[0] + e.direction[1] * e.direction[1] +
                               e.direction[2] * e.direction[2]);
    if (!(n > 0.5 && n < 1.5)) {
      return MakeError(ErrorCode::kInvalidInput, where,
                       "light direction ({}, {}, {}) is not a unit vector", e.direction[0],
                       e.direction[1], e.direction[2]);
    }
    for (auto& c : e.direction) c /= n;
    std::filesystem::path p(e.image);
    if (p.is_relative()) p = folder / p;
    e.image = p.string();
    out.push_back(e);
  }
  if (count < 0) return MakeError(ErrorCode::kInvalidInput, path, "empty light file");
  if (static_cast<long>(out.size()) != count) {
    if (static_cast<long>(out.size()) > count) {
      return MakeError(ErrorCode::kInvalidInput, fmt::format("{}:{}", path, out[count].line),
                       "the count says {} images, this is image {}", count, count + 1);
    }
    return MakeError(ErrorCode::kInvalidInput, path, "the count says {} images, {} are listed",
                     count, out.size());
  }
  return out;
}

Result<RtiImages> LoadRtiImages(const std::vector<LpEntry>& entries, bool linear,
                                int downsample) {
  RtiImages out;
  cv::Mat lut(1, 256, CV_32F);
  for (int v = 0; v < 256; ++v)
    lut.at<float>(v) = linear ? v / 255.0f : SrgbDecode(v / 255.0f);
  for (const auto& e : entries) {
    cv::Mat img;
    try {
      img = cv::imread(e.image, cv::IMREAD_COLOR);
    } catch (const cv::Exception& ex) {
      return MakeError(ErrorCode::kIo, e.image, "cannot read: {}", ex.what());
    }
    if (img.empty()) return MakeError(ErrorCode::kNotFound, e.image, "cannot read the image");
    if (downsample > 1) {
      cv::Mat small;
      cv::resize(img, small, cv::Size(img.cols / downsample, img.rows / downsample), 0, 0,
                 cv::INTER_AREA);
      img = small;
    }
    if (!out.encoded.empty() && img.size() != out.encoded[0].size()) {
      return MakeError(ErrorCode::kInvalidInput, e.image, "size {}x{} differs from the first image",
                       img.cols, img.rows);
    }
    cv::Mat rad(img.size(), CV_32FC3);
    for (int y = 0; y < img.rows; ++y) {
      const uint8_t* s = img.ptr<uint8_t>(y);
      float* d = rad.ptr<float>(y);
      for (int x = 0; x < img.cols * 3; ++x) d[x] = lut.at<float>(s[x]);
    }
    out.encoded.push_back(img);
    out.radiance.push_back(rad);
  }
  return out;
}

std::vector<LooRow> RtiLeaveOneOut(const RtiImages& images, const std::vector<Vec3>& dirs,
                                   const std::vector<LooSpec>& specs, bool linear,
                                   double max_condition) {
  using Clock = std::chrono::steady_clock;
  const size_t n = images.radiance.size();
  const size_t values = images.radiance.empty() ? 0 : images.radiance[0].total() * 3;
  const std::vector<double> weights = UniformHemisphereWeights(n);
  std::map<FitSpace, std::pair<SampleMatrix, Eigen::MatrixXd>> per_space;
  std::vector<LooRow> rows;
  for (const auto& spec : specs) {
    const auto t0 = Clock::now();
    LooRow row;
    row.basis = BasisKindName(spec.basis);
    row.order = spec.order;
    row.terms = Basis::SizeFor(spec.basis, spec.order);
    row.method = FitMethodName(spec.method);
    row.space = FitSpaceName(spec.space);
    FitOptions o;
    o.basis = spec.basis;
    o.order = spec.order;
    o.max_order = spec.order;
    o.method = spec.method;
    o.transform.space = spec.space;
    o.max_condition = max_condition;
    auto it = per_space.find(spec.space);
    if (it == per_space.end()) {
      SampleMatrix y;
      std::vector<uint8_t> missing;
      Status s = BuildSamples(images.radiance, {}, {1, 1, 1}, o.transform, &y, &missing);
      RIG_CHECK(s.ok(), s.ok() ? "" : s.error().ToString());
      Eigen::MatrixXd g = (y.cast<double>() * y.cast<double>().transpose());
      it = per_space.emplace(spec.space, std::make_pair(std::move(y), std::move(g))).first;
    }
    const SampleMatrix& y = it->second.first;
    const Eigen::MatrixXd& gram = it->second.second;
    // Only the requested order is evaluated; λ (rls) is chosen by LOO error in fit space.
    auto sel = [&]() -> Result<Selection> {
      Basis basis(spec.basis, spec.order);
      std::vector<double> lambdas;
      if (spec.method == FitMethod::kRls) {
        for (int e = -16; e <= 2; ++e) lambdas.push_back(std::pow(10.0, e * 0.5));
      } else {
        lambdas.push_back(0);
      }
      Selection best;
      double best_mse = std::numeric_limits<double>::infinity();
      Error last{ErrorCode::kInvalidInput, "leave-one-out error undefined", ""};
      for (double lam : lambdas) {
        auto pr = BuildProjector(basis, dirs, weights, spec.method, lam, max_condition);
        if (!pr.ok()) {
          last = pr.error();
          continue;
        }
        const double mse = LooMse(LooOperator(*pr), gram, static_cast<double>(values));
        if (mse < best_mse) {
          best_mse = mse;
          best.projector = *pr;
          best.order = spec.order;
        }
      }
      if (!std::isfinite(best_mse)) return last;
      return best;
    }();
    if (!sel.ok()) {
      row.refusal = sel.error().message;
      rows.push_back(row);
      continue;
    }
    const Projector& pr = sel->projector;
    row.supported = true;
    row.lambda_relative = pr.lambda_relative;
    row.condition = pr.condition;
    const Eigen::MatrixXf m = LooOperator(pr).cast<float>();
    SampleMatrix pred = y;
    pred.noalias() -= m * y;  // y - LOO residual = LOO prediction
    row.fit_space_rmse = std::sqrt((pred - y).cast<double>().squaredNorm() /
                                   static_cast<double>(n * values));
    std::vector<double> mse(n), psnr(n);
    double mse_sum = 0;
    for (size_t i = 0; i < n; ++i) {
      float* p = pred.row(static_cast<Eigen::Index>(i)).data();
      o.transform.InverseInPlace(p, values);
      const cv::Mat& enc = images.encoded[i];
      double sum = 0;
      size_t idx = 0;
      for (int yy = 0; yy < enc.rows; ++yy) {
        const uint8_t* e = enc.ptr<uint8_t>(yy);
        for (int x = 0; x < enc.cols * 3; ++x, ++idx) {
          const float lin = p[idx];
          const float v = linear ? lin : SrgbEncode(lin);
          const double q = std::round(std::clamp(v * 255.0f, 0.0f, 255.0f));
          const double d = q - e[x];
          sum += d * d;
        }
      }
      mse[i] = sum / static_cast<double>(values);
      mse_sum += mse[i];
      psnr[i] = 10.0 * std::log10(255.0 * 255.0 / std::max(mse[i], 1e-12));
    }
    row.psnr_mean_mse_db = 10.0 * std::log10(255.0 * 255.0 / std::max(mse_sum / n, 1e-12));
    std::sort(psnr.begin(), psnr.end());
    row.psnr_median_db = n % 2 ? psnr[n / 2] : 0.5 * (psnr[n / 2 - 1] + psnr[n / 2]);
    row.time_s = std::chrono::duration<double>(Clock::now() - t0).count();
    rows.push_back(row);
  }
  return rows;
}

std::string LooTableMarkdown(const std::vector<LooRow>& rows) {
  std::string s =
      "| basis | order | terms/channel | method | fit space | LOO PSNR (mean MSE) dB | "
      "LOO PSNR (median) dB | LOO RMSE (fit space) | lambda (rel.) | cond(B) | time (s) |\n"
      "|---|---|---|---|---|---|---|---|---|---|---|\n";
  for (const auto& r : rows) {
    if (!r.supported) {
      s += fmt::format("| {} | {} | {} | {} | {} | refused: {} | | | | | |\n", r.basis, r.order,
                       r.terms, r.method, r.space, r.refusal);
      continue;
    }
    s += fmt::format("| {} | {} | {} | {} | {} | {:.2f} | {:.2f} | {:.5f} | {:.3g} | {:.3g} | "
                     "{:.2f} |\n",
                     r.basis, r.order, r.terms, r.method, r.space, r.psnr_mean_mse_db,
                     r.psnr_median_db, r.fit_space_rmse, r.lambda_relative, r.condition,
                     r.time_s);
  }
  return s;
}

}  // namespace rig
