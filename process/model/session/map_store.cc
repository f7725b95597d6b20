// Radiance maps held in memory as their files hold them, read back as bands.
#include "process/model/session/map_store.h"

#include <unistd.h>

#include <algorithm>

#include "config/log.h"

namespace rig {
namespace {

size_t MapBytes(int width, int height, ExrPixelType type, bool flags) {
  const size_t px = static_cast<size_t>(width) * static_cast<size_t>(height);
  return px * (type == ExrPixelType::kHalf ? 6 : 12) + (flags ? px : 0);
}

// The held maps of one fit, read as bands (CV_32FC3; validity when some map has flags).
class StoreBands : public MapBands {
 public:
  StoreBands(const MapStore* store, std::vector<std::string> keys,
             std::vector<std::shared_ptr<const void>> keep, std::vector<const cv::Mat*> bgr,
             std::vector<const cv::Mat*> valid, int width, int height)
      : store_(store), keys_(std::move(keys)), keep_(std::move(keep)), bgr_(std::move(bgr)),
        valid_(std::move(valid)), width_(width), height_(height) {
    for (const cv::Mat* v : valid_) any_flags_ = any_flags_ || !v->empty();
  }
  int width() const override { return width_; }
  int height() const override { return height_; }
  size_t count() const override { return bgr_.size(); }
  bool any_flags() const override { return any_flags_; }
  bool concurrent() const override { return true; }
  // Each map's rows converted one at a time into a row of floats (in the cache) and made into
  // samples from there: the same values as Read + BuildSamples without a band of floats per
  // map written and read back.
  Status ReadSamples(int y0, int y1, const SampleSpace& space, const std::vector<Vec3>& directions,
                     std::vector<cv::Mat>* bgr, std::vector<cv::Mat>* /*valid*/, SampleMatrix* samples,
                     std::vector<uint8_t>* missing) override {
    if (y0 < 0 || y1 > height_ || y0 >= y1) {
      return MakeError(ErrorCode::kInvalidInput, "maps in memory", "rows {}-{} of {}", y0, y1 - 1,
                       height_);
    }
    bgr->resize(1);
    cv::Mat& row = (*bgr)[0];
    row.create(1, width_, CV_32FC3);
    const bool near = space.lamp.near();
    std::vector<cv::Mat> one(1);
    auto row_of = [&](size_t i, int y) -> const float* {
      const cv::Mat& held = *bgr_[i];
      if (held.type() == CV_32FC3 && !near) return held.ptr<float>(y0 + y);
      held.row(y0 + y).convertTo(row, CV_32F);
      if (near && i < directions.size()) {
        one[0] = row;
        DivideByFalloff(space.lamp, {directions[i]}, 0, y0 + y, width_, height_, &one);
      }
      return row.ptr<float>(0);
    };
    auto valid_of = [&](size_t i, int y) -> const uint8_t* {
      return valid_[i]->empty() ? nullptr : valid_[i]->ptr<uint8_t>(y0 + y);
    };
    return BuildSamplesFromRows(bgr_.size(), y1 - y0, width_, row_of, valid_of, space.lamp_radiance_rgb,
                                space.transform, samples, missing);
  }
  std::optional<GramSum> SelectionGram(const std::vector<Vec3>& directions, const SelectionLayout& layout,
                                       const SampleSpace& space) const override {
    return store_->SelectionGram(keys_, directions, layout, space);
  }
  Status Read(int y0, int y1, std::vector<cv::Mat>* bgr, std::vector<cv::Mat>* valid) override {
    if (y0 < 0 || y1 > height_ || y0 >= y1) {
      return MakeError(ErrorCode::kInvalidInput, "maps in memory", "rows {}-{} of {}", y0, y1 - 1,
                       height_);
    }
    bgr->resize(bgr_.size());
    valid->resize(any_flags_ ? bgr_.size() : 0);
    for (size_t i = 0; i < bgr_.size(); ++i) {
      // Half to float is exact: the values the file's reader would give.
      bgr_[i]->rowRange(y0, y1).convertTo((*bgr)[i], CV_32F);
      if (any_flags_) {
        // copyTo/setTo reuse the caller's buffer when it has the size already.
        cv::Mat& v = (*valid)[i];
        if (valid_[i]->empty()) {
          v.create(y1 - y0, width_, CV_8U);
          v.setTo(1);
        } else {
          valid_[i]->rowRange(y0, y1).copyTo(v);
        }
      }
    }
    return Ok();
  }

