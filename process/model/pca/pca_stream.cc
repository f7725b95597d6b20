// The streamed PCA fit: every image's JPEG decoder open at once, bands of rows read from all of
// them, pass 1 for the sample and the crop the choice needs, pass 2 for the coefficients,
// solved in FitPcaCoefficients' own blocks so that the bytes are the in-memory path's.
#include "process/model/pca/pca_stream.h"

#include <algorithm>
#include <chrono>
#include <cstring>
#include <filesystem>
#include <functional>
#include <memory>
#include <mutex>
#include <thread>

#include <fmt/format.h>
#include <opencv2/imgcodecs.hpp>

#include "process/io/jpeg_io.h"
#include "config/console.h"

namespace rig {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

double PcaSeconds(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

std::string Where(const PcaStreamOptions& s, const LpEntry& e) {
  return s.lp.empty() ? fmt::format("line {}", e.line) : fmt::format("{}:{}", s.lp, e.line);
}

bool IsJpeg(const std::string& path) {
  std::string ext = fs::path(path).extension().string();
  for (auto& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return ext == ".jpg" || ext == ".jpeg";
}

// Runs body(t) for t = 0..threads-1 on its own thread (t = 0 on the caller's).
void OnThreads(int threads, const std::function<void(int)>& body) {
  std::vector<std::thread> pool;
  for (int t = 1; t < threads; ++t) pool.emplace_back(body, t);
  body(0);
  for (auto& th : pool) th.join();
}

// Every image's decoder, open at once, read band by band.
class PcaBandReader {
 public:
  static Result<PcaBandReader> Open(const std::vector<LpEntry>& entries, const PcaStreamOptions& s) {
    PcaBandReader r;
    r.threads_ = std::max(1, s.threads);
    for (const auto& e : entries) {
      const std::string where = Where(s, e);
      if (!IsJpeg(e.image)) {
        return MakeError(ErrorCode::kUnsupported, where,
                         "image '{}': the streamed fit reads JPEG images only", e.image);
      }
      auto reader = JpegReader::Open(e.image);
      if (!reader.ok()) return MakeError(reader.error().code, where, "{}", reader.error().ToString());
      if ((*reader)->channels() != 3) {
        return MakeError(ErrorCode::kInvalidInput, where, "image '{}' has {} channels, 3 needed",
                         e.image, (*reader)->channels());
      }
      if (!r.readers_.empty() && ((*reader)->width() != r.width_ || (*reader)->height() != r.height_)) {
        return MakeError(ErrorCode::kInvalidInput, where,
                         "image '{}' is {}x{}, the first image is {}x{}", e.image,
                         (*reader)->width(), (*reader)->height(), r.width_, r.height_);
      }
      r.width_ = (*reader)->width();
      r.height_ = (*reader)->height();
      r.where_.push_back(where);
      r.readers_.push_back(std::move(*reader));
    }
    r.bands_.resize(r.readers_.size());
    return r;
  }
  int width() const { return width_; }
  int height() const { return height_; }
  // The next `rows` rows of every image: band(l) is rows × width, R, G, B.
  Status Read(int rows) {
    std::mutex mutex;
    Status status = Ok();
    OnThreads(threads_, [&](int t) {
      for (size_t l = static_cast<size_t>(t); l < readers_.size(); l += threads_) {
        Status s = readers_[l]->Read(rows, &bands_[l]);
        if (!s.ok()) {
          std::lock_guard<std::mutex> lock(mutex);
          if (status.ok()) status = MakeError(s.error().code, where_[l], "{}", s.error().ToString());
        }
      }
    });
    return status;
  }
  const uint8_t* band(size_t l) const { return bands_[l].ptr<uint8_t>(); }

 private:
  int width_ = 0, height_ = 0, threads_ = 1;
  std::vector<std::unique_ptr<JpegReader>> readers_;
  std::vector<std::string> where_;
  std::vector<cv::Mat> bands_;
};

// Pixel `local` of the band (all lights) to dst, laid out as LightSamples::values.
void CopyPixel(const PcaBandReader& r, size_t lights, size_t local, uint8_t* dst) {
  for (size_t l = 0; l < lights; ++l) std::memcpy(dst + l * 3, r.band(l) + local * 3, 3);
}

}  // namespace

Result<uint64_t> RtiSampleBytes(const std::vector<LpEntry>& entries, int downsample) {
  if (entries.empty()) return uint64_t{0};
  const LpEntry& e = entries[0];
  int w = 0, h = 0;
  if (IsJpeg(e.image)) {
    RIG_ASSIGN_OR_RETURN(auto r, JpegReader::Open(e.image));
    w = r->width();
    h = r->height();
  } else {
    cv::Mat img;
    try {
      img = cv::imread(e.image, cv::IMREAD_UNCHANGED);
    } catch (const cv::Exception& ex) {
      return MakeError(ErrorCode::kInvalidInput, e.image, "cannot read: {}", ex.what());
    }
    if (img.empty()) return MakeError(ErrorCode::kInvalidInput, e.image, "cannot read");
    w = img.cols;
    h = img.rows;
  }
  downsample = std::max(1, downsample);
  return static_cast<uint64_t>(w / downsample) * static_cast<uint64_t>(h / downsample) *
         entries.size() * 3;
}

namespace {

// Pass 1: the seeded sample of pixels and the central crop, read band by band; the size and
// the bands read into *out.
Result<PcaChoiceInput> GatherChoiceInput(const std::vector<LpEntry>& entries,
                                         const PcaChoiceOptions& options,
                                         const PcaStreamOptions& stream,
                                         const std::vector<Vec3>& directions,
                                         std::vector<size_t>* subset, PcaStreamFit* out) {
  const size_t lights = entries.size(), dim = lights * 3;
  const int band_rows = std::max(1, stream.band_rows);
  PcaChoiceInput in;
  RIG_ASSIGN_OR_RETURN(PcaBandReader reader, PcaBandReader::Open(entries, stream));
  const int w = reader.width(), h = reader.height();
  out->width = w;
  out->height = h;
  const size_t pixels = static_cast<size_t>(w) * h;
  *subset = SamplePixels(pixels, options.base.basis_pixels, options.base.seed);
  const cv::Rect crop = PcaChoiceCrop(w, h);
  in.pixels = pixels;
  in.sampled.width = static_cast<int>(subset->size());
  in.sampled.height = 1;
  in.sampled.directions = directions;
  in.sampled.values.resize(subset->size() * dim);
  in.crop.width = crop.width;
  in.crop.height = crop.height;
  in.crop.directions = directions;
  in.crop.values.resize(in.crop.pixels() * dim);
  size_t next = 0;
  ProgressTask task("reading bands", (h + band_rows - 1) / band_rows);
  for (int y0 = 0; y0 < h; y0 += band_rows) {
    task.Advance(1, fmt::format("rows {}-{}", y0, std::min(h, y0 + band_rows) - 1));
    const int rows = std::min(band_rows, h - y0);
    RIG_TRY(reader.Read(rows));
    ++out->bands;
    const size_t first = static_cast<size_t>(y0) * w, end = first + static_cast<size_t>(rows) * w;
    for (; next < subset->size() && (*subset)[next] < end; ++next)
      CopyPixel(reader, lights, (*subset)[next] - first, in.sampled.values.data() + next * dim);
    for (int y = std::max(y0, crop.y); y < std::min(y0 + rows, crop.y + crop.height); ++y) {
      for (int x = 0; x < crop.width; ++x) {
        const size_t local = static_cast<size_t>(y - y0) * w + crop.x + x;
        const size_t i = static_cast<size_t>(y - crop.y) * crop.width + x;
        CopyPixel(reader, lights, local, in.crop.values.data() + i * dim);
      }
    }
  }
  return in;
}

}  // namespace

// A pixel's coefficients depend on its place in its block (to the last bit), not on the other
// pixels in it: each block holding sampled pixels is solved with them in their places and
// neutral samples (mid-grey, never masked) elsewhere.
std::vector<PlaneQuantisation> PcaSampledQuantisation(
    const PcaCoefficientSolver& solver, const std::vector<std::pair<size_t, size_t>>& blocks,
    const std::vector<size_t>& subset, const LightSamples& sampled, int k, double quantile,
    int threads) {
  const size_t dim = static_cast<size_t>(sampled.lights()) * 3;
  // [first sampled index, end) per block, both in increasing pixel order.
  std::vector<std::pair<size_t, size_t>> spans(blocks.size());
  size_t next = 0;
  for (size_t b = 0; b < blocks.size(); ++b) {
    const size_t first = next, end_pixel = blocks[b].first + blocks[b].second;
    while (next < subset.size() && subset[next] < end_pixel) ++next;
    spans[b] = {first, next};
  }
  Eigen::MatrixXf coefficients(static_cast<Eigen::Index>(subset.size()), k);
  OnThreads(threads, [&](int t) {
    std::vector<uint8_t> fake(2048 * dim, 128);
    Eigen::MatrixXf part;
    size_t ignored = 0;
    for (size_t b = static_cast<size_t>(t); b < blocks.size(); b += threads) {
      const auto [start, count] = blocks[b];
      const auto [lo, hi] = spans[b];
      if (lo == hi) continue;
      if (fake.size() < count * dim) fake.assign(count * dim, 128);
      for (size_t i = lo; i < hi; ++i)
        std::memcpy(fake.data() + (subset[i] - start) * dim, sampled.values.data() + i * dim, dim);
      solver.Solve(fake.data(), count, &part, &ignored, &ignored);
      for (size_t i = lo; i < hi; ++i) {
        coefficients.row(static_cast<Eigen::Index>(i)) =
            part.col(static_cast<Eigen::Index>(subset[i] - start)).transpose();
        std::memset(fake.data() + (subset[i] - start) * dim, 128, dim);
      }
    }
  });
  return PcaQuantisation(coefficients, quantile);
}

namespace {

// The pixels of pass 2 between reading and writing: samples of pixels [pend_start, ...) not
// yet solved; plane bytes of pixels [out_start, solved_end) not yet written (per file, three
// planes interleaved).
struct PlaneRows {
  std::vector<uint8_t> pending;
  size_t pend_start = 0, out_start = 0, solved_end = 0, block_next = 0;
  std::vector<std::vector<uint8_t>> rgb;
  std::vector<size_t> masked, refitted;  // per thread
};

// Solves the blocks that end by pixel `band_end`, quantised into the rows' plane bytes.
void SolveBlocksUpTo(const PcaPlanePass& pp, size_t band_end, int threads, PlaneRows* pr) {
  const size_t dim = pp.directions.size() * 3;
  size_t block_end = pr->block_next;
  while (block_end < pp.blocks.size() &&
         pp.blocks[block_end].first + pp.blocks[block_end].second <= band_end)
    ++block_end;
  if (block_end == pr->block_next) return;
  const size_t new_end = pp.blocks[block_end - 1].first + pp.blocks[block_end - 1].second;
  for (auto& v : pr->rgb) v.resize((new_end - pr->out_start) * 3, 0);
  OnThreads(threads, [&](int t) {
    Eigen::MatrixXf part;
    std::vector<uint8_t> bytes;
    for (size_t b = pr->block_next + t; b < block_end; b += threads) {
      const auto [start, count] = pp.blocks[b];
      pp.solver.Solve(pr->pending.data() + (start - pr->pend_start) * dim, count, &part,
                      &pr->masked[t], &pr->refitted[t]);
      bytes.resize(count);
      for (int p = 0; p < pp.k; ++p) {
        QuantisePcaPlane(part, p, pp.quant[p], bytes.data());
        uint8_t* dst = pr->rgb[p / 3].data() + (start - pr->out_start) * 3 + p % 3;
        for (size_t i = 0; i < count; ++i) dst[i * 3] = bytes[i];
      }
    }
  });
  pr->solved_end = new_end;
  pr->pending.erase(pr->pending.begin(),
                    pr->pending.begin() + static_cast<std::ptrdiff_t>((new_end - pr->pend_start) * dim));
  pr->pend_start = new_end;
  pr->block_next = block_end;
}

}  // namespace

Status WritePcaPlanes(const PcaPlanePass& pp, const PcaBandSource& source,
                      const std::string& out_folder, PcaStreamFit* out) {
  const size_t dim = pp.directions.size() * 3;
  const int band_rows = std::max(1, pp.band_rows);
  const int threads = std::max(1, pp.threads);
  const int w = pp.width, h = pp.height;
  const size_t pixels = static_cast<size_t>(w) * h;
  std::error_code ec;
  fs::create_directories(out_folder, ec);
  if (ec) return MakeError(ErrorCode::kIo, out_folder, "cannot create the folder: {}", ec.message());
  const int files = (pp.k + 2) / 3;
  std::vector<std::unique_ptr<JpegWriter>> writers;
  for (int j = 0; j < files; ++j) {
    RIG_ASSIGN_OR_RETURN(auto wr, JpegWriter::Open(
                                      (fs::path(out_folder) / fmt::format("plane_{}.jpg", j)).string(),
                                      w, h, 3, kPcaPlaneColor, pp.po.jpeg_quality));
    writers.push_back(std::move(wr));
  }
  PlaneRows pr;
  pr.rgb.resize(files);
  pr.masked.assign(threads, 0);
  pr.refitted.assign(threads, 0);
  size_t with_masked = 0;
  LightSamples band;
  band.width = w;
  band.directions = pp.directions;
  for (int y0 = 0; y0 < h; y0 += band_rows) {
    const int rows = std::min(band_rows, h - y0);
    // The band as LightSamples, masked.
    band.height = rows;
    const size_t n = band.pixels();
    band.values.resize(n * dim);
    auto t = Clock::now();
    RIG_TRY(source(y0, rows, &band.values));
    out->source_s += PcaSeconds(t);
    t = Clock::now();
    if (band.values.size() != n * dim) {
      return MakeError(ErrorCode::kInternal, pp.context, "a band of {} values for {} pixels", band.values.size(), n);
    }
    out->masked_samples += MaskLdrSamples(&band, pp.po.thresholds);
    for (size_t p = 0; p < n; ++p) {
      const uint8_t* u = band.usable.data() + p * dim;
      if (std::find(u, u + dim, 0) != u + dim) ++with_masked;
    }
    pr.pending.insert(pr.pending.end(), band.values.begin(), band.values.end());
    SolveBlocksUpTo(pp, static_cast<size_t>(y0 + rows) * w, threads, &pr);
    out->solve_s += PcaSeconds(t);
    t = Clock::now();
    // Whole rows solved: to the files, each file's encoder on one of the threads (the files
    // are independent, so their bytes do not depend on it).
    const int full_rows = static_cast<int>((pr.solved_end - pr.out_start) / w);
    if (full_rows > 0) {
      const size_t used = static_cast<size_t>(full_rows) * w * 3;
      std::vector<Status> written(files, Ok());
      OnThreads(std::min(threads, files), [&](int th) {
        for (int j = th; j < files; j += std::min(threads, files)) {
          written[j] = writers[j]->Write(cv::Mat(full_rows, w, CV_8UC3, pr.rgb[j].data()));
          pr.rgb[j].erase(pr.rgb[j].begin(), pr.rgb[j].begin() + static_cast<std::ptrdiff_t>(used));
        }
      });
      for (const Status& st : written) RIG_TRY(st);
      pr.out_start += static_cast<size_t>(full_rows) * w;
    }
    out->encode_s += PcaSeconds(t);
  }
  if (pr.out_start != pixels || pr.block_next != pp.blocks.size()) {
    return MakeError(ErrorCode::kInternal, pp.context, "{} of {} pixels written", pr.out_start,
                     pixels);
  }
  const auto t_finish = Clock::now();
  std::vector<Status> finished(files, Ok());
  OnThreads(std::min(threads, files), [&](int th) {
    for (int j = th; j < files; j += std::min(threads, files)) finished[j] = writers[j]->Finish();
  });
  for (const Status& st : finished) RIG_TRY(st);
  out->encode_s += PcaSeconds(t_finish);
  for (int t = 0; t < threads; ++t) {
    out->stats.masked_samples += pr.masked[t];
    out->stats.refitted_pixels += pr.refitted[t];
  }
  out->masked_fraction = static_cast<double>(out->masked_samples) /
                         static_cast<double>(std::max<size_t>(1, pixels * dim));
  out->pixels_with_masked =
      static_cast<double>(with_masked) / static_cast<double>(std::max<size_t>(1, pixels));
  return Ok();
}

Result<PcaStreamFit> FitPcaStreaming(const std::vector<LpEntry>& entries,
                                     const PcaChoiceOptions& options,
                                     const std::string& out_folder,
                                     const PcaStreamOptions& stream) {
  const auto t0 = Clock::now();
  const std::string context = stream.lp.empty() ? std::string("pca stream") : stream.lp;
  if (entries.size() < 4) {
    return MakeError(ErrorCode::kInvalidInput, context, "{} images: at least 4 needed",
                     entries.size());
  }
  std::vector<Vec3> directions;
  for (const auto& e : entries) {
    if (!(e.direction[2] > 0)) {
      return MakeError(ErrorCode::kInvalidInput, Where(stream, e),
                       "light at or below the horizon (z <= 0); the pca model covers the upper "
                       "hemisphere only — remove it, or fit sh or ptm");
    }
    directions.push_back(e.direction);
  }
  PcaStreamFit out;
  out.lights = static_cast<int>(entries.size());
  std::vector<size_t> subset;
  RIG_ASSIGN_OR_RETURN(PcaChoiceInput in,
                       GatherChoiceInput(entries, options, stream, directions, &subset, &out));
  out.gather_s = PcaSeconds(t0);

  // The choice and the basis, exactly as FitPcaAuto makes them from the whole samples.
  const auto t1 = Clock::now();
  const size_t pixels = in.pixels;
  RIG_ASSIGN_OR_RETURN(PcaComponents comps,
                       ComputePcaComponentsOfSample(in.sampled, subset, LargestCandidate(options), options.base));
  RIG_ASSIGN_OR_RETURN(out.choice, ChoosePca(in, comps, options));
  in.crop = LightSamples();
  const PcaOptions& po = out.choice.options;
  RIG_ASSIGN_OR_RETURN(PcaBasis basis,
                       FitPcaBasis(comps, po.components, po.grid_resolution, po.smoothness));
  const int k = basis.components;
  const PcaCoefficientSolver solver(basis, directions, po);
  const auto blocks = PcaCoefficientBlocks(pixels, po.threads);
  const std::vector<PlaneQuantisation> quant = PcaSampledQuantisation(
      solver, blocks, subset, in.sampled, k, po.quantile, std::max(1, stream.threads));
  in.sampled = LightSamples();
  out.choice_s = PcaSeconds(t1);

  const auto t2 = Clock::now();
  RIG_ASSIGN_OR_RETURN(PcaBandReader reader, PcaBandReader::Open(entries, stream));
  if (static_cast<size_t>(reader.width()) * reader.height() != pixels) {
    return MakeError(ErrorCode::kInvalidInput, context, "the images changed between the passes");
  }
  const size_t lights = entries.size(), dim = lights * 3;
  const int threads = std::max(1, stream.threads);
  const PcaPlanePass pp{directions, po, solver, blocks, quant, k, out.width, out.height,
                        stream.band_rows, threads, context};
  RIG_TRY(WritePcaPlanes(pp, [&](int, int rows, std::vector<uint8_t>* values) -> Status {
    RIG_TRY(reader.Read(rows));
    const size_t n = static_cast<size_t>(rows) * reader.width();
    OnThreads(threads, [&](int t) {
      const size_t lo = n * t / threads, hi = n * (t + 1) / threads;
      for (size_t p = lo; p < hi; ++p) CopyPixel(reader, lights, p, values->data() + p * dim);
    });
    return Ok();
  }, out_folder, &out));
  RIG_TRY(WritePcaInfo(out_folder, out.width, out.height, basis, quant, directions,
                       po.jpeg_quality));
  out.write_s = PcaSeconds(t2);
  out.stats.time_s = PcaSeconds(t0);
  return out;
}

}  // namespace rig
