// Fitting a model to radiance maps band by band: row bands are read from every map (from the
// EXR files, as OpenEXR scanline ranges, or from maps held in memory as they arrived: see
// map_store.h), fitted with the shared matrix and written band by band, so the peak memory
// beyond the maps' own is a few bands (24 MP x 40 poses x RGB float is 11.5 GB).
#pragma once

#include <array>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "config/config.h"
#include "config/result.h"
#include "process/io/exr_io.h"
#include "process/model/harmonic/fit.h"
#include "process/model/session/selection_gram.h"

namespace rig {

struct StreamFitInput {
  std::vector<std::string> paths;  // radiance EXRs (R, G, B; optional "flags", 0 = valid)
  std::vector<Vec3> directions;
  std::vector<double> weights;     // quadrature weights; empty: 2π/N each
  std::array<double, 3> lamp_radiance_rgb = {1, 1, 1};
  LightFrameConfig light_frame;
  int band_rows = 32;              // rows per band
  int selection_rows = 256;        // rows (in evenly spaced bands) that choose order and λ
  // The model file's compression (all lossless; docs/model.md has their size and speed).
  ExrCompression compression = ExrCompression::kZip;
  // A near lamp (docs/lights.md "Near lamps"): every sample is divided by its pixel's
  // fall-off, and every tile of near_tile_px x near_tile_px pixels (on a grid from the
  // image's top-left corner) is fitted with its own projector, built from the directions at
  // the tile's centre (1: every pixel its own). Order and λ are chosen once, as for a far
  // lamp, from `directions` (the lamp seen from the centre of rotation). A far lamp
  // (distance 0) takes the one shared projector, as before.
  NearLamp near_lamp;
  int near_tile_px = 0;             // 0: near_lamp.TilePx(width, height, near_tile_max_deg)
  double near_tile_max_deg = 1.0;   // see NearLamp::TilePx
  bool near_falloff_only = false;   // divide by the fall-off, one projector (for measurement)
};

struct StreamFitOutput {
  Selection selection;
  MissingStats missing;
  double loo_rmse = 0;
  double time_s = 0;
  int width = 0, height = 0;  // of the maps and the model
  int near_tile_px = 0;       // the tile of a near-lamp fit (0: far lamp, or fall-off only)
  size_t projectors = 1;      // projectors built for the bands (tiles recurring in bands counted again)
};

// Where a band-wise fit reads its maps: rows [y0, y1) of every map, as CV_32FC3 BGR radiance
// and, when some map has a "flags" channel, CV_8U validity per map (1 = valid).
class MapBands {
 public:
  virtual ~MapBands() = default;
  virtual int width() const = 0;
  virtual int height() const = 0;
  virtual size_t count() const = 0;
  virtual bool any_flags() const = 0;
  // Whether Read may be called from several threads at once (for different bands).
  virtual bool concurrent() const = 0;
  // Throws only what OpenEXR throws (caught by the fit); other failures are a Status.
  virtual Status Read(int y0, int y1, std::vector<cv::Mat>* bgr, std::vector<cv::Mat>* valid) = 0;
  // Rows [y0, y1) of every map as fit-space samples: Read, DivideByFalloff (a near lamp, the
  // lamps commanded to `directions`) and BuildSamples, with `bgr` and `valid` as scratch. A
  // source may make them in one pass; the values are the same bit for bit.
  virtual Status ReadSamples(int y0, int y1, const SampleSpace& space,
                             const std::vector<Vec3>& directions, std::vector<cv::Mat>* bgr,
                             std::vector<cv::Mat>* valid, SampleMatrix* samples,
                             std::vector<uint8_t>* missing);
  // The selection rows' Gram matrix when the source accumulated it already (maps held in
  // memory as they arrived, for this layout, sample space and these directions), equal bit
  // for bit to SelectionGramOfBands of the same maps; nullopt: the fit computes it.
  virtual std::optional<GramSum> SelectionGram(const std::vector<Vec3>& /*directions*/,
                                               const SelectionLayout& /*layout*/,
                                               const SampleSpace& /*space*/) const {
    return std::nullopt;
  }
};

// The maps of `paths` read from their EXR files (R, G, B; optional "flags", 0 = valid); all
// of one size.
Result<std::unique_ptr<MapBands>> OpenMapFiles(const std::vector<std::string>& paths);

// The patch (x, y, width, height) of every map, as the CV_32FC3 crops CalibrateLampRadiance
// takes; a patch outside the maps is an error naming process.reference_patch_px.
Result<std::vector<cv::Mat>> ReadPatches(MapBands& maps, const std::array<int, 4>& patch_px);

// The lamp's radiance from the reference patch (x, y, width, height) of every map, of known
// reflectance: the patch's samples divided by the near lamp's fall-off first (the patch's
// reflectance is the far lamp's; a far lamp leaves them as they are), then
// CalibrateLampRadiance.
Result<std::array<double, 3>> LampRadianceFromPatch(MapBands& maps, const std::array<int, 4>& patch_px,
                                                    double reflectance, const NearLamp& lamp,
                                                    const std::vector<Vec3>& directions);

// A near lamp: every CV_32FC3 image of `bgr` (one per direction; a crop whose top-left
// pixel is (x0, y0) of a width x height image) divided by each pixel's fall-off, in place.
// Negative and non-finite samples stay so; a far lamp leaves them unchanged.
void DivideByFalloff(const NearLamp& lamp, const std::vector<Vec3>& directions, int x0, int y0,
                     int width, int height, std::vector<cv::Mat>* bgr);

// Bytes the in-memory fit would hold for the samples (width x height x 3 x 4 x maps), from
// the headers only.
Result<size_t> EstimateSampleBytes(const std::vector<std::string>& paths);

// Two passes: the Gram matrix of `selection_rows` rows chooses order/λ; then every band is
// fitted and written. The model is written atomically (temporary file, then rename); it has a
// "valid" channel whenever some input has a "flags" channel.
Result<StreamFitOutput> FitModelStreaming(const StreamFitInput& input, const FitOptions& options,
                                          const std::string& out_path, ExrPixelType type);

// The same fit from any band source (input.paths is not used): the same bands choose order
// and λ and the same arithmetic fits every band, so a fit from maps held in memory equals the
// fit from their files bit for bit. Bands are computed by options.threads workers when the
// source allows concurrent reads (else one), beside the writer that compresses the file.
Result<StreamFitOutput> FitModelFromBands(MapBands& maps, const StreamFitInput& input,
                                          const FitOptions& options, const std::string& out_path,
                                          ExrPixelType type);

}  // namespace rig
