// rig hdr --list LIST --out FILE.exr: merges one exposure bracket into a radiance map (EXR).
#include <cstdio>
#include <map>
#include <string>
#include <vector>

#include "process/hdr/bracket_file.h"
#include "rig/commands/command.h"

namespace rig {

int RunHdr(int argc, char** argv) {
  CLI::App app{"Merge one exposure bracket into a float radiance map (OpenEXR).\n"
               "LIST holds one '<image> <exposure_s>' per line (exposures increasing, '#' "
               "comments; relative paths are relative to the LIST's folder).",
               "rig hdr"};
  std::string list, out, response_in, response_out, pixel_type = "float", log_level;
  // RLE: this command is the quick way to one map; on float radiance it costs a tenth of
  // ZIP's time for a file about a fifth larger (docs/hdr.md). Sessions keep ZIP
  // ([process] hdr_compression).
  std::string compression = "rle";
  std::vector<std::string> attributes;
  bool linear = false;
  ResponseOptions ro;
  MergeOptions mo;
  int threads = 2;
  app.add_option("--list", list, "bracket list file")->required();
  app.add_option("--out", out, "output radiance map (.exr)")->required();
  app.add_option("--response", response_in,
                 "use this stored response curve (CSV from --save-response) instead of "
                 "recovering one");
  app.add_option("--save-response", response_out, "write the response curve used (CSV)");
  app.add_flag("--linear", linear, "the frames are linear (decoded RAW): no response recovery");
  app.add_option("--lambda", ro.lambda, "smoothness of the recovered response (relative)")
      ->check(CLI::NonNegativeNumber);
  app.add_option("--samples", ro.samples, "sample patches for response recovery")
      ->check(CLI::PositiveNumber);
  app.add_option("--threads", threads, "threads for decoding, merging and writing")
      ->check(CLI::Range(1, 64));
  std::string weighting = "noise";
  app.add_option("--weighting", weighting,
                 "merge weights: hat (Debevec-Malik), photon (hat x exposure), noise (inverse "
                 "variance under a noise model fitted to the bracket)")
      ->check(CLI::IsMember({"hat", "photon", "noise"}));
  app.add_option("--pixel-type", pixel_type, "EXR pixel type")
      ->check(CLI::IsMember({"half", "float"}));
  app.add_option("--compression", compression,
                 "EXR compression, all lossless: rle (fast), none (fastest, largest), zip "
                 "(small, slow), zip-fast (zlib level 1), piz, zips; docs/hdr.md measures each")
      ->check(CLI::IsMember(ExrCompressionNames()));
  app.add_option("--max-unrecorded", mo.max_unrecorded_fraction,
                 "largest fraction of pixels saturated (or black) in every exposure before the "
                 "bracket is rejected as too short (1: never)")
      ->check(CLI::Range(0.0, 1.0));
  app.add_option("--attribute", attributes, "extra EXR header attribute KEY=VALUE (repeatable)");
  AddLogLevelOption(app, &log_level);
  if (auto rc = ParseCommandLine(app, argc, argv)) return *rc;
  if (auto rc = ApplyLogLevel(log_level)) return *rc;
  if (linear && !response_in.empty()) {
    std::fprintf(stderr, "rig hdr: --linear and --response exclude each other\n");
    return 2;
  }
  std::map<std::string, std::string> extra;
  for (const auto& a : attributes) {
    const size_t eq = a.find('=');
    if (eq == std::string::npos || eq == 0) {
      std::fprintf(stderr, "rig hdr: --attribute '%s' is not KEY=VALUE\n", a.c_str());
      return 2;
    }
    extra[a.substr(0, eq)] = a.substr(eq + 1);
  }
  ro.threads = mo.threads = threads;
  mo.weighting = *ParseMergeWeighting(weighting);
  BracketFileRequest rq;
  rq.list = list;
  rq.out = out;
  rq.response_in = response_in;
  rq.response_out = response_out;
  rq.linear = linear;
  rq.response = ro;
  rq.merge = mo;
  rq.pixel_type = *ParseExrPixelType(pixel_type);
  rq.compression = *ParseExrCompression(compression);
  rq.attributes = extra;
  rq.threads = threads;
  auto r = MergeBracketFile(rq);
  if (!r.ok()) return ReportError("hdr", r.error());
  const double pixels = double(r->width) * r->height;
  std::printf("%s: %dx%d from %zu frames, response %s; saturated %d (%.2f%%), black %d (%.2f%%); "
              "decode %.3f s, response %.3f s, merge %.3f s, write %.3f s\n",
              out.c_str(), r->width, r->height, r->frames, r->response_id.c_str(),
              r->saturated_pixels, 100.0 * r->saturated_pixels / pixels, r->black_pixels,
              100.0 * r->black_pixels / pixels, r->decode_s, r->response_s, r->merge_s, r->write_s);
  return 0;
}

}  // namespace rig
