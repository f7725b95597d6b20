// The session's PCA model from bands of its radiance maps.
#include "process/model/session/pca_session.h"

#include <algorithm>
#include <chrono>
#include <cstring>
#include <exception>
#include <thread>

#include <fmt/format.h>

#include "config/console.h"
#include "config/log.h"

namespace rig {
namespace {

using Clock = std::chrono::steady_clock;

double Since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

// Rows [y0, y1) of every map; OpenEXR's exceptions (a file source) as an error naming the rows.
Status ReadRows(MapBands& maps, int y0, int y1, std::vector<cv::Mat>* bgr) {
  std::vector<cv::Mat> valid;
  try {
    return maps.Read(y0, y1, bgr, &valid);
  } catch (const std::exception& e) {
    return MakeError(ErrorCode::kIo, fmt::format("radiance maps rows {}-{}", y0, y1 - 1),
                     "cannot read: {}", e.what());
  }
}

// Pass 2 over rows [y0, y1) of one band: the curve's sample-channels and the sampled pixels'
// radiance (from subset index *next on; *next advanced past the rows).
Status GatherRows(MapBands& maps, const std::vector<size_t>& subset, int y0, int y1,
                  std::vector<cv::Mat>* bgr, HdrCurveSampler* sampler, size_t* next,
                  std::vector<float>* sampled) {
  const size_t w = static_cast<size_t>(maps.width()), lights = maps.count();
  RIG_TRY(ReadRows(maps, y0, y1, bgr));
  const size_t first = static_cast<size_t>(y0) * w, end = static_cast<size_t>(y1) * w;
  for (size_t l = 0; l < lights; ++l) sampler->Add(l, first, (*bgr)[l]);
  for (; *next < subset.size() && subset[*next] < end; ++*next)
    for (size_t l = 0; l < lights; ++l)
      std::memcpy(sampled->data() + (*next * lights + l) * 3,
                  (*bgr)[l].ptr<float>() + (subset[*next] - first) * 3, 3 * sizeof(float));
  return Ok();
}

// Pass 2: the curve's sample-channels of every map and the radiance of the components' sampled
// pixels (subset.size() × lights × BGR floats, in subset order). Maps that may be read from
// several threads at once are read in `threads` slices of rows, each with its own sampler,
// merged at the end (the curve's quantiles do not depend on the order of the values).
Status GatherSample(MapBands& maps, const std::vector<size_t>& subset, int band_rows, int threads,
                    const std::array<double, 3>& lamp, HdrCurveSampler* sampler,
                    std::vector<float>* sampled) {
  const int h = maps.height();
  const size_t pixels = static_cast<size_t>(maps.width()) * h;
  sampled->assign(subset.size() * maps.count() * 3, 0.0f);
  const int slices = maps.concurrent() ? std::max(1, std::min(threads, h)) : 1;
  std::vector<HdrCurveSampler> part(static_cast<size_t>(slices - 1),
                                    HdrCurveSampler(maps.count(), pixels, lamp));
  std::vector<Status> status(static_cast<size_t>(slices), Ok());
  auto slice = [&](int t) {
    const int a = h * t / slices, b = h * (t + 1) / slices;
    HdrCurveSampler* s = t == 0 ? sampler : &part[t - 1];
    size_t next = static_cast<size_t>(
        std::lower_bound(subset.begin(), subset.end(), static_cast<size_t>(a) * maps.width()) -
        subset.begin());
    std::vector<cv::Mat> bgr;
    for (int y0 = a; y0 < b && status[t].ok(); y0 += band_rows)
      status[t] = GatherRows(maps, subset, y0, std::min(b, y0 + band_rows), &bgr, s, &next, sampled);
  };
  std::vector<std::thread> pool;
  for (int t = 1; t < slices; ++t) pool.emplace_back(slice, t);
  slice(0);
  for (auto& th : pool) th.join();
  for (const Status& st : status) RIG_TRY(st);
  for (const auto& p : part) sampler->Merge(p);
  return Ok();
}

// The sampled pixels' codes, as SamplesFromMaps would make them (R, G, B from B, G, R).
LightSamples SampledCodes(const std::vector<float>& sampled, size_t count,
                          const std::vector<Vec3>& directions, const std::array<double, 3>& lamp,
                          const HdrCodeCurve& curve) {
  LightSamples s;
  s.width = static_cast<int>(count);
  s.height = 1;
  s.directions = directions;
  s.values.resize(sampled.size());
  // By table: HdrCode's own codes (HdrCodeTable), without a power per sample.
  const std::array<HdrCodeTable, 3> code = {HdrCodeTable(curve, lamp[0]), HdrCodeTable(curve, lamp[1]),
                                            HdrCodeTable(curve, lamp[2])};
  for (size_t i = 0; i < sampled.size(); i += 3)
    for (int c = 0; c < 3; ++c) s.values[i + c] = code[c](sampled[i + (2 - c)]);
  return s;
}

// A band's codes, laid out as LightSamples::values. A source that may be read from several
// threads at once (the maps in memory) is read and coded in row slices, one per thread, each
// slice's codes in its place (pixel-major, so the slices are contiguous); otherwise read once
// and coded on the threads by map. The codes are the same either way.
class BandCoder {
 public:
  BandCoder(MapBands& maps, const std::vector<Vec3>& directions, const std::array<double, 3>& lamp,
            const HdrCodeCurve& curve, int threads)
      : maps_(maps), directions_(directions), lamp_(lamp), curve_(curve),
        threads_(std::max(1, threads)), bgr_(static_cast<size_t>(threads_)) {}

