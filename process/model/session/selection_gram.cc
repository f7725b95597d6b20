// The selection rows' Gram matrix, all maps at once or map by map, in one arithmetic.
#include "process/model/session/selection_gram.h"

#include <algorithm>
#include <atomic>
#include <thread>

#include "process/model/session/model_stream.h"

namespace rig {
namespace {

// Values per chunk of a pair sum: 40 maps' chunks (640 KB of floats) stay in the cache while
// every pair of them is summed.
constexpr size_t kGramChunk = 4096;

// Σ a·b over one chunk, in double: a product of two floats is exact in double, so only the
// additions round, in this fixed order (eight running sums, then a fixed tree), whatever the
// data's alignment or the caller.
double DotChunk(const float* a, const float* b, size_t m) {
  double s[8] = {};
  size_t k = 0;
  for (; k + 8 <= m; k += 8)
    for (int l = 0; l < 8; ++l) s[l] += static_cast<double>(a[k + l]) * static_cast<double>(b[k + l]);
  for (int l = 0; k < m; ++k, ++l) s[l] += static_cast<double>(a[k]) * static_cast<double>(b[k]);
  return ((s[0] + s[1]) + (s[2] + s[3])) + ((s[4] + s[5]) + (s[6] + s[7]));
}

// Σ a·b over m values: the chunks' sums added in order, starting from 0.
double PairSum(const float* a, const float* b, size_t m) {
  double s = 0;
  for (size_t c0 = 0; c0 < m; c0 += kGramChunk) s += DotChunk(a + c0, b + c0, std::min(kGramChunk, m - c0));
  return s;
}

// Every pair's PairSum of `rows` (each m values), the chunks outermost so that a chunk of every
// row is read from memory once: entry (i, j) receives the same chunk sums in the same order as
// PairSum(rows[i], rows[j], m), so it is equal to it bit for bit.
Eigen::MatrixXd AllPairSums(const std::vector<const float*>& rows, size_t m) {
  const Eigen::Index n = static_cast<Eigen::Index>(rows.size());
  Eigen::MatrixXd p = Eigen::MatrixXd::Zero(n, n);
  for (size_t c0 = 0; c0 < m; c0 += kGramChunk) {
    const size_t len = std::min(kGramChunk, m - c0);
    for (Eigen::Index j = 0; j < n; ++j)
      for (Eigen::Index i = 0; i <= j; ++i) p(i, j) += DotChunk(rows[i] + c0, rows[j] + c0, len);
  }
  for (Eigen::Index j = 0; j < n; ++j)
    for (Eigen::Index i = 0; i < j; ++i) p(j, i) = p(i, j);
  return p;
}

// One selection band's share: the pair sums over all its pixels (missing samples are 0), less
// the same sums over the pixels some map has no sample of, and the values that remain.
struct BandPartial {
  Eigen::MatrixXd all, incomplete;
  double count = 0;
};

// `rows[i]`: map i's 3 x pixels samples of the band; `missing[i]`: its per-pixel missing flags
// or nullptr. `all`: the band's pair sums when already known (map by map), else computed.
BandPartial PartialOf(const std::vector<const float*>& rows, const std::vector<const uint8_t*>& missing,
                      size_t pixels, const Eigen::MatrixXd* all) {
  BandPartial b;
  b.all = all != nullptr ? *all : AllPairSums(rows, 3 * pixels);
  std::vector<uint8_t> gone(pixels, 0);
  for (const uint8_t* m : missing)
    if (m != nullptr)
      for (size_t p = 0; p < pixels; ++p) gone[p] |= m[p];
  size_t incomplete = 0;
  for (uint8_t g : gone) incomplete += g;
  b.count = 3.0 * static_cast<double>(pixels - incomplete);
  const Eigen::Index n = static_cast<Eigen::Index>(rows.size());
  if (incomplete == 0) {
    b.incomplete = Eigen::MatrixXd::Zero(n, n);
    return b;
  }
  // The incomplete pixels' samples, map by map, in pixel order.
  std::vector<std::vector<float>> gathered(rows.size(), std::vector<float>(3 * incomplete));
  for (size_t i = 0; i < rows.size(); ++i) {
    float* g = gathered[i].data();
    for (size_t p = 0; p < pixels; ++p) {
      if (!gone[p]) continue;
      *g++ = rows[i][3 * p];
      *g++ = rows[i][3 * p + 1];
      *g++ = rows[i][3 * p + 2];
    }
  }
  std::vector<const float*> g(rows.size());
  for (size_t i = 0; i < rows.size(); ++i) g[i] = gathered[i].data();
  b.incomplete = AllPairSums(g, 3 * incomplete);
  return b;
}

// The bands' shares summed in band order.
GramSum Combine(const std::vector<BandPartial>& bands, Eigen::Index n) {
  GramSum out;
  out.gram = Eigen::MatrixXd::Zero(n, n);
  for (const BandPartial& b : bands) {
    out.gram += b.all - b.incomplete;
    out.count += b.count;
  }
  return out;
}

}  // namespace

std::vector<std::pair<int, int>> SelectionLayout::Bands() const {
  const int band = std::max(1, band_rows);
  const int bands_total = (height + band - 1) / band;
  const int bands_sel = std::clamp(selection_rows / band, 1, std::max(1, bands_total));
  std::vector<std::pair<int, int>> out;
  for (int s = 0; s < bands_sel; ++s) {
    const int b = static_cast<int>(static_cast<long>(s) * bands_total / bands_sel);
    out.emplace_back(b * band, std::min(height, b * band + band));
  }
  return out;
}

bool SampleSpace::SameAs(const SampleSpace& o) const {
  return lamp_radiance_rgb == o.lamp_radiance_rgb && transform.space == o.transform.space &&
         transform.log_epsilon == o.transform.log_epsilon && lamp.SameSamplingAs(o.lamp);
}

size_t MapSelectionSamples::bytes() const {
  size_t b = 0;
  for (const auto& v : values) b += v.size() * sizeof(float);
  for (const auto& m : missing) b += m.size();
  return b;
}

Result<MapSelectionSamples> SelectionSamplesOf(const cv::Mat& bgr, const cv::Mat& valid,
                                               const Vec3& direction, const SelectionLayout& layout,
                                               const SampleSpace& space) {
  if (bgr.cols != layout.width || bgr.rows != layout.height) {
    return MakeError(ErrorCode::kInvalidInput, "selection samples", "map of {}x{}, the layout is {}x{}",
                     bgr.cols, bgr.rows, layout.width, layout.height);
  }
  MapSelectionSamples out;
  std::vector<cv::Mat> one(1), mask;
  SampleMatrix y;
  std::vector<uint8_t> missing;
  for (const auto& [y0, y1] : layout.Bands()) {
    // The values the band reader gives (half to float is exact), then as the fit makes them.
    bgr.rowRange(y0, y1).convertTo(one[0], CV_32F);
    DivideByFalloff(space.lamp, {direction}, 0, y0, layout.width, layout.height, &one);
    mask.clear();
    if (!valid.empty()) mask.push_back(valid.rowRange(y0, y1));
    RIG_TRY(BuildSamples(one, mask, space.lamp_radiance_rgb, space.transform, &y, &missing));
    out.values.emplace_back(y.data(), y.data() + y.size());
    out.missing.push_back(missing);
  }
  return out;
}

Result<GramSum> SelectionGramOfBands(MapBands& maps, const std::vector<Vec3>& directions,
                                     const SelectionLayout& layout, const SampleSpace& space,
                                     int threads) {
  const auto bands = layout.Bands();
  const size_t n = maps.count();
  std::vector<BandPartial> partials(bands.size());
  std::vector<Status> status(bands.size(), Ok());
  std::atomic<size_t> next{0};
  auto worker = [&] {
    std::vector<cv::Mat> bgr, valid;
    SampleMatrix y;
    std::vector<uint8_t> missing;
    for (size_t s; (s = next.fetch_add(1)) < bands.size();) {
      const auto [y0, y1] = bands[s];
      Status& st = status[s];
      try {
        st = maps.Read(y0, y1, &bgr, &valid);
        if (st.ok()) DivideByFalloff(space.lamp, directions, 0, y0, layout.width, layout.height, &bgr);
        if (st.ok()) st = BuildSamples(bgr, valid, space.lamp_radiance_rgb, space.transform, &y, &missing);
        if (!st.ok()) continue;
        const size_t pixels = static_cast<size_t>(y1 - y0) * static_cast<size_t>(layout.width);
        std::vector<const float*> rows(n);
        std::vector<const uint8_t*> miss(n, nullptr);
        for (size_t i = 0; i < n; ++i) {
          rows[i] = y.row(static_cast<Eigen::Index>(i)).data();
          if (!missing.empty()) miss[i] = missing.data() + i * pixels;
        }
        partials[s] = PartialOf(rows, miss, pixels, nullptr);
      } catch (const std::exception& e) {
        st = MakeError(ErrorCode::kIo, "radiance maps", "reading rows {}-{}: {}", y0, y1 - 1, e.what());
      }
    }
  };
  const int workers = maps.concurrent() ? std::clamp(threads, 1, static_cast<int>(bands.size())) : 1;
  std::vector<std::thread> pool;
  for (int i = 1; i < workers; ++i) pool.emplace_back(worker);
  worker();
  for (auto& t : pool) t.join();
  for (const Status& st : status) RIG_TRY(st);
  return Combine(partials, static_cast<Eigen::Index>(n));
}

SelectionGramAccumulator::SelectionGramAccumulator(SelectionLayout layout, SampleSpace space,
                                                   std::map<std::string, Vec3> directions)
    : layout_(layout), space_(std::move(space)), directions_(std::move(directions)) {}

const Vec3* SelectionGramAccumulator::Direction(const std::string& key) const {
  auto it = directions_.find(key);
  return it == directions_.end() ? nullptr : &it->second;
}

void SelectionGramAccumulator::Add(const std::string& key,
                                   std::shared_ptr<const MapSelectionSamples> samples) {
  Drop(key);
  const size_t bands = samples->values.size();
  for (const auto& [other, theirs] : held_) {
    std::vector<double> sums(bands);
    for (size_t s = 0; s < bands; ++s)
      sums[s] = PairSum(samples->values[s].data(), theirs->values[s].data(), samples->values[s].size());
    pairs_[std::minmax(key, other)] = std::move(sums);
  }
  std::vector<double> self(bands);
  for (size_t s = 0; s < bands; ++s)
    self[s] = PairSum(samples->values[s].data(), samples->values[s].data(), samples->values[s].size());
  pairs_[{key, key}] = std::move(self);
  bytes_ += samples->bytes();
  held_[key] = std::move(samples);
}

void SelectionGramAccumulator::Drop(const std::string& key) {
  auto it = held_.find(key);
  if (it == held_.end()) return;
  bytes_ -= it->second->bytes();
  held_.erase(it);
  for (auto p = pairs_.begin(); p != pairs_.end();) {
    if (p->first.first == key || p->first.second == key) {
      p = pairs_.erase(p);
    } else {
      ++p;
    }
  }
}

std::optional<GramSum> SelectionGramAccumulator::Gram(const std::vector<std::string>& keys) const {
  const size_t n = keys.size();
  std::vector<const MapSelectionSamples*> maps(n);
  for (size_t i = 0; i < n; ++i) {
    auto it = held_.find(keys[i]);
    if (it == held_.end()) return std::nullopt;
    maps[i] = it->second.get();
  }
  const auto bands = layout_.Bands();
  std::vector<BandPartial> partials(bands.size());
  for (size_t s = 0; s < bands.size(); ++s) {
    Eigen::MatrixXd all(static_cast<Eigen::Index>(n), static_cast<Eigen::Index>(n));
    for (size_t i = 0; i < n; ++i)
      for (size_t j = 0; j < n; ++j) {
        auto p = pairs_.find(std::minmax(keys[i], keys[j]));
        if (p == pairs_.end() || p->second.size() != bands.size()) return std::nullopt;
        all(static_cast<Eigen::Index>(i), static_cast<Eigen::Index>(j)) = p->second[s];
      }
    const size_t pixels = static_cast<size_t>(bands[s].second - bands[s].first) * static_cast<size_t>(layout_.width);
    std::vector<const float*> rows(n);
    std::vector<const uint8_t*> miss(n, nullptr);
    for (size_t i = 0; i < n; ++i) {
      rows[i] = maps[i]->values[s].data();
      if (!maps[i]->missing[s].empty()) miss[i] = maps[i]->missing[s].data();
    }
    partials[s] = PartialOf(rows, miss, pixels, &all);
  }
  return Combine(partials, static_cast<Eigen::Index>(n));
}

}  // namespace rig
