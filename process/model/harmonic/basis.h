// Bases over unit light directions: real spherical harmonics (SH), hemispherical harmonics
// (HSH, Gautron et al. 2004) and the PTM polynomial; each builds the design matrix of a set
// of lamp directions, so that every fitting method works on any of them.
#pragma once

#include <string>
#include <vector>

#include <Eigen/Core>

#include "config/result.h"
#include "process/model/light_direction.h"

namespace rig {

enum class BasisKind { kSh, kHsh, kPtm };

// "sh", "hsh", "ptm".
const char* BasisKindName(BasisKind kind);
Result<BasisKind> ParseBasisKind(const std::string& name);

// One basis of a given order. Immutable, cheap to copy, thread-safe.
//   SH  order L: (L+1)² terms, Y_lm of process/model/sh.h (θ from +z, the camera axis).
//   HSH order L: (L+1)² terms on the hemisphere z >= 0 (the lamp side):
//       H_lm = √2 K_lm cos(mφ) P_l^m(2cosθ-1) (m>0), K_l0 P_l(2cosθ-1) (m=0),
//              √2 K_lm sin(|m|φ) P_l^|m|(2cosθ-1) (m<0), K_lm = N_lm of sh.h;
//       orthonormal over the hemisphere. Directions with z < 0 are evaluated at z = 0.
//   PTM order L: the bivariate polynomial of total degree L in (lu, lv) = (x, y), terms
//       ordered by degree: 1, lu, lv, lu², lu·lv, lv², ...; order 2 is the classic
//       biquadratic PTM (6 terms).
class Basis {
 public:
  Basis(BasisKind kind, int order);
  // Validates the name and the order (0..12 for SH/HSH, 1..8 for PTM).
  static Result<Basis> Create(const std::string& name, int order);

  BasisKind kind() const { return kind_; }
  int order() const { return order_; }
  int size() const { return size_; }
  std::string name() const { return BasisKindName(kind_); }
  static int SizeFor(BasisKind kind, int order);

  // All terms at one direction (normalised inside), out[0 .. size()).
  void Eval(const Vec3& direction, double* out) const;
  std::vector<double> Eval(const Vec3& direction) const;
  // The design matrix: one row per direction, one column per term.
  Eigen::MatrixXd Design(const std::vector<Vec3>& directions) const;
  // The "degree" l of every term (SH/HSH: l; PTM: total degree); the regulariser's weight
  // for term k is l(l+1).
  std::vector<int> Degrees() const;
  // A short name for term k: "l1m-1" (SH/HSH), "u1v0" (PTM).
  std::string TermName(int k) const;

 private:
  BasisKind kind_;
  int order_;
  int size_;
};

}  // namespace rig
