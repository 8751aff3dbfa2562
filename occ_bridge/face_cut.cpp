// Cut by face (thesis §6.3, Fig. 6.12): every B-rep face is split in its own (u, v) by the
// grid planes crossing its box, with the plane ∩ surface curves in closed form (planes: lines,
// cylinders: v(u) graphs or u(v) branches) or, on any other surface, traced in (u, v) (Newton
// onto X_a = q; closed islands from the interior extrema of X_a), its trimming loops split where the edges cross the
// planes (roots on the edges' 3D curves, so both faces of an edge agree). The cells' grid faces
// are built from the same curves and the cell-face squares; subvolumes are the connected
// components of a cell's patches (shared boundary points). Cells no face reaches are classified
// in connected runs, one OCCT point test per run. Every point the cut creates keeps its class
// (face–plane, edge–plane, face–plane–plane, vertex) and its (u, v) on each surface it lies
// on (CutSample), for the shape derivatives of §6.5.3.
#include <BRepAdaptor_Curve.hxx>
#include <BRepAdaptor_Surface.hxx>
#include <BRepBndLib.hxx>
#include <BRepClass3d_SolidClassifier.hxx>
#include <BRepGProp.hxx>
#include <BRepTools.hxx>
#include <BRepTools_WireExplorer.hxx>
#include <BRep_Tool.hxx>
#include <Bnd_Box.hxx>
#include <GProp_GProps.hxx>
#include <Geom2d_Line.hxx>
#include <Geom_Line.hxx>
#include <Standard_Failure.hxx>
#include <TopExp.hxx>
#include <TopExp_Explorer.hxx>
#include <TopTools_IndexedDataMapOfShapeListOfShape.hxx>
#include <TopoDS.hxx>
#include <TopoDS_Vertex.hxx>
#include <TopoDS_Wire.hxx>
#include <gp_Cylinder.hxx>
#include <gp_Pln.hxx>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <iterator>
#include <map>
#include <numeric>
#include <set>
#include <sstream>
#include <tuple>

#include "grid_cut_detail.h"
#include "occt_shape.h"
#include "xfem/area_rules.h"

namespace parafab::occ::detail {

namespace {

using NodeId = std::int64_t;
constexpr NodeId kVertexNode = 0, kEdgePlaneNode = 1LL << 60, kFaceNode = 2LL << 60, kCornerNode = 3LL << 60;

struct FaceFailure {
  std::string why;
  int axis = -1;  ///< the grid plane's axis when one plane is at fault (cut_by_grid shifts along it)
};

double cross2(const Vec2& a, const Vec2& b) { return a.x() * b.y() - a.y() * b.x(); }

// A curve in a face's (u, v) (or, for grid faces, in a plane's coordinates).
class UvCurve {
 public:
  virtual ~UvCurve() = default;
  virtual Vec2 at(double t) const = 0;
  virtual bool straight() const { return false; }
};

// An edge's pcurve on a face.
class PCurve : public UvCurve {
 public:
  PCurve(Handle(Geom2d_Curve) c, int edge) : c_(std::move(c)), edge_(edge) {
    straight_ = c_->DynamicType() == STANDARD_TYPE(Geom2d_Line);
  }
  Vec2 at(double t) const override { return eval2(c_, t); }
  bool straight() const override { return straight_; }
  int edge() const { return edge_; }

 private:
  Handle(Geom2d_Curve) c_;
  int edge_;
  bool straight_ = false;
};

// A component of {X_axis = q} on a surface of any type, traced in (u, v) (predictor along the
// level tangent, Newton corrector onto the level set): points, unit tangents and chord-length
// parameter. Evaluation between points is a cubic Hermite in (u, v) projected back onto the
// level set, so every point handed out lies on the plane to round-off.
struct TracedLevel {
  Handle(Geom_Surface) surface;
  int axis = 0;
  double q = 0;
  std::vector<Vec2> p, t;
  std::vector<double> s;
  bool closed = false;
  double length() const { return s.back(); }

  // f − q and its (u, v) gradient.
  double value(const Vec2& uv, Vec2* grad = nullptr) const {
    gp_Pnt X;
    gp_Vec du, dv;
    surface->D1(uv.x(), uv.y(), X, du, dv);
    if (grad) *grad = Vec2(du.Coord(axis + 1), dv.Coord(axis + 1));
    return X.Coord(axis + 1) - q;
  }
  // Newton steps along the gradient onto f = q. False if it does not converge.
  bool project(Vec2& uv, double scale) const {
    for (int it = 0; it < 12; ++it) {
      Vec2 g;
      const double f = value(uv, &g);
      const double g2 = g.squaredNorm();
      if (!(g2 > 0)) return false;
      const Vec2 d = -f * g / g2;
      uv += d;
      if (d.norm() <= 1e-15 * scale) return true;
    }
    Vec2 g;
    return std::abs(value(uv, &g)) <= 1e-12 * (1 + std::abs(q)) && g.squaredNorm() > 0;
  }
  Vec2 tangent(const Vec2& uv) const {
    Vec2 g;
    value(uv, &g);
    return Vec2(-g.y(), g.x()).normalized();
  }
  double wrap(double x) const {
    if (!closed) return x;
    const double L = length();
    x = std::fmod(x, L);
    return x < 0 ? x + L : x;
  }
  Vec2 at(double x, double scale) const {
    x = wrap(x);
    const int n = static_cast<int>(p.size());
    int i = static_cast<int>(std::upper_bound(s.begin(), s.end(), x) - s.begin()) - 1;
    i = std::clamp(i, 0, n - 2);
    const double h = s[i + 1] - s[i], r = (x - s[i]) / h;
    const double h00 = (1 + 2 * r) * (1 - r) * (1 - r), h10 = r * (1 - r) * (1 - r), h01 = r * r * (3 - 2 * r),
                 h11 = r * r * (r - 1);
    Vec2 uv = h00 * p[i] + h10 * h * t[i] + h01 * p[i + 1] + h11 * h * t[i + 1];
    project(uv, scale);
    return uv;
  }
  // Distance from uv to the traced polyline (a cheap bound: the curve lies within a chord's
  // sagitta, < 1 % of the step, of it).
  double polyline_distance(const Vec2& uv) const {
    double best = 1e300;
    for (size_t i = 0; i + 1 < p.size(); ++i) {
      const Vec2 d = p[i + 1] - p[i];
      const double r = std::clamp((uv - p[i]).dot(d) / d.squaredNorm(), 0.0, 1.0);
      best = std::min(best, (p[i] + r * d - uv).norm());
    }
    return best;
  }
  // The parameter of the point of the curve nearest to uv.
  double param(const Vec2& uv, double scale) const {
    double best = 1e300, sb = 0;
    for (size_t i = 0; i + 1 < p.size(); ++i) {
      const Vec2 d = p[i + 1] - p[i];
      const double r = std::clamp((uv - p[i]).dot(d) / d.squaredNorm(), 0.0, 1.0);
      const double dist = (p[i] + r * d - uv).norm();
      if (dist < best) best = dist, sb = s[i] + r * (s[i + 1] - s[i]);
    }
    for (int it = 0; it < 8; ++it) {  // Newton on the foot point
      const double e = 1e-6 * length();
      const Vec2 c = at(sb, scale), tg = (at(sb + e, scale) - at(sb - e, scale)) / (2 * e);
      const double ds = (uv - c).dot(tg) / std::max(tg.squaredNorm(), 1e-300);
      sb += ds;
      if (std::abs(ds) <= 1e-15 * (1 + length())) break;
    }
    return closed ? wrap(sb) : sb;
  }
};

// Where grid plane X_axis = q meets a face's surface, in the face's (u, v).
//   Line (plane face): uv = p0 + s·dir.
//   Graph (cylinder, axis not ⟂ e_axis): uv = (s, (c − A cos(s − φ)) / d).
//   Branch (cylinder, axis ⟂ or nearly ⟂ e_axis): uv = (φ + sgn·acos((c − s·d)/A) + off, s).
//   Traced (any other surface: cones, spheres, tori, B-splines, ...): TracedLevel.
class LevelCurve : public UvCurve {
 public:
  enum Type { Line, Graph, Branch, Traced } type = Line;
  Vec2 p0{0, 0}, dir{1, 0};
  double c = 0, A = 0, phi = 0, d = 0, sgn = 1, off = 0;
  int face = -1, axis = -1, plane = -1;  // plane: index k (1..cells−1), coordinate planes[axis][k−1]
  std::shared_ptr<const TracedLevel> traced;
  double scale = 1;  ///< the face's (u, v) extent (Traced)

  Vec2 at(double s) const override {
    switch (type) {
      case Line: return p0 + s * dir;
      case Graph: return Vec2(s, (c - A * std::cos(s - phi)) / d);
      case Branch: {
        const double x = std::clamp((c - s * d) / A, -1.0, 1.0);
        return Vec2(phi + sgn * std::acos(x) + off, s);
      }
      case Traced: return traced->at(s, scale);
    }
    return p0;
  }
  bool straight() const override { return type == Line || (type == Branch && d == 0); }
  bool closed() const { return type == Traced && traced->closed; }
  double period() const { return traced->length(); }
  /// False if uv is certainly not on the curve (far from a traced curve's polyline).
  bool may_hold(const Vec2& uv) const {
    return type != Traced || traced->polyline_distance(uv) <= 0.05 * scale / 48 + 1e-6 * (1 + uv.norm());
  }
  double param(const Vec2& uv) const {
    switch (type) {
      case Line: return (uv - p0).dot(dir);
      case Graph: return uv.x();
      case Branch: return uv.y();
      case Traced: return traced->param(uv, scale);
    }
    return 0;
  }
};

// A level curve on a face seen in its grid plane's coordinates (X_{a+1}, X_{a+2}).
class ProjectedCurve : public UvCurve {
 public:
  ProjectedCurve(std::shared_ptr<const LevelCurve> c, Handle(Geom_Surface) s) : c_(std::move(c)), s_(std::move(s)) {}
  Vec2 at(double t) const override {
    const Vec2 uv = c_->at(t);
    const gp_Pnt p = s_->Value(uv.x(), uv.y());
    const int a = c_->axis;
    return Vec2(p.Coord((a + 1) % 3 + 1), p.Coord((a + 2) % 3 + 1));
  }
  const LevelCurve& level() const { return *c_; }

 private:
  std::shared_ptr<const LevelCurve> c_;
  Handle(Geom_Surface) s_;
};

class Segment : public UvCurve {  // straight, t ∈ [0, 1]
 public:
  Segment(const Vec2& a, const Vec2& b) : a_(a), b_(b) {}
  Vec2 at(double t) const override { return (1 - t) * a_ + t * b_; }
  bool straight() const override { return true; }

