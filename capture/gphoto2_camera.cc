// The camera backend over libgphoto2.
#include "capture/gphoto2_camera.h"

#include <gphoto2/gphoto2-camera.h>
#include <gphoto2/gphoto2-port-result.h>
#include <gphoto2/gphoto2-setting.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <thread>

#include <fmt/format.h>

#include "config/log.h"

namespace rig {

std::optional<double> ParseShutterSpeed(const std::string& label) {
  std::string s = label;
  while (!s.empty() && (s.back() == 's' || s.back() == ' ')) s.pop_back();
  if (s.empty()) return std::nullopt;
  try {
    size_t used = 0;
    const auto slash = s.find('/');
    if (slash != std::string::npos) {
      const double num = std::stod(s.substr(0, slash), &used);
      if (used != slash) return std::nullopt;
      const std::string den_text = s.substr(slash + 1);
      const double den = std::stod(den_text, &used);
      if (used != den_text.size() || den <= 0 || num <= 0) return std::nullopt;
      return num / den;
    }
    const double v = std::stod(s, &used);
    if (used != s.size() || v <= 0) return std::nullopt;
    return v;
  } catch (const std::exception&) {
    return std::nullopt;
  }
}

std::optional<double> JpegExifExposure(const std::vector<uint8_t>& j) {
  // SOI, then segments; APP1 "Exif\0\0" holds a TIFF header and IFD0 -> ExifIFD (0x8769).
  if (j.size() < 4 || j[0] != 0xFF || j[1] != 0xD8) return std::nullopt;
  size_t p = 2;
  while (p + 4 <= j.size() && j[p] == 0xFF) {
    const uint8_t marker = j[p + 1];
    const size_t len = (size_t(j[p + 2]) << 8) | j[p + 3];
    if (marker == 0xDA || len < 2 || p + 2 + len > j.size()) break;
    if (marker == 0xE1 && len >= 8 && std::memcmp(&j[p + 4], "Exif\0\0", 6) == 0) {
      const uint8_t* t = &j[p + 10];
      const size_t n = len - 8;
      if (n < 8) return std::nullopt;
      const bool le = t[0] == 'I';
      auto u16 = [&](size_t o) -> uint32_t {
        return o + 2 > n ? 0 : le ? t[o] | (t[o + 1] << 8) : (t[o] << 8) | t[o + 1];
      };
      auto u32 = [&](size_t o) -> uint32_t {
        return o + 4 > n ? 0 : le ? u16(o) | (u16(o + 2) << 16) : (u16(o) << 16) | u16(o + 2);
      };
      auto find = [&](uint32_t ifd, uint16_t tag) -> std::optional<uint32_t> {
        const uint32_t count = u16(ifd);
        for (uint32_t i = 0; i < count; ++i) {
          const size_t e = ifd + 2 + 12 * i;
          if (e + 12 > n) break;
          if (u16(e) == tag) return static_cast<uint32_t>(e);
        }
        return std::nullopt;
      };
      const auto exif = find(u32(4), 0x8769);
      if (!exif) return std::nullopt;
      const auto et = find(u32(*exif + 8), 0x829A);  // ExposureTime, RATIONAL
      if (!et) return std::nullopt;
      const uint32_t off = u32(*et + 8), num = u32(off), den = u32(off + 4);
      if (den == 0 || num == 0) return std::nullopt;
      return double(num) / den;
    }
    p += 2 + len;
  }
  return std::nullopt;
}

namespace {

using Clock = std::chrono::steady_clock;

class GPhoto2Camera final : public Camera {
 public:
  explicit GPhoto2Camera(CameraConfig config) : config_(std::move(config)) {}
  ~GPhoto2Camera() override { Close(); }

  std::string Describe() const override {
    if (camera_) return fmt::format("gphoto2 {} on {}", model_, port_);
    std::string want = config_.model.empty() ? "auto-detected body" : config_.model;
    if (!config_.port.empty()) want += " on " + config_.port;
    if (!config_.serial.empty()) want += " serial " + config_.serial;
    return "gphoto2 " + want;
  }

