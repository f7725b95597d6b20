// The lens's focal length and the sensor's width from a photograph's EXIF, through libexif.
#include "process/io/exif.h"

#include <cmath>
#include <filesystem>
#include <memory>

#include <fmt/format.h>
#include <libexif/exif-data.h>

namespace rig {
namespace {

// The first entry with `tag` in any IFD.
ExifEntry* Find(ExifData* d, ExifTag tag) {
  for (int ifd = 0; ifd < EXIF_IFD_COUNT; ++ifd)
    if (d->ifd[ifd])
      if (ExifEntry* e = exif_content_get_entry(d->ifd[ifd], tag)) return e;
  return nullptr;
}

// A numeric entry's first value; 0 when absent, empty or of another kind.
double Number(ExifData* d, ExifTag tag) {
  ExifEntry* e = Find(d, tag);
  if (!e || !e->data || e->components < 1) return 0;
  if (e->size < exif_format_get_size(e->format)) return 0;
  const ExifByteOrder order = exif_data_get_byte_order(d);
  switch (e->format) {
    case EXIF_FORMAT_RATIONAL: {
      const ExifRational r = exif_get_rational(e->data, order);
      return r.denominator ? static_cast<double>(r.numerator) / r.denominator : 0;
    }
    case EXIF_FORMAT_SRATIONAL: {
      const ExifSRational r = exif_get_srational(e->data, order);
      return r.denominator ? static_cast<double>(r.numerator) / r.denominator : 0;
    }
    case EXIF_FORMAT_SHORT: return exif_get_short(e->data, order);
    case EXIF_FORMAT_LONG: return exif_get_long(e->data, order);
    default: return 0;
  }
}

ExifFocal FocalFromTags(const ExifLens& lens, int width_px, int height_px);

}  // namespace

Result<ExifLens> ReadExifLens(const std::string& path) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec))
    return MakeError(ErrorCode::kNotFound, path, "no such file (reading its EXIF)");
  std::unique_ptr<ExifData, void (*)(ExifData*)> d(exif_data_new_from_file(path.c_str()),
                                                   exif_data_unref);
  ExifLens lens;
  if (!d) return lens;  // no EXIF block
  lens.has_exif = true;
  lens.focal_mm = Number(d.get(), EXIF_TAG_FOCAL_LENGTH);
  lens.focal_35mm = Number(d.get(), EXIF_TAG_FOCAL_LENGTH_IN_35MM_FILM);
  lens.exif_width_px = static_cast<int>(Number(d.get(), EXIF_TAG_PIXEL_X_DIMENSION));
  const double xres = Number(d.get(), EXIF_TAG_FOCAL_PLANE_X_RESOLUTION);
  // FocalPlaneResolutionUnit: 2 inch (EXIF's default when absent), 3 cm; TIFF/EP adds 4 mm and
  // 5 um, which some bodies write; 1 (no unit) cannot place the sensor.
  const int unit_tag = static_cast<int>(Number(d.get(), EXIF_TAG_FOCAL_PLANE_RESOLUTION_UNIT));
  const int unit = unit_tag == 0 ? 2 : unit_tag;
  const double mm_per_unit = unit == 2 ? 25.4 : unit == 3 ? 10.0 : unit == 4 ? 1.0
                             : unit == 5 ? 1e-3 : 0.0;
  if (xres > 0 && mm_per_unit > 0) lens.x_res_per_mm = xres / mm_per_unit;
  return lens;
}

ExifFocal FocalFromExif(const ExifLens& lens, int width_px, int height_px) {
  ExifFocal f = FocalFromTags(lens, width_px, height_px);
  // Tags are the file's word: a focal length or a sensor outside any camera's is no model.
  constexpr double kMaxFocalMm = 5000, kMinSensorMm = 0.5, kMaxSensorMm = 500;
  if (f.focal_mm > 0 && !(std::isfinite(f.focal_mm) && f.focal_mm <= kMaxFocalMm &&
                          std::isfinite(f.sensor_width_mm) && f.sensor_width_mm >= kMinSensorMm &&
                          f.sensor_width_mm <= kMaxSensorMm)) {
    ExifFocal refused;
    refused.how = fmt::format("EXIF gives focal length {:g} mm and sensor width {:g} mm, outside "
                              "any camera's (focal up to {:g} mm, sensor {:g}-{:g} mm): not used",
                              f.focal_mm, f.sensor_width_mm, kMaxFocalMm, kMinSensorMm,
                              kMaxSensorMm);
    return refused;
  }
  return f;
}

namespace {

ExifFocal FocalFromTags(const ExifLens& lens, int width_px, int height_px) {
  ExifFocal f;
  if (!lens.has_exif) return f;
  if (lens.focal_mm > 0 && lens.x_res_per_mm > 0) {
    const int w = lens.exif_width_px > 0 ? lens.exif_width_px : width_px;
    f.focal_mm = lens.focal_mm;
    f.sensor_width_mm = w / lens.x_res_per_mm;
    f.how = fmt::format("EXIF FocalLength {:.2f} mm, sensor {:.2f} mm wide from "
                        "FocalPlaneXResolution ({:.1f} px/mm over {} px)", f.focal_mm,
                        f.sensor_width_mm, lens.x_res_per_mm, w);
    return f;
  }
  if (lens.focal_35mm > 0 && width_px > 0 && height_px > 0) {
    // The 35 mm equivalent scales the diagonal (43.27 mm for a 36 x 24 mm frame); the width
    // follows from the image's aspect.
    const double diag_35 = std::hypot(36.0, 24.0);
    const double width_of_diag = width_px / std::hypot(static_cast<double>(width_px), height_px);
    const double f_mm = lens.focal_mm > 0 ? lens.focal_mm : lens.focal_35mm;
    f.focal_mm = f_mm;
    f.sensor_width_mm = diag_35 * f_mm / lens.focal_35mm * width_of_diag;
    f.how = lens.focal_mm > 0
                ? fmt::format("EXIF FocalLength {:.2f} mm, sensor {:.2f} mm wide from "
                              "FocalLengthIn35mmFilm {:.0f} mm", f.focal_mm, f.sensor_width_mm,
                              lens.focal_35mm)
                : fmt::format("EXIF FocalLengthIn35mmFilm {:.0f} mm (no FocalLength: a 35 mm "
                              "frame's {:.2f} mm width)", lens.focal_35mm, f.sensor_width_mm);
  }
  return f;
}

}  // namespace

}  // namespace rig
