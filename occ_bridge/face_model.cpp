// Face model of a part (thesis §6.2.1, §6.5.1): primitives, NURBS patches and trimming loops
// (via BRepBuilderAPI_NurbsConvert, so loops and patches share parameters), edge continuity,
// and the look-up table of tangency relations between adjacent primitives (Fig. 6.11).
#include "face_model.h"

#include <BRepAdaptor_Surface.hxx>
#include <BRepBuilderAPI_NurbsConvert.hxx>
#include <BRepGProp.hxx>
#include <BRepTools.hxx>
#include <BRepTools_WireExplorer.hxx>
#include <BRep_Tool.hxx>
#include <Eigen/Geometry>
#include <GProp_GProps.hxx>
#include <Geom2dAdaptor_Curve.hxx>
#include <Geom2d_BSplineCurve.hxx>
#include <Geom2d_Curve.hxx>
#include <Geom_BSplineSurface.hxx>
#include <Standard_Failure.hxx>
#include <TopExp.hxx>
#include <TopExp_Explorer.hxx>
#include <TopTools_IndexedDataMapOfShapeListOfShape.hxx>
#include <TopoDS.hxx>
#include <TopoDS_Wire.hxx>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>

#include "common/error.h"
#include "occt_shape.h"

namespace parafab::occ {

namespace {

Vec3 vec(const gp_XYZ& p) { return {p.X(), p.Y(), p.Z()}; }

void set_frame(Primitive& p, const gp_Ax3& ax) {
  p.location = vec(ax.Location().XYZ());
  p.axis = vec(ax.Direction().XYZ());
  p.x_direction = vec(ax.XDirection().XYZ());
}

Primitive primitive_of(const TopoDS_Face& face) {
  const BRepAdaptor_Surface s(face, false);
  Primitive p;
  switch (s.GetType()) {
    case GeomAbs_Plane:
      p.type = SurfaceType::plane;
      set_frame(p, s.Plane().Position());
      if (!s.Plane().Position().Direct()) p.axis = -p.axis;  // n = σ_u × σ_v
      break;
    case GeomAbs_Cylinder:
      p.type = SurfaceType::cylinder;
      set_frame(p, s.Cylinder().Position());
      p.radius = s.Cylinder().Radius();
      break;
    case GeomAbs_Cone:
      p.type = SurfaceType::cone;
      set_frame(p, s.Cone().Position());
      p.radius = s.Cone().RefRadius();
      p.semi_angle = s.Cone().SemiAngle();
      break;
    case GeomAbs_Sphere:
      p.type = SurfaceType::sphere;
      set_frame(p, s.Sphere().Position());
      p.radius = s.Sphere().Radius();
      break;
    case GeomAbs_Torus:
      p.type = SurfaceType::torus;
      set_frame(p, s.Torus().Position());
      p.major_radius = s.Torus().MajorRadius();
      p.radius = s.Torus().MinorRadius();
      break;
    case GeomAbs_BSplineSurface:
      p.type = SurfaceType::bspline;
      break;
    case GeomAbs_BezierSurface:
      p.type = SurfaceType::bezier;
      break;
    case GeomAbs_SurfaceOfRevolution:
      p.type = SurfaceType::revolution;
      p.location = vec(s.AxeOfRevolution().Location().XYZ());
      p.axis = vec(s.AxeOfRevolution().Direction().XYZ());
      break;
    case GeomAbs_SurfaceOfExtrusion:
      p.type = SurfaceType::extrusion;
      p.axis = vec(s.Direction().XYZ());
      break;
    case GeomAbs_OffsetSurface:
      p.type = SurfaceType::offset;
      p.offset = s.OffsetValue();
      break;
    default:
      p.type = SurfaceType::other;
  }
  return p;
}

// A non-periodic B-spline surface with homogeneous poles [w x, w y, w z, w].
NurbsSurface projective(const Geom_BSplineSurface& bs) {
  NurbsSurface n;
  n.degree_u = bs.UDegree();
  n.degree_v = bs.VDegree();
  n.count_u = bs.NbUPoles();
  n.count_v = bs.NbVPoles();
  for (double k : bs.UKnotSequence()) n.knots_u.push_back(k);
  for (double k : bs.VKnotSequence()) n.knots_v.push_back(k);
  for (int i = 1; i <= n.count_u; ++i)
    for (int j = 1; j <= n.count_v; ++j) {
      const double w = bs.Weight(i, j);
      n.poles.emplace_back(w * bs.Pole(i, j).X(), w * bs.Pole(i, j).Y(), w * bs.Pole(i, j).Z(), w);
    }
  return n;
}

// The converted face's B-spline surface, segmented to the face's uv bounds and made
// non-periodic, in projective coordinates.
NurbsSurface nurbs_of(const TopoDS_Face& nface, int index) {
  const auto surface = Handle(Geom_BSplineSurface)::DownCast(BRep_Tool::Surface(nface));
  PARAFAB_VERIFY(!surface.IsNull(),
                 "face " << index << ": BRepBuilderAPI_NurbsConvert gave no B-spline surface");
  const auto bs = Handle(Geom_BSplineSurface)::DownCast(surface->Copy());
  double u0, u1, v0, v1, su0, su1, sv0, sv1;
  BRepTools::UVBounds(nface, u0, u1, v0, v1);
  bs->Bounds(su0, su1, sv0, sv1);
  if (!bs->IsUPeriodic()) u0 = std::max(u0, su0), u1 = std::min(u1, su1);
  if (!bs->IsVPeriodic()) v0 = std::max(v0, sv0), v1 = std::min(v1, sv1);
  // A full turn whose start is a round-off off the surface's own period start (u from
  // −1.8e-15 to 2π on a turned filleted boss's cylinder), where CheckAndSegment fails: snapped
  // onto it. A full turn starting elsewhere keeps its start.
  auto full_turn = [](double& a, double& b, double start, double period) {
    if (b - a < period - 1e-9) return;
    const double k = std::round((a - start) / period);
    if (std::abs(a - (start + k * period)) <= 1e-9) a = start + k * period;
    b = a + period;
  };
  if (bs->IsUPeriodic()) full_turn(u0, u1, su0, bs->UPeriod());
  if (bs->IsVPeriodic()) full_turn(v0, v1, sv0, bs->VPeriod());
  bs->CheckAndSegment(u0, u1, v0, v1);
  if (bs->IsUPeriodic()) bs->SetUNotPeriodic();
  if (bs->IsVPeriodic()) bs->SetVNotPeriodic();
  return projective(*bs);
}

// The B-rep's own B-spline surface of a face (located, not segmented), or count_u = 0 for other
// surfaces. A periodic direction is unwrapped (NurbsSurface::periodic_u): OCCT's periodic flat
// knots (distinct poles + 2 degree + 1 of them) over the distinct poles followed by the first
// `degree` again, the layout in which OCCT evaluates it (checked against Geom_BSplineSurface::D0
// by BsplinePoles.PeriodicFacePolesAreParametersWithExactMassDerivatives).
NurbsSurface own_bspline(const TopoDS_Face& face) {
  const auto bs = Handle(Geom_BSplineSurface)::DownCast(BRep_Tool::Surface(face));
  if (bs.IsNull()) return {};
  if (!bs->IsUPeriodic() && !bs->IsVPeriodic()) return projective(*bs);
  NurbsSurface n;
  n.degree_u = bs->UDegree();
  n.degree_v = bs->VDegree();
  n.periodic_u = bs->IsUPeriodic();
  n.periodic_v = bs->IsVPeriodic();
  const int du = bs->NbUPoles(), dv = bs->NbVPoles();
  n.count_u = du + (n.periodic_u ? n.degree_u : 0);
  n.count_v = dv + (n.periodic_v ? n.degree_v : 0);
  for (double k : bs->UKnotSequence()) n.knots_u.push_back(k);
  for (double k : bs->VKnotSequence()) n.knots_v.push_back(k);
  PARAFAB_VERIFY(static_cast<int>(n.knots_u.size()) == n.count_u + n.degree_u + 1 &&
                     static_cast<int>(n.knots_v.size()) == n.count_v + n.degree_v + 1,
                 "periodic B-spline surface: " << n.knots_u.size() << " x " << n.knots_v.size()
                                               << " flat knots for " << du << " x " << dv << " poles");
  for (int i = 0; i < n.count_u; ++i)
    for (int j = 0; j < n.count_v; ++j) {
      const int pi = i % du + 1, pj = j % dv + 1;
      const double w = bs->Weight(pi, pj);
      const gp_Pnt P = bs->Pole(pi, pj);
      n.poles.emplace_back(w * P.X(), w * P.Y(), w * P.Z(), w);
    }
  return n;
}

// Parameters at which to sample a pcurve: its ends for a line, its knots for a polyline
// (degree-1 B-spline), else `samples` equal steps.
std::vector<double> curve_samples(const Geom2dAdaptor_Curve& c, int samples) {
  const double f = c.FirstParameter(), l = c.LastParameter();
  std::vector<double> t{f};
  if (c.GetType() == GeomAbs_BSplineCurve && c.Degree() == 1) {
    for (int k = 1; k <= c.NbKnots(); ++k)
      if (const double x = c.BSpline()->Knot(k); x > f && x < l) t.push_back(x);
  } else if (c.GetType() != GeomAbs_Line) {
    for (int k = 1; k < samples; ++k) t.push_back(f + (l - f) * k / samples);
  }
  t.push_back(l);
  return t;
}

// Boundary loops of a converted (FORWARD) face as uv polylines, outer loop first.
std::vector<TrimLoop> loops_of(const TopoDS_Face& nface, const TopTools_IndexedMapOfShape& nedges,
                               int samples, int index) {
  const TopoDS_Wire outer = BRepTools::OuterWire(nface);
  std::vector<TrimLoop> loops;
  for (TopExp_Explorer w(nface, TopAbs_WIRE); w.More(); w.Next()) {
    TrimLoop loop;
    loop.outer = w.Current().IsSame(outer);
    for (BRepTools_WireExplorer ex(TopoDS::Wire(w.Current()), nface); ex.More(); ex.Next()) {
      double f, l;
      const Handle(Geom2d_Curve) c = BRep_Tool::CurveOnSurface(ex.Current(), nface, f, l);
      PARAFAB_VERIFY(!c.IsNull(), "face " << index << ": an edge has no curve in the face's parameters");
      std::vector<double> t = curve_samples(Geom2dAdaptor_Curve(c, f, l), samples);
      // The edge's own orientation (BRepTools_WireExplorer::Orientation() is wrong for one-edge wires).
      if (ex.Current().Orientation() == TopAbs_REVERSED) std::reverse(t.begin(), t.end());
      for (size_t k = loop.uv.empty() ? 0 : 1; k < t.size(); ++k) {
        const gp_Pnt2d p = c->Value(t[k]);
        loop.uv.emplace_back(p.X(), p.Y());
      }
      loop.edges.push_back(nedges.FindIndex(ex.Current()) - 1);
    }
    if (loop.uv.empty()) continue;
    loop.uv.back() = loop.uv.front();
    loops.insert(loop.outer ? loops.begin() : loops.end(), std::move(loop));
  }
  return loops;
}

const char* continuity_name(GeomAbs_Shape s) {
  static const char* names[] = {"C0", "G1", "C1", "G2", "C2", "C3", "CN"};
  return names[static_cast<int>(s)];
}

// Unit outward normal of a converted face at (u, v), or zero where it is undefined.
Vec3 outward_normal(const BRepAdaptor_Surface& s, bool reversed, const gp_Pnt2d& uv) {
  gp_Pnt P;
  gp_Vec du, dv;
  s.D1(uv.X(), uv.Y(), P, du, dv);
  const Vec3 n = vec(du.Crossed(dv).XYZ());
  return n.norm() < 1e-300 ? Vec3::Zero() : Vec3((reversed ? -1.0 : 1.0) * n.normalized());
}

// --- Tangency relations: the look-up table of §6.5.1 ----------------------------------------

using Residuals = std::vector<double>;

Residuals residuals(std::initializer_list<Vec3> vectors, std::initializer_list<double> scalars) {
  Residuals r;
  for (const Vec3& v : vectors) r.insert(r.end(), {v.x(), v.y(), v.z()});
  r.insert(r.end(), scalars);
  return r;
}

int sign_of(double x) { return x < 0 ? -1 : 1; }
int closer(double plus, double minus) { return std::abs(plus) <= std::abs(minus) ? 1 : -1; }

// Equations are written with {a}, {b} (face indices), {s} ("" or "-"), {pm} ("+" or "-"), and
// {xyz} (a vector equation, expanded into its .x, .y, .z components). `eval` returns the
// residuals in the same order; `sign` fixes the side at detection.
struct RelationKind {
  const char* name;
  SurfaceType a, b;
  std::vector<const char*> equations;
  int (*sign)(const Primitive& a, const Primitive& b);
  Residuals (*eval)(const Primitive& a, const Primitive& b, int s);
};

const std::vector<RelationKind>& relation_table() {
  using T = SurfaceType;
  using P = const Primitive&;
  // clang-format off
  static const std::vector<RelationKind> table = {
      // Coplanar neighbours (a face split in two).
      {"plane-plane", T::plane, T::plane,
       {"cross(n{a}, n{b}){xyz} = 0", "dot(p{b} - p{a}, n{a}) = 0"},
       [](P, P) { return 1; },
       [](P a, P b, int) { return residuals({a.axis.cross(b.axis)}, {(b.location - a.location).dot(a.axis)}); }},
      // Fig. 6.11: the axis lies at distance r from the plane, parallel to it.
      {"plane-cylinder", T::plane, T::cylinder,
       {"{s}dot(p{a} - c{b}, n{a}) - r{b} = 0", "dot(n{a}, d{b}) = 0"},
       [](P a, P b) { return sign_of((a.location - b.location).dot(a.axis)); },
       [](P a, P b, int s) {
         return residuals({}, {s * (a.location - b.location).dot(a.axis) - b.radius, a.axis.dot(b.axis)});
       }},
      // Tangent along a ruling: the apex lies on the plane, the axis at the semi-angle to it.
      {"plane-cone", T::plane, T::cone,
       {"dot(c{b} - r{b}/tan(a{b}) d{b} - p{a}, n{a}) = 0", "{s}dot(n{a}, d{b}) - sin(a{b}) = 0"},
       [](P a, P b) { return sign_of(a.axis.dot(b.axis) * std::sin(b.semi_angle)); },
       [](P a, P b, int s) {
         const Vec3 apex = b.location - b.radius / std::tan(b.semi_angle) * b.axis;
         return residuals({}, {(apex - a.location).dot(a.axis), s * a.axis.dot(b.axis) - std::sin(b.semi_angle)});
       }},
      {"plane-sphere", T::plane, T::sphere,
       {"{s}dot(p{a} - c{b}, n{a}) - r{b} = 0"},
       [](P a, P b) { return sign_of((a.location - b.location).dot(a.axis)); },
       [](P a, P b, int s) { return residuals({}, {s * (a.location - b.location).dot(a.axis) - b.radius}); }},
      // Plane perpendicular to the axis, touching the tube along a circle.
      {"plane-torus", T::plane, T::torus,
       {"cross(n{a}, d{b}){xyz} = 0", "{s}dot(p{a} - c{b}, n{a}) - r{b} = 0"},
       [](P a, P b) { return sign_of((a.location - b.location).dot(a.axis)); },
       [](P a, P b, int s) {
         return residuals({a.axis.cross(b.axis)}, {s * (a.location - b.location).dot(a.axis) - b.radius});
       }},
      // Parallel axes at distance r_a ± r_b; a has the larger radius.
      {"cylinder-cylinder", T::cylinder, T::cylinder,
       {"cross(d{a}, d{b}){xyz} = 0", "|cross(c{b} - c{a}, d{a})| - (r{a} {pm} r{b}) = 0"},
       [](P a, P b) {
         const double dist = (b.location - a.location).cross(a.axis).norm();
         return closer(dist - a.radius - b.radius, dist - a.radius + b.radius);
       },
       [](P a, P b, int s) {
         return residuals({a.axis.cross(b.axis)},
                          {(b.location - a.location).cross(a.axis).norm() - (a.radius + s * b.radius)});
       }},
      // Sphere centre on the axis, equal radii (a rounded corner, a capsule).
      {"cylinder-sphere", T::cylinder, T::sphere,
       {"cross(c{b} - c{a}, d{a}){xyz} = 0", "r{b} - r{a} = 0"},
       [](P, P) { return 1; },
       [](P a, P b, int) { return residuals({(b.location - a.location).cross(a.axis)}, {b.radius - a.radius}); }},
      // Coaxial, the tube touching the cylinder: a fillet at the foot of a boss.
      {"cylinder-torus", T::cylinder, T::torus,
       {"cross(d{a}, d{b}){xyz} = 0", "cross(c{b} - c{a}, d{a}){xyz} = 0", "R{b} {pm} r{b} - r{a} = 0"},
       [](P a, P b) { return closer(b.major_radius + b.radius - a.radius, b.major_radius - b.radius - a.radius); },
       [](P a, P b, int s) {
         return residuals({a.axis.cross(b.axis), (b.location - a.location).cross(a.axis)},
                          {b.major_radius + s * b.radius - a.radius});
       }},
      // The cylinder continues the torus tube (a pipe elbow): its axis is tangent to the centre circle.
      {"cylinder-torus-pipe", T::cylinder, T::torus,
       {"dot(d{a}, d{b}) = 0", "dot(c{a} - c{b}, d{b}) = 0", "|cross(c{a} - c{b}, d{a})| - R{b} = 0",
        "r{a} - r{b} = 0"},
       [](P, P) { return 1; },
       [](P a, P b, int) {
         const Vec3 cc = a.location - b.location;
         return residuals({}, {a.axis.dot(b.axis), cc.dot(b.axis), cc.cross(a.axis).norm() - b.major_radius,
                               a.radius - b.radius});
       }},
      // Sphere centre on the torus axis, touching the tube along a circle.
      {"sphere-torus", T::sphere, T::torus,
       {"cross(c{a} - c{b}, d{b}){xyz} = 0", "sqrt(R{b}^2 + dot(c{a} - c{b}, d{b})^2) - (r{a} {pm} r{b}) = 0"},
       [](P a, P b) {
         const double h = (a.location - b.location).dot(b.axis), dist = std::hypot(b.major_radius, h);
         return closer(dist - a.radius - b.radius, dist - a.radius + b.radius);
       },
       [](P a, P b, int s) {
         const Vec3 cc = a.location - b.location;
         return residuals({cc.cross(b.axis)},
                          {std::hypot(b.major_radius, cc.dot(b.axis)) - (a.radius + s * b.radius)});
       }},
  };
  // clang-format on
  return table;
}

const RelationKind* find_kind(const std::string& name) {
  for (const RelationKind& k : relation_table())
    if (name == k.name) return &k;
  return nullptr;
}

std::string replace_all(std::string s, const std::string& from, const std::string& to) {
  for (size_t at = s.find(from); at != std::string::npos; at = s.find(from, at + to.size()))
    s.replace(at, from.size(), to);
  return s;
}

std::vector<std::string> equations_of(const RelationKind& kind, int a, int b, int s) {
  std::vector<std::string> out;
  for (const char* eq : kind.equations) {
    std::string t = replace_all(eq, "{a}", std::to_string(a));
    t = replace_all(replace_all(replace_all(t, "{b}", std::to_string(b)), "{s}", s < 0 ? "-" : ""), "{pm}",
                    s < 0 ? "-" : "+");
    if (t.find("{xyz}") == std::string::npos)
      out.push_back(t);
    else
      for (const char* c : {".x", ".y", ".z"}) out.push_back(replace_all(t, "{xyz}", c));
  }
  return out;
}

Vec3 nurbs_normal(const NurbsSurface& s, const Vec2& uv) {
  Vec3 X, Xu, Xv;
  evaluate(s, uv.x(), uv.y(), X, Xu, Xv);
  const Vec3 n = Xu.cross(Xv);
  return n.norm() < 1e-300 ? Vec3::Zero() : Vec3(n.normalized());
}

std::string g1_equation(int a, int b, const std::array<Vec2, 2>& uv, const char* component) {
  char buf[160];
  std::snprintf(buf, sizeof buf, "cross(N%d(%.9g, %.9g), N%d(%.9g, %.9g))%s = 0", a, uv[0].x(), uv[0].y(), b,
                uv[1].x(), uv[1].y(), component);
  return buf;
}

bool has_axis(SurfaceType t) { return t == SurfaceType::cylinder || t == SurfaceType::cone || t == SurfaceType::torus; }
bool of_revolution(SurfaceType t) { return has_axis(t) || t == SurfaceType::sphere; }

// "coaxial" (a has an axis; b has one too, or is a sphere): b's axis parallel to a's, b's centre on
// a's axis. Design intent of faces of revolution meeting along a sharp edge: a countersink or
// counterbore and its hole, a shaft's steps and chamfers.
Residuals coaxial_residuals(const Primitive& a, const Primitive& b) {
  const Vec3 off = (b.location - a.location).cross(a.axis);
  if (b.type == SurfaceType::sphere) return residuals({off}, {});
  return residuals({a.axis.cross(b.axis), off}, {});
}

std::vector<std::string> coaxial_equations(int a, int b, bool sphere) {
  std::vector<std::string> out;
  const std::string A = std::to_string(a), B = std::to_string(b);
  for (const char* c : {".x", ".y", ".z"})
    if (!sphere) out.push_back("cross(d" + A + ", d" + B + ")" + c + " = 0");
  for (const char* c : {".x", ".y", ".z"}) out.push_back("cross(c" + B + " - c" + A + ", d" + A + ")" + c + " = 0");
  return out;
}

}  // namespace

const char* to_string(SurfaceType type) {
  static const char* names[] = {"plane",  "cylinder",  "cone",       "sphere", "torus", "bspline",
                                "bezier", "extrusion", "revolution", "offset", "other"};
  return names[static_cast<int>(type)];
}

std::vector<double> tangency_residuals(const TangencyRelation& relation, const FaceInfo& a,
                                       const FaceInfo& b) {
  if (relation.kind == "g1") {
    Residuals r;
    for (const auto& uv : relation.samples) {
      const Vec3 c = nurbs_normal(a.nurbs, uv[0]).cross(nurbs_normal(b.nurbs, uv[1]));
      r.insert(r.end(), {c.x(), c.y(), c.z()});
    }
    return r;
  }
  if (relation.kind == "coaxial") return coaxial_residuals(a.primitive, b.primitive);
  const RelationKind* kind = find_kind(relation.kind);
  PARAFAB_VERIFY(kind, "unknown tangency relation kind '" << relation.kind << "'");
  PARAFAB_VERIFY(a.primitive.type == kind->a && b.primitive.type == kind->b,
                 "relation " << relation.kind << " needs a " << to_string(kind->a) << " and a "
                             << to_string(kind->b) << ", got faces of type " << to_string(a.primitive.type)
                             << " and " << to_string(b.primitive.type));
  return kind->eval(a.primitive, b.primitive, relation.sign);
}

FaceModel build_face_model(const PartShape& part, const FaceModelOptions& options) {
  PARAFAB_VERIFY(options.edge_samples >= 1 && options.loop_samples_per_edge >= 1,
                 "face model: edge_samples and loop_samples_per_edge must be >= 1");
  FaceModel model;
  const int nf = part.face_count(), ne = part.edge_count();
  // Convert every face to NURBS at once; pcurves are re-parameterized consistently.
  std::vector<TopoDS_Face> nfaces(nf);
  TopTools_IndexedMapOfShape nedges;
  try {
    BRepBuilderAPI_NurbsConvert convert(part.shape, true);
    for (int i = 0; i < nf; ++i)
      nfaces[i] = TopoDS::Face(convert.ModifiedShape(part.face(i)).Oriented(TopAbs_FORWARD));
    for (int i = 0; i < ne; ++i) nedges.Add(convert.ModifiedShape(part.edge(i)));
  } catch (const Standard_Failure& e) {
    PARAFAB_INPUT_ERROR(part.source << ": conversion of the faces to NURBS failed: " << e.GetMessageString());
  }

  for (int i = 0; i < nf; ++i) {
    FaceInfo f;
    f.index = i;
    f.primitive = primitive_of(part.face(i));
    f.reversed = part.face(i).Orientation() == TopAbs_REVERSED;
    GProp_GProps props;
    BRepGProp::SurfaceProperties(part.face(i), props);
    f.area = props.Mass();
    try {
      f.nurbs = nurbs_of(nfaces[i], i);
      if (f.primitive.type == SurfaceType::bspline) f.bspline = own_bspline(part.face(i));
      f.loops = loops_of(nfaces[i], nedges, options.loop_samples_per_edge, i);
    } catch (const Standard_Failure& e) {
      PARAFAB_INPUT_ERROR(part.source << ": face " << i << ": NURBS form failed: " << e.GetMessageString());
    }
    f.uv_bounds = {f.nurbs.u_min(), f.nurbs.u_max(), f.nurbs.v_min(), f.nurbs.v_max()};
    model.faces.push_back(std::move(f));
  }

  // Edges: the faces on both sides, and normal angles at interior samples (uv kept for "g1").
  TopTools_IndexedDataMapOfShapeListOfShape edge_faces;
  TopExp::MapShapesAndAncestors(part.shape, TopAbs_EDGE, TopAbs_FACE, edge_faces);
  std::vector<std::vector<std::array<Vec2, 2>>> edge_uv(ne);
  for (int i = 0; i < ne; ++i) {
    EdgeInfo e;
    e.index = i;
    const TopoDS_Edge& edge = part.edge(i);
    std::vector<int> faces;
    for (const TopoDS_Shape& f : edge_faces.FindFromKey(edge))
      if (std::find(faces.begin(), faces.end(), part.face_index(f)) == faces.end())
        faces.push_back(part.face_index(f));
    std::sort(faces.begin(), faces.end());
    PARAFAB_VERIFY(!faces.empty(), part.source << ": edge " << i << " bounds no face");
    e.degenerated = BRep_Tool::Degenerated(edge);
    e.seam = faces.size() == 1 && !e.degenerated && BRep_Tool::IsClosed(edge, part.face(faces[0]));
    e.faces = {faces[0], faces.size() > 1 ? faces[1] : e.seam ? faces[0] : -1};
    if (!e.degenerated) {
      const int a = e.faces[0], b = e.faces[1];
      e.continuity = continuity_name(BRep_Tool::Continuity(edge, part.face(a), part.face(b)));
      // Seam: the edge's two pcurves on the same face (edge FORWARD and REVERSED).
      const TopoDS_Edge ea = TopoDS::Edge(nedges(i + 1).Oriented(TopAbs_FORWARD));
      const TopoDS_Edge eb = e.seam ? TopoDS::Edge(ea.Reversed()) : ea;
      double fa, la, fb, lb;
      const Handle(Geom2d_Curve) ca = BRep_Tool::CurveOnSurface(ea, nfaces[a], fa, la);
      const Handle(Geom2d_Curve) cb = BRep_Tool::CurveOnSurface(eb, nfaces[b], fb, lb);
      PARAFAB_VERIFY(!ca.IsNull() && !cb.IsNull(), part.source << ": edge " << i << " has no curve on face "
                                                               << a << " or " << b
                                                               << " after NURBS conversion");
      const BRepAdaptor_Surface sa(nfaces[a], false), sb(nfaces[b], false);
      for (int k = 1; k <= options.edge_samples; ++k) {
        const double t = static_cast<double>(k) / (options.edge_samples + 1);
        const gp_Pnt2d ua = ca->Value(fa + t * (la - fa)), ub = cb->Value(fb + t * (lb - fb));
        const Vec3 na = outward_normal(sa, model.faces[a].reversed, ua);
        const Vec3 nb = outward_normal(sb, model.faces[b].reversed, ub);
        edge_uv[i].push_back({Vec2(ua.X(), ua.Y()), Vec2(ub.X(), ub.Y())});
        if (na.isZero() || nb.isZero()) continue;
        e.max_angle_deg =
            std::max(e.max_angle_deg, std::acos(std::clamp(na.dot(nb), -1.0, 1.0)) * 180.0 / M_PI);
      }
      e.tangent = e.max_angle_deg * M_PI / 180.0 < options.tangent_angle;
    }
    model.edges.push_back(std::move(e));
  }

  // Tangency relations: one per pair of faces sharing tangent edges (seams excluded).
  std::map<std::pair<int, int>, std::vector<int>> pairs;
  for (const EdgeInfo& e : model.edges)
    if (e.tangent && !e.seam && e.faces[0] != e.faces[1]) pairs[{e.faces[0], e.faces[1]}].push_back(e.index);
  const double tolerance = options.relation_tolerance * std::max(1.0, part_box(part).diagonal());
  for (const auto& [pair, edges] : pairs) {
    TangencyRelation r;
    r.edges = edges;
    const FaceInfo *a = &model.faces[pair.first], *b = &model.faces[pair.second];
    const auto ta = a->primitive.type, tb = b->primitive.type;
    const bool swap =
        ta > tb || (ta == tb && ta == SurfaceType::cylinder && a->primitive.radius < b->primitive.radius);
    if (swap) std::swap(a, b);
    r.faces = {a->index, b->index};
    for (const RelationKind& kind : relation_table()) {
      if (kind.a != a->primitive.type || kind.b != b->primitive.type) continue;
      const int s = kind.sign(a->primitive, b->primitive);
      const Residuals res = kind.eval(a->primitive, b->primitive, s);
      if (std::all_of(res.begin(), res.end(), [&](double x) { return std::abs(x) <= tolerance; })) {
        r.kind = kind.name;
        r.sign = s;
        r.equations = equations_of(kind, a->index, b->index, s);
        r.residuals = res;
        break;
      }
    }
    if (r.kind.empty()) {  // no table entry fits: normals parallel at the edge samples
      r.kind = "g1";
      for (int e : edges)
        for (auto uv : edge_uv[e]) {
          if (swap) std::swap(uv[0], uv[1]);
          r.samples.push_back(uv);
          for (const char* c : {".x", ".y", ".z"})
            r.equations.push_back(g1_equation(a->index, b->index, uv, c));
        }
      r.residuals = tangency_residuals(r, *a, *b);
    }
    model.relations.push_back(std::move(r));
  }
  // Coaxial faces of revolution meeting along sharp edges (not already tangent).
  std::map<std::pair<int, int>, std::vector<int>> sharp;
  for (const EdgeInfo& e : model.edges)
    if (!e.tangent && !e.seam && e.faces[0] >= 0 && e.faces[1] >= 0 && e.faces[0] != e.faces[1] &&
        !pairs.count({e.faces[0], e.faces[1]}))  // (a degenerated edge has one face)
      sharp[{e.faces[0], e.faces[1]}].push_back(e.index);
  for (const auto& [pair, edges] : sharp) {
    const FaceInfo *a = &model.faces[pair.first], *b = &model.faces[pair.second];
    if (!of_revolution(a->primitive.type) || !of_revolution(b->primitive.type)) continue;
    if (!has_axis(a->primitive.type)) std::swap(a, b);
    if (!has_axis(a->primitive.type)) continue;  // two spheres
    const Residuals res = coaxial_residuals(a->primitive, b->primitive);
    if (!std::all_of(res.begin(), res.end(), [&](double x) { return std::abs(x) <= tolerance; })) continue;
    TangencyRelation r;
    r.kind = "coaxial";
    r.faces = {a->index, b->index};
    r.edges = edges;
    r.equations = coaxial_equations(a->index, b->index, b->primitive.type == SurfaceType::sphere);
    r.residuals = res;
    model.relations.push_back(std::move(r));
  }
  return model;
}

}  // namespace parafab::occ
