// Reading a radiance map for rendering and tone mapping: OpenEXR (R, G, B) or Radiance RGBE
// (.hdr, .pic), as linear CV_32FC3 BGR, with what its header says about the picture (the
// primaries of its RGB, its view, the exposure already applied to its values).
#pragma once

#include <array>
#include <map>
#include <optional>
#include <string>

#include <opencv2/core.hpp>

#include "config/result.h"

namespace rig {

// CIE 1931 xy chromaticities of an RGB space's primaries and white, in the order of
// Radiance's PRIMARIES= line and OpenEXR's chromaticities attribute.
struct Chromaticities {
  double red_x = 0, red_y = 0, green_x = 0, green_y = 0, blue_x = 0, blue_y = 0;
  double white_x = 0, white_y = 0;
  // Equal within Radiance's colour epsilon (1e-4 per coordinate).
  bool SameAs(const Chromaticities& other) const;
};
// Radiance's standard primaries (color.h: a nominal CRT, equal-energy white), assumed for a
// Radiance picture without a PRIMARIES= line.
Chromaticities RadiancePrimaries();
// ITU-R BT.709 / sRGB with D65 white, assumed for an OpenEXR file without chromaticities.
Chromaticities Rec709Primaries();

// RGB → CIE XYZ for these primaries, row-major [X; Y; Z], the white balanced to equal energy
// by a von Kries transform in the Sharp space as Radiance's comprgb2xyzWBmat: the Y row is
// what pcond weighs luminance with (0.265, 0.670, 0.065 for RadiancePrimaries()).
// Degenerate chromaticities (collinear primaries, a white with y = 0) give an error.
Result<cv::Matx33d> RgbToXyzWhiteBalanced(const Chromaticities& p);
// RGB of `from` → RGB of `to`, the white of `from` carried to the white of `to` by a von
// Kries transform in the Sharp space (Radiance's comprgb2rgbWBmat). Identity when the two
// are the same.
Result<cv::Matx33d> RgbToRgbWhiteBalanced(const Chromaticities& from, const Chromaticities& to);

// A Radiance view (the VIEW= line, or a rpict/rvu/rpiece/pinterp command line in the header):
// its type (-vt: v perspective, l parallel, c cylindrical, h hemispherical, a angular fisheye)
// and its size in degrees (-vh, -vv). Radiance's default view is -vtv -vh 45 -vv 45.
struct PictureView {
  char type = 'v';
  double horizontal_deg = 45, vertical_deg = 45;
};

// The image-plane extents pcond samples its foveal image over (Radiance's setview: sqrt(hn2),
// sqrt(vn2)): 2·tan(size/2) for a perspective view, the angle in radians for an angular
// fisheye, 2·sin(size/2) for a hemispherical one, the horizontal angle in radians and
// 2·tan(vertical/2) for a cylindrical panorama. A size out of the type's range is an error.
Result<std::array<double, 2>> ViewExtent(const PictureView& view);

// What a Radiance header (or an OpenEXR header) says about the pixels.
struct PictureHeader {
  Chromaticities primaries;        // the file's, or the format's default
  bool primaries_given = false;    // PRIMARIES= / chromaticities present
  std::optional<PictureView> view; // VIEW= (and the view-giving command lines), if any
  double exposure = 1;             // the product of every EXPOSURE= line
  std::array<double, 3> colour_correction{1, 1, 1};  // the product of every COLORCORR= (R, G, B)
  double pixel_aspect = 1;         // the product of every PIXASPECT=
};

// A radiance map and its header. The pixels are the original values: what the file stores
// divided by the exposure and, per channel, by the colour correction (Radiance's convention:
// a program that scales a picture multiplies EXPOSURE by the same factor).
struct RadiancePicture {
  cv::Mat radiance;  // CV_32FC3 BGR
  PictureHeader header;
};

// Parses a Radiance header's text (the lines up to the blank line, without the resolution
// line); `path` names the file in errors. A malformed PRIMARIES=, EXPOSURE=, COLORCORR= or
// PIXASPECT= value (not a positive number where one is needed) is an error naming the line.
Result<PictureHeader> ParseRadianceHeader(const std::string& text, const std::string& path);

// Errors name the file: missing (kNotFound), unknown extension or unreadable (kInvalidInput).
Result<RadiancePicture> ReadRadiancePicture(const std::string& path);
// The pixels alone (ReadRadiancePicture(path).radiance).
Result<cv::Mat> ReadRadianceFile(const std::string& path);

}  // namespace rig