  Status Open() override {
    Close();
    context_ = gp_context_new();
    // Per-call timeout: libgphoto2 asks the context whether to cancel during long
    // operations (transfers, waits); past the call's deadline the answer is yes.
    gp_context_set_cancel_func(context_, &GPhoto2Camera::CancelIfLate, this);
    Arm();
    // Which body: as configured, else the first (or the one with the serial) detected.
    std::vector<std::pair<std::string, std::string>> bodies;  // model, port
    if (!config_.model.empty() && !config_.port.empty()) {
      bodies.push_back({config_.model, config_.port});
    } else {
      CameraList* list = nullptr;
      gp_list_new(&list);
      const int n = gp_camera_autodetect(list, context_);
      for (int i = 0; i < n; ++i) {
        const char *m = nullptr, *p = nullptr;
        gp_list_get_name(list, i, &m);
        gp_list_get_value(list, i, &p);
        if ((config_.model.empty() || config_.model == m) && (config_.port.empty() || config_.port == p))
          bodies.push_back({m, p});
      }
      gp_list_free(list);
      if (n < 0) return Failure(n, "auto-detecting cameras");
    }
    if (bodies.empty()) {
      return MakeError(ErrorCode::kNotFound, Describe(),
                       "no camera found (is it on, in PC/PTP mode, and connected by USB?)");
    }
    Error last = MakeError(ErrorCode::kNotFound, Describe(), "no body matched serial '{}'", config_.serial);
    for (const auto& [model, port] : bodies) {
      Status st = OpenBody(model, port);
      if (!st.ok()) {
        last = st.error();
        continue;
      }
      if (config_.serial.empty()) return Ok();
      auto serial = GetValue("serialnumber");
      if (serial.ok() && *serial == config_.serial) return Ok();
      CloseBody();
    }
    return last;
  }

  void Close() override {
    CloseBody();
    if (context_) gp_context_unref(context_);
    context_ = nullptr;
  }

  Result<std::vector<Seconds>> ShutterSpeeds() override {
    RIG_ASSIGN_OR_RETURN(Speeds s, ReadSpeeds());
    std::vector<Seconds> out;
    for (const auto& [v, label] : s.choices) out.push_back(Seconds(v));
    return out;
  }

  Result<CameraSettings> Configure(const CameraSettings& wanted) override {
    auto log = Log("camera");
    CameraSettings applied = wanted;
    auto apply = [&](const std::vector<const char*>& names, const std::string& value, std::string* out) {
      if (value.empty()) return;
      for (const char* name : names) {
        if (SetValue(name, value).ok()) {
          auto back = GetValue(name);
          *out = back.ok() ? *back : value;
          return;
        }
      }
      log->warn("camera {}: this body offers no setting {} = '{}'; left as it is", Describe(), names[0], value);
      out->clear();
    };
    apply({"iso", "isospeed"}, wanted.iso, &applied.iso);
    apply({"f-number", "aperture"}, wanted.aperture, &applied.aperture);
    apply({"whitebalance"}, wanted.white_balance, &applied.white_balance);
    if (!wanted.capture_target.empty()) {
      const std::string label = wanted.capture_target == "card" ? "Memory card" : "Internal RAM";
      if (!SetValue("capturetarget", label).ok()) {
        log->warn("camera {}: no capture target setting; the body keeps its own", Describe());
      }
    }
    return applied;
  }

  Result<CapturedFrame> Capture(Seconds exposure) override {
    const auto deadline = Clock::now() + std::chrono::duration_cast<Clock::duration>(
                                             std::chrono::duration<double>(config_.capture_deadline_s));
    RIG_ASSIGN_OR_RETURN(Speeds s, ReadSpeeds());
    // The body's own value closest to what was asked (in stops), matched by value.
    const std::pair<double, std::string>* best = nullptr;
    for (const auto& c : s.choices)
      if (!best || std::abs(std::log2(c.first / exposure.count())) < std::abs(std::log2(best->first / exposure.count())))
        best = &c;
    if (!best) return MakeError(ErrorCode::kUnsupported, Describe(), "the body lists no shutter speeds");
    double backoff = config_.retry_backoff_s;
    for (int attempt = 0;; ++attempt) {
      auto frame = CaptureOnce(s.widget, *best);
      if (frame.ok()) return frame;
      const bool busy = frame.error().code == ErrorCode::kBusy;
      if (!busy || attempt >= config_.retries || Clock::now() + std::chrono::duration_cast<Clock::duration>(
                                                     std::chrono::duration<double>(backoff)) > deadline)
        return frame;
      Log("camera")->warn("camera {}: busy; retrying in {:.2f} s", Describe(), backoff);
      std::this_thread::sleep_for(std::chrono::duration<double>(backoff));
      backoff *= 2;
    }
  }

 private:
  struct Speeds {
    std::string widget;                                 // "shutterspeed" or "shutterspeed2"
    std::vector<std::pair<double, std::string>> choices;  // ascending seconds, body's label
  };

