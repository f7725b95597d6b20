// The radiance maps of a session kept in memory as they are merged, exactly as their EXR files
// hold them (rounded to half when the maps are written as half), so that the model is fitted
// the moment the last map arrives instead of after reading every map back: reading 40
// ZIP-compressed 24 MP maps is most of a 40 s fit. The fit from the store runs the same code
// on the same values as the fit from the files (FitModelFromBands), so the two models are
// equal bit for bit.
//
// Held per map: B, G, R at 2 bytes (half) or 4 (float) and, when the map has flags, one byte
// of validity per pixel. A store given a byte bound turns itself off (and frees what it holds)
// as soon as the planned maps would not fit: the model is then fitted from the files.
#pragma once

#include <cstddef>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "config/result.h"
#include "process/io/exr_io.h"
#include "process/model/session/model_stream.h"
#include "process/model/session/selection_gram.h"

namespace rig {

class MapStore {
 public:
  // `planned`: how many maps the session will have (the bound is checked against all of them
  // from the first map's size); `max_bytes`: the bound.
  MapStore(ExrPixelType type, size_t planned, size_t max_bytes);

  // Keeps the map under `key` (replacing an earlier one): radiance CV_32FC3 BGR; flags
  // CV_8UC1 (0 = valid, as the merge writes them) or empty. Nothing is kept once the store is
  // off; a map of another size than the first is an error.
  Status Add(const std::string& key, const cv::Mat& radiance_bgr, const cv::Mat& flags);
  // The same from a radiance EXR file (R, G, B, optional flags), e.g. a map merged before a
  // resume.
  Status AddFile(const std::string& key, const std::string& path);
  // Forgets one map (its file was found damaged or replaced).
  void Drop(const std::string& key);

  bool Has(const std::string& key) const;
  bool off() const;
  std::string off_reason() const;  // why the store turned itself off ("" while on)
  size_t bytes() const;            // held now
  size_t maps() const;

  // The maps named by `keys`, in that order, as bands for FitModelFromBands (concurrent
  // reads); an error names the first key that is not held.
  Result<std::unique_ptr<MapBands>> Bands(const std::vector<std::string>& keys) const;

  // Half the machine's physical memory: the default bound.
  static size_t DefaultMaxBytes();

  // From now on, every map added is also turned into the selection rows' fit-space samples
  // and multiplied with every map held, so that the harmonic fit's Gram matrix (order and λ)
  // is ready when the last map arrives (selection_gram.h): `directions` per key (a key
  // without one is held but not accumulated), the lamp's radiance, the fit space, the light
  // frame (a near lamp is placed from the first map's height), the fit's band and selection
  // rows. A fit whose samples would differ (another lamp radiance, e.g. from a reference
  // patch, another space or directions) computes its own Gram matrix, as without a plan.
  void PlanSelectionGram(std::map<std::string, Vec3> directions,
                         std::array<double, 3> lamp_radiance_rgb, FitTransform transform,
                         LightFrameConfig light_frame, int band_rows = StreamFitInput{}.band_rows,
                         int selection_rows = StreamFitInput{}.selection_rows);
  // The accumulated Gram matrix of `keys` (in order) when it was planned for this layout,
  // sample space and directions; nullopt otherwise.
  std::optional<GramSum> SelectionGram(const std::vector<std::string>& keys,
                                       const std::vector<Vec3>& directions,
                                       const SelectionLayout& layout, const SampleSpace& space) const;

 private:
  struct Held {
    cv::Mat bgr;    // CV_16FC3 or CV_32FC3
    cv::Mat valid;  // CV_8U 1 = valid, or empty (no flags)
  };
  struct GramPlan {
    std::map<std::string, Vec3> directions;
    std::array<double, 3> lamp_radiance_rgb;
    FitTransform transform;
    LightFrameConfig light_frame;
    int band_rows, selection_rows;
  };
  // Serialises Add, Drop and the accumulator (taken before mu_).
  mutable std::mutex gram_mu_;
  std::optional<GramPlan> plan_;
  std::unique_ptr<SelectionGramAccumulator> gram_;  // made at the first map
  ExrPixelType type_;
  size_t planned_, max_bytes_;
  mutable std::mutex mu_;
  std::map<std::string, std::shared_ptr<const Held>> held_;
  int width_ = 0, height_ = 0;
  size_t bytes_ = 0;
  std::string off_reason_;
};

}  // namespace rig