 private:
  Vec2 a_, b_;
};

struct Piece {
  std::shared_ptr<const UvCurve> curve;
  double t0 = 0, t1 = 1;
  NodeId n0 = -1, n1 = -1;  ///< global point ids at t0, t1
  Vec2 a() const { return curve->at(t0); }
  Vec2 b() const { return curve->at(t1); }
};
using Loop = std::vector<Piece>;
using Region = std::vector<Loop>;

// The face's part in one cell: outer loop first, then its holes.
struct FacePatch {
  std::array<int, 3> cell{0, 0, 0};
  Region loops;
};

// Roots of g on (a, b) (a < b), from sign changes on `n` samples, refined by bisection. A pair
// of roots closer than the sampling (a plane within a hair of a circle's extreme point, e.g. a
// grid plane shifted 1e-4 cells off a tangency) shows no sign change at the samples: where |g|
// has a local minimum at a sample, the extremum of g is located by golden-section search, and if
// g changes sign there it joins the samples, so both roots are bracketed.
template <class G>
std::vector<double> roots(const G& g, double a, double b, int n) {
  std::vector<std::pair<double, double>> samples;  // (t, g(t))
  samples.reserve(n + 4);
  for (int k = 0; k <= n; ++k) {
    const double t = k == n ? b : a + (b - a) * k / n;
    samples.push_back({t, g(t)});
  }
  const size_t m = samples.size();
  for (size_t k = 1; k + 1 < m; ++k) {
    const double g0 = samples[k - 1].second, g1 = samples[k].second, g2 = samples[k + 1].second;
    if (g1 == 0 || (g0 > 0) != (g1 > 0) || (g2 > 0) != (g1 > 0) || g0 == 0 || g2 == 0) continue;
    if (!(std::abs(g1) < std::abs(g0) && std::abs(g1) <= std::abs(g2))) continue;
    const double sgn = g1 > 0 ? 1 : -1;  // minimize sgn·g: towards zero
    double lo = samples[k - 1].first, hi = samples[k + 1].first;
    const double phi = 0.5 * (std::sqrt(5.0) - 1);
    double x1 = hi - phi * (hi - lo), x2 = lo + phi * (hi - lo);
    double f1 = sgn * g(x1), f2 = sgn * g(x2);
    for (int it = 0; it < 80 && hi - lo > 1e-15 * (1 + std::abs(lo)); ++it) {
      if (f1 < f2) hi = x2, x2 = x1, f2 = f1, x1 = hi - phi * (hi - lo), f1 = sgn * g(x1);
      else lo = x1, x1 = x2, f1 = f2, x2 = lo + phi * (hi - lo), f2 = sgn * g(x2);
    }
    const double t = f1 < f2 ? x1 : x2, gt = g(t);
    if (sgn * gt < 0) samples.push_back({t, gt});
  }
  if (samples.size() > m)
    std::sort(samples.begin(), samples.end(), [](const auto& p, const auto& q) { return p.first < q.first; });
  std::vector<double> r;
  double ta = samples[0].first, ga = samples[0].second;
  for (size_t k = 1; k < samples.size(); ++k) {
    const double tb = samples[k].first, gb = samples[k].second;
    if (ga == 0 && k > 1) r.push_back(ta);
    else if ((ga < 0 && gb > 0) || (ga > 0 && gb < 0)) {
      double lo = ta, hi = tb, glo = ga;
      for (int it = 0; it < 200 && hi - lo > 0; ++it) {
        const double mid = 0.5 * (lo + hi);
        if (mid <= lo || mid >= hi) break;
        const double gm = g(mid);
        if (gm == 0) { lo = hi = mid; break; }
        if ((gm < 0) == (glo < 0)) lo = mid, glo = gm;
        else hi = mid;
      }
      r.push_back(0.5 * (lo + hi));
    }
    ta = tb, ga = gb;
  }
  return r;
}

// Parameters where the edge's 3D curve crosses the plane X_axis = q, ascending (the same for
// both faces of the edge; a degenerated edge, a pole or apex, has none).
std::vector<double> edge_plane_roots(const TopoDS_Edge& e, int axis, double q) {
  if (BRep_Tool::Degenerated(e)) return {};
  BRepAdaptor_Curve c(TopoDS::Edge(e.Oriented(TopAbs_FORWARD)));
  double f, l;
  BRep_Tool::Range(e, f, l);
  const int n = c.GetType() == GeomAbs_Line ? 1 : 64;
  return roots([&](double t) { return c.Value(t).Coord(axis + 1) - q; }, f, l, n);
}

Vec3 to_vec(const gp_Pnt& p) { return Vec3(p.X(), p.Y(), p.Z()); }

// Signed area of a loop (polyline through samples of its pieces).
std::vector<Vec2> polyline(const Loop& loop, int per_piece = 16) {
  std::vector<Vec2> pts;
  for (const Piece& p : loop)
    for (int k = 0; k < per_piece; ++k) pts.push_back(p.curve->at(p.t0 + (p.t1 - p.t0) * k / per_piece));
  return pts;
}
double signed_area(const std::vector<Vec2>& pts) {
  double a = 0;
  for (size_t i = 0; i < pts.size(); ++i) a += cross2(pts[i], pts[(i + 1) % pts.size()]);
  return 0.5 * a;
}
int winding(const std::vector<Vec2>& poly, const Vec2& q) {
  int w = 0;
  for (size_t i = 0; i < poly.size(); ++i) {
    const Vec2& p0 = poly[i];
    const Vec2& p1 = poly[(i + 1) % poly.size()];
    if (p0.y() <= q.y()) {
      if (p1.y() > q.y() && cross2(p1 - p0, q - p0) > 0) ++w;
    } else if (p1.y() <= q.y() && cross2(p1 - p0, q - p0) < 0) --w;
  }
  return w;
}

// Groups loops into patches: each counter-clockwise loop with the clockwise loops it holds.
std::vector<Region> group_loops(Region loops, const char* what) {
  std::vector<std::vector<Vec2>> polys;
  std::vector<double> areas;
  for (const Loop& l : loops) polys.push_back(polyline(l)), areas.push_back(signed_area(polys.back()));
  std::vector<Region> out;
  std::vector<int> outer_of(loops.size(), -1);
  std::vector<int> outers;
  for (size_t i = 0; i < loops.size(); ++i)
    if (areas[i] > 0) outer_of[i] = static_cast<int>(out.size()), outers.push_back(static_cast<int>(i)), out.push_back({loops[i]});
  for (size_t i = 0; i < loops.size(); ++i) {
    if (areas[i] > 0) continue;
    int best = -1;
    for (int o : outers)
      if (winding(polys[o], polys[i][0]) != 0 && (best < 0 || areas[o] < areas[best])) best = o;
    if (best < 0) throw FaceFailure{std::string("a hole of ") + what + " lies in no outer loop"};
    out[outer_of[best]].push_back(loops[i]);
  }
  return out;
}

// Everything about one face the cut needs, read-only during its task.
class FaceCutter {
 public:
  FaceCutter(const PartShape& part, const GridCut& g, int face) : part_(part), g_(g), index_(face) {
    face_ = TopoDS::Face(part.face(face).Oriented(TopAbs_FORWARD));
    surface_ = BRep_Tool::Surface(face_);
    BRepAdaptor_Surface ad(face_, false);
    type_ = ad.GetType();
    if (type_ == GeomAbs_Plane) pln_ = ad.Plane();
    else if (type_ == GeomAbs_Cylinder) cyl_ = ad.Cylinder();
    BRepTools::UVBounds(face_, uv0_[0], uv1_[0], uv0_[1], uv1_[1]);
    uv_scale_ = std::max(uv1_[0] - uv0_[0], uv1_[1] - uv0_[1]);
  }

  std::vector<FacePatch> cut() {
    Region whole = loops();
    for (const Loop& l : whole) face_polys_.push_back(polyline(l));
    Bnd_Box bb;
    BRepBndLib::Add(face_, bb, false);
    double lo[3], hi[3];
    bb.Get(lo[0], lo[1], lo[2], hi[0], hi[1], hi[2]);
    // Slabs along x, then y, then z.
    std::vector<std::pair<std::array<int, 3>, Region>> current{{{0, 0, 0}, std::move(whole)}};
    for (int a = 0; a < 3; ++a) {
      std::vector<std::pair<std::array<int, 3>, Region>> next;
      const auto& pl = g_.planes[a];
      const int k0 = static_cast<int>(std::upper_bound(pl.begin(), pl.end(), lo[a]) - pl.begin());
      const int k1 = static_cast<int>(std::upper_bound(pl.begin(), pl.end(), hi[a]) - pl.begin());
      for (auto& [cell, region] : current) {
        Region rest = std::move(region);
        for (int k = k0 + 1; k <= k1 && !rest.empty(); ++k) {  // plane k between cells k−1 and k
          auto [neg, pos] = split(rest, a, k);
          if (!neg.empty()) {
            auto c = cell;
            c[a] = k - 1;
            next.emplace_back(c, std::move(neg));
          }
          rest = std::move(pos);
        }
        if (!rest.empty()) {
          auto c = cell;
          c[a] = k1;
          next.emplace_back(c, std::move(rest));
        }
      }
      current = std::move(next);
    }
    std::vector<FacePatch> out;
    for (auto& [cell, region] : current)
      for (Region& r : group_loops(std::move(region), ("face " + std::to_string(index_)).c_str()))
        out.push_back({cell, std::move(r)});
    return out;
  }

  const Handle(Geom_Surface)& surface() const { return surface_; }

 private:
  double plane_coord(int axis, int k) const { return g_.planes[axis][k - 1]; }

  // The face's loops in (u, v), region on the left.
  Region loops() {
    Region out;
    for (TopExp_Explorer wires(face_, TopAbs_WIRE); wires.More(); wires.Next()) {
      Loop loop;
      for (BRepTools_WireExplorer ex(TopoDS::Wire(wires.Current()), face_); ex.More(); ex.Next()) {
        const TopoDS_Edge& e = ex.Current();
        double f, l;
        Handle(Geom2d_Curve) pc = BRep_Tool::CurveOnSurface(e, face_, f, l);
        if (pc.IsNull()) throw FaceFailure{"an edge of face " + std::to_string(index_) + " has no pcurve"};
        const int ei = part_.edge_index(e);
        const bool rev = e.Orientation() == TopAbs_REVERSED;
        Piece p;
        p.curve = std::make_shared<PCurve>(pc, ei);
        p.t0 = rev ? l : f;
        p.t1 = rev ? f : l;
        p.n0 = kVertexNode + part_.vertices.FindIndex(TopExp::FirstVertex(e, true)) - 1;
        p.n1 = kVertexNode + part_.vertices.FindIndex(TopExp::LastVertex(e, true)) - 1;
        loop.push_back(p);
        edges_.try_emplace(ei, e);
      }
      if (!loop.empty()) out.push_back(std::move(loop));
    }
    return out;
  }

