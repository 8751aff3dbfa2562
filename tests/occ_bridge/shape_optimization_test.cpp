// Shape parameters of STEP parts, their projection, write-back into the B-rep and exact mass
// shape derivatives (thesis §6.2.3 Eq. 6.5, §6.5.1-6.5.2 Eq. 6.25-6.29), against independent
// references: closed-form volume changes, OCCT mass properties (BRepGProp) and their central
// finite differences, BRepCheck, and a STEP round trip.
#include <gtest/gtest.h>

#include <BRepAlgoAPI_Cut.hxx>
#include <BRepGProp.hxx>
#include <BRepPrimAPI_MakeBox.hxx>
#include <BRepPrimAPI_MakeCylinder.hxx>
#include <BRepPrimAPI_MakeCone.hxx>
#include <GProp_GProps.hxx>
#include <GProp_PrincipalProps.hxx>
#include <BRepPrimAPI_MakeSphere.hxx>
#include <cmath>
#include <cstdio>

#include "common/error.h"
#include "occt_mass_properties.h"
#include "occt_shape.h"
#include "part_reader.h"
#include "shape_derivatives.h"
#include "shape_modify.h"
#include "shape_optimization.h"
#include "shape_parameters.h"

namespace parafab::occ {
namespace {

std::string sample(const std::string& name) { return std::string(PARAFAB_SAMPLES_DIR) + "/parts/" + name + ".step"; }

// The face of `type` whose primitive satisfies `pred`; fails the test if not exactly one.
int find_face(const FaceModel& m, SurfaceType type, const std::function<bool(const Primitive&)>& pred) {
  int found = -1, count = 0;
  for (const FaceInfo& f : m.faces)
    if (f.primitive.type == type && pred(f.primitive)) found = f.index, ++count;
  EXPECT_EQ(count, 1);
  return found;
}
int cylinder_at(const FaceModel& m, double r, double x, double y) {
  return find_face(m, SurfaceType::cylinder, [&](const Primitive& p) {
    return std::abs(p.radius - r) < 1e-6 && std::abs(p.location.x() - x) < 1e-6 && std::abs(p.location.y() - y) < 1e-6;
  });
}
int plane_at(const FaceModel& m, const Vec3& normal, double offset) {
  return find_face(m, SurfaceType::plane, [&](const Primitive& p) {
    return std::abs(std::abs(p.axis.dot(normal)) - 1) < 1e-9 && std::abs(p.location.dot(normal) - offset) < 1e-6;
  });
}

int fillet_r5(const FaceModel& m) {
  return find_face(m, SurfaceType::cylinder, [](const Primitive& p) { return std::abs(p.radius - 5) < 1e-6; });
}

struct PartSetup {
  std::shared_ptr<const PartShape> part;
  FaceModel model;
  ShapeParameters sp;
  optimize::ProjectionResult start;
  explicit PartSetup(const std::string& name) {
    part = read_part(sample(name));
    model = build_face_model(*part);
    sp = build_shape_parameters(model);
    start = optimize::project(sp.constraints, sp.initial, sp.initial, sp.lower, sp.upper);
  }
  // Projection weights as the optimizer sets them: 1 on the changed (design) entries, 1e-6 on
  // the others so that tangent neighbours follow.
  Eigen::VectorXd weights(const std::vector<int>& design) const {
    const PartInfo info = part_info(*part);
    return projection_weights(sp, design, 1e-6, (info.bbox_max - info.bbox_min).norm());
  }
  // p⊥ for the start with entries changed.
  optimize::ProjectionResult projected(const std::vector<std::pair<int, double>>& changes) const {
    Eigen::VectorXd t = start.p;
    std::vector<int> design;
    for (auto [i, v] : changes) t[i] = v, design.push_back(i);
    optimize::ProjectionOptions o;
    o.weights = weights(design);
    return optimize::project(sp.constraints, t, start.p, sp.lower, sp.upper, {}, o);
  }
};

TEST(ShapeParameters, SamplePartsSatisfyTheirConstraintsAndJacobiansAreExact) {
  for (const std::string name : {"l_bracket", "wheel", "wrench", "housing", "countersunk_pin_block"}) {
    PartSetup s(name);
    ASSERT_GT(s.sp.size(), 0) << name;
    // The part as read satisfies c_para to the face model's detection tolerance.
    EXPECT_LT(s.sp.constraints.values(s.sp.initial).cwiseAbs().maxCoeff(), 1e-6) << name;
    ASSERT_TRUE(s.start.done) << name << ": " << s.start.message;
    EXPECT_LT(s.start.distance, 1e-5) << name;
    // Jacobian against central differences at the part's parameters.
    const Eigen::MatrixXd J = s.sp.constraints.jacobian(s.sp.initial);
    double worst = 0;
    for (int i = 0; i < s.sp.size(); ++i) {
      Eigen::VectorXd pp = s.sp.initial, pm = s.sp.initial;
      pp[i] += 1e-6, pm[i] -= 1e-6;
      const Eigen::VectorXd fd = (s.sp.constraints.values(pp) - s.sp.constraints.values(pm)) / 2e-6;
      for (int r = 0; r < J.rows(); ++r) worst = std::max(worst, std::abs(J(r, i) - fd[r]) / std::max(1.0, std::abs(fd[r])));
    }
    EXPECT_LT(worst, 1e-7) << name;
  }
  PartSetup l("l_bracket");
  const int hole = cylinder_at(l.model, 4, 40, 12);
  EXPECT_EQ(l.sp.names[parameter_index(l.sp, hole, "radius")], "face " + std::to_string(hole) + " cylinder radius");
  EXPECT_GT(l.sp.relation_equations, 0);
  EXPECT_THROW(parameter_index(l.sp, hole, "offset"), Error);
}

// Draft on curved faces: a cone (axis z) and a cylinder keep their axis parallel to the pull
// direction. Two independent rows each; they vanish at the start, change by exactly the axis
// tilt's cross product with the pull direction, and a wrong direction, a sphere or a zero axis
// is refused naming the entry.
TEST(ShapeParameters, DraftKeepsConeAndCylinderAxesParallelToThePull) {
  const auto cone = make_part(BRepPrimAPI_MakeCone(gp_Ax2(gp_Pnt(1, 2, 0), gp_Dir(0, 0, 1)), 20, 8, 30).Shape(), "cone");
  const FaceModel model = build_face_model(*cone);
  const int lateral = find_face(model, SurfaceType::cone, [](const Primitive&) { return true; });
  ShapeParameterOptions o;
  o.orthogonal.push_back({lateral, Vec3(0, 0, 2)});
  const ShapeParameters plain = build_shape_parameters(model);
  const ShapeParameters sp = build_shape_parameters(model, o);
  ASSERT_EQ(sp.constraints.size(), plain.constraints.size() + 2);
  EXPECT_LT(sp.constraints.values(sp.initial).tail(2).cwiseAbs().maxCoeff(), 1e-15);
  // Tilt the axis: the rows are (v × a) x and y for a = z, i.e. v_y and −v_x.
  Eigen::VectorXd p = sp.initial;
  const int ax = parameter_index(sp, lateral, "axis x"), ay = parameter_index(sp, lateral, "axis y");
  p[ax] += 0.01, p[ay] -= 0.02;
  const Eigen::Vector2d rows = sp.constraints.values(p).tail(2);
  EXPECT_NEAR(std::abs(rows[0]) + std::abs(rows[1]), 0.03, 1e-15);
  EXPECT_NEAR(std::abs(rows[0]), 0.02, 1e-15);  // x of v × a = v_y a_z
  // A pull direction the axis does not follow at the start, a sphere, a zero axis.
  ShapeParameterOptions tilted;
  tilted.orthogonal.push_back({lateral, Vec3(0.1, 0, 1)});
  try {
    build_shape_parameters(model, tilted);
    ADD_FAILURE() << "a tilted pull direction was accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("orthogonal[0]: face " + std::to_string(lateral) + "'s axis is not parallel"),
              std::string::npos) << e.what();
  }
  const auto ball = make_part(BRepPrimAPI_MakeSphere(10).Shape(), "sphere");
  const FaceModel ball_model = build_face_model(*ball);
  ShapeParameterOptions on_ball;
  on_ball.orthogonal.push_back({0, Vec3(0, 0, 1)});
  try {
    build_shape_parameters(ball_model, on_ball);
    ADD_FAILURE() << "a sphere was accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("orthogonal[0]: face 0 is sphere"), std::string::npos) << e.what();
  }
  ShapeParameterOptions zero;
  zero.orthogonal.push_back({lateral, Vec3::Zero()});
  EXPECT_THROW(build_shape_parameters(model, zero), Error);
}

TEST(ShapeParameters, ProjectionOfAPerturbedFilletPartRestoresTangency) {
  PartSetup s("l_bracket");
  const int top = plane_at(s.model, Vec3::UnitZ(), 8);  // the base top, tangent to the inner fillet
  const int fillet = fillet_r5(s.model);
  ASSERT_GE(fillet, 0);
  const int d = parameter_index(s.sp, top, "offset");
  const double sign = s.sp.initial[d] > 0 ? 1 : -1;  // n·X = d with n = ±z
  // User constraint: keep the fillet radius (bounds lower = upper); then the fillet translates.
  const int radius = parameter_index(s.sp, fillet, "radius");
  s.sp.lower[radius] = s.sp.upper[radius] = 5;
  const optimize::ProjectionResult r = s.projected({{d, s.sp.initial[d] + sign * 0.5}});
  ASSERT_TRUE(r.done) << r.message;
  // The face model's own relation formulas (not the reduced ones) at p⊥.
  EXPECT_LT(tangency_residual_max(s.model, s.sp, r.p), 1e-10);
  // The target offset is kept up to the follower weight (1e-6 · 0.5) and the fillet moved up.
  EXPECT_NEAR(r.p[d], s.sp.initial[d] + sign * 0.5, 1e-6);
  const auto* fb = s.sp.block(fillet);
  EXPECT_NEAR(r.p[fb->offset + 2], 13.5, 1e-6);
  EXPECT_NEAR(r.p[fb->offset + 6], 5, 1e-9);
}

// Ipopt 3.11 stopped with "search direction too small" at a feasible warm start 0.125 mm from
// the nearest point: python.optimize_compliance on this machine (2026-11-28), where the hole
// radii's target 3.713 came back as the previous trial's 3.838, so every shorter trial of the
// line search evaluated the same model and the run ended "line_search_failed" at a worse design.
// The recorded warm start and target of that call (the followers carry the run's ~1e-10 drift),
// projected with the optimizer's weights (both radii design entries, followers 1e-4): the result
// must be the target (the radii are free of constraints). With the stationarity check switched
// off the same call is printed for comparison (0.125 mm off here; round-off decides whether
// Ipopt stops there, so that figure is not asserted).
TEST(ShapeParameters, WarmStartedProjectionReachesTheNearestPoint) {
  PartSetup s("l_bracket");
  const std::vector<double> warm = {
      -0, -1, -0, -0, 6.5162419650215935e-18, 0, 1, -4.1877320231312702e-11, 12.000000000083755,
      -8.5226323907615029e-321, 12.000000000041878, -4.9406564584124654e-324, 1, 0,
      12.000000000083755, 1, 0, -0, 60, 1, 0, -0, 0, 2.2732786746477073e-17, 0, 1,
      7.9999999998631655, 0, 0, 1, 50, 13.000000000136836, 0, 13.000000000136836, -0, 1, 0,
      5.00000000027367, 1, 0, 2.2732786746376099e-17, 7.9999999998631655, 0, 1, 0, 40, 40, 12, -5,
      0, 0, 1, 3.8380174953574668, 40, 28, -5, 0, 0, 1, 3.8380174953574997};
  const std::vector<double> target = {
      -0, -1, -0, -0, 3.258151782133337e-18, 0, 1, -2.0939938380991516e-11, 12.000000000041879, 0,
      12.00000000002094, -0, 1, 0, 12.000000000041879, 1, 0, -0, 60, 1, 0, -0, 0,
      1.1979511257011927e-17, 0, 1, 7.9999999999270868, 0, 0, 1, 50, 13.000000000072914, 0,
      13.000000000072914, -0, 1, 0, 5.0000000001458274, 1, 0, 1.1979511256910953e-17,
      7.9999999999270868, 0, 1, 0, 40, 40, 12, -5, 0, 0, 1, 3.7130174953574402, 40, 28, -5, 0, 0, 1,
      3.7130174953574668};
  ASSERT_EQ(static_cast<int>(warm.size()), s.sp.size());
  std::vector<int> holes;
  for (const FaceInfo& f : s.model.faces)
    if (f.primitive.type == SurfaceType::cylinder && std::abs(f.primitive.radius - 4) < 1e-6)
      holes.push_back(parameter_index(s.sp, f.index, "radius"));
  ASSERT_EQ(holes.size(), 2u);
  const Eigen::VectorXd w0 = Eigen::Map<const Eigen::VectorXd>(warm.data(), warm.size());
  const Eigen::VectorXd t = Eigen::Map<const Eigen::VectorXd>(target.data(), target.size());
  for (int i : holes) EXPECT_NEAR(t[i], 3.713017495357, 1e-9);
  const PartInfo info = part_info(*s.part);
  optimize::ProjectionOptions o;
  o.weights = projection_weights(s.sp, holes, 1e-4, (info.bbox_max - info.bbox_min).norm());
  for (const double stationarity : {1e300, o.stationarity}) {
    optimize::ProjectionOptions oo = o;
    oo.stationarity = stationarity;
    const optimize::ProjectionResult r = optimize::project(s.sp.constraints, t, w0, s.sp.lower, s.sp.upper, {}, oo);
    double worst = 0;
    for (int i : holes) worst = std::max(worst, std::abs(r.p[i] - t[i]));
    std::printf("stationarity check %s: %s (%s), radii off their target by %.3g mm, %d cold restarts\n",
                stationarity > 1 ? "off" : "on", r.status.c_str(), r.message.c_str(), worst, r.restarts);
    if (stationarity > 1) continue;
    ASSERT_TRUE(r.done) << r.message;
    EXPECT_LT(worst, 1e-9);
    EXPECT_LT(tangency_residual_max(s.model, s.sp, r.p), 1e-10);
  }
}

struct VolumeCase {
  std::string part;
  std::vector<std::pair<int, double>> changes;  // (index in p, new value)
  double delta_volume;                          // closed form
};

TEST(ShapeModify, ParameterChangesGiveValidPartsWithTheClosedFormVolume) {
  std::vector<std::pair<PartSetup*, VolumeCase>> cases;
  PartSetup l("l_bracket"), w("wheel"), r("wrench"), h("housing");
  {
    const int hole = cylinder_at(l.model, 4, 40, 12);
    cases.push_back({&l, {"l_bracket hole r 4 -> 4.5", {{parameter_index(l.sp, hole, "radius"), 4.5}},
                          -M_PI * (4.5 * 4.5 - 16) * 8}});
    const int top = plane_at(l.model, Vec3::UnitZ(), 8);
    const int d = parameter_index(l.sp, top, "offset");
    const int radius = parameter_index(l.sp, fillet_r5(l.model), "radius");  // keep the fillet radius
    l.sp.lower[radius] = l.sp.upper[radius] = 5;
    const double v = l.sp.initial[d] + (l.sp.initial[d] > 0 ? 0.5 : -0.5);
    cases.push_back({&l, {"l_bracket fillet-adjacent base top 8 -> 8.5", {{d, v}}, 0.5 * (52 * 40 - 2 * M_PI * 16)}});
  }
  {
    const int hole = cylinder_at(w.model, 5, 0, 0);
    cases.push_back({&w, {"wheel hub hole r 5 -> 5.5", {{parameter_index(w.sp, hole, "radius"), 5.5}},
                          -M_PI * (5.5 * 5.5 - 25) * 10}});
  }
  {
    const int hole = cylinder_at(r.model, 5, 0, 0);
    cases.push_back({&r, {"wrench ring hole r 5 -> 5.5", {{parameter_index(r.sp, hole, "radius"), 5.5}},
                          -M_PI * (5.5 * 5.5 - 25) * 6}});
  }
  {
    const int fin = plane_at(h.model, Vec3::UnitX(), 10);  // first fin's +x side (x = 8..10)
    const int d = parameter_index(h.sp, fin, "offset");
    const double v = h.sp.initial[d] + (h.sp.initial[d] > 0 ? 0.5 : -0.5);
    cases.push_back({&h, {"housing fin 2 -> 2.5 wide", {{d, v}}, 0.5 * 30 * 8}});
  }
  for (auto& [s, c] : cases) {
    const optimize::ProjectionResult p = s->projected(c.changes);
    ASSERT_TRUE(p.done) << c.part << ": " << p.message;
    const ModifyResult m = modify_part(*s->part, s->model, s->sp, p.p);
    ASSERT_TRUE(m.done) << c.part << ": " << m.message;
    const double v0 = occt_mass_properties(*s->part).volume, v1 = occt_mass_properties(*m.part).volume;
    EXPECT_NEAR(v1 - v0, c.delta_volume, 1e-7 * v0) << c.part;
    // STEP round trip: read back (read_part validates: closed, manifold, BRepCheck).
    const std::string path = ::testing::TempDir() + "/shape_modify_roundtrip.step";
    write_step(*m.part, path);
    const auto back = read_part(path);
    EXPECT_EQ(back->face_count(), s->part->face_count()) << c.part;
    EXPECT_NEAR(occt_mass_properties(*back).volume, v1, 1e-7 * v0) << c.part;
    // The written part keeps its tangencies (its own face model finds the same relations).
    const FaceModel after = build_face_model(*back);
    EXPECT_EQ(after.relations.size(), s->model.relations.size()) << c.part;
    std::remove(path.c_str());
  }
}

// Cones and spheres (samples/parts/countersunk_pin_block.step): a countersunk hole (cone of
// half-angle 45° from r = 4 at z = 8, where it meets the hole's cylinder, up to the top z = 12)
// and a pin (cylinder r = 6 from the top to z = 24) capped by a tangent hemisphere (centre
// z = 24). Each change goes through the projection (the cylinder-sphere tangency moves the other
// face) and the write-back; OCCT's volume of the written part against the closed form, whose
// inputs (cone reference circle, half-angle, radii, centre) are read from the written part's own
// face model; STEP round trip with the same faces and tangency relation.
TEST(ShapeModify, ConeAndSpherePartsKeepTheClosedFormVolume) {
  PartSetup s("countersunk_pin_block");
  const int cone = find_face(s.model, SurfaceType::cone, [](const Primitive&) { return true; });
  const int sphere = find_face(s.model, SurfaceType::sphere, [](const Primitive&) { return true; });
  const int pin = cylinder_at(s.model, 6, 42, 20);
  const int hole = cylinder_at(s.model, 4, 15, 20);
  ASSERT_EQ(s.model.relations.size(), 2u);  // cylinder-sphere (pin, cap), coaxial (hole, cone)
  // The part's volume from its primitives: block, minus the hole (r_h through z 0..12) and the
  // countersink beyond it (frustum from the cone's circle of radius r_h up to z = 12), plus the
  // pin (cylinder from z = 12 to the sphere's centre) and its hemisphere.
  auto closed_form = [](const FaceModel& m, int cone_face, int hole_face, int pin_face, int sphere_face) {
    const Primitive& c = m.faces[cone_face].primitive;
    const Primitive& h = m.faces[hole_face].primitive;
    const Primitive& pc = m.faces[pin_face].primitive;
    const Primitive& sp = m.faces[sphere_face].primitive;
    const double rh = h.radius, t = std::tan(c.semi_angle);
    // Cone radius r(z) = c.radius + (z − z_c) tan α along its axis +z (checked on the part as read).
    const double z0 = c.location.z() + (rh - c.radius) / t, r_top = c.radius + (12 - c.location.z()) * t;
    const double countersink = M_PI / 3 * (12 - z0) * (r_top * r_top + r_top * rh + rh * rh) - M_PI * rh * rh * (12 - z0);
    const double rp = pc.radius;
    return 60.0 * 40 * 12 - M_PI * rh * rh * 12 - countersink + M_PI * rp * rp * (sp.location.z() - 12) +
           2.0 / 3 * M_PI * std::pow(sp.radius, 3);
  };
  EXPECT_NEAR(s.model.faces[cone].primitive.axis.z(), 1, 1e-12);
  EXPECT_NEAR(closed_form(s.model, cone, hole, pin, sphere), occt_mass_properties(*s.part).volume, 1e-9 * 29738);
  struct Change {
    std::string what;
    int index;
    double value;
  };
  const std::vector<Change> changes = {
      {"cone half-angle 45 -> 40 deg", parameter_index(s.sp, cone, "half-angle"), 40 * M_PI / 180},
      {"cone half-angle 45 -> 52 deg", parameter_index(s.sp, cone, "half-angle"), 52 * M_PI / 180},
      {"pin radius 6 -> 6.5 (sphere follows)", parameter_index(s.sp, pin, "radius"), 6.5},
      {"sphere radius 6 -> 5.5 (pin follows)", parameter_index(s.sp, sphere, "radius"), 5.5},
      {"sphere centre z 24 -> 27 (pin grows)", parameter_index(s.sp, sphere, "centre z"), 27},
  };
  for (const Change& c : changes) {
    const optimize::ProjectionResult p = s.projected({{c.index, c.value}});
    ASSERT_TRUE(p.done) << c.what << ": " << p.message;
    // The entry reaches its value up to its weighted compromise with the tangent follower
    // (weights 1 and 1e-6: measured 5.0e-7 of a 0.5 mm radius change).
    EXPECT_NEAR(p.p[c.index], c.value, 2e-6 * std::abs(c.value - s.start.p[c.index])) << c.what;
    const ModifyResult m = modify_part(*s.part, s.model, s.sp, p.p);
    ASSERT_TRUE(m.done) << c.what << ": " << m.message;
    const std::string path = ::testing::TempDir() + "/cone_sphere_roundtrip.step";
    write_step(*m.part, path);
    const auto back = read_part(path);
    std::remove(path.c_str());
    const FaceModel after = build_face_model(*back);
    ASSERT_EQ(after.faces.size(), s.model.faces.size()) << c.what;
    ASSERT_EQ(after.relations.size(), 2u) << c.what;
    const double v = occt_mass_properties(*back).volume, ref = closed_form(after, cone, hole, pin, sphere);
    std::printf("%-40s OCCT volume %.9f, closed form %.9f (relative %.1e); sphere r %.9f, pin r %.9f, centre z %.9f\n",
                c.what.c_str(), v, ref, std::abs(v - ref) / ref, after.faces[sphere].primitive.radius,
                after.faces[pin].primitive.radius, after.faces[sphere].primitive.location.z());
    EXPECT_NEAR(v, ref, 1e-9 * ref) << c.what;
    EXPECT_GT(std::abs(v - occt_mass_properties(*s.part).volume), 10) << c.what;  // the change is not lost
    // Tangency kept on the written part up to the write-back's threshold: moves below
    // Precision::Confusion (1e-7) are not written (measured: the centre move leaves the pin's
    // radius 1.5e-8 from the sphere's, the followers' drift in the projection).
    EXPECT_NEAR(after.faces[sphere].primitive.radius, after.faces[pin].primitive.radius, 1e-7) << c.what;
  }
  // The countersink moved sideways: the coaxial relation (cone and hole meet along a sharp
  // circle on one axis) drags the hole along, and the write-back moves both (the volume stays).
  // Without the relation the cone alone moved off the hole's axis and the write-back refused the
  // part ("vertex 11 ... off the new curve of edge 15": the seam vertex the two faces share
  // cannot stay on both seams).
  const int axis_y = parameter_index(s.sp, cone, "axis point y"), hole_y = parameter_index(s.sp, hole, "axis point y");
  const optimize::ProjectionResult side = s.projected({{axis_y, s.start.p[axis_y] + 1.5}});
  ASSERT_TRUE(side.done) << side.message;
  EXPECT_NEAR(side.p[hole_y] - s.start.p[hole_y], 1.5, 1e-5);
  const ModifyResult moved = modify_part(*s.part, s.model, s.sp, side.p);
  ASSERT_TRUE(moved.done) << moved.message;
  const FaceModel after = build_face_model(*moved.part);
  ASSERT_EQ(after.relations.size(), 2u);
  EXPECT_NEAR(after.faces[hole].primitive.location.y(), 21.5, 1e-5);
  EXPECT_NEAR(occt_mass_properties(*moved.part).volume, occt_mass_properties(*s.part).volume, 1e-9 * 29738);
  EXPECT_NEAR(occt_mass_properties(*moved.part).volume, closed_form(after, cone, hole, pin, sphere), 1e-9 * 29738);
}

// A pointed cone (base r 10 at z = 0, apex at z = 20): its apex is the vertex of a degenerated
// edge. Radius and half-angle changes move the apex (v = −R/sin α on the cone); OCCT's volume of
// the written part against the cone's closed form π R² h / 3, h = R / tan α, both read from the
// written part's own face model.
TEST(ShapeModify, PointedConeMovesItsApex) {
  const auto part = make_part(BRepPrimAPI_MakeCone(gp_Ax2(gp_Pnt(0, 0, 0), gp_Dir(0, 0, 1)), 10, 0, 20).Shape(), "cone");
  const FaceModel model = build_face_model(*part);
  const ShapeParameters sp = build_shape_parameters(model);
  const int lateral = find_face(model, SurfaceType::cone, [](const Primitive&) { return true; });
  const Primitive& c0 = model.faces[lateral].primitive;
  std::printf("cone as read: location z %.9g, radius %.9g, half-angle %.9g, axis z %.3g\n", c0.location.z(), c0.radius,
              c0.semi_angle, c0.axis.z());
  auto closed_form = [&](const Primitive& c) {
    // Base radius at z = 0 from the cone's reference circle, height to the apex.
    const Vec3 apex = c.location - c.radius / std::tan(c.semi_angle) * c.axis;
    const double h = std::abs(apex.z());
    const double R = h * std::tan(c.semi_angle);
    return M_PI * R * R * h / 3;
  };
  EXPECT_NEAR(closed_form(c0), M_PI * 100 * 20 / 3, 1e-12 * 2094);
  for (const auto& [parameter, delta] : std::vector<std::pair<std::string, double>>{{"radius", 0.5}, {"half-angle", 0.05}}) {
    const int i = parameter_index(sp, lateral, parameter);
    Eigen::VectorXd t = sp.initial;
    t[i] += delta;
    optimize::ProjectionOptions o;
    o.weights = projection_weights(sp, {i}, 1e-6, 30);
    const optimize::ProjectionResult p = optimize::project(sp.constraints, t, sp.initial, sp.lower, sp.upper, {}, o);
    ASSERT_TRUE(p.done) << parameter << ": " << p.message;
    const ModifyResult m = modify_part(*part, model, sp, p.p);
    ASSERT_TRUE(m.done) << parameter << ": " << m.message;
    const Primitive c = build_face_model(*m.part).faces[lateral].primitive;
    const double v = occt_mass_properties(*m.part).volume, ref = closed_form(c);
    std::printf("pointed cone %s %+g: OCCT volume %.9f, closed form %.9f (relative %.1e)\n", parameter.c_str(), delta, v,
                ref, std::abs(v - ref) / ref);
    EXPECT_NEAR(v, ref, 1e-13 * ref) << parameter;  // measured 0 and 1.9e-16
    EXPECT_GT(std::abs(v - M_PI * 100 * 20 / 3), 10) << parameter;  // the change is not lost
  }
}

TEST(ShapeDerivatives, BoundaryQuadratureMatchesOcctMoments) {
  for (const std::string name : {"l_bracket", "wheel", "wrench", "housing"}) {
    PartSetup s(name);
    const MomentDerivatives md = moment_derivatives(*s.part, s.sp, s.sp.initial);
    const Moments ref = occt_moments(*s.part);
    for (int k = 0; k < 10; ++k)
      EXPECT_NEAR(md.moments[k], ref[k], 1e-8 * std::abs(ref[0]) * (k == 0 ? 1 : k < 4 ? 100 : 1e4)) << name << " " << k;
  }
}

// A blind hole (r = 5, from the top z = 20 of a 40 x 40 x 20 block down to z = 10) deepened by
// moving its bottom plane: OCCT's volume of the written part against the closed form at every
// depth, then through the block's bottom face. Found: below z = 1.4 the seam vertex kept its
// old place (a vertex moved at most 0.25 (1 + |P|), here 8.6 mm) and the part's volume was
// wrong by 1.5 % while BRepCheck_Analyzer passed it; and a bottom pushed through the far wall
// gives a solid BRepCheck_Analyzer passes too (faces crossing away from shared edges).
TEST(ShapeModify, BlindHoleDeepensToTheClosedFormAndIsRejectedThroughTheFarWall) {
  const TopoDS_Shape block = BRepPrimAPI_MakeBox(40, 40, 20).Shape();
  const TopoDS_Shape drill = BRepPrimAPI_MakeCylinder(gp_Ax2(gp_Pnt(20, 20, 10), gp_Dir(0, 0, 1)), 5, 20).Shape();
  const auto part = make_part(BRepAlgoAPI_Cut(block, drill).Shape(), "blind hole block");
  const FaceModel model = build_face_model(*part);
  const ShapeParameters sp = build_shape_parameters(model);
  const int hole_floor = plane_at(model, Vec3::UnitZ(), 10), block_bottom = plane_at(model, Vec3::UnitZ(), 0);
  const int hole = cylinder_at(model, 5, 20, 20);
  const int d = parameter_index(sp, hole_floor, "offset");
  const double sign = sp.initial[d] > 0 ? 1 : -1;  // offset = n · point, n = ±z
  const double v0 = 40 * 40 * 20 - M_PI * 25 * 10;
  ASSERT_NEAR(occt_mass_properties(*part).volume, v0, 1e-9 * v0);
  auto deepened = [&](double z, const ModifyOptions& options = {}) {
    // Through the projection, as the optimizer does (it also moves the hole's radius by about
    // 1e-7: the seam vertex then has two moved faces).
    Eigen::VectorXd t = sp.initial;
    t[d] = sign * z;
    optimize::ProjectionOptions o;
    o.weights = projection_weights(sp, {d}, 1e-6, 60);
    const optimize::ProjectionResult p = optimize::project(sp.constraints, t, sp.initial, sp.lower, sp.upper, {}, o);
    EXPECT_TRUE(p.done) << p.message;
    return modify_part(*part, model, sp, p.p, options);
  };
  for (const double z : {8.0, 5.0, 1.5, 1.0, 0.5, 0.01}) {
    const ModifyResult m = deepened(z);
    ASSERT_TRUE(m.done) << "z = " << z << ": " << m.message;
    // The radius as written (the face model of the result), the floor height from the part.
    const double r = build_face_model(*m.part).faces[hole].primitive.radius;
    EXPECT_NEAR(r, 5, 2e-7);
    EXPECT_NEAR(occt_mass_properties(*m.part).volume, 40 * 40 * 20 - M_PI * r * r * (20 - z), 1e-9 * v0) << "z = " << z;
  }
  for (const double z : {0.0, -2.0}) {
    const ModifyResult m = deepened(z);
    EXPECT_FALSE(m.done) << "z = " << z;
    std::printf("floor at z = %g: %s\n", z, m.message.c_str());
    EXPECT_NE(m.message.find("intersects itself: self-interference between"), std::string::npos) << m.message;
    EXPECT_NE(m.message.find("face " + std::to_string(block_bottom)), std::string::npos) << m.message;
    if (z < 0)  // the hole's wall crosses the bottom (at z = 0 its rim touches it: also "face 4 and face 6")
      EXPECT_NE(m.message.find("face " + std::to_string(hole)), std::string::npos) << m.message;
    // What catches it: without the self-interference test the write-back accepts the part.
    ModifyOptions unchecked;
    unchecked.check_self_interference = false;
    EXPECT_TRUE(deepened(z, unchecked).done) << "z = " << z;
  }
}

// d moments / d p̃ (Hadamard, chained through dp⊥/dp̃) against central differences of OCCT's
// mass properties of the written-back parts.
TEST(ShapeDerivatives, GradientsMatchFiniteDifferencesOfOcctMassProperties) {
  struct Case {
    std::string part;
    std::function<int(const PartSetup&)> index;
  };
  const std::vector<Case> cases = {
      {"l_bracket", [](const PartSetup& s) { return parameter_index(s.sp, cylinder_at(s.model, 4, 40, 12), "radius"); }},
      {"l_bracket", [](const PartSetup& s) { return parameter_index(s.sp, plane_at(s.model, Vec3::UnitZ(), 8), "offset"); }},
      {"l_bracket", [](const PartSetup& s) { return parameter_index(s.sp, fillet_r5(s.model), "radius"); }},
      {"wheel", [](const PartSetup& s) { return parameter_index(s.sp, cylinder_at(s.model, 50, 0, 0), "radius"); }},
      {"wrench", [](const PartSetup& s) { return parameter_index(s.sp, cylinder_at(s.model, 5, 0, 0), "axis point x"); }},
      {"housing", [](const PartSetup& s) { return parameter_index(s.sp, plane_at(s.model, Vec3::UnitX(), 10), "offset"); }},
      {"countersunk_pin_block", [](const PartSetup& s) {
         return parameter_index(s.sp, find_face(s.model, SurfaceType::cone, [](const Primitive&) { return true; }), "half-angle");
       }},
      {"countersunk_pin_block", [](const PartSetup& s) {
         return parameter_index(s.sp, find_face(s.model, SurfaceType::cone, [](const Primitive&) { return true; }), "radius");
       }},
      {"countersunk_pin_block", [](const PartSetup& s) {  // the coaxial countersink follows
         return parameter_index(s.sp, cylinder_at(s.model, 4, 15, 20), "axis point y");
       }},
      {"countersunk_pin_block", [](const PartSetup& s) {
         return parameter_index(s.sp, find_face(s.model, SurfaceType::sphere, [](const Primitive&) { return true; }), "radius");
       }},
      {"countersunk_pin_block", [](const PartSetup& s) {
         return parameter_index(s.sp, find_face(s.model, SurfaceType::sphere, [](const Primitive&) { return true; }), "centre z");
       }},
  };
  for (const Case& c : cases) {
    PartSetup s(c.part);
    const int i = c.index(s);
    const MomentDerivatives md = moment_derivatives(*s.part, s.sp, s.start.p);  // the part as read: p = p⊥ to 1e-6
    const optimize::ProjectionResult base = s.projected({{i, s.start.p[i]}});
    const optimize::ProjectionDerivative D =
        optimize::projection_derivative(s.sp.constraints, base, s.sp.lower, s.sp.upper, s.weights({i}));
    const Eigen::VectorXd exact = md.gradient * D.jacobian.col(i);
    const double h = 1e-3;
    Moments m[2];
    for (int side = 0; side < 2; ++side) {
      const optimize::ProjectionResult p = s.projected({{i, s.start.p[i] + (side ? -h : h)}});
      ASSERT_TRUE(p.done) << c.part << " " << s.sp.names[i];
      const ModifyResult mod = modify_part(*s.part, s.model, s.sp, p.p);
      ASSERT_TRUE(mod.done) << c.part << " " << s.sp.names[i] << ": " << mod.message;
      m[side] = occt_moments(*mod.part);
    }
    const Moments fd = (m[0] - m[1]) / (2 * h);
    for (int k = 0; k < 10; ++k) {
      // Scale: the largest |d moment| of the same degree (0, 1, 2).
      const int lo = k == 0 ? 0 : k < 4 ? 1 : 4, n = k == 0 ? 1 : k < 4 ? 3 : 6;
      const double scale = std::max(fd.segment(lo, n).cwiseAbs().maxCoeff(), 1e-6 * fd.cwiseAbs().maxCoeff());
      EXPECT_LE(std::abs(exact[k] - fd[k]), 1e-4 * scale) << c.part << " " << s.sp.names[i] << " moment " << k
                                                           << ": exact " << exact[k] << " FD " << fd[k];
    }
  }
}

TEST(ShapeOptimization, WheelCentreOfMassMovesTowardsTheAxisWithValidParts) {
  const auto part = read_part(sample("wheel"));
  const FaceModel model = build_face_model(*part);
  ShapeOptimizationOptions o;
  o.objective.type = "center_of_mass";
  o.objective.axis = Vec3::UnitZ();
  // Design: the offsets of the spoke side planes (normals with x or y components).
  const ShapeParameters sp = build_shape_parameters(model);
  for (const auto& b : sp.blocks)
    if (b.kind == optimize::PrimitiveKind::plane && std::abs(sp.initial[b.offset + 2]) < 0.5)
      o.design.push_back(b.offset + 3);
  ASSERT_EQ(o.design.size(), 10u);
  o.lbfgs.max_iterations = 4;
  o.relative_bound = 0.05;
  const ShapeOptimizationResult r = optimize_shape(*part, o);
  ASSERT_TRUE(r.part) << r.message;
  EXPECT_LT(r.final_objective, 0.5 * r.initial_objective) << r.message;
  // Independent: OCCT's centre of mass of the returned part.
  const auto props = occt_mass_properties(*r.part);
  EXPECT_NEAR(std::hypot(props.center.x(), props.center.y()), std::sqrt(r.final_objective), 1e-6);
  EXPECT_LT(r.tangency_residual_max, 1e-9);
  for (size_t k = 1; k < r.iterations.size(); ++k) EXPECT_LT(r.iterations[k].objective, r.iterations[k - 1].objective);
}

// "inertia_alignment" (|I a − (aᵀ I a) a|² / (tr I)², from the boundary quadrature's moments, as
// optimize_shape evaluates it) against OCCT's principal axes and moments (GProp_PrincipalProps:
// I = Σ Iₖ vₖ vₖᵀ, an eigen-decomposition the objective never makes): the same value for the spin
// axis z on parts as they are and tilted, and zero when the axis is OCCT's principal axis.
TEST(ShapeOptimization, InertiaAlignmentAgreesWithOcctsPrincipalAxes) {
  double worst = 0, worst_on_axis = 0;
  for (const std::string name : {"wheel", "housing", "wrench"})
    for (double tilt : {0.0, 7.0, 25.0}) {
      const auto base = read_part(sample(name));
      const auto part = tilt == 0 ? base : rotated_part(*base, Vec3(1, 2, 3), Vec3(1, 0.4, 0), tilt);
      const ShapeParameters sp = build_shape_parameters(build_face_model(*part));
      const MomentDerivatives md = moment_derivatives(*part, sp, sp.initial);
      GProp_GProps g;
      BRepGProp::VolumeProperties(part->shape, g, 1e-12, Standard_True);
      const GProp_PrincipalProps pp = g.PrincipalProperties();
      double I[3];
      pp.Moments(I[0], I[1], I[2]);
      const gp_Vec v[3] = {pp.FirstAxisOfInertia(), pp.SecondAxisOfInertia(), pp.ThirdAxisOfInertia()};
      Eigen::Matrix3d inertia = Eigen::Matrix3d::Zero();
      for (int k = 0; k < 3; ++k) {
        const Vec3 e(v[k].X(), v[k].Y(), v[k].Z());
        inertia += I[k] * e * e.transpose();
      }
      auto occt_alignment = [&](const Vec3& a) {
        const Vec3 off = inertia * a - a.dot(inertia * a) * a;
        return off.squaredNorm() / std::pow(inertia.trace(), 2);
      };
      ObjectiveSpec spec;
      spec.type = "inertia_alignment";
      spec.axis = Vec3::UnitZ();
      const double ours = objective_from_moments(spec, md.moments, nullptr);
      const double occt = occt_alignment(Vec3::UnitZ());
      // Along each of OCCT's principal axes the objective vanishes.
      double on_axis = 0;
      for (int k = 0; k < 3; ++k) {
        spec.axis = Vec3(v[k].X(), v[k].Y(), v[k].Z());
        on_axis = std::max(on_axis, objective_from_moments(spec, md.moments, nullptr));
      }
      std::printf("%-8s tilted %4.1f deg: alignment %.6e, OCCT's principal axes %.6e (relative %.1e); along "
                  "OCCT's principal axes %.1e\n",
                  name.c_str(), tilt, ours, occt, std::abs(ours - occt) / std::max(occt, 1e-300), on_axis);
      if (tilt > 0) EXPECT_GT(occt, 1e-5) << name;  // the tilted parts are far from aligned
      worst = std::max(worst, std::abs(ours - occt) / std::max(occt, 1e-12));
      worst_on_axis = std::max(worst_on_axis, on_axis);
    }
  std::printf("worst relative difference %.1e, worst value along a principal axis %.1e\n", worst, worst_on_axis);
  // Relative to OCCT's value, floored at 1e-12: the wheel and wrench as they are are aligned
  // (both values below 1e-28). Measured 8.0e-11, at the housing as it is (value 4.1e-6).
  EXPECT_LT(worst, 5e-10);
  EXPECT_LT(worst_on_axis, 3e-24);  // measured 2.4e-25: round-off of the off-axis inertia, squared
}

}  // namespace
}  // namespace parafab::occ
