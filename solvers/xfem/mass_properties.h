// Mass properties (volume, centre of mass, inertia tensor about the centre) from volume
// quadrature rules: exact when the rules integrate polynomials of degree ≤ 2 exactly.
#pragma once

#include <Eigen/Core>
#include <vector>

namespace parafab::xfem {

struct MassProperties {
  double volume = 0;
  Eigen::Vector3d center{0, 0, 0};
  Eigen::Matrix3d inertia = Eigen::Matrix3d::Zero();  ///< ∫ (|r|² I − r rᵀ) dV, r = X − center
};

/// Accumulates ∫1, ∫X, ∫XXᵀ over weighted points (any number of rules), then forms the
/// properties with the parallel-axis theorem.
class MassAccumulator {
 public:
  void add(const std::vector<Eigen::Vector3d>& points, const std::vector<double>& weights) {
    for (size_t i = 0; i < points.size(); ++i) {
      m0_ += weights[i];
      m1_ += weights[i] * points[i];
      m2_ += weights[i] * points[i] * points[i].transpose();
    }
  }
  MassProperties result() const {
    MassProperties p;
    p.volume = m0_;
    if (m0_ == 0) return p;
    p.center = m1_ / m0_;
    const Eigen::Matrix3d second = m2_ - m0_ * p.center * p.center.transpose();
    p.inertia = second.trace() * Eigen::Matrix3d::Identity() - second;
    return p;
  }

 private:
  double m0_ = 0;
  Eigen::Vector3d m1_ = Eigen::Vector3d::Zero();
  Eigen::Matrix3d m2_ = Eigen::Matrix3d::Zero();
};

}  // namespace parafab::xfem
