// Surface maps shared by the quadrature tests (tests/solvers/xfem).
#pragma once

#include <cmath>

#include "xfem/cut_geometry.h"

namespace parafab::xfem::testing {

/// σ(u, v) = origin + u e1 + v e2.
class PlaneMap : public SurfaceMap {
 public:
  PlaneMap(Vec3 origin, Vec3 e1, Vec3 e2) : o_(origin), e1_(e1), e2_(e2) {}
  void evaluate(double u, double v, Vec3& X, Vec3& Xu, Vec3& Xv) const override {
    X = o_ + u * e1_ + v * e2_;
    Xu = e1_;
    Xv = e2_;
  }

 private:
  Vec3 o_, e1_, e2_;
};

/// σ(θ, z) = (cx + R cos θ, cy + R sin θ, z); σθ × σz points outwards.
class CylinderMap : public SurfaceMap {
 public:
  CylinderMap(Vec2 center, double radius) : c_(center), r_(radius) {}
  void evaluate(double t, double z, Vec3& X, Vec3& Xu, Vec3& Xv) const override {
    X = Vec3(c_.x() + r_ * std::cos(t), c_.y() + r_ * std::sin(t), z);
    Xu = Vec3(-r_ * std::sin(t), r_ * std::cos(t), 0);
    Xv = Vec3(0, 0, 1);
  }

 private:
  Vec2 c_;
  double r_;
};

}  // namespace parafab::xfem::testing