  Status Codes(int y0, int rows, std::vector<uint8_t>* values) {
    const int slices = maps_.concurrent() ? std::min(threads_, rows) : 1;
    if (slices == 1) {
      RIG_TRY(ReadRows(maps_, y0, y0 + rows, &bgr_[0]));
      *values = SamplesFromMaps(bgr_[0], directions_, lamp_, curve_, threads_).values;
      return Ok();
    }
    const size_t per_row = static_cast<size_t>(maps_.width()) * maps_.count() * 3;
    values->resize(per_row * static_cast<size_t>(rows));
    std::vector<Status> status(static_cast<size_t>(slices), Ok());
    auto slice = [&](int t) {
      const int a = y0 + rows * t / slices, b = y0 + rows * (t + 1) / slices;
      status[t] = ReadRows(maps_, a, b, &bgr_[t]);
      if (!status[t].ok()) return;
      const LightSamples s = SamplesFromMaps(bgr_[t], directions_, lamp_, curve_, 1);
      std::memcpy(values->data() + per_row * static_cast<size_t>(a - y0), s.values.data(), s.values.size());
    };
    std::vector<std::thread> pool;
    for (int t = 1; t < slices; ++t) pool.emplace_back(slice, t);
    slice(0);
    for (auto& th : pool) th.join();
    for (const Status& st : status) RIG_TRY(st);
    return Ok();
  }

