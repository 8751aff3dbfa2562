// Tests of the face model (thesis §6.2.1, §6.5.1): surface types and parameters of the sample
// parts, projective NURBS reproducing the B-rep surfaces, trimming loops, edge continuity, and
// tangency relations (Fig. 6.11) whose residuals vanish on the actual parts.
#include "face_model.h"

#include <gtest/gtest.h>

#include <BRepAdaptor_Curve.hxx>
#include <BRepAdaptor_Surface.hxx>
#include <BRepAlgoAPI_Cut.hxx>
#include <BRepAlgoAPI_Fuse.hxx>
#include <BRepClass3d_SolidClassifier.hxx>
#include <BRepFilletAPI_MakeFillet.hxx>
#include <BRepPrimAPI_MakeBox.hxx>
#include <BRepPrimAPI_MakeCone.hxx>
#include <BRepPrimAPI_MakeCylinder.hxx>
#include <BRepPrimAPI_MakeSphere.hxx>
#include <BRepPrimAPI_MakeTorus.hxx>
#include <BRep_Tool.hxx>
#include <Eigen/Geometry>
#include <GeomAPI_ProjectPointOnSurf.hxx>
#include <Geom_BSplineSurface.hxx>
#include <TColStd_Array1OfInteger.hxx>
#include <TColStd_Array1OfReal.hxx>
#include <TColStd_Array2OfReal.hxx>
#include <TColgp_Array2OfPnt.hxx>
#include <TopExp_Explorer.hxx>
#include <TopoDS.hxx>
#include <gp.hxx>
#include <cmath>
#include <map>
#include <set>

#include "common/error.h"
#include "occt_shape.h"
#include "part_reader.h"