 private:
  const MapStore* store_;
  std::vector<std::string> keys_;
  std::vector<std::shared_ptr<const void>> keep_;  // the maps stay alive while read
  std::vector<const cv::Mat*> bgr_, valid_;
  int width_, height_;
  bool any_flags_ = false;
};

}  // namespace

MapStore::MapStore(ExrPixelType type, size_t planned, size_t max_bytes)
    : type_(type), planned_(std::max<size_t>(planned, 1)), max_bytes_(max_bytes) {}

size_t MapStore::DefaultMaxBytes() {
  const long pages = ::sysconf(_SC_PHYS_PAGES), page = ::sysconf(_SC_PAGESIZE);
  if (pages <= 0 || page <= 0) return size_t{4} << 30;
  return static_cast<size_t>(pages) * static_cast<size_t>(page) / 2;
}

Status MapStore::Add(const std::string& key, const cv::Mat& radiance, const cv::Mat& flags) {
  if (radiance.type() != CV_32FC3 || radiance.empty()) {
    return MakeError(ErrorCode::kInvalidInput, key, "radiance must be a non-empty CV_32FC3");
  }
  if (!flags.empty() && (flags.type() != CV_8UC1 || flags.size() != radiance.size())) {
    return MakeError(ErrorCode::kInvalidInput, key, "flags must be CV_8UC1 of the map's size");
  }
  std::lock_guard<std::mutex> serial(gram_mu_);
  std::unique_lock<std::mutex> lock(mu_);
  if (!off_reason_.empty()) return Ok();
  if (width_ == 0) {
    // Every planned map as large as this one, each with flags (and its selection samples when
    // the Gram matrix is accumulated): the most the store would hold.
    size_t per_map = MapBytes(radiance.cols, radiance.rows, type_, true);
    if (plan_) {
      const SelectionLayout layout{radiance.cols, radiance.rows, plan_->band_rows, plan_->selection_rows};
      for (const auto& [y0, y1] : layout.Bands()) per_map += static_cast<size_t>(y1 - y0) * radiance.cols * 13;
    }
    const size_t need = planned_ * per_map;
    if (need > max_bytes_) {
      off_reason_ = fmt::format("{} maps of {}x{} need {:.1f} GB in memory, more than the {:.1f} GB "
                                "allowed",
                                planned_, radiance.cols, radiance.rows, need / 1e9,
                                max_bytes_ / 1e9);
      return Ok();
    }
    width_ = radiance.cols;
    height_ = radiance.rows;
  } else if (radiance.cols != width_ || radiance.rows != height_) {
    return MakeError(ErrorCode::kInvalidInput, key, "map of {}x{}, the first held map is {}x{}",
                     radiance.cols, radiance.rows, width_, height_);
  }
  auto held = std::make_shared<Held>();
  // The values the EXR holds: OpenCV's CV_16F conversion is the one the EXR writer uses.
  if (type_ == ExrPixelType::kHalf) {
    radiance.convertTo(held->bgr, CV_16F);
  } else {
    held->bgr = radiance.clone();
  }
  if (!flags.empty()) held->valid = (flags == 0) / 255;
  auto it = held_.find(key);
  if (it != held_.end()) {
    bytes_ -= MapBytes(width_, height_, type_, !it->second->valid.empty());
  }
  bytes_ += MapBytes(width_, height_, type_, !held->valid.empty());
  held_[key] = held;
  lock.unlock();
  if (plan_) {
    // The new map's products with every map held, while the rig moves on.
    if (!gram_) {
      const SelectionLayout layout{width_, height_, plan_->band_rows, plan_->selection_rows};
      const SampleSpace space{plan_->lamp_radiance_rgb, plan_->transform,
                              NearLamp::FromLightFrame(plan_->light_frame, height_)};
      gram_ = std::make_unique<SelectionGramAccumulator>(layout, space, plan_->directions);
    }
    const Vec3* direction = gram_->Direction(key);
    if (direction == nullptr) {
      gram_->Drop(key);
    } else {
      auto samples = SelectionSamplesOf(held->bgr, held->valid, *direction, gram_->layout(), gram_->space());
      if (!samples.ok()) {
        // Held without its products: the fit computes the Gram matrix itself.
        Log("process")->warn("{}: the selection's Gram matrix is not accumulated: {}", key,
                             samples.error().ToString());
        gram_->Drop(key);
        return Ok();
      }
      const size_t before = gram_->bytes();
      gram_->Add(key, std::make_shared<const MapSelectionSamples>(std::move(samples).value()));
      lock.lock();
      bytes_ = bytes_ + gram_->bytes() - before;
    }
  }
  return Ok();
}

void MapStore::PlanSelectionGram(std::map<std::string, Vec3> directions,
                                 std::array<double, 3> lamp_radiance_rgb, FitTransform transform,
                                 LightFrameConfig light_frame, int band_rows, int selection_rows) {
  std::lock_guard<std::mutex> serial(gram_mu_);
  plan_ = GramPlan{std::move(directions), lamp_radiance_rgb, transform, light_frame, band_rows, selection_rows};
  gram_.reset();
}

std::optional<GramSum> MapStore::SelectionGram(const std::vector<std::string>& keys,
                                               const std::vector<Vec3>& directions,
                                               const SelectionLayout& layout,
                                               const SampleSpace& space) const {
  std::lock_guard<std::mutex> serial(gram_mu_);
  if (!gram_ || keys.size() != directions.size() || !(gram_->layout() == layout) ||
      !gram_->space().SameAs(space)) {
    return std::nullopt;
  }
  for (size_t i = 0; i < keys.size(); ++i) {
    const Vec3* d = gram_->Direction(keys[i]);
    if (d == nullptr || *d != directions[i]) return std::nullopt;
  }
  return gram_->Gram(keys);
}

Status MapStore::AddFile(const std::string& key, const std::string& path) {
  {
    std::lock_guard<std::mutex> lock(mu_);
    if (!off_reason_.empty()) return Ok();
  }
  RIG_ASSIGN_OR_RETURN(ExrImage image, ReadExr(path));
  cv::Mat planes[3], flags;
  const char* kNames[3] = {"B", "G", "R"};
  for (size_t i = 0; i < image.channel_names.size(); ++i) {
    for (int c = 0; c < 3; ++c)
      if (image.channel_names[i] == kNames[c]) planes[c] = image.channels[i];
    if (image.channel_names[i] == "flags") {
      // 0 = valid, as in the file; any other value (a float flag) counts as flagged.
      flags = cv::Mat(image.channels[i] != 0) / 255;
    }
  }
  for (int c = 0; c < 3; ++c) {
    if (planes[c].empty()) {
      return MakeError(ErrorCode::kInvalidInput, path, "no '{}' channel (a radiance map is needed)",
                       kNames[c]);
    }
  }
  cv::Mat bgr;
  cv::merge(planes, 3, bgr);
  return Add(key, bgr, flags);
}

void MapStore::Drop(const std::string& key) {
  std::lock_guard<std::mutex> serial(gram_mu_);
  if (gram_) {
    const size_t before = gram_->bytes();
    gram_->Drop(key);
    std::lock_guard<std::mutex> lock(mu_);
    bytes_ -= before - gram_->bytes();
  }
  std::lock_guard<std::mutex> lock(mu_);
  auto it = held_.find(key);
  if (it == held_.end()) return;
  bytes_ -= MapBytes(width_, height_, type_, !it->second->valid.empty());
  held_.erase(it);
}

bool MapStore::Has(const std::string& key) const {
  std::lock_guard<std::mutex> lock(mu_);
  return held_.count(key) > 0;
}

bool MapStore::off() const {
  std::lock_guard<std::mutex> lock(mu_);
  return !off_reason_.empty();
}

std::string MapStore::off_reason() const {
  std::lock_guard<std::mutex> lock(mu_);
  return off_reason_;
}

size_t MapStore::bytes() const {
  std::lock_guard<std::mutex> lock(mu_);
  return bytes_;
}

size_t MapStore::maps() const {
  std::lock_guard<std::mutex> lock(mu_);
  return held_.size();
}

Result<std::unique_ptr<MapBands>> MapStore::Bands(const std::vector<std::string>& keys) const {
  std::lock_guard<std::mutex> lock(mu_);
  if (!off_reason_.empty()) return MakeError(ErrorCode::kInvalidInput, "maps in memory", "{}", off_reason_);
  std::vector<std::shared_ptr<const void>> keep;
  std::vector<const cv::Mat*> bgr, valid;
  for (const auto& k : keys) {
    auto it = held_.find(k);
    if (it == held_.end()) {
      return MakeError(ErrorCode::kNotFound, k, "this map is not held in memory");
    }
    keep.push_back(it->second);
    bgr.push_back(&it->second->bgr);
    valid.push_back(&it->second->valid);
  }
  if (keys.empty()) return MakeError(ErrorCode::kInvalidInput, "maps in memory", "no maps named");
  return std::unique_ptr<MapBands>(
      std::make_unique<StoreBands>(this, keys, std::move(keep), std::move(bgr), std::move(valid), width_, height_));
}

}  // namespace rig
