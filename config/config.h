// The configuration schema of a rig session: camera, motor, lamp, grid, bracket,
// light frame, processing and simulation. Units are in the key names.
//
// One TOML file holds it (config/sim.toml is the default). LoadConfig() validates every
// value and reports every problem at once, each with file:line:column and its key path.
#pragma once

#include <array>
#include <chrono>
#include <string>
#include <vector>

#include "config/result.h"

namespace rig {

using Seconds = std::chrono::duration<double>;

// The lamp positions visited, in the rig's own angles (degrees).
struct GridConfig {
  double h_min_deg = 0, h_max_deg = 90, h_step_deg = 10;
  double v_min_deg = 0, v_max_deg = 30, v_step_deg = 10;
  std::string order = "serpentine";  // "serpentine" (short moves) | "raster"
  // "full": every pose of the grid. "adaptive": the grid is the set of poses allowed; the
  // session takes a spread seed, then after each pose the next one its images so far say is
  // worth most per second of the rig's time (process/model/light_choice.h), each choice
  // journaled with its reason before the arm moves (docs/lights.md "Adaptive grid").
  std::string mode = "full";
  int max_poses = 0;          // adaptive: at most this many poses (0: half the grid's, rounded up)
  int seed_poses = 8;         // adaptive: the spread seed (at least 6)
  // Adaptive: stop before max_poses when the predicted error over the grid's span (sampled
  // at a quarter of its steps) is within this fraction (+ half a code) of what every pose of
  // the grid would leave, by the choice's per-pixel model (0: only max_poses stops).
  double target = 0.1;
  // Adaptive: a pose's cost beside its motion, seconds (settle, lamp, bracket, transfer);
  // < 0: estimated from the configuration (docs/lights.md).
  double pose_cost_s = -1;
};

// The exposure bracket at every pose: an explicit list, or a centre with EV spacing.
struct BracketConfig {
  std::vector<double> exposure_times_s;  // explicit list (wins when given)
  double center_s = 0;                   // else: centre exposure time
  double ev_step = 1.0;                  //       spacing in stops
  int count = 0;                         //       number of exposures
  // "fixed": every pose gets the bracket above. "adaptive": each pose is metered with one
  // frame at the bracket's centre exposure and gets only the exposures its radiance range
  // needs (capture/plan/adaptive_bracket.h), never longer than the bracket's longest; the
  // plan is journaled per pose before its frames are taken (docs/brackets.md).
  std::string mode = "fixed";
};

struct CameraConfig {
  std::string backend;                 // "sim" | "gphoto2"
  std::string model, port, serial;     // gphoto2 body selection; all empty: auto-detect
  std::string iso, aperture, white_balance;  // fixed where the body offers them; empty: leave
  std::string capture_target = "ram";  // "ram" | "card"
  bool delete_from_card = true;
  bool capture_raw = false;            // RAW+JPEG pairs (the same as format = "raw+jpeg")
  // "jpeg": process the camera's JPEGs; "raw+jpeg": store both, process the RAW files;
  // "raw": RAW only. RAW frames are decoded by LibRaw to linear values (no response recovery).
  std::string format = "jpeg";
  bool linear = false;                 // frames are linear: skip response recovery
  int retries = 3;                     // per capture, for transient faults
  double retry_backoff_s = 0.5;        // first back-off; doubles each retry
  double call_timeout_s = 10;          // any single camera call
  double capture_deadline_s = 120;     // one whole capture including retries
  double exif_tolerance = 0.1;         // relative mismatch of EXIF vs applied exposure
};

// Whether the body is asked for RAW files (capture_raw, or a format with "raw"), and whether
// processing uses them (format "raw" or "raw+jpeg"; capture_raw alone only stores them).
inline bool CapturesRaw(const CameraConfig& c) { return c.capture_raw || c.format != "jpeg"; }
inline bool ProcessesRaw(const CameraConfig& c) { return c.format != "jpeg"; }

struct GrblConfig {
  std::string h_axis = "X", v_axis = "Y";
  double units_per_degree = 1.0;       // controller axis units per degree
  std::string completion = "dwell";    // "dwell" (G4 P0) | "poll" ('?' until Idle)
  double banner_timeout_s = 3;
  double poll_interval_s = 0.2;        // '?' period with completion = "poll" (GRBL: <= 5 Hz)
};

struct MaestroConfig {
  int h_channel = 0, v_channel = 1;
  double h_us_at_zero = 1000, h_us_per_deg = 10;  // pulse width calibration
  double v_us_at_zero = 1000, v_us_per_deg = 10;
  double poll_interval_s = 0.02;       // moving-state (0x93) query period
  double position_tolerance_us = 1.0;  // reported position vs target after a move
};

struct MotorConfig {
  std::string backend;                  // "sim" | "grbl" | "maestro"
  std::string port;                     // device path, e.g. /dev/ttyACM0; or find by USB:
  std::string usb_vid_pid;              // "2341:0043"
  std::string usb_serial;
  int baud = 115200;
  double speed_deg_per_s = 30;
  double accel_deg_per_s2 = 60;
  double settle_time_s = 0.3;           // wait after motion before the lamp goes on
  bool home_on_start = true;
  std::string after_reconnect = "home";  // "home" | "verify"
  double reply_timeout_s = 2;           // one protocol exchange
  double move_timeout_s = 60;           // one move to completion
  int retries = 3;
  double retry_backoff_s = 1;
  double h_limit_min_deg = -5, h_limit_max_deg = 95;  // soft limits
  double v_limit_min_deg = -5, v_limit_max_deg = 60;
  GrblConfig grbl;
  MaestroConfig maestro;
};

struct LampConfig {
  std::string backend;                  // "sim" | "gpiod"
  std::string chip = "gpiochip0";       // name, path or number
  std::string line;                     // line name or offset
  bool active_low = false;
  double warmup_s = 0.2;                // before the first exposure after switching on
  std::array<double, 3> radiance_rgb = {1.0, 1.0, 1.0};  // lamp radiance E (R, G, B)
};

// Rig angles to the object frame: physical = sign * commanded + offset (design.md).
struct LightFrameConfig {
  double h_offset_deg = 0, v_offset_deg = 0;
  int h_sign = 1, v_sign = 1;
  // Near lamp (docs/lights.md): the lamp's distance from the arm's centre of rotation (on the
  // object, at the image centre), 0: far enough to be a direction; and the height of the
  // camera's field at the object (both mm), which places every pixel relative to the lamp.
  double lamp_distance_mm = 0;
  double field_height_mm = 0;
  // The object's surface, taken as a plane facing the camera: its z (mm, along the camera
  // axis, positive towards the camera, as NearLamp::plane_z_mm and depth_mm) relative to the
  // arm's centre of rotation; 0: the surface through the centre. Negative when the object
  // lies behind the centre (the simulator's plane: -field_height_mm / 2). A near lamp only.
  double surface_depth_mm = 0;
};

struct ProcessConfig {
  // HDR
  double response_lambda = 10;          // smoothness weight of Debevec-Malik
  int response_samples = 1000;          // pixel locations used for recovery
  int response_poses = 4;               // brackets recovered from jointly
  std::string hdr_pixel_type = "float";  // "half" | "float"
  // The session's radiance maps: "zip" | "zip-fast" | "piz" | "zips" | "rle" | "none", all
  // lossless (process/io/exr_io.h, docs/hdr.md). ZIP: the maps are what a session keeps, and
  // they are written while the arm moves on, so the smallest common choice wins over speed.
  std::string hdr_compression = "zip";
  std::string merge_weighting = "noise";  // "hat" | "photon" | "noise" (docs/hdr.md)
  // Reflectance model: "auto" (the family chosen per byte at held-out lamps: the PCA family's
  // own choice against the harmonic family's, the smaller unless the other is more accurate
  // beyond the measurement's noise; harmonic for a near lamp), "harmonic" (a fixed basis:
  // basis, fit_method, order below; model/model.exr) or "pca" (components of the session's
  // reflectance through an HDR value curve, light dependence on an octahedral grid, relight's
  // web format in model/pca/; its curve and size chosen at held-out lamps per byte within
  // pca_max_bytes_per_pixel). docs/model.md.
  std::string model_family = "auto";
  double pca_max_bytes_per_pixel = 30;
  std::string basis = "sh";             // "sh" | "hsh" | "ptm"
  std::string fit_method = "rls";       // "quadrature" | "ls" | "rls"
  int order = -1;                       // -1: "auto" (chosen from held-out error)
  int max_order = 6;
  double order_tolerance = 0.02;        // relative to the best held-out error
  double max_condition_number = 1e6;    // beyond it an unregularised fit is refused
  std::string fit_space = "linear";     // "linear" | "srgb" | "log"
  std::string model_pixel_type = "half";  // "half" | "float"
  // The session model's file (model/model.exr), lossless like hdr_compression. "none": the
  // model is written the moment the last map is in (ZIP saves ~11% of a coefficient model at
  // 15x the write time; a session's frames and maps dwarf it; `rig export` makes the compact
  // deliverables). docs/model.md has the measurements.
  std::string model_compression = "none";
  // Lamp radiance from a reference patch of known reflectance (x, y, w, h; w = 0: off).
  std::array<int, 4> reference_patch_px = {0, 0, 0, 0};
  double reference_reflectance = 0.18;
  // Rendering / tone mapping
  double field_of_view_deg = 40;        // horizontal, for Ward's 1-degree sampling
  double display_min_cd_m2 = 1, display_max_cd_m2 = 100;
  // Execution
  int queue_depth = 4;                  // brackets between capture and processing
  int threads = 2;
};

struct SimCameraConfig {
  double gain = 1.0;                    // electrons per unit radiance per second
  double full_well = 20000;             // electrons at saturation
  double read_noise_e = 5;
  bool shot_noise = true;
  std::string response = "filmic";      // "filmic" | "gamma" | "linear"
  std::array<double, 3> response_gamma_rgb = {2.2, 2.0, 2.4};
  std::string format = "jpg";           // "jpg" | "png"
  int jpeg_quality = 95;
  double shutter_min_s = 1.0 / 8000, shutter_max_s = 30;  // third stops between
  double download_time_s = 0.2;
  // Faults on demand (capture numbers count from 1 across the session).
  std::vector<int> fail_capture_at;     // these captures fail once
  int fail_capture_every = 0;           // every Nth capture fails once
  int fail_forever_after = 0;           // from this capture on every capture fails
  int disconnect_at = 0;                // camera disconnects at this capture ...
  int disconnect_captures = 2;          // ... and is back after this many attempts
};

struct SimMotorConfig {
  std::vector<int> stall_at_move;       // these moves stall once
  std::vector<int> timeout_at_move;     // these moves time out once
  int fail_forever_after = 0;
};

struct SimLampConfig {
  std::vector<int> fail_switch_at;      // these switchings fail once
};

struct SimConfig {
  int seed = 1;
  std::string scene = "full";           // "matte" | "gloss" | "sharp" | "full"
  int width = 320, height = 240;
  double latency_scale = 0.0;           // 0: no waiting; 1: real device timing
  // Calibration targets (docs/lights.md), off by default: chrome spheres (0, 1 or 2; top left,
  // top right) and a matte sphere (bottom right) in front of the plane.
  int chrome_spheres = 0;
  bool matte_sphere = false;
  // The simulated lamp's true distance from the centre of rotation (mm, 0: a far lamp, as
  // before) and the scene's height in mm (its 2 units); the rig's knowledge of them lives in
  // [light_frame] (the simulated camera takes the arm offsets from there).
  double lamp_distance_mm = 0;
  double field_height_mm = 100;
  SimCameraConfig camera;
  SimMotorConfig motor;
  SimLampConfig lamp;
};

struct Config {
  std::string source;                   // the file it was read from
  GridConfig grid;
  BracketConfig bracket;
  CameraConfig camera;
  MotorConfig motor;
  LampConfig lamp;
  LightFrameConfig light_frame;
  ProcessConfig process;
  SimConfig sim;
};

// Limits checked before anything is allocated from a configuration (docs/robustness.md).
inline constexpr double kMaxGridPoses = 100000;      // poses of one grid
inline constexpr size_t kMaxConfigBytes = 1 << 20;  // a configuration file

// One problem found in a configuration, with where it is.
struct ConfigDiagnostic {
  std::string file;
  int line = 0, column = 0;  // 0: no position (a missing key)
  std::string key_path;      // "camera.backend"
  std::string message;
  std::string ToString() const;  // "file:line:col: key_path: message"
};

struct ConfigResult {
  Config config;
  std::vector<ConfigDiagnostic> diagnostics;  // empty: valid
  bool ok() const { return diagnostics.empty(); }
  // All diagnostics as one error (kInvalidInput), one per line.
  Error AsError() const;
};

// Reads and validates a configuration file; every problem is reported.
ConfigResult LoadConfig(const std::string& path);
// The same from text; `source_name` is used in the diagnostics.
ConfigResult ParseConfig(const std::string& text, const std::string& source_name);
// The resolved configuration (defaults filled in) as TOML text that ParseConfig accepts.
std::string ToToml(const Config& config);

// The same as LoadConfig but as a Result.
Result<Config> LoadConfigOrError(const std::string& path);

}  // namespace rig