  // Roots of plane (axis, k) on the whole edge, on its 3D curve (the same for both faces).
  const std::vector<double>& edge_roots(int edge, int axis, int k) {
    const auto key = std::array<int, 3>{edge, axis, k};
    auto it = edge_roots_.find(key);
    if (it != edge_roots_.end()) return it->second;
    return edge_roots_.emplace(key, edge_plane_roots(edges_.at(edge), axis, plane_coord(axis, k))).first->second;
  }

  double level_value(const Vec2& uv, int axis, double q) const {
    return surface_->Value(uv.x(), uv.y()).Coord(axis + 1) - q;
  }
  Vec2 level_gradient(const Vec2& uv, int axis) const {
    gp_Pnt p;
    gp_Vec du, dv;
    surface_->D1(uv.x(), uv.y(), p, du, dv);
    return Vec2(du.Coord(axis + 1), dv.Coord(axis + 1));
  }

  // Traces the component of {X_axis = q} through `seed` (projected onto it) across the face's
  // (u, v) box and a margin, or around until it closes. Null if the tracing fails.
  std::shared_ptr<TracedLevel> trace(int axis, double q, Vec2 seed) const {
    auto L = std::make_shared<TracedLevel>();
    L->surface = surface_, L->axis = axis, L->q = q;
    const double scale = uv_scale_;
    if (!L->project(seed, scale)) return nullptr;
    const double margin = 1e-3 * scale;
    auto outside = [&](const Vec2& x) {
      return x.x() < uv0_[0] - margin || x.x() > uv1_[0] + margin || x.y() < uv0_[1] - margin || x.y() > uv1_[1] + margin;
    };
    const double h_max = scale / 48, h_min = 1e-10 * scale;
    // One direction (sgn ±1) from the seed: points until the curve leaves the box or closes.
    auto march = [&](double sgn, std::vector<Vec2>& pts, bool& closed) {
      pts = {seed};
      closed = false;
      Vec2 x = seed, tx = L->tangent(seed);
      double h = h_max / 4;
      for (int step = 0; step < 200000; ++step) {
        Vec2 y = x + sgn * h * tx;
        const bool ok = L->project(y, scale);
        const Vec2 ty = ok ? L->tangent(y) : Vec2(0, 0);
        const double cosang = tx.dot(ty);
        if (!ok || cosang < std::cos(0.08) || (y - x).norm() > 1.5 * h) {
          h *= 0.5;
          if (h < h_min) return false;
          continue;
        }
        // Closed: the step passes over the seed (which lies on the curve).
        if (pts.size() > 3) {
          const Vec2 d = y - x;
          const double r = (seed - x).dot(d) / d.squaredNorm();
          if (r > 0 && r <= 1 && (x + r * d - seed).norm() < 0.05 * d.norm()) {
            pts.push_back(seed);
            closed = true;
            return true;
          }
        }
        pts.push_back(y);
        x = y, tx = ty;
        if (outside(y)) return true;
        if (cosang > std::cos(0.03)) h = std::min(1.5 * h, h_max);
      }
      return false;
    };
    std::vector<Vec2> fwd, bwd;
    bool closed = false, closed_b = false;
    if (!march(1, fwd, closed)) return nullptr;
    std::vector<Vec2> pts;
    if (closed) pts = std::move(fwd);
    else {
      if (!march(-1, bwd, closed_b) || closed_b) return nullptr;
      pts.assign(bwd.rbegin(), bwd.rend());
      pts.insert(pts.end(), fwd.begin() + 1, fwd.end());
    }
    L->closed = closed;
    L->p = pts;
    L->s.push_back(0);
    for (size_t i = 0; i < pts.size(); ++i) {
      L->t.push_back(L->tangent(pts[i]));
      if (i > 0) L->s.push_back(L->s.back() + (pts[i] - pts[i - 1]).norm());
    }
    return L;
  }

  // Interior local extrema of X_axis on the face (grid samples inside the face, refined by
  // Newton on the gradient): where closed level curves (islands) can lie.
  struct Extremum {
    Vec2 uv;
    double f;
    bool max;
  };
  const std::vector<Extremum>& extrema(int axis) {
    auto it = extrema_.find(axis);
    if (it != extrema_.end()) return it->second;
    std::vector<Extremum> out;
    const int N = 40;
    std::vector<double> f((N + 1) * (N + 1));
    auto uv_at = [&](int i, int j) {
      return Vec2(uv0_[0] + (uv1_[0] - uv0_[0]) * i / N, uv0_[1] + (uv1_[1] - uv0_[1]) * j / N);
    };
    for (int i = 0; i <= N; ++i)
      for (int j = 0; j <= N; ++j) {
        const Vec2 uv = uv_at(i, j);
        f[i * (N + 1) + j] = surface_->Value(uv.x(), uv.y()).Coord(axis + 1);
      }
    for (int i = 1; i < N; ++i)
      for (int j = 1; j < N; ++j) {
        const double c = f[i * (N + 1) + j];
        bool is_max = true, is_min = true;
        for (int di = -1; di <= 1; ++di)
          for (int dj = -1; dj <= 1; ++dj) {
            if (!di && !dj) continue;
            const double o = f[(i + di) * (N + 1) + j + dj];
            is_max &= c > o, is_min &= c < o;
          }
        if (!is_max && !is_min) continue;
        Vec2 uv = uv_at(i, j);
        for (int iter = 0; iter < 30; ++iter) {  // Newton on ∇f = 0
          gp_Pnt X;
          gp_Vec du, dv, duu, dvv, duv;
          surface_->D2(uv.x(), uv.y(), X, du, dv, duu, dvv, duv);
          const Vec2 g(du.Coord(axis + 1), dv.Coord(axis + 1));
          const double a = duu.Coord(axis + 1), b = duv.Coord(axis + 1), c2 = dvv.Coord(axis + 1), det = a * c2 - b * b;
          const Vec2 d = -Vec2(c2 * g.x() - b * g.y(), a * g.y() - b * g.x()) / det;
          if (!d.allFinite()) break;
          uv += d;
          if (d.norm() < 1e-14 * uv_scale_) break;
        }
        int w = 0;
        for (const auto& poly : face_polys_) w += winding(poly, uv);
        if (w == 0) continue;  // outside the face (or on its boundary)
        bool dup = false;
        for (const Extremum& e : out) dup |= (e.uv - uv).norm() < 1e-9 * uv_scale_;
        if (!dup) out.push_back({uv, surface_->Value(uv.x(), uv.y()).Coord(axis + 1), is_max});
      }
    return extrema_.emplace(axis, std::move(out)).first->second;
  }

  // Closed components of {X_axis = q} inside the face that its boundary does not cross: one
  // around each interior extremum beyond q, seeded by walking up or down the gradient to q.
  const std::vector<std::shared_ptr<LevelCurve>>& islands(int axis, int k) {
    auto found = islands_.find({axis, k});
    if (found != islands_.end()) return found->second;
    std::vector<std::shared_ptr<LevelCurve>> out;
    const double q = plane_coord(axis, k);
    // The face boundary's crossings with the plane (an island touches none).
    std::vector<Vec2> boundary;
    for (const auto& poly : face_polys_)
      for (size_t i = 0; i < poly.size(); ++i) {
        const Vec2 &a = poly[i], &b = poly[(i + 1) % poly.size()];
        const double fa = level_value(a, axis, q), fb = level_value(b, axis, q);
        if ((fa < 0) != (fb < 0)) boundary.push_back(a + fa / (fa - fb) * (b - a));
      }
    for (const Extremum& e : extrema(axis)) {
      if (e.max ? e.f <= q : e.f >= q) continue;
      // Walk from the extremum towards q along the gradient.
      Vec2 x = e.uv;
      const double h = uv_scale_ / 400;
      double fx = e.f - q;
      bool hit = false;
      Vec2 y;
      for (int step = 0; step < 2000; ++step) {
        Vec2 g = level_gradient(x, axis);
        if (g.norm() == 0) g = Vec2(1, 0);
        y = x + (e.max ? -h : h) * g.normalized();
        const double fy = level_value(y, axis, q);
        if ((fy < 0) != (fx < 0)) {
          hit = true;
          break;
        }
        x = y, fx = fy;
        if (y.x() < uv0_[0] || y.x() > uv1_[0] || y.y() < uv0_[1] || y.y() > uv1_[1]) break;
      }
      if (!hit) continue;
      bool known = false;
      for (const auto& c : out) known |= (c->at(c->param(y)) - y).norm() <= 1e-6 * (1 + y.norm());
      if (known) continue;
      auto tr = trace(axis, q, y);
      if (!tr || !tr->closed) continue;
      auto c = std::make_shared<LevelCurve>();
      c->face = index_, c->axis = axis, c->plane = k;
      c->type = LevelCurve::Traced;
      c->traced = std::move(tr);
      c->scale = uv_scale_;
      bool touches = false;  // approximate boundary crossings: within a polyline chord's sagitta
      for (const Vec2& b : boundary) touches |= (c->at(c->param(b)) - b).norm() <= 1e-3 * uv_scale_;
      if (touches) continue;
      out.push_back(c);
    }
    return islands_.emplace(std::make_pair(axis, k), std::move(out)).first->second;
  }

