// Band-streamed model fit: OpenEXR scanline ranges in, the shared matrix, bands out.
#include "process/model/session/model_stream.h"
#include "process/io/exr_ostream.h"

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <filesystem>
#include <condition_variable>
#include <map>
#include <memory>
#include <mutex>
#include <thread>

#include <Iex.h>
#include <ImfChannelList.h>
#include <ImfFrameBuffer.h>
#include <ImfHeader.h>
#include <ImfInputFile.h>
#include <ImfOutputFile.h>
#include <ImfStringAttribute.h>

#include "config/log.h"
#include "process/model/harmonic/model.h"
#include "config/console.h"

namespace rig {
namespace {

// The maps, open, read band by band into CV_32FC3 BGR and CV_8U validity.
class BandReader : public MapBands {
 public:
  Status Open(const std::vector<std::string>& paths) {
    for (const auto& p : paths) {
      if (!std::filesystem::exists(p)) return MakeError(ErrorCode::kNotFound, p, "no such file");
      auto f = std::make_unique<Imf::InputFile>(p.c_str(), 1);
      const Imath::Box2i dw = f->header().dataWindow();
      const int w = dw.max.x - dw.min.x + 1, h = dw.max.y - dw.min.y + 1;
      if (files_.empty()) {
        width_ = w;
        height_ = h;
      } else if (w != width_ || h != height_) {
        return MakeError(ErrorCode::kInvalidInput, p, "size {}x{} differs from {} ({}x{})", w, h,
                         paths[0], width_, height_);
      }
      for (const char* c : {"R", "G", "B"}) {
        if (!f->header().channels().findChannel(c)) {
          return MakeError(ErrorCode::kInvalidInput, p, "no '{}' channel", c);
        }
      }
      has_flags_.push_back(f->header().channels().findChannel("flags") != nullptr);
      origin_.push_back({dw.min.x, dw.min.y});
      files_.push_back(std::move(f));
    }
    return Ok();
  }
  int width() const override { return width_; }
  int height() const override { return height_; }
  size_t count() const override { return files_.size(); }
  bool any_flags() const override {
    return std::any_of(has_flags_.begin(), has_flags_.end(), [](bool b) { return b; });
  }
  // One InputFile per map, read from one thread at a time.
  bool concurrent() const override { return false; }

  // Rows [y0, y1) of every map.
  Status Read(int y0, int y1, std::vector<cv::Mat>* bgr, std::vector<cv::Mat>* valid) override {
    const int rows = y1 - y0;
    bgr->resize(files_.size());
    valid->resize(any_flags() ? files_.size() : 0);
    for (size_t i = 0; i < files_.size(); ++i) {
      cv::Mat& m = (*bgr)[i];
      m.create(rows, width_, CV_32FC3);
      const size_t xs = 3 * sizeof(float), ys = xs * width_;
      const auto [ox, oy] = origin_[i];
      char* base = reinterpret_cast<char*>(m.data) - static_cast<ptrdiff_t>(ox) * xs -
                   static_cast<ptrdiff_t>(oy + y0) * static_cast<ptrdiff_t>(ys);
      Imf::FrameBuffer fb;
      fb.insert("B", Imf::Slice(Imf::FLOAT, base, xs, ys));
      fb.insert("G", Imf::Slice(Imf::FLOAT, base + sizeof(float), xs, ys));
      fb.insert("R", Imf::Slice(Imf::FLOAT, base + 2 * sizeof(float), xs, ys));
      cv::Mat flags;
      if (has_flags_[i]) {
        flags.create(rows, width_, CV_32F);
        char* fbase = reinterpret_cast<char*>(flags.data) -
                      static_cast<ptrdiff_t>(ox) * sizeof(float) -
                      static_cast<ptrdiff_t>(oy + y0) * width_ * sizeof(float);
        fb.insert("flags", Imf::Slice(Imf::FLOAT, fbase, sizeof(float), sizeof(float) * width_));
      }
      files_[i]->setFrameBuffer(fb);
      files_[i]->readPixels(oy + y0, oy + y1 - 1);
      if (!valid->empty()) {
        (*valid)[i] = has_flags_[i] ? cv::Mat((flags == 0) / 255)
                                    : cv::Mat(rows, width_, CV_8U, cv::Scalar(1));
      }
    }
    return Ok();
  }

