// Compliance objective of shape optimization (thesis §6.5.3): the semi-analytic gradient
// against central finite differences of the full pipeline (projection, B-rep write-back,
// re-cut on the fixed grid, XFEM solve), and an optimization run checked by a fresh simulation
// of the written STEP and OCCT's volume. The L-bracket is turned off the grid (cells are cut).
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <map>
#include <optional>
#include <tuple>

#include "common/error.h"
#include "face_lookup.h"
#include "occt_mass_properties.h"
#include "part_reader.h"
#include "piece_gaps.h"
#include "shape_compliance.h"
#include "shape_modify.h"
#include "shape_optimization.h"
#include "shape_parameters.h"
#include "turned_bracket.h"

namespace parafab::occ {
namespace {

using testing::compliance_on;
using testing::DesignLine;
using testing::EntryCase;
using testing::ProjectedEntry;
using testing::richardson;
using testing::turned;
using BracketCase = testing::TurnedBracket;


// A design entry of `space` projected as the optimizer moves it, the state at its start and the
// exact route there (one solve, boundary integrals); failure() says which step failed ("" when
// none did).
struct ExactAtEntry {
  ProjectedEntry entry;
  ComplianceState at;
  ComplianceGradient gradient;
  double along = 0;  ///< dC/dp̃ along the entry: gradient · column of dp⊥/dp̃
  ExactAtEntry(const PartShape& part, const testing::DesignSpace& space, int index, const ComplianceSetup& setup)
      : entry(part, space.model, space.parameters, space.start.p, index, space.size) {
    if (!entry.p0.done) return;
    at = compliance_start(entry.part_at(0), setup);
    if (!at.done) return;
    gradient = compliance_gradient(at, setup, space.parameters, entry.p0.p);
    if (gradient.done) along = gradient.gradient.dot(entry.column);
  }
  std::string failure() const {
    if (!entry.p0.done) return "projection: " + entry.p0.message;
    if (!at.done) return "start: " + at.message;
    return gradient.done ? "" : "gradient: " + gradient.message;
  }
};

TEST(ShapeCompliance, SemiAnalyticGradientMatchesFiniteDifferencesOfTheFullPipeline) {
  BracketCase c;
  const testing::DesignSpace space(*c.part, {c.setup.dirichlet[0].face, c.setup.tractions[0].face});
  ASSERT_TRUE(space.start.done);
  const auto& [model, sp, start, L] = space;
  // Tolerances: near the measured relative differences (4.7e-7 hole, 1.2e-6 and 1.0e-6 fillets,
  // 5.5e-6 and 2.3e-6 plane offsets, whose moves cross many cells).
  const std::vector<EntryCase> cases = {
      {"hole radius", parameter_index(sp, c.hole, "radius"), 1e-6},
      {"inner fillet radius (tangent planes follow)", parameter_index(sp, c.fillet, "radius"), 2.5e-6},
      {"outer fillet radius (tangent planes follow)", parameter_index(sp, c.outer, "radius"), 2e-6},
      {"upright inner plane offset (inner fillet follows)", parameter_index(sp, c.upright_inner, "offset"), 1e-5},
      {"base top plane offset (inner fillet follows)", parameter_index(sp, c.base_top, "offset"), 5e-6},
  };
  for (const EntryCase& k : cases) {
    const DesignLine line(*c.part, model, sp, k.index, start.p, L);
    auto part_at = [&](double s) { return line.at(s); };
    const ComplianceState at = compliance_start(part_at(0), c.setup);
    ASSERT_TRUE(at.done) << at.message;
    const double h = 1e-4 * L;
    const ComplianceDerivative d = compliance_derivative(at, part_at(h), part_at(-h), h, c.setup);
    ASSERT_TRUE(d.done) << d.message;
    EXPECT_LE(d.topology_switches, 1) << k.what;  // measured 0 or 1 (a sliver appears on one side)
    EXPECT_GT(d.cells_changed, 0) << k.what;
    // Independent: central differences of the whole pipeline (every side re-cut from the start
    // model on the same grid and solved), at a larger step.
    // Richardson extrapolation of the steps H and H/2 removes their O(H²) error. Small H: at
    // H = 1e-3·L the plane offsets' differences crossed kinks of the cut rules (measured on the
    // upright plane: FD −4.0411 at 1e-3·L, −4.05131 at 5e-4·L, −4.051565 at 1e-4·L; the
    // semi-analytic value −4.05157 for h = 3e-5 … 1e-4·L).
    double fds[1];
    const double fd = richardson([&](double H) { return compliance_on(part_at(H), at, c.setup); }, 2e-4 * L, fds);
    std::printf("%s: C = %.10g, semi-analytic %.10g, FD %.10g (H: %.10g), relative difference %.2e, %d cells, %d switches\n",
                k.what, at.compliance, d.derivative, fd, fds[0], std::abs(d.derivative - fd) / std::abs(fd), d.cells_changed,
                d.topology_switches);
    EXPECT_LE(std::abs(d.derivative - fd), k.tolerance * std::abs(fd)) << k.what;
  }
}

// The exact route (rule derivatives, Eq. 6.30–6.31: boundary integrals over the moving patches
// and along the edges of the support and load, one solve, no perturbed model) against
// Richardson-extrapolated central differences of the whole pipeline, chained through the
// projection like the optimizer (dC/dp̃_k = Σ_i dC/dp_i · dp⊥_i/dp̃_k). Two loadings of the turned
// bracket: (a) the total-force case above, where the fillet and both planes drag the base top
// plane, whose edge with the load face then moves (the load face's area and traction change);
// (b) dead weight only (the gravity term). The outer fillet runs tangent into the support: its
// edge moves with the cylinder's axis (the null-space completion; before it, the fillet was
// flagged, and left without the edge term its value was 4.6 % / 12.8 % off).
// compliance_gradient with `moving` (the optimizer passes the rows of dp⊥/dp̃ its design moves):
// the wanted entries are those of the full gradient to the last bit, with fewer quadrature
// points; the other entries lack their faces' own boundary integrals (they differ from the full
// gradient, and no design direction uses them).
TEST(ShapeCompliance, GradientOfTheMovingEntriesOnlyIsTheFullGradientsOwn) {
  BracketCase c;
  const testing::DesignSpace space(*c.part, {c.setup.dirichlet[0].face, c.setup.tractions[0].face});
  ASSERT_TRUE(space.start.done);
  const ShapeParameters& sp = space.parameters;
  const ComplianceState at = compliance_start(c.part, c.setup);
  ASSERT_TRUE(at.done) << at.message;
  const ComplianceGradient all = compliance_gradient(at, c.setup, sp, space.start.p);
  ASSERT_TRUE(all.done) << all.message;
  std::vector<char> moving(sp.size(), 0);
  const optimize::ParameterBlock& hole = *sp.block(c.hole);
  for (int k = 0; k < hole.size(); ++k) moving[hole.offset + k] = 1;
  const ComplianceGradient some = compliance_gradient(at, c.setup, sp, space.start.p, &moving);
  ASSERT_TRUE(some.done) << some.message;
  double skipped = 0;
  for (int i = 0; i < sp.size(); ++i) {
    if (moving[i]) EXPECT_EQ(some.gradient[i], all.gradient[i]) << sp.names[i];
    else skipped = std::max(skipped, std::abs(some.gradient[i] - all.gradient[i]));
  }
  EXPECT_NE(all.gradient[parameter_index(sp, c.hole, "radius")], 0.0);
  EXPECT_GT(skipped, 0.0);
  EXPECT_LT(some.points, all.points);
  std::printf("moving entries only: %d of %d quadrature points; the other entries differ by up to %.3g\n", some.points,
              all.points, skipped);
}

TEST(ShapeCompliance, ExactGradientMatchesFiniteDifferencesOfTheFullPipeline) {
  for (const bool dead_weight : {false, true}) {
    BracketCase c;
    if (dead_weight) {
      c.setup.tractions.clear();
      c.setup.forces.clear();
      c.setup.material.density = 7.85e-9;                                     // t/mm³
      c.setup.solver.gravity = 1000 * (turned(Vec3(0, 0, -9810)) - turned(Vec3::Zero()));  // mm/s², ×1000
    }
    std::vector<int> fixed = {c.setup.dirichlet[0].face};
    if (!dead_weight) fixed.push_back(c.setup.tractions[0].face);
    const testing::DesignSpace space(*c.part, fixed);
    ASSERT_TRUE(space.start.done);
    const auto& [model, sp, start, L] = space;
    struct Case {
      const char* what;
      int index;
      bool exact;  // expected route: not flagged incomplete
      double tolerance;
    };
    // Tolerances near the measured relative differences (traction / dead weight): hole 3.8e-8 /
    // 2.9e-9, inner fillet 1.4e-9 / 1.4e-8, upright plane 6.4e-8 / 2.0e-7, base top plane 1.4e-6 /
    // 1.5e-5 (its move crosses many cells; the semi-analytic route above measures 5.5e-6 there),
    // outer fillet 3.3e-9 / 1.2e-8.
    // Without the edge terms the three traction cases that move the load face's edge were off
    // by 2.6e-5 to 7.0e-5.
    const std::vector<Case> cases = {
        {"hole radius", parameter_index(sp, c.hole, "radius"), true, dead_weight ? 1e-8 : 1e-7},
        {"inner fillet radius", parameter_index(sp, c.fillet, "radius"), true, 5e-8},
        {"upright inner plane offset", parameter_index(sp, c.upright_inner, "offset"), true, 5e-7},
        {"base top plane offset", parameter_index(sp, c.base_top, "offset"), true, dead_weight ? 3e-5 : 3e-6},
        {"outer fillet radius (tangent to the support)", parameter_index(sp, c.outer, "radius"), true,
         dead_weight ? 3e-8 : 1e-8},
    };
    for (const Case& k : cases) {
      const ExactAtEntry e(*c.part, space, k.index, c.setup);
      ASSERT_EQ(e.failure(), "") << k.what;
      auto part_at = [&](double s) { return e.entry.part_at(s); };
      const ComplianceState& at = e.at;
      const ComplianceGradient& g = e.gradient;
      const double exact = e.along;
      const bool flagged = !exact_along(g, e.entry.column);
      EXPECT_EQ(!flagged, k.exact) << k.what;
      const double fd = richardson([&](double H) { return compliance_on(part_at(H), at, c.setup); }, 2e-4 * L);
      std::printf("%s, %s: C = %.10g, exact %.10g%s, FD %.10g, relative difference %.2e, %d elements, %d points, %.3f s\n",
                  dead_weight ? "dead weight" : "traction", k.what, at.compliance, exact, flagged ? " (incomplete)" : "", fd,
                  std::abs(exact - fd) / std::abs(fd), g.elements, g.points, g.seconds);
      if (!flagged) EXPECT_LE(std::abs(exact - fd), k.tolerance * std::abs(fd)) << k.what;
    }
  }
}

// The local Nitsche penalty (xfem::LinearXfemOptions::NitschePenalty::Local): a clamped cut
// cell's penalty κΛ is an eigenvalue of that cell's own geometry; compliance_gradient adds its
// change dΛ = vᵀdBv − Λ vᵀdÂv (xfem::LocalPenaltyParts) and the strips along the clamped patch's
// moving edges with that penalty. Against Richardson-extrapolated central differences of the
// whole pipeline with the same penalty, for a face far from the clamp and for the outer fillet
// that runs tangent into it (its cells hold the clamp's patch; until 2026-11-28 it was flagged
// and differenced, and the exact route without the penalty's change was 12 % off); the
// semi-analytic route (whole element systems, penalty included) is printed beside it.
TEST(ShapeCompliance, LocalPenaltyGradientIsExactAlsoInTheClampedCells) {
  for (const xfem::ElementType element : {xfem::ElementType::Hex8, xfem::ElementType::Hex27}) {
    const bool hex27 = element == xfem::ElementType::Hex27;
    BracketCase c;
    c.setup.solver.nitsche_penalty = xfem::LinearXfemOptions::NitschePenalty::Local;
    c.setup.solver.element = element;
    c.setup.grid = rules_for_element(element, c.setup.grid);
    const testing::DesignSpace space(*c.part, {c.setup.dirichlet[0].face, c.setup.tractions[0].face});
    ASSERT_TRUE(space.start.done);
    const auto& [model, sp, start, L] = space;
    // Measured relative differences of the exact route to the reference, hex8 / hex27: hole
    // 4.0e-8 / 2.8e-7, upright plane 7.8e-8 / 4.0e-8, outer fillet 3.7e-10 / 3.5e-8 (the
    // semi-analytic route: 4.8e-7 / 4.5e-6, 5.6e-6 / 1.3e-5, 9.4e-7 / 5.3e-6). The hex8 outer
    // fillet is at the round-off of dp⊥/dp̃: with the projection's weights ZᵀHZ has a condition
    // number near 1e8, and the dense double solve differed from a long-double one by 4.5e-9 ...
    // 8.6e-9 of |D| (measured 2026-12-01). Since dp⊥/dp̃ is solved per coupled group (same
    // formula, other round-off) it measures 6.7e-9 (2.4e-10 before); the reference itself
    // spreads by 2.2e-9 between base steps 1e-4 L and 2e-4 L. So 1e-8, not 1.5e-9.
    const std::vector<EntryCase> cases = {
        {"hole radius", parameter_index(sp, c.hole, "radius"), hex27 ? 6e-7 : 1e-7},
        {"upright inner plane offset (8 mm from the support, no cut cell shared)",
         parameter_index(sp, c.upright_inner, "offset"), hex27 ? 1e-7 : 3e-7},
        {"outer fillet radius (tangent to the support)", parameter_index(sp, c.outer, "radius"), hex27 ? 1e-7 : 1e-8},
    };
    for (const EntryCase& k : cases) {
      const ProjectedEntry entry(*c.part, model, sp, start.p, k.index, L);
      ASSERT_TRUE(entry.p0.done);
      auto part_at = [&](double s) { return entry.line->at(s); };
      const ComplianceState at = compliance_start(part_at(0), c.setup);
      ASSERT_TRUE(at.done) << at.message;
      // Where the local penalty is not coercive: its floor (â = aₑ + 0.005 × the uncut cell's
      // energy) bounds a sliver's penalty, so that cell's terms are only ≥ aₑ − âₑ/κ. On this
      // hex8 grid the matrix is then indefinite (measured: floor 1e-4 or 0 gives a positive
      // definite one); the solve says so, naming the floor, and LU solves it; the derivatives
      // below still agree.
      if (!hex27)
        EXPECT_NE(at.solution.message.find("local Nitsche penalty's floor"), std::string::npos) << at.solution.message;
      const ComplianceGradient g = compliance_gradient(at, c.setup, sp, entry.p0.p);
      ASSERT_TRUE(g.done) << g.message;
      const Eigen::VectorXd& column = entry.column;
      EXPECT_TRUE(exact_along(g, column)) << k.what;
      const double exact = g.gradient.dot(column);
      const double h = 1e-4 * L;
      const ComplianceDerivative d = compliance_derivative(at, part_at(h), part_at(-h), h, c.setup);
      ASSERT_TRUE(d.done) << d.message;
      const double fd = richardson([&](double H) { return compliance_on(part_at(H), at, c.setup); }, 2e-4 * L);
      std::printf("local penalty, %s, %s: C = %.10g, exact route %.10g, semi-analytic %.10g, FD %.10g; relative "
                  "differences to FD %.2e (exact route), %.2e (semi-analytic); %s\n",
                  xfem::element_type_name(element), k.what, at.compliance, exact, d.derivative, fd,
                  std::abs(exact - fd) / std::abs(fd), std::abs(d.derivative - fd) / std::abs(fd),
                  at.solution.message.c_str());
      EXPECT_LE(std::abs(exact - fd), k.tolerance * std::abs(fd)) << xfem::element_type_name(element) << ", " << k.what;
    }
  }
}

// A torus fillet running tangent into a support: the housing sample (turned 9° off the grid)
// hangs by its boss, whose cylinder is clamped, under its own weight. The boss's base fillet
// (torus, minor radius 2, major 8) is tangent to the cylinder along a circle, which moves with
// the torus's centre circle when the fillet radius changes (both tangencies kept: R = r + 6,
// centre 30 + r above the base). Until 2026-11-28 only a cylinder had this edge term and the
// torus was flagged (semi-analytic route). Against Richardson-extrapolated central differences of
// the whole pipeline; the fin plane far from the clamp is the control.
TEST(ShapeCompliance, TorusFilletTangentIntoTheSupportHasAnExactGradient) {
  const Vec3 centre(30, 20, 20), axis = Vec3(2, -1, 3).normalized();
  const double degrees = 9;
  auto turn = [&](const Vec3& X) -> Vec3 { return centre + Eigen::AngleAxisd(degrees * M_PI / 180, axis) * (X - centre); };
  const auto part = rotated_part(*read_part(testing::sample_part("housing")), centre, axis, degrees);
  const double tol = 1e-6;
  const int boss = face_at_point(*part, turn({48 + 6, 20, 36}), tol);
  const int fillet = face_at_point(*part, turn({48 + 8 - 2 * std::sqrt(0.5), 20, 32 - 2 * std::sqrt(0.5)}), tol);
  const int fin = face_at_point(*part, turn({8, 20, 34}), tol);  // the first fin's x = 8 side
  ASSERT_GE(boss, 0);
  ASSERT_GE(fillet, 0);
  ASSERT_GE(fin, 0);
  ComplianceSetup setup;
  setup.material.youngs_modulus = 210000;
  setup.material.poisson_ratio = 0.3;
  setup.material.density = 7.85e-9;
  xfem::DirichletCondition d;
  d.face = boss;
  setup.dirichlet.push_back(d);
  setup.solver.gravity = 1000 * (turn(Vec3(0, 0, -9810)) - turn(Vec3::Zero()));  // mm/s², ×1000
  setup.grid.grid.cells_longest = 10;
  setup.grid.grid.block_cells = 4;
  setup.grid.grid.method = CutMethod::FaceCut;
  // The clamp is curved: its Nitsche integrand (σ(u)n with n turning around the boss) is not a
  // polynomial, and the pipeline differentiates its patch rules, which the edge term (an exact
  // line integral) does only up to their error. Measured on the fillet: degree 5 (the default
  // on supports until 2026-12-02) 5.3e-4, 8 (dirichlet_surface_degree's default since) 1.5e-6,
  // 11 1.0e-8 (C itself moves by 9e-5 from 5 to 8). Planar clamps (the bracket above) have
  // polynomial integrands and need no more than degree 5.
  setup.solver.surface_degree = 11;
  const testing::DesignSpace space(*part, {boss});
  ASSERT_TRUE(space.start.done);
  const auto& [model, sp, start, L] = space;
  const std::vector<EntryCase> cases = {
      // Measured 1.0e-8 and 5.7e-9 (the edge term is 31 % of the fillet's derivative; without it,
      // or with the cylinder's axis formula, the torus was flagged before 2026-11-28).
      {"boss fillet radius (torus tangent to the clamped boss)", parameter_index(sp, fillet, "minor radius"), 3e-8},
      {"fin side plane offset", parameter_index(sp, fin, "offset"), 2e-8},
  };
  for (const EntryCase& k : cases) {
    const ExactAtEntry e(*part, space, k.index, setup);
    ASSERT_EQ(e.failure(), "") << k.what;
    auto part_at = [&](double s) { return e.entry.part_at(s); };
    const ComplianceState& at = e.at;
    const ComplianceGradient& g = e.gradient;
    EXPECT_TRUE(exact_along(g, e.entry.column)) << k.what;
    const double exact = e.along;
    const double fd = richardson([&](double H) { return compliance_on(part_at(H), at, setup); }, 2e-4 * L);
    std::printf("housing hanging by its boss, %s: C = %.10g, exact %.10g, FD %.10g, relative difference %.2e, %d edge points\n",
                k.what, at.compliance, exact, fd, std::abs(exact - fd) / std::abs(fd), g.edge_points);
    EXPECT_LE(std::abs(exact - fd), k.tolerance * std::abs(fd)) << k.what;
  }
  // The fillet with coarser patch rules on the clamp: the exact line integral and the
  // pipeline's differentiated rules part by the rules' error (measured 1.5e-6 at degree 8, the
  // default on curved supports, 5.3e-4 at 5), and C itself moves by 9.2e-5 from degree 8 to 5.
  const ProjectedEntry entry(*part, model, sp, start.p, cases[0].index, L);
  ASSERT_TRUE(entry.p0.done);
  double c8 = 0;
  for (const auto& [degree, low, high] : {std::tuple{8, 7e-7, 3e-6}, std::tuple{5, 3e-4, 8e-4}}) {
    ComplianceSetup coarser = setup;
    coarser.solver.surface_degree = degree;
    coarser.solver.dirichlet_surface_degree = degree;
    const ComplianceState at = compliance_start(entry.line->at(0), coarser);
    ASSERT_TRUE(at.done) << at.message;
    const ComplianceGradient g = compliance_gradient(at, coarser, sp, entry.p0.p);
    ASSERT_TRUE(g.done) << g.message;
    const double exact = g.gradient.dot(entry.column);
    const double fd = richardson([&](double H) { return compliance_on(entry.line->at(H), at, coarser); }, 2e-4 * L);
    const double gap = std::abs(exact - fd) / std::abs(fd);
    std::printf("boss fillet with patch rules of degree %d: C = %.10g, relative difference %.2e\n", degree, at.compliance, gap);
    EXPECT_GT(gap, low) << degree;
    EXPECT_LT(gap, high) << degree;
    if (degree == 8) c8 = at.compliance;
    else EXPECT_NEAR(std::abs(at.compliance - c8) / c8, 9.2e-5, 2e-5);
  }
}

// One design entry of the turned bracket (support and load faces fixed) moved as the optimizer
// moves it, the start simulated, and the compliance at s along it on the start's grid (its
// discrete switches frozen at `frozen` when given).
struct BracketLine {
  BracketCase c;
  testing::DesignSpace space{*c.part, {c.setup.dirichlet[0].face, c.setup.tractions[0].face}};
  DesignLine line;
  ComplianceState base;
  BracketLine(int BracketCase::*face, const char* parameter)
      : line(*c.part, space.model, space.parameters, parameter_index(space.parameters, c.*face, parameter),
             space.start.p, space.size),
        base(compliance_start(line.at(0), c.setup)) {}
  ComplianceState state_at(double s, const ComplianceState* frozen = nullptr) const {
    ComplianceState st = compliance_at(line.at(s), base, c.setup, frozen ? frozen->model.get() : nullptr);
    EXPECT_TRUE(st.done) << "s = " << s << ": " << st.message;
    return st;
  }
};

// Discrete switches frozen along a line search (ShapeOptimizationOptions::freeze_switches):
// the turned bracket's inner fillet radius grows until a cut cell crosses the aggregation threshold
// (volume fraction 0.05) and a DOF node starts or stops following its neighbour, with no cell
// gaining or losing a subvolume; the switch is bracketed by bisection to 1e-8 mm. With each model's own switches the compliance jumps there; with the
// switches of the bracket's left end (as a line search from there sees them) it moves only by
// the slope times the interval. A state frozen at itself is the natural one.
TEST(ShapeCompliance, FrozenSwitchesRemoveTheAggregationJumpAlongALine) {
  // The inner fillet's radius (its tangent planes follow). Found by scanning the design entries:
  // the hole radius shows no such switch up to +1.5 mm; the base top offset has one at +0.068 mm
  // (jump 2.2e-6 relative), the upright's inner offset at +0.195 mm (3.6e-7).
  const BracketLine line(&BracketCase::fillet, "radius");
  const BracketCase& c = line.c;
  ASSERT_TRUE(line.space.start.done);
  ASSERT_TRUE(line.base.done) << line.base.message;
  const double step = 0.05;
  // Signature of a state: elements per cut cell, which elements are small, and the number of
  // DOF nodes aggregated (a small element whose nodes all lose their normal elements).
  using Signature = std::map<std::array<int, 3>, std::vector<char>>;
  auto signature = [&](const ComplianceState& st) {
    Signature sig;
    for (const xfem::GridElement& el : st.model->elements)
      if (el.subvolume) sig[el.cell].push_back(xfem::volume_fraction(el) < c.setup.solver.aggregation_fraction);
    sig[{-1, -1, -1}] = std::vector<char>(st.solution.aggregated_nodes, 1);
    return sig;
  };
  auto same_counts = [](const Signature& a, const Signature& b) {
    if (a.size() != b.size()) return false;
    for (auto i = a.begin(), j = b.begin(); i != a.end(); ++i, ++j)
      if (i->first != j->first || (i->first[0] >= 0 && i->second.size() != j->second.size())) return false;
    return true;
  };
  auto state_at = [&](double s, const ComplianceState* frozen = nullptr) { return line.state_at(s, frozen); };
  // Scan the radius (entry s = Δr) for a pure switch.
  double a = -1, b = -1;
  ComplianceState left = state_at(0);
  for (double s = step; s <= 0.5 && b < 0; s += step) {
    ComplianceState right = state_at(s);
    if (same_counts(signature(left), signature(right)) && left.solution.aggregated_nodes != right.solution.aggregated_nodes)
      a = s - step, b = s;
    left = std::move(right);
  }
  ASSERT_GE(b, 0) << "no aggregation switch without a topology change for Δr in (0, 0.5]";
  const Signature switch_left = signature(state_at(a));
  while (b - a > 1e-8) {
    const double m = 0.5 * (a + b);
    (signature(state_at(m)) == switch_left ? a : b) = m;
  }
  const ComplianceState sa = state_at(a), sb = state_at(b);
  ASSERT_TRUE(same_counts(signature(sa), signature(sb)));
  const ComplianceState fb = state_at(b, &sa), fa = state_at(a, &sa);
  EXPECT_GT(fb.frozen_elements, 0);
  EXPECT_FALSE(fb.switches_own);
  EXPECT_TRUE(fa.switches_own);
  EXPECT_EQ(fa.compliance, sa.compliance);
  // The slope from a step well away from the switch.
  const double slope = (state_at(a - 0.01).compliance - state_at(a - 0.02).compliance) / 0.01;
  const double jump = std::abs(sb.compliance - sa.compliance), frozen_step = std::abs(fb.compliance - sa.compliance);
  std::printf("switch at fillet radius + %.7f mm: C %.12g; own switches jump by %.3e (relative %.2e), frozen ones by %.3e "
              "(slope x interval %.3e); %d elements frozen\n",
              a, sa.compliance, jump, jump / sa.compliance, frozen_step, std::abs(slope) * (b - a), fb.frozen_elements);
  // Measured: jump 3.9e-4 (9.4e-6 relative) against slope x interval 4.0e-8; frozen 1.003 times that.
  EXPECT_GT(jump, 1000 * std::abs(slope) * (b - a));
  EXPECT_LT(frozen_step, 1.5 * std::abs(slope) * (b - a));
  // The optimizer's switch refresh (compliance_own_switches) of the frozen state at b is the
  // own-switch state there, to the last bit, on the frozen state's cut (not cut again).
  const ComplianceState rb = compliance_own_switches(fb, c.setup);
  ASSERT_TRUE(rb.done) << rb.message;
  EXPECT_EQ(rb.compliance, sb.compliance);
  EXPECT_EQ(rb.solution.aggregated_nodes, sb.solution.aggregated_nodes);
  EXPECT_NE(rb.compliance, fb.compliance);
  EXPECT_EQ(rb.model->cut.get(), fb.model->cut.get());
}

// Known failure in the default basis (hex8 with incompatible modes, merge off): where a cut
// cell's material pieces join or one vanishes, the DOF structure changes and C jumps. The thesis
// smooths this with a penalty b(d)‖x¹ − x²‖² on the enriched copies of a node (Eq. 6.24; ParaFab's
// `merge` ties, off by default: MergePenalty* tests below), and freezing
// the discrete switches along a line search (above) does not cover it: what the user gets is a
// jump of the objective at that point. Found by scanning the turned bracket's design entries (bench_piece_changes): on the upright's
// inner offset two cells change pieces at +0.6016 mm: in one, two small pieces (volume
// fractions 1.0e-3 and 1.6e-2, both aggregated) join into one (1.7e-2); the other, cut with a
// piece of fraction 1.000, becomes an uncut cell. (The hole radius has a smaller one at
// +0.1312 mm: a piece splits off, 5.2e-6 relative.)
TEST(ShapeCompliance, ASubvolumeMergeStillMakesTheObjectiveJumpAlongALine) {
  const BracketLine line(&BracketCase::upright_inner, "offset");
  ASSERT_TRUE(line.space.start.done);
  ASSERT_TRUE(line.base.done) << line.base.message;
  auto pieces = [](const ComplianceState& st) {  // material pieces (elements) per cut cell
    std::map<std::array<int, 3>, int> m;
    if (!st.done) return m;  // (a model the cut refuses: state_at's EXPECT fails the test)
    for (const xfem::GridElement& el : st.model->elements)
      if (el.subvolume) ++m[el.cell];
    return m;
  };
  auto state_at = [&](double s, const ComplianceState* frozen = nullptr) { return line.state_at(s, frozen); };
  double a = 0.58, b = 0.62;
  const auto left = pieces(state_at(a));
  ASSERT_NE(left, pieces(state_at(b)));
  while (b - a > 1e-8) {
    const double m = 0.5 * (a + b);
    (pieces(state_at(m)) == left ? a : b) = m;
  }
  const ComplianceState sa = state_at(a), sb = state_at(b), frozen = state_at(b, &sa);
  int changed = 0;
  const auto pa = pieces(sa), pb = pieces(sb);
  for (const auto& [cell, n] : pa) changed += !pb.count(cell) || pb.at(cell) != n;
  for (const auto& [cell, n] : pb) changed += !pa.count(cell);
  const double slope = (state_at(a - 0.004).compliance - state_at(a - 0.008).compliance) / 0.004;
  const double jump = sb.compliance - sa.compliance;
  std::printf("pieces change at upright inner offset + %.7f mm in %d cells: C %.10g, jump %.3e (relative %.2e), "
              "with the switches frozen %.3e; slope x interval %.2e\n",
              a, changed, sa.compliance, jump, jump / sa.compliance, frozen.compliance - sa.compliance,
              std::abs(slope) * (b - a));
  // Measured: +0.6015615 mm, 2 cells, jump +1.344e-2 (3.6e-4 relative) against slope x interval
  // 5.2e-8; frozen switches give the same jump (they apply to cells whose pieces match).
  EXPECT_NEAR(a, 0.6015615, 1e-6);
  EXPECT_EQ(changed, 2);
  EXPECT_NEAR(jump / sa.compliance, 3.6e-4, 0.2e-4);
  EXPECT_GT(std::abs(jump), 1e5 * std::abs(slope) * (b - a));
  EXPECT_NEAR(frozen.compliance - sa.compliance, jump, 1e-9 * sa.compliance);
  // Without small-cell aggregation (fraction 0) the same point still jumps, by 5.5e-5 relative
  // (measured 2.072e-3): the DOF merge itself, Fig. 6.10's case, not only the aggregation's
  // switches; a smoother aggregation alone would not make C continuous here. (Tried by hand on
  // 11-29: tying small pieces' nodes to their host by a penalty log²(φ/0.05) instead of the map
  // T reproduced the aggregated C to 1e-5 and the same 1.344e-2 jump.)
  BracketLine plain(&BracketCase::upright_inner, "offset");
  plain.c.setup.solver.aggregation_fraction = 0;
  plain.base = compliance_start(plain.line.at(0), plain.c.setup);
  ASSERT_TRUE(plain.base.done) << plain.base.message;
  const ComplianceState qa = plain.state_at(a), qb = plain.state_at(b);
  ASSERT_EQ(pieces(qa), left);
  ASSERT_EQ(pieces(qb), pieces(sb));
  const double plain_jump = (qb.compliance - qa.compliance) / qa.compliance;
  std::printf("without aggregation: C %.10g, jump %.3e relative\n", qa.compliance, plain_jump);
  EXPECT_NEAR(plain_jump, 5.55e-5, 0.3e-5);
}

// The d of Eq. 6.24 at the join above (piece_gaps): OCCT's Euclidean gap between the two
// pieces of the cell that join at +0.6015615 mm goes to zero exactly there, as k·√(a − s) (the
// pieces close around a curved face, the upright's inner fillet), and its derivative along the
// optimizer's line (from the faces' normal velocities at the closest points) matches
// differences of the gap over written parts.
TEST(PieceGaps, GapOfTheJoiningPiecesGoesToZeroWhereTheCutJoinsThem) {
  const BracketLine line(&BracketCase::upright_inner, "offset");
  ASSERT_TRUE(line.base.done) << line.base.message;
  auto pieces_of = [](const GridModel& m) {
    std::map<std::array<int, 3>, int> n;
    for (const xfem::GridElement& el : m.elements)
      if (el.subvolume) ++n[el.cell];
    return n;
  };
  // The join (at +0.6015615 mm: ShapeCompliance.ASubvolumeMergeStillMakesTheObjectiveJumpAlongALine)
  // bracketed to 1e-8 mm (closer, the cut fails: a model within 1e-10 mm of it is refused, "a hole of
  // face 7 lies in no outer loop").
  double a = 0.6015, b = 0.6016;
  const auto left = pieces_of(*line.state_at(a).model);
  ASSERT_NE(left, pieces_of(*line.state_at(b).model));
  while (b - a > 1e-8) {
    const double m = 0.5 * (a + b);
    (pieces_of(*line.state_at(m).model) == left ? a : b) = m;
  }
  std::array<int, 3> joining{-1, -1, -1};
  {
    const auto after = pieces_of(*line.state_at(b).model);
    for (const auto& [cell, n] : left)
      if (n == 2 && after.count(cell) && after.at(cell) == 1) joining = cell;
  }
  ASSERT_NE(joining[0], -1);
  struct At {
    PieceGap gap;
    std::shared_ptr<const PartShape> part;
  };
  auto gap_at = [&](double s) {
    const ComplianceState st = line.state_at(s);
    const PieceGapResult gr = piece_gaps(*st.part, *st.model);
    EXPECT_TRUE(gr.done) << gr.message;
    for (const PieceGap& q : gr.gaps)
      if (q.cell == joining) return At{q, st.part};
    ADD_FAILURE() << "s = " << s << ": no pair of pieces in the joining cell";
    return At{};
  };
  std::vector<double> d;
  for (double ds : {1e-4, 1e-5, 1e-6}) {
    const At at = gap_at(a - ds);
    d.push_back(at.gap.distance);
    std::printf("s = a - %g: gap %.10g (/sqrt %.6g), ends on faces %d %d\n", ds, at.gap.distance,
                at.gap.distance / std::sqrt(ds), at.gap.a.faces.size() == 1 ? at.gap.a.faces[0] : -1, at.gap.b.faces.size() == 1 ? at.gap.b.faces[0] : -1);
    EXPECT_FALSE(at.gap.joined);
    EXPECT_EQ(at.gap.a.faces, std::vector<int>{line.c.fillet});
    EXPECT_EQ(at.gap.b.faces, std::vector<int>{line.c.fillet});
  }
  // Measured 0.06111, 0.01933, 0.006139: each decade of a − s a factor √10 (3.162) within 0.3 %.
  EXPECT_NEAR(d[0] / d[1], std::sqrt(10.0), 0.01);
  EXPECT_NEAR(d[1] / d[2], std::sqrt(10.0), 0.01);
  // The derivative along the line, away from the join: the exact d' against differences.
  auto parameters_of = [](const PartShape& part) { return build_shape_parameters(build_face_model(part)); };
  const double s0 = a - 0.01, h = 1e-4;
  const At at = gap_at(s0);
  const ShapeParameters sp = parameters_of(*at.part);
  std::vector<char> complete;
  const Eigen::MatrixXd g = piece_gap_gradient({at.gap}, sp, sp.initial, &complete);
  ASSERT_TRUE(complete[0]);
  const Eigen::VectorXd dp = (parameters_of(*line.line.at(s0 + h)).initial - parameters_of(*line.line.at(s0 - h)).initial) / (2 * h);
  const double exact = g.row(0).dot(dp);
  const double fd = (gap_at(s0 + h).gap.distance - gap_at(s0 - h).gap.distance) / (2 * h);
  std::printf("at a - 0.01: gap %.10g, d' exact %.10g, differences %.10g, relative difference %.2e\n", at.gap.distance, exact,
              fd, std::abs(exact - fd) / std::abs(fd));
  EXPECT_NEAR(exact, fd, 5e-5 * std::abs(fd));  // measured 1.25e-5 (central differences, step 1e-4 mm)
}

// The bracket's join above on a line whose setup has `merge` on (crit 5 % of the cell), in the
// basis given: the switch bracketed to 1e-8 mm from the pieces per cell.
struct MergeLine : BracketLine {
  double a = 0.6015, b = 0.6016;
  MergeLine(bool merge, double aggregation, bool modes, xfem::ElementType element = xfem::ElementType::Hex8)
      : BracketLine(&BracketCase::upright_inner, "offset") {
    c.setup.merge.enabled = merge;
    c.setup.solver.aggregation_fraction = aggregation;
    c.setup.solver.incompatible_modes = modes;
    c.setup.solver.element = element;
    c.setup.grid = rules_for_element(element, c.setup.grid);
    base = compliance_start(line.at(0), c.setup);
    EXPECT_TRUE(base.done) << base.message;
    auto pieces = [&](double s) {
      std::map<std::array<int, 3>, int> n;
      for (const xfem::GridElement& el : state_at(s).model->elements)
        if (el.subvolume) ++n[el.cell];
      return n;
    };
    const auto left = pieces(a);
    while (b - a > 1e-8) {
      const double m = 0.5 * (a + b);
      (pieces(m) == left ? a : b) = m;
    }
  }
};

// The exact gradient of C on `tied`'s line at a − 0.001 mm, inside the ties' range (gap
// 0.19 mm < d_crit 0.32 mm, where the tie's weight changes: b' ≠ 0), the entry moved as the
// optimizer moves it, against Richardson differences of the whole pipeline at `steps`; the tie
// term (the part of the gradient the ties add) is printed and returned.
struct TieGradientCheck {
  double exact = 0, tie_term = 0;
  std::vector<double> fd;  ///< per step
  /// The semi-analytic route (compliance_derivative, step 1e-4), and the same element
  /// differences without the mode-tied pair's term.
  double semi = 0, semi_without_pair = 0;
  int mode_tied_pairs = 0;
};
TieGradientCheck tie_gradient_check(const MergeLine& tied, const char* basis, const std::vector<double>& steps) {
  TieGradientCheck r;
  const auto part = tied.line.at(tied.a - 0.001);
  const testing::DesignSpace space(*part, {tied.c.setup.dirichlet[0].face, tied.c.setup.tractions[0].face});
  EXPECT_TRUE(space.start.done);
  const ProjectedEntry entry(*part, space.model, space.parameters, space.start.p,
                             parameter_index(space.parameters, tied.c.upright_inner, "offset"), space.size);
  EXPECT_TRUE(entry.p0.done);
  const ComplianceState at = compliance_at(entry.part_at(0), tied.base, tied.c.setup);
  EXPECT_TRUE(at.done) << at.message;
  EXPECT_EQ(at.ties.size(), 1u);
  r.mode_tied_pairs = at.solution.mode_tied_pairs;
  {
    const double H = 1e-4;
    const ComplianceSetup& setup = tied.c.setup;
    r.semi = compliance_derivative(at, entry.part_at(H), entry.part_at(-H), H, setup).derivative;
    r.semi_without_pair =
        element_difference(at, entry.part_at(H), entry.part_at(-H), H, setup,
                           [&](const xfem::GridElement& el, const std::vector<xfem::TractionCondition>& tractions, int base) {
                             const xfem::ElementSystem es =
                                 xfem::element_system(el, setup.material, setup.dirichlet, tractions, setup.solver);
                             const Eigen::VectorXd ue = element_values(at.solution.u, at.solution.node[base]);
                             return 2 * ue.dot(es.f) - ue.dot(es.K * ue);
                           })
            .derivative;
  }
  const ComplianceGradient g = compliance_gradient(at, tied.c.setup, space.parameters, entry.p0.p);
  EXPECT_TRUE(g.done) << g.message;
  EXPECT_TRUE(exact_along(g, entry.column));
  EXPECT_EQ(g.ties_without_derivative, 0);
  r.exact = g.gradient.dot(entry.column);
  ComplianceState bare = at;  // the same solution without the tie term in the gradient
  bare.ties.clear(), bare.gaps.clear();
  r.tie_term = r.exact - compliance_gradient(bare, tied.c.setup, space.parameters, entry.p0.p).gradient.dot(entry.column);
  for (double H : steps) {
    r.fd.push_back(richardson([&](double s) { return compliance_on(entry.part_at(s), at, tied.c.setup); }, H));
    std::printf("%s: Richardson step %g: FD %.10g, relative difference %.2e\n", basis, H, r.fd.back(),
                std::abs(r.exact - r.fd.back()) / std::abs(r.fd.back()));
  }
  std::printf("%s: gap %.6g mm (d_crit %.6g): C %.10g, exact %.10g (tie term %.4g); semi-analytic %.10g (%.10g "
              "without the mode-tied pair's term)\n", basis, at.gaps[0].distance,
              0.05 * at.model->elements[0].box.size().minCoeff(), at.compliance, r.exact, r.tie_term, r.semi,
              r.semi_without_pair);
  return r;
}

// Thesis §6.4.4, Eq. 6.24 in the plain trilinear basis (no incompatible modes, no aggregation):
// the pieces that join at +0.6015615 mm are tied by E·h·b(d) before the join (d: their gap, from
// piece_gaps) and C passes the join continuously: its step there is the slope times the interval
// (without the ties: a jump of 1.15e-4 relative). The exact gradient inside the ties' range,
// with the tie term −E·h·b'(d)·d'·‖u_a − u_b‖², against differences of the whole pipeline.
TEST(ShapeCompliance, MergePenaltyMakesTheJoinContinuousInThePlainBasis) {
  const MergeLine tied(true, 0, false), plain(false, 0, false);
  const ComplianceState ta = tied.state_at(tied.a), tb = tied.state_at(tied.b);
  const ComplianceState pa = plain.state_at(tied.a), pb = plain.state_at(tied.b);
  const double slope = (tied.state_at(tied.a - 0.01).compliance - tied.state_at(tied.a - 0.011).compliance) / 0.001;
  const double step = std::abs(slope) * (tied.b - tied.a);
  std::printf("join at + %.8f mm: without ties C %.10g -> %.10g (jump %.3e relative); with %zu tie(s) C %.10g -> %.10g "
              "(%zu after; step %.3e relative); slope x interval %.2e relative\n",
              tied.a, pa.compliance, pb.compliance, (pb.compliance - pa.compliance) / pa.compliance, ta.ties.size(),
              ta.compliance, tb.compliance, tb.ties.size(), (tb.compliance - ta.compliance) / ta.compliance, step / ta.compliance);
  EXPECT_NEAR(tied.a, plain.a, 1e-8);
  EXPECT_EQ(ta.ties.size(), 1u);
  EXPECT_EQ(tb.ties.size(), 0u);
  EXPECT_EQ(pb.compliance, tb.compliance);  // no tie after the join: the same model
  // Measured: without ties -1.154e-4 relative; with them -8.3e-10, the slope times the interval
  // 8.29e-10 (C falls along the line).
  EXPECT_NEAR((pb.compliance - pa.compliance) / pa.compliance, -1.154e-4, 0.01e-4);
  EXPECT_LT(std::abs(tb.compliance - ta.compliance), 1.5 * step);
  const TieGradientCheck g = tie_gradient_check(tied, "plain hex8", {2e-4, 1e-4, 5e-5});
  // Measured on 2026-12-02's machine (AMD EPYC): relative differences 1.9e-8, 1.5e-8, 2.8e-9 at
  // the three steps, whose own spread (3.4e-8 relative: C's round-off over the step) is the
  // floor here; the machine before measured 1.5e-9 at 1e-4 (asserted then: 5e-9). The tie term
  // (-4.3e-4) is 3e3 times that spread: the exact value lies inside it.
  const auto [lo, hi] = std::minmax_element(g.fd.begin(), g.fd.end());
  EXPECT_LT(*hi - *lo, 6e-8 * std::abs(g.fd[1]));
  EXPECT_GE(g.exact, *lo - 0.25 * (*hi - *lo));
  EXPECT_LE(g.exact, *hi + 0.25 * (*hi - *lo));
  EXPECT_LT(std::abs(g.exact - g.fd[1]), 2e-4 * std::abs(g.tie_term));
}

// The same join in ParaFab's default basis, hex8 with incompatible modes, with and without
// aggregation. The two pieces' modes are condensed jointly (xfem::mode_tied: ½w‖α_a − α_b‖²,
// mean shifts blended towards the pair's by θ), so at the join they are the joined piece's one
// set. Before that, each piece kept its own set and mean and the ties made the jump worse:
// 3.59e-4 relative (5.55e-5 without ties) and, with aggregation, 3.60e-4. The gradient (without
// aggregation: with it the tie blends a floating node, a change of T this gradient does not
// carry) includes the pair's ‖α_a − α_b‖² and ∂/∂θ terms and its pieces' ψ with the joint modes.
TEST(ShapeCompliance, MergePenaltyMakesTheJoinContinuousWithIncompatibleModes) {
  // Measured jumps without ties, relative: 5.55e-5 and 3.61e-4 (with aggregation).
  for (const auto& [aggregation, untied_jump] : {std::pair{0.0, 5.55e-5}, std::pair{0.05, 3.61e-4}}) {
    const MergeLine tied(true, aggregation, true), bare(false, aggregation, true);
    const ComplianceState ta = tied.state_at(tied.a), tb = tied.state_at(tied.b);
    const ComplianceState ba = bare.state_at(tied.a), bb = bare.state_at(tied.b);
    const double slope = (tied.state_at(tied.a - 0.01).compliance - tied.state_at(tied.a - 0.011).compliance) / 0.001;
    const double step = std::abs(slope) * (tied.b - tied.a);
    const double jump = (tb.compliance - ta.compliance) / ta.compliance;
    std::printf("modes on, aggregation fraction %.2f: without ties a jump of %.3e relative; with them C %.10g -> %.10g, "
                "%.3e relative (slope x interval %.2e)\n",
                aggregation, (bb.compliance - ba.compliance) / ba.compliance, ta.compliance, tb.compliance, jump,
                step / ta.compliance);
    EXPECT_NEAR(tied.a, bare.a, 1e-8);
    ASSERT_EQ(ta.ties.size(), 1u);
    EXPECT_EQ(ta.solution.mode_tied_pairs, 1);
    EXPECT_EQ(tb.ties.size(), 0u);
    EXPECT_EQ(bb.compliance, tb.compliance);  // no tie after the join: the same model
    EXPECT_NEAR((bb.compliance - ba.compliance) / ba.compliance, untied_jump, 0.02 * untied_jump);
    // Measured -1.65e-9 for both (the slope times the interval: 8.9e-10).
    EXPECT_LT(std::abs(tb.compliance - ta.compliance), 2.5 * step);
  }
  // Here the tie term (11.0) is twice the gradient (5.58), and the differences converge to the
  // exact value as Richardson's h⁴ (the gap goes as √(a − s), 1 µm away): measured relative
  // differences 3.8e-5, 2.5e-6, 3.7e-7 at steps 1e-4, 5e-5, 2.5e-5 (the last near the round-off
  // of differences of C: ~3e-7). A missing term would not shrink with the step.
  const TieGradientCheck g =
      tie_gradient_check(MergeLine(true, 0, true), "hex8 with incompatible modes", {1e-4, 5e-5, 2.5e-5});
  EXPECT_EQ(g.mode_tied_pairs, 1);
  const double e0 = std::abs(g.exact - g.fd[0]), e1 = std::abs(g.exact - g.fd[1]), e2 = std::abs(g.exact - g.fd[2]);
  EXPECT_GT(e0 / e1, 10);  // h⁴: 16
  EXPECT_LT(e2, 1e-6 * std::abs(g.exact));
  EXPECT_LT(e2, 5e-7 * std::abs(g.tie_term));  // measured 1.9e-7
}

// The semi-analytic route holds the ties' weight and blend (it has no term for their change):
// with the cap at 0.3 the bracket's tie above (b = 0.47 at the gap 0.19 mm) sits on the cap, so
// its weight does not change there and that route is complete. It then matches the exact
// gradient and the differences of the whole pipeline only with the mode-tied pair's term
// (element_difference's pair_term: the pair's joint-condensation correction differenced).
TEST(ShapeCompliance, SemiAnalyticDerivativeCarriesATiedPairsJointModes) {
  MergeLine tied(true, 0, true);
  tied.c.setup.merge.cap = 0.3;
  const TieGradientCheck g = tie_gradient_check(tied, "modes, cap 0.3", {1e-4});
  EXPECT_EQ(g.mode_tied_pairs, 1);
  const double fd = g.fd[0];
  std::printf("cap 0.3: exact %.10g, FD %.10g, semi-analytic %.10g (%.2e), without the pair's term %.10g (%.2e)\n",
              g.exact, fd, g.semi, std::abs(g.semi - fd) / std::abs(fd), g.semi_without_pair,
              std::abs(g.semi_without_pair - fd) / std::abs(fd));
  // Measured relative differences: exact 2.5e-8, semi-analytic 1.2e-8, without the pair's term 1.4e-2.
  EXPECT_LT(std::abs(g.exact - fd), 1e-7 * std::abs(fd));
  EXPECT_LT(std::abs(g.semi - fd), 5e-8 * std::abs(fd));
  EXPECT_GT(std::abs(g.semi_without_pair - fd), 1e-3 * std::abs(fd));
}

}  // namespace
}  // namespace parafab::occ

