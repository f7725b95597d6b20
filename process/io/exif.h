// A photograph's lens from its EXIF (libexif): the focal length and what gives the sensor's
// width, for a perspective camera model when the user gives neither.
#pragma once

#include <string>

#include "config/result.h"

namespace rig {

struct ExifLens {
  bool has_exif = false;
  double focal_mm = 0;          // FocalLength; 0: absent
  double focal_35mm = 0;        // FocalLengthIn35mmFilm; 0: absent
  double x_res_per_mm = 0;      // FocalPlaneXResolution over FocalPlaneResolutionUnit; 0: absent
  int exif_width_px = 0;        // PixelXDimension: the width the focal plane's resolution is for
};

// Reads the EXIF of a JPEG (or a raw EXIF block) at `path`. A file without EXIF is no error
// (has_exif false); a file that cannot be read is (kIo, naming it).
Result<ExifLens> ReadExifLens(const std::string& path);

struct ExifFocal {
  double focal_mm = 0;         // 0: the EXIF cannot give a focal length with a sensor width
  double sensor_width_mm = 0;  // the width of the image's field on the sensor
  std::string how;             // which tags gave them, for the output
};

// The focal length and sensor width for an image `width_px` x `height_px` (as the file holds
// it): FocalLength with the sensor width from FocalPlaneXResolution (PixelXDimension, else
// width_px, over it); else from FocalLengthIn35mmFilm (the equivalent is by the diagonal,
// 43.27 mm: the width is that diagonal scaled by f / f35 and the image's aspect); else nothing.
ExifFocal FocalFromExif(const ExifLens& lens, int width_px, int height_px);

}  // namespace rig