 private:
  std::vector<std::unique_ptr<Imf::InputFile>> files_;
  std::vector<bool> has_flags_;
  std::vector<std::pair<int, int>> origin_;
  int width_ = 0, height_ = 0;
};

}  // namespace

Result<size_t> EstimateSampleBytes(const std::vector<std::string>& paths) {
  size_t total = 0;
  for (const auto& p : paths) {
    try {
      if (!std::filesystem::exists(p)) return MakeError(ErrorCode::kNotFound, p, "no such file");
      Imf::InputFile f(p.c_str(), 1);
      const Imath::Box2i dw = f.header().dataWindow();
      total += static_cast<size_t>(dw.max.x - dw.min.x + 1) * (dw.max.y - dw.min.y + 1) * 12;
    } catch (const std::exception& e) {
      return MakeError(ErrorCode::kCorrupt, p, "cannot read EXR header: {}", e.what());
    }
  }
  return total;
}

Result<std::unique_ptr<MapBands>> OpenMapFiles(const std::vector<std::string>& paths) {
  auto reader = std::make_unique<BandReader>();
  try {
    RIG_TRY(reader->Open(paths));
  } catch (const std::exception& e) {
    return MakeError(ErrorCode::kCorrupt, paths.empty() ? std::string("maps") : paths[0],
                     "cannot open the radiance maps: {}", e.what());
  }
  return std::unique_ptr<MapBands>(std::move(reader));
}

Result<std::vector<cv::Mat>> ReadPatches(MapBands& maps, const std::array<int, 4>& patch_px) {
  const cv::Rect r(patch_px[0], patch_px[1], patch_px[2], patch_px[3]);
  if (r.width <= 0 || r.height <= 0 || (r & cv::Rect(0, 0, maps.width(), maps.height())) != r) {
    return MakeError(ErrorCode::kInvalidInput, "process.reference_patch_px",
                     "the patch {}x{}+{}+{} is outside the {}x{} image", r.width, r.height, r.x,
                     r.y, maps.width(), maps.height());
  }
  std::vector<cv::Mat> bgr, valid, crops;
  try {
    RIG_TRY(maps.Read(r.y, r.y + r.height, &bgr, &valid));
  } catch (const std::exception& e) {
    return MakeError(ErrorCode::kCorrupt, "radiance maps", "cannot read the patch: {}", e.what());
  }
  for (const cv::Mat& m : bgr) crops.push_back(m(cv::Rect(r.x, 0, r.width, r.height)).clone());
  return crops;
}

Result<std::array<double, 3>> LampRadianceFromPatch(MapBands& maps, const std::array<int, 4>& patch,
                                                    double reflectance, const NearLamp& lamp,
                                                    const std::vector<Vec3>& directions) {
  RIG_ASSIGN_OR_RETURN(std::vector<cv::Mat> crops, ReadPatches(maps, patch));
  DivideByFalloff(lamp, directions, patch[0], patch[1], maps.width(), maps.height(), &crops);
  return CalibrateLampRadiance(crops, {0, 0, patch[2], patch[3]}, reflectance);
}

Status MapBands::ReadSamples(int y0, int y1, const SampleSpace& space,
                             const std::vector<Vec3>& directions, std::vector<cv::Mat>* bgr,
                             std::vector<cv::Mat>* valid, SampleMatrix* samples,
                             std::vector<uint8_t>* missing) {
  RIG_TRY(Read(y0, y1, bgr, valid));
  DivideByFalloff(space.lamp, directions, 0, y0, width(), height(), bgr);
  return BuildSamples(*bgr, *valid, space.lamp_radiance_rgb, space.transform, samples, missing);
}

void DivideByFalloff(const NearLamp& lamp, const std::vector<Vec3>& dirs, int x0, int y0,
                     int width, int height, std::vector<cv::Mat>* bgr) {
  if (!lamp.near()) return;
  for (size_t i = 0; i < bgr->size() && i < dirs.size(); ++i) {
    cv::Mat& m = (*bgr)[i];
    for (int r = 0; r < m.rows; ++r) {
      float* p = m.ptr<float>(r);
      for (int x = 0; x < m.cols; ++x) {
        const float f =
            static_cast<float>(lamp.InverseFalloff(x0 + x, y0 + r, width, height, dirs[i]));
        p[3 * x] *= f;
        p[3 * x + 1] *= f;
        p[3 * x + 2] *= f;
      }
    }
  }
}

Result<StreamFitOutput> FitModelStreaming(const StreamFitInput& in, const FitOptions& o,
                                          const std::string& out_path, ExrPixelType type) {
  const size_t n = in.paths.size();
  if (n == 0 || in.directions.size() != n) {
    return MakeError(ErrorCode::kInvalidInput, "fit", "{} maps, {} directions", n,
                     in.directions.size());
  }
  RIG_ASSIGN_OR_RETURN(std::unique_ptr<MapBands> maps, OpenMapFiles(in.paths));
  return FitModelFromBands(*maps, in, o, out_path, type);
}

namespace {

// One band's coefficients in the file's pixel type, computed by a worker for the writer.
struct FittedBand {
  int y0 = 0, rows = 0;
  double samples_s = 0, project_s = 0;  // this band's stages
  cv::Mat store;        // 3k rows: term t's B, G, R planes are rows 3t, 3t + 1, 3t + 2
  cv::Mat valid_store;  // rows x width, when the model has a "valid" channel
  MissingStats missing;
  Status status;
};

// A near-lamp band's buffers for one tile, reused tile after tile.
struct TileBuffers {
  std::vector<Vec3> dirs;
  SampleMatrix y, coeffs;
  std::vector<uint8_t> missing, valid;
};

// Fits rows [y0, y0 + rows) of a near-lamp band tile by tile: each tile's projector is built
// from the directions at the tile's centre with the chosen basis, method and relative λ;
// its pixels' samples are gathered and fitted exactly as ApplyProjector fits a band (the
// same solves for missing samples), and the coefficients scattered back.
Status ApplyTiles(const Projector& chosen, const NearLamp& lamp, const std::vector<Vec3>& dirs,
                  const std::vector<double>& weights, double max_condition, int tile, int y0,
                  int rows, int w, int h, const SampleMatrix& y,
                  const std::vector<uint8_t>& missing, SampleMatrix* coeffs,
                  std::vector<uint8_t>* valid_px, MissingStats* stats, size_t* built,
                  TileBuffers* buf) {
  const size_t n = dirs.size();
  const size_t pixels = static_cast<size_t>(rows) * w;
  const int k = chosen.basis.size();
  coeffs->resize(k, y.cols());
  valid_px->assign(pixels, 1);
  buf->dirs.resize(n);
  for (int ty0 = (y0 / tile) * tile; ty0 < y0 + rows; ty0 += tile) {
    const int ty1 = std::min(h, ty0 + tile);
    const int ry0 = std::max(y0, ty0), ry1 = std::min(y0 + rows, ty1);
    for (int tx0 = 0; tx0 < w; tx0 += tile) {
      const int tx1 = std::min(w, tx0 + tile);
      // The tile's centre, on the plane or at the tile's mean depth.
      const double z =
          lamp.depth_mm.empty() ? lamp.plane_z_mm
                                : cv::mean(lamp.depth_mm(cv::Range(ty0, ty1), cv::Range(tx0, tx1)))[0];
      double falloff = 1;
      for (size_t i = 0; i < n; ++i)
        buf->dirs[i] = lamp.AtPosition((tx0 + tx1) / 2.0, (ty0 + ty1) / 2.0, z, w, h, dirs[i], &falloff);
      auto pr = BuildProjector(chosen.basis, buf->dirs, weights, chosen.method,
                               chosen.lambda_relative, max_condition);
      if (!pr.ok()) {
        return pr.error().Within(fmt::format("near-lamp tile x {}-{}, y {}-{}", tx0, tx1 - 1, ty0, ty1 - 1));
      }
      ++*built;
      const int tw = tx1 - tx0, th = ry1 - ry0;
      const size_t tpx = static_cast<size_t>(tw) * th;
      buf->y.resize(static_cast<Eigen::Index>(n), static_cast<Eigen::Index>(3 * tpx));
      for (int r = 0; r < th; ++r)
        buf->y.middleCols(3 * r * tw, 3 * tw) =
            y.middleCols(3 * ((static_cast<Eigen::Index>(ry0 - y0 + r)) * w + tx0), 3 * tw);
      buf->missing.clear();
      if (!missing.empty()) {
        buf->missing.assign(n * tpx, 0);
        bool any = false;
        for (size_t i = 0; i < n; ++i)
          for (int r = 0; r < th; ++r) {
            const uint8_t* src = missing.data() + i * pixels + static_cast<size_t>(ry0 - y0 + r) * w + tx0;
            uint8_t* dst = buf->missing.data() + i * tpx + static_cast<size_t>(r) * tw;
            for (int c = 0; c < tw; ++c) any |= (dst[c] = src[c]) != 0;
          }
        if (!any) buf->missing.clear();
      }
      const MissingStats s = ApplyProjector(*pr, buf->dirs, weights, max_condition, buf->y,
                                            buf->missing, &buf->coeffs, &buf->valid);
      stats->pixels_with_missing += s.pixels_with_missing;
      stats->flagged += s.flagged;
      stats->patterns += s.patterns;
      for (int r = 0; r < th; ++r) {
        const Eigen::Index row = ry0 - y0 + r;
        coeffs->middleCols(3 * (row * w + tx0), 3 * tw) = buf->coeffs.middleCols(3 * r * tw, 3 * tw);
        std::copy_n(buf->valid.data() + static_cast<size_t>(r) * tw, tw,
                    valid_px->data() + static_cast<size_t>(row) * w + tx0);
      }
    }
  }
  return Ok();
}

// What every band of one streamed fit shares.
struct BandFit {
  MapBands& maps;
  const StreamFitInput& in;
  const FitOptions& o;
  const Projector& pr;
  const std::vector<double>& weights;
  const SampleSpace& space;
  const std::string& out_path;
  ExrPixelType type;
  int w, h, band, tile, k;
  bool with_valid;
  std::atomic<size_t>* projectors;
};

// A worker's buffers, reused band after band (a fresh band-sized block costs a page fault per
// 4 KiB: on a virtual machine that was half of the fit's time).
struct BandBuffers {
  std::vector<cv::Mat> bgr, valid;
  SampleMatrix y, coeffs;
  std::vector<uint8_t> missing, valid_px;
  TileBuffers tiles;
  cv::Mat plane[3];  // one term's B, G, R in float, before the conversion to half
};

// The model's header, as the in-memory fit writes it, with the file's channels.
Imf::Header StreamHeader(const StreamFitInput& in, const FitOptions& o, const StreamFitOutput& out,
                         int tile, bool with_valid, ExrPixelType type) {
  const Projector& pr = out.selection.projector;
  const NearLamp& lamp = in.near_lamp;
  const ModelInfo info =
      FittedModelInfo(o, pr, out.loo_rmse, in.lamp_radiance_rgb, in.light_frame, in.directions);
  Model header_model(pr.basis, info, out.width, out.height);
  auto attributes = ModelHeaderAttributes(header_model);
  attributes["flagged_pixels"] = "see the 'valid' channel (streamed fit)";
  if (lamp.near()) {
    attributes["near_lamp"] = fmt::format(
        "{:.6g} mm, {:.6g} mm/px, {}; samples divided by their fall-off, {}", lamp.distance_mm,
        lamp.mm_per_px,
        lamp.depth_mm.empty() ? fmt::format("surface at z = {:.6g} mm", lamp.plane_z_mm)
                              : std::string("depth map given"),
        tile > 0 ? fmt::format("directions at the centre of every {} px tile", tile)
                 : std::string("one direction per lamp"));
  }
  const Imf::PixelType pixel = type == ExrPixelType::kHalf ? Imf::HALF : Imf::FLOAT;
  const ExrCompressionCode code = ExrCompressionCodeOf(in.compression);
  Imf::Header header(out.width, out.height, 1.0f, Imath::V2f(0, 0), 1.0f, Imf::INCREASING_Y,
                     static_cast<Imf::Compression>(code.imf_compression));
  if (code.zip_level > 0) header.zipCompressionLevel() = code.zip_level;
  if (code.dwa_level > 0) header.dwaCompressionLevel() = code.dwa_level;
  for (int t = 0; t < pr.basis.size(); ++t)
    for (char c : {'R', 'G', 'B'})
      header.channels().insert(CoefficientChannelName(t, c), Imf::Channel(pixel));
  if (with_valid) header.channels().insert("valid", Imf::Channel(pixel));
  for (const auto& [key, value] : attributes) header.insert(key, Imf::StringAttribute(value));
  return header;
}

// Planar for the writer: term t's channel c (B, G, R) is row 3t + c of `store`, the band's
// pixels in order, in the file's pixel type. OpenEXR copies a slice of consecutive values
// several times faster than one strided through interleaved BGR (the writer was a third of
// the fit's CPU time at 24 MP), and the split and the conversion run on the workers instead.
void PlanarForWriter(const BandFit& f, BandBuffers& buf, FittedBand* r) {
  const int px = r->rows * f.w;
  r->store.create(3 * f.k, px, f.type == ExrPixelType::kHalf ? CV_16F : CV_32F);
  for (int t = 0; t < f.k; ++t) {
    cv::Mat interleaved(1, px, CV_32FC3, buf.coeffs.row(t).data());
    if (f.type == ExrPixelType::kHalf) {
      for (auto& m : buf.plane) m.create(1, px, CV_32F);
      cv::split(interleaved, buf.plane);
      for (int c = 0; c < 3; ++c) {
        cv::Mat dst = r->store.row(3 * t + c);
        buf.plane[c].convertTo(dst, CV_16F);
      }
    } else {
      cv::Mat planes[3] = {r->store.row(3 * t), r->store.row(3 * t + 1), r->store.row(3 * t + 2)};
      cv::split(interleaved, planes);
    }
  }
  if (f.with_valid) {
    cv::Mat v(r->rows, f.w, CV_8U, buf.valid_px.data()), vf;
    v.convertTo(vf, CV_32F);
    if (f.type == ExrPixelType::kHalf) {
      vf.convertTo(r->valid_store, CV_16F);
    } else {
      r->valid_store = vf;
    }
  }
}

// One band: read into samples, projected (per tile for a near lamp), made planar.
void FitOneBand(const BandFit& f, int b, FittedBand* r, BandBuffers& buf) {
  r->y0 = b * f.band;
  const int y1 = std::min(f.h, r->y0 + f.band);
  r->rows = y1 - r->y0;
  auto t = std::chrono::steady_clock::now();
  auto lap = [&t] {
    const auto now = std::chrono::steady_clock::now();
    const double s = std::chrono::duration<double>(now - t).count();
    t = now;
    return s;
  };
  try {
    r->status = f.maps.ReadSamples(r->y0, y1, f.space, f.in.directions, &buf.bgr, &buf.valid,
                                   &buf.y, &buf.missing);
  } catch (const std::exception& e) {
    r->status = MakeError(ErrorCode::kIo, f.out_path, "reading rows {}-{}: {}", r->y0, y1 - 1,
                          e.what());
  }
  r->samples_s = lap();  // read and made into samples, in one pass from memory
  if (!r->status.ok()) return;
  if (f.tile > 0) {
    size_t built = 0;
    r->status = ApplyTiles(f.pr, f.in.near_lamp, f.in.directions, f.weights, f.o.max_condition,
                           f.tile, r->y0, r->rows, f.w, f.h, buf.y, buf.missing, &buf.coeffs,
                           &buf.valid_px, &r->missing, &built, &buf.tiles);
    *f.projectors += built;
    if (!r->status.ok()) return;
  } else {
    r->missing = ApplyProjector(f.pr, f.in.directions, f.weights, f.o.max_condition, buf.y,
                                buf.missing, &buf.coeffs, &buf.valid_px);
  }
  PlanarForWriter(f, buf, r);
  r->project_s = lap();
}

// Where the writer's time went.
struct WriterTimes {
  double samples_s = 0, project_s = 0, write_s = 0, wait_s = 0;
};

// One fitted band into the file at its rows.
void WriteBand(const BandFit& f, const FittedBand& r, Imf::OutputFile& file) {
  const Imf::PixelType pixel = f.type == ExrPixelType::kHalf ? Imf::HALF : Imf::FLOAT;
  const size_t elem = f.type == ExrPixelType::kHalf ? 2 : sizeof(float);
  Imf::FrameBuffer fb;
  const size_t ys = elem * f.w;
  for (int t = 0; t < f.k; ++t) {
    for (int c = 0; c < 3; ++c) {
      char* plane = reinterpret_cast<char*>(const_cast<uchar*>(r.store.ptr(3 * t + c))) -
                    static_cast<ptrdiff_t>(r.y0) * static_cast<ptrdiff_t>(ys);
      fb.insert(CoefficientChannelName(t, "BGR"[c]), Imf::Slice(pixel, plane, elem, ys));
    }
  }
  if (f.with_valid) {
    fb.insert("valid", Imf::Slice(pixel,
                                  reinterpret_cast<char*>(r.valid_store.data) -
                                      static_cast<ptrdiff_t>(r.y0) * f.w * elem,
                                  elem, elem * f.w));
  }
  file.setFrameBuffer(fb);
  file.writePixels(r.rows);
}

// Pass 2: `workers` threads fit bands at most `ahead` bands before the writer, which writes
// them in order into `file`; OpenEXR compresses each band's 16-line blocks on its own pool.
// Returns the first band's failure; *missing sums the bands' missing-sample statistics.
Status FitAndWriteBands(const BandFit& f, int workers, Imf::OutputFile& file,
                        MissingStats* missing, WriterTimes* times) {
  const int bands_total = (f.h + f.band - 1) / f.band;
  const int ahead = 2 * workers + 1;
  std::mutex mu;
  std::condition_variable cv;
  std::map<int, FittedBand> done;  // band index -> result, waiting for the writer
  int next = 0, written = 0;
  bool stop = false;
  auto worker = [&] {
    BandBuffers buffers;
    for (;;) {
      int b;
      {
        std::unique_lock<std::mutex> lock(mu);
        cv.wait(lock, [&] { return stop || next >= bands_total || next < written + ahead; });
        if (stop || next >= bands_total) return;
        b = next++;
      }
      FittedBand r;
      try {
        FitOneBand(f, b, &r, buffers);
      } catch (const std::exception& e) {
        r.status = MakeError(ErrorCode::kIo, f.out_path, "fitting rows from {}: {}", b * f.band,
                             e.what());
      }
      {
        std::lock_guard<std::mutex> lock(mu);
        done.emplace(b, std::move(r));
      }
      cv.notify_all();
    }
  };
  std::vector<std::thread> pool;
  auto stop_pool = [&] {
    {
      std::lock_guard<std::mutex> lock(mu);
      stop = true;
    }
    cv.notify_all();
    for (auto& t : pool) t.join();
  };
  Status failed = Ok();
  ProgressTask task("fitting the model", bands_total);
  for (int i = 0; i < workers; ++i) pool.emplace_back(worker);
  try {
    for (int b = 0; b < bands_total; ++b) {
      FittedBand r;
      const auto t_wait = std::chrono::steady_clock::now();
      {
        std::unique_lock<std::mutex> lock(mu);
        cv.wait(lock, [&] { return done.count(b) > 0; });
        r = std::move(done.at(b));
        done.erase(b);
      }
      if (!r.status.ok()) {
        failed = r.status;
        break;
      }
      const auto t_write = std::chrono::steady_clock::now();
      times->wait_s += std::chrono::duration<double>(t_write - t_wait).count();
      times->samples_s += r.samples_s;
      times->project_s += r.project_s;
      task.Advance(1, fmt::format("rows {}-{}", r.y0, r.y0 + r.rows - 1));
      missing->pixels_with_missing += r.missing.pixels_with_missing;
      missing->flagged += r.missing.flagged;
      missing->patterns += r.missing.patterns;
      WriteBand(f, r, file);
      times->write_s += std::chrono::duration<double>(std::chrono::steady_clock::now() - t_write).count();
      {
        std::lock_guard<std::mutex> lock(mu);
        written = b + 1;
      }
      cv.notify_all();
    }
  } catch (...) {
    stop_pool();
    throw;
  }
  stop_pool();
  return failed;
}

// Pass 1: the Gram matrix of evenly spaced bands — accumulated already when the maps were
// kept in memory as they arrived (selection_gram.h), else computed now from the bands, in the
// same arithmetic. *accumulated says which.
Result<GramSum> SelectionGramFor(MapBands& maps, const StreamFitInput& in,
                                 const SelectionLayout& layout, const SampleSpace& space,
                                 int threads, bool* accumulated) {
  std::optional<GramSum> gram = maps.SelectionGram(in.directions, layout, space);
  *accumulated = gram.has_value();
  if (gram) return std::move(*gram);
  return SelectionGramOfBands(maps, in.directions, layout, space, threads);
}

}  // namespace

Result<StreamFitOutput> FitModelFromBands(MapBands& maps, const StreamFitInput& in,
                                          const FitOptions& o, const std::string& out_path,
                                          ExrPixelType type) {
  const auto t0 = std::chrono::steady_clock::now();
  auto since_t0 = [&t0] {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  };
  const size_t n = maps.count();
  if (n == 0 || in.directions.size() != n) {
    return MakeError(ErrorCode::kInvalidInput, "fit", "{} maps, {} directions", n,
                     in.directions.size());
  }
  const std::vector<double> weights = in.weights.empty() ? UniformHemisphereWeights(n) : in.weights;
  // The model through the project's one writer: a fresh temporary (O_EXCL|O_NOFOLLOW) moved
  // over out_path when complete, removed when anything fails.
  RIG_ASSIGN_OR_RETURN(AtomicFile out_file, AtomicFile::Create(out_path));
  try {
    const int w = maps.width(), h = maps.height();
    const int band = std::max(1, in.band_rows);
    // A near lamp: samples divided by their fall-off; tiles with their own projectors.
    const NearLamp& lamp = in.near_lamp;
    if (lamp.near() && !lamp.depth_mm.empty() &&
        (lamp.depth_mm.type() != CV_32FC1 || lamp.depth_mm.cols != w || lamp.depth_mm.rows != h)) {
      return MakeError(ErrorCode::kInvalidInput, "near lamp",
                       "the depth map must be CV_32FC1 {}x{} like the radiance maps", w, h);
    }
    const int tile = !lamp.near() || in.near_falloff_only
                         ? 0
                         : (in.near_tile_px > 0 ? in.near_tile_px : lamp.TilePx(w, h, in.near_tile_max_deg));
    const int threads = std::max(1, o.threads);
    const SelectionLayout layout{w, h, band, in.selection_rows};
    const SampleSpace space{in.lamp_radiance_rgb, o.transform, lamp};
    bool gram_accumulated = false;
    auto gram = SelectionGramFor(maps, in, layout, space, threads, &gram_accumulated);
    if (!gram.ok()) return gram.error().Within(out_path);
    StreamFitOutput out;
    out.width = w;
    out.height = h;
    out.near_tile_px = tile;
    const double gram_s = since_t0();
    RIG_ASSIGN_OR_RETURN(out.selection, SelectProjector(in.directions, weights, gram->gram, gram->count, o));
    const double select_s = since_t0() - gram_s;
    const Projector& pr = out.selection.projector;
    for (const auto& r : out.selection.orders)
      if (r.order == out.selection.order) out.loo_rmse = r.loo_rmse;
    const bool with_valid = maps.any_flags();
    const Imf::Header header = StreamHeader(in, o, out, tile, with_valid, type);
    std::atomic<size_t> projectors{0};
    const BandFit f{maps, in, o, pr, weights, space, out_path, type, w, h, band, tile,
                    pr.basis.size(), with_valid, &projectors};
    const int workers = maps.concurrent() ? threads : 1;
    WriterTimes times;
    Status failed = Ok();
    SetExrThreads(threads);
    AtomicExrStream stream(std::move(out_file));
    {
      Imf::OutputFile file(stream, header, threads);
      failed = FitAndWriteBands(f, workers, file, &out.missing, &times);
    }
    if (!failed.ok()) return failed.error();
    double sync_s = 0;
    if (Status st = stream.Commit(&sync_s); !st.ok())
      return st.error().Within("cannot move the written model into place");
    out.time_s = since_t0();
    if (tile > 0) out.projectors = projectors.load();
    if (lamp.near()) {
      Log("process")->info("near lamp distance_mm={:.6g} mm_per_px={:.6g} surface_z_mm={} "
                           "tile_px={} projectors={}", lamp.distance_mm, lamp.mm_per_px,
                           lamp.depth_mm.empty() ? fmt::format("{:.6g}", lamp.plane_z_mm)
                                                 : std::string("map"), tile, out.projectors);
    }
    Log("process")->info("band fit {}x{} poses={} order={} terms={} workers={} missing_pixels={} "
                         "flagged={} time_s={:.2f} (gram {:.2f}{}, selection {:.2f}; summed over "
                         "workers: read into samples {:.2f}, projection {:.2f}; writer: waited "
                         "{:.2f}, wrote {:.2f}, fsync {:.2f})",
                         w, h, n, out.selection.order, pr.basis.size(), workers,
                         out.missing.pixels_with_missing, out.missing.flagged, out.time_s, gram_s,
                         gram_accumulated ? " accumulated as the maps arrived" : "", select_s,
                         times.samples_s, times.project_s, times.wait_s, times.write_s, sync_s);
    return out;
  } catch (const std::exception& e) {
    return MakeError(ErrorCode::kIo, out_path, "streamed fit failed: {}", e.what());
  }
}

}  // namespace rig
