// Golden test of Ward's histogram adjustment against an independent reference: a plain,
// straightforward re-implementation of Radiance's pcond (src/px/pcond.c getahead/getfovimg,
// pcond3.c comphist/mkcumf/mkbrmap/BLw/putmapping), written here from a reading of that
// source and sharing no code with process/render/tonemap.cc. Its foveal image is a box filter
// over pixel centres (pfilt -b), ours cv::resize INTER_AREA; the random single-pixel samples
// are the same pixels (Floyd's algorithm over std::mt19937_64, re-implemented below). The
// curve is compared as pcond -x writes it: display luminance at the centre of every bin.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <random>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>

#include "process/io/exr_io.h"
#include "process/render/tonemap.h"

namespace rig {
namespace {

namespace fs = std::filesystem;

fs::path SharedDir() {
  if (const char* d = std::getenv("RIG_SHARED_DIR")) return d;
  if (const char* d = std::getenv("RIG_SOURCE_DIR")) return fs::path(d) / ".." / "shared";
  return "../shared";
}

struct Curve {
  std::vector<double> world, display;  // cd/m² pairs at the bin centres (pcond -x)
  bool linear = false;
};

// ---- the reference -------------------------------------------------------------------------

Curve ReferencePcond(const cv::Mat& rgb, double fov_deg, double ld_min, double ld_max,
                     uint64_t seed) {
  const int w = rgb.cols, h = rgb.rows, bins = 100;
  std::vector<double> lum(static_cast<size_t>(w) * h);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const cv::Vec3f p = rgb.at<cv::Vec3f>(y, x);  // B, G, R
      lum[static_cast<size_t>(y) * w + x] = 0.0722 * p[0] + 0.7152 * p[1] + 0.2126 * p[2];
    }
  // getahead: 40° on the larger side; the other by tan; getfovimg: sqrt(hn2)/FOVDIA + .5.
  const double t = std::tan(fov_deg / 2 * M_PI / 180);
  double hspan, vspan;
  if (h < w) {
    hspan = 2 * t;
    vspan = 2 * t * h / w;
  } else {
    vspan = 2 * t;
    hspan = 2 * t * w / h;
  }
  int fx = std::max(2, static_cast<int>(hspan / (M_PI / 180) + 0.5));
  int fy = std::max(2, static_cast<int>(vspan / (M_PI / 180) + 0.5));
  std::vector<double> fov;
  for (int j = 0; j < fy; ++j)
    for (int i = 0; i < fx; ++i) {
      const int x0 = i * w / fx, x1 = (i + 1) * w / fx, y0 = j * h / fy, y1 = (j + 1) * h / fy;
      double s = 0;
      for (int y = y0; y < y1; ++y)
        for (int x = x0; x < x1; ++x) s += lum[static_cast<size_t>(y) * w + x];
      fov.push_back(s / ((x1 - x0) * (y1 - y0)));
    }
  // comphist: 16 point samples per foveal sample, distinct pixels.
  const long long npix = static_cast<long long>(w) * h;
  long long n = std::min<long long>(static_cast<long long>(fov.size()) * 16, npix);
  std::vector<double> pts;
  std::vector<char> used(static_cast<size_t>(npix), 0);
  std::mt19937_64 gen(seed);
  for (long long j = npix - n; j < npix; ++j) {
    long long k = static_cast<long long>(gen() % static_cast<unsigned long long>(j + 1));
    if (used[k]) k = j;
    used[k] = 1;
    pts.push_back(lum[static_cast<size_t>(k)]);
  }
  double lwmin = 1e300, lwmax = 0;
  // Black pixels are left out (pcond would clamp them to its absolute 1e-7 cd/m²; our
  // radiance is relative, so both implementations ignore them).
  for (double l : fov)
    if (l > 0) lwmin = std::min(lwmin, l), lwmax = std::max(lwmax, l);
  for (double l : pts)
    if (l > 0) lwmin = std::min(lwmin, l), lwmax = std::max(lwmax, l);
  lwmax *= 1.01;
  const double bwmax = std::log(lwmax);
  const double bwmin = bwmax - (bwmax - std::log(lwmin)) * bins / (bins - 1);
  lwmin = std::exp(bwmin);
  std::vector<double> hist(bins, 0.0);
  double histot = 0, bwavg = 0;
  auto add = [&](double l, double wt) {
    if (l <= lwmin || l >= lwmax) return;
    const double b = std::log(l);
    hist[static_cast<int>(bins * (b - bwmin) / (bwmax - bwmin))] += wt;
    histot += wt;
    bwavg += wt * b;
  };
  for (double l : fov) add(l, 1);
  const double wpt = histot / static_cast<double>(n);
  for (double l : pts) add(l, wpt);
  bwavg /= histot;
  hist[1] *= 0.5;
  hist[0] += hist[1];
  const double bldmin = std::log(ld_min), bldmax = std::log(ld_max), s = (bwmax - bwmin) / bins;
  Curve c;
  std::vector<double> cumf(bins + 1);
  bool linear = bwmax - bwmin <= bldmax - bldmin;  // check2do
  if (!linear) {
    std::vector<double> mod = hist;
    double trimmings;
    do {
      double mtot = 0;
      for (double v : mod) mtot += v;
      double sum = 0;
      for (int i = 0; i < bins; ++i) {
        cumf[i] = sum / mtot;
        sum += mod[i];
      }
      cumf[bins] = 1;
      if (mtot <= histot * 0.025) {
        linear = true;
        break;
      }
      const double ceiling = mtot * s / (bldmax - bldmin);
      trimmings = 0;
      for (double& v : mod)
        if (v > ceiling) trimmings += v - ceiling, v = ceiling;
      if (!(trimmings > mtot * 0.025)) break;
    } while (true);
  }
  c.linear = linear;
  const double scalef = std::exp(0.5 * (bldmax + bldmin)) / std::exp(bwavg);
  for (int i = 0; i < bins; ++i) {
    const double b = bwmin + (i + 0.5) * s;
    double bd;
    if (linear) {
      bd = std::log(scalef * std::exp(b));
    } else if (b <= bwmin + 1e-6) {
      bd = bldmin;
    } else if (b >= bwmax - 1e-6) {
      bd = bldmax;
    } else {
      const double x = bins * (b - bwmin) / (bwmax - bwmin);
      const int k = static_cast<int>(x);
      bd = bldmin + (cumf[k] * (1 - (x - k)) + cumf[k + 1] * (x - k)) * (bldmax - bldmin);
    }
    c.world.push_back(std::exp(b));
    c.display.push_back(std::exp(bd));
  }
  return c;
}

// ---- the comparison --------------------------------------------------------------------------

cv::Mat Read(const fs::path& path) {
  if (path.extension() == ".exr") {
    auto r = ReadRgbExr(path.string());
    return r.ok() ? *r : cv::Mat();
  }
  return cv::imread(path.string(), cv::IMREAD_ANYDEPTH | cv::IMREAD_COLOR);
}

struct Difference {
  double rms_stops = 0, max_stops = 0;
};

Difference Compare(const WardMapping& m, const Curve& ref) {
  Difference d;
  double sum = 0;
  for (size_t i = 0; i < ref.world.size(); ++i) {
    const double e = std::log2(m.DisplayLuminance(ref.world[i]) / ref.display[i]);
    sum += e * e;
    d.max_stops = std::max(d.max_stops, std::abs(e));
  }
  d.rms_stops = std::sqrt(sum / ref.world.size());
  return d;
}

class WardGolden : public ::testing::TestWithParam<const char*> {};

TEST_P(WardGolden, DefaultCurveMatchesAnIndependentPcondWithinFiveHundredthsOfAStopRms) {
  const fs::path path = SharedDir() / "data" / "hdr" / GetParam();
  if (!fs::exists(path)) GTEST_SKIP() << path << " is not there";
  const cv::Mat rgb = Read(path);
  ASSERT_EQ(rgb.type(), CV_32FC3);
  const ToneMapOptions pcond;  // the default: WardVariant::kPcond, 40°, 1 … 100 cd/m²
  ASSERT_EQ(pcond.ward_variant, WardVariant::kPcond);
  const Curve ref = ReferencePcond(rgb, pcond.field_of_view_deg, pcond.display_min_cd_m2,
                                   pcond.display_max_cd_m2, pcond.ward_seed);
  ASSERT_FALSE(ref.linear);
  ToneMapReport report;
  const WardMapping ours = ComputeWardMappingForImage(rgb, pcond, &report);
  ASSERT_FALSE(ours.linear);
  const Difference d = Compare(ours, ref);
  ToneMapOptions paper;
  paper.ward_variant = WardVariant::kPaper;
  const Difference dp = Compare(ComputeWardMappingForImage(rgb, paper), ref);
  std::printf("%s: pcond variant vs reference %.4f stops RMS, %.4f max; paper variant %.4f RMS, "
              "%.4f max (foveal %dx%d, %d point samples)\n",
              GetParam(), d.rms_stops, d.max_stops, dp.rms_stops, dp.max_stops,
              report.foveal_width, report.foveal_height, report.point_samples);
  // What the default picture gained: mean 8-bit green code, pcond against paper (sRGB).
  ToneMapOptions pcond_srgb = pcond, paper_srgb = paper;
  pcond_srgb.srgb = paper_srgb.srgb = true;
  auto pic_pcond = ToneMap(rgb, pcond_srgb), pic_paper = ToneMap(rgb, paper_srgb);
  ASSERT_TRUE(pic_pcond.ok() && pic_paper.ok());
  cv::Mat diff;
  cv::absdiff(*pic_pcond, *pic_paper, diff);
  std::printf("%s: 8-bit sRGB picture, pcond mean %.1f, paper mean %.1f, mean |difference| %.2f "
              "codes\n",
              GetParam(), cv::mean(*pic_pcond)[1], cv::mean(*pic_paper)[1], cv::mean(diff)[1]);
  RecordProperty("rms_stops", std::to_string(d.rms_stops));
  RecordProperty("max_stops", std::to_string(d.max_stops));
  EXPECT_LT(d.rms_stops, 0.05);
  EXPECT_LT(d.max_stops, 0.15);
  // The reference would catch the paper's variant: it is measurably off.
  EXPECT_GT(dp.rms_stops, 2 * d.rms_stops);
}

INSTANTIATE_TEST_SUITE_P(SharedData, WardGolden, ::testing::Values("mpi_atrium_3.hdr", "Desk.exr"));

}  // namespace
}  // namespace rig
