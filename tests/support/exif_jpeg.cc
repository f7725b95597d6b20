// Test-only JPEGs with EXIF: libexif builds and serialises the block, spliced after the SOI.
#include "tests/support/exif_jpeg.h"

#include <cmath>
#include <cstdlib>
#include <fstream>
#include <vector>

#include <libexif/exif-data.h>
#include <opencv2/imgcodecs.hpp>

namespace rig::testing {
namespace {

// A one-component entry of `format` for `tag` in `ifd`, its data allocated; owned by `d`.
unsigned char* AddEntry(ExifData* d, ExifIfd ifd, ExifTag tag, ExifFormat format) {
  ExifEntry* e = exif_entry_new();
  ExifMem* mem = exif_mem_new_default();
  e->tag = tag;
  e->format = format;
  e->components = 1;
  e->size = exif_format_get_size(format);
  e->data = static_cast<unsigned char*>(exif_mem_alloc(mem, e->size));
  exif_mem_unref(mem);
  exif_content_add_entry(d->ifd[ifd], e);
  exif_entry_unref(e);
  return e->data;
}

ExifRational Rational(double v) {
  return {static_cast<ExifLong>(std::lround(v * 1000)), 1000};
}

}  // namespace

bool WriteJpegWithExif(const std::string& path, const cv::Mat& bgr, const ExifTags& tags) {
  std::vector<uint8_t> jpeg;
  if (!cv::imencode(".jpg", bgr, jpeg, {cv::IMWRITE_JPEG_QUALITY, 95}) || jpeg.size() < 4)
    return false;
  ExifData* d = exif_data_new();
  // Only the tags asked for (no mandatory defaults added, no PixelXDimension the test left out).
  exif_data_unset_option(d, EXIF_DATA_OPTION_FOLLOW_SPECIFICATION);
  const ExifByteOrder o = EXIF_BYTE_ORDER_INTEL;
  exif_data_set_byte_order(d, o);
  if (tags.focal_mm > 0)
    exif_set_rational(AddEntry(d, EXIF_IFD_EXIF, EXIF_TAG_FOCAL_LENGTH, EXIF_FORMAT_RATIONAL), o,
                      Rational(tags.focal_mm));
  if (tags.focal_35mm > 0)
    exif_set_short(AddEntry(d, EXIF_IFD_EXIF, EXIF_TAG_FOCAL_LENGTH_IN_35MM_FILM,
                            EXIF_FORMAT_SHORT), o, static_cast<ExifShort>(tags.focal_35mm));
  if (tags.focal_plane_x_res > 0)
    exif_set_rational(AddEntry(d, EXIF_IFD_EXIF, EXIF_TAG_FOCAL_PLANE_X_RESOLUTION,
                               EXIF_FORMAT_RATIONAL), o, Rational(tags.focal_plane_x_res));
  if (tags.focal_plane_unit > 0)
    exif_set_short(AddEntry(d, EXIF_IFD_EXIF, EXIF_TAG_FOCAL_PLANE_RESOLUTION_UNIT,
                            EXIF_FORMAT_SHORT), o, static_cast<ExifShort>(tags.focal_plane_unit));
  if (tags.pixel_x_dimension > 0)
    exif_set_long(AddEntry(d, EXIF_IFD_EXIF, EXIF_TAG_PIXEL_X_DIMENSION, EXIF_FORMAT_LONG), o,
                  static_cast<ExifLong>(tags.pixel_x_dimension));
  unsigned char* block = nullptr;
  unsigned int size = 0;
  exif_data_save_data(d, &block, &size);  // starts with "Exif\0\0"
  exif_data_unref(d);
  if (!block || size == 0 || size + 2 > 0xFFFF) {
    std::free(block);
    return false;
  }
  std::vector<uint8_t> out(jpeg.begin(), jpeg.begin() + 2);  // SOI
  out.push_back(0xFF);
  out.push_back(0xE1);
  out.push_back(static_cast<uint8_t>((size + 2) >> 8));
  out.push_back(static_cast<uint8_t>((size + 2) & 0xFF));
  out.insert(out.end(), block, block + size);
  std::free(block);
  out.insert(out.end(), jpeg.begin() + 2, jpeg.end());
  std::ofstream f(path, std::ios::binary | std::ios::trunc);
  f.write(reinterpret_cast<const char*>(out.data()), static_cast<std::streamsize>(out.size()));
  return static_cast<bool>(f.flush());
}

}  // namespace rig::testing