  // The components of {X_axis = q} on the surface, in (u, v); traced ones (surfaces other than
  // planes and cylinders) through the given points on them, kept per plane for the face.
  std::vector<std::shared_ptr<LevelCurve>> level_curves(int axis, int k, const std::vector<Vec2>& through = {}) {
    const double q = plane_coord(axis, k);
    std::vector<std::shared_ptr<LevelCurve>> out;
    auto make = [&]() {
      auto c = std::make_shared<LevelCurve>();
      c->face = index_, c->axis = axis, c->plane = k;
      return c;
    };
    if (type_ != GeomAbs_Plane && type_ != GeomAbs_Cylinder) {
      auto& known = traced_[{axis, k}];
      for (const Vec2& uv : through) {
        bool found = false;
        for (const auto& c : known) {
          if (!c->may_hold(uv)) continue;
          const double dist = (c->at(c->param(uv)) - uv).norm();
          if (dist <= 1e-6 * (1 + uv.norm())) {
            found = true;
            break;
          }
        }
        if (found) continue;
        auto tr = trace(axis, q, uv);
        if (!tr)
          throw FaceFailure{"face " + std::to_string(index_) + ": tracing plane " + std::to_string(axis) + "/" +
                            std::to_string(k) + " on its surface failed (singular or tangent)", axis};
        auto c = make();
        c->type = LevelCurve::Traced;
        c->traced = std::move(tr);
        c->scale = uv_scale_;
        known.push_back(c);
      }
      return known;
    }
    if (type_ == GeomAbs_Plane) {
      const gp_Ax3 ax = pln_.Position();
      const Vec2 grad(ax.XDirection().Coord(axis + 1), ax.YDirection().Coord(axis + 1));
      if (grad.norm() < 1e-14) return out;  // parallel to the grid plane (never on it: shifted)
      auto c = make();
      c->type = LevelCurve::Line;
      c->p0 = grad * (q - ax.Location().Coord(axis + 1)) / grad.squaredNorm();
      c->dir = Vec2(-grad.y(), grad.x()) / grad.norm();
      out.push_back(c);
      return out;
    }
    const gp_Ax3 ax = cyl_.Position();
    const double r = cyl_.Radius();
    const double xa = ax.XDirection().Coord(axis + 1), ya = ax.YDirection().Coord(axis + 1);
    const double d = ax.Direction().Coord(axis + 1);
    const double rho = std::hypot(xa, ya);
    const double A = r * rho, phi = std::atan2(ya, xa), cc = q - ax.Location().Coord(axis + 1);
    if (std::abs(d) > 1e-3 * A) {
      auto c = make();
      c->type = LevelCurve::Graph;
      c->A = A, c->phi = phi, c->c = cc, c->d = d;
      out.push_back(c);
      return out;
    }
    double u0, u1, v0, v1;
    BRepTools::UVBounds(face_, u0, u1, v0, v1);
    for (double sgn : {1.0, -1.0}) {
      auto c = make();
      c->type = LevelCurve::Branch;
      c->A = A, c->phi = phi, c->c = cc, c->d = std::abs(d) < 1e-15 ? 0.0 : d, c->sgn = sgn;
      const double vm = 0.5 * (v0 + v1);
      const double um = c->at(vm).x();
      c->off = std::floor((u0 - 1e-9 - um) / (2 * M_PI) + 1) * 2 * M_PI;  // into [u0 − ε, u0 − ε + 2π)
      out.push_back(c);
    }
    return out;
  }

  struct Crossing {
    Vec2 uv;
    NodeId id;
    double s = 0;
    int component = -1;
    bool enters = false;
    Vec2 tangent{0, 0};  ///< of the loop at the crossing
  };
  struct Element {  // a run of boundary pieces or a level interval, from crossing `from` to `to`
    int from, to;
    Loop pieces;
  };

  // Splits the region by plane (axis, k) into the parts with X_axis < q and > q.
  std::pair<Region, Region> split(const Region& region, int axis, int k) {
    const double q = plane_coord(axis, k);
    Region side[2];
    std::vector<Crossing> crossings;
    std::vector<Element> runs[2];
    auto value_at = [&](const Piece& p, double t) { return level_value(p.curve->at(t), axis, q); };
    for (const Loop& loop : region) {
      // Sub-pieces with the crossings at their ends.
      Loop subs;
      std::vector<int> end_crossing;  // per sub-piece: crossing index at its end, or −1
      for (const Piece& p : loop) {
        std::vector<double> ts;
        std::vector<NodeId> ids;
        const double lo = std::min(p.t0, p.t1), hi = std::max(p.t0, p.t1);
        if (auto pc = dynamic_cast<const PCurve*>(p.curve.get())) {
          const auto& all = edge_roots(pc->edge(), axis, k);
          for (size_t i = 0; i < all.size(); ++i)
            if (all[i] > lo && all[i] < hi) {
              ts.push_back(all[i]);
              ids.push_back(kEdgePlaneNode + (static_cast<NodeId>(pc->edge()) << 28) + (axis << 26) + (k << 13) +
                            static_cast<NodeId>(i));
            }
        } else {
          const int n = p.curve->straight() ? 1 : 48;
          ts = roots([&](double t) { return level_value(p.curve->at(t), axis, q); }, lo, hi, n);
          // The same level piece lies in the regions on both sides of its plane and is split
          // identically in both (same curve, same range): one id per curve, plane and root.
          for (double t : ts) {
            auto [it, fresh] = face_nodes_.try_emplace(std::make_tuple(p.curve.get(), axis, k, t), 0);
            if (fresh) it->second = kFaceNode + (static_cast<NodeId>(index_) << 32) + next_node_++;
            ids.push_back(it->second);
          }
        }
        if (p.t1 < p.t0) std::reverse(ts.begin(), ts.end()), std::reverse(ids.begin(), ids.end());
        double t = p.t0;
        NodeId n = p.n0;
        for (size_t i = 0; i < ts.size(); ++i) {
          subs.push_back({p.curve, t, ts[i], n, ids[i]});
          const double dt = 1e-7 * (p.t1 - p.t0);
          const Vec2 tan = p.curve->at(ts[i] + dt) - p.curve->at(ts[i] - dt);
          end_crossing.push_back(static_cast<int>(crossings.size()));
          crossings.push_back({p.curve->at(ts[i]), ids[i]});
          crossings.back().tangent = tan;

          t = ts[i], n = ids[i];
        }
        subs.push_back({p.curve, t, p.t1, n, p.n1});
        end_crossing.push_back(-1);
      }
      auto side_of = [&](const Piece& p) { return value_at(p, 0.5 * (p.t0 + p.t1)) < 0 ? 0 : 1; };
      const size_t first_crossing = std::find_if(end_crossing.begin(), end_crossing.end(), [](int c) { return c >= 0; }) - end_crossing.begin();
      if (first_crossing == end_crossing.size()) {  // the loop lies on one side
        side[side_of(subs[0])].push_back(loop);
        continue;
      }
      // Runs: start after a crossing, cut at every crossing.
      const size_t n = subs.size();
      Element run{end_crossing[first_crossing], -1, {}};
      for (size_t j = 1; j <= n; ++j) {
        const size_t i = (first_crossing + j) % n;
        run.pieces.push_back(subs[i]);
        if (end_crossing[i] >= 0) {
          run.to = end_crossing[i];
          runs[side_of(run.pieces[0])].push_back(run);
          run = Element{end_crossing[i], -1, {}};
        }
      }
    }
    // Closed level curves inside the region that its boundary does not cross (islands).
    if (type_ != GeomAbs_Plane && type_ != GeomAbs_Cylinder)
      for (const auto& isl : islands(axis, k)) {
        bool crossed = false;
        for (const Crossing& c : crossings)
          crossed |= isl->may_hold(c.uv) && (isl->at(isl->param(c.uv)) - c.uv).norm() <= 1e-6 * (1 + c.uv.norm());
        if (crossed) continue;
        const Vec2 x = isl->at(0);
        int w = 0;
        for (const Loop& l : region) w += winding(polyline(l), x);
        if (w == 0) continue;
        auto [it, fresh] = island_nodes_.try_emplace(isl.get(), 0);
        if (fresh) it->second = kFaceNode + (static_cast<NodeId>(index_) << 32) + next_node_++;
        const double L = isl->period();
        // Forward (s increasing) has f < q on its left.
        side[0].push_back({Piece{isl, 0, L, it->second, it->second}});
        side[1].push_back({Piece{isl, L, 0, it->second, it->second}});
      }
    if (crossings.empty()) {
      return {std::move(side[0]), std::move(side[1])};
    }
    // Level intervals between consecutive crossings along each component.
    std::vector<Vec2> through;
    for (const Crossing& c : crossings) through.push_back(c.uv);
    const auto comps = level_curves(axis, k, through);
    if (comps.empty()) throw FaceFailure{"face " + std::to_string(index_) + ": crossings without a level curve"};
    for (size_t i = 0; i < crossings.size(); ++i) {
      Crossing& c = crossings[i];
      double best = 1e300;
      for (size_t j = 0; j < comps.size(); ++j) {
        if (!comps[j]->may_hold(c.uv)) continue;
        const double s = comps[j]->param(c.uv);
        const double dist = (comps[j]->at(s) - c.uv).norm();
        if (dist < best) best = dist, c.component = static_cast<int>(j), c.s = s;
      }
      if (best > 1e-6 * (1 + c.uv.norm()))
        throw FaceFailure{"face " + std::to_string(index_) + ": a crossing of plane " + std::to_string(axis) + "/" +
                          std::to_string(k) + " is off its level curve by " + std::to_string(best), axis};
      const LevelCurve& L = *comps[c.component];
      const double ds = 1e-7 * (1 + std::abs(c.s));
      const Vec2 lt = L.at(c.s + ds) - L.at(c.s - ds);
      c.enters = cross2(c.tangent, lt) > 0;
    }
    for (size_t j = 0; j < comps.size(); ++j) {
      std::vector<int> on;
      for (size_t i = 0; i < crossings.size(); ++i)
        if (crossings[i].component == static_cast<int>(j)) on.push_back(static_cast<int>(i));
      std::sort(on.begin(), on.end(), [&](int a, int b) { return crossings[a].s < crossings[b].s; });
      if (on.size() % 2 != 0)
        throw FaceFailure{"face " + std::to_string(index_) + ": odd number of crossings (" + std::to_string(on.size()) +
                          ") on a level curve of plane " + std::to_string(axis) + "/" + std::to_string(k), axis};
      if (!on.empty() && comps[j]->closed() && !crossings[on[0]].enters) {  // start the pairs at an entry
        crossings[on[0]].s += comps[j]->period();
        std::rotate(on.begin(), on.begin() + 1, on.end());
      }
      for (size_t m = 0; m < on.size(); m += 2) {
        const Crossing& c0 = crossings[on[m]];
        const Crossing& c1 = crossings[on[m + 1]];
        if (!c0.enters || c1.enters)
          throw FaceFailure{"face " + std::to_string(index_) + ": level-curve crossings of plane " + std::to_string(axis) +
                            "/" + std::to_string(k) + " do not alternate (tangent or ambiguous)", axis};
        const double sm = 0.5 * (c0.s + c1.s);
        const Vec2 lt = comps[j]->at(sm + 1e-7 * (c1.s - c0.s)) - comps[j]->at(sm - 1e-7 * (c1.s - c0.s));
        const bool neg_left = Vec2(-lt.y(), lt.x()).dot(level_gradient(comps[j]->at(sm), axis)) < 0;
        Piece fwd{comps[j], c0.s, c1.s, c0.id, c1.id};
        Piece bwd{comps[j], c1.s, c0.s, c1.id, c0.id};
        runs[neg_left ? 0 : 1].push_back({on[m], on[m + 1], {fwd}});
        runs[neg_left ? 1 : 0].push_back({on[m + 1], on[m], {bwd}});
      }
    }
    // Link elements into loops at the crossings.
    for (int sd = 0; sd < 2; ++sd) {
      std::map<int, int> starting;
      for (size_t e = 0; e < runs[sd].size(); ++e)
        if (!starting.emplace(runs[sd][e].from, static_cast<int>(e)).second)
        {
          // Two crossings at one point: the plane passes through a point where two earlier
          // planes meet on the face, i.e. a grid vertex lies on the surface.
          std::string why = "two boundary pieces leave one crossing";
          for (size_t i = 0; i < crossings.size(); ++i)
            for (size_t j = i + 1; j < crossings.size(); ++j)
              if ((crossings[i].uv - crossings[j].uv).norm() <= 1e-9 * uv_scale_)
                why = "grid plane " + std::to_string(axis) + "/" + std::to_string(k) +
                      " passes through a point where two other grid planes meet the face (a grid vertex on the surface)";
          throw FaceFailure{"face " + std::to_string(index_) + ": " + why, axis};
        }
      std::vector<bool> used(runs[sd].size(), false);
      for (size_t e0 = 0; e0 < runs[sd].size(); ++e0) {
        if (used[e0]) continue;
        Loop loop;
        int e = static_cast<int>(e0);
        while (!used[e]) {
          used[e] = true;
          loop.insert(loop.end(), runs[sd][e].pieces.begin(), runs[sd][e].pieces.end());
          auto it = starting.find(runs[sd][e].to);
          if (it == starting.end()) throw FaceFailure{"face " + std::to_string(index_) + ": a boundary piece ends nowhere"};
          e = it->second;
        }
        if (e != static_cast<int>(e0)) throw FaceFailure{"face " + std::to_string(index_) + ": boundary pieces do not close"};
        side[sd].push_back(std::move(loop));
      }
    }
    return {std::move(side[0]), std::move(side[1])};
  }

