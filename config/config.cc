// Reading, validating and writing the TOML configuration. The schema is written once, in
// VisitConfig(): the reader and the writer both walk it, so they cannot disagree.
#include "config/config.h"

#include "config/did_you_mean.h"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <optional>
#include <set>
#include <sstream>

#define TOML_EXCEPTIONS 1
#include <toml++/toml.h>

namespace rig {
namespace {

struct Range {
  double min = -1e300, max = 1e300;
};

std::string Join(const std::vector<std::string>& v, const char* sep) {
  std::string out;
  for (size_t i = 0; i < v.size(); ++i) out += (i ? sep : "") + v[i];
  return out;
}

// Walks the schema reading a parsed TOML document; collects every problem.
class Reader {
 public:
  Reader(const toml::table& root, std::string file, std::vector<ConfigDiagnostic>* out)
      : root_(root), file_(std::move(file)), out_(out) {}

  template <typename F>
  void Section(const std::string& name, bool required, F&& body) {
    const toml::table* parent = stack_.empty() ? &root_ : stack_.back().table;
    std::string path = stack_.empty() ? name : stack_.back().path + "." + name;
    const toml::node* node = parent ? parent->get(name) : nullptr;
    const toml::table* table = nullptr;
    if (node && !node->is_table()) {
      Report(node->source(), path, "expected a table [" + path + "]");
    } else if (node) {
      table = node->as_table();
      positions_[path] = node->source();
    } else if (required) {
      ReportMissing(path, "missing required table [" + path + "]");
    }
    stack_.push_back({table, path, {}});
    body();
    Frame frame = std::move(stack_.back());
    stack_.pop_back();
    if (frame.table) CheckUnknown(*frame.table, frame.path, frame.known);
  }

  void Field(const char* key, double& v, Range r, bool required = false) {
    const toml::node* n = Find(key, required);
    if (!n) return;
    std::optional<double> d;
    if (auto f = n->value<double>()) d = *f;  // integers convert too
    if (!d) return TypeError(n, key, "a number");
    if (!std::isfinite(*d) || *d < r.min || *d > r.max)
      return Report(n->source(), PathOf(key),
                    fmt::format("{} is out of range [{}, {}]", *d, r.min, r.max));
    v = *d;
  }
  void Field(const char* key, int& v, Range r, bool required = false) {
    const toml::node* n = Find(key, required);
    if (!n) return;
    if (!n->is_integer()) return TypeError(n, key, "an integer");
    int64_t i = *n->value<int64_t>();
    if (i < r.min || i > r.max)
      return Report(n->source(), PathOf(key),
                    fmt::format("{} is out of range [{}, {}]", i, r.min, r.max));
    v = static_cast<int>(i);
  }
  void Field(const char* key, bool& v, bool required = false) {
    const toml::node* n = Find(key, required);
    if (!n) return;
    if (!n->is_boolean()) return TypeError(n, key, "true or false");
    v = *n->value<bool>();
  }
  void Field(const char* key, std::string& v, std::vector<std::string> choices = {},
             bool required = false) {
    const toml::node* n = Find(key, required);
    if (!n) return;
    if (!n->is_string()) return TypeError(n, key, "a string");
    std::string s = *n->value<std::string>();
    if (!choices.empty() && std::find(choices.begin(), choices.end(), s) == choices.end()) {
      std::string hint = DidYouMean(s, choices);
      return Report(n->source(), PathOf(key),
                    fmt::format("'{}' is not one of: {}{}", s, Join(choices, ", "),
                                hint.empty() ? "" : " (did you mean '" + hint + "'?)"));
    }
    v = s;
  }
  void Field(const char* key, std::vector<double>& v, Range r, size_t min_len = 0) {
    const toml::node* n = Find(key, false);
    if (!n) return;
    const toml::array* a = n->as_array();
    if (!a) return TypeError(n, key, "an array of numbers");
    std::vector<double> out;
    for (const auto& e : *a) {
      auto d = e.value<double>();
      if (!d) return TypeError(&e, key, "an array of numbers");
      if (!std::isfinite(*d) || *d < r.min || *d > r.max)
        return Report(e.source(), PathOf(key),
                      fmt::format("element {} is out of range [{}, {}]", *d, r.min, r.max));
      out.push_back(*d);
    }
    if (out.size() < min_len)
      return Report(n->source(), PathOf(key),
                    fmt::format("needs at least {} elements, has {}", min_len, out.size()));
    v = out;
  }
  void Field(const char* key, std::vector<int>& v, Range r) {
    const toml::node* n = Find(key, false);
    if (!n) return;
    const toml::array* a = n->as_array();
    if (!a) return TypeError(n, key, "an array of integers");
    std::vector<int> out;
    for (const auto& e : *a) {
      if (!e.is_integer()) return TypeError(&e, key, "an array of integers");
      int64_t i = *e.value<int64_t>();
      if (i < r.min || i > r.max)
        return Report(e.source(), PathOf(key),
                      fmt::format("element {} is out of range [{}, {}]", i, r.min, r.max));
      out.push_back(static_cast<int>(i));
    }
    v = out;
  }
  template <typename T, size_t N>
  void Field(const char* key, std::array<T, N>& v, Range r) {
    const toml::node* n = Find(key, false);
    if (!n) return;
    const toml::array* a = n->as_array();
    const char* what = std::is_integral_v<T> ? "integers" : "numbers";
    if (!a || a->size() != N)
      return TypeError(n, key, fmt::format("an array of {} {}", N, what));
    std::array<T, N> out{};
    for (size_t i = 0; i < N; ++i) {
      const toml::node& e = *a->get(i);
      std::optional<double> d;
      if constexpr (std::is_integral_v<T>) {
        if (e.is_integer()) d = static_cast<double>(*e.value<int64_t>());
      } else {
        d = e.value<double>();
      }
      if (!d) return TypeError(n, key, fmt::format("an array of {} {}", N, what));
      if (!std::isfinite(*d) || *d < r.min || *d > r.max)
        return Report(e.source(), PathOf(key),
                      fmt::format("element {} is out of range [{}, {}]", *d, r.min, r.max));
      out[i] = static_cast<T>(*d);
    }
    v = out;
  }
  // The model order: an integer, or "auto" (stored as -1).
  // A number whose value `absent` the writer leaves out (read like any other).
  void OptionalField(const char* key, double& v, Range r, double) { Field(key, v, r); }
  void OrderField(const char* key, int& v, Range r) {
    const toml::node* n = Find(key, false);
    if (!n) return;
    if (n->is_string() && *n->value<std::string>() == "auto") {
      v = -1;
      return;
    }
    if (!n->is_integer()) return TypeError(n, key, "an integer or \"auto\"");
    int64_t i = *n->value<int64_t>();
    if (i < r.min || i > r.max)
      return Report(n->source(), PathOf(key),
                    fmt::format("{} is out of range [{}, {}]", i, r.min, r.max));
    v = static_cast<int>(i);
  }