  Error Failure(int rc, const std::string& during) const {
    std::string msg = fmt::format("{}: {} ({})", during, gp_result_as_string(rc), rc);
    ErrorCode code = ErrorCode::kDevice;
    if (rc == GP_ERROR_CAMERA_BUSY) code = ErrorCode::kBusy;
    if (rc == GP_ERROR_TIMEOUT) code = ErrorCode::kTimeout;
    if (rc == GP_ERROR_CANCEL) {
      code = ErrorCode::kTimeout;
      msg += fmt::format(": no answer within camera.call_timeout_s = {} s", config_.call_timeout_s);
    }
    if (rc == GP_ERROR_MODEL_NOT_FOUND || rc == GP_ERROR_IO_USB_FIND) code = ErrorCode::kNotFound;
    if (rc == GP_ERROR_IO_USB_CLAIM) {
      code = ErrorCode::kBusy;
      msg += ": another program holds the camera — usually the desktop's camera mounter "
             "(gvfs-gphoto2-volume-monitor) or another gphoto2; close or kill it and retry";
    }
    return Error{code, msg, Describe()};
  }

  Status OpenBody(const std::string& model, const std::string& port) {
    gp_camera_new(&camera_);
    CameraAbilitiesList* al = nullptr;
    gp_abilities_list_new(&al);
    gp_abilities_list_load(al, context_);
    const int m = gp_abilities_list_lookup_model(al, model.c_str());
    CameraAbilities abilities;
    int rc = m < 0 ? m : gp_abilities_list_get_abilities(al, m, &abilities);
    gp_abilities_list_free(al);
    if (rc < 0) {
      CloseBody();
      return Failure(rc, fmt::format("looking up the model '{}'", model));
    }
    gp_camera_set_abilities(camera_, abilities);
    GPPortInfoList* il = nullptr;
    gp_port_info_list_new(&il);
    gp_port_info_list_load(il);
    const int p = gp_port_info_list_lookup_path(il, port.c_str());
    GPPortInfo info;
    rc = p < 0 ? p : gp_port_info_list_get_info(il, p, &info);
    if (rc >= 0) rc = gp_camera_set_port_info(camera_, info);
    gp_port_info_list_free(il);
    if (rc < 0) {
      CloseBody();
      return Failure(rc, fmt::format("finding the port '{}'", port));
    }
    gp_camera_set_timeout_funcs(camera_, nullptr, nullptr, nullptr);
    rc = gp_camera_init(camera_, context_);
    if (rc < 0) {
      CloseBody();
      return Failure(rc, fmt::format("opening {} on {}", model, port));
    }
    model_ = model;
    port_ = port;
    Log("camera")->info("camera opened model=\"{}\" port={}", model, port);
    return Ok();
  }

  void CloseBody() {
    if (camera_) {
      gp_camera_exit(camera_, context_);
      gp_camera_unref(camera_);
    }
    camera_ = nullptr;
  }

  static GPContextFeedback CancelIfLate(GPContext*, void* data) {
    return Clock::now() > static_cast<GPhoto2Camera*>(data)->call_deadline_ ? GP_CONTEXT_FEEDBACK_CANCEL
                                                                            : GP_CONTEXT_FEEDBACK_OK;
  }
  // Starts the clock of one camera call (camera.call_timeout_s).
  void Arm() {
    call_deadline_ = Clock::now() + std::chrono::duration_cast<Clock::duration>(
                                        std::chrono::duration<double>(config_.call_timeout_s));
  }

  Result<std::string> GetValue(const char* name) {
    if (!camera_) return MakeError(ErrorCode::kFault, Describe(), "not open");
    Arm();
    CameraWidget* w = nullptr;
    int rc = gp_camera_get_single_config(camera_, name, &w, context_);
    if (rc < 0) return Failure(rc, fmt::format("reading '{}'", name));
    const char* v = nullptr;
    rc = gp_widget_get_value(w, &v);
    std::string out = rc >= 0 && v ? v : "";
    gp_widget_free(w);
    if (rc < 0) return Failure(rc, fmt::format("reading '{}'", name));
    return out;
  }

  // Sets a value on a fresh widget each time (after a busy error an old widget is stale).
  Status SetValue(const char* name, const std::string& value) {
    if (!camera_) return MakeError(ErrorCode::kFault, Describe(), "not open");
    Arm();
    CameraWidget* w = nullptr;
    int rc = gp_camera_get_single_config(camera_, name, &w, context_);
    if (rc < 0) return Failure(rc, fmt::format("reading '{}'", name));
    rc = gp_widget_set_value(w, value.c_str());
    if (rc >= 0) rc = gp_camera_set_single_config(camera_, name, w, context_);
    gp_widget_free(w);
    if (rc < 0) return Failure(rc, fmt::format("setting '{}' to '{}'", name, value));
    return Ok();
  }