  const PartShape& part_;
  const GridCut& g_;
  int index_;
  TopoDS_Face face_;
  Handle(Geom_Surface) surface_;
  GeomAbs_SurfaceType type_;
  gp_Pln pln_;
  gp_Cylinder cyl_;
  std::map<int, TopoDS_Edge> edges_;
  std::map<std::array<int, 3>, std::vector<double>> edge_roots_;
  NodeId next_node_ = 0;
  std::map<std::tuple<const UvCurve*, int, int, double>, NodeId> face_nodes_;
  double uv0_[2] = {0, 0}, uv1_[2] = {0, 0}, uv_scale_ = 1;
  std::map<std::pair<int, int>, std::vector<std::shared_ptr<LevelCurve>>> traced_, islands_;
  std::map<int, std::vector<Extremum>> extrema_;
  std::vector<std::vector<Vec2>> face_polys_;
  std::map<const LevelCurve*, NodeId> island_nodes_;
};

// Union–find over patch indices.
struct Components {
  std::vector<int> parent;
  explicit Components(int n) : parent(n) { std::iota(parent.begin(), parent.end(), 0); }
  int find(int i) { return parent[i] == i ? i : parent[i] = find(parent[i]); }
  void join(int a, int b) { parent[find(a)] = find(b); }
};

// A plane's map σ(u, v): X_a = q, X_{a+1} = u, X_{a+2} = v (σu × σv = e_a).
class GridPlaneMap : public xfem::SurfaceMap {
 public:
  GridPlaneMap(int axis, double q) : a_(axis), q_(q) {}
  void evaluate(double u, double v, Vec3& X, Vec3& Xu, Vec3& Xv) const override {
    X[a_] = q_, X[(a_ + 1) % 3] = u, X[(a_ + 2) % 3] = v;
    Xu = Vec3::Zero(), Xv = Vec3::Zero();
    Xu[(a_ + 1) % 3] = 1, Xv[(a_ + 2) % 3] = 1;
  }

 private:
  int a_;
  double q_;
};

struct PatchRef {
  int face = -1;     ///< B-rep face, or −1 for a grid patch
  int index = -1;    ///< into the face's patches, or into the grid patches
  int sign = 1;      ///< grid patch: +1 below its plane (normal +e_a), −1 above
};

struct GridPatch {
  int axis, plane;
  std::array<int, 2> cells2;  ///< the square's cell indices along axis+1, axis+2
  Region loops;
  std::array<int, 2> owner{INT32_MIN, INT32_MIN};  ///< below, above: subvolume ≥ 0 or −1 − interior cell
  std::array<int, 2> patch{-1, -1};  ///< below, above: the owning subvolume's patch index
};

// A piece of a subvolume's patch that may be an intersection curve (face–plane or face–face).
struct CurveJob {
  int subvolume;
  Piece piece;
  int face;
  bool level;
};

// A patch whose boundary loops are sampled into polynomial segments.
struct LoopJob {
  int subvolume, patch;
  const Region* region;
};

// What the phases of cut_by_faces share: the grid's cells, the faces' patches, the cells'
// states and the grid patches on the cut cells' squares.
struct FaceRoute {
  const PartShape& part;
  const GridOptions& o;
  GridCut& g;
  FaceRecut* recut;
  const std::array<int, 3>& n;
  int nf = 0, ncells = 0;
  std::vector<std::vector<FacePatch>> patches{};
  std::vector<Handle(Geom_Surface)> surfaces{};
  std::map<std::array<int, 3>, std::vector<PatchRef>> in_cell{};  ///< cut cells and the face patches in each
  std::vector<int> status{};  ///< per cell: −1 unknown, 0 outside, 1 inside, 2 cut
  std::map<std::array<int, 3>, int> interior_index{};
  std::vector<GridPatch> grid_patches{};
  std::map<std::array<int, 3>, std::vector<int>> grid_in_cell[2]{};  ///< [0]: cell below, [1]: above
  std::vector<CurveJob> curve_jobs{};
  std::vector<LoopJob> loop_jobs{};
  std::vector<int> pending{};  ///< re-cut: grid patches whose other side is a kept cut cell
  int open_edges = 0, first_open = -1;
  double verify_seconds = 0;

  int lin(const std::array<int, 3>& c) const { return c[0] + n[0] * (c[1] + n[1] * c[2]); }
  bool dirty(const std::array<int, 3>& c) const { return !recut || recut->dirty[lin(c)]; }
};

// Point tests against the solid, at 1e-9 of the largest cell side.
struct PointTest {
  BRepClass3d_SolidClassifier classifier;
  double h;
  TopAbs_State at(const Vec3& p) {
    classifier.Perform(gp_Pnt(p.x(), p.y(), p.z()), 1e-9 * h);
    return classifier.State();
  }
};

// Re-cut: only faces whose box meets a dirty cell are cut again.
std::vector<char> faces_to_cut(FaceRoute& r) {
  const GridCut& g = r.g;
  const auto& n = r.n;
  std::vector<char> cut_this(r.nf, 1);
  if (!r.recut) return cut_this;
  const double tol = 1e-7 * g.cell_size.maxCoeff();
  for (int f = 0; f < r.nf; ++f) {
    const Box3 fb = tight_box(r.part.face(f));
    std::array<int, 3> lo{}, hi{};
    for (int a = 0; a < 3; ++a) {
      const auto& pl = g.planes[a];
      lo[a] = static_cast<int>(std::upper_bound(pl.begin(), pl.end(), fb.min[a] - tol) - pl.begin());
      hi[a] = std::min(n[a] - 1, static_cast<int>(std::upper_bound(pl.begin(), pl.end(), fb.max[a] + tol) - pl.begin()));
    }
    bool meets = false;
    for (int i = lo[0]; i <= hi[0] && !meets; ++i)
      for (int j = lo[1]; j <= hi[1] && !meets; ++j)
        for (int k = lo[2]; k <= hi[2] && !meets; ++k) meets = r.recut->dirty[r.lin({i, j, k})];
    cut_this[f] = meets;
    r.recut->faces_cut += meets;
  }
  return cut_this;
}

// Each face cut into its patches per cell (FaceCutter), in parallel with o.face_parallel.
bool cut_faces(FaceRoute& r, const std::vector<char>& cut_this) {
  const int nf = r.nf;
  r.patches.assign(nf, {});
  r.surfaces.assign(nf, Handle(Geom_Surface)());
  std::vector<std::string> failures(nf);
  std::vector<int> failed_axis(nf, -1);
  auto cut_face = [&](int f) {
    if (!cut_this[f]) return;
    try {
      FaceCutter fc(r.part, r.g, f);
      r.surfaces[f] = fc.surface();
      r.patches[f] = fc.cut();
    } catch (const FaceFailure& e) {
      failures[f] = e.why;
      failed_axis[f] = e.axis;
    } catch (const Standard_Failure& e) {
      failures[f] = "face " + std::to_string(f) + ": OCCT: " + e.GetMessageString();
    }
  };
  if (r.o.face_parallel) tbb::parallel_for(0, nf, cut_face);
  else
    for (int f = 0; f < nf; ++f) cut_face(f);
  for (int f = 0; f < nf; ++f)
    if (!failures[f].empty()) {
      r.g.message = "face route: " + failures[f];
      r.g.failed_axis = failed_axis[f];
      return false;
    }
  return true;
}

// Cut cells and the face patches in each; uncut cells in connected runs, one point test each
// (re-cut: kept cells keep their state); the interior cells.
bool classify_cells(FaceRoute& r, PointTest& test) {
  GridCut& g = r.g;
  const auto& n = r.n;
  const int ncells = r.ncells;
  FaceRecut* recut = r.recut;
  std::vector<int>& status = r.status;
  for (int f = 0; f < r.nf; ++f)
    for (size_t p = 0; p < r.patches[f].size(); ++p) r.in_cell[r.patches[f][p].cell].push_back({f, static_cast<int>(p), 1});
  status.assign(ncells, -1);
  if (recut)
    for (int i = 0; i < ncells; ++i)
      if (!recut->dirty[i]) status[i] = recut->status[i];
  for (const auto& [c, list] : r.in_cell) {
    if (recut && !recut->dirty[r.lin(c)] && status[r.lin(c)] != 2) {
      g.message = "face route re-cut: a face meets a kept cell the old cut did not cut";
      return false;
    }
    status[r.lin(c)] = 2;
  }
  if (recut)
    for (int i = 0; i < ncells; ++i) recut->cells_cut += recut->dirty[i] && status[i] == 2;
  // A cell's state from a point inside it, off-centre (aligned parts have faces through centres).
  auto cell_inside = [&](const Box3& b) {
    for (const Vec3& f : {Vec3(0.5123, 0.4871, 0.5377), Vec3(0.3137, 0.6911, 0.2719), Vec3(0.7211, 0.2293, 0.6631)}) {
      const TopAbs_State s = test.at(b.min + f.cwiseProduct(b.size()));
      if (s == TopAbs_IN || s == TopAbs_OUT) return s == TopAbs_IN;
    }
    throw FaceFailure{"the point tests of an uncut cell landed on the boundary"};
  };
  try {
    for (int start = 0; start < ncells; ++start) {
      if (status[start] != -1) continue;
      const std::array<int, 3> c0{start % n[0], (start / n[0]) % n[1], start / (n[0] * n[1])};
      const Box3 b = g.cell_box(c0);
      const int s = cell_inside(b) ? 1 : 0;
      std::vector<int> stack{start};
      status[start] = s;
      while (!stack.empty()) {
        const int i = stack.back();
        stack.pop_back();
        const std::array<int, 3> c{i % n[0], (i / n[0]) % n[1], i / (n[0] * n[1])};
        for (int a = 0; a < 3; ++a)
          for (int dlt : {-1, 1}) {
            auto m = c;
            m[a] += dlt;
            if (m[a] < 0 || m[a] >= n[a]) continue;
            const int j = r.lin(m);
            if (status[j] == -1) status[j] = s, stack.push_back(j);
          }
      }
    }
  } catch (const FaceFailure& e) {
    g.message = "face route: " + e.why;
    return false;
  }
  for (int i = 0; i < ncells; ++i)
    if (status[i] == 1) {
      const std::array<int, 3> c{i % n[0], (i / n[0]) % n[1], i / (n[0] * n[1])};
      r.interior_index[c] = static_cast<int>(g.interior_cells.size());
      g.interior_cells.push_back(c);
    }
  return true;
}

// One square of the grid (axis a, plane k, cells j1 = sq[2], j2 = sq[3] along a+1, a+2) in its
// plane's (u, v): its corners, their nodes and the perimeter parameter τ ∈ [0, 4).
struct Square {
  int a, k, b1, b2;
  std::array<int, 4> sq;
  const std::array<int, 3>& n;
  Vec2 lo, hi;
  Vec2 corners[4];

