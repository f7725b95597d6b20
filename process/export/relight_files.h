// Writers and readers of relight's web format (types ptm and hsh, colorspace rgb), RTIViewer's
// .ptm (PTM 1.2: PTM_FORMAT_RGB and PTM_FORMAT_LRGB, raw) and .rti (HSH), and .lp light files.
// Pure functions of RelightCoefficients; every size read from a file is bounded before any
// allocation, and every refusal names the file and the field.
#pragma once

#include <string>
#include <vector>

#include "config/result.h"
#include "process/export/relight_coefficients.h"
#include "process/model/light_direction.h"

namespace rig {

// ---- relight's web format: a folder with info.json and plane_N.jpg -----------------------
struct WebWriteOptions {
  int quality = 95;
  double quantile = 0.0025;  // each plane's range from these quantiles (relight's -Q 0.995)
  // In-JPEG YCbCr 4:4:4, as relight writes (and its C++ reader, Rti::load, decodes: it forces
  // JCS_YCbCr on every plane). false: JCS_RGB with the Adobe marker, ~2 dB closer at twice the
  // bytes, for readers that honour the marker (libjpeg's default, browsers, ReadRelightWeb).
  bool ycbcr = true;
};
// The folder is created (it must not hold a model already: info.json present is refused).
// info.json: width, height, format "jpg", type, colorspace, lights (when known, 3 decimals),
// nplanes, quality, colorprofile "sRGB", materials [{scale, bias}]. rgb: plane 3j+c =
// coefficient j of channel c (R, G, B) in plane_j.jpg; lrgb (ptm): plane_0 = the albedo's bytes
// (scale 1, bias 0), planes 3..8 = the luminance terms. Scale/bias per plane as relight's
// Material::Plane reads them: c = 255·(byte/255 − bias)·scale, range from the quantiles.
Status WriteRelightWeb(const std::string& folder, const RelightCoefficients& c,
                       const WebWriteOptions& options);
// The planes as WriteRelightWeb writes them, before JPEG: the files' 8-bit images (plane_j's
// R, G, B = planes 3j, 3j+1, 3j+2; unused channels 0) and every plane's scale and bias.
struct RelightWebPlanes {
  std::vector<cv::Mat> files;  // CV_8UC3, channel order R, G, B as stored
  std::vector<double> scale, bias;
};
RelightWebPlanes QuantiseRelightWeb(const RelightCoefficients& c, const WebWriteOptions& options);
// The info.json text WriteRelightWeb writes for those planes.
std::string RelightWebInfo(const RelightCoefficients& c, const RelightWebPlanes& planes,
                           const WebWriteOptions& options);
// Types "ptm" (18 planes, rgb; 9 planes, lrgb) and "hsh" (27 or 12 planes, rgb).
Result<RelightCoefficients> ReadRelightWeb(const std::string& folder);
// The same checks of info.json and of every plane file's header (size, channels), without
// decoding the planes: `planes` and `albedo` are left empty.
Result<RelightCoefficients> ReadRelightWebInfo(const std::string& folder);
// What a web-format folder declares, and only that: info.json and plane_0.jpg ..
// plane_{ceil(nplanes/3)-1}.jpg, nplanes read from its info.json (an integer 1..256, else an
// error naming the file and the field). Planes past them, and any other file, are not the
// model's: publishing (rig view, rig export --format relight) copies these names only.
Result<std::vector<std::string>> DeclaredWebFiles(const std::string& folder);
// The "type" of a web-format folder's info.json ("" when it cannot be read).
std::string RelightWebType(const std::string& folder);

// ---- RTIViewer's .ptm (Malzbender et al., PTM format 1.2) -------------------------------
// Header lines PTM_1.2 / PTM_FORMAT_RGB|PTM_FORMAT_LRGB / width / height / 6 scales (floats) /
// 6 biases (ints), then raw bytes, rows bottom-up, coefficients in the file's order
// (x², y², xy, x, y, 1): RGB as three blocks (R, G, B) of 6 bytes per pixel; LRGB as 6 bytes
// per pixel, then 3 (R, G, B) per pixel. coefficient = (byte − bias)·scale (0..255 units; LRGB
// luminance L = Σ w·coefficient / 255). Scale and bias are chosen to hold every coefficient
// (biases outside 0..255 are written as they are, unlike relight's savePTM). `c` must be PTM;
// c.lrgb picks the variant.
Status WritePtm(const std::string& path, const RelightCoefficients& c);
// Raw RGB and LRGB (1.2 layout when the version line is exactly PTM_1.2, 9 interleaved bytes
// per pixel otherwise). JPEG and LUT variants are refused.
Result<RelightCoefficients> ReadPtm(const std::string& path);

// ---- .rti, HSH ("#HSH1.2") --------------------------------------------------------------
// "#HSH1.2" / rti_type 3 / "width height 3" / "terms 2 1", then terms float scales and terms
// float biases (little-endian), then per pixel, rows top-down as relight reads them, per
// channel (R, G, B) the term bytes: coefficient/255 = byte/255·scale + bias. One scale/bias
// per term for all three channels, chosen to hold every channel's coefficients.
Status WriteRti(const std::string& path, const RelightCoefficients& c);
Result<RelightCoefficients> ReadRti(const std::string& path);

// ---- .lp ----------------------------------------------------------------------------------
// The count on the first line, then "<image> <x> <y> <z>" per line (6 decimals).
Status WriteLp(const std::string& path, const std::vector<std::string>& images,
               const std::vector<Vec3>& directions);

}  // namespace rig
