// The camera backend over libgphoto2.
#include "capture/devices/gphoto2_camera.h"

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
    RIG_TRY(OpenSelected());
    // A body opened again (after a disconnect) gets the session's settings again: some
    // bodies and libgphoto2's own capture target forget them with the connection.
    if (configured_) {
      auto again = Configure(*configured_);
      if (!again.ok()) return again.error();
    }
    return Ok();
  }

  void Close() override {
    CloseBody();
    if (context_) gp_context_unref(context_);
    context_ = nullptr;
  }

  Result<CapturedFile> CapturePreview() override {
    if (!camera_) return MakeError(ErrorCode::kDevice, Describe(), "preview before Open()");
    CameraFile* file = nullptr;
    gp_file_new(&file);
    Arm();
    const int rc = gp_camera_capture_preview(camera_, file, context_);
    if (rc < 0) {
      gp_file_unref(file);
      Error e = Failure(rc, "capturing a preview (live view)");
      if (rc == GP_ERROR_NOT_SUPPORTED) {
        e.code = ErrorCode::kUnsupported;
        e.message += ": libgphoto2 offers no live view for this body; frame and focus with "
                     "`rig shot --exposure S --save FILE` instead";
      }
      return e;
    }
    const char* data = nullptr;
    const char* mime = nullptr;
    unsigned long size = 0;
    gp_file_get_data_and_size(file, &data, &size);
    gp_file_get_mime_type(file, &mime);
    CapturedFile out;
    out.bytes.assign(reinterpret_cast<const uint8_t*>(data), reinterpret_cast<const uint8_t*>(data) + size);
    const std::string type = mime ? mime : "";
    out.extension = type == "image/png" ? "png" : type == "image/tiff" ? "tif" : "jpg";
    gp_file_unref(file);
    return out;
  }

  Result<std::vector<CameraReading>> Readings() override {
    // The names libgphoto2's ptp2 driver (and others) give these settings, first found wins.
    static const std::vector<std::pair<const char*, std::vector<const char*>>> kWanted = {
        {"iso", {"iso", "isospeed"}},
        {"aperture", {"f-number", "aperture"}},
        {"shutter", {"shutterspeed", "shutterspeed2", "eos-shutterspeed"}},
        {"image format", {"imagequality", "imageformat"}},  // not "imagesize": pixels
        {"battery", {"batterylevel"}},
    };
    std::vector<CameraReading> out;
    for (const auto& [what, names] : kWanted) {
      for (const char* name : names) {
        RIG_ASSIGN_OR_RETURN(CameraWidget * w, RetryWhileBusy(fmt::format("reading '{}'", name),
                                                              [&] { return FreshWidget(name); }));
        if (!w) continue;
        CameraReading r{what, name, "", ""};
        const char* label = nullptr;
        if (gp_widget_get_label(w, &label) >= 0 && label) r.label = label;
        r.value = WidgetValueText(w);
        gp_widget_free(w);
        out.push_back(std::move(r));
        break;
      }
    }
    return out;
  }

  // A widget's current value as text, whatever its type (text, menu and radio: the text;
  // range: the number; toggle: 0/1; date: seconds since the epoch).
  static std::string WidgetValueText(CameraWidget* w) {
    CameraWidgetType type;
    if (gp_widget_get_type(w, &type) < 0) return "";
    switch (type) {
      case GP_WIDGET_TEXT:
      case GP_WIDGET_RADIO:
      case GP_WIDGET_MENU: {
        const char* v = nullptr;
        return gp_widget_get_value(w, &v) >= 0 && v ? v : "";
      }
      case GP_WIDGET_RANGE: {
        float f = 0;
        return gp_widget_get_value(w, &f) >= 0 ? fmt::format("{:g}", f) : "";
      }
      case GP_WIDGET_TOGGLE:
      case GP_WIDGET_DATE: {
        int i = 0;
        return gp_widget_get_value(w, &i) >= 0 ? std::to_string(i) : "";
      }
      default:
        return "";
    }
  }

  Result<std::vector<Seconds>> ShutterSpeeds() override {
    RIG_ASSIGN_OR_RETURN(Speeds s, ReadSpeeds());
    std::vector<Seconds> out;
    for (const auto& [v, label] : s.choices) out.push_back(Seconds(v));
    return out;
  }

  Result<CameraSettings> Configure(const CameraSettings& wanted) override {
    CameraSettings applied;
    // ISO and aperture are matched by value ("8" finds "f/8", "100" finds "ISO 100");
    // white balance by its name, which is the body's own (and may be translated).
    RIG_ASSIGN_OR_RETURN(applied.iso, ApplyChoice({"iso", "isospeed"}, "camera.iso", wanted.iso, MatchNumber));
    RIG_ASSIGN_OR_RETURN(applied.aperture,
                         ApplyChoice({"f-number", "aperture"}, "camera.aperture", wanted.aperture, MatchNumber));
    RIG_ASSIGN_OR_RETURN(applied.white_balance, ApplyChoice({"whitebalance"}, "camera.white_balance",
                                                            wanted.white_balance, MatchName));
    if (!wanted.capture_target.empty()) {
      // libgphoto2 lists "Internal RAM" then "Memory card", translated into the user's
      // language: chosen by position, never by the label.
      const int index = wanted.capture_target == "card" ? 1 : 0;
      RIG_ASSIGN_OR_RETURN(bool offered, SetChoiceIndex("capturetarget", index));
      if (offered) {
        applied.capture_target = wanted.capture_target;
      } else {
        Log("camera")->warn("camera {}: this body has no capture target setting; it keeps its own",
                            Describe());
        applied.capture_target.clear();
      }
    }
    if (wanted.capture_raw) {
      // "RAW + Large Fine JPEG" (Canon), "NEF+Fine" (Nikon), "RAW+JPEG" ...: the first
      // RAW+JPEG choice the body lists.
      RIG_ASSIGN_OR_RETURN(std::string pair, ApplyChoice({"imageformat", "imagequality"}, "camera.capture_raw",
                                                         "RAW+JPEG", MatchRawPlusJpeg));
      applied.capture_raw = !pair.empty();
    }
    raw_pair_ = applied.capture_raw;
    configured_ = wanted;
    return applied;
  }

  Result<CapturedFrame> Capture(Seconds exposure) override {
    RIG_ASSIGN_OR_RETURN(Speeds s, ReadSpeeds());
    // The body's own value closest to what was asked (in stops), matched by value.
    const std::pair<double, std::string>* best = nullptr;
    auto stops = [&](double v) { return std::abs(std::log2(v / exposure.count())); };
    for (const auto& c : s.choices)
      if (!best || stops(c.first) < stops(best->first)) best = &c;
    if (!best) return MakeError(ErrorCode::kUnsupported, Describe(), "the body lists no shutter speeds");
    // A busy body gets the whole step again — the exposure set anew on a fresh widget too.
    return RetryWhileBusy(fmt::format("capturing at {}", best->second),
                          [&] { return CaptureOnce(s.widget, *best); });
  }

 private:
  struct Speeds {
    std::string widget;                                 // "shutterspeed" or "shutterspeed2"
    std::vector<std::pair<double, std::string>> choices;  // ascending seconds, body's label
  };

  // Opens the configured body, or the first detected one that matches model, port, serial.
  Status OpenSelected() {
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
  // Runs `f` again while the body answers busy, with doubling back-off, within the retries
  // and the capture deadline; each try fetches its widgets afresh (an old one is stale).
  template <typename F>
  auto RetryWhileBusy(const std::string& what, F f) -> decltype(f()) {
    const auto deadline = Clock::now() + ToClock(config_.capture_deadline_s);
    double backoff = config_.retry_backoff_s;
    for (int attempt = 0;; ++attempt) {
      auto r = f();
      if (r.ok() || r.error().code != ErrorCode::kBusy || attempt >= config_.retries ||
          Clock::now() + ToClock(backoff) > deadline)
        return r;
      Log("camera")->warn("camera {}: busy {}; retry {}/{} in {:.2f} s", Describe(), what, attempt + 1,
                          config_.retries, backoff);
      std::this_thread::sleep_for(std::chrono::duration<double>(backoff));
      backoff *= 2;
    }
  }

  static Clock::duration ToClock(double seconds) {
    return std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(seconds));
  }

  // Choice matchers: (the body's label, the configured value).
  static bool MatchNumber(const std::string& label, const std::string& wanted) {
    auto number = [](std::string t) -> std::optional<double> {
      for (const char* prefix : {"f/", "F/", "ISO", "iso", "F"})
        if (t.rfind(prefix, 0) == 0) t.erase(0, std::strlen(prefix));
      while (!t.empty() && t.front() == ' ') t.erase(0, 1);
      try {
        size_t used = 0;
        const double v = std::stod(t, &used);
        if (used != t.size()) return std::nullopt;
        return v;
      } catch (const std::exception&) {
        return std::nullopt;
      }
    };
    const auto a = number(label), b = number(wanted);
    return a && b && std::abs(*a - *b) <= 1e-3 * std::max(1.0, std::abs(*b));
  }
  static std::string Upper(std::string t) {
    for (char& c : t) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
    return t;
  }
  static bool MatchName(const std::string& label, const std::string& wanted) {
    return Upper(label) == Upper(wanted);
  }
  static bool MatchRawPlusJpeg(const std::string& label, const std::string&) {
    const std::string u = Upper(label);
    if (u.find('+') == std::string::npos) return false;
    for (const char* raw : {"RAW", "NEF", "CR2", "CR3", "ARW", "RAF", "ORF", "PEF", "RW2", "DNG"})
      if (u.find(raw) != std::string::npos) return true;
    return false;
  }

  // The setting's widget, fetched afresh (the caller frees it); nullptr when the body lacks it.
  Result<CameraWidget*> FreshWidget(const char* name) {
    if (!camera_) return MakeError(ErrorCode::kFault, Describe(), "not open");
    Arm();
    CameraWidget* w = nullptr;
    const int rc = gp_camera_get_single_config(camera_, name, &w, context_);
    if (rc == GP_ERROR_BAD_PARAMETERS || rc == GP_ERROR_NOT_SUPPORTED) return nullptr;
    if (rc < 0) return Failure(rc, fmt::format("reading '{}'", name));
    return w;
  }

  // Sets the first of `names` the body offers to its choice that `match`es `wanted` and
  // returns the value read back. Empty `wanted`: nothing to do. A body without the setting:
  // a warning and "". A body with the setting but not this value: an error listing its own.
  Result<std::string> ApplyChoice(const std::vector<const char*>& names, const char* key,
                                  const std::string& wanted,
                                  bool (*match)(const std::string&, const std::string&)) {
    if (wanted.empty()) return std::string();
    for (const char* name : names) {
      bool absent = false;
      auto r = RetryWhileBusy(fmt::format("setting '{}'", name), [&]() -> Result<std::string> {
        RIG_ASSIGN_OR_RETURN(CameraWidget * w, FreshWidget(name));
        if (!w) {
          absent = true;
          return std::string();
        }
        CameraWidgetType type;
        gp_widget_get_type(w, &type);
        int rc = GP_OK;
        if (type == GP_WIDGET_RADIO || type == GP_WIDGET_MENU) {
          std::vector<std::string> offered;
          std::string chosen;
          const int n = gp_widget_count_choices(w);
          for (int i = 0; i < n; ++i) {
            const char* c = nullptr;
            if (gp_widget_get_choice(w, i, &c) < 0 || !c) continue;
            offered.push_back(c);
            if (chosen.empty() && match(c, wanted)) chosen = c;
          }
          if (chosen.empty()) {
            gp_widget_free(w);
            return MakeError(ErrorCode::kInvalidInput, Describe(), "{} = '{}': the body's '{}' offers only {}", key,
                             wanted, name, fmt::join(offered, ", "));
          }
          rc = gp_widget_set_value(w, chosen.c_str());
        } else if (type == GP_WIDGET_RANGE) {
          const auto v = ParseShutterSpeed(wanted);  // a plain positive number
          if (!v) {
            gp_widget_free(w);
            return MakeError(ErrorCode::kInvalidInput, Describe(), "{} = '{}': the body's '{}' wants a number",
                             key, wanted, name);
          }
          const float f = static_cast<float>(*v);
          rc = gp_widget_set_value(w, &f);
        } else {
          rc = gp_widget_set_value(w, wanted.c_str());
        }
        Arm();
        if (rc >= 0) rc = gp_camera_set_single_config(camera_, name, w, context_);
        gp_widget_free(w);
        if (rc < 0) return Failure(rc, fmt::format("setting '{}' to '{}'", name, wanted));
        return GetValue(name);
      });
      if (!r.ok()) return r.error();
      if (absent) continue;
      Log("camera")->info("camera set {}=\"{}\" ({} = '{}')", name, *r, key, wanted);
      return r;
    }
    Log("camera")->warn("camera {}: this body offers no '{}' setting; {} = '{}' is left as the body has it",
                        Describe(), names[0], key, wanted);
    return std::string();
  }

  // Sets a radio setting by the position of its choice; false when the body lacks it.
  Result<bool> SetChoiceIndex(const char* name, int index) {
    return RetryWhileBusy(fmt::format("setting '{}'", name), [&]() -> Result<bool> {
      RIG_ASSIGN_OR_RETURN(CameraWidget * w, FreshWidget(name));
      if (!w) return false;
      const char* c = nullptr;
      int rc = gp_widget_get_choice(w, index, &c);
      if (rc >= 0) rc = gp_widget_set_value(w, c);
      Arm();
      if (rc >= 0) rc = gp_camera_set_single_config(camera_, name, w, context_);
      gp_widget_free(w);
      if (rc < 0) return Failure(rc, fmt::format("setting '{}' to choice {}", name, index));
      return true;
    });
  }

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
      RIG_ASSIGN_OR_RETURN(CameraWidget * w, RetryWhileBusy(fmt::format("reading '{}'", name),
                                                            [&] { return FreshWidget(name); }));
      if (!w) continue;
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
    // Drain every pending event (bodies stay busy otherwise) until the body has nothing
    // more to say. A RAW+JPEG body announces its second file here, sometimes only after a
    // while: wait for it; else a short wait drains what is already queued.
    for (int i = 0; i < 100; ++i) {
      const bool pair_due = raw_pair_ && frame.files.size() < 2;
      const int wait_ms = pair_due ? static_cast<int>(config_.call_timeout_s * 1000) : 10;
      CameraEventType type;
      void* data = nullptr;
      Arm();
      rc = gp_camera_wait_for_event(camera_, wait_ms, &type, &data, context_);
      if (rc < 0) return Failure(rc, "waiting for the capture's events");
      if (type == GP_EVENT_FILE_ADDED && data) {
        RIG_ASSIGN_OR_RETURN(CapturedFile extra, Download(*static_cast<CameraFilePath*>(data)));
        frame.files.push_back(std::move(extra));
      }
      free(data);
      if (type == GP_EVENT_TIMEOUT) {
        if (pair_due)
          return MakeError(ErrorCode::kDevice, Describe(),
                           "asked for RAW+JPEG but the body delivered only {} within {} s", path.name,
                           config_.call_timeout_s);
        break;
      }
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
  std::optional<CameraSettings> configured_;  // re-applied when the body is opened again
  bool raw_pair_ = false;  // each capture delivers RAW and JPEG
};

}  // namespace

std::unique_ptr<Camera> MakeGPhoto2Camera(const CameraConfig& config) {
  return std::make_unique<GPhoto2Camera>(config);
}

}  // namespace rig
