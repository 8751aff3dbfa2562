// The poles of B-spline faces as shape parameters (thesis §6.5.1, "B-spline poles for free-form
// faces"): their names and values against the generator's closed form, the write-back of moved
// poles checked by BRepCheck and OCCT's face areas, the boundary-integral mass derivatives
// (∂X/∂P_ij = R_ij) against central differences of OCCT's mass properties, and the compliance
// and failure derivatives of a pole against central differences of the whole pipeline on a
// turned part.
#include <gtest/gtest.h>

#include <BRepBuilderAPI_MakeEdge.hxx>
#include <BRepCheck_Analyzer.hxx>
#include <BRepBuilderAPI_MakeFace.hxx>
#include <BRepBuilderAPI_MakeSolid.hxx>
#include <BRepBuilderAPI_MakeWire.hxx>
#include <BRepBuilderAPI_Sewing.hxx>
#include <BRepLib.hxx>
#include <BRep_Tool.hxx>
#include <Geom_BSplineSurface.hxx>
#include <Precision.hxx>
#include <TColStd_Array1OfInteger.hxx>
#include <TColStd_Array1OfReal.hxx>
#include <TColgp_Array2OfPnt.hxx>
#include <TopExp_Explorer.hxx>
#include <TopoDS.hxx>
#include <TopoDS_Shell.hxx>
#include <TopoDS_Solid.hxx>
#include <cmath>
#include <cstdio>

#include "common/error.h"
#include "face_lookup.h"
#include "nurbs_surface.h"
#include "occt_mass_properties.h"
#include "optimize/projection.h"
#include "occt_shape.h"
#include "shape_compliance.h"
#include "shape_failure.h"
#include "shape_derivatives.h"
#include "shape_modify.h"
#include "shape_parameters.h"
#include "turned_bracket.h"