namespace parafab::occ {
namespace {

// Cones and spheres in the exact compliance gradient (Eq. 6.30–6.31 with Vₙ from the cone's and
// sphere's own parameters): samples/parts/countersunk_pin_block.step turned 11° off the grid
// (every face cuts cells), clamped at x = 0, 500 N down on the end x = 60 (a total force), steel,
// 10 cells. Entries as the optimizer moves them (projection, write-back) against Richardson
// differences of the whole pipeline (re-cut on the same grid, solve).
TEST(ShapeCompliance, ConeAndSphereEntriesHaveExactGradients) {
  const Vec3 center(30, 20, 12);
  auto turned = [&](const Vec3& X) -> Vec3 {
    return center + Eigen::AngleAxisd(11 * M_PI / 180, testing::kBracketAxis) * (X - center);
  };
  const auto part = rotated_part(*read_part(testing::sample_part("countersunk_pin_block")), center,
                                 testing::kBracketAxis, 11);
  const double tol = 1e-6;
  const int support = face_at_point(*part, turned({0, 20, 6}), tol);
  const int load = face_at_point(*part, turned({60, 20, 6}), tol);
  const int cone = face_at_point(*part, turned({15 + 6, 20, 10}), tol);  // countersink, r 6 at z 10
  const int pin = face_at_point(*part, turned({48, 20, 18}), tol);       // pin cylinder r 6
  const int sphere = face_at_point(*part, turned({42, 20, 30}), tol);    // its cap's top
  const int hole = face_at_point(*part, turned({15 + 4, 20, 4}), tol);   // the countersunk hole
  const ComplianceSetup setup =
      testing::steel_cantilever(*part, support, load, turned(Vec3(0, 0, -500)) - turned(Vec3::Zero()));
  const testing::DesignSpace space(*part, {support, load});
  ASSERT_TRUE(space.start.done);
  const auto& [model, sp, start, L] = space;
  // Tolerances near the measured relative differences: half-angle 1.3e-6, cone radius 1.9e-6,
  // hole axis point (cone and hole move together) 9.0e-6, pin radius (the sphere's radius is
  // tied to it: the same column) 3.4e-6, sphere centre 8.1e-5 of a derivative 70×
  // smaller than the radii's (absolute 7.7e-8, as theirs: 2.2e-7). The centre's side steps failed
  // the write-back until 2026-11-29 (the cap's pole vertex missed the moved pole: BRepCheck).
  const std::vector<EntryCase> cases = {
      {"cone half-angle", parameter_index(sp, cone, "half-angle"), 3e-6},
      {"cone radius", parameter_index(sp, cone, "radius"), 4e-6},
      {"hole axis point y (the coaxial countersink follows)", parameter_index(sp, hole, "axis point y"), 1.5e-5},
      {"pin radius (the sphere follows)", parameter_index(sp, pin, "radius"), 6e-6},
      {"sphere centre z (along the pin's axis)", parameter_index(sp, sphere, "centre z"), 1.5e-4},
  };
  for (const EntryCase& k : cases) {
    const ExactAtEntry e(*part, space, k.index, setup);
    ASSERT_EQ(e.failure(), "") << k.what;
    auto part_at = [&](double s) { return e.entry.part_at(s); };
    const ComplianceState& at = e.at;
    const ComplianceGradient& g = e.gradient;
    const double exact = e.along;
    EXPECT_TRUE(exact_along(g, e.entry.column)) << k.what;
    // Steps in the entry's own unit: radians for the half-angle (2e-4·L would be 1°), mm otherwise.
    const double H = sp.names[k.index].find("half-angle") != std::string::npos ? 2e-4 : 2e-4 * L;
    double coarse = 0;
    const double fd = richardson([&](double s) { return compliance_on(part_at(s), at, setup); }, H, &coarse);
    std::printf("%s: C = %.10g, exact %.10g, FD %.10g (H: %.10g), relative difference %.2e, %d elements, %d points\n",
                k.what, at.compliance, exact, fd, coarse, std::abs(exact - fd) / std::abs(fd), g.elements, g.points);
    EXPECT_LE(std::abs(exact - fd), k.tolerance * std::abs(fd)) << k.what;
  }
}

// A support's own motion in the exact route (a bolt hole clamped by its bolt, the upright's top
// clamped, a countersink under a clamped screw head): with uₕ frozen, the Nitsche terms on the
// moving support Γ change by ∫_Γ [(∂ₙF + κF) Vₙ − ∂F/∂n·∇_Γ Vₙ] dA + ∮ F α ds (the normal
// turning by −∇_Γ Vₙ: the hole's axis point, the top's normal), besides the bulk term.
// Against Richardson differences of the whole pipeline; the semi-analytic route (until
// 2026-12-02 the only one for these entries) is printed beside it.
TEST(ShapeCompliance, ASupportsOwnMotionHasAnExactGradient) {
  struct SupportCase {
    const char* what;
    std::shared_ptr<const PartShape> part;
    int support, load, entry_face;
    const char* parameter;
    bool local_penalty, prescribed;
    double tolerance, tolerance_12;  // the solver's default patch rules (5; 8 on curved supports), all at 12
  };
  BracketCase bracket;
  const Vec3 center(30, 20, 12);
  auto turned_block = [&](const Vec3& X) -> Vec3 {
    return center + Eigen::AngleAxisd(11 * M_PI / 180, testing::kBracketAxis) * (X - center);
  };
  const auto block = rotated_part(*read_part(testing::sample_part("countersunk_pin_block")), center,
                                  testing::kBracketAxis, 11);
  const double tol = 1e-6;
  const int bracket_end = bracket.setup.tractions[0].face;
  const int top = face_at_point(*bracket.part, turned({4, 20, 50}), tol);  // its offset: a kink in C (FD 1.6 % off both routes)
  const int block_end = face_at_point(*block, turned_block({60, 20, 6}), tol);
  const int cone = face_at_point(*block, turned_block({15 + 6, 20, 10}), tol);
  // Tolerances near the measured relative differences. The route differentiates the exact
  // Nitsche integrals; the solver integrates them with its patch rules, whose error on a curved
  // support changes with the shape too. With the solver's defaults (degree 8 on curved supports
  // since 2026-12-02, 5 on planes): 4.9e-6, 1.5e-5, 2.4e-6, 9.4e-11, 1.2e-6 (the plane), 6.6e-7
  // and 3.1e-6 (in the order below); with every patch rule at degree 12: 1.7e-7, 2.9e-7, 2.3e-6,
  // 2.5e-11, 3.3e-8, 7.5e-7 and 4.5e-7. (With degree 5 on curved supports, the default until
  // then: 3.6e-4, 1.2e-3, 1.6e-4, 5.2e-8, 3.3e-4 and 5.0e-4; the plane at 8: 7.5e-10.)
  const std::vector<SupportCase> cases = {
      {"bracket hole radius, the hole clamped", bracket.part, bracket.hole, bracket_end, bracket.hole, "radius",
       false, false, 1e-5, 5e-7},
      {"bracket hole axis point x, the hole clamped", bracket.part, bracket.hole, bracket_end, bracket.hole,
       "axis point x", false, false, 3e-5, 8e-7},
      {"bracket hole radius, local Nitsche penalty", bracket.part, bracket.hole, bracket_end, bracket.hole, "radius",
       true, false, 5e-6, 5e-6},
      {"bracket hole radius, a prescribed displacement", bracket.part, bracket.hole, bracket_end, bracket.hole,
       "radius", false, true, 3e-10, 1e-10},
      {"upright top normal y, the top clamped", bracket.part, top, bracket_end, top, "normal y", false, false, 3e-6,
       1e-7},
      {"countersink radius, the screw head clamped", block, cone, block_end, cone, "radius", false, false, 1.5e-6, 2e-6},
      {"countersink half-angle, the screw head clamped", block, cone, block_end, cone, "half-angle", false, false,
       6e-6, 1.5e-6},
      // A plane support into which a fillet runs tangent: the edge is the foot of the fillet's
      // spine on the support, a tilt slides it by −φ(S) ν·∂n (offset: no slide). Measured 7.4e-6
      // and 8.0e-5 at both degrees; the semi-analytic route is 3.6e-6 and 8.05e-5 off the same
      // differences (4e-7 from the exact tilt): the tilt's figure is the reference's.
      {"upright back offset, the back clamped (outer fillet tangent)", bracket.part, bracket.setup.dirichlet[0].face,
       bracket_end, bracket.setup.dirichlet[0].face, "offset", false, false, 1.5e-5, 1.5e-5},
      {"upright back normal z, the back clamped (outer fillet tangent)", bracket.part, bracket.setup.dirichlet[0].face,
       bracket_end, bracket.setup.dirichlet[0].face, "normal z", false, false, 1.2e-4, 1.2e-4},
  };
  // Supports whose own motion stays differenced (flagged): the base's bottom next to the loaded
  // end face; the hole both clamped and loaded; the hole clamped to a prescribed `field`. (The
  // back of the upright, tangent into the outer fillet, was flagged until 2026-12-02: above.)
  {
    const int bottom = face_at_point(*bracket.part, turned({30, 20, 0}), tol);
    const Vec3 down = testing::turned(Vec3(0, 0, -500)) - testing::turned(Vec3::Zero());
    ComplianceSetup both = testing::steel_cantilever(*bracket.part, bracket.hole, bracket_end, down);
    xfem::TractionCondition bolt{bracket.hole, Vec3(0, 0, -1)};
    both.tractions.push_back(bolt);
    both.forces.push_back(Vec3::Zero());
    ComplianceSetup field = testing::steel_cantilever(*bracket.part, bracket.hole, bracket_end, down);
    field.dirichlet[0].field = [](const Vec3&) { return Vec3::Zero(); };
    const std::vector<std::tuple<const char*, ComplianceSetup, int, const char*>> flagged = {
        {"base bottom next to the loaded end", testing::steel_cantilever(*bracket.part, bottom, bracket_end, down), bottom,
         "offset"},
        {"hole clamped and loaded", both, bracket.hole, "radius"},
        {"hole clamped to a field", field, bracket.hole, "radius"},
    };
    const testing::DesignSpace space(*bracket.part, {bracket_end});
    ASSERT_TRUE(space.start.done);
    for (const auto& [what, setup, face, parameter] : flagged) {
      const ExactAtEntry e(*bracket.part, space, parameter_index(space.parameters, face, parameter), setup);
      ASSERT_EQ(e.failure(), "") << what;
      EXPECT_FALSE(exact_along(e.gradient, e.entry.column)) << what;
    }
  }
  for (const int degree : {5, 12})
  for (const SupportCase& k : cases) {
    ComplianceSetup setup = testing::steel_cantilever(*k.part, k.support, k.load,
                                                      testing::turned(Vec3(0, 0, -500)) - testing::turned(Vec3::Zero()));
    setup.solver.surface_degree = degree;  // 5: the default, whose curved supports get dirichlet_surface_degree (8)
    if (k.local_penalty) setup.solver.nitsche_penalty = xfem::LinearXfemOptions::NitschePenalty::Local;
    if (k.prescribed) {  // the bolt pulls its hole 0.01 mm along x and turns it a little
      setup.dirichlet[0].offset = Vec3(0.01, 0, 0);
      setup.dirichlet[0].gradient << 0, -1e-4, 0, 1e-4, 0, 0, 0, 0, 0;
    }
    const testing::DesignSpace space(*k.part, {k.load});
    ASSERT_TRUE(space.start.done);
    const int index = parameter_index(space.parameters, k.entry_face, k.parameter);
    const ExactAtEntry e(*k.part, space, index, setup);
    ASSERT_EQ(e.failure(), "") << k.what;
    auto part_at = [&](double s) { return e.entry.part_at(s); };
    EXPECT_TRUE(exact_along(e.gradient, e.entry.column)) << k.what;
    const double L = space.size;
    const bool angle = std::string(k.parameter) == "half-angle" || std::string(k.parameter).rfind("normal", 0) == 0;
    const double H = angle ? 2e-4 : 2e-4 * L;
    const double fd = richardson([&](double s) { return compliance_on(part_at(s), e.at, setup); }, H);
    const ComplianceDerivative semi = compliance_derivative(e.at, part_at(H / 2), part_at(-H / 2), H / 2, setup);
    std::printf("degree %d, %s: C = %.10g, exact %.10g, FD %.10g, relative difference %.2e; semi-analytic %.10g (%.2e); %d points, "
                "%d on edges\n",
                degree, k.what, e.at.compliance, e.along, fd, std::abs(e.along - fd) / std::abs(fd), semi.derivative,
                std::abs(semi.derivative - fd) / std::abs(fd), e.gradient.points, e.gradient.edge_points);
    EXPECT_LE(std::abs(e.along - fd), (degree == 5 ? k.tolerance : k.tolerance_12) * std::abs(fd)) << degree << ", " << k.what;
  }
}

// A load face's own motion in the exact route (a bolt hole under its bolt load, the end face that
// carries the load, a countersink under a screw head): with uₕ frozen, 2 d/ds ∫_Γ uₕ·t dA adds
// the normal derivative and mean curvature terms over Γ and the slide of Γ's edges along its
// neighbours (α = −Vₙ (n_Γ·n_F)/(ν·n_F), non-zero at the countersink's 135° edges), besides the
// bulk term and a total force's change of traction with Γ's area. Against Richardson differences
// of the whole pipeline; the semi-analytic route (until 2026-12-02 the only one for these
// entries) is printed beside it. Until then a load's own motion was flagged incomplete.
TEST(ShapeCompliance, ALoadFacesOwnMotionHasAnExactGradient) {
  struct LoadCase {
    const char* what;
    std::shared_ptr<const PartShape> part;
    int support, load, entry_face;
    const char* parameter;
    bool total_force;
    double tolerance;
  };
  BracketCase bracket;
  const Vec3 center(30, 20, 12);
  auto turned_block = [&](const Vec3& X) -> Vec3 {
    return center + Eigen::AngleAxisd(11 * M_PI / 180, testing::kBracketAxis) * (X - center);
  };
  const auto block = rotated_part(*read_part(testing::sample_part("countersunk_pin_block")), center,
                                  testing::kBracketAxis, 11);
  const double tol = 1e-6;
  const int bracket_support = bracket.setup.dirichlet[0].face, bracket_end = bracket.setup.tractions[0].face;
  const int block_support = face_at_point(*block, turned_block({0, 20, 6}), tol);
  const int cone = face_at_point(*block, turned_block({15 + 6, 20, 10}), tol);
  // Tolerances near the measured relative differences: end face 5.3e-11; hole 1.07e-4 with the
  // total force, whose dC (0.0107) is what is left of terms of the fixed traction's size (5.90,
  // 1.15e-7 there): the absolute differences are alike, 1.1e-6 and 6.8e-7; countersink radius
  // 2.3e-6, half-angle 4.7e-6 (the cone entries of the test above: 1.9e-6 and 1.3e-6), where the
  // edge terms are most of the value: without them the exact values were 34× and 24× off.
  const std::vector<LoadCase> cases = {
      {"bracket end face offset (its load moves with it)", bracket.part, bracket_support, bracket_end, bracket_end,
       "offset", true, 1e-9},
      {"bracket hole radius, bolt load as a total force", bracket.part, bracket_support, bracket.hole, bracket.hole,
       "radius", true, 2e-4},
      {"bracket hole radius, bolt load as a fixed traction", bracket.part, bracket_support, bracket.hole, bracket.hole,
       "radius", false, 3e-7},
      {"countersink radius, screw head load", block, block_support, cone, cone, "radius", true, 5e-6},
      {"countersink half-angle, screw head load", block, block_support, cone, cone, "half-angle", true, 1e-5},
  };
  // Loads whose own motion stays differenced (flagged): the inner fillet, which runs tangent
  // into both its planes, and the end face next to a support on the base's bottom.
  const int bottom = face_at_point(*bracket.part, testing::turned({30, 20, 0}), tol);
  const std::vector<std::tuple<const char*, int, int, int, const char*>> flagged = {
      {"inner fillet radius, the fillet loaded", bracket_support, bracket.fillet, bracket.fillet, "radius"},
      {"end face offset, the base's bottom supported", bottom, bracket_end, bracket_end, "offset"},
  };
  for (const auto& [what, support, load, face, parameter] : flagged) {
    const ComplianceSetup setup = testing::steel_cantilever(*bracket.part, support, load,
                                                            testing::turned(Vec3(0, 0, -500)) - testing::turned(Vec3::Zero()));
    const testing::DesignSpace space(*bracket.part, {support});
    ASSERT_TRUE(space.start.done);
    const ExactAtEntry e(*bracket.part, space, parameter_index(space.parameters, face, parameter), setup);
    ASSERT_EQ(e.failure(), "") << what;
    EXPECT_FALSE(exact_along(e.gradient, e.entry.column)) << what;
  }
  for (const LoadCase& k : cases) {
    ComplianceSetup setup = testing::steel_cantilever(*k.part, k.support, k.load,
                                                      testing::turned(Vec3(0, 0, -500)) - testing::turned(Vec3::Zero()));
    if (!k.total_force) setup.forces.clear();
    const testing::DesignSpace space(*k.part, {k.support});
    ASSERT_TRUE(space.start.done);
    const int index = parameter_index(space.parameters, k.entry_face, k.parameter);
    const ExactAtEntry e(*k.part, space, index, setup);
    ASSERT_EQ(e.failure(), "") << k.what;
    auto part_at = [&](double s) { return e.entry.part_at(s); };
    EXPECT_TRUE(exact_along(e.gradient, e.entry.column)) << k.what;
    const double L = space.size;
    const double H = std::string(k.parameter) == "half-angle" ? 2e-4 : 2e-4 * L;
    const double fd = richardson([&](double s) { return compliance_on(part_at(s), e.at, setup); }, H);
    const ComplianceDerivative semi = compliance_derivative(e.at, part_at(H / 2), part_at(-H / 2), H / 2, setup);
    std::printf("%s: C = %.10g, exact %.10g, FD %.10g, relative difference %.2e; semi-analytic %.10g (%.2e); %d points\n",
                k.what, e.at.compliance, e.along, fd, std::abs(e.along - fd) / std::abs(fd), semi.derivative,
                std::abs(semi.derivative - fd) / std::abs(fd), e.gradient.points);
    EXPECT_LE(std::abs(e.along - fd), k.tolerance * std::abs(fd)) << k.what;
  }
}

}  // namespace
}  // namespace parafab::occ