  // Reports a problem at a key's position (or its section's, if the key is absent).
  void ReportAt(const std::string& key_path, const std::string& message) {
    auto it = positions_.find(key_path);
    if (it != positions_.end()) return Report(it->second, key_path, message);
    ReportMissing(key_path, message);
  }

  void Finish() { CheckUnknown(root_, "", root_known_); }

 private:
  struct Frame {
    const toml::table* table;
    std::string path;
    std::vector<std::string> known;
  };

  const toml::node* Find(const char* key, bool required) {
    Frame& f = stack_.back();
    f.known.push_back(key);
    const toml::node* n = f.table ? f.table->get(key) : nullptr;
    if (n) positions_[PathOf(key)] = n->source();
    // A missing required table was reported already; its keys are not reported again.
    if (!n && required && f.table) ReportMissing(PathOf(key), "missing required key");
    return n;
  }
  std::string PathOf(const char* key) const { return stack_.back().path + "." + key; }

  void TypeError(const toml::node* n, const char* key, const std::string& want) {
    Report(n->source(), PathOf(key), "expected " + want);
  }
  void Report(const toml::source_region& where, const std::string& path,
              const std::string& message) {
    out_->push_back({file_, static_cast<int>(where.begin.line),
                     static_cast<int>(where.begin.column), path, message});
  }
  void ReportMissing(const std::string& path, const std::string& message) {
    // Point at the enclosing table where it exists, else at the file.
    std::string parent = path.substr(0, path.rfind('.') == std::string::npos ? 0 : path.rfind('.'));
    auto it = positions_.find(parent);
    if (it != positions_.end()) {
      out_->push_back({file_, static_cast<int>(it->second.begin.line),
                       static_cast<int>(it->second.begin.column), path, message});
    } else {
      out_->push_back({file_, 0, 0, path, message});
    }
  }
  void CheckUnknown(const toml::table& t, const std::string& path,
                    const std::vector<std::string>& known) {
    for (const auto& [k, node] : t) {
      std::string key(k.str());
      if (std::find(known.begin(), known.end(), key) != known.end()) continue;
      std::string hint = DidYouMean(key, known);
      std::string where = path.empty() ? "at the top level" : "in [" + path + "]";
      Report(k.source().begin.line ? k.source() : node.source(),
             path.empty() ? key : path + "." + key,
             fmt::format("unknown key '{}' {}{}", key, where,
                         hint.empty() ? "" : " (did you mean '" + hint + "'?)"));
    }
  }