  NodeId corner_id(int which) const {  // 0: (lo,lo) 1: (hi,lo) 2: (hi,hi) 3: (lo,hi)
    std::array<int, 3> v{};
    v[a] = k, v[b1] = sq[2] + (which == 1 || which == 2), v[b2] = sq[3] + (which >= 2);
    return kCornerNode + v[0] + (n[0] + 1) * (v[1] + (n[1] + 1) * static_cast<NodeId>(v[2]));
  }
  double tau(const Vec2& p) const {
    const double w1 = hi.x() - lo.x(), w2 = hi.y() - lo.y();
    const double d[4] = {std::abs(p.y() - lo.y()) / w2, std::abs(p.x() - hi.x()) / w1, std::abs(p.y() - hi.y()) / w2,
                         std::abs(p.x() - lo.x()) / w1};
    const int side = static_cast<int>(std::min_element(d, d + 4) - d);
    if (d[side] > 1e-7) throw FaceFailure{"a cut curve ends inside a cell face"};
    // A curve ending at a corner (a face lying in a grid plane or on the grid's box, e.g. an
    // aligned part whose side equals the grid's): the corner's exact τ, so the closing side
    // pieces neither repeat the corner nor take a zero-length piece to it.
    for (int c = 0; c < 4; ++c)
      if (std::abs(p.x() - corners[c].x()) <= 1e-9 * w1 && std::abs(p.y() - corners[c].y()) <= 1e-9 * w2) return double(c);
    switch (side) {
      case 0: return std::clamp((p.x() - lo.x()) / w1, 0.0, 1.0);
      case 1: return 1 + std::clamp((p.y() - lo.y()) / w2, 0.0, 1.0);
      case 2: return 2 + std::clamp((hi.x() - p.x()) / w1, 0.0, 1.0);
      default: return 3 + std::clamp((hi.y() - p.y()) / w2, 0.0, 1.0);
    }
  }
  // Close an open chain from τ0 to τ1 along the square's sides, counter-clockwise.
  void side_pieces(double t0, const Vec2& p0, NodeId n0, double t1, const Vec2& p1, NodeId n1, Loop& out) const {
    if (t1 <= t0) t1 += 4;
    Vec2 from = p0;
    NodeId from_id = n0;
    for (int c = static_cast<int>(std::floor(t0)) + 1; c < t1; ++c) {
      const Vec2 to = corners[c % 4];
      out.push_back({std::make_shared<Segment>(from, to), 0, 1, from_id, corner_id(c % 4)});
      from = to, from_id = corner_id(c % 4);
    }
    out.push_back({std::make_shared<Segment>(from, p1), 0, 1, from_id, n1});
  }
};

// The level pieces on a square of the faces' patches in the cell below it, reversed against the
// face's outward boundary.
std::vector<Piece> square_chain(const FaceRoute& r, const Square& s, const std::array<int, 3>& below) {
  std::vector<Piece> chain;
  auto it = r.in_cell.find(below);
  if (it != r.in_cell.end())
    for (const PatchRef& ref : it->second) {
      const bool forward = r.part.face(ref.face).Orientation() != TopAbs_REVERSED;
      for (const Loop& loop : r.patches[ref.face][ref.index].loops)
        for (const Piece& p : loop) {
          auto lc = std::dynamic_pointer_cast<const LevelCurve>(p.curve);
          if (!lc || lc->axis != s.a || lc->plane != s.k) continue;
          auto pc = std::make_shared<ProjectedCurve>(lc, r.surfaces[ref.face]);
          chain.push_back(forward ? Piece{pc, p.t1, p.t0, p.n1, p.n0} : Piece{pc, p.t0, p.t1, p.n0, p.n1});
        }
    }
  return chain;
}

// The chains linked at shared nodes into the square's loops: closed chains as they are, open
// ones closed along the square's sides; with no curve reaching the sides, the whole square or
// nothing by the state of its sides. Throws FaceFailure.
Region square_loops(const FaceRoute& r, PointTest& test, const Square& sq, const std::vector<Piece>& chain,
                    const std::array<int, 3>& below, const std::array<int, 3>& above) {
  const int a = sq.a, k = sq.k, b1 = sq.b1, b2 = sq.b2;
  const Vec2* corners = sq.corners;
  std::map<NodeId, int> starting;
  std::set<NodeId> ending;
  for (size_t i = 0; i < chain.size(); ++i) {
    if (!starting.emplace(chain[i].n0, static_cast<int>(i)).second)
      throw FaceFailure{"two cut curves leave one point on a cell face"};
    ending.insert(chain[i].n1);
  }
  std::vector<bool> used(chain.size(), false);
  Region loops;
  struct Open {
    Loop pieces;
    double t_start, t_end;
  };
  std::vector<Open> open;
  for (size_t i = 0; i < chain.size(); ++i) {  // open chains start where no piece ends
    if (used[i] || ending.count(chain[i].n0)) continue;
    Open oc;
    int j = static_cast<int>(i);
    while (j >= 0 && !used[j]) {
      used[j] = true;
      oc.pieces.push_back(chain[j]);
      auto s = starting.find(chain[j].n1);
      j = s == starting.end() ? -1 : s->second;
    }
    oc.t_start = sq.tau(oc.pieces.front().a());
    oc.t_end = sq.tau(oc.pieces.back().b());
    open.push_back(std::move(oc));
  }
  for (size_t i = 0; i < chain.size(); ++i) {  // closed chains
    if (used[i]) continue;
    Loop l;
    int j = static_cast<int>(i);
    while (!used[j]) {
      used[j] = true;
      l.push_back(chain[j]);
      auto s = starting.find(chain[j].n1);
      if (s == starting.end()) throw FaceFailure{"a cut curve on a cell face does not close"};
      j = s->second;
    }
    if (j != static_cast<int>(i)) throw FaceFailure{"cut curves on a cell face do not close"};
    loops.push_back(std::move(l));
  }
  // Close the open chains along the square's sides, counter-clockwise.
  if (!open.empty()) {
    std::vector<bool> done(open.size(), false);
    for (size_t i0 = 0; i0 < open.size(); ++i0) {
      if (done[i0]) continue;
      Loop l;
      size_t i = i0;
      while (!done[i]) {
        done[i] = true;
        l.insert(l.end(), open[i].pieces.begin(), open[i].pieces.end());
        // next start counter-clockwise after this end
        size_t best = open.size();
        double best_d = 1e300;
        for (size_t j = 0; j < open.size(); ++j) {
          double d = open[j].t_start - open[i].t_end;
          if (d <= 0) d += 4;
          if (d < best_d) best_d = d, best = j;
        }
        sq.side_pieces(open[i].t_end, open[i].pieces.back().b(), open[i].pieces.back().n1, open[best].t_start,
                       open[best].pieces.front().a(), open[best].pieces.front().n0, l);
        i = best;
      }
      if (i != i0) throw FaceFailure{"cut curves on a cell face close in the wrong order"};
      loops.push_back(std::move(l));
    }
  } else {
    // No curve reaches the square's sides: its sides lie wholly inside or outside.
    int st = -1;
    if (r.status[r.lin(below)] != 2) st = r.status[r.lin(below)];
    else if (r.status[r.lin(above)] != 2) st = r.status[r.lin(above)];
    else {  // the square's corners share the state of its sides (no curve reaches them)
      for (int c = 0; c < 4 && st < 0; ++c) {
        Vec3 p;
        p[a] = r.g.planes[a][k - 1], p[b1] = corners[c].x(), p[b2] = corners[c].y();
        const TopAbs_State s = test.at(p);
        if (s == TopAbs_IN || s == TopAbs_OUT) st = s == TopAbs_IN ? 1 : 0;
      }
      if (st < 0) throw FaceFailure{"the point tests of a cell face landed on the boundary"};
    }
    if (st == 1) {
      Loop l;
      for (int c = 0; c < 4; ++c)
        l.push_back({std::make_shared<Segment>(corners[c], corners[(c + 1) % 4]), 0, 1, sq.corner_id(c), sq.corner_id((c + 1) % 4)});
      loops.push_back(std::move(l));
    }
  }
  return loops;
}

// Grid patches on the squares of cut cells: the level pieces of the faces below the plane,
// reversed against the face's outward boundary, closed along the square's sides.
bool make_grid_patches(FaceRoute& r, PointTest& test) {
  const auto& n = r.n;
  std::set<std::array<int, 4>> squares;  // axis, plane, j1, j2
  for (const auto& [c, list] : r.in_cell)
    for (int a = 0; a < 3 && r.dirty(c); ++a) {
      const int j1 = c[(a + 1) % 3], j2 = c[(a + 2) % 3];
      if (c[a] > 0) squares.insert({a, c[a], j1, j2});
      if (c[a] + 1 < n[a]) squares.insert({a, c[a] + 1, j1, j2});
    }
  try {
    for (const auto& sq : squares) {
      const int a = sq[0], k = sq[1], b1 = (a + 1) % 3, b2 = (a + 2) % 3;
      std::array<int, 3> below{}, above{};
      below[a] = k - 1, above[a] = k, below[b1] = above[b1] = sq[2], below[b2] = above[b2] = sq[3];
      const Box3 cb = r.g.cell_box(below);
      const Vec2 lo(cb.min[b1], cb.min[b2]), hi(cb.max[b1], cb.max[b2]);
      const Square square{a, k, b1, b2, sq, n, lo, hi, {lo, Vec2(hi.x(), lo.y()), hi, Vec2(lo.x(), hi.y())}};
      const std::vector<Piece> chain = square_chain(r, square, below);
      for (Region& reg : group_loops(square_loops(r, test, square, chain, below, above), "a cell face"))
        r.grid_patches.push_back({a, k, {sq[2], sq[3]}, std::move(reg), {INT32_MIN, INT32_MIN}});
    }
  } catch (const FaceFailure& e) {
    r.g.message = "face route: " + e.why;
    return false;
  }
  return true;
}

// Grid patches of each cell: listed for the cut cells on either side, owned by the interior ones.
bool assign_grid_patches(FaceRoute& r) {
  for (size_t i = 0; i < r.grid_patches.size(); ++i) {
    const GridPatch& gp = r.grid_patches[i];
    std::array<int, 3> below{}, above{};
    below[gp.axis] = gp.plane - 1, above[gp.axis] = gp.plane;
    below[(gp.axis + 1) % 3] = above[(gp.axis + 1) % 3] = gp.cells2[0];
    below[(gp.axis + 2) % 3] = above[(gp.axis + 2) % 3] = gp.cells2[1];
    for (int sd = 0; sd < 2; ++sd) {
      const auto& c = sd == 0 ? below : above;
      const int st = r.status[r.lin(c)];
      if (st == 2 && !r.dirty(c)) continue;  // a kept cut cell: matched by the caller (block faces)
      if (st == 2) r.grid_in_cell[sd][c].push_back(static_cast<int>(i));
      else if (st == 1) r.grid_patches[i].owner[sd] = -1 - r.interior_index.at(c);
      else {
        r.g.message = "face route: a cell face's cross-section borders a cell outside the part";
        return false;
      }
    }
  }
  return true;
}

// A region's loops sampled into polynomial boundary segments (o.segment_order, tolerance
// relative to the region's size); `segments` counts them.
std::vector<xfem::BoundaryLoop> sample_loops(const Region& r, const GridOptions& o, int& segments) {
  std::vector<xfem::BoundaryLoop> out;
  Vec2 lo = Vec2::Constant(1e300), hi = Vec2::Constant(-1e300);
  for (const Loop& l : r)
    for (const Vec2& p : polyline(l, 4)) lo = lo.cwiseMin(p), hi = hi.cwiseMax(p);
  const double tol = o.segment_tolerance * (hi - lo).maxCoeff();
  for (const Loop& l : r) {
    xfem::BoundaryLoop bl;
    bl.order = o.segment_order;
    bl.points.push_back(l.front().a());
    for (const Piece& p : l)
      segments += append_curve<Vec2>([&](double t) { return p.curve->at(t); }, p.t0, p.t1, p.curve->straight(), o, tol, bl.points);
    bl.points.back() = bl.points.front();
    out.push_back(std::move(bl));
  }
  return out;
}

// Subvolumes: connected components of each dirty cut cell's patches (shared points), their
// patches (loops sampled later: r.loop_jobs) and the pieces that may be intersection curves
// (r.curve_jobs). With o.verify, every subvolume's boundary is checked to close.
void build_subvolumes(FaceRoute& r) {
  const PartShape& part = r.part;
  GridCut& g = r.g;
  std::vector<std::shared_ptr<const xfem::SurfaceMap>> maps(r.nf);
  for (int f = 0; f < r.nf; ++f)
    if (!r.surfaces[f].IsNull()) maps[f] = std::make_shared<OcctSurfaceMap>(r.surfaces[f]);
  for (const auto& [cell, list] : r.in_cell) {
    if (!r.dirty(cell)) continue;
    std::vector<PatchRef> refs = list;
    for (int sd = 0; sd < 2; ++sd) {
      auto it = r.grid_in_cell[sd].find(cell);
      if (it != r.grid_in_cell[sd].end())
        for (int i : it->second) refs.push_back({-1, i, sd == 0 ? 1 : -1});
    }
    auto region_of = [&](const PatchRef& ref) -> const Region& {
      return ref.face >= 0 ? r.patches[ref.face][ref.index].loops : r.grid_patches[ref.index].loops;
    };
    Components comp(static_cast<int>(refs.size()));
    std::map<NodeId, int> first_with;
    for (size_t i = 0; i < refs.size(); ++i)
      for (const Loop& l : region_of(refs[i]))
        for (const Piece& p : l)
          for (NodeId id : {p.n0, p.n1}) {
            auto [it, fresh] = first_with.emplace(id, static_cast<int>(i));
            if (!fresh) comp.join(static_cast<int>(i), it->second);
          }
    // Check: every subvolume's boundary closes (each curve between two points is run through
    // once in each direction by its patches, oriented outward).
    if (r.o.verify) {
      const auto tv = std::chrono::steady_clock::now();
      std::map<int, std::map<std::pair<NodeId, NodeId>, int>> directed;  // component root → counts
      for (size_t i = 0; i < refs.size(); ++i) {
        const PatchRef& ref = refs[i];
        const int sign = ref.face >= 0 ? (part.face(ref.face).Orientation() == TopAbs_REVERSED ? -1 : 1) : ref.sign;
        auto& d = directed[comp.find(static_cast<int>(i))];
        for (const Loop& l : region_of(ref))
          for (const Piece& p : l)
            if (p.n0 != p.n1) ++d[sign > 0 ? std::make_pair(p.n0, p.n1) : std::make_pair(p.n1, p.n0)];
      }
      for (const auto& [root, d] : directed)
        for (const auto& [e, count] : d) {
          auto it = d.find({e.second, e.first});
          if (it == d.end() || it->second != count) {
            if (r.open_edges++ == 0) r.first_open = static_cast<int>(g.subvolumes.size());
          }
        }
      r.verify_seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - tv).count();
    }
    std::map<int, int> sv_of_root;
    CutCell cc{cell, {}};
    for (size_t i = 0; i < refs.size(); ++i) {
      const int root = comp.find(static_cast<int>(i));
      auto [it, fresh] = sv_of_root.emplace(root, static_cast<int>(g.subvolumes.size()));
      if (fresh) {
        xfem::Subvolume sv;
        sv.cell = g.cell_box(cell);
        cc.subvolumes.push_back(it->second);
        g.subvolumes.push_back(std::move(sv));
      }
      const int s = it->second;
      const PatchRef& ref = refs[i];
      xfem::CutPatch patch;
      r.loop_jobs.push_back({s, static_cast<int>(g.subvolumes[s].patches.size()), &region_of(ref)});
      if (ref.face >= 0) {
        patch.surface = maps[ref.face];
        patch.orientation = part.face(ref.face).Orientation() == TopAbs_REVERSED ? -1 : 1;
        patch.source_face = ref.face;
        for (const Loop& l : region_of(ref))
          for (const Piece& p : l) {
            const bool level = dynamic_cast<const LevelCurve*>(p.curve.get()) != nullptr;
            r.curve_jobs.push_back({s, p, ref.face, level});
          }
      } else {
        GridPatch& gp = r.grid_patches[ref.index];
        patch.surface = std::make_shared<GridPlaneMap>(gp.axis, g.planes[gp.axis][gp.plane - 1]);
        patch.orientation = ref.sign;
        patch.grid_axis = gp.axis;
        gp.owner[ref.sign > 0 ? 0 : 1] = s;
        gp.patch[ref.sign > 0 ? 0 : 1] = static_cast<int>(g.subvolumes[s].patches.size());
      }
      g.subvolumes[s].patches.push_back(std::move(patch));
      ++g.patches;
    }
    g.cut_cells.push_back(std::move(cc));
  }
}

// The grid patches' two sides: subvolume–subvolume and subvolume–interior connections; on a
// re-cut, those facing a kept cut cell are left for block faces (r.pending).
bool connect_grid_patches(FaceRoute& r) {
  GridCut& g = r.g;
  for (size_t i = 0; i < r.grid_patches.size(); ++i) {
    const GridPatch& gp = r.grid_patches[i];
    const int a = gp.owner[0], b = gp.owner[1];
    if (r.recut && (a == INT32_MIN) != (b == INT32_MIN)) {
      r.pending.push_back(static_cast<int>(i));
      continue;
    }
    if (a == INT32_MIN || b == INT32_MIN) {
      g.message = "face route: a cell-face patch has no subvolume on one side";
      return false;
    }
    if (a >= 0 && b >= 0) g.connections.push_back({std::min(a, b), std::max(a, b)});
    else if (a >= 0 || b >= 0) g.interior_connections.push_back({std::max(a, b), -1 - std::min(a, b)});
  }
  return true;
}

// The patches' boundary loops as polynomial segments, in parallel.
void sample_patch_loops(FaceRoute& r) {
  GridCut& g = r.g;
  std::vector<int> segs(r.loop_jobs.size(), 0);
  auto run = [&](int i) {
    const LoopJob& j = r.loop_jobs[i];
    g.subvolumes[j.subvolume].patches[j.patch].loops = sample_loops(*j.region, r.o, segs[i]);
  };
  if (r.o.face_parallel) tbb::parallel_for(0, static_cast<int>(r.loop_jobs.size()), run);
  else
    for (int i = 0; i < static_cast<int>(r.loop_jobs.size()); ++i) run(i);
  for (int n : segs) g.segments += n;
}

// Block faces of the re-cut side, after its loops are sampled.
bool pending_block_faces(FaceRoute& r) {
  GridCut& g = r.g;
  for (int i : r.pending) {
    const GridPatch& gp = r.grid_patches[i];
    const int side = gp.owner[0] == INT32_MIN ? 1 : 0;  // the re-cut side
    const int owner = gp.owner[side];
    BlockFace bf;
    bf.owner = owner;
    bf.cell_face = {gp.axis, gp.plane, gp.cells2[0], gp.cells2[1]};
    bf.upper = side == 1;
    const double q = g.planes[gp.axis][gp.plane - 1];
    if (owner >= 0) {
      grid_patch_area_centroid(g.subvolumes[owner].patches[gp.patch[side]], gp.axis, q, bf.area, bf.centroid);
    } else {  // an interior cell facing a kept cut cell: cannot happen (squares come from re-cut cut cells)
      g.message = "face route re-cut: an interior cell's face borders a kept cut cell without a cut cell face";
      return false;
    }
    g.block_faces.push_back(bf);
  }
  return true;
}

// A face–plane intersection curve (a level piece) with its samples.
void level_curve(const FaceRoute& r, const CurveJob& job, CutCurve& curve, int& segments) {
  const PartShape& part = r.part;
  const GridOptions& o = r.o;
  const GridCut& g = r.g;
  const double h = g.cell_size.maxCoeff();
  const Piece& p = job.piece;
  const Handle(Geom_Surface)& S = r.surfaces[job.face];
  std::vector<double> ts{p.t0};
  const auto& L = static_cast<const LevelCurve&>(*p.curve);
  curve.kind = CutCurve::FacePlane;
  curve.sources = {job.face, -1 - L.axis};
  auto at3 = [&](double t) { const Vec2 uv = L.at(t); return to_vec(S->Value(uv.x(), uv.y())); };
  curve.points.push_back(at3(p.t0));
  segments += append_curve<Vec3>(at3, p.t0, p.t1, false, o, o.segment_tolerance * h, curve.points, &ts);
  for (size_t i = 0; i < ts.size(); ++i) {
    CutSample smp;
    const Vec2 uv = L.at(ts[i]);
    const Vec3& X = curve.points[i];
    smp.on.push_back({job.face, uv});
    smp.on.push_back({-1 - L.axis, Vec2(X[(L.axis + 1) % 3], X[(L.axis + 2) % 3])});
    const NodeId node = i == 0 ? p.n0 : (i + 1 == ts.size() ? p.n1 : -1);
    if (node >= 0 && (node & (3LL << 60)) == kEdgePlaneNode) {
      smp.kind = CutSample::EdgePlane;
      const NodeId code = node - kEdgePlaneNode;  // edge << 28 | axis << 26 | plane << 13 | root
      smp.edge = static_cast<int>(code >> 28);
      const int axis = static_cast<int>((code >> 26) & 3), plane = static_cast<int>((code >> 13) & 8191);
      const std::vector<double> rr = edge_plane_roots(part.edge(smp.edge), axis, g.planes[axis][plane - 1]);
      const size_t root = static_cast<size_t>(code & 8191);
      if (root < rr.size()) smp.edge_param = rr[root];
    } else if (node >= 0 && (node & (3LL << 60)) == kFaceNode) {
      smp.kind = CutSample::FacePlanePlane;
      for (int b = 0; b < 3; ++b) {
        if (b == L.axis) continue;
        const auto& pl = g.planes[b];
        for (double x : pl)
          if (std::abs(X[b] - x) < 1e-9 * h) smp.on.push_back({-1 - b, Vec2(X[(b + 1) % 3], X[(b + 2) % 3])});
      }
      // A face node on no second plane: where a closed level curve (an island) was opened.
      if (smp.on.size() == 2) smp.kind = CutSample::FacePlane;
    }
    curve.samples.push_back(std::move(smp));
  }
}

// A face–face intersection curve (a piece of an edge between two faces) with its samples.
void edge_curve(const FaceRoute& r, const CurveJob& job, const std::array<int, 2>& ff, CutCurve& curve, int& segments) {
  const PartShape& part = r.part;
  const GridOptions& o = r.o;
  const double h = r.g.cell_size.maxCoeff();
  const Piece& p = job.piece;
  std::vector<double> ts{p.t0};
  const auto* pc = static_cast<const PCurve*>(p.curve.get());
  const int e = pc->edge();
  const TopoDS_Edge& edge = part.edge(e);
  BRepAdaptor_Curve c3(edge);
  curve.kind = CutCurve::FaceFace;
  curve.sources = ff;
  auto at3 = [&](double t) { return to_vec(c3.Value(t)); };
  curve.points.push_back(at3(p.t0));
  segments += append_curve<Vec3>(at3, p.t0, p.t1, c3.GetType() == GeomAbs_Line, o, o.segment_tolerance * h,
                                 curve.points, &ts);
  std::array<Handle(Geom2d_Curve), 2> pcs;
  for (int j = 0; j < 2; ++j) {
    double f, l;
    pcs[j] = BRep_Tool::CurveOnSurface(edge, part.face(ff[j]), f, l);
  }
  for (size_t i = 0; i < ts.size(); ++i) {
    CutSample smp;
    smp.kind = CutSample::OnEdge;
    smp.edge = e;
    smp.edge_param = ts[i];
    for (int j = 0; j < 2; ++j)  // pcurve (u, v) refined onto the 3D point (pcurves approximate)
      if (!pcs[j].IsNull())
        smp.on.push_back({ff[j], refine_uv(r.surfaces[ff[j]], eval2(pcs[j], ts[i]), c3.Value(ts[i]), 1e-6 * (1 + eval2(pcs[j], ts[i]).norm()))});
    const NodeId node = i == 0 ? p.n0 : (i + 1 == ts.size() ? p.n1 : -1);
    if (node >= 0 && (node & (3LL << 60)) == kVertexNode) smp.kind = CutSample::Vertex, smp.edge = static_cast<int>(node);
    else if (node >= 0 && (node & (3LL << 60)) == kEdgePlaneNode) {
      smp.kind = CutSample::EdgePlane;
      const int axis = static_cast<int>(((node - kEdgePlaneNode) >> 26) & 3);
      const Vec3& X = curve.points[i];
      smp.on.push_back({-1 - axis, Vec2(X[(axis + 1) % 3], X[(axis + 2) % 3])});
    }
    curve.samples.push_back(std::move(smp));
  }
}

// Intersection curves with their samples: level pieces, and edge pieces (once, not seams), in
// parallel; appended to g.curves on a re-cut.
void intersection_curves(FaceRoute& r) {
  const PartShape& part = r.part;
  GridCut& g = r.g;
  std::map<int, std::array<int, 2>> edge_faces;
  for (int e = 0; e < part.edge_count(); ++e) edge_faces[e] = {-1, -1};
  {
    TopTools_IndexedDataMapOfShapeListOfShape ef;
    TopExp::MapShapesAndAncestors(part.shape, TopAbs_EDGE, TopAbs_FACE, ef);
    for (int i = 1; i <= ef.Extent(); ++i) {
      const int e = part.edge_index(ef.FindKey(i));
      std::vector<int> fs;
      for (const TopoDS_Shape& f : ef(i)) fs.push_back(part.face_index(f));
      if (fs.size() == 2) edge_faces[e] = {std::min(fs[0], fs[1]), std::max(fs[0], fs[1])};
    }
  }
  // Which pieces are intersection curves: level pieces, and edge pieces (once, not seams).
  std::set<std::tuple<int, NodeId, NodeId>> edge_done;
  std::vector<CurveJob> jobs;
  for (const CurveJob& job : r.curve_jobs) {
    if (!job.level) {
      const auto* pc = dynamic_cast<const PCurve*>(job.piece.curve.get());
      if (!pc) continue;
      const auto ff = edge_faces.at(pc->edge());
      if (ff[0] < 0 || ff[0] == ff[1]) continue;  // seam or free edge: not an intersection curve
      if (!edge_done.emplace(pc->edge(), std::min(job.piece.n0, job.piece.n1), std::max(job.piece.n0, job.piece.n1)).second)
        continue;
    }
    jobs.push_back(job);
  }
  std::vector<CutCurve> curves(jobs.size());
  std::vector<int> curve_segments(jobs.size(), 0);
  auto make_curve = [&](int job_index) {
    const CurveJob& job = jobs[job_index];
    CutCurve& curve = curves[job_index];
    curve.subvolume = job.subvolume;
    curve.order = r.o.segment_order;
    if (job.level) level_curve(r, job, curve, curve_segments[job_index]);
    else
      edge_curve(r, job, edge_faces.at(static_cast<const PCurve*>(job.piece.curve.get())->edge()), curve,
                 curve_segments[job_index]);
  };
  if (r.o.face_parallel) tbb::parallel_for(0, static_cast<int>(jobs.size()), make_curve);
  else
    for (int i = 0; i < static_cast<int>(jobs.size()); ++i) make_curve(i);
  for (int n : curve_segments) g.segments += n;
  if (r.recut) g.curves.insert(g.curves.end(), std::make_move_iterator(curves.begin()), std::make_move_iterator(curves.end()));
  else g.curves = std::move(curves);
}

}  // namespace

