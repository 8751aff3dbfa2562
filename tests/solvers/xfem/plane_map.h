// Surface maps shared by the quadrature tests (tests/solvers/xfem).
#pragma once

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

}  // namespace parafab::xfem::testing
