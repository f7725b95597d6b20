// Decoding camera files (8-bit JPEG/PNG, 16-bit PNG/TIFF) into BGR frames, and bracket lists.
#pragma once

#include <functional>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "config/config.h"
#include "config/result.h"

namespace rig {

// One exposure of a bracket, as decoded from the camera's file.
struct LdrFrame {
  cv::Mat image;          // CV_8UC3 or CV_16UC3, BGR
  Seconds exposure{0};    // the exposure time the camera applied
  std::string source;     // file name (used in every error about this frame)
};
using Bracket = std::vector<LdrFrame>;

// Decodes one camera file into CV_8UC3 or CV_16UC3 BGR (grey is expanded to three channels,
// alpha dropped; EXIF orientation is NOT applied, so every frame keeps the sensor's layout).
// Unreadable, unsupported and truncated files (a JPEG without its end marker, a PNG without
// IEND) are errors naming the file.
Result<cv::Mat> DecodeImage(const std::string& path);
// The same from the file's bytes already in memory; `path` names it in errors.
Result<cv::Mat> DecodeImageBytes(const std::vector<uchar>& bytes, const std::string& path);

// Writes `image` to `path` as cv::imwrite would (the format from the extension, `params` as
// imwrite's), encoded in memory (cv::imencode) and written by the project's one writer
// (config/atomic_file.h): never through a link, never half a file. Errors name the file.
Status WriteImageFile(const std::string& path, const cv::Mat& image,
                      const std::vector<int>& params = {});

// Decodes files[i] into frame i, `threads` files at a time. The first error (in file order)
// is returned; it names the file.
Result<Bracket> DecodeFrames(const std::vector<std::string>& files,
                             const std::vector<Seconds>& exposures, int threads = 2);

// Reads a bracket list: one "<image> <exposure_s>" per line ("1/250" is accepted too),
// blank lines and '#' comments ignored, relative paths relative to the list's folder, and
// decodes the images in parallel. Errors name "list:line" or the image file. The frames are
// returned in list order; ValidateBracket (process/hdr/hdr.h) checks them.
Result<Bracket> LoadBracketList(const std::string& list_path, int threads = 2);

// Runs fn(begin, end) over [0, n) split into contiguous chunks on up to `threads` threads
// (the calling thread takes part). fn must be thread-safe for disjoint ranges.
// Keeps freed image-sized blocks in the process for the next image instead of returning
// them to the system (glibc's mmap threshold raised to 1 GiB, trimming off): every fresh
// 70 MB radiance map or decoded bracket otherwise costs a page fault per 4 KiB, which on a
// virtual machine can take more time than the merge itself (docs/hdr.md). The resident size
// stays at the peak instead of falling between poses.
void ReuseFreedImageMemory();

void ParallelFor(int n, int threads, const std::function<void(int begin, int end)>& fn,
                 int min_chunk = 1);

}  // namespace rig
