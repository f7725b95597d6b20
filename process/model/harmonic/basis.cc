// SH, HSH and PTM bases over unit light directions, and their design matrices.
#include "process/model/harmonic/basis.h"

#include <algorithm>
#include <cmath>
#include <numbers>

#include <fmt/format.h>

#include "process/model/harmonic/sh.h"

namespace rig {

const char* BasisKindName(BasisKind kind) {
  switch (kind) {
    case BasisKind::kSh: return "sh";
    case BasisKind::kHsh: return "hsh";
    case BasisKind::kPtm: return "ptm";
  }
  return "?";
}

Result<BasisKind> ParseBasisKind(const std::string& name) {
  if (name == "sh") return BasisKind::kSh;
  if (name == "hsh") return BasisKind::kHsh;
  if (name == "ptm") return BasisKind::kPtm;
  return MakeError(ErrorCode::kInvalidInput, "basis", "unknown basis '{}' (sh, hsh or ptm)",
                   name);
}

int Basis::SizeFor(BasisKind kind, int order) {
  if (kind == BasisKind::kPtm) return (order + 1) * (order + 2) / 2;
  return (order + 1) * (order + 1);
}

Basis::Basis(BasisKind kind, int order)
    : kind_(kind), order_(order), size_(SizeFor(kind, order)) {
  RIG_CHECK(order >= 0 && order <= 12, "basis order out of range");
}

Result<Basis> Basis::Create(const std::string& name, int order) {
  RIG_ASSIGN_OR_RETURN(BasisKind kind, ParseBasisKind(name));
  const int lo = kind == BasisKind::kPtm ? 1 : 0;
  const int hi = kind == BasisKind::kPtm ? 8 : 12;
  if (order < lo || order > hi) {
    return MakeError(ErrorCode::kInvalidInput, "basis",
                     "order {} is outside {}..{} for basis '{}'", order, lo, hi, name);
  }
  return Basis(kind, order);
}

void Basis::Eval(const Vec3& d, double* out) const {
  const double n = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
  RIG_CHECK(n > 0, "Basis::Eval needs a non-zero direction");
  const double x = d[0] / n, y = d[1] / n, z = d[2] / n;
  switch (kind_) {
    case BasisKind::kSh:
      ShEvalAll(order_, {x, y, z}, out);
      return;
    case BasisKind::kHsh: {
      const double t = 2.0 * std::max(0.0, z) - 1.0;  // shifted Legendre argument
      const double phi = std::atan2(y, x);
      for (int l = 0; l <= order_; ++l) {
        for (int m = 0; m <= l; ++m) {
          const double p = AssocLegendre(l, m, t) * ShNormalization(l, m);
          if (m == 0) {
            out[ShIndex(l, 0)] = p;
          } else {
            out[ShIndex(l, m)] = std::numbers::sqrt2 * p * std::cos(m * phi);
            out[ShIndex(l, -m)] = std::numbers::sqrt2 * p * std::sin(m * phi);
          }
        }
      }
      return;
    }
    case BasisKind::kPtm: {
      int k = 0;
      for (int deg = 0; deg <= order_; ++deg) {
        for (int j = 0; j <= deg; ++j) {  // lu^(deg-j) lv^j
          out[k++] = std::pow(x, deg - j) * std::pow(y, j);
        }
      }
      return;
    }
  }
}

std::vector<double> Basis::Eval(const Vec3& d) const {
  std::vector<double> v(size_);
  Eval(d, v.data());
  return v;
}

Eigen::MatrixXd Basis::Design(const std::vector<Vec3>& dirs) const {
  Eigen::MatrixXd b(static_cast<Eigen::Index>(dirs.size()), size_);
  std::vector<double> row(size_);
  for (size_t i = 0; i < dirs.size(); ++i) {
    Eval(dirs[i], row.data());
    for (int k = 0; k < size_; ++k) b(static_cast<Eigen::Index>(i), k) = row[k];
  }
  return b;
}

std::vector<int> Basis::Degrees() const {
  std::vector<int> deg(size_);
  if (kind_ == BasisKind::kPtm) {
    int k = 0;
    for (int d = 0; d <= order_; ++d)
      for (int j = 0; j <= d; ++j) deg[k++] = d;
  } else {
    for (int l = 0; l <= order_; ++l)
      for (int m = -l; m <= l; ++m) deg[ShIndex(l, m)] = l;
  }
  return deg;
}

std::string Basis::TermName(int k) const {
  if (kind_ == BasisKind::kPtm) {
    int i = 0;
    for (int d = 0; d <= order_; ++d)
      for (int j = 0; j <= d; ++j, ++i)
        if (i == k) return fmt::format("u{}v{}", d - j, j);
    return "?";
  }
  int l = static_cast<int>(std::floor(std::sqrt(static_cast<double>(k))));
  return fmt::format("l{}m{}", l, k - l * l - l);
}

}  // namespace rig
