// Arc-length geometry of space curves against the helix's closed forms.
#include <gtest/gtest.h>

#include <cmath>

#include "common/error.h"
#include "rod_test_curves.h"

namespace parafab {
namespace {

TEST(RodCurve, HelixArcLengthFrameCurvatureTorsion) {
  const double r = 0.1, p = 0.03, w = std::sqrt(r * r + p * p);
  const SpaceCurve c = rod_test::helix(r, p, 3 * M_PI);
  EXPECT_NEAR(c.length(), 3 * M_PI * w, 1e-14);
  for (int i = 0; i <= 97; ++i) {
    const double s = c.length() * i / 97;
    EXPECT_NEAR(c.parameter_at(s), s / w, 1e-13);
    const RodSample q = c.at_arc_length(s);
    EXPECT_NEAR(q.s, s, 1e-13);
    EXPECT_NEAR(q.kappa, r / (w * w), 1e-12);
    EXPECT_NEAR(q.torsion, p / (w * w), 1e-12);
    const double t = s / w;
    EXPECT_LT((q.normal - Vec3(-std::cos(t), -std::sin(t), 0)).norm(), 1e-12);
    EXPECT_LT((q.binormal - Vec3(p * std::sin(t), -p * std::cos(t), r) / w).norm(), 1e-12);
  }
  const auto samples = sample_by_arc_length(c, 11);
  EXPECT_DOUBLE_EQ(samples.back().s, c.length());
  EXPECT_NO_THROW(require_frenet_curve(c, samples));
}

TEST(RodCurve, InvalidCurvesThrow) {
  const auto f = [](double t) {
    return std::array<Vec3, 4>{Vec3(t * t, 0, 0), Vec3(2 * t, 0, 0), Vec3(2, 0, 0), Vec3(0, 0, 0)};
  };
  EXPECT_THROW(SpaceCurve(f, -1, 1), Error);  // zero speed at t = 0
  EXPECT_THROW(SpaceCurve(f, 1, 0), Error);   // empty range
}

}  // namespace
}  // namespace parafab
