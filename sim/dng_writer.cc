// DNG through libtiff's client I/O into memory.
#include "sim/dng_writer.h"

#include <algorithm>
#include <cstring>

#include <tiffio.h>

namespace rig {
namespace {

struct MemoryFile {
  std::vector<uint8_t> bytes;
  size_t pos = 0;
};

tsize_t MemRead(thandle_t h, tdata_t buf, tsize_t size) {
  auto* f = static_cast<MemoryFile*>(h);
  const size_t n = std::min<size_t>(size_t(size), f->bytes.size() - std::min(f->pos, f->bytes.size()));
  if (n) std::memcpy(buf, f->bytes.data() + f->pos, n);
  f->pos += n;
  return tsize_t(n);
}
tsize_t MemWrite(thandle_t h, tdata_t buf, tsize_t size) {
  auto* f = static_cast<MemoryFile*>(h);
  if (f->pos + size_t(size) > f->bytes.size()) f->bytes.resize(f->pos + size_t(size));
  std::memcpy(f->bytes.data() + f->pos, buf, size_t(size));
  f->pos += size_t(size);
  return size;
}
toff_t MemSeek(thandle_t h, toff_t off, int whence) {
  auto* f = static_cast<MemoryFile*>(h);
  const toff_t base = whence == SEEK_SET ? 0 : whence == SEEK_CUR ? f->pos : f->bytes.size();
  f->pos = size_t(base + off);
  return f->pos;
}
int MemClose(thandle_t) { return 0; }
toff_t MemSize(thandle_t h) { return static_cast<MemoryFile*>(h)->bytes.size(); }
int MemMap(thandle_t, tdata_t*, toff_t*) { return 0; }
void MemUnmap(thandle_t, tdata_t, toff_t) {}

// ExposureTime (an EXIF tag) is not in libtiff's table of IFD0 tags; DNG readers (LibRaw)
// read it from IFD0 as well.
const TIFFFieldInfo kExtraFields[] = {
    {33434, 1, 1, TIFF_RATIONAL, FIELD_CUSTOM, 1, 0, const_cast<char*>("ExposureTime")},
};

}  // namespace

Result<std::vector<uint8_t>> EncodeDng(const cv::Mat& bgr16, const DngOptions& o) {
  if (bgr16.type() != CV_16UC3 || bgr16.empty())
    return MakeError(ErrorCode::kInvalidInput, "dng", "expects a non-empty CV_16UC3 image");
  if ((bgr16.cols % 2 || bgr16.rows % 2) && o.mosaic)
    return MakeError(ErrorCode::kInvalidInput, "dng", "a Bayer mosaic needs even dimensions");
  MemoryFile mem;
  TIFFSetWarningHandler(nullptr);
  TIFF* tif = TIFFClientOpen("sim.dng", "w", &mem, MemRead, MemWrite, MemSeek, MemClose, MemSize,
                             MemMap, MemUnmap);
  if (!tif) return MakeError(ErrorCode::kInternal, "dng", "libtiff cannot open a memory file");
  TIFFMergeFieldInfo(tif, kExtraFields, 1);
  const uint16_t spp = o.mosaic ? 1 : 3;
  const uint8_t version[4] = {1, 4, 0, 0}, backward[4] = {1, 1, 0, 0};
  TIFFSetField(tif, TIFFTAG_SUBFILETYPE, 0);
  TIFFSetField(tif, TIFFTAG_IMAGEWIDTH, uint32_t(bgr16.cols));
  TIFFSetField(tif, TIFFTAG_IMAGELENGTH, uint32_t(bgr16.rows));
  TIFFSetField(tif, TIFFTAG_BITSPERSAMPLE, 16);
  TIFFSetField(tif, TIFFTAG_SAMPLESPERPIXEL, spp);
  TIFFSetField(tif, TIFFTAG_COMPRESSION, COMPRESSION_NONE);
  TIFFSetField(tif, TIFFTAG_PLANARCONFIG, PLANARCONFIG_CONTIG);
  TIFFSetField(tif, TIFFTAG_PHOTOMETRIC, o.mosaic ? 32803 /* CFA */ : 34892 /* LinearRaw */);
  TIFFSetField(tif, TIFFTAG_ROWSPERSTRIP, uint32_t(bgr16.rows));
  TIFFSetField(tif, TIFFTAG_MAKE, "rig");
  TIFFSetField(tif, TIFFTAG_MODEL, o.model.c_str());
  TIFFSetField(tif, TIFFTAG_DNGVERSION, version);
  TIFFSetField(tif, TIFFTAG_DNGBACKWARDVERSION, backward);
  TIFFSetField(tif, TIFFTAG_UNIQUECAMERAMODEL, o.model.c_str());
  if (o.mosaic) {
    const uint16_t dim[2] = {2, 2};
    const uint8_t rggb[4] = {0, 1, 1, 2};
    TIFFSetField(tif, TIFFTAG_CFAREPEATPATTERNDIM, dim);
    TIFFSetField(tif, TIFFTAG_CFAPATTERN, 4, rggb);
  }
  const float black = o.black;
  const uint32_t white = o.white;
  TIFFSetField(tif, TIFFTAG_BLACKLEVEL, 1, &black);
  TIFFSetField(tif, TIFFTAG_WHITELEVEL, 1, &white);
  const float identity[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};
  TIFFSetField(tif, TIFFTAG_COLORMATRIX1, 9, identity);
  TIFFSetField(tif, TIFFTAG_CALIBRATIONILLUMINANT1, uint16_t(21));  // D65
  const float neutral[3] = {float(o.as_shot_neutral[0]), float(o.as_shot_neutral[1]),
                            float(o.as_shot_neutral[2])};
  TIFFSetField(tif, TIFFTAG_ASSHOTNEUTRAL, 3, neutral);
  if (o.exposure_s > 0) TIFFSetField(tif, 33434, double(o.exposure_s));
  std::vector<uint16_t> row(size_t(bgr16.cols) * spp);
  bool ok = true;
  for (int y = 0; y < bgr16.rows && ok; ++y) {
    const uint16_t* in = bgr16.ptr<uint16_t>(y);
    for (int x = 0; x < bgr16.cols; ++x) {
      const uint16_t b = in[3 * x], g = in[3 * x + 1], r = in[3 * x + 2];
      if (o.mosaic) {
        const bool even_row = y % 2 == 0, even_col = x % 2 == 0;
        row[x] = even_row ? (even_col ? r : g) : (even_col ? g : b);
      } else {
        row[3 * x] = r;
        row[3 * x + 1] = g;
        row[3 * x + 2] = b;
      }
    }
    ok = TIFFWriteScanline(tif, row.data(), uint32_t(y), 0) >= 0;
  }
  ok = ok && TIFFWriteDirectory(tif);
  TIFFClose(tif);
  if (!ok) return MakeError(ErrorCode::kInternal, "dng", "libtiff failed writing the image");
  return mem.bytes;
}

}  // namespace rig
