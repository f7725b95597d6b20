// RAW decoding through LibRaw (the thread-safe build: brackets decode in parallel).
#include "process/io/raw_io.h"

#include <algorithm>
#include <cmath>
#include <cctype>
#include <filesystem>
#include <memory>

#include <libraw/libraw.h>
#include <opencv2/imgproc.hpp>

namespace rig {

bool IsRawPath(const std::string& path) {
  std::string ext = std::filesystem::path(path).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return std::tolower(c); });
  static const char* kRaw[] = {".dng", ".cr2", ".cr3", ".nef", ".arw", ".raf",
                               ".orf", ".rw2", ".pef", ".srw"};
  return std::any_of(std::begin(kRaw), std::end(kRaw), [&](const char* e) { return ext == e; });
}

namespace {

Error RawError(const std::string& path, const std::string& what, int code) {
  return MakeError(ErrorCode::kInvalidInput, path, "cannot decode as RAW ({}): {}", what,
                   libraw_strerror(code));
}

// Share of raw photosites at or above `white`, and their mask in raw-image coordinates
// (CV_8U, 255 where clipped), for Bayer data (one value per photosite) or 3/4-colour data.
double ClippedPhotosites(const LibRaw& raw, cv::Mat* mask) {
  const auto& s = raw.imgdata.sizes;
  const unsigned white = raw.imgdata.color.maximum;
  const auto& rd = raw.imgdata.rawdata;
  const int w = s.raw_width, h = s.raw_height;
  *mask = cv::Mat::zeros(h, w, CV_8U);
  size_t clipped = 0;
  for (int y = 0; y < h; ++y) {
    uint8_t* m = mask->ptr<uint8_t>(y);
    for (int x = 0; x < w; ++x) {
      bool hit = false;
      if (rd.raw_image) {
        hit = rd.raw_image[size_t(y) * (s.raw_pitch / 2) + x] >= white;
      } else if (rd.color3_image) {
        const uint16_t* p = rd.color3_image[size_t(y) * (s.raw_pitch / 6) + x];
        hit = p[0] >= white || p[1] >= white || p[2] >= white;
      } else if (rd.color4_image) {
        const uint16_t* p = rd.color4_image[size_t(y) * (s.raw_pitch / 8) + x];
        hit = p[0] >= white || p[1] >= white || p[2] >= white || p[3] >= white;
      }
      if (hit) {
        m[x] = 255;
        ++clipped;
      }
    }
  }
  return w * h > 0 ? double(clipped) / (double(w) * h) : 0.0;
}

}  // namespace

Result<cv::Mat> DecodeRawBytes(std::span<const uint8_t> bytes, const std::string& path,
                               const RawDecodeOptions& options, RawInfo* info) {
  if (bytes.empty()) return MakeError(ErrorCode::kInvalidInput, path, "empty file");
  auto raw = std::make_unique<LibRaw>();
  auto& p = raw->imgdata.params;
  p.output_bps = 16;
  p.gamm[0] = 1.0;  // linear: no tone curve
  p.gamm[1] = 1.0;
  p.no_auto_bright = 1;
  p.output_color = 0;  // the sensor's own primaries
  p.user_flip = 0;     // the sensor's layout, as every other frame of a bracket
  p.highlight = 0;     // clip: a clipped photosite stays at the top
  p.use_auto_wb = 0;
  p.use_camera_wb = options.white_balance == RawWhiteBalance::kCamera ? 1 : 0;
  p.use_camera_matrix = 0;
  if (options.white_balance != RawWhiteBalance::kCamera) {
    const auto m = options.white_balance == RawWhiteBalance::kFixed ? options.fixed_rgb
                                                                     : std::array<double, 3>{1, 1, 1};
    for (double v : m) {
      if (!(v > 0) || !std::isfinite(v))
        return MakeError(ErrorCode::kInvalidInput, path, "white balance multipliers must be positive");
    }
    p.user_mul[0] = float(m[0]);
    p.user_mul[1] = float(m[1]);
    p.user_mul[2] = float(m[2]);
    p.user_mul[3] = float(m[1]);
  }
  // LibRaw takes a non-const buffer but does not write to it.
  int rc = raw->open_buffer(const_cast<uint8_t*>(bytes.data()), bytes.size());
  if (rc != LIBRAW_SUCCESS) return RawError(path, "open", rc);
  const auto& s = raw->imgdata.sizes;
  if (s.width == 0 || s.height == 0 || double(s.width) * s.height > 400e6)
    return MakeError(ErrorCode::kInvalidInput, path, "RAW image size {}x{} out of range", s.width,
                     s.height);
  rc = raw->unpack();
  if (rc != LIBRAW_SUCCESS) return RawError(path, "unpack", rc);
  cv::Mat clipped_raw;
  const double clipped = ClippedPhotosites(*raw, &clipped_raw);
  const bool mosaic = raw->imgdata.idata.filters != 0;
  RawInfo local;
  local.camera = std::string(raw->imgdata.idata.make) + " " + raw->imgdata.idata.model;
  local.black = raw->imgdata.color.black;
  local.white = raw->imgdata.color.maximum;
  local.shutter_s = raw->imgdata.other.shutter;
  local.clipped_fraction = clipped;
  local.mosaic = mosaic;
  rc = raw->dcraw_process();
  if (rc != LIBRAW_SUCCESS) return RawError(path, "process", rc);
  for (int c = 0; c < 3; ++c) local.multipliers[c] = raw->imgdata.color.pre_mul[c];
  int err = 0;
  std::unique_ptr<libraw_processed_image_t, void (*)(libraw_processed_image_t*)> img(
      raw->dcraw_make_mem_image(&err), [](libraw_processed_image_t* i) { LibRaw::dcraw_clear_mem(i); });
  if (!img || err != LIBRAW_SUCCESS) return RawError(path, "make image", err);
  if (img->type != LIBRAW_IMAGE_BITMAP || img->colors != 3 || img->bits != 16)
    return MakeError(ErrorCode::kInvalidInput, path, "RAW decoded to {} colours of {} bits, not 3 of 16",
                     int(img->colors), int(img->bits));
  cv::Mat rgb(img->height, img->width, CV_16UC3, img->data);
  cv::Mat bgr;
  cv::cvtColor(rgb, bgr, cv::COLOR_RGB2BGR);
  // Clipped photosites: the visible area's part of the raw mask, grown by the demosaicing
  // neighbourhood, marks every channel of the pixels they reached as clipped.
  if (clipped > 0) {
    cv::Rect visible(s.left_margin, s.top_margin, s.width, s.height);
    visible &= cv::Rect(0, 0, clipped_raw.cols, clipped_raw.rows);
    cv::Mat m = clipped_raw(visible).clone();
    if (mosaic) cv::dilate(m, m, cv::Mat::ones(3, 3, CV_8U));
    if (m.size() == bgr.size()) bgr.setTo(cv::Scalar::all(65535), m);
  }
  if (info) *info = local;
  return bgr;
}

}  // namespace rig
