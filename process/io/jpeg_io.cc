// libjpeg writer and reader by bands of rows, errors turned into Result (setjmp at the C
// boundary; nothing with a destructor lives across it).
#include "process/io/jpeg_io.h"

#include <csetjmp>
#include <optional>
#include <cstdlib>
#include <cstring>
#include <vector>

#include <fcntl.h>
#include <unistd.h>

#include <fmt/format.h>

#include "config/atomic_file.h"

extern "C" {
#include <jerror.h>
#include <jpeglib.h>
}

namespace rig {
namespace {

struct ErrorManager {
  jpeg_error_mgr pub;
  std::jmp_buf jump;
  char message[JMSG_LENGTH_MAX] = {0};
  bool truncated = false;
};

void OnError(j_common_ptr cinfo) {
  auto* err = reinterpret_cast<ErrorManager*>(cinfo->err);
  (*cinfo->err->format_message)(cinfo, err->message);
  std::longjmp(err->jump, 1);
}

void OnMessage(j_common_ptr cinfo, int level) {
  auto* err = reinterpret_cast<ErrorManager*>(cinfo->err);
  // A premature end of data is a truncated file: libjpeg would fill the rest with grey.
  if (level < 0 && cinfo->err->msg_code == JWRN_JPEG_EOF) err->truncated = true;
}

}  // namespace

void SetUp(jpeg_compress_struct* cinfo, int width, int height, int channels, JpegColor color,
           int quality);

// libjpeg's output into the project's writer (config/atomic_file.h): a temporary with a fresh
// name, moved over the target when finished. A failed write is kept and reported by Finish.
struct AtomicDestination {
  jpeg_destination_mgr pub{};
  AtomicFile* file = nullptr;
  Status status = Ok();
  std::vector<JOCTET> buffer = std::vector<JOCTET>(size_t{1} << 16);

