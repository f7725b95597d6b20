// JPEG through libjpeg, for coefficient planes: three independent 8-bit planes per file stored
// in the RGB colour space (Adobe marker, no YCbCr transform, no chroma subsampling), so one
// plane's error never leaks into another's — as relight writes its PCA planes. Written and
// read by bands of rows, so a 24 MP plane never has to be whole in memory.
#pragma once

#include <cstdint>
#include <cstdio>
#include <memory>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "config/result.h"

namespace rig {

enum class JpegColor {
  kRgb,    // three independent planes: JCS_RGB in the file, no subsampling
  kYcbcr,  // a picture: YCbCr 4:4:4
  kGray,   // one plane
};

// Writes rows top to bottom. Not thread-safe; one writer per file. The file is written through
// AtomicFile (config/atomic_file.h): `path` shows the old file until Finish() moves the new one
// over it (a link at `path` is replaced, never followed); abandoned, nothing is left.
class JpegWriter {
 public:
  ~JpegWriter();
  static Result<std::unique_ptr<JpegWriter>> Open(const std::string& path, int width, int height,
                                                  int channels, JpegColor color, int quality);
  // `rows` is CV_8UC(channels) with the writer's width, channels in file order (R, G, B).
  Status Write(const cv::Mat& rows);
  Status Finish();  // after the last row; fsyncs

 private:
  JpegWriter() = default;
  struct State;
  std::unique_ptr<State> state_;
};

// Whole-image convenience: `image` CV_8UC3 in R, G, B order, or CV_8UC1.
Status WriteJpeg(const std::string& path, const cv::Mat& image, JpegColor color, int quality);

// In memory: the bytes of the file WriteJpeg would write, and back.
Result<std::vector<uint8_t>> EncodeJpeg(const cv::Mat& image, JpegColor color, int quality);
Result<cv::Mat> DecodeJpeg(const std::vector<uint8_t>& bytes, const std::string& context);

// Reads rows top to bottom; channels in file order (R, G, B for colour files).
class JpegReader {
 public:
  ~JpegReader();
  // Errors name the file; a truncated file is an error (no silent grey rows).
  static Result<std::unique_ptr<JpegReader>> Open(const std::string& path);
  int width() const;
  int height() const;
  int channels() const;
  // The file's own colour space is RGB (an Adobe marker, no YCbCr transform).
  bool rgb_space() const;
  // Reads the next `count` rows into *rows (CV_8UC(channels), resized as needed).
  Status Read(int count, cv::Mat* rows);

 private:
  JpegReader() = default;
  struct State;
  std::unique_ptr<State> state_;
};

// Whole image, channels in file order (R, G, B).
Result<cv::Mat> ReadJpeg(const std::string& path);

}  // namespace rig