  Result<Speeds> ReadSpeeds() {
    if (!camera_) return MakeError(ErrorCode::kFault, Describe(), "not open");
    // Nikon offers "shutterspeed2" with "1/100" beside "shutterspeed" with "0.0100s"; both
    // parse by value, so either serves. Labels are never matched as text.
    for (const char* name : {"shutterspeed", "shutterspeed2", "exptime"}) {
      CameraWidget* w = nullptr;
      if (gp_camera_get_single_config(camera_, name, &w, context_) < 0) continue;
      Speeds s{name, {}};
      const int n = gp_widget_count_choices(w);
      for (int i = 0; i < n; ++i) {
        const char* c = nullptr;
        if (gp_widget_get_choice(w, i, &c) < 0 || !c) continue;
        if (auto v = ParseShutterSpeed(c)) s.choices.push_back({*v, c});
      }
      gp_widget_free(w);
      std::sort(s.choices.begin(), s.choices.end());
      if (!s.choices.empty()) return s;
    }
    return MakeError(ErrorCode::kUnsupported, Describe(),
                     "the body offers no shutter speed setting (is it in manual (M) mode?)");
  }

  Result<CapturedFrame> CaptureOnce(const std::string& widget, const std::pair<double, std::string>& speed) {
    RIG_TRY(SetValue(widget.c_str(), speed.second));
    RIG_ASSIGN_OR_RETURN(std::string back, GetValue(widget.c_str()));
    const auto applied = ParseShutterSpeed(back);
    if (!applied || std::abs(std::log2(*applied / speed.first)) > 0.05) {
      return MakeError(ErrorCode::kDevice, Describe(), "asked for shutter speed {} but the body reads back '{}'",
                       speed.second, back);
    }
    CameraFilePath path;
    Arm();
    int rc = gp_camera_capture(camera_, GP_CAPTURE_IMAGE, &path, context_);
    if (rc < 0) return Failure(rc, fmt::format("capturing at {}", speed.second));
    CapturedFrame frame;
    frame.exposure = Seconds(*applied);
    RIG_ASSIGN_OR_RETURN(CapturedFile file, Download(path));
    frame.files.push_back(std::move(file));
    // Drain the events the capture raised (a RAW+JPEG body announces the second file here).
    for (int i = 0; i < 50; ++i) {
      CameraEventType type;
      void* data = nullptr;
      rc = gp_camera_wait_for_event(camera_, 50, &type, &data, context_);
      if (rc < 0 || type == GP_EVENT_TIMEOUT || type == GP_EVENT_CAPTURE_COMPLETE) {
        free(data);
        break;
      }
      if (type == GP_EVENT_FILE_ADDED && data) {
        auto* added = static_cast<CameraFilePath*>(data);
        auto extra = Download(*added);
        if (extra.ok()) frame.files.push_back(std::move(extra).value());
      }
      free(data);
    }
    for (const auto& f : frame.files) {
      if (f.extension != "jpg" && f.extension != "jpeg") continue;
      if (auto t = JpegExifExposure(f.bytes)) {
        frame.exif_exposure = Seconds(*t);
        if (std::abs(*t / *applied - 1) > config_.exif_tolerance) {
          return MakeError(ErrorCode::kDevice, Describe(),
                           "the file's EXIF exposure {:.6g} s differs from the {:.6g} s applied", *t, *applied);
        }
      }
    }
    return frame;
  }

  Result<CapturedFile> Download(const CameraFilePath& path) {
    CameraFile* file = nullptr;
    gp_file_new(&file);
    Arm();
    int rc = gp_camera_file_get(camera_, path.folder, path.name, GP_FILE_TYPE_NORMAL, file, context_);
    if (rc < 0) {
      gp_file_unref(file);
      return Failure(rc, fmt::format("downloading {}/{}", path.folder, path.name));
    }
    const char* data = nullptr;
    unsigned long size = 0;
    gp_file_get_data_and_size(file, &data, &size);
    CapturedFile out;
    out.bytes.assign(reinterpret_cast<const uint8_t*>(data), reinterpret_cast<const uint8_t*>(data) + size);
    gp_file_unref(file);
    std::string name = path.name;
    const auto dot = name.rfind('.');
    out.extension = dot == std::string::npos ? "" : name.substr(dot + 1);
    for (char& c : out.extension) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    if (config_.delete_from_card) {
      rc = gp_camera_file_delete(camera_, path.folder, path.name, context_);
      if (rc < 0)
        Log("camera")->warn("camera {}: cannot delete {}/{}: {}", Describe(), path.folder, path.name, gp_result_as_string(rc));
    }
    return out;
  }

  CameraConfig config_;
  GPContext* context_ = nullptr;
  ::Camera* camera_ = nullptr;
  std::string model_, port_;
  Clock::time_point call_deadline_{};
};

}  // namespace

std::unique_ptr<Camera> MakeGPhoto2Camera(const CameraConfig& config) {
  return std::make_unique<GPhoto2Camera>(config);
}

}  // namespace rig