  static void Init(j_compress_ptr cinfo) {
    auto* d = reinterpret_cast<AtomicDestination*>(cinfo->dest);
    d->pub.next_output_byte = d->buffer.data();
    d->pub.free_in_buffer = d->buffer.size();
  }
  static boolean Empty(j_compress_ptr cinfo) {
    auto* d = reinterpret_cast<AtomicDestination*>(cinfo->dest);
    if (d->status.ok()) d->status = d->file->Write(d->buffer.data(), d->buffer.size());
    Init(cinfo);
    return TRUE;
  }
  static void Term(j_compress_ptr cinfo) {
    auto* d = reinterpret_cast<AtomicDestination*>(cinfo->dest);
    const size_t n = d->buffer.size() - d->pub.free_in_buffer;
    if (d->status.ok() && n > 0) d->status = d->file->Write(d->buffer.data(), n);
  }
};

struct JpegWriter::State {
  jpeg_compress_struct cinfo{};
  ErrorManager err;
  std::optional<AtomicFile> file;
  AtomicDestination dest;
  std::string path;
  int width = 0, height = 0, channels = 0, written = 0;
  bool started = false;
};

JpegWriter::~JpegWriter() {
  if (!state_) return;
  if (state_->started) jpeg_destroy_compress(&state_->cinfo);
}

Result<std::unique_ptr<JpegWriter>> JpegWriter::Open(const std::string& path, int width,
                                                     int height, int channels, JpegColor color,
                                                     int quality) {
  if (width <= 0 || height <= 0 || width > 65500 || height > 65500) {
    return MakeError(ErrorCode::kInvalidInput, path, "JPEG size {}x{} is out of range", width,
                     height);
  }
  if ((color == JpegColor::kGray) != (channels == 1) || (channels != 1 && channels != 3)) {
    return MakeError(ErrorCode::kInternal, path, "JPEG: {} channels do not fit the colour kind",
                     channels);
  }
  std::unique_ptr<JpegWriter> w(new JpegWriter);
  w->state_ = std::make_unique<State>();
  State& s = *w->state_;
  s.path = path;
  s.width = width;
  s.height = height;
  s.channels = channels;
  RIG_ASSIGN_OR_RETURN(AtomicFile file, AtomicFile::Create(path));
  s.file.emplace(std::move(file));
  s.dest.file = &*s.file;
  s.dest.pub.init_destination = AtomicDestination::Init;
  s.dest.pub.empty_output_buffer = AtomicDestination::Empty;
  s.dest.pub.term_destination = AtomicDestination::Term;
  s.cinfo.err = jpeg_std_error(&s.err.pub);
  s.err.pub.error_exit = OnError;
  s.err.pub.emit_message = OnMessage;
  if (setjmp(s.err.jump)) {
    return MakeError(ErrorCode::kIo, path, "JPEG: {}", s.err.message);
  }
  jpeg_create_compress(&s.cinfo);
  s.started = true;
  s.cinfo.dest = &s.dest.pub;
  SetUp(&s.cinfo, width, height, channels, color, quality);
  jpeg_start_compress(&s.cinfo, TRUE);
  return w;
}

Status JpegWriter::Write(const cv::Mat& rows) {
  State& s = *state_;
  if (rows.cols != s.width || rows.channels() != s.channels || rows.depth() != CV_8U ||
      s.written + rows.rows > s.height) {
    return MakeError(ErrorCode::kInternal, s.path, "JPEG rows {}x{}x{} do not fit {}x{}x{}",
                     rows.cols, rows.rows, rows.channels(), s.width, s.height, s.channels);
  }
  if (setjmp(s.err.jump)) return MakeError(ErrorCode::kIo, s.path, "JPEG: {}", s.err.message);
  for (int y = 0; y < rows.rows; ++y) {
    JSAMPROW row = const_cast<JSAMPROW>(rows.ptr<uint8_t>(y));
    jpeg_write_scanlines(&s.cinfo, &row, 1);
  }
  s.written += rows.rows;
  return Ok();
}

Status JpegWriter::Finish() {
  State& s = *state_;
  if (s.written != s.height) {
    return MakeError(ErrorCode::kInternal, s.path, "JPEG: {} of {} rows written", s.written,
                     s.height);
  }
  if (setjmp(s.err.jump)) return MakeError(ErrorCode::kIo, s.path, "JPEG: {}", s.err.message);
  jpeg_finish_compress(&s.cinfo);
  jpeg_destroy_compress(&s.cinfo);
  s.started = false;
  RIG_TRY(s.dest.status);
  Status st = s.file->Commit();
  s.file.reset();
  return st;
}

Status WriteJpeg(const std::string& path, const cv::Mat& image, JpegColor color, int quality) {
  RIG_ASSIGN_OR_RETURN(auto w, JpegWriter::Open(path, image.cols, image.rows, image.channels(),
                                                color, quality));
  RIG_TRY(w->Write(image));
  return w->Finish();
}

// Compression settings shared by the file writer and the in-memory encoder.
void SetUp(jpeg_compress_struct* cinfo, int width, int height, int channels, JpegColor color,
           int quality) {
  cinfo->image_width = static_cast<JDIMENSION>(width);
  cinfo->image_height = static_cast<JDIMENSION>(height);
  cinfo->input_components = channels;
  cinfo->in_color_space = channels == 1 ? JCS_GRAYSCALE : JCS_RGB;
  jpeg_set_defaults(cinfo);
  if (color == JpegColor::kRgb) jpeg_set_colorspace(cinfo, JCS_RGB);
  jpeg_set_quality(cinfo, quality, TRUE);
  for (int c = 0; c < cinfo->num_components; ++c) {
    cinfo->comp_info[c].h_samp_factor = 1;
    cinfo->comp_info[c].v_samp_factor = 1;
  }
  cinfo->optimize_coding = TRUE;  // smaller files at no cost in quality
}

namespace {

struct MemoryEncoder {
  jpeg_compress_struct cinfo{};
  ErrorManager err;
  unsigned char* buffer = nullptr;
  unsigned long size = 0;
  bool started = false;
  ~MemoryEncoder() {
    if (started) jpeg_destroy_compress(&cinfo);
    std::free(buffer);
  }
};

struct MemoryDecoder {
  jpeg_decompress_struct cinfo{};
  ErrorManager err;
  bool started = false;
  ~MemoryDecoder() {
    if (started) jpeg_destroy_decompress(&cinfo);
  }
};

}  // namespace

Result<std::vector<uint8_t>> EncodeJpeg(const cv::Mat& image, JpegColor color, int quality) {
  if (image.empty() || image.depth() != CV_8U || (image.channels() != 1 && image.channels() != 3) ||
      (color == JpegColor::kGray) != (image.channels() == 1)) {
    return MakeError(ErrorCode::kInternal, "jpeg", "cannot encode a {}x{}x{} image", image.cols,
                     image.rows, image.channels());
  }
  MemoryEncoder e;
  e.cinfo.err = jpeg_std_error(&e.err.pub);
  e.err.pub.error_exit = OnError;
  e.err.pub.emit_message = OnMessage;
  if (setjmp(e.err.jump)) return MakeError(ErrorCode::kInternal, "jpeg", "{}", e.err.message);
  jpeg_create_compress(&e.cinfo);
  e.started = true;
  jpeg_mem_dest(&e.cinfo, &e.buffer, &e.size);
  SetUp(&e.cinfo, image.cols, image.rows, image.channels(), color, quality);
  jpeg_start_compress(&e.cinfo, TRUE);
  for (int y = 0; y < image.rows; ++y) {
    JSAMPROW row = const_cast<JSAMPROW>(image.ptr<uint8_t>(y));
    jpeg_write_scanlines(&e.cinfo, &row, 1);
  }
  jpeg_finish_compress(&e.cinfo);
  return std::vector<uint8_t>(e.buffer, e.buffer + e.size);
}

// Bounded before allocating: 2^28 pixels (a 24 MP frame is 2^24.5; libjpeg allows 65500²).
static Status CheckJpegSize(const jpeg_decompress_struct& cinfo, const std::string& context) {
  const uint64_t pixels = uint64_t{cinfo.output_width} * cinfo.output_height;
  if (pixels == 0 || pixels > (uint64_t{1} << 28)) {
    return MakeError(ErrorCode::kInvalidInput, context,
                     "JPEG of {}x{} pixels: beyond the 2^28 pixels read here", cinfo.output_width,
                     cinfo.output_height);
  }
  return Ok();
}

Result<cv::Mat> DecodeJpeg(const std::vector<uint8_t>& bytes, const std::string& context) {
  MemoryDecoder d;
  d.cinfo.err = jpeg_std_error(&d.err.pub);
  d.err.pub.error_exit = OnError;
  d.err.pub.emit_message = OnMessage;
  cv::Mat out;
  if (setjmp(d.err.jump)) {
    return MakeError(ErrorCode::kInvalidInput, context, "not a readable JPEG: {}", d.err.message);
  }
  jpeg_create_decompress(&d.cinfo);
  d.started = true;
  jpeg_mem_src(&d.cinfo, bytes.data(), static_cast<unsigned long>(bytes.size()));
  jpeg_read_header(&d.cinfo, TRUE);
  d.cinfo.out_color_space = d.cinfo.num_components == 1 ? JCS_GRAYSCALE : JCS_RGB;
  jpeg_start_decompress(&d.cinfo);
  RIG_TRY(CheckJpegSize(d.cinfo, context));
  out.create(static_cast<int>(d.cinfo.output_height), static_cast<int>(d.cinfo.output_width),
             CV_MAKETYPE(CV_8U, d.cinfo.output_components));
  // Stops at the end of the data: a header claiming 65500x65500 in a few bytes would otherwise
  // be decoded into grey row by row (found by tests/fuzz/jpeg).
  for (int y = 0; y < out.rows && !d.err.truncated; ++y) {
    JSAMPROW row = out.ptr<uint8_t>(y);
    jpeg_read_scanlines(&d.cinfo, &row, 1);
  }
  if (d.err.truncated) return MakeError(ErrorCode::kInvalidInput, context, "truncated JPEG");
  jpeg_finish_decompress(&d.cinfo);
  return out;
}

struct JpegReader::State {
  jpeg_decompress_struct cinfo{};
  ErrorManager err;
  FILE* file = nullptr;
  std::string path;
  bool started = false;
};

JpegReader::~JpegReader() {
  if (!state_) return;
  if (state_->started) jpeg_destroy_decompress(&state_->cinfo);
}

Result<std::unique_ptr<JpegReader>> JpegReader::Open(const std::string& path) {
  std::unique_ptr<JpegReader> r(new JpegReader);
  r->state_ = std::make_unique<State>();
  State& s = *r->state_;
  s.path = path;
  s.file = std::fopen(path.c_str(), "rb");
  if (!s.file) return MakeError(ErrorCode::kNotFound, path, "cannot open: {}", std::strerror(errno));
  s.cinfo.err = jpeg_std_error(&s.err.pub);
  s.err.pub.error_exit = OnError;
  s.err.pub.emit_message = OnMessage;
  if (setjmp(s.err.jump)) {
    return MakeError(ErrorCode::kInvalidInput, path, "not a readable JPEG: {}", s.err.message);
  }
  jpeg_create_decompress(&s.cinfo);
  s.started = true;
  jpeg_stdio_src(&s.cinfo, s.file);
  jpeg_read_header(&s.cinfo, TRUE);
  s.cinfo.out_color_space = s.cinfo.num_components == 1 ? JCS_GRAYSCALE : JCS_RGB;
  jpeg_start_decompress(&s.cinfo);
  if (s.err.truncated) return MakeError(ErrorCode::kInvalidInput, path, "truncated JPEG");
  RIG_TRY(CheckJpegSize(s.cinfo, path));
  return r;
}

int JpegReader::width() const { return static_cast<int>(state_->cinfo.output_width); }
int JpegReader::height() const { return static_cast<int>(state_->cinfo.output_height); }
int JpegReader::channels() const { return state_->cinfo.output_components; }
bool JpegReader::rgb_space() const { return state_->cinfo.jpeg_color_space == JCS_RGB; }

Status JpegReader::Read(int count, cv::Mat* rows) {
  State& s = *state_;
  const int left = static_cast<int>(s.cinfo.output_height - s.cinfo.output_scanline);
  if (count > left) {
    return MakeError(ErrorCode::kInternal, s.path, "JPEG: {} rows asked, {} left", count, left);
  }
  rows->create(count, width(), CV_MAKETYPE(CV_8U, channels()));
  if (setjmp(s.err.jump)) {
    return MakeError(ErrorCode::kInvalidInput, s.path, "corrupt JPEG: {}", s.err.message);
  }
  for (int y = 0; y < count && !s.err.truncated; ++y) {
    JSAMPROW row = rows->ptr<uint8_t>(y);
    jpeg_read_scanlines(&s.cinfo, &row, 1);
  }
  if (s.err.truncated) return MakeError(ErrorCode::kInvalidInput, s.path, "truncated JPEG");
  return Ok();
}

Result<cv::Mat> ReadJpeg(const std::string& path) {
  RIG_ASSIGN_OR_RETURN(auto r, JpegReader::Open(path));
  cv::Mat out;
  RIG_TRY(r->Read(r->height(), &out));
  return out;
}

}  // namespace rig
