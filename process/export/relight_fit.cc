// relight's bases fitted straight to the photographs (see relight_fit.h).
#include "process/export/relight_fit.h"

#include <stdlib.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <limits>
#include <thread>

#include <Eigen/Dense>
#include <fmt/format.h>

#include "process/export/relight_files.h"

namespace rig {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

double FitSeconds(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

// The rgb coefficients of every pixel from the images in `use` (indices into the samples'
// lights): one pseudo-inverse for the pixels whose samples are all usable, a least-squares
// solve of its own for a channel with masked samples (all its samples when fewer usable ones
// than terms are left: the clipped values as they are rather than no fit).
RelightCoefficients FitRgb(const LightSamples& s, const RelightTarget& t, const std::vector<int>& use,
                           int threads, size_t* refitted) {
  const int terms = t.terms, n = static_cast<int>(use.size());
  Eigen::MatrixXd w(n, terms);
  double row[kMaxRelightTerms];
  for (int i = 0; i < n; ++i) {
    RelightWeights(t.type, terms, s.directions[use[i]], row);
    for (int k = 0; k < terms; ++k) w(i, k) = row[k];
  }
  const Eigen::MatrixXd pinv = w.completeOrthogonalDecomposition().pseudoInverse();  // T × n
  RelightCoefficients c;
  c.type = t.type;
  c.terms = terms;
  c.width = s.width;
  c.height = s.height;
  for (int k = 0; k < terms; ++k) c.planes.push_back(cv::Mat::zeros(s.height, s.width, CV_32FC3));
  for (int l : use) c.lights.push_back(s.directions[l]);
  const size_t lights = s.directions.size();
  std::vector<size_t> counts(std::max(1, threads), 0);
  auto band = [&](int part, int y0, int y1) {
    Eigen::VectorXd v(n), out(terms);
    std::vector<int> rows;
    for (int y = y0; y < y1; ++y)
      for (int x = 0; x < s.width; ++x) {
        const size_t p = static_cast<size_t>(y) * s.width + x;
        bool masked_pixel = false;
        for (int ch = 0; ch < 3; ++ch) {
          rows.clear();
          for (int i = 0; i < n; ++i) {
            v(i) = s.values[(p * lights + use[i]) * 3 + ch];
            if (s.is_usable(p, use[i], ch)) rows.push_back(i);
          }
          if (static_cast<int>(rows.size()) == n || static_cast<int>(rows.size()) < terms) {
            out = pinv * v;
          } else {
            masked_pixel = true;
            Eigen::MatrixXd a(rows.size(), terms);
            Eigen::VectorXd b(rows.size());
            for (size_t r = 0; r < rows.size(); ++r) {
              a.row(static_cast<Eigen::Index>(r)) = w.row(rows[r]);
              b(static_cast<Eigen::Index>(r)) = v(rows[r]);
            }
            out = a.completeOrthogonalDecomposition().solve(b);
          }
          for (int k = 0; k < terms; ++k) c.planes[k].ptr<float>(y)[3 * x + 2 - ch] = static_cast<float>(out(k));
        }
        if (masked_pixel) ++counts[part];
      }
  };
  const int parts = std::max(1, threads);
  std::vector<std::thread> pool;
  for (int i = 1; i < parts; ++i)
    pool.emplace_back(band, i, s.height * i / parts, s.height * (i + 1) / parts);
  band(0, 0, s.height / parts);
  for (auto& th : pool) th.join();
  if (refitted) {
    *refitted = 0;
    for (size_t k : counts) *refitted += k;
  }
  return c;
}

// 8-bit PSNR of the coefficients' renders (clamped to 0..255) against the photographs at `at`.
double PsnrAtImages(const LightSamples& s, const RelightCoefficients& c, const std::vector<int>& at) {
  double sse = 0;
  const size_t lights = s.directions.size();
  for (int l : at) {
    const cv::Mat r = RenderRelight(c, s.directions[l]);
    for (int y = 0; y < s.height; ++y) {
      const float* q = r.ptr<float>(y);
      for (int x = 0; x < s.width; ++x) {
        const size_t p = static_cast<size_t>(y) * s.width + x;
        for (int ch = 0; ch < 3; ++ch) {
          const double d = std::clamp(q[3 * x + 2 - ch], 0.0f, 255.0f) - s.values[(p * lights + l) * 3 + ch];
          sse += d * d;
        }
      }
    }
  }
  const double count = 3.0 * static_cast<double>(s.pixels()) * static_cast<double>(at.size());
  if (sse <= 0) return std::numeric_limits<double>::infinity();
  return 10 * std::log10(255.0 * 255.0 / (sse / count));
}

RelightCoefficients Finished(RelightCoefficients rgb, const RelightTarget& t) {
  if (!t.lrgb) return rgb;
  RelightCoefficients l = FactoriseLrgb(rgb, rgb.lights);
  l.lights = rgb.lights;
  return l;
}

// The coefficients as the file holds them: written to a private scratch folder and read back.
Result<RelightCoefficients> AsWritten(const RelightCoefficients& c, const std::string& format) {
  std::string tmpl = (fs::temp_directory_path() / "rig-relight-fit-XXXXXX").string();
  if (::mkdtemp(tmpl.data()) == nullptr)
    return MakeError(ErrorCode::kIo, tmpl, "cannot create a scratch folder: {}", std::strerror(errno));
  const std::string path = (fs::path(tmpl) / ("held-out." + format)).string();
  Result<RelightCoefficients> back = MakeError(ErrorCode::kInternal, path, "not written");
  const Status written = format == "rti" ? WriteRti(path, c) : WritePtm(path, c);
  if (written.ok()) back = format == "rti" ? ReadRti(path) : ReadPtm(path);
  std::error_code ec;
  fs::remove_all(tmpl, ec);
  if (!written.ok()) return written.error();
  return back;
}

}  // namespace

Result<RelightFit> FitRelightToSamples(const LightSamples& s, const RelightTarget& t,
                                       const RelightFitOptions& o) {
  const bool ok = t.type == RelightType::kPtm ? t.terms == 6
                  : t.type == RelightType::kHsh ? (t.terms == 9 || t.terms == 4 || t.terms == 16)
                                                : false;
  if (!ok || (t.lrgb && t.type != RelightType::kPtm)) {
    return MakeError(ErrorCode::kInvalidInput, "fit",
                     "no {} basis of {} terms{} is written here (ptm 6 rgb/lrgb, hsh 4, 9 or 16)",
                     RelightTypeName(t.type), t.terms, t.lrgb ? " in lrgb" : "");
  }
  if (s.lights() < t.terms) {
    return MakeError(ErrorCode::kInvalidInput, "fit", "{} images cannot determine {} {} terms",
                     s.lights(), t.terms, RelightTypeName(t.type));
  }
  if (t.type == RelightType::kHsh) {
    for (int l = 0; l < s.lights(); ++l)
      if (!(s.directions[l][2] > 0)) {
        return MakeError(ErrorCode::kInvalidInput, "fit",
                         "image {} is lit from ({:.3f}, {:.3f}, {:.3f}), at or below the horizon: "
                         "the HSH basis is the upper hemisphere's (use .ptm, or leave it out of the .lp)",
                         l + 1, s.directions[l][0], s.directions[l][1], s.directions[l][2]);
      }
  }
  RelightFit out;
  const auto t0 = Clock::now();
  std::vector<int> all(s.lights());
  for (int l = 0; l < s.lights(); ++l) all[l] = l;
  out.coefficients = Finished(FitRgb(s, t, all, o.threads, &out.refitted_pixels), t);
  if (o.fitted_psnr) out.fitted_psnr_db = PsnrAtImages(s, out.coefficients, all);
  out.fit_s = FitSeconds(t0);
  if (o.every <= 0) return out;
  const auto t1 = Clock::now();
  std::vector<int> kept, held;
  for (int l = 0; l < s.lights(); ++l) (l % o.every == 0 ? held : kept).push_back(l);
  if (static_cast<int>(kept.size()) < t.terms) {
    return MakeError(ErrorCode::kInvalidInput, "fit",
                     "{} images left after holding out every {}th cannot determine {} terms", kept.size(),
                     o.every, t.terms);
  }
  const RelightCoefficients fold = Finished(FitRgb(s, t, kept, o.threads, nullptr), t);
  RIG_ASSIGN_OR_RETURN(RelightCoefficients written, AsWritten(fold, o.format));
  out.held_out = static_cast<int>(held.size());
  out.held_out_psnr_db = PsnrAtImages(s, written, held);
  out.held_out_s = FitSeconds(t1);
  return out;
}

}  // namespace rig