bool cut_by_faces(const PartShape& part, const GridOptions& o, GridCut& g, FaceRecut* recut) {
  FaceRoute r{part, o, g, recut, g.cells};
  r.nf = part.face_count();
  r.ncells = r.n[0] * r.n[1] * r.n[2];
  if (recut && (static_cast<int>(recut->dirty.size()) != r.ncells || static_cast<int>(recut->status.size()) != r.ncells)) {
    g.message = "face route re-cut: the cell lists do not match the grid";
    return false;
  }
  if (!cut_faces(r, faces_to_cut(r))) return false;
  PointTest test{BRepClass3d_SolidClassifier(part.shape), g.cell_size.maxCoeff()};
  if (!classify_cells(r, test) || !make_grid_patches(r, test) || !assign_grid_patches(r)) return false;
  build_subvolumes(r);
  if (!connect_grid_patches(r)) return false;
  sample_patch_loops(r);
  if (!pending_block_faces(r)) return false;
  intersection_curves(r);
  if (g.cut_cells.empty() && g.interior_cells.empty()) {
    g.message = "face route: no cell meets the part";
    return false;
  }

  g.verify_seconds = r.verify_seconds;
  if (r.open_edges > 0) {
    g.verify_open_edges = r.open_edges;
    g.message = "face route check failed: " + std::to_string(r.open_edges) + " boundary curve(s) of subvolume " +
                std::to_string(r.first_open) + " are not matched by an opposite curve (its boundary does not close)";
    return false;
  }
  return true;
}

}  // namespace parafab::occ::detail
