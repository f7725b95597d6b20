// The Gram matrix that chooses a harmonic fit's order and λ (pose × pose sums of products of
// the selection rows' fit-space samples, over the pixels with no missing sample), computed so
// that it can be accumulated map by map as a session's radiance maps arrive: every entry is a
// sum over (map, map) pairs, so when map j arrives only its row is new. After the last map
// only the last row and the correction for pixels that some map left without a sample remain
// (docs/model.md "The model at the last frame").
//
// One arithmetic for both ways: the pair sums are computed by the same kernel, chunk by
// chunk, whether all maps are at hand (a fit from the files, SelectionGramOfBands) or they
// arrive one at a time (SelectionGramAccumulator, kept by MapStore), so the two Gram
// matrices — and hence the two models — are equal bit for bit, whatever order the maps
// arrive in.
#pragma once

#include <array>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "config/result.h"
#include "process/model/harmonic/fit.h"
#include "process/model/light_direction.h"

namespace rig {

class MapBands;

// Which rows choose order and λ: `selection_rows` rows in evenly spaced bands of `band_rows`.
struct SelectionLayout {
  int width = 0, height = 0, band_rows = 32, selection_rows = 256;
  // [y0, y1) of each selection band, top to bottom.
  std::vector<std::pair<int, int>> Bands() const;
  bool operator==(const SelectionLayout& o) const {
    return width == o.width && height == o.height && band_rows == o.band_rows &&
           selection_rows == o.selection_rows;
  }
};

// What turns a map's radiance into fit-space samples (BuildSamples, after the near lamp's
// fall-off is divided out).
struct SampleSpace {
  std::array<double, 3> lamp_radiance_rgb = {1, 1, 1};
  FitTransform transform;
  NearLamp lamp;  // far: one direction for every pixel, no fall-off
  // Whether samples made in `o` equal those made in this space, bit for bit (a near lamp
  // with a depth map is never taken as equal).
  bool SameAs(const SampleSpace& o) const;
};

// The Gram matrix and how many pixel-channel values it sums (3 per complete pixel).
struct GramSum {
  Eigen::MatrixXd gram;
  double count = 0;
};

// One map's selection samples: per selection band, its fit-space samples (3 per pixel, BGR,
// missing samples 0) and one missing flag per pixel (empty: none missing).
struct MapSelectionSamples {
  std::vector<std::vector<float>> values;
  std::vector<std::vector<uint8_t>> missing;
  size_t bytes() const;
};

// The selection samples of one map (`bgr` CV_32FC3 or CV_16FC3 with the whole map's rows,
// `valid` CV_8U 1 = valid or empty), the map of a lamp commanded to `direction`.
Result<MapSelectionSamples> SelectionSamplesOf(const cv::Mat& bgr, const cv::Mat& valid,
                                               const Vec3& direction, const SelectionLayout& layout,
                                               const SampleSpace& space);

// The Gram matrix of every map of `maps` (all at hand), the selection bands read by
// `threads` workers when the source allows.
Result<GramSum> SelectionGramOfBands(MapBands& maps, const std::vector<Vec3>& directions,
                                     const SelectionLayout& layout, const SampleSpace& space,
                                     int threads);

// The same Gram matrix accumulated map by map: Add computes the new map's products with every
// map held (a map added again under its key replaces the old one). Not thread-safe: the
// caller serialises.
class SelectionGramAccumulator {
 public:
  SelectionGramAccumulator(SelectionLayout layout, SampleSpace space, std::map<std::string, Vec3> directions);

  const SelectionLayout& layout() const { return layout_; }
  const SampleSpace& space() const { return space_; }
  // The planned direction of `key`'s lamp (nullptr: the key is not planned).
  const Vec3* Direction(const std::string& key) const;

  void Add(const std::string& key, std::shared_ptr<const MapSelectionSamples> samples);
  void Drop(const std::string& key);
  size_t bytes() const { return bytes_; }

  // The Gram matrix of the maps `keys` in that order; nullopt when one of them is not held.
  std::optional<GramSum> Gram(const std::vector<std::string>& keys) const;

 private:
  SelectionLayout layout_;
  SampleSpace space_;
  std::map<std::string, Vec3> directions_;
  std::map<std::string, std::shared_ptr<const MapSelectionSamples>> held_;
  // Per (key, key) pair, key order: each selection band's sum of products.
  std::map<std::pair<std::string, std::string>, std::vector<double>> pairs_;
  size_t bytes_ = 0;
};

}  // namespace rig
