// The analytic scene: geometry, procedural textures and the exact apparent BRDF.
#include "sim/scene.h"

#include <algorithm>
#include <cmath>
#include <numbers>

namespace rig {
namespace {

constexpr double kPi = std::numbers::pi;

// See scene.h: with gain 1 e/(unit s), 20000 e full well and the 1/400 .. 1/6 s default
// bracket, the glossy sphere's peak (rho ~ 2.7 * scale in "full") saturates the exposures
// from 1/25 s up, and the darkest lit texture (rho ~ 1.7e-3 * scale at grazing light) still
// collects ~55 e in the longest one.
constexpr double kRadianceScale = 2.0e5;

uint64_t Mix(uint64_t x) {
  x += 0x9e3779b97f4a7c15ull;
  x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ull;
  x = (x ^ (x >> 27)) * 0x94d049bb133111ebull;
  return x ^ (x >> 31);
}

// Uniform in [0, 1) from a lattice point, a seed and a salt.
double Hash01(int64_t ix, int64_t iy, uint64_t seed, uint64_t salt) {
  uint64_t h = Mix(seed ^ Mix(salt ^ Mix(static_cast<uint64_t>(ix) ^
                                         Mix(static_cast<uint64_t>(iy)))));
  return (h >> 11) * (1.0 / 9007199254740992.0);
}

// Smooth value noise in [0, 1) with lattice spacing `cell`.
double ValueNoise(double x, double y, double cell, uint64_t seed, uint64_t salt) {
  double fx = x / cell, fy = y / cell;
  double x0 = std::floor(fx), y0 = std::floor(fy);
  double tx = fx - x0, ty = fy - y0;
  tx = tx * tx * (3 - 2 * tx);
  ty = ty * ty * (3 - 2 * ty);
  auto ix = static_cast<int64_t>(x0), iy = static_cast<int64_t>(y0);
  double a = Hash01(ix, iy, seed, salt), b = Hash01(ix + 1, iy, seed, salt);
  double c = Hash01(ix, iy + 1, seed, salt), d = Hash01(ix + 1, iy + 1, seed, salt);
  return (a * (1 - tx) + b * tx) * (1 - ty) + (c * (1 - tx) + d * tx) * ty;
}

Vec3 Normalize(const Vec3& v) {
  double n = std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
  return {v[0] / n, v[1] / n, v[2] / n};
}

double Dot(const Vec3& a, const Vec3& b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

// Does the ray p + s l (s > 0) from a point outside the sphere meet it? Both roots then
// have the sign of -b.
bool RayHitsSphere(const Vec3& p, const Vec3& l, const Vec3& center, double radius) {
  const Vec3 oc = {p[0] - center[0], p[1] - center[1], p[2] - center[2]};
  const double b = Dot(oc, l);
  const double c = Dot(oc, oc) - radius * radius;
  return b < 0 && b * b - c > 0;
}

nlohmann::json Rgb(const std::array<double, 3>& c) { return {c[0], c[1], c[2]}; }

}  // namespace

Result<SimScene> SimScene::Create(const SimConfig& sim) {
  static const char* kKinds[] = {"matte", "gloss", "sharp", "full"};
  if (std::find(std::begin(kKinds), std::end(kKinds), sim.scene) == std::end(kKinds))
    return MakeError(ErrorCode::kInvalidInput, "sim.scene",
                     "unknown scene '{}' (matte, gloss, sharp or full)", sim.scene);
  if (sim.width < 8 || sim.height < 8 || sim.width > 20000 || sim.height > 20000)
    return MakeError(ErrorCode::kInvalidInput, "sim.width/height",
                     "scene size {}x{} is outside 8 .. 20000", sim.width, sim.height);
  SimScene s;
  s.kind_ = sim.scene;
  s.width_ = sim.width;
  s.height_ = sim.height;
  s.seed_ = sim.seed;
  s.chrome_spheres_ = sim.chrome_spheres;
  s.matte_sphere_ = sim.matte_sphere;
  s.mm_per_unit_ = sim.field_height_mm / 2.0;
  s.lamp_distance_ = sim.lamp_distance_mm / s.mm_per_unit_;
  if (s.lamp_distance_ > 0 && s.lamp_distance_ < 4.0)
    return MakeError(ErrorCode::kInvalidInput, "sim.lamp_distance_mm",
                     "a lamp {} mm away is inside the {} mm scene (needs at least 2 field "
                     "heights)", sim.lamp_distance_mm, sim.field_height_mm);
  s.Build();
  return s;
}

struct SimScene::Surface {
  Vec3 normal;
  std::array<double, 3> rgb;
  SimMaterialId id;
  double depth;
};

void SimScene::Build() {
  const uint64_t seed = static_cast<uint64_t>(seed_);
  radiance_scale_ = kRadianceScale;
  cast_shadows_ = kind_ == "full";
  relief_ = kind_ == "full";
  ChooseLayout(seed);
  const size_t n = static_cast<size_t>(width_) * height_;
  normal_.assign(3 * n, 0.f);
  albedo_.assign(3 * n, 0.f);
  material_.assign(n, 0);
  depth_.assign(n, 0.f);
  for (int j = 0; j < height_; ++j) {
    const double y = PixelY(j);
    for (int i = 0; i < width_; ++i) {
      const double x = PixelX(i);
      const size_t p = static_cast<size_t>(j) * width_ + i;
      const Surface surface = SurfaceAt(x, y, seed);
      const Vec3& nrm = surface.normal;
      const std::array<double, 3>& rgb = surface.rgb;
      const SimMaterialId id = surface.id;
      const double depth = surface.depth;
      material_[p] = static_cast<uint8_t>(id);
      depth_[p] = static_cast<float>(depth);
      for (int c = 0; c < 3; ++c) {
        normal_[3 * p + c] = static_cast<float>(nrm[c]);
        albedo_[3 * p + c] = static_cast<float>(rgb[2 - c]);  // BGR
      }
    }
  }
}

void SimScene::ChooseLayout(uint64_t seed) {
  // A plane facing up and to the right, behind a sphere that floats in front of it.
  plane_dzdx_ = -0.2;
  plane_dzdy_ = -0.3;
  plane_z0_ = -1.0;
  plane_normal_ = Normalize({-plane_dzdx_, -plane_dzdy_, 1.0});
  sphere_center_ = {0.35, 0.0, -0.3};
  sphere_radius_ = 0.62;
  relief_box_ = {-1.2, -0.5, -0.9, 0.35};
  relief_amplitude_ = 0.03;
  relief_wavelength_ = 0.25;
  checker_size_ = 0.25;
  noise_cell_ = 0.12;

  // Colours, jittered a little by the seed (R, G, B).
  auto jitter = [&](std::array<double, 3> c, uint64_t salt) {
    for (int k = 0; k < 3; ++k) c[k] *= 0.9 + 0.2 * Hash01(k, 0, seed, salt);
    return c;
  };
  plane_rgb_light_ = jitter({0.75, 0.66, 0.50}, 11);
  plane_rgb_dark_ = jitter({0.04, 0.045, 0.06}, 12);
  sphere_rgb_a_ = jitter({0.62, 0.16, 0.10}, 13);
  sphere_rgb_b_ = jitter({0.85, 0.75, 0.30}, 14);
  relief_rgb_ = jitter({0.22, 0.48, 0.30}, 15);

  materials_[0] = {"plane", 0, 1};
  materials_[1] = {"sphere", 0, 1};
  materials_[2] = {"relief", 0, 1};
  materials_[3] = {"chrome", 0.8, 1000};
  materials_[4] = {"matte", 0, 1};
  // The calibration spheres: in corners the main sphere and the relief leave free, in front
  // of the plane; the second chrome sphere further back, out of the first one's light path
  // at h 90 (a sphere shadowing another's highlight biases it).
  extras_.clear();
  if (chrome_spheres_ >= 1) extras_.push_back({{-0.95, 0.68, -0.3}, 0.28, SimMaterialId::kChrome});
  if (chrome_spheres_ >= 2) extras_.push_back({{1.08, 0.76, -0.7}, 0.22, SimMaterialId::kChrome});
  if (matte_sphere_) extras_.push_back({{1.06, -0.76, -0.3}, 0.22, SimMaterialId::kMatte});
  if (kind_ == "gloss") {
    materials_[0] = {"plane", 0.05, 10};
    materials_[1] = {"sphere", 0.35, 20};
  } else if (kind_ == "sharp") {
    materials_[1] = {"sphere", 0.5, 300};
  } else if (kind_ == "full") {
    materials_[0] = {"plane", 0.05, 10};
    materials_[1] = {"sphere", 0.5, 120};
    materials_[2] = {"relief", 0.25, 40};
  }
}

// The surface seen at (x, y): an extra sphere's, the main sphere's, the relief's or the plane's.
SimScene::Surface SimScene::SurfaceAt(double x, double y, uint64_t seed) const {
  const double k = 2 * kPi / relief_wavelength_;
  Vec3 nrm;
  std::array<double, 3> rgb;
  SimMaterialId id;
  const double dx = x - sphere_center_[0], dy = y - sphere_center_[1];
  const double rr = sphere_radius_ * sphere_radius_ - dx * dx - dy * dy;
  const double noise = ValueNoise(x, y, noise_cell_, seed, 1);
  const ExtraSphere* extra = nullptr;
  double err = 0;
  for (const ExtraSphere& e : extras_) {
    const double ex = x - e.center[0], ey = y - e.center[1];
    err = e.radius * e.radius - ex * ex - ey * ey;
    if (err > 0) {
      extra = &e;
      break;
    }
  }
  double depth;
  if (extra) {
    id = extra->id;
    const double r = extra->radius;
    nrm = {(x - extra->center[0]) / r, (y - extra->center[1]) / r, std::sqrt(err) / r};
    depth = extra->center[2] + std::sqrt(err);
    rgb = id == SimMaterialId::kChrome ? std::array<double, 3>{0.005, 0.005, 0.005}
                                       : std::array<double, 3>{0.6, 0.6, 0.6};
  } else if (rr > 0) {
    depth = sphere_center_[2] + std::sqrt(rr);
    id = SimMaterialId::kSphere;
    nrm = {dx / sphere_radius_, dy / sphere_radius_, std::sqrt(rr) / sphere_radius_};
    // Latitude bands on the sphere, with a little noise.
    double band = std::sin(9.0 * std::asin(std::clamp(nrm[1], -1.0, 1.0)) + 1.0);
    const auto& c = band > 0 ? sphere_rgb_a_ : sphere_rgb_b_;
    double m = 0.85 + 0.15 * noise;
    rgb = {c[0] * m, c[1] * m, c[2] * m};
  } else if (relief_ && x >= relief_box_[0] && x <= relief_box_[1] && y >= relief_box_[2] &&
             y <= relief_box_[3]) {
    id = SimMaterialId::kRelief;
    depth = PlaneZ(x, y) + relief_amplitude_ * std::sin(k * x) * std::sin(k * y);
    // Height field on the plane: z = plane + A sin(kx) sin(ky).
    double gx = plane_dzdx_ + relief_amplitude_ * k * std::cos(k * x) * std::sin(k * y);
    double gy = plane_dzdy_ + relief_amplitude_ * k * std::sin(k * x) * std::cos(k * y);
    nrm = Normalize({-gx, -gy, 1.0});
    double m = 0.6 + 0.4 * ValueNoise(x, y, noise_cell_ * 0.5, seed, 2);
    rgb = {relief_rgb_[0] * m, relief_rgb_[1] * m, relief_rgb_[2] * m};
  } else {
    id = SimMaterialId::kPlane;
    depth = PlaneZ(x, y);
    nrm = plane_normal_;
    auto cx = static_cast<int64_t>(std::floor(x / checker_size_));
    auto cy = static_cast<int64_t>(std::floor(y / checker_size_));
    const auto& c = ((cx + cy) & 1) ? plane_rgb_dark_ : plane_rgb_light_;
    double m = 0.7 + 0.3 * noise;
    rgb = {c[0] * m, c[1] * m, c[2] * m};
  }
  return {nrm, rgb, id, depth};
}

double SimScene::PlaneZ(double x, double y) const {
  return plane_z0_ + plane_dzdx_ * x + plane_dzdy_ * y;
}

bool SimScene::Shadowed(int i, int j, const Vec3& l) const {
  // The sphere's cast shadow on the plane (and on the relief, taken at the plane's depth):
  // does the ray P + s L (s > 0) meet the sphere? P lies outside the sphere, so both roots
  // have the sign of -b.
  const double x = PixelX(i), y = PixelY(j);
  const size_t p = static_cast<size_t>(j) * width_ + i;
  const auto id = static_cast<SimMaterialId>(material_[p]);
  const bool extra = id == SimMaterialId::kChrome || id == SimMaterialId::kMatte;
  const Vec3 oc = {x - sphere_center_[0], y - sphere_center_[1],
                   (extra ? depth_[p] : PlaneZ(x, y)) - sphere_center_[2]};
  const double b = Dot(oc, l);
  const double c = Dot(oc, oc) - sphere_radius_ * sphere_radius_;
  return b < 0 && b * b - c > 0;
}

bool SimScene::ShadowedByExtras(int i, int j, const Vec3& l) const {
  const double x = PixelX(i), y = PixelY(j);
  const size_t p = static_cast<size_t>(j) * width_ + i;
  const auto id = static_cast<SimMaterialId>(material_[p]);
  const bool on_sphere = id != SimMaterialId::kPlane && id != SimMaterialId::kRelief;
  const Vec3 pt = {x, y, on_sphere ? depth_[p] : PlaneZ(x, y)};
  for (const ExtraSphere& e : extras_) {
    const double ex = x - e.center[0], ey = y - e.center[1];
    if (ex * ex + ey * ey < e.radius * e.radius) continue;  // its own sphere
    if (RayHitsSphere(pt, l, e.center, e.radius)) return true;
  }
  return false;
}

Vec3 SimScene::SurfacePoint(int i, int j) const {
  return {PixelX(i), PixelY(j), depth_[static_cast<size_t>(j) * width_ + i]};
}

Vec3 SimScene::LightAt(int i, int j, const Vec3& light_dir, double* falloff) const {
  const Vec3 l = Normalize(light_dir);
  if (lamp_distance_ <= 0) {
    *falloff = 1;
    return l;
  }
  const Vec3 p = SurfacePoint(i, j);
  const Vec3 d = {lamp_distance_ * l[0] - p[0], lamp_distance_ * l[1] - p[1],
                  lamp_distance_ * l[2] - p[2]};
  const double dist2 = Dot(d, d);
  *falloff = lamp_distance_ * lamp_distance_ / dist2;
  const double inv = 1.0 / std::sqrt(dist2);
  return {d[0] * inv, d[1] * inv, d[2] * inv};
}

std::vector<SimSphereView> SimScene::CalibrationSpheres() const {
  std::vector<SimSphereView> out;
  const double s = height_ / 2.0;  // pixels per scene unit
  for (const ExtraSphere& e : extras_)
    out.push_back({e.id, e.center[0] * s + width_ / 2.0, height_ / 2.0 - e.center[1] * s,
                   e.radius * s, e.center, e.radius});
  return out;
}

std::array<double, 3> SimScene::BrdfAt(int i, int j, const Vec3& light_dir) const {
  const Vec3 l = Normalize(light_dir);
  const size_t p = static_cast<size_t>(j) * width_ + i;
  const Vec3 nrm = {normal_[3 * p], normal_[3 * p + 1], normal_[3 * p + 2]};
  const double ndl = Dot(nrm, l);
  if (ndl <= 0) return {0, 0, 0};
  const auto id = static_cast<SimMaterialId>(material_[p]);
  if (cast_shadows_ && id != SimMaterialId::kSphere && Shadowed(i, j, l)) return {0, 0, 0};
  if (cast_shadows_ && !extras_.empty() && ShadowedByExtras(i, j, l)) return {0, 0, 0};
  const Material& m = materials_[material_[p]];
  double spec = 0;
  const Vec3 hv = {l[0], l[1], l[2] + 1.0};
  const double hn = std::sqrt(Dot(hv, hv));
  if (m.ks > 0 && hn > 1e-12) {
    const double ndh = Dot(nrm, hv) / hn;
    if (ndh > 0) spec = m.ks * (m.shininess + 8) / (8 * kPi) * std::pow(ndh, m.shininess);
  }
  std::array<double, 3> out;
  for (int c = 0; c < 3; ++c)
    out[c] = radiance_scale_ * (albedo_[3 * p + c] / kPi + spec) * ndl;
  return out;
}

cv::Mat SimScene::Brdf(const Vec3& light_dir) const {
  cv::Mat out(height_, width_, CV_32FC3);
  const Vec3 l = Normalize(light_dir);
  const Vec3 hv = {l[0], l[1], l[2] + 1.0};
  const double hn = std::sqrt(Dot(hv, hv));
  const Vec3 h = hn > 1e-12 ? Vec3{hv[0] / hn, hv[1] / hn, hv[2] / hn} : Vec3{0, 0, 0};
  // Per material: scale * ks * (n + 8) / (8 pi), the lobe's constant.
  std::array<double, 5> lobe;
  for (int k = 0; k < 5; ++k)
    lobe[k] = materials_[k].ks * (materials_[k].shininess + 8) / (8 * kPi);
  const double inv_pi = 1.0 / kPi;
  for (int j = 0; j < height_; ++j) {
    float* row = out.ptr<float>(j);
    for (int i = 0; i < width_; ++i) {
      const size_t p = static_cast<size_t>(j) * width_ + i;
      const float* nrm = &normal_[3 * p];
      const double ndl = nrm[0] * l[0] + nrm[1] * l[1] + nrm[2] * l[2];
      float* o = row + 3 * i;
      const uint8_t id = material_[p];
      if (ndl <= 0 ||
          (cast_shadows_ && id != static_cast<uint8_t>(SimMaterialId::kSphere) &&
           Shadowed(i, j, l)) ||
          (cast_shadows_ && !extras_.empty() && ShadowedByExtras(i, j, l))) {
        o[0] = o[1] = o[2] = 0.f;
        continue;
      }
      double spec = 0;
      if (lobe[id] > 0) {
        const double ndh = nrm[0] * h[0] + nrm[1] * h[1] + nrm[2] * h[2];
        if (ndh > 0) spec = lobe[id] * std::pow(ndh, materials_[id].shininess);
      }
      const double s = radiance_scale_ * ndl;
      for (int c = 0; c < 3; ++c)
        o[c] = static_cast<float>(s * (albedo_[3 * p + c] * inv_pi + spec));
    }
  }
  return out;
}

cv::Mat SimScene::Radiance(const Vec3& light_dir, const std::array<double, 3>& lamp_rgb) const {
  cv::Mat rho;
  if (lamp_distance_ > 0) {
    // A near lamp: every pixel its own direction and fall-off.
    rho.create(height_, width_, CV_32FC3);
    for (int j = 0; j < height_; ++j) {
      float* row = rho.ptr<float>(j);
      for (int i = 0; i < width_; ++i) {
        double falloff = 1;
        const Vec3 l = LightAt(i, j, light_dir, &falloff);
        const auto v = BrdfAt(i, j, l);
        for (int c = 0; c < 3; ++c) row[3 * i + c] = static_cast<float>(v[c] * falloff);
      }
    }
  } else {
    rho = Brdf(light_dir);
  }
  // BGR image, RGB lamp.
  const float e[3] = {static_cast<float>(lamp_rgb[2]), static_cast<float>(lamp_rgb[1]),
                      static_cast<float>(lamp_rgb[0])};
  for (int j = 0; j < rho.rows; ++j) {
    float* row = rho.ptr<float>(j);
    for (int i = 0; i < rho.cols; ++i)
      for (int c = 0; c < 3; ++c) row[3 * i + c] *= e[c];
  }
  return rho;
}

cv::Mat SimScene::Normals() const {
  cv::Mat out(height_, width_, CV_32FC3);
  std::copy(normal_.begin(), normal_.end(), out.ptr<float>(0));
  return out;
}

cv::Mat SimScene::Albedo() const {
  cv::Mat out(height_, width_, CV_32FC3);
  std::copy(albedo_.begin(), albedo_.end(), out.ptr<float>(0));
  return out;
}

cv::Mat SimScene::MaterialIds() const {
  cv::Mat out(height_, width_, CV_8UC1);
  std::copy(material_.begin(), material_.end(), out.ptr<uint8_t>(0));
  return out;
}

nlohmann::json SimScene::Describe() const {
  nlohmann::json mats = nlohmann::json::array();
  // The calibration materials only when their spheres are there: a scene without them
  // describes itself as before.
  const size_t used = extras_.empty() ? 3 : materials_.size();
  for (size_t k = 0; k < used; ++k) {
    const auto& m = materials_[k];
    mats.push_back({{"name", m.name}, {"ks", m.ks}, {"shininess", m.shininess}});
  }
  nlohmann::json out = {
      {"version", 1},
      {"kind", kind_},
      {"width", width_},
      {"height", height_},
      {"seed", seed_},
      {"camera",
       "orthographic, looking down -z; pixel (i, j) sees x = (i + 0.5 - W/2) / (H/2), "
       "y = (H/2 - j - 0.5) / (H/2); view direction +z"},
      {"brdf",
       "rho = radiance_scale * (albedo / pi + ks * (n + 8) / (8 pi) * max(0, N.H)^n) * "
       "max(0, N.L) * visible(L); H = normalize(L + V), V = (0, 0, 1); rho = radiance / "
       "lamp radiance per channel"},
      {"radiance_scale", radiance_scale_},
      {"cast_shadows", cast_shadows_},
      {"plane",
       {{"z", "z0 + dzdx * x + dzdy * y"},
        {"z0", plane_z0_},
        {"dzdx", plane_dzdx_},
        {"dzdy", plane_dzdy_},
        {"normal", {plane_normal_[0], plane_normal_[1], plane_normal_[2]}},
        {"texture",
         "checker of cell size checker_size (light/dark RGB), times 0.7 + 0.3 * value noise"},
        {"checker_size", checker_size_},
        {"noise_cell", noise_cell_},
        {"rgb_light", Rgb(plane_rgb_light_)},
        {"rgb_dark", Rgb(plane_rgb_dark_)}}},
      {"sphere",
       {{"center", {sphere_center_[0], sphere_center_[1], sphere_center_[2]}},
        {"radius", sphere_radius_},
        {"texture", "latitude bands sin(9 asin(N.y) + 1) > 0 ? rgb_a : rgb_b, times 0.85 + "
                    "0.15 * value noise"},
        {"rgb_a", Rgb(sphere_rgb_a_)},
        {"rgb_b", Rgb(sphere_rgb_b_)}}},
      {"relief",
       {{"present", relief_},
        {"box", {relief_box_[0], relief_box_[1], relief_box_[2], relief_box_[3]}},
        {"height", "plane + amplitude * sin(2 pi x / wavelength) * sin(2 pi y / wavelength)"},
        {"amplitude", relief_amplitude_},
        {"wavelength", relief_wavelength_},
        {"rgb", Rgb(relief_rgb_)}}},
      {"materials", mats},
  };
  if (!extras_.empty()) {
    nlohmann::json spheres = nlohmann::json::array();
    for (const ExtraSphere& e : extras_)
      spheres.push_back({{"material", e.id == SimMaterialId::kChrome ? "chrome" : "matte"},
                         {"center", {e.center[0], e.center[1], e.center[2]}},
                         {"radius", e.radius}});
    out["calibration_spheres"] = spheres;
  }
  if (lamp_distance_ > 0)
    out["near_lamp"] = {{"distance", lamp_distance_},
                        {"mm_per_unit", mm_per_unit_},
                        {"model",
                         "point lamp at distance * direction(h, v) from the origin; per pixel "
                         "L = normalize(lamp - P), radiance *= (distance / |lamp - P|)^2"}};
  return out;
}

}  // namespace rig