namespace parafab::occ {
namespace {

std::string sample(const std::string& name) {
  return std::string(PARAFAB_SAMPLES_DIR) + "/parts/" + name + ".step";
}

const std::vector<std::string> kSamples = {"box",  "cylinder",   "l_bracket", "wrench",
                                           "ring", "half_torus", "wheel",     "housing", "countersunk_pin_block"};

double part_size(const PartShape& part) {
  const PartInfo info = part_info(part);
  return (info.bbox_max - info.bbox_min).norm();
}

std::map<std::string, int> type_counts(const FaceModel& m) {
  std::map<std::string, int> out;
  for (const auto& f : m.faces) ++out[to_string(f.primitive.type)];
  return out;
}

std::multiset<double> radii(const FaceModel& m, SurfaceType type) {
  std::multiset<double> out;
  for (const auto& f : m.faces)
    if (f.primitive.type == type) out.insert(std::round(f.primitive.radius * 1e6) / 1e6);
  return out;
}

std::vector<const TangencyRelation*> relations_of(const FaceModel& m, const std::string& kind) {
  std::vector<const TangencyRelation*> out;
  for (const auto& r : m.relations)
    if (r.kind == kind) out.push_back(&r);
  return out;
}

Vec3 vec(const gp_Pnt& p) { return {p.X(), p.Y(), p.Z()}; }

// The NURBS as an OCCT surface, to check our evaluation against OCCT's.
Handle(Geom_BSplineSurface) occt_surface(const NurbsSurface& s) {
  auto split = [](const std::vector<double>& flat, std::vector<double>& k, std::vector<int>& m) {
    for (double x : flat)
      if (!k.empty() && x == k.back())
        ++m.back();
      else
        k.push_back(x), m.push_back(1);
  };
  std::vector<double> ku, kv;
  std::vector<int> mu, mv;
  split(s.knots_u, ku, mu);
  split(s.knots_v, kv, mv);
  TColStd_Array1OfReal UK(1, static_cast<int>(ku.size())), VK(1, static_cast<int>(kv.size()));
  TColStd_Array1OfInteger UM(1, static_cast<int>(mu.size())), VM(1, static_cast<int>(mv.size()));
  for (size_t i = 0; i < ku.size(); ++i) UK(i + 1) = ku[i], UM(i + 1) = mu[i];
  for (size_t i = 0; i < kv.size(); ++i) VK(i + 1) = kv[i], VM(i + 1) = mv[i];
  TColgp_Array2OfPnt P(1, s.count_u, 1, s.count_v);
  TColStd_Array2OfReal W(1, s.count_u, 1, s.count_v);
  for (int i = 0; i < s.count_u; ++i)
    for (int j = 0; j < s.count_v; ++j) {
      const Eigen::Vector4d& q = s.pole(i, j);
      P(i + 1, j + 1) = gp_Pnt(q[0] / q[3], q[1] / q[3], q[2] / q[3]);
      W(i + 1, j + 1) = q[3];
    }
  return new Geom_BSplineSurface(P, W, UK, VK, UM, VM, s.degree_u, s.degree_v);
}

TEST(FaceModel, BoxHasSixPlanesAndTwelveSharpRightAngledEdges) {
  const auto part = read_part(sample("box"));
  const FaceModel m = build_face_model(*part);
  EXPECT_EQ(type_counts(m), (std::map<std::string, int>{{"plane", 6}}));
  ASSERT_EQ(m.edges.size(), 12u);
  for (const auto& e : m.edges) {
    EXPECT_NEAR(e.max_angle_deg, 90.0, 1e-9);
    EXPECT_FALSE(e.tangent);
    EXPECT_FALSE(e.seam);
    EXPECT_EQ(e.continuity, "C0");
    EXPECT_NE(e.faces[0], e.faces[1]);
  }
  EXPECT_TRUE(m.relations.empty());
  for (const auto& f : m.faces) {
    EXPECT_NEAR(f.primitive.axis.norm(), 1.0, 1e-12);
    EXPECT_EQ(f.nurbs.degree_u, 1);
    EXPECT_EQ(f.nurbs.degree_v, 1);
    EXPECT_EQ(f.loops.size(), 1u);
    EXPECT_EQ(f.loops[0].edges.size(), 4u);
  }
  double area = 0;
  for (const auto& f : m.faces) area += f.area;
  EXPECT_NEAR(area, 2 * (40 * 30 + 40 * 20 + 30 * 20), 1e-6);
}

TEST(FaceModel, PrimitiveParametersMatchMakeParts) {
  const FaceModel cyl = build_face_model(*read_part(sample("cylinder")));
  EXPECT_EQ(type_counts(cyl), (std::map<std::string, int>{{"cylinder", 1}, {"plane", 2}}));
  for (const auto& f : cyl.faces)
    if (f.primitive.type == SurfaceType::cylinder) {
      EXPECT_NEAR(f.primitive.radius, 15, 1e-12);
      EXPECT_NEAR(std::abs(f.primitive.axis.z()), 1, 1e-12);
      EXPECT_NEAR(f.primitive.location.head<2>().norm(), 0, 1e-12);
    }
  int seams = 0;
  for (const auto& e : cyl.edges)
    if (e.seam) {
      ++seams;
      EXPECT_EQ(e.faces[0], e.faces[1]);
      EXPECT_TRUE(e.tangent);
    }
  EXPECT_EQ(seams, 1);
  EXPECT_TRUE(cyl.relations.empty());  // a seam is no tangency between two faces

  const FaceModel ring = build_face_model(*read_part(sample("ring")));
  EXPECT_EQ(radii(ring, SurfaceType::cylinder), (std::multiset<double>{20, 30}));
  const FaceModel torus = build_face_model(*read_part(sample("half_torus")));
  EXPECT_EQ(type_counts(torus), (std::map<std::string, int>{{"plane", 2}, {"torus", 1}}));
  for (const auto& f : torus.faces)
    if (f.primitive.type == SurfaceType::torus) {
      EXPECT_NEAR(f.primitive.major_radius, 30, 1e-12);
      EXPECT_NEAR(f.primitive.radius, 8, 1e-12);
    }
  const FaceModel bracket = build_face_model(*read_part(sample("l_bracket")));
  EXPECT_EQ(radii(bracket, SurfaceType::cylinder), (std::multiset<double>{4, 4, 5, 12}));  // holes, fillets
  const FaceModel wheel = build_face_model(*read_part(sample("wheel")));
  EXPECT_EQ(type_counts(wheel), (std::map<std::string, int>{{"cylinder", 12}, {"plane", 12}}));
  EXPECT_TRUE(wheel.relations.empty());
}

// The projective NURBS, evaluated by ParaFab, equals OCCT's evaluation of the same data, lies
// on the face's B-rep surface (after perspective division), and has consistent derivatives.
TEST(FaceModel, NurbsReproducesTheBrepSurfaces) {
  for (const auto& name : kSamples) {
    SCOPED_TRACE(name);
    const auto part = read_part(sample(name));
    const double size = part_size(*part);
    const FaceModel m = build_face_model(*part);
    for (const auto& f : m.faces) {
      SCOPED_TRACE("face " + std::to_string(f.index) + " " + to_string(f.primitive.type));
      const Handle(Geom_BSplineSurface) reference = occt_surface(f.nurbs);
      const Handle(Geom_Surface) brep = BRep_Tool::Surface(part->face(f.index));
      const BRepAdaptor_Surface adaptor(part->face(f.index));
      const auto [u0, u1, v0, v1] = f.uv_bounds;
      for (int a = 0; a <= 4; ++a)
        for (int b = 0; b <= 4; ++b) {
          const double u = u0 + (u1 - u0) * a / 4, v = v0 + (v1 - v0) * b / 4;
          const Eigen::Vector4d q = evaluate_projective(f.nurbs, u, v);
          Vec3 X, Xu, Xv;
          evaluate(f.nurbs, u, v, X, Xu, Xv);
          EXPECT_LT((q.head<3>() / q[3] - X).norm(), 1e-12 * size);
          EXPECT_LT((X - vec(reference->Value(u, v))).norm(), 1e-9 * size);
          GeomAPI_ProjectPointOnSurf onto(gp_Pnt(X.x(), X.y(), X.z()), brep);
          ASSERT_GT(onto.NbPoints(), 0);
          EXPECT_LT(onto.LowerDistance(), 1e-9 * size);
          if (f.primitive.type == SurfaceType::plane)  // same parameterization: same point
            EXPECT_LT((X - vec(adaptor.Value(u, v))).norm(), 1e-9 * size);
          const double hu = 1e-6 * (u1 - u0), hv = 1e-6 * (v1 - v0);
          if (a > 0 && a < 4 && b > 0 && b < 4) {
            Vec3 Xp, Xm, d1, d2;
            evaluate(f.nurbs, u + hu, v, Xp, d1, d2);
            evaluate(f.nurbs, u - hu, v, Xm, d1, d2);
            EXPECT_LT((Xu - (Xp - Xm) / (2 * hu)).norm(), 1e-5 * (1 + Xu.norm()));
            evaluate(f.nurbs, u, v + hv, Xp, d1, d2);
            evaluate(f.nurbs, u, v - hv, Xm, d1, d2);
            EXPECT_LT((Xv - (Xp - Xm) / (2 * hv)).norm(), 1e-5 * (1 + Xv.norm()));
          }
        }
    }
  }
}

double signed_area(const std::vector<Vec2>& poly) {
  double a = 0;
  for (size_t i = 0; i + 1 < poly.size(); ++i)
    a += poly[i].x() * poly[i + 1].y() - poly[i + 1].x() * poly[i].y();
  return a / 2;
}

// Loops are closed uv polylines on the NURBS, outer first and counter-clockwise, holes
// clockwise; just inside the outer loop, −σ_u × σ_v (reversed) or +σ_u × σ_v points out of the solid.
TEST(FaceModel, TrimmingLoopsAndOrientationAreConsistent) {
  for (const auto& name : kSamples) {
    SCOPED_TRACE(name);
    const auto part = read_part(sample(name));
    const double size = part_size(*part);
    const FaceModel m = build_face_model(*part);
    BRepClass3d_SolidClassifier classify(part->shape);
    for (const auto& f : m.faces) {
      SCOPED_TRACE("face " + std::to_string(f.index));
      ASSERT_FALSE(f.loops.empty());
      EXPECT_TRUE(f.loops[0].outer);
      for (size_t k = 0; k < f.loops.size(); ++k) {
        const TrimLoop& loop = f.loops[k];
        EXPECT_EQ(loop.outer, k == 0);
        EXPECT_EQ(loop.uv.front(), loop.uv.back());
        EXPECT_FALSE(loop.edges.empty());
        for (int e : loop.edges) EXPECT_TRUE(e >= 0 && e < static_cast<int>(m.edges.size()));
        EXPECT_GT((k == 0 ? 1 : -1) * signed_area(loop.uv), 0);
        const double span = std::max(f.uv_bounds[1] - f.uv_bounds[0], f.uv_bounds[3] - f.uv_bounds[2]);
        for (size_t i = 0; i + 1 < loop.uv.size(); ++i)  // no jump across a seam
          EXPECT_LE((loop.uv[i + 1] - loop.uv[i]).norm(), span * (1 + 1e-9));
      }
      // A point just inside the outer loop, left of its first segment.
      const Vec2 p0 = f.loops[0].uv[0], p1 = f.loops[0].uv[1];
      const Vec2 t = (p1 - p0).normalized();
      const Vec2 uv = (p0 + p1) / 2 + 1e-2 * (p1 - p0).norm() * Vec2(-t.y(), t.x());
      Vec3 X, Xu, Xv;
      evaluate(f.nurbs, uv.x(), uv.y(), X, Xu, Xv);
      const Vec3 n = (f.reversed ? -1.0 : 1.0) * Xu.cross(Xv).normalized();
      const double eps = 1e-4 * size;
      classify.Perform(gp_Pnt(X.x() + eps * n.x(), X.y() + eps * n.y(), X.z() + eps * n.z()), 1e-9);
      EXPECT_EQ(classify.State(), TopAbs_OUT);
      classify.Perform(gp_Pnt(X.x() - eps * n.x(), X.y() - eps * n.y(), X.z() - eps * n.z()), 1e-9);
      EXPECT_EQ(classify.State(), TopAbs_IN);
    }
  }
  const FaceModel ring = build_face_model(*read_part(sample("ring")));
  for (const auto& f : ring.faces)
    EXPECT_EQ(f.loops.size(), f.primitive.type == SurfaceType::plane ? 2u : 1u);  // annulus: outer + hole
}

// Every detected relation holds on the actual part, and re-evaluates to the same residuals.
void expect_relations_hold(const FaceModel& m, double tolerance) {
  for (const auto& r : m.relations) {
    SCOPED_TRACE(r.kind + " faces " + std::to_string(r.faces[0]) + ", " + std::to_string(r.faces[1]));
    ASSERT_EQ(r.equations.size(), r.residuals.size());
    EXPECT_FALSE(r.edges.empty());
    for (double x : r.residuals) EXPECT_LT(std::abs(x), tolerance);
    EXPECT_EQ(tangency_residuals(r, m.faces[r.faces[0]], m.faces[r.faces[1]]), r.residuals);
    for (int e : r.edges) EXPECT_EQ(m.edges[e].tangent, r.kind != "coaxial");  // coaxial: sharp edges
  }
}

TEST(FaceModel, FilletedBracketHasFourPlaneCylinderTangencies) {
  const FaceModel m = build_face_model(*read_part(sample("l_bracket")));
  ASSERT_EQ(m.relations.size(), 4u);
  expect_relations_hold(m, 1e-9);
  std::multiset<double> fillet_radii;
  for (const auto& r : m.relations) {
    EXPECT_EQ(r.kind, "plane-cylinder");
    const FaceInfo& plane = m.faces[r.faces[0]];
    const FaceInfo& cyl = m.faces[r.faces[1]];
    EXPECT_EQ(plane.primitive.type, SurfaceType::plane);
    fillet_radii.insert(cyl.primitive.radius);
    for (int e : r.edges) EXPECT_EQ(m.edges[e].continuity, "G1");
    const std::string i = std::to_string(plane.index), j = std::to_string(cyl.index);
    EXPECT_EQ(r.equations[1], "dot(n" + i + ", d" + j + ") = 0");
    EXPECT_NE(r.equations[0].find("dot(p" + i + " - c" + j + ", n" + i + ") - r" + j + " = 0"),
              std::string::npos);
    // Re-evaluation for changed parameters: a larger radius breaks the distance equation only.
    FaceInfo bigger = cyl;
    bigger.primitive.radius += 0.25;
    const auto res = tangency_residuals(r, plane, bigger);
    EXPECT_NEAR(res[0], -0.25, 1e-9);
    EXPECT_NEAR(res[1], 0.0, 1e-12);
  }
  EXPECT_EQ(fillet_radii, (std::multiset<double>{5, 5, 12, 12}));
  for (const auto& e : m.edges)
    if (!e.tangent) EXPECT_NEAR(e.max_angle_deg, 90.0, 1e-6);
}

TEST(FaceModel, RelationsHoldOnEverySample) {
  std::map<std::string, int> kinds;
  for (const auto& name : kSamples) {
    SCOPED_TRACE(name);
    const auto part = read_part(sample(name));
    const FaceModel m = build_face_model(*part);
    expect_relations_hold(m, 1e-9 * part_size(*part));
    for (const auto& r : m.relations) ++kinds[name + ":" + r.kind];
  }
  EXPECT_EQ(kinds["wrench:plane-cylinder"], 10);
  EXPECT_EQ(kinds["wrench:cylinder-cylinder"], 6);  // fillets on the head, ring and jaw
  EXPECT_EQ(kinds["housing:plane-cylinder"], 16);   // rounded corners, outside and inside
  EXPECT_EQ(kinds["housing:plane-torus"], 1);       // boss base fillet
  EXPECT_EQ(kinds["housing:cylinder-torus"], 1);
  EXPECT_EQ(kinds.count("wrench:g1") + kinds.count("housing:g1"), 0u);
  EXPECT_EQ(kinds["countersunk_pin_block:cylinder-sphere"], 1);  // the pin's cap
  EXPECT_EQ(kinds["countersunk_pin_block:coaxial"], 1);          // the countersink and its hole
  int coaxial = 0;
  for (const auto& [key, n] : kinds) coaxial += key.find(":coaxial") != std::string::npos ? n : 0;
  EXPECT_EQ(coaxial, 1);  // no other sample has faces of revolution meeting along a sharp edge
  for (const std::string name : {"flange", "plate_holes", "blind_hole_block", "bump_block", "l_bracket_holes5"})
    for (const auto& r : build_face_model(*read_part(sample(name))).relations) EXPECT_NE(r.kind, "coaxial") << name;
}

// Coaxial faces of revolution meeting along a sharp edge (design intent, not a tangency), every
// part turned 11° off the axes: a shaft (cylinder r 10) with a chamfer (cone to r 8) at its top
// and a cross hole (r 3, along x) through it. The cylinder and the cone are coaxial; the cross
// hole meets the shaft along sharp saddle curves on a perpendicular axis: no relation.
TEST(FaceModel, ChamferAndBallAreCoaxialWithTheirShaftsAndHolesOffTheAxisAreNot) {
  TopoDS_Shape shaft = BRepPrimAPI_MakeCylinder(gp_Ax2(gp_Pnt(0, 0, 0), gp::DZ()), 10, 20).Shape();
  shaft = BRepAlgoAPI_Fuse(shaft, BRepPrimAPI_MakeCone(gp_Ax2(gp_Pnt(0, 0, 20), gp::DZ()), 10, 8, 2).Shape()).Shape();
  shaft = BRepAlgoAPI_Cut(shaft, BRepPrimAPI_MakeCylinder(gp_Ax2(gp_Pnt(-15, 0, 10), gp::DX()), 3, 30).Shape()).Shape();
  const auto straight = make_part(shaft, "chamfered shaft");
  const auto part = rotated_part(*straight, Vec3(1, 2, 3), Vec3(1, 2, 3).normalized(), 11);
  const FaceModel m = build_face_model(*part);
  int coaxial = 0;
  for (const TangencyRelation& r : m.relations) {
    EXPECT_EQ(r.kind, "coaxial");
    if (r.kind != "coaxial") continue;
    ++coaxial;
    EXPECT_EQ(m.faces[r.faces[0]].primitive.type, SurfaceType::cylinder);
    EXPECT_EQ(m.faces[r.faces[1]].primitive.type, SurfaceType::cone);
    EXPECT_EQ(r.equations.size(), 6u);
    for (double x : r.residuals) EXPECT_LT(std::abs(x), 1e-12);
  }
  expect_relations_hold(m, 1e-12);
  EXPECT_EQ(coaxial, 1);
  int cylinders = 0;  // the shaft and the cross hole
  for (const FaceInfo& f : m.faces) cylinders += f.primitive.type == SurfaceType::cylinder;
  EXPECT_EQ(cylinders, 2);

  // A parallel hole off the axis breaking through the shaft's side (r 3 at x = 9): the axes are
  // parallel, the centre is not on the shaft's axis: no relation. A ball (r 8) on a thinner
  // shaft (r 5) meets it along a sharp circle with its centre on the axis: coaxial, sphere as b
  // (three equations).
  TopoDS_Shape side = BRepPrimAPI_MakeCylinder(gp_Ax2(gp_Pnt(0, 0, 0), gp::DZ()), 10, 20).Shape();
  side = BRepAlgoAPI_Cut(side, BRepPrimAPI_MakeCylinder(gp_Ax2(gp_Pnt(9, 0, -5), gp::DZ()), 3, 30).Shape()).Shape();
  const FaceModel off = build_face_model(*rotated_part(*make_part(side, "notched shaft"), Vec3(1, 2, 3),
                                                       Vec3(1, 2, 3).normalized(), 11));
  EXPECT_TRUE(off.relations.empty()) << off.relations.front().kind;
  TopoDS_Shape knob = BRepPrimAPI_MakeCylinder(gp_Ax2(gp_Pnt(0, 0, 0), gp::DZ()), 5, 20).Shape();
  knob = BRepAlgoAPI_Fuse(knob, BRepPrimAPI_MakeSphere(gp_Pnt(0, 0, 24), 8).Shape()).Shape();
  const FaceModel ball = build_face_model(*rotated_part(*make_part(knob, "ball knob"), Vec3(1, 2, 3),
                                                        Vec3(1, 2, 3).normalized(), 11));
  expect_relations_hold(ball, 1e-12);
  ASSERT_EQ(ball.relations.size(), 1u);
  EXPECT_EQ(ball.relations[0].kind, "coaxial");
  EXPECT_EQ(ball.faces[ball.relations[0].faces[0]].primitive.type, SurfaceType::cylinder);
  EXPECT_EQ(ball.faces[ball.relations[0].faces[1]].primitive.type, SurfaceType::sphere);
  EXPECT_EQ(ball.relations[0].equations.size(), 3u);
}

std::shared_ptr<const PartShape> part_of(const TopoDS_Shape& shape) { return make_part(shape, "test shape"); }

// A boss on a plate, its foot filleted by OCCT, the part turned by 11°: the boss's cylinder and the fillet's torus are
// full-turn faces whose u bounds start a round-off before the periodic surface's knot (the
// cylinder's at −1.8e-15, ending at 2π), which made the segmentation to the face's bounds
// fail ("face 6: NURBS form failed: NCollection_Array2::Allocate"). A full turn now takes the
// surface's own period; the NURBS forms reproduce the B-rep and the fillet's two tangencies
// are found with their closed forms.
TEST(FaceModel, FullTurnFacesOfAFilletedBoss) {
  const TopoDS_Shape plate = BRepPrimAPI_MakeBox(60, 40, 8).Shape();
  const TopoDS_Shape boss = BRepPrimAPI_MakeCylinder(gp_Ax2(gp_Pnt(30, 20, 8), gp::DZ()), 8, 20).Shape();
  BRepAlgoAPI_Fuse fuse(plate, boss);
  ASSERT_TRUE(fuse.IsDone());
  BRepFilletAPI_MakeFillet fillet(fuse.Shape());
  for (TopExp_Explorer e(fuse.Shape(), TopAbs_EDGE); e.More(); e.Next()) {
    const BRepAdaptor_Curve c(TopoDS::Edge(e.Current()));
    if (c.GetType() == GeomAbs_Circle && std::abs(c.Circle().Location().Z() - 8) < 1e-9) fillet.Add(3, TopoDS::Edge(e.Current()));
  }
  ASSERT_EQ(fillet.NbContours(), 1);
  fillet.Build();
  ASSERT_TRUE(fillet.IsDone());
  // Turned off the axes, as the compliance tests turn parts against the grid.
  const auto part = rotated_part(*make_part(fillet.Shape(), "filleted boss"), Vec3(30, 20, 14), Vec3(1, 2, 3).normalized(), 11);
  const FaceModel m = build_face_model(*part);
  std::multiset<std::string> kinds;
  for (const auto& r : m.relations) kinds.insert(r.kind);
  EXPECT_EQ(kinds, (std::multiset<std::string>{"plane-torus", "cylinder-torus"}));
  int full_turns = 0;
  for (const auto& f : m.faces) {
    if (f.primitive.type != SurfaceType::cylinder && f.primitive.type != SurfaceType::torus) continue;
    EXPECT_NEAR(f.uv_bounds[1] - f.uv_bounds[0], 2 * M_PI, 1e-12);
    ++full_turns;
    for (int a = 0; a <= 8; ++a) {  // the NURBS form on the B-rep surface, all the way round
      Vec3 X, Xu, Xv;
      evaluate(f.nurbs, f.uv_bounds[0] + (f.uv_bounds[1] - f.uv_bounds[0]) * a / 8, 0.5 * (f.uv_bounds[2] + f.uv_bounds[3]), X, Xu, Xv);
      GeomAPI_ProjectPointOnSurf onto(gp_Pnt(X.x(), X.y(), X.z()), BRep_Tool::Surface(part->face(f.index)));
      ASSERT_GT(onto.NbPoints(), 0);
      EXPECT_LT(onto.LowerDistance(), 1e-9);
    }
  }
  EXPECT_EQ(full_turns, 2);
}

TEST(FaceModel, RoundedBoxHasCylinderSphereCorners) {
  const TopoDS_Shape box = BRepPrimAPI_MakeBox(20, 30, 40).Shape();
  BRepFilletAPI_MakeFillet fillet(box);
  for (TopExp_Explorer e(box, TopAbs_EDGE); e.More(); e.Next()) fillet.Add(3, TopoDS::Edge(e.Current()));
  const FaceModel m = build_face_model(*part_of(fillet.Shape()));
  expect_relations_hold(m, 1e-9);
  std::map<std::string, int> kinds;
  for (const auto& r : m.relations) ++kinds[r.kind];
  EXPECT_EQ(kinds["plane-cylinder"], 24);
  EXPECT_EQ(kinds["cylinder-sphere"], 24);
}

TEST(FaceModel, PipeElbowAndCapsule) {
  // Quarter torus (R 20, r 4) continued by a cylinder of the same radius.
  const TopoDS_Shape elbow = BRepPrimAPI_MakeTorus(20, 4, M_PI / 2).Shape();
  const TopoDS_Shape leg = BRepPrimAPI_MakeCylinder(gp_Ax2(gp_Pnt(20, 0, 0), -gp::DY()), 4, 15).Shape();
  const FaceModel pipe = build_face_model(*part_of(BRepAlgoAPI_Fuse(elbow, leg).Shape()));
  expect_relations_hold(pipe, 1e-9);
  ASSERT_EQ(relations_of(pipe, "cylinder-torus-pipe").size(), 1u);
  EXPECT_EQ(relations_of(pipe, "cylinder-torus-pipe")[0]->residuals.size(), 4u);

  // A cylinder (r 5) with a half sphere on top.
  const TopoDS_Shape body = BRepPrimAPI_MakeCylinder(5, 20).Shape();
  const TopoDS_Shape cap = BRepPrimAPI_MakeSphere(gp_Pnt(0, 0, 20), 5).Shape();
  const FaceModel capsule = build_face_model(*part_of(BRepAlgoAPI_Fuse(body, cap).Shape()));
  expect_relations_hold(capsule, 1e-9);
  EXPECT_FALSE(relations_of(capsule, "cylinder-sphere").empty());
}

TEST(FaceModel, VariableRadiusFilletGivesGenericG1Relations) {
  const TopoDS_Shape box = BRepPrimAPI_MakeBox(40, 30, 20).Shape();
  BRepFilletAPI_MakeFillet fillet(box);
  TopExp_Explorer e(box, TopAbs_EDGE);
  fillet.Add(2, 6, TopoDS::Edge(e.Current()));
  const FaceModel m = build_face_model(*part_of(fillet.Shape()));
  EXPECT_EQ(type_counts(m)["bspline"], 1);
  const auto g1 = relations_of(m, "g1");
  ASSERT_EQ(g1.size(), 2u);        // the fillet against each of the two planes
  expect_relations_hold(m, 1e-9);  // the fillet surface meets the planes with equal normals
  for (const auto* r : g1) {
    EXPECT_EQ(r->residuals.size(), 3 * r->samples.size());
    EXPECT_EQ(r->samples.size(), 9u * r->edges.size());
    EXPECT_NE(r->equations[0].find("cross(N"), std::string::npos);
  }
}

TEST(FaceModel, RelationFormulasVanishOnTangentConfigurations) {
  const double alpha = 0.5, h = 7;
  FaceInfo plane, cone, sphere, torus;
  plane.primitive.type = SurfaceType::plane;
  plane.primitive.location = Vec3(0, 3, 0);  // contains the apex (origin) ruling along (sin a, 0, cos a)
  plane.primitive.axis = Vec3(std::cos(alpha), 0, -std::sin(alpha));
  cone.primitive.type = SurfaceType::cone;
  cone.primitive.location = Vec3(0, 0, h);
  cone.primitive.axis = Vec3(0, 0, 1);
  cone.primitive.radius = h * std::tan(alpha);
  cone.primitive.semi_angle = alpha;
  TangencyRelation r;
  r.kind = "plane-cone";
  r.sign = -1;
  for (double x : tangency_residuals(r, plane, cone)) EXPECT_NEAR(x, 0, 1e-12);

  // Sphere (r 5) resting in a torus (R 6, r 2) along a circle: |centre to tube circle| = 5 + 2.
  sphere.primitive.type = SurfaceType::sphere;
  sphere.primitive.radius = 5;
  torus.primitive.type = SurfaceType::torus;
  torus.primitive.axis = Vec3(0, 0, 1);
  torus.primitive.major_radius = 6;
  torus.primitive.radius = 2;
  sphere.primitive.location = Vec3(0, 0, std::sqrt(49.0 - 36.0));
  r.kind = "sphere-torus";
  r.sign = 1;
  for (double x : tangency_residuals(r, sphere, torus)) EXPECT_NEAR(x, 0, 1e-12);

  EXPECT_THROW(tangency_residuals(r, plane, torus), Error);  // wrong face types
  r.kind = "plane-hyperboloid";
  EXPECT_THROW(tangency_residuals(r, plane, cone), Error);
}

}  // namespace
}  // namespace parafab::occ
