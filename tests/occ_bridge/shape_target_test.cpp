// Target surfaces of the target-shape objective (thesis §6.2.3 Eq. 6.6, shape_target.h): the
// signed distances against points placed at a known distance, their gradients against central
// differences, the face's own surface read from the sample parts, and input errors.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <string>

#include "common/error.h"
#include "face_model.h"
#include "part_reader.h"
#include "shape_target.h"
#include "turned_bracket.h"

namespace parafab::occ {
namespace {

#ifndef PARAFAB_SAMPLES_DIR
#define PARAFAB_SAMPLES_DIR "samples"
#endif

// Every surface type: a point built at distance `d` from the surface along its outward normal
// (from a foot point on the surface) reports d; ∇d equals central differences and the normal.
TEST(ShapeTarget, SignedDistancesOfPointsPlacedAtAKnownDistance) {
  const Vec3 c(1.5, -2.0, 0.7);
  const Vec3 a = Vec3(0.3, -0.4, 0.86).normalized();
  const Vec3 e1 = a.unitOrthogonal(), e2 = a.cross(e1);
  struct Case {
    TargetSurface t;
    Vec3 foot, normal;
  };
  std::vector<Case> cases;
  const double R = 7.0, r = 2.5, th = 0.9, ph = 2.1;
  {
    TargetSurface t{SurfaceType::plane, c, 3.0 * a, 0, 0};  // normal not unit: normalized
    cases.push_back({t, c + 4.0 * e1 - 2.0 * e2, a});
  }
  {
    TargetSurface t{SurfaceType::sphere, c, a, r, 0};
    const Vec3 n = (std::cos(th) * e1 + std::sin(th) * (std::cos(ph) * e2 + std::sin(ph) * a)).normalized();
    cases.push_back({t, c + r * n, n});
  }
  {
    TargetSurface t{SurfaceType::cylinder, c, -2.0 * a, r, 0};
    const Vec3 n = std::cos(ph) * e1 + std::sin(ph) * e2;
    cases.push_back({t, c + 3.3 * a + r * n, n});
  }
  {
    TargetSurface t{SurfaceType::torus, c, a, r, R};
    const Vec3 radial = std::cos(ph) * e1 + std::sin(ph) * e2;
    const Vec3 n = std::cos(th) * radial + std::sin(th) * a;
    cases.push_back({t, c + R * radial + r * n, n});
  }
  for (const Case& k : cases) {
    SCOPED_TRACE(to_string(k.t.type));
    for (double d : {-1.2, -0.01, 0.0, 0.3, 1.7}) {
      const Vec3 x = k.foot + d * k.normal;
      Vec3 g;
      EXPECT_NEAR(signed_distance(k.t, x, &g), d, 1e-13);
      EXPECT_NEAR((g - k.normal).norm(), 0, 1e-13);
      const double h = 1e-5;
      for (int i = 0; i < 3; ++i) {
        const Vec3 dx = h * Vec3::Unit(i);
        const double fd = (signed_distance(k.t, x + dx) - signed_distance(k.t, x - dx)) / (2 * h);
        EXPECT_NEAR(g[i], fd, 1e-9);
      }
    }
  }
}

TEST(ShapeTarget, AFacesOwnSurfaceIsItsTarget) {
  const auto cylinder = read_part(std::string(PARAFAB_SAMPLES_DIR) + "/parts/cylinder.step");
  const FaceModel cm = build_face_model(*cylinder);
  int lateral = -1;
  for (size_t f = 0; f < cm.faces.size(); ++f)
    if (cm.faces[f].primitive.type == SurfaceType::cylinder) lateral = static_cast<int>(f);
  ASSERT_GE(lateral, 0);
  const TargetSurface t = target_of_face(cm, lateral);
  EXPECT_EQ(t.type, SurfaceType::cylinder);
  // make_parts.py: Part.makeCylinder(15, 40) (radius 15, axis z through the origin).
  EXPECT_NEAR(t.radius, 15, 1e-12);
  EXPECT_NEAR(std::abs(t.axis.normalized().z()), 1, 1e-12);
  EXPECT_NEAR(signed_distance(t, Vec3(15 * std::cos(0.4), 15 * std::sin(0.4), 12)), 0, 1e-12);

  const auto torus = read_part(std::string(PARAFAB_SAMPLES_DIR) + "/parts/half_torus.step");
  const FaceModel tm = build_face_model(*torus);
  int toroidal = -1;
  for (size_t f = 0; f < tm.faces.size(); ++f)
    if (tm.faces[f].primitive.type == SurfaceType::torus) toroidal = static_cast<int>(f);
  ASSERT_GE(toroidal, 0);
  const TargetSurface tt = target_of_face(tm, toroidal);
  EXPECT_EQ(tt.type, SurfaceType::torus);
  EXPECT_GT(tt.major_radius, tt.radius);
}

// The adjoint gradient of J against central differences of the pipeline on the run's fixed grid
// (re-cut, solve, J; Richardson from H and H/2): the L-bracket turned 11° (cut cells), its base
// top face matched to its own plane, linear and hyperelastic (CalculiX's isochoric neo-Hooke,
// E = 3 GPa: the face's RMS distance 2.5 mm, max 4.8 mm, so the tangent differs from K; with
// the fixed Nitsche penalty that tangent is indefinite and the kept factorization is an LU).
// Differences with the optimizer's fresh grids (`start` runs) would move the grid with the part.
TEST(ShapeTarget, AdjointGradientMatchesFiniteDifferencesOnTheFixedGrid) {
  testing::TurnedBracket c;
  const testing::DesignSpace space(*c.part, {c.setup.dirichlet[0].face, c.setup.tractions[0].face});
  ASSERT_TRUE(space.start.done);
  const auto& [model, sp, start, L] = space;
  TargetOptions o;
  o.face = c.base_top;
  o.target = target_of_face(model, c.base_top);
  struct Entry {
    const char* what;
    int index;
    double tolerance[2];  // linear, hyperelastic (relative, near the measured figures)
  };
  const std::vector<Entry> entries = {
      // Measured: 1.1e-7 / 1.4e-7 (17 cells), 6.1e-6 / 1.4e-6 (171 cells).
      {"hole radius", parameter_index(sp, c.hole, "radius"), {1e-6, 1e-6}},
      {"base top plane offset (inner fillet follows)", parameter_index(sp, c.base_top, "offset"), {3e-5, 1e-5}},
  };
  for (const bool hyperelastic : {false, true}) {
    ComplianceSetup setup = c.setup;
    if (hyperelastic) {
      setup.material.youngs_modulus = 3000;
      setup.hyperelastic = xfem::make_material("neo_hooke_isochoric", 3000, 0.3);
      setup.load_steps = 3;
    }
    for (const Entry& k : entries) {
      const testing::DesignLine line(*c.part, model, sp, k.index, start.p, L);
      const ComplianceState at = compliance_start(line.at(0), setup);
      ASSERT_TRUE(at.done) << at.message;
      const TargetValue v = target_value(at, setup, o, true);
      ASSERT_TRUE(v.done) << v.message;
      const double h = 1e-4 * L;
      const ComplianceDerivative d = target_derivative(at, v, {}, line.at(h), line.at(-h), h, setup, o);
      ASSERT_TRUE(d.done) << d.message;
      EXPECT_GT(d.cells_changed, 0) << k.what;
      double coarse = 0;
      const double fd = testing::richardson(
          [&](double H) {
            const ComplianceState side = compliance_at(line.at(H), at, setup);
            EXPECT_TRUE(side.done) << k.what << ": " << side.message;
            return side.done ? target_value(side, setup, o).objective : std::nan("");
          },
          2e-4 * L, &coarse);
      std::printf("%s (%s): J = %.10g (RMS %.4g mm, max %.4g mm), adjoint %.10g, FD %.10g (H: %.10g), relative %.2e, "
                  "%d cells, %d switches\n",
                  k.what, hyperelastic ? "neo-Hooke" : "linear", v.objective, std::sqrt(v.objective), v.max_distance,
                  d.derivative, fd, coarse, std::abs(d.derivative - fd) / std::abs(fd), d.cells_changed,
                  d.topology_switches);
      EXPECT_LE(std::abs(d.derivative - fd), k.tolerance[hyperelastic] * std::abs(fd)) << k.what;
    }
  }
}

// The exact route (target_gradient: the adjoint above, boundary integrals over the moving
// patches plus the matched face's own motion and its edges' slide; linear) against the same
// reference: Richardson differences of the full pipeline on the fixed grid, the L-bracket turned
// 11°. Two matched faces: the base top plane, into which the inner fillet runs tangent (its
// offset moves the fillet along: the edge is the foot of the fillet's spine), and the bolt hole
// (a cylinder: the κg term; its edges slide on the base's planes). The semi-analytic route is
// printed beside it.
TEST(ShapeTarget, ExactRouteMatchesFiniteDifferencesOfTheFullPipeline) {
  testing::TurnedBracket c;
  const testing::DesignSpace space(*c.part, {c.setup.dirichlet[0].face, c.setup.tractions[0].face});
  ASSERT_TRUE(space.start.done);
  const auto& [model, sp, start, L] = space;
  struct Case {
    const char* what;
    int face, index;
    double tolerance;  // relative, near the measured figure
    bool direction;    // a normal component: steps 1e-4 (else 1e-4 L)
  };
  // Measured (relative to the differences), in this order: 9.9e-9, 2.4e-9 (7.3e-5 without the
  // fillet foot's slide −φ_F(S) ν·∂n_F), 2.6e-8, 1.6e-9, 2.3e-9; 2.1e-7, 3.0e-6, 7.1e-7. The
  // semi-analytic route: 6.1e-6 … 1.1e-7, but 2.9 (a factor 3.9) on the hole's own radius.
  const std::vector<Case> cases = {
      {"base top matched, its offset (inner fillet follows)", c.base_top, parameter_index(sp, c.base_top, "offset"), 3e-8, false},
      {"base top matched, its normal x (inner fillet follows)", c.base_top, parameter_index(sp, c.base_top, "normal x"), 1e-8, true},
      {"base top matched, hole radius", c.base_top, parameter_index(sp, c.hole, "radius"), 1e-7, false},
      {"base top matched, inner fillet radius", c.base_top, parameter_index(sp, c.fillet, "radius"), 1e-8, false},
      {"base top matched, upright inner offset", c.base_top, parameter_index(sp, c.upright_inner, "offset"), 1e-8, false},
      {"hole matched, its radius", c.hole, parameter_index(sp, c.hole, "radius"), 1e-6, false},
      {"hole matched, base top offset", c.hole, parameter_index(sp, c.base_top, "offset"), 1e-5, false},
      {"hole matched, base top normal x", c.hole, parameter_index(sp, c.base_top, "normal x"), 3e-6, true},
  };
  for (const Case& k : cases) {
    TargetOptions o;
    o.face = k.face;
    o.target = target_of_face(model, k.face);
    const testing::ProjectedEntry entry(*c.part, model, sp, start.p, k.index, L);
    ASSERT_TRUE(entry.p0.done);
    auto part_at = [&](double s) { return entry.part_at(s); };
    const ComplianceState at = compliance_start(part_at(0), c.setup);
    ASSERT_TRUE(at.done) << at.message;
    const TargetValue v = target_value(at, c.setup, o, true);
    ASSERT_TRUE(v.done) << v.message;
    const Eigen::VectorXd lambda = target_adjoint(at, v);
    const ComplianceGradient g = target_gradient(at, v, lambda, c.setup, o, sp, entry.p0.p);
    ASSERT_TRUE(g.done) << g.message;
    EXPECT_TRUE(exact_along(g, entry.column)) << k.what;
    const double exact = g.gradient.dot(entry.column);
    const double scale = k.direction ? 1.0 : L, h = 1e-4 * scale;
    const ComplianceDerivative d = target_derivative(at, v, lambda, part_at(h), part_at(-h), h, c.setup, o);
    ASSERT_TRUE(d.done) << d.message;
    const double fd = testing::richardson(
        [&](double H) {
          const ComplianceState side = compliance_at(part_at(H), at, c.setup);
          EXPECT_TRUE(side.done) << k.what << ": " << side.message;
          return side.done ? target_value(side, c.setup, o).objective : std::nan("");
        },
        2e-4 * scale);
    std::printf("%s: J = %.10g, exact %.10g (%.3f s, %d elements, %d points, %d on edges), semi-analytic %.10g "
                "(%d cells, %d switches), FD %.10g, relative: exact %.2e, semi-analytic %.2e\n",
                k.what, v.objective, exact, g.seconds, g.elements, g.points, g.edge_points, d.derivative, d.cells_changed,
                d.topology_switches, fd,
                std::abs(exact - fd) / std::abs(fd), std::abs(d.derivative - fd) / std::abs(fd));
    EXPECT_LE(std::abs(exact - fd), k.tolerance * std::abs(fd)) << k.what;
  }
}

TEST(ShapeTarget, BadSurfacesAreNamed) {
  auto message = [](const TargetSurface& t) {
    try {
      check_target_surface(t, "objective.target.x");
    } catch (const Error& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  EXPECT_NE(message({SurfaceType::plane, Vec3::Zero(), Vec3::Zero(), 0, 0}).find("objective.target.x: the normal is zero"),
            std::string::npos);
  EXPECT_NE(message({SurfaceType::cylinder, Vec3::Zero(), Vec3::UnitZ(), 0, 0}).find("radius must be positive, got 0"),
            std::string::npos);
  EXPECT_NE(message({SurfaceType::torus, Vec3::Zero(), Vec3::UnitZ(), 3, 2}).find("major_radius must exceed radius (3)"),
            std::string::npos);
  EXPECT_NE(message({SurfaceType::cone, Vec3::Zero(), Vec3::UnitZ(), 3, 0}).find("a plane, sphere, cylinder or torus"),
            std::string::npos);
  EXPECT_EQ(message({SurfaceType::sphere, Vec3(1, 2, 3), Vec3::Zero(), 3, 0}), "");
  // No direction on a cylinder's axis: an error, never NaN.
  EXPECT_THROW(signed_distance({SurfaceType::cylinder, Vec3::Zero(), Vec3::UnitZ(), 1, 0}, Vec3(0, 0, 5)), Error);
}

}  // namespace
}  // namespace parafab::occ