 public:
  // Sections register themselves as known keys of their parent.
  void NoteSection(const std::string& name) {
    if (stack_.empty()) root_known_.push_back(name);
    else stack_.back().known.push_back(name);
  }

 private:
  const toml::table& root_;
  std::string file_;
  std::vector<ConfigDiagnostic>* out_;
  std::vector<Frame> stack_;
  std::vector<std::string> root_known_;
  std::map<std::string, toml::source_region> positions_;
};

// Walks the schema building a TOML document.
class Writer {
 public:
  template <typename F>
  void Section(const std::string& name, bool, F&& body) {
    toml::table* parent = stack_.empty() ? &root_ : stack_.back();
    parent->insert_or_assign(name, toml::table{});
    stack_.push_back(parent->get(name)->as_table());
    body();
    stack_.pop_back();
  }
  void NoteSection(const std::string&) {}
  void Field(const char* key, double& v, Range, bool = false) { Put(key, v); }
  void Field(const char* key, int& v, Range, bool = false) { Put(key, int64_t{v}); }
  void Field(const char* key, bool& v, bool = false) { Put(key, v); }
  void Field(const char* key, std::string& v, std::vector<std::string> = {}, bool = false) {
    if (!v.empty()) Put(key, v);
  }
  void Field(const char* key, std::vector<double>& v, Range, size_t = 0) {
    if (v.empty()) return;
    toml::array a;
    for (double d : v) a.push_back(d);
    Put(key, a);
  }
  void Field(const char* key, std::vector<int>& v, Range) {
    if (v.empty()) return;
    toml::array a;
    for (int d : v) a.push_back(int64_t{d});
    Put(key, a);
  }
  template <typename T, size_t N>
  void Field(const char* key, std::array<T, N>& v, Range) {
    toml::array a;
    for (T d : v) {
      if constexpr (std::is_integral_v<T>) a.push_back(int64_t{d});
      else a.push_back(static_cast<double>(d));
    }
    Put(key, a);
  }
  void OptionalField(const char* key, double& v, Range, double absent) {
    if (v != absent) Put(key, v);
  }
  void OrderField(const char* key, int& v, Range) {
    if (v < 0) Put(key, std::string("auto"));
    else Put(key, int64_t{v});
  }
  std::string Text() const {
    std::ostringstream s;
    s << root_;
    return s.str();
  }

