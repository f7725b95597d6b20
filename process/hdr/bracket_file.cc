// rig hdr's work: decode, response, merge, write — each timed.
#include "process/hdr/bracket_file.h"

#include <algorithm>
#include <chrono>

#include "process/io/image_io.h"
#include "process/io/raw_io.h"

namespace rig {
namespace {

using Clock = std::chrono::steady_clock;

double SinceStart(Clock::time_point t) {
  return std::chrono::duration<double>(Clock::now() - t).count();
}

// The response: linear, stored, or recovered from the bracket.
Result<ResponseCurve> BracketResponse(const BracketFileRequest& rq, const std::vector<LdrFrame>& frames,
                                      bool linear) {
  if (linear) return LinearResponse(frames.front().image.depth() == CV_16U ? 65536 : 256);
  if (!rq.response_in.empty()) return LoadResponse(rq.response_in);
  const Bracket brackets[1] = {frames};
  auto r = RecoverResponse(brackets, rq.response);
  if (!r.ok()) return r.error().Within(rq.list);
  return r;
}

}  // namespace

Result<BracketFileResult> MergeBracketFile(const BracketFileRequest& rq) {
  BracketFileResult out;
  auto t0 = Clock::now();
  RIG_ASSIGN_OR_RETURN(std::vector<LdrFrame> frames, LoadBracketList(rq.list, rq.threads));
  if (auto s = ValidateBracket(frames); !s.ok()) return s.error().Within(rq.list);
  out.decode_s = SinceStart(t0);
  // RAW frames are linear once decoded: no response to recover. A bracket mixing RAW with
  // camera-rendered frames has no one response.
  const size_t raw_frames = std::count_if(frames.begin(), frames.end(),
                                          [](const LdrFrame& f) { return IsRawPath(f.source); });
  if (raw_frames > 0 && raw_frames < frames.size()) {
    return MakeError(ErrorCode::kInvalidInput, rq.list,
                     "{} of {} frames are RAW: a bracket is all RAW or none", raw_frames,
                     frames.size());
  }
  if (raw_frames > 0 && !rq.response_in.empty()) {
    return MakeError(ErrorCode::kInvalidInput, rq.list,
                     "RAW frames are linear; --response does not apply");
  }
  t0 = Clock::now();
  RIG_ASSIGN_OR_RETURN(ResponseCurve response, BracketResponse(rq, frames, rq.linear || raw_frames > 0));
  out.response_s = SinceStart(t0);
  if (!rq.response_out.empty()) RIG_TRY(SaveResponse(response, rq.response_out));

  t0 = Clock::now();
  RIG_ASSIGN_OR_RETURN(RadianceMap map, MergeBracket(frames, response, rq.merge));
  out.merge_s = SinceStart(t0);
  for (const auto& [k, v] : rq.attributes) map.attributes[k] = v;

  t0 = Clock::now();
  RIG_TRY(WriteRadianceMap(rq.out, map, rq.pixel_type, rq.threads, rq.compression));
  out.write_s = SinceStart(t0);
  out.width = map.radiance.cols;
  out.height = map.radiance.rows;
  out.frames = frames.size();
  out.response_id = response.id;
  out.saturated_pixels = map.saturated_pixels;
  out.black_pixels = map.black_pixels;
  return out;
}

}  // namespace rig