 private:
  MapBands& maps_;
  const std::vector<Vec3>& directions_;
  const std::array<double, 3>& lamp_;
  const HdrCodeCurve& curve_;
  int threads_;
  std::vector<std::vector<cv::Mat>> bgr_;  // per slice, reused
};

}  // namespace

cv::Rect PcaHdrChoiceRegion(int width, int height) {
  const int w = std::min(width, kPcaHdrChoiceSide), h = std::min(height, kPcaHdrChoiceSide);
  return {(width - w) / 2, (height - h) / 2, w, h};
}

Result<std::vector<cv::Mat>> ReadChoiceRegion(MapBands& maps) {
  const cv::Rect r = PcaHdrChoiceRegion(maps.width(), maps.height());
  std::vector<cv::Mat> rows, region;
  RIG_TRY(ReadRows(maps, r.y, r.y + r.height, &rows));
  for (auto& m : rows) region.push_back(m(cv::Rect(r.x, 0, r.width, r.height)).clone());
  return region;
}

Result<PcaSessionFit> FitPcaHdrFromBands(MapBands& maps, const std::vector<Vec3>& directions,
                                         const std::array<double, 3>& lamp,
                                         const LightFrameConfig& light_frame,
                                         const PcaHdrChoiceOptions& o,
                                         const std::string& out_folder, int band_rows,
                                         const PcaHdrFit* choice) {
  const auto t0 = Clock::now();
  band_rows = std::max(1, band_rows);
  if (maps.count() != directions.size()) {
    return MakeError(ErrorCode::kInvalidInput, "pca", "{} maps for {} directions", maps.count(),
                     directions.size());
  }
  PcaSessionFit out;
  out.width = maps.width();
  out.height = maps.height();
  const size_t pixels = static_cast<size_t>(out.width) * out.height;
  // The bar counts rows: the choice's region once, every row for the sample, every row for the
  // planes.
  const cv::Rect choice_rect = PcaHdrChoiceRegion(out.width, out.height);
  ProgressTask task("fitting the model", (choice ? 0 : choice_rect.height) + 2 * int64_t{out.height});
  // 1. The choice, on the central region's maps.
  out.choice_region = PcaHdrChoiceRegion(out.width, out.height);
  const cv::Rect& r = out.choice_region;
  if (choice) {
    out.choice = *choice;
  } else {
    RIG_ASSIGN_OR_RETURN(std::vector<cv::Mat> region, ReadChoiceRegion(maps));
    RIG_ASSIGN_OR_RETURN(out.choice, ChoosePcaHdr(region, directions, lamp, o));
    task.Advance(r.height, "the choice");
  }
  out.choice_s = Since(t0);
  // 2. The curve from every map, the components from the sampled pixels.
  const auto t1 = Clock::now();
  const PcaOptions& po = out.choice.options;
  const std::vector<size_t> subset = SamplePixels(pixels, po.basis_pixels, po.seed);
  HdrCurveSampler sampler(maps.count(), pixels, lamp);
  std::vector<float> sampled_radiance;
  RIG_TRY(GatherSample(maps, subset, band_rows, o.threads, lamp, &sampler, &sampled_radiance));
  task.Advance(out.height, "the sample");
  out.curve = sampler.Curve(PcaHdrCurveOptions(out.choice.curve, o.high));
  const LightSamples sampled = SampledCodes(sampled_radiance, subset.size(), directions, lamp, out.curve);
  sampled_radiance = {};
  RIG_ASSIGN_OR_RETURN(PcaComponents comps,
                       ComputePcaComponentsOfSample(sampled, subset, po.components, po));
  const int k = std::min<int>(po.components, static_cast<int>(comps.vectors.cols()));
  RIG_ASSIGN_OR_RETURN(PcaBasis basis, FitPcaBasis(comps, k, po.grid_resolution, po.smoothness));
  out.components = basis.components;
  const PcaCoefficientSolver solver(basis, directions, po);
  const auto blocks = PcaCoefficientBlocks(pixels, po.threads);
  const int threads = std::max(1, o.threads);
  const std::vector<PlaneQuantisation> quant =
      PcaSampledQuantisation(solver, blocks, subset, sampled, basis.components, po.quantile, threads);
  out.gather_s = Since(t1);
  // 3. Every pixel's codes, solved and written.
  const auto t2 = Clock::now();
  const PcaPlanePass pass{directions, po, solver, blocks, quant, basis.components,
                          out.width,  out.height, band_rows, threads, "pca of radiance maps"};
  BandCoder coder(maps, directions, lamp, out.curve, threads);
  RIG_TRY(WritePcaPlanes(pass, [&](int y0, int rows, std::vector<uint8_t>* values) -> Status {
    RIG_TRY(coder.Codes(y0, rows, values));
    task.Advance(rows, "the planes");
    return Ok();
  }, out_folder, &out.planes));
  RIG_TRY(WritePcaInfo(out_folder, out.width, out.height, basis, quant, directions, po.jpeg_quality,
                       "", PcaHdrValues{out.curve, lamp, light_frame}));
  out.write_s = Since(t2);
  out.time_s = Since(t0);
  Log("process")->info("pca of radiance maps: {} (choice {:.2f} s on {}x{}, sample {:.2f} s, "
                       "planes {:.2f} s: codes {:.2f}, solve {:.2f}, JPEG {:.2f})",
                       out.choice.reason, out.choice_s, r.width, r.height, out.gather_s,
                       out.write_s, out.planes.source_s, out.planes.solve_s, out.planes.encode_s);
  return out;
}

}  // namespace rig
