#include "rods/bspline_curve3.h"

#include <Eigen/SparseCore>
#include <Eigen/SparseLU>
#include <algorithm>
#include <cmath>

#include "common/error.h"

namespace parafab {

std::vector<Vec2> BSplineCurve3::split(const std::vector<Vec3>& p, bool xy) {
  std::vector<Vec2> out;
  out.reserve(p.size());
  for (const auto& v : p) out.emplace_back(xy ? v.x() : v.z(), xy ? v.y() : 0.0);
  return out;
}

BSplineCurve3::BSplineCurve3(int degree, std::vector<double> knots, std::vector<Vec3> poles,
                             std::vector<double> weights)
    : poles_(poles),
      xy_(degree, knots, split(poles, true), weights),
      z_(degree, std::move(knots), split(poles, false), std::move(weights)) {}

std::array<Vec3, 4> BSplineCurve3::derivatives(double u) const {
  const auto a = xy_.derivatives(u), b = z_.derivatives(u);
  std::array<Vec3, 4> d;
  for (int k = 0; k < 4; ++k) d[k] = Vec3(a[k].x(), a[k].y(), b[k].x());
  return d;
}

SpaceCurve BSplineCurve3::space_curve(int table_intervals) const {
  const BSplineCurve3 copy = *this;
  return SpaceCurve([copy](double u) { return copy.derivatives(u); }, first_parameter(),
                    last_parameter(), table_intervals);
}

BSplineCurve3 interpolate_points3(const std::vector<Vec3>& points, int degree) {
  if (degree < 1 || degree > 7) PARAFAB_INPUT_ERROR("curve.degree must be 1..7, got " << degree);
  Eigen::MatrixXd P(points.size(), 3);
  for (size_t i = 0; i < points.size(); ++i) P.row(static_cast<Eigen::Index>(i)) = points[i].transpose();
  InterpolatedBSpline s = interpolate_rows(P, degree);
  std::vector<Vec3> poles(points.size());
  for (size_t i = 0; i < poles.size(); ++i) poles[i] = s.poles.row(static_cast<Eigen::Index>(i)).transpose();
  return BSplineCurve3(s.degree, std::move(s.knots), std::move(poles));
}

}  // namespace parafab