 private:
  template <typename T>
  void Put(const char* key, T&& v) {
    stack_.back()->insert_or_assign(key, std::forward<T>(v));
  }
  toml::table root_;
  std::vector<toml::table*> stack_;
};

constexpr Range kPositive{1e-12, 1e300};
constexpr Range kNonNegative{0, 1e300};
constexpr Range kAngle{-360, 360};

// A section of the schema: noted (for unknown-key checks), then visited.
template <typename V, typename Body>
void VisitSection(V& v, const std::string& name, bool required, Body&& body) {
  v.NoteSection(name);
  v.Section(name, required, body);
}

// The schema: every section and key, once — a function per top-level section.
template <typename V>
void VisitGridSection(Config& c, V& v) {
  auto& g = c.grid;
  v.Field("h_min_deg", g.h_min_deg, kAngle);
  v.Field("h_max_deg", g.h_max_deg, kAngle);
  v.Field("h_step_deg", g.h_step_deg, Range{0.01, 360});
  v.Field("v_min_deg", g.v_min_deg, Range{-90, 90});
  v.Field("v_max_deg", g.v_max_deg, Range{-90, 90});
  v.Field("v_step_deg", g.v_step_deg, Range{0.01, 180});
  v.Field("order", g.order, {"serpentine", "raster"});
  v.Field("mode", g.mode, {"full", "adaptive"});
  v.Field("max_poses", g.max_poses, Range{0, 100000});
  v.Field("seed_poses", g.seed_poses, Range{1, 1000});
  v.Field("target", g.target, Range{0, 1});
  v.Field("pose_cost_s", g.pose_cost_s, Range{-1, 3600});
}

template <typename V>
void VisitBracketSection(Config& c, V& v) {
  auto& b = c.bracket;
  v.Field("exposure_times_s", b.exposure_times_s, Range{1e-6, 3600}, 1);
  v.Field("center_s", b.center_s, Range{0, 3600});
  v.Field("ev_step", b.ev_step, Range{0.1, 6});
  v.Field("count", b.count, Range{0, 64});
  v.Field("mode", b.mode, {"fixed", "adaptive"});
}

template <typename V>
void VisitCameraSection(Config& c, V& v) {
  auto& k = c.camera;
  v.Field("backend", k.backend, {"sim", "gphoto2"}, true);
  v.Field("model", k.model);
  v.Field("port", k.port);
  v.Field("serial", k.serial);
  v.Field("iso", k.iso);
  v.Field("aperture", k.aperture);
  v.Field("white_balance", k.white_balance);
  v.Field("capture_target", k.capture_target, {"ram", "card"});
  v.Field("delete_from_card", k.delete_from_card);
  v.Field("capture_raw", k.capture_raw);
  v.Field("format", k.format, {"jpeg", "raw+jpeg", "raw"});
  v.Field("linear", k.linear);
  v.Field("retries", k.retries, Range{0, 100});
  v.Field("retry_backoff_s", k.retry_backoff_s, Range{0, 600});
  v.Field("call_timeout_s", k.call_timeout_s, Range{0.01, 3600});
  v.Field("capture_deadline_s", k.capture_deadline_s, Range{0.01, 36000});
  v.Field("exif_tolerance", k.exif_tolerance, Range{0, 10});
}

template <typename V>
void VisitMotorSection(Config& c, V& v) {
  auto& m = c.motor;
  v.Field("backend", m.backend, {"sim", "grbl", "maestro"}, true);
  v.Field("port", m.port);
  v.Field("usb_vid_pid", m.usb_vid_pid);
  v.Field("usb_serial", m.usb_serial);
  v.Field("baud", m.baud, Range{300, 4000000});
  v.Field("speed_deg_per_s", m.speed_deg_per_s, kPositive);
  v.Field("accel_deg_per_s2", m.accel_deg_per_s2, kPositive);
  v.Field("settle_time_s", m.settle_time_s, Range{0, 60});
  v.Field("home_on_start", m.home_on_start);
  v.Field("after_reconnect", m.after_reconnect, {"home", "verify"});
  v.Field("reply_timeout_s", m.reply_timeout_s, Range{0.01, 600});
  v.Field("move_timeout_s", m.move_timeout_s, Range{0.01, 3600});
  v.Field("retries", m.retries, Range{0, 100});
  v.Field("retry_backoff_s", m.retry_backoff_s, Range{0, 600});
  v.Field("h_limit_min_deg", m.h_limit_min_deg, kAngle);
  v.Field("h_limit_max_deg", m.h_limit_max_deg, kAngle);
  v.Field("v_limit_min_deg", m.v_limit_min_deg, kAngle);
  v.Field("v_limit_max_deg", m.v_limit_max_deg, kAngle);
  VisitSection(v, "grbl", false, [&] {
    auto& g = m.grbl;
    v.Field("h_axis", g.h_axis, {"X", "Y", "Z"});
    v.Field("v_axis", g.v_axis, {"X", "Y", "Z"});
    v.Field("units_per_degree", g.units_per_degree, kPositive);
    v.Field("completion", g.completion, {"dwell", "poll"});
    v.Field("banner_timeout_s", g.banner_timeout_s, Range{0.01, 60});
    v.Field("poll_interval_s", g.poll_interval_s, Range{0.001, 10});
  });
  VisitSection(v, "maestro", false, [&] {
    auto& s = m.maestro;
    v.Field("h_channel", s.h_channel, Range{0, 23});
    v.Field("v_channel", s.v_channel, Range{0, 23});
    v.Field("h_us_at_zero", s.h_us_at_zero, Range{64, 4080});
    v.Field("h_us_per_deg", s.h_us_per_deg, Range{-100, 100});
    v.Field("v_us_at_zero", s.v_us_at_zero, Range{64, 4080});
    v.Field("v_us_per_deg", s.v_us_per_deg, Range{-100, 100});
    v.Field("poll_interval_s", s.poll_interval_s, Range{0.001, 10});
    v.Field("position_tolerance_us", s.position_tolerance_us, Range{0.25, 1000});
  });
}

template <typename V>
void VisitLampSection(Config& c, V& v) {
  auto& l = c.lamp;
  v.Field("backend", l.backend, {"sim", "gpiod"}, true);
  v.Field("chip", l.chip);
  v.Field("line", l.line);
  v.Field("active_low", l.active_low);
  v.Field("warmup_s", l.warmup_s, Range{0, 600});
  v.Field("radiance_rgb", l.radiance_rgb, kPositive);
}

template <typename V>
void VisitLightFrameSection(Config& c, V& v) {
  auto& f = c.light_frame;
  v.Field("h_offset_deg", f.h_offset_deg, kAngle);
  v.Field("v_offset_deg", f.v_offset_deg, kAngle);
  v.Field("h_sign", f.h_sign, Range{-1, 1});
  v.Field("v_sign", f.v_sign, Range{-1, 1});
  v.Field("lamp_distance_mm", f.lamp_distance_mm, Range{0, 1e7});
  v.Field("field_height_mm", f.field_height_mm, Range{0, 1e7});
  // Written only when set: the resolved text (and digest) of a session without it is
  // what it was before the key existed, so such sessions still resume.
  v.OptionalField("surface_depth_mm", f.surface_depth_mm, Range{-1e7, 1e7}, 0.0);
}

template <typename V>
void VisitProcessSection(Config& c, V& v) {
  auto& p = c.process;
  v.Field("response_lambda", p.response_lambda, Range{0, 1e6});
  v.Field("response_samples", p.response_samples, Range{16, 100000});
  v.Field("response_poses", p.response_poses, Range{1, 1000});
  v.Field("hdr_pixel_type", p.hdr_pixel_type, {"half", "float"});
  // The names of process/io/exr_io.h's ExrCompressionNames() (config is below process; a
  // test keeps the two lists equal).
  v.Field("hdr_compression", p.hdr_compression,
          {"none", "rle", "zips", "zip", "zip-fast", "piz"});
  v.Field("merge_weighting", p.merge_weighting, {"hat", "photon", "noise"});
  v.Field("model_family", p.model_family, {"auto", "harmonic", "pca"});
  v.Field("pca_max_bytes_per_pixel", p.pca_max_bytes_per_pixel, Range{0.1, 1e4});
  v.Field("basis", p.basis, {"sh", "hsh", "ptm"});
  v.Field("fit_method", p.fit_method, {"quadrature", "ls", "rls"});
  v.OrderField("order", p.order, Range{0, 12});
  v.Field("max_order", p.max_order, Range{0, 12});
  v.Field("order_tolerance", p.order_tolerance, Range{0, 1});
  v.Field("max_condition_number", p.max_condition_number, Range{1, 1e300});
  v.Field("fit_space", p.fit_space, {"linear", "srgb", "log"});
  v.Field("model_pixel_type", p.model_pixel_type, {"half", "float"});
  // ExrModelCompressionNames(): the same, and the lossy ones a model file may use.
  v.Field("model_compression", p.model_compression,
          {"none", "rle", "zips", "zip", "zip-fast", "piz", "dwaa", "dwab"});
  v.Field("reference_patch_px", p.reference_patch_px, Range{0, 1e6});
  v.Field("reference_reflectance", p.reference_reflectance, Range{1e-3, 1});
  v.Field("field_of_view_deg", p.field_of_view_deg, Range{0.1, 360});
  v.Field("display_min_cd_m2", p.display_min_cd_m2, kPositive);
  v.Field("display_max_cd_m2", p.display_max_cd_m2, kPositive);
  v.Field("queue_depth", p.queue_depth, Range{1, 1000});
  v.Field("threads", p.threads, Range{1, 256});
}

template <typename V>
void VisitSimSection(Config& c, V& v) {
  auto& s = c.sim;
  v.Field("seed", s.seed, Range{0, 2147483647});
  v.Field("scene", s.scene, {"matte", "gloss", "sharp", "full"});
  v.Field("width", s.width, Range{8, 20000});
  v.Field("height", s.height, Range{8, 20000});
  v.Field("latency_scale", s.latency_scale, Range{0, 100});
  v.Field("chrome_spheres", s.chrome_spheres, Range{0, 2});
  v.Field("matte_sphere", s.matte_sphere);
  v.Field("lamp_distance_mm", s.lamp_distance_mm, Range{0, 1e7});
  v.Field("field_height_mm", s.field_height_mm, Range{1e-3, 1e7});
  VisitSection(v, "camera", false, [&] {
    auto& k = s.camera;
    v.Field("gain", k.gain, kPositive);
    v.Field("full_well", k.full_well, Range{1, 1e9});
    v.Field("read_noise_e", k.read_noise_e, kNonNegative);
    v.Field("shot_noise", k.shot_noise);
    v.Field("response", k.response, {"filmic", "gamma", "linear"});
    v.Field("response_gamma_rgb", k.response_gamma_rgb, Range{0.2, 5});
    v.Field("format", k.format, {"jpg", "png"});
    v.Field("jpeg_quality", k.jpeg_quality, Range{1, 100});
    v.Field("shutter_min_s", k.shutter_min_s, Range{1e-6, 3600});
    v.Field("shutter_max_s", k.shutter_max_s, Range{1e-6, 3600});
    v.Field("download_time_s", k.download_time_s, kNonNegative);
    v.Field("fail_capture_at", k.fail_capture_at, Range{1, 1e9});
    v.Field("fail_capture_every", k.fail_capture_every, Range{0, 1e9});
    v.Field("fail_forever_after", k.fail_forever_after, Range{0, 1e9});
    v.Field("disconnect_at", k.disconnect_at, Range{0, 1e9});
    v.Field("disconnect_captures", k.disconnect_captures, Range{1, 1000});
  });
  VisitSection(v, "motor", false, [&] {
    auto& m = s.motor;
    v.Field("stall_at_move", m.stall_at_move, Range{1, 1e9});
    v.Field("timeout_at_move", m.timeout_at_move, Range{1, 1e9});
    v.Field("fail_forever_after", m.fail_forever_after, Range{0, 1e9});
  });
  VisitSection(v, "lamp", false, [&] {
    v.Field("fail_switch_at", s.lamp.fail_switch_at, Range{1, 1e9});
  });
}

template <typename V>
void VisitConfig(Config& c, V& v) {
  VisitSection(v, "grid", false, [&] { VisitGridSection(c, v); });
  VisitSection(v, "bracket", true, [&] { VisitBracketSection(c, v); });
  VisitSection(v, "camera", true, [&] { VisitCameraSection(c, v); });
  VisitSection(v, "motor", true, [&] { VisitMotorSection(c, v); });
  VisitSection(v, "lamp", true, [&] { VisitLampSection(c, v); });
  VisitSection(v, "light_frame", false, [&] { VisitLightFrameSection(c, v); });
  VisitSection(v, "process", false, [&] { VisitProcessSection(c, v); });
  VisitSection(v, "sim", false, [&] { VisitSimSection(c, v); });
}

bool Divides(double span, double step) {
  double n = span / step;
  return std::fabs(n - std::round(n)) < 1e-6;
}

// Checks between values, after each value passed its own checks.
void CheckConsistency(const Config& c, Reader& r) {
  const auto& g = c.grid;
  if (g.h_max_deg < g.h_min_deg)
    r.ReportAt("grid.h_max_deg", fmt::format("h_max_deg {} is below h_min_deg {}", g.h_max_deg, g.h_min_deg));
  else if (!Divides(g.h_max_deg - g.h_min_deg, g.h_step_deg))
    r.ReportAt("grid.h_step_deg", fmt::format("step {} does not divide the span {} .. {}",
                                              g.h_step_deg, g.h_min_deg, g.h_max_deg));
  if (g.v_max_deg < g.v_min_deg)
    r.ReportAt("grid.v_max_deg", fmt::format("v_max_deg {} is below v_min_deg {}", g.v_max_deg, g.v_min_deg));
  else if (!Divides(g.v_max_deg - g.v_min_deg, g.v_step_deg))
    r.ReportAt("grid.v_step_deg", fmt::format("step {} does not divide the span {} .. {}",
                                              g.v_step_deg, g.v_min_deg, g.v_max_deg));
  // The grid's size, bounded before anything allocates it (PlanGrid, the journal's plan).
  if (g.h_max_deg >= g.h_min_deg && g.v_max_deg >= g.v_min_deg) {
    const double nh = std::floor((g.h_max_deg - g.h_min_deg) / g.h_step_deg + 0.5) + 1;
    const double nv = std::floor((g.v_max_deg - g.v_min_deg) / g.v_step_deg + 0.5) + 1;
    if (nh * nv > kMaxGridPoses)
      r.ReportAt("grid.h_step_deg",
                 fmt::format("the grid has {:.0f} x {:.0f} = {:.4g} poses; at most {} are allowed",
                             nh, nv, nh * nv, kMaxGridPoses));
  }
  const auto& m = c.motor;
  if (g.h_min_deg < m.h_limit_min_deg || g.h_max_deg > m.h_limit_max_deg)
    r.ReportAt("grid.h_max_deg", fmt::format("grid {} .. {} leaves the motor's soft limits {} .. {}",
                                             g.h_min_deg, g.h_max_deg, m.h_limit_min_deg, m.h_limit_max_deg));
  if (g.v_min_deg < m.v_limit_min_deg || g.v_max_deg > m.v_limit_max_deg)
    r.ReportAt("grid.v_max_deg", fmt::format("grid {} .. {} leaves the motor's soft limits {} .. {}",
                                             g.v_min_deg, g.v_max_deg, m.v_limit_min_deg, m.v_limit_max_deg));

  const auto& b = c.bracket;
  if (!b.exposure_times_s.empty()) {
    for (size_t i = 1; i < b.exposure_times_s.size(); ++i) {
      if (b.exposure_times_s[i] <= b.exposure_times_s[i - 1]) {
        r.ReportAt("bracket.exposure_times_s", "exposure times must be strictly increasing");
        break;
      }
    }
    if (b.count != 0 || b.center_s != 0)
      r.ReportAt("bracket.exposure_times_s", "give either exposure_times_s or center_s with count, not both");
  } else if (b.center_s <= 0 || b.count < 1) {
    r.ReportAt("bracket", "needs exposure_times_s, or center_s > 0 with count >= 1");
  }

  if (m.backend == "grbl" || m.backend == "maestro") {
    if (m.port.empty() && m.usb_vid_pid.empty() && m.usb_serial.empty())
      r.ReportAt("motor.port", "backend '" + m.backend + "' needs port, usb_vid_pid or usb_serial");
  }
  if (!m.usb_vid_pid.empty()) {
    unsigned vid = 0, pid = 0;
    char extra = 0;
    if (std::sscanf(m.usb_vid_pid.c_str(), "%4x:%4x%c", &vid, &pid, &extra) != 2)
      r.ReportAt("motor.usb_vid_pid", "expected 'vvvv:pppp' in hexadecimal, e.g. '2341:0043'");
  }
  if (m.grbl.h_axis == m.grbl.v_axis)
    r.ReportAt("motor.grbl.v_axis", "h_axis and v_axis are the same axis");
  if (m.maestro.h_channel == m.maestro.v_channel)
    r.ReportAt("motor.maestro.v_channel", "h_channel and v_channel are the same channel");
  if (c.lamp.backend == "gpiod" && c.lamp.line.empty())
    r.ReportAt("lamp.line", "backend 'gpiod' needs the GPIO line (name or offset)");
  for (const char* key : {"h_sign", "v_sign"}) {
    int s = std::string(key) == "h_sign" ? c.light_frame.h_sign : c.light_frame.v_sign;
    if (s == 0) r.ReportAt(std::string("light_frame.") + key, "must be 1 or -1");
  }
  const auto& p = c.process;
  if (p.order > p.max_order)
    r.ReportAt("process.order", fmt::format("order {} exceeds max_order {}", p.order, p.max_order));
  if (p.display_max_cd_m2 <= p.display_min_cd_m2)
    r.ReportAt("process.display_max_cd_m2", "must exceed display_min_cd_m2");
  if (c.light_frame.lamp_distance_mm > 0 && c.light_frame.field_height_mm <= 0)
    r.ReportAt("light_frame.field_height_mm",
               "a near lamp (lamp_distance_mm > 0) needs the field's height at the object");
  // A lamp no farther from the arm's centre than the field is tall sits inside the field it
  // lights (a typo for a longer distance, most likely); the near-lamp fit would shrink its
  // tiles to single pixels and run for hours.
  if (c.light_frame.lamp_distance_mm > 0 && c.light_frame.field_height_mm > 0 &&
      c.light_frame.lamp_distance_mm <= c.light_frame.field_height_mm)
    r.ReportAt("light_frame.lamp_distance_mm",
               fmt::format("{:g} mm is no farther than the field is tall ({:g} mm): the lamp "
                           "would sit inside the field it lights",
                           c.light_frame.lamp_distance_mm, c.light_frame.field_height_mm));
  // The surface off the centre of rotation: the lamp must still lie outside the field and in
  // front of the surface, farther from the surface's point at the image centre than the field
  // is tall: lamp_distance_mm > field_height_mm + |surface_depth_mm| (the lamp, anywhere on its
  // sphere around the centre, is then at least that far from the surface's centre point).
  else if (c.light_frame.lamp_distance_mm > 0 && c.light_frame.field_height_mm > 0 &&
           c.light_frame.lamp_distance_mm <=
               c.light_frame.field_height_mm + std::abs(c.light_frame.surface_depth_mm))
    r.ReportAt("light_frame.surface_depth_mm",
               fmt::format("a surface at z = {:g} mm leaves the lamp {:g} mm from the arm's "
                           "centre no farther from it than the field is tall ({:g} mm): "
                           "|surface_depth_mm| + field_height_mm must stay below "
                           "lamp_distance_mm (z is mm towards the camera from the centre)",
                           c.light_frame.surface_depth_mm, c.light_frame.lamp_distance_mm,
                           c.light_frame.field_height_mm));
  if (c.sim.camera.shutter_max_s <= c.sim.camera.shutter_min_s)
    r.ReportAt("sim.camera.shutter_max_s", "must exceed shutter_min_s");
}

}  // namespace

std::string ConfigDiagnostic::ToString() const {
  std::string where = file;
  if (line > 0) where += fmt::format(":{}:{}", line, column);
  return fmt::format("{}: {}: {}", where, key_path, message);
}

Error ConfigResult::AsError() const {
  std::string msg;
  for (size_t i = 0; i < diagnostics.size(); ++i) {
    if (i) msg += '\n';
    msg += diagnostics[i].ToString();
  }
  return Error{ErrorCode::kInvalidInput, msg, ""};
}

ConfigResult ParseConfig(const std::string& text, const std::string& source_name) {
  ConfigResult result;
  result.config.source = source_name;
  toml::table root;
  try {
    root = toml::parse(text, source_name);
  } catch (const toml::parse_error& e) {
    const auto& src = e.source();
    result.diagnostics.push_back({source_name, static_cast<int>(src.begin.line),
                                  static_cast<int>(src.begin.column), "(syntax)",
                                  std::string(e.description())});
    return result;
  } catch (const std::exception& e) {  // e.g. std::bad_alloc on a hostile document
    result.diagnostics.push_back({source_name, 0, 0, "(syntax)", e.what()});
    return result;
  }
  Reader reader(root, source_name, &result.diagnostics);
  VisitConfig(result.config, reader);
  reader.Finish();
  CheckConsistency(result.config, reader);
  std::stable_sort(result.diagnostics.begin(), result.diagnostics.end(),
                   [](const ConfigDiagnostic& a, const ConfigDiagnostic& b) {
                     return std::tie(a.line, a.column) < std::tie(b.line, b.column);
                   });
  return result;
}

ConfigResult LoadConfig(const std::string& path) {
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec)) {
    // An ifstream opens a folder and reads nothing: every table would be reported missing.
    ConfigResult r;
    r.diagnostics.push_back({path, 0, 0, "(file)",
                             "is a directory, not a configuration file (give a .toml file, e.g. "
                             "config/sim.toml)"});
    return r;
  }
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    const int e = errno;
    ConfigResult r;
    std::error_code ec;
    const bool missing = !std::filesystem::exists(std::filesystem::symlink_status(path, ec));
    r.diagnostics.push_back(
        {path, 0, 0, "(file)",
         missing ? std::string("no such file")
                 : fmt::format("cannot open the file: {}", std::strerror(e))});
    return r;
  }
  std::stringstream ss;
  ss << in.rdbuf();
  if (ss.str().size() > kMaxConfigBytes) {
    ConfigResult r;
    r.diagnostics.push_back({path, 0, 0, "(file)",
                             fmt::format("{} bytes: a configuration is at most {} bytes",
                                         ss.str().size(), kMaxConfigBytes)});
    return r;
  }
  return ParseConfig(ss.str(), path);
}

Result<Config> LoadConfigOrError(const std::string& path) {
  ConfigResult r = LoadConfig(path);
  if (!r.ok()) return r.AsError();
  return r.config;
}

std::string ToToml(const Config& config) {
  Config copy = config;
  Writer w;
  VisitConfig(copy, w);
  return w.Text();
}

}  // namespace rig