namespace parafab::occ {
namespace {

using testing::DesignLine;
using testing::richardson;
using testing::sample_part;

// samples/parts/make_parts.py bump_block: pole (i, j), 1-based, at x = 12 (i − 1), y = 10 (j − 1),
// z = 12 + 0.05 x, interior poles raised by 2 + 0.5 (i − 1).
Vec3 generator_pole(int i, int j) {
  const double x = 12.0 * (i - 1), y = 10.0 * (j - 1);
  const bool interior = i > 1 && i < 6 && j > 1 && j < 5;
  return {x, y, 12 + 0.05 * x + (interior ? 2 + 0.5 * (i - 1) : 0)};
}

int bspline_face(const FaceModel& model) {
  int found = -1, count = 0;
  for (const FaceInfo& f : model.faces)
    if (f.primitive.type == SurfaceType::bspline) found = f.index, ++count;
  EXPECT_EQ(count, 1);
  return found;
}

TEST(BsplinePoles, PolesAreParametersNumberedAsInOcct) {
  const auto part = read_part(sample_part("bump_block"));
  const FaceModel model = build_face_model(*part);
  const int top = bspline_face(model);
  const ShapeParameters sp = build_shape_parameters(model);
  ASSERT_NE(sp.poles(top), nullptr);
  const PoleBlock& b = *sp.poles(top);
  EXPECT_EQ(b.count_u(), 6);
  EXPECT_EQ(b.count_v(), 5);
  EXPECT_EQ(sp.size(), 5 * 4 + 90);  // five planes (n, d), then the 30 poles
  EXPECT_EQ(sp.blocks.size(), 5u);   // "auto" designs take the analytic blocks only
  for (int i = 1; i <= 6; ++i)
    for (int j = 1; j <= 5; ++j)
      for (int c = 0; c < 3; ++c) {
        const std::string name = std::string("pole ") + std::to_string(i) + " " + std::to_string(j) + " " + "xyz"[c];
        const int k = parameter_index(sp, top, name);
        EXPECT_EQ(k, b.entry(i, j, c));
        EXPECT_EQ(sp.names[k], "face " + std::to_string(top) + " bspline " + name);
        EXPECT_NEAR(sp.initial[k], generator_pole(i, j)[c], 1e-12) << name;
      }
  try {
    parameter_index(sp, top, "pole 7 1 z");
    ADD_FAILURE() << "pole 7 1 z accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("i in 1..6 and j in 1..5"), std::string::npos) << e.what();
  }
  // A tie moves poles together (one design variable for a row of the bump).
  ShapeParameterOptions o;
  o.ties.push_back({{top, "pole 3 2 z"}, {top, "pole 3 3 z"}, {top, "pole 3 4 z"}});
  EXPECT_EQ(build_shape_parameters(model, o).constraints.size(), 5 + 2);  // unit normals, the tie's two rows
}

// The ten moments of the bump block from its top surface alone (independent of the boundary
// quadrature under test): the sides are vertical and the bottom is z = 0, so with F_z = ∫₀^z g dz
// the divergence theorem leaves ∫_V g dV = ∫∫ F_z(S(u, v)) (S_u × S_v)_z du dv over the top, a
// polynomial on each knot span, integrated exactly by 10 × 10 Gauss points per span (OCCT's
// evaluation of the surface).
Moments top_surface_moments(const Handle(Geom_BSplineSurface)& s) {
  static const double x10[] = {-0.9739065285171717, -0.8650633666889845, -0.6794095682990244, -0.4333953941292472,
                               -0.1488743389816312, 0.1488743389816312,  0.4333953941292472,  0.6794095682990244,
                               0.8650633666889845,  0.9739065285171717};
  static const double w10[] = {0.0666713443086881, 0.1494513491505806, 0.2190863625159820, 0.2692667193099963,
                               0.2955242247147529, 0.2955242247147529, 0.2692667193099963, 0.2190863625159820,
                               0.1494513491505806, 0.0666713443086881};
  Moments m = Moments::Zero();
  for (int a = 1; a < s->NbUKnots(); ++a)
    for (int b = 1; b < s->NbVKnots(); ++b) {
      const double u0 = s->UKnot(a), u1 = s->UKnot(a + 1), v0 = s->VKnot(b), v1 = s->VKnot(b + 1);
      for (int i = 0; i < 10; ++i)
        for (int j = 0; j < 10; ++j) {
          const double u = 0.5 * (u0 + u1 + (u1 - u0) * x10[i]), v = 0.5 * (v0 + v1 + (v1 - v0) * x10[j]);
          gp_Pnt P;
          gp_Vec Su, Sv;
          s->D1(u, v, P, Su, Sv);
          const double w = 0.25 * (u1 - u0) * (v1 - v0) * w10[i] * w10[j] * Su.Crossed(Sv).Z();
          const double x = P.X(), y = P.Y(), z = P.Z();
          Moments g;
          g << z, x * z, y * z, z * z / 2, x * x * z, y * y * z, z * z * z / 3, x * y * z, y * z * z / 2, x * z * z / 2;
          m += w * g;
        }
    }
  return m;
}

Handle(Geom_BSplineSurface) top_surface(const PartShape& part, int face) {
  return Handle(Geom_BSplineSurface)::DownCast(BRep_Tool::Surface(part.face(face)));
}

// Largest difference per moment, relative to the largest moment (derivative) of its degree.
double worst_relative(const Moments& a, const Moments& b) {
  double worst = 0;
  for (int k = 0; k < 10; ++k) {
    const int lo = k == 0 ? 0 : k < 4 ? 1 : 4, n = k == 0 ? 1 : k < 4 ? 3 : 6;
    const double scale = std::max(b.segment(lo, n).cwiseAbs().maxCoeff(), 1e-6 * b.cwiseAbs().maxCoeff());
    worst = std::max(worst, std::abs(a[k] - b[k]) / scale);
  }
  return worst;
}

// Moved poles written into the B-rep: a valid solid whose top surface carries the moved pole; an
// interior pole leaves the side faces alone (OCCT's areas unchanged), a pole of the boundary
// row in the plane x = 0 moves that face's edge (the plane cut with the moved surface). The
// boundary-integral moments and their pole derivatives (V_n = R_ij n_c, Green's rule split at
// the knots) against the closed form above and its central differences in the pole.
TEST(BsplinePoles, MovedPolesGiveValidPartsAndExactMassDerivatives) {
  const auto part = read_part(sample_part("bump_block"));
  const FaceModel model = build_face_model(*part);
  const int top = bspline_face(model);
  const ShapeParameters sp = build_shape_parameters(model);
  const MomentDerivatives md = moment_derivatives(*part, sp, sp.initial);
  const Moments reference = top_surface_moments(top_surface(*part, top)), occt = occt_moments(*part);
  std::printf("moments: boundary quadrature %.2e, OCCT's mass properties %.2e off the closed form (volume %.10g)\n",
              worst_relative(md.moments, reference), worst_relative(occt, reference), reference[0]);
  EXPECT_LE(worst_relative(md.moments, reference), 2e-14);  // measured 5.2e-15 (before the knot splits 1.6e-5)
  EXPECT_LE(worst_relative(occt, reference), 1e-14);        // measured 8.0e-16 (adaptive BRepGProp)
  struct Case {
    const char* parameter;
    bool boundary;
  };
  for (const Case& c : {Case{"pole 3 2 z", false}, Case{"pole 4 3 x", false}, Case{"pole 2 4 y", false},
                        Case{"pole 1 3 z", true}}) {
    const int i = parameter_index(sp, top, c.parameter);
    const double h = 1e-3;
    Moments m[2];
    double written = 0;
    for (int side = 0; side < 2; ++side) {
      Eigen::VectorXd p = sp.initial;
      p[i] += side ? -h : h;
      const ModifyResult mod = modify_part(*part, model, sp, p);
      ASSERT_TRUE(mod.done) << c.parameter << ": " << mod.message;
      EXPECT_EQ(mod.modified_faces, 1) << c.parameter;
      const Handle(Geom_BSplineSurface) moved = top_surface(*mod.part, top);
      ASSERT_FALSE(moved.IsNull());
      const PoleBlock& b = *sp.poles(top);
      for (int pi = 1; pi <= b.count_u(); ++pi)
        for (int pj = 1; pj <= b.count_v(); ++pj)
          for (int k = 0; k < 3; ++k) EXPECT_EQ(moved->Pole(pi, pj).Coord(k + 1), p[b.entry(pi, pj, k)]);
      m[side] = top_surface_moments(moved);
      written = std::max(written, worst_relative(occt_moments(*mod.part), m[side]));  // OCCT's mass properties
      int sides_changed = 0;
      for (int f = 0; f < part->face_count(); ++f)
        if (f != top) sides_changed += std::abs(face_area(*mod.part, f) - face_area(*part, f)) > 1e-9 * face_area(*part, f);
      EXPECT_EQ(sides_changed, c.boundary ? 1 : 0) << c.parameter;
    }
    EXPECT_LE(written, 1e-14) << c.parameter;  // measured 4e-16 .. 1.4e-15
    // Reference derivative: Richardson-extrapolated central differences of the closed form with
    // the pole moved in a copy of OCCT's surface (cubic in the pole: exact up to round-off).
    auto moved_moments = [&](double s) {
      const auto copy = Handle(Geom_BSplineSurface)::DownCast(top_surface(*part, top)->Copy());
      const PoleBlock& b = *sp.poles(top);
      const int k = i - b.offset, pi = k / 3 / b.count_v() + 1, pj = k / 3 % b.count_v() + 1;
      gp_Pnt P = copy->Pole(pi, pj);
      P.SetCoord(k % 3 + 1, P.Coord(k % 3 + 1) + s);
      copy->SetPole(pi, pj, P);
      return top_surface_moments(copy);
    };
    auto central = [&](double H) -> Moments { return (moved_moments(H) - moved_moments(-H)) / (2 * H); };
    const Moments fd = (4 * central(0.05) - central(0.1)) / 3;
    const Moments exact = md.gradient.col(i);
    std::printf("%s: dV/dP %.12g (closed form's differences %.12g), worst moment %.2e of its degree's scale; "
                "written parts' OCCT moments %.2e off their closed form\n",
                c.parameter, exact[0], fd[0], worst_relative(exact, fd), written);
    // Measured 2.3e-12 (z moves), 9.0e-11 and 2.4e-11 (x, y moves: moments of higher degree in
    // the pole, where the extrapolated differences keep an H⁴ error).
    EXPECT_LE(worst_relative(exact, fd), 2e-10) << c.parameter;
  }
}

// `unturned` turned 11° about (1, 2, 3) through `center` (its cells are cut), with the steel
// cantilever job: the faces through `support` and `load` (unturned points) clamped and pulled by
// `force` (unturned).
struct TurnedCantilever {
  std::shared_ptr<const PartShape> part;
  ComplianceSetup setup;
  TurnedCantilever(const PartShape& unturned, const Vec3& center, const Vec3& support, const Vec3& load,
                   const Vec3& force) {
    const Vec3 axis = Vec3(1, 2, 3).normalized();
    const double degrees = 11;
    auto turned = [&](const Vec3& X) -> Vec3 { return center + Eigen::AngleAxisd(degrees * M_PI / 180, axis) * (X - center); };
    part = rotated_part(unturned, center, axis, degrees);
    setup = testing::steel_cantilever(*part, face_at_point(*part, turned(support), 1e-6),
                                      face_at_point(*part, turned(load), 1e-6), turned(force) - turned(Vec3::Zero()));
  }
};

// The bump block turned 11° about (1, 2, 3): clamped at x = 0, pulled down by 500 N at x = 60.
TurnedCantilever turned_bump_block() {
  return TurnedCantilever(*read_part(sample_part("bump_block")), {30, 20, 8}, {0, 20, 5}, {60, 20, 5}, {0, 0, -500});
}

// The compliance derivative of an interior pole by both routes (exact: Vₙ = R_ij n_c on the
// patches; semi-analytic: two perturbed re-cut models) against Richardson-extrapolated central
// differences of the whole pipeline, on the bump block turned 11° off the grid: x = 0
// supported, x = 60 pulled down by 500 N.
TEST(BsplinePoles, ComplianceDerivativeOfAPoleMatchesTheFullPipeline) {
  const TurnedCantilever c = turned_bump_block();
  const auto& [part, setup] = c;
  const testing::DesignSpace space(*part, {setup.dirichlet[0].face, setup.tractions[0].face});
  ASSERT_TRUE(space.start.done);
  const auto& [model, sp, start, L] = space;
  const int top = bspline_face(model);
  for (const char* parameter : {"pole 3 2 z", "pole 5 3 z"}) {
    const int index = parameter_index(sp, top, parameter);
    const DesignLine line(*part, model, sp, index, start.p, L);
    const ComplianceState at = compliance_start(line.at(0), setup);
    ASSERT_TRUE(at.done) << at.message;
    const ComplianceGradient g = compliance_gradient(at, setup, sp, start.p);
    ASSERT_TRUE(g.done) << g.message;
    EXPECT_FALSE(g.incomplete[index]) << parameter;  // interior: its basis functions miss the support's and load's edges
    // Poles of the boundary rows on the support (u = 0) and the load (u = 1) move those edges:
    // flagged for the semi-analytic route.
    EXPECT_TRUE(g.incomplete[parameter_index(sp, top, "pole 1 3 z")]);
    EXPECT_TRUE(g.incomplete[parameter_index(sp, top, "pole 6 2 x")]);
    EXPECT_FALSE(g.incomplete[parameter_index(sp, top, "pole 3 1 z")]);  // the side y = 0 is free
    const double h = 1e-4 * L;
    const ComplianceDerivative dc = compliance_derivative(at, line.at(h), line.at(-h), h, setup);
    ASSERT_TRUE(dc.done) << dc.message;
    EXPECT_GT(dc.cells_changed, 0);
    double coarse = 0;
    const double fd = richardson([&](double H) { return testing::compliance_on(line.at(H), at, setup); }, 2e-4 * L, &coarse);
    std::printf("%s: C = %.10g, exact %.10g, semi-analytic %.10g, FD %.10g (H: %.10g), relative differences %.2e / %.2e, "
                "%d cells, %d switches\n",
                parameter, at.compliance, g.gradient[index], dc.derivative, fd, coarse,
                std::abs(g.gradient[index] - fd) / std::abs(fd), std::abs(dc.derivative - fd) / std::abs(fd),
                dc.cells_changed, dc.topology_switches);
    EXPECT_LE(std::abs(g.gradient[index] - fd), 5e-8 * std::abs(fd)) << parameter;
    EXPECT_LE(std::abs(dc.derivative - fd), 5e-8 * std::abs(fd)) << parameter;  // measured 1.7e-8, 9.9e-10
  }
}

// The failure metric's exact route on the same poles (failure_gradient: Vₙ = R_ij(u, v) n_c on
// the B-spline face's patches, ĵ on the frozen frames), σ_y half the start's max σ_vm, α 6,
// against Richardson differences of the whole pipeline with the frames frozen at the start.
TEST(BsplinePoles, FailureDerivativeOfAPoleMatchesTheFullPipeline) {
  const TurnedCantilever c = turned_bump_block();
  const auto& [part, setup] = c;
  const testing::DesignSpace space(*part, {setup.dirichlet[0].face, setup.tractions[0].face});
  ASSERT_TRUE(space.start.done);
  const auto& [model, sp, start, L] = space;
  const int top = bspline_face(model);
  for (const char* parameter : {"pole 3 2 z", "pole 5 3 z"}) {
    const int index = parameter_index(sp, top, parameter);
    const DesignLine line(*part, model, sp, index, start.p, L);
    const ComplianceState at = compliance_start(line.at(0), setup);
    ASSERT_TRUE(at.done) << at.message;
    const FailureValue v0 = failure_value(at, setup, {1, 1, true});
    ASSERT_TRUE(v0.done) << v0.message;
    const FailureOptions fo{v0.max_von_mises / 2, 6, true};
    const FailureValue v = failure_value(at, setup, fo, true);
    const ComplianceGradient g = failure_gradient(at, v, {}, setup, fo, sp, start.p);
    ASSERT_TRUE(g.done) << g.message;
    EXPECT_FALSE(g.incomplete[index]) << parameter;
    const double fd = richardson(
        [&](double H) { return testing::failure_on(line.at(H), at, setup, fo); },
        2e-4 * L);
    std::printf("%s: J = %.10g (max σ_vm %.4g), exact %.10g, FD %.10g, relative %.2e\n", parameter, v.objective,
                v.max_von_mises, g.gradient[index], fd, std::abs(g.gradient[index] - fd) / std::abs(fd));
    EXPECT_LE(std::abs(g.gradient[index] - fd), 4e-7 * std::abs(fd)) << parameter;  // measured 1.5e-7, 2.7e-8
  }
}

// The same with the local Nitsche penalty, for a pole of the row next to the support: its basis
// function reaches the top patches of the clamped cut cells, whose penalty κΛ changes with it
// (dΛ = vᵀdBv − Λ vᵀdÂv, see compliance_gradient). Until 2026-11-28 such poles were flagged and
// differenced.
TEST(BsplinePoles, LocalPenaltyComplianceDerivativeOfAClampSidePoleIsExact) {
  TurnedCantilever c = turned_bump_block();
  auto& [part, setup] = c;
  setup.solver.nitsche_penalty = xfem::LinearXfemOptions::NitschePenalty::Local;
  setup.solver.nitsche_beta = 0;
  const testing::DesignSpace space(*part, {setup.dirichlet[0].face, setup.tractions[0].face});
  ASSERT_TRUE(space.start.done);
  const auto& [model, sp, start, L] = space;
  const int top = bspline_face(model);
  const int index = parameter_index(sp, top, "pole 2 3 z");
  const DesignLine line(*part, model, sp, index, start.p, L);
  const ComplianceState at = compliance_start(line.at(0), setup);
  ASSERT_TRUE(at.done) << at.message;
  const ComplianceGradient g = compliance_gradient(at, setup, sp, start.p);
  ASSERT_TRUE(g.done) << g.message;
  EXPECT_FALSE(g.incomplete[index]);
  const double fd = richardson([&](double H) { return testing::compliance_on(line.at(H), at, setup); }, 2e-4 * L);
  const double h = 1e-4 * L;
  const ComplianceDerivative dc = compliance_derivative(at, line.at(h), line.at(-h), h, setup);
  ASSERT_TRUE(dc.done) << dc.message;
  std::printf("local penalty, pole 2 3 z: C = %.10g, exact %.10g, semi-analytic %.10g, FD %.10g, relative differences "
              "%.2e / %.2e\n",
              at.compliance, g.gradient[index], dc.derivative, fd, std::abs(g.gradient[index] - fd) / std::abs(fd),
              std::abs(dc.derivative - fd) / std::abs(fd));
  EXPECT_LE(std::abs(g.gradient[index] - fd), 1e-8 * std::abs(fd));  // measured 3.7e-9
}

// The solid bounded by the faces added to `sew` (sewn, oriented outward), as a part.
std::shared_ptr<const PartShape> sewn_solid(BRepBuilderAPI_Sewing& sew, const std::string& name) {
  sew.Perform();
  TopExp_Explorer shells(sew.SewedShape(), TopAbs_SHELL);
  EXPECT_TRUE(shells.More()) << name;
  TopoDS_Solid solid = BRepBuilderAPI_MakeSolid(TopoDS::Shell(shells.Current())).Solid();
  BRepLib::OrientClosedSolid(solid);
  return make_part(solid, name);
}

// A closed free-form face: a tube periodic in u (8 distinct poles about z, cubic, a uniform
// periodic knot vector), quadratic in v over three rows at z = 0, 10, 20 whose middle row bulges
// by 1.5 + 0.5 cos 2t, capped by the planes of its first and last rows.
std::shared_ptr<const PartShape> periodic_tube() {
  const int nu = 8;
  TColgp_Array2OfPnt poles(1, nu, 1, 3);
  for (int i = 1; i <= nu; ++i) {
    const double t = 2 * M_PI * (i - 1) / nu;
    for (int j = 1; j <= 3; ++j) {
      const double r = 10 + (j == 2 ? 1.5 + 0.5 * std::cos(2 * t) : 0.0);
      poles(i, j) = gp_Pnt(r * std::cos(t), r * std::sin(t), 10.0 * (j - 1));
    }
  }
  TColStd_Array1OfReal uk(1, nu + 1), vk(1, 2);
  TColStd_Array1OfInteger um(1, nu + 1), vm(1, 2);
  for (int k = 1; k <= nu + 1; ++k) uk(k) = k - 1, um(k) = 1;
  vk(1) = 0, vk(2) = 1, vm(1) = vm(2) = 3;
  const Handle(Geom_BSplineSurface) s = new Geom_BSplineSurface(poles, uk, vk, um, vm, 3, 2, true, false);
  BRepBuilderAPI_Sewing sew(1e-6);
  sew.Add(BRepBuilderAPI_MakeFace(s, Precision::Confusion()).Face());
  for (const double v : {0.0, 1.0})
    sew.Add(BRepBuilderAPI_MakeFace(BRepBuilderAPI_MakeWire(BRepBuilderAPI_MakeEdge(s->VIso(v)).Edge()).Wire(), true).Face());
  return sewn_solid(sew, "periodic tube");
}

// Its poles are parameters (8 × 3 distinct, not the 11 × 3 of the unwrapped layout); the
// unwrapped surface evaluates as OCCT's, also a period away; a moved pole is written into the
// periodic surface (the caps stay for a middle-row pole); and dV/dP of a pole repeated in the
// unwrapped layout (i = 1, its two copies add) and of another match central differences of
// OCCT's mass properties of the written parts.
TEST(BsplinePoles, PeriodicFacePolesAreParametersWithExactMassDerivatives) {
  const auto part = periodic_tube();
  const FaceModel model = build_face_model(*part);
  const int side = bspline_face(model);
  ASSERT_GE(side, 0);
  const auto occt = top_surface(*part, side);
  ASSERT_TRUE(occt->IsUPeriodic());
  const NurbsSurface& n = model.faces[side].bspline;
  ASSERT_TRUE(n.periodic_u);
  EXPECT_EQ(n.distinct_u(), 8);
  EXPECT_EQ(n.distinct_v(), 3);
  double worst = 0;
  for (int a = 0; a <= 40; ++a)
    for (int b = 0; b <= 4; ++b) {
      const double u = -8 + 24.0 * a / 40, v = 0.25 * b;  // three periods
      Eigen::Vector3d X, Xu, Xv;
      evaluate(n, u, v, X, Xu, Xv);
      const gp_Pnt P = occt->Value(u, v);
      worst = std::max(worst, (X - Eigen::Vector3d(P.X(), P.Y(), P.Z())).norm());
    }
  std::printf("periodic tube: the unwrapped surface is %.2e from OCCT's evaluation over three periods\n", worst);
  EXPECT_LT(worst, 1e-12) << "the unwrapped layout is not OCCT's";
  const ShapeParameters sp = build_shape_parameters(model);
  ASSERT_NE(sp.poles(side), nullptr);
  EXPECT_EQ(sp.poles(side)->size(), 3 * 8 * 3);
  EXPECT_NEAR(sp.initial[parameter_index(sp, side, "pole 3 2 y")], 11.0 * std::sin(M_PI / 2), 1e-12);  // r = 10 + 1.5 + 0.5 cos π
  const MomentDerivatives md = moment_derivatives(*part, sp, sp.initial);
  const Moments volume = occt_moments(*part);
  std::printf("periodic tube: V = %.10g (OCCT), boundary quadrature %.2e off\n", volume[0],
              worst_relative(md.moments, volume));
  EXPECT_LE(worst_relative(md.moments, volume), 2e-9);  // measured 8.0e-10 (the bump block's top: 5e-15)
  for (const char* parameter : {"pole 1 2 x", "pole 3 2 y", "pole 6 2 z"}) {
    const int i = parameter_index(sp, side, parameter);
    auto moments_at = [&](double h) {
      Eigen::VectorXd p = sp.initial;
      p[i] += h;
      const ModifyResult mod = modify_part(*part, model, sp, p);
      EXPECT_TRUE(mod.done) << parameter << ": " << mod.message;
      EXPECT_EQ(mod.modified_faces, 1) << parameter;
      return occt_moments(*mod.part);
    };
    // Richardson-extrapolated central differences (the moments are polynomials in the pole; a
    // larger step keeps OCCT's own relative error, 1e-12, small against the difference).
    auto central = [&](double H) -> Moments { return (moments_at(H) - moments_at(-H)) / (2 * H); };
    const Moments fd = (4 * central(0.01) - central(0.02)) / 3;
    const Moments exact = md.gradient.col(i);
    std::printf("%s: dV/dP %.12g, OCCT's differences %.12g, worst moment %.2e of its degree's scale\n", parameter,
                exact[0], fd[0], worst_relative(exact, fd));
    EXPECT_LE(worst_relative(exact, fd), 5e-10) << parameter;  // measured 3.5e-12, 1.1e-11, 9.3e-11
  }
}

// The compliance derivative of a periodic face's poles by the exact route (Vₙ = R_ij n_c at the
// rules' (u, v)) against Richardson-extrapolated central differences of the whole pipeline: the
// tube turned 11° off the grid, its bottom cap clamped, its top cap pulled sideways by 500 N.
TEST(BsplinePoles, PeriodicFacePoleComplianceDerivativeMatchesThePipeline) {
  const TurnedCantilever c(*periodic_tube(), {0, 0, 10}, {0, 0, 0}, {0, 0, 20}, {500, 0, 0});
  const auto& [part, setup] = c;
  const testing::DesignSpace space(*part, {setup.dirichlet[0].face, setup.tractions[0].face});
  ASSERT_TRUE(space.start.done);
  const auto& [model, sp, start, L] = space;
  const int side = bspline_face(model);
  // Poles 2 and 3 are repeated in the unwrapped layout (their basis functions wrap across u = 0).
  // Measured 1.8e-9 and 3.3e-9. Radial moves of poles 1 and 2, which move the seam most, leave
  // the pipeline's differences 1e-4 to 3e-4 apart between step sizes (the exact route equals the
  // semi-analytic one there to 1e-9): not a reference at this tolerance.
  for (const char* parameter : {"pole 2 2 z", "pole 3 2 y"}) {
    const int index = parameter_index(sp, side, parameter);
    const DesignLine line(*part, model, sp, index, start.p, L);
    const ComplianceState at = compliance_start(line.at(0), setup);
    ASSERT_TRUE(at.done) << at.message;
    const ComplianceGradient g = compliance_gradient(at, setup, sp, start.p);
    ASSERT_TRUE(g.done) << g.message;
    EXPECT_FALSE(g.incomplete[index]) << parameter;  // a middle-row pole: its basis misses the caps' edges
    const double fd = richardson([&](double H) { return testing::compliance_on(line.at(H), at, setup); }, 2e-4 * L);
    std::printf("periodic tube, %s: C = %.10g, exact %.10g, FD %.10g, relative difference %.2e\n", parameter,
                at.compliance, g.gradient[index], fd, std::abs(g.gradient[index] - fd) / std::abs(fd));
    EXPECT_LE(std::abs(g.gradient[index] - fd), 1e-8 * std::abs(fd)) << parameter;
  }
  // A radial move of pole 1, which moves the seam: the pipeline's differences at two step sizes
  // are 3e-4 apart (measured), so they cannot check the exact route here; the semi-analytic route
  // (the perturbed models, element systems with the topology frozen) equals it (measured 2e-10).
  const int index = parameter_index(sp, side, "pole 1 2 x");
  const DesignLine line(*part, model, sp, index, start.p, L);
  const ComplianceState at = compliance_start(line.at(0), setup);
  ASSERT_TRUE(at.done) << at.message;
  const ComplianceGradient g = compliance_gradient(at, setup, sp, start.p);
  ASSERT_TRUE(g.done) << g.message;
  const double h = 1e-4 * L;
  const ComplianceDerivative dc = compliance_derivative(at, line.at(h), line.at(-h), h, setup);
  ASSERT_TRUE(dc.done) << dc.message;
  const double fine = richardson([&](double H) { return testing::compliance_on(line.at(H), at, setup); }, 2e-4 * L);
  const double wide = richardson([&](double H) { return testing::compliance_on(line.at(H), at, setup); }, 1e-3 * L);
  std::printf("periodic tube, pole 1 2 x (moves the seam): exact %.10g, semi-analytic %.10g, pipeline differences "
              "%.10g / %.10g (steps 2e-4 / 1e-3 L, %.2e apart)\n",
              g.gradient[index], dc.derivative, fine, wide, std::abs(fine - wide) / std::abs(wide));
  EXPECT_LE(std::abs(g.gradient[index] - dc.derivative), 2e-9 * std::abs(dc.derivative));
  EXPECT_GT(std::abs(fine - wide) / std::abs(wide), 1e-4);  // optimization.md's "1e-4–3e-4"
}

// A block 60 × 30 × 10 whose top is the plane z = 10 for x ≤ 20 and, for x ≥ 20, a B-spline
// face (6 × 4 poles, cubic in u along x, quadratic in v along y, clamped) whose first two rows
// of poles lie in that plane, so that it leaves the plane tangentially (G1), bulges and ends at
// z = 13.2 (14.2 in the middle) on x = 60.
std::shared_ptr<const PartShape> g1_block() {
  TColgp_Array2OfPnt poles(1, 6, 1, 4);
  for (int i = 1; i <= 6; ++i)
    for (int j = 1; j <= 4; ++j)
      poles(i, j) = gp_Pnt(20 + 8.0 * (i - 1), 10.0 * (j - 1), 10 + (i >= 3 ? 0.8 * (i - 2) + (j == 2 || j == 3 ? 1.0 : 0.0) : 0.0));
  TColStd_Array1OfReal uk(1, 4), vk(1, 3);
  TColStd_Array1OfInteger um(1, 4), vm(1, 3);
  uk(1) = 0, uk(2) = 1.0 / 3, uk(3) = 2.0 / 3, uk(4) = 1, um(1) = um(4) = 4, um(2) = um(3) = 1;
  vk(1) = 0, vk(2) = 0.5, vk(3) = 1, vm(1) = vm(3) = 3, vm(2) = 1;
  const Handle(Geom_BSplineSurface) s = new Geom_BSplineSurface(poles, uk, vk, um, vm, 3, 2);
  auto line = [](const gp_Pnt& a, const gp_Pnt& b) { return BRepBuilderAPI_MakeEdge(a, b).Edge(); };
  auto planar = [](std::initializer_list<TopoDS_Edge> edges) {
    BRepBuilderAPI_MakeWire w;
    for (const TopoDS_Edge& e : edges) w.Add(e);
    return BRepBuilderAPI_MakeFace(w.Wire(), true).Face();
  };
  const double zr = poles(6, 1).Z();
  BRepBuilderAPI_Sewing sew(1e-6);
  sew.Add(BRepBuilderAPI_MakeFace(s, Precision::Confusion()).Face());
  sew.Add(planar({line({0, 0, 10}, {20, 0, 10}), line({20, 0, 10}, {20, 30, 10}), line({20, 30, 10}, {0, 30, 10}),
                  line({0, 30, 10}, {0, 0, 10})}));  // the top plane
  sew.Add(planar({line({0, 0, 0}, {60, 0, 0}), line({60, 0, 0}, {60, 30, 0}), line({60, 30, 0}, {0, 30, 0}),
                  line({0, 30, 0}, {0, 0, 0})}));  // bottom
  sew.Add(planar({line({0, 0, 0}, {0, 30, 0}), line({0, 30, 0}, {0, 30, 10}), line({0, 30, 10}, {0, 0, 10}),
                  line({0, 0, 10}, {0, 0, 0})}));  // x = 0
  sew.Add(planar({line({60, 0, 0}, {60, 30, 0}), line({60, 30, 0}, {60, 30, zr}), BRepBuilderAPI_MakeEdge(s->UIso(1)).Edge(),
                  line({60, 0, zr}, {60, 0, 0})}));  // x = 60
  for (const double v : {0.0, 1.0}) {  // y = 0 and y = 30
    const double y = 30 * v;
    sew.Add(planar({line({0, y, 0}, {60, y, 0}), line({60, y, 0}, {60, y, zr}), BRepBuilderAPI_MakeEdge(s->VIso(v)).Edge(),
                    line({20, y, 10}, {0, y, 10}), line({0, y, 10}, {0, y, 0})}));
  }
  return sewn_solid(sew, "g1 block");
}

// G1 between a plane and a B-spline face (§6.5.2 for free-form faces): the two boundary rows of
// poles stay in the plane (n·P − d = 0 on 8 poles) instead of both faces being fixed. Moving the
// plane drags those rows through the projection; the written part keeps the tangency (the
// B-spline's normal along the edge equals the plane's, measured by OCCT), passes BRepCheck, and
// its volume changes as the boundary-integral derivative along the projected direction says
// (against central differences of OCCT's mass properties of the written parts).
TEST(BsplinePoles, PlaneTangentToABsplineFaceKeepsItsBoundaryRowsInThePlane) {
  const auto part = g1_block();
  const FaceModel model = build_face_model(*part);
  const int side = bspline_face(model);
  const int top = face_at_point(*part, {10, 15, 10}, 1e-7), bottom = face_at_point(*part, {30, 15, 0}, 1e-7);
  ASSERT_GE(top, 0);
  int g1 = 0;
  for (const TangencyRelation& r : model.relations) g1 += r.kind == "g1";
  EXPECT_EQ(g1, 1);
  const testing::DesignSpace space(*part, {bottom});
  ASSERT_TRUE(space.start.done);
  const auto& [m, sp, start, L] = space;
  EXPECT_EQ(sp.relation_equations, 8);  // rows i = 1, 2 of 4 poles each
  for (const std::string& note : sp.notes) EXPECT_EQ(note.find("tangent without equations"), std::string::npos) << note;
  EXPECT_LT(sp.constraints.values(start.p).cwiseAbs().maxCoeff(), 1e-12);
  const int offset = parameter_index(sp, top, "offset");
  const testing::DesignLine line(*part, model, sp, offset, start.p, L);
  const MomentDerivatives md = moment_derivatives(*part, sp, start.p);
  // The projected direction of the plane's offset: the rows follow it.
  optimize::ProjectionOptions popt;
  popt.weights = projection_weights(sp, {offset}, 1e-4, L);
  const optimize::ProjectionResult p0 = optimize::project(sp.constraints, start.p, start.p, sp.lower, sp.upper, {}, popt);
  ASSERT_TRUE(p0.done);
  const Eigen::VectorXd column =
      optimize::projection_derivative(sp.constraints, p0, sp.lower, sp.upper, popt.weights).jacobian.col(offset);
  // The rows follow d (0.999: the plane also tilts a little, its normal weighted by L²), and the
  // direction keeps every equation to first order.
  EXPECT_NEAR(column[parameter_index(sp, side, "pole 2 3 z")], 1.0, 2e-3);
  EXPECT_LT((sp.constraints.jacobian(p0.p) * column).cwiseAbs().maxCoeff(), 1e-10);
  EXPECT_NEAR(column[parameter_index(sp, side, "pole 3 3 z")], 0.0, 1e-6);  // the bump is not a follower
  auto volume_at = [&](double h) {
    const auto moved = line.at(h);
    EXPECT_TRUE(BRepCheck_Analyzer(moved->shape).IsValid());
    // G1 kept: the B-spline's normal along its boundary u = 0 is the plane's.
    const auto bs = top_surface(*moved, side);
    double worst = 0;
    for (int k = 0; k <= 10; ++k) {
      gp_Pnt P;
      gp_Vec Su, Sv;
      bs->D1(0, 0.1 * k, P, Su, Sv);
      worst = std::max(worst, 1.0 - std::abs(Su.Crossed(Sv).Normalized().Z()));
    }
    EXPECT_LT(worst, 1e-12) << "h = " << h;
    return occt_moments(*moved)[0];
  };
  const double fd = (4 * (volume_at(0.01) - volume_at(-0.01)) / 0.02 - (volume_at(0.02) - volume_at(-0.02)) / 0.04) / 3;
  const double exact = md.gradient.row(0).dot(column);
  std::printf("g1 block: %d tangency equations; dV/d(top plane offset) %.12g (boundary integrals along dp/dd), "
              "OCCT's differences %.12g, relative difference %.2e\n",
              sp.relation_equations, exact, fd, std::abs(exact - fd) / std::abs(fd));
  EXPECT_LE(std::abs(exact - fd), 5e-9 * std::abs(fd));  // measured 1.7e-9
}

}  // namespace
}  // namespace parafab::occ
