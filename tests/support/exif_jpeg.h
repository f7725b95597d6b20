// Test-only: a JPEG with the EXIF lens tags a test chooses, written through libexif.
#pragma once

#include <string>

#include <opencv2/core.hpp>

namespace rig::testing {

struct ExifTags {           // each written only when > 0
  double focal_mm = 0;      // FocalLength (RATIONAL)
  double focal_35mm = 0;    // FocalLengthIn35mmFilm (SHORT)
  double focal_plane_x_res = 0;  // FocalPlaneXResolution (RATIONAL), per focal_plane_unit
  int focal_plane_unit = 0;      // FocalPlaneResolutionUnit (SHORT): 2 inch, 3 cm
  int pixel_x_dimension = 0;     // PixelXDimension (LONG)
};

// Encodes `bgr` (CV_8UC3) as a JPEG with an APP1 EXIF segment holding `tags`. false on failure.
bool WriteJpegWithExif(const std::string& path, const cv::Mat& bgr, const ExifTags& tags);

}  // namespace rig::testing
