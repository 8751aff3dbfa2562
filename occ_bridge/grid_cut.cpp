#include "grid_cut.h"

#include <BRepAlgoAPI_Splitter.hxx>
#include <BRepBndLib.hxx>
#include <BRepBuilderAPI_MakeFace.hxx>
#include <BRepBuilderAPI_NurbsConvert.hxx>
#include <Standard_Failure.hxx>
#include <BRepTools.hxx>
#include <BRepTools_WireExplorer.hxx>
#include <BRep_Tool.hxx>
#include <Bnd_Box.hxx>
#include <Geom2d_Curve.hxx>
#include <Geom2d_Line.hxx>
#include <Geom_Curve.hxx>
#include <Geom_Line.hxx>
#include <Geom_Surface.hxx>
#include <Message_Report.hxx>
#include <TopExp.hxx>
#include <TopExp_Explorer.hxx>
#include <TopTools_DataMapOfShapeInteger.hxx>
#include <TopTools_IndexedDataMapOfShapeListOfShape.hxx>
#include <TopoDS.hxx>
#include <TopoDS_Face.hxx>
#include <TopoDS_Wire.hxx>
#include <gp_Pln.hxx>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <map>
#include <sstream>

#include "common/error.h"
#include "occt_shape.h"

namespace parafab::occ {

using xfem::Box3;
using xfem::Vec2;
using xfem::Vec3;

xfem::Box3 GridCut::cell_box(const std::array<int, 3>& ijk) const {
  Box3 b;
  for (int a = 0; a < 3; ++a) {
    b.min[a] = ijk[a] == 0 ? grid.min[a] : planes[a][ijk[a] - 1];
    b.max[a] = ijk[a] == cells[a] - 1 ? grid.max[a] : planes[a][ijk[a]];
  }
  return b;
}

namespace {

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

Box3 tight_box(const TopoDS_Shape& s) {
  Bnd_Box bb;
  BRepBndLib::AddOptimal(s, bb, /*useTriangulation=*/false, /*useShapeTolerance=*/false);
  double x0, y0, z0, x1, y1, z1;
  bb.Get(x0, y0, z0, x1, y1, z1);
  Box3 b;
  b.min = Vec3(x0, y0, z0);
  b.max = Vec3(x1, y1, z1);
  return b;
}

/// The surface of a face (location applied) as the quadrature's SurfaceMap.
class OcctSurfaceMap : public xfem::SurfaceMap {
 public:
  explicit OcctSurfaceMap(Handle(Geom_Surface) s) : surface_(std::move(s)) {}
  void evaluate(double u, double v, Vec3& X, Vec3& Xu, Vec3& Xv) const override {
    gp_Pnt p;
    gp_Vec du, dv;
    surface_->D1(u, v, p, du, dv);
    X = Vec3(p.X(), p.Y(), p.Z());
    Xu = Vec3(du.X(), du.Y(), du.Z());
    Xv = Vec3(dv.X(), dv.Y(), dv.Z());
  }

 private:
  Handle(Geom_Surface) surface_;
};

Vec2 eval2(const Handle(Geom2d_Curve)& c, double t) {
  const gp_Pnt2d p = c->Value(t);
  return Vec2(p.X(), p.Y());
}

// Appends the curve `at(t)` from t0 to t1 (t1 < t0 for a reversed edge) as `order`
// polynomial segments (without the first point, which the caller already holds), refined by
// doubling until the interpolant deviates less than `tol` from the curve at interior test
// points. Returns the number of segments.
template <class Vec, class Eval>
int append_curve(const Eval& at, double t0, double t1, bool straight, const GridOptions& o,
                 double tol, std::vector<Vec>& out) {
  int n = 1;
  const int order = o.segment_order;
  auto point_at = [&](int k, int n_seg, double frac) { return at(t0 + (t1 - t0) * (k + frac) / n_seg); };
  while (!straight && n < o.max_segments_per_edge) {
    double err = 0;
    for (int k = 0; k < n && err <= tol; ++k) {
      const Vec p0 = point_at(k, n, 0), p1 = point_at(k, n, 1);
      if (order == 1) {
        for (double f : {0.25, 0.5, 0.75})
          err = std::max(err, (point_at(k, n, f) - ((1 - f) * p0 + f * p1)).norm());
      } else {
        const Vec pm = point_at(k, n, 0.5);
        for (double f : {0.25, 0.75}) {  // Lagrange parabola through t = 0, 1/2, 1
          const Vec q = 2 * (f - 0.5) * (f - 1) * p0 - 4 * f * (f - 1) * pm + 2 * f * (f - 0.5) * p1;
          err = std::max(err, (point_at(k, n, f) - q).norm());
        }
      }
    }
    if (err <= tol) break;
    n *= 2;
  }
  for (int k = 0; k < n; ++k) {
    if (order == 2) out.push_back(point_at(k, n, 0.5));
    out.push_back(point_at(k, n, 1.0));
  }
  return n;
}

int append_pcurve(const Handle(Geom2d_Curve)& c, double t0, double t1, const GridOptions& o,
                  double tol, std::vector<Vec2>& out) {
  const bool straight = c->DynamicType() == STANDARD_TYPE(Geom2d_Line);
  return append_curve<Vec2>([&](double t) { return eval2(c, t); }, t0, t1, straight, o, tol, out);
}

// Boundary loops of a face in its surface's natural (u, v), material on the left.
std::vector<xfem::BoundaryLoop> face_loops(const TopoDS_Face& face_in, const GridOptions& o,
                                           int& segments) {
  const TopoDS_Face face = TopoDS::Face(face_in.Oriented(TopAbs_FORWARD));
  double u0, u1, v0, v1;
  BRepTools::UVBounds(face, u0, u1, v0, v1);
  const double tol = o.segment_tolerance * std::max(u1 - u0, v1 - v0);
  std::vector<xfem::BoundaryLoop> loops;
  for (TopExp_Explorer wires(face, TopAbs_WIRE); wires.More(); wires.Next()) {
    xfem::BoundaryLoop loop;
    loop.order = o.segment_order;
    for (BRepTools_WireExplorer ex(TopoDS::Wire(wires.Current()), face); ex.More(); ex.Next()) {
      const TopoDS_Edge& e = ex.Current();
      double f, l;
      Handle(Geom2d_Curve) pc = BRep_Tool::CurveOnSurface(e, face, f, l);
      if (pc.IsNull()) continue;
      const bool rev = e.Orientation() == TopAbs_REVERSED;
      const double ta = rev ? l : f, tb = rev ? f : l;
      if (loop.points.empty()) loop.points.push_back(eval2(pc, ta));
      segments += append_pcurve(pc, ta, tb, o, tol, loop.points);
    }
    if (loop.points.size() >= 3) {
      loop.points.back() = loop.points.front();  // close exactly (pcurve ends agree to tolerance)
      loops.push_back(std::move(loop));
    }
  }
  return loops;
}

// Interior grid planes of one axis, shifted off vertices and face extremes.
std::vector<double> grid_planes(double lo, double h, int n, const std::vector<double>& avoid,
                                double shift, int& shifted) {
  std::vector<double> planes;
  for (int k = 1; k < n; ++k) {
    double x = lo + k * h;
    for (int attempt = 0; attempt < 16 && shift > 0; ++attempt) {
      const bool clash = std::any_of(avoid.begin(), avoid.end(),
                                     [&](double a) { return std::abs(a - x) <= shift * h; });
      if (!clash) break;
      x += (attempt % 2 == 0 ? 1.0 : -2.0) * 1.5 * shift * h;  // +1.5, −1.5, ... deterministic
      if (attempt == 0) ++shifted;
    }
    planes.push_back(x);
  }
  return planes;
}

// A point inside the closed box of a piece (cheap, unlike an optimal bounding box): the mean
// of its vertices, edge midpoints and face mid-parameter points.
Vec3 representative_point(const TopoDS_Shape& solid) {
  Vec3 sum = Vec3::Zero();
  int n = 0;
  auto add = [&](const gp_Pnt& p) { sum += Vec3(p.X(), p.Y(), p.Z()), ++n; };
  for (TopExp_Explorer ex(solid, TopAbs_VERTEX); ex.More(); ex.Next())
    add(BRep_Tool::Pnt(TopoDS::Vertex(ex.Current())));
  for (TopExp_Explorer ex(solid, TopAbs_EDGE); ex.More(); ex.Next()) {
    double f, l;
    Handle(Geom_Curve) c = BRep_Tool::Curve(TopoDS::Edge(ex.Current()), f, l);
    if (!c.IsNull()) add(c->Value(0.5 * (f + l)));
  }
  for (TopExp_Explorer ex(solid, TopAbs_FACE); ex.More(); ex.Next()) {
    const TopoDS_Face& f = TopoDS::Face(ex.Current());
    double u0, u1, v0, v1;
    BRepTools::UVBounds(f, u0, u1, v0, v1);
    add(BRep_Tool::Surface(f)->Value(0.5 * (u0 + u1), 0.5 * (v0 + v1)));
  }
  return sum / std::max(n, 1);
}

std::array<int, 3> cell_of(const Vec3& p, const GridCut& g) {
  std::array<int, 3> ijk{};
  for (int a = 0; a < 3; ++a) {
    const auto& pl = g.planes[a];
    ijk[a] = static_cast<int>(std::upper_bound(pl.begin(), pl.end(), p[a]) - pl.begin());
  }
  return ijk;
}

}  // namespace

GridCut cut_by_grid(const PartShape& part, const GridOptions& o) {
  PARAFAB_VERIFY(o.cells_longest >= 1, "grid: cells must be >= 1, got " << o.cells_longest);
  PARAFAB_VERIFY(o.cell_size >= 0, "grid: cell size must be >= 0, got " << o.cell_size);
  PARAFAB_VERIFY(o.segment_order == 1 || o.segment_order == 2,
                 "grid: segment order must be 1 or 2, got " << o.segment_order);
  GridCut g;
  const auto t0 = std::chrono::steady_clock::now();
  const Box3 bb = tight_box(part.shape);
  const Vec3 ext = bb.size();
  const double h = o.cell_size > 0 ? o.cell_size : ext.maxCoeff() / o.cells_longest;
  // What the planes must avoid: vertex coordinates and every face's extreme coordinates.
  std::array<std::vector<double>, 3> avoid;
  for (TopExp_Explorer ex(part.shape, TopAbs_VERTEX); ex.More(); ex.Next()) {
    const gp_Pnt p = BRep_Tool::Pnt(TopoDS::Vertex(ex.Current()));
    for (int a = 0; a < 3; ++a) avoid[a].push_back(p.Coord(a + 1));
  }
  for (int i = 1; i <= part.faces.Extent(); ++i) {
    const Box3 fb = tight_box(part.faces(i));
    for (int a = 0; a < 3; ++a) avoid[a].push_back(fb.min[a]), avoid[a].push_back(fb.max[a]);
  }
  for (int a = 0; a < 3; ++a) {
    double lo;
    if (o.anchored) {
      lo = o.origin[a] + std::floor((bb.min[a] - o.origin[a]) / h) * h;
      g.cells[a] = std::max(1, static_cast<int>(std::ceil((bb.max[a] - lo) / h - 1e-9)));
    } else {
      g.cells[a] = std::max(1, static_cast<int>(std::ceil(ext[a] / h - 1e-9)));
      lo = bb.min[a] - 0.5 * (g.cells[a] * h - ext[a]);
    }
    const double span = g.cells[a] * h;
    g.grid.min[a] = std::min(lo, bb.min[a]);
    g.grid.max[a] = std::max(lo + span, bb.max[a]);
    g.cell_size[a] = h;
    g.planes[a] = grid_planes(lo, h, g.cells[a], avoid[a], o.perturbation, g.shifted_planes);
  }

  // Split the solid by all grid planes at once.
  const double big = 2.0 * (bb.max.cwiseAbs().maxCoeff() + bb.min.cwiseAbs().maxCoeff() + ext.norm());
  // The solid that is cut, and its faces in face-model order.
  TopoDS_Shape solid_to_cut = part.shape;
  std::vector<TopoDS_Shape> faces_to_cut(part.face_count());
  for (int i = 0; i < part.face_count(); ++i) faces_to_cut[i] = part.face(i);
  if (o.nurbs) {
    try {
      BRepBuilderAPI_NurbsConvert convert(part.shape, true);
      solid_to_cut = convert.Shape();
      for (int i = 0; i < part.face_count(); ++i) faces_to_cut[i] = convert.ModifiedShape(part.face(i));
    } catch (const Standard_Failure& e) {
      g.message = std::string("conversion of the faces to NURBS failed: ") + e.GetMessageString();
      return g;
    }
  }
  TopTools_ListOfShape args, tools;
  args.Append(solid_to_cut);
  std::vector<std::pair<TopoDS_Shape, int>> tool_faces;  // (face, axis)
  for (int a = 0; a < 3; ++a)
    for (double x : g.planes[a]) {
      gp_Pnt p(0, 0, 0);
      p.SetCoord(a + 1, x);
      gp_Dir n(a == 0, a == 1, a == 2);
      const TopoDS_Face f = BRepBuilderAPI_MakeFace(gp_Pln(p, n), -big, big, -big, big).Face();
      tools.Append(f);
      tool_faces.emplace_back(f, a);
    }
  TopoDS_Shape pieces = solid_to_cut;
  BRepAlgoAPI_Splitter splitter;
  if (!tools.IsEmpty()) {
    splitter.SetArguments(args);
    splitter.SetTools(tools);
    splitter.SetRunParallel(o.parallel);
    splitter.SetNonDestructive(true);
    splitter.SetUseOBB(true);  // oriented boxes prune more face pairs (l_bracket: −30 %)
    splitter.Build();
    if (splitter.HasErrors() || !splitter.IsDone()) {
      std::ostringstream os;
      splitter.GetReport()->Dump(os);
      g.message = "OCCT's splitter failed to cut the part by the grid: " + os.str();
      return g;
    }
    pieces = splitter.Shape();
  }
  g.split_seconds = seconds_since(t0);
  const auto t1 = std::chrono::steady_clock::now();

  // Where every face of the pieces came from: a B-rep face (index) or a grid plane (axis).
  TopTools_DataMapOfShapeInteger source;  // ≥ 0: B-rep face index; −1 − axis: grid plane
  for (int i = 0; i < part.face_count(); ++i) {
    const TopoDS_Shape& f = faces_to_cut[i];
    bool modified = false;
    if (!tools.IsEmpty())
      for (const TopoDS_Shape& m : splitter.Modified(f)) source.Bind(m, i), modified = true;
    if (!modified) source.Bind(f, i);
  }
  for (const auto& [f, axis] : tool_faces)
    for (const TopoDS_Shape& m : splitter.Modified(f)) source.Bind(m, -1 - axis);

  TopTools_IndexedDataMapOfShapeListOfShape face_solids;
  TopExp::MapShapesAndAncestors(pieces, TopAbs_FACE, TopAbs_SOLID, face_solids);
  TopTools_DataMapOfShapeInteger solid_id;  // piece → subvolume index, or −1 − cell for interior
  std::map<std::array<int, 3>, int> cut_cell_of;
  std::vector<TopoDS_Shape> solids;
  for (TopExp_Explorer ex(pieces, TopAbs_SOLID); ex.More(); ex.Next()) solids.push_back(ex.Current());
  for (const TopoDS_Shape& solid : solids) {
    const std::array<int, 3> ijk = cell_of(representative_point(solid), g);
    xfem::Subvolume sv;
    sv.cell = g.cell_box(ijk);
    bool cut = false;
    for (TopExp_Explorer fx(solid, TopAbs_FACE); fx.More(); fx.Next()) {
      const TopoDS_Face& face = TopoDS::Face(fx.Current());
      int src = -1;
      if (!source.Find(face, src)) {
        g.message = "a face of the cut part has no known origin (neither B-rep face nor grid plane)";
        return g;
      }
      xfem::CutPatch patch;
      patch.surface = std::make_shared<OcctSurfaceMap>(BRep_Tool::Surface(face));
      patch.loops = face_loops(face, o, g.segments);
      patch.orientation = face.Orientation() == TopAbs_REVERSED ? -1 : 1;
      patch.source_face = src >= 0 ? src : -1;
      patch.grid_axis = src >= 0 ? -1 : -1 - src;
      cut |= src >= 0;
      sv.patches.push_back(std::move(patch));
    }
    if (!cut) {  // a whole cell inside the part: tensor Gauss rule later, no patches needed
      g.interior_cells.push_back(ijk);
      solid_id.Bind(solid, -1 - static_cast<int>(g.interior_cells.size() - 1));
      continue;
    }
    // Intersection curves of this subvolume: B-rep face ∩ grid plane, and B-rep face ∩ B-rep face.
    TopTools_IndexedDataMapOfShapeListOfShape edge_faces;
    TopExp::MapShapesAndAncestors(solid, TopAbs_EDGE, TopAbs_FACE, edge_faces);
    for (int e = 1; e <= edge_faces.Extent(); ++e) {
      const TopoDS_Edge& edge = TopoDS::Edge(edge_faces.FindKey(e));
      const TopTools_ListOfShape& faces = edge_faces(e);
      if (faces.Extent() != 2 || BRep_Tool::Degenerated(edge) || faces.First().IsSame(faces.Last())) continue;
      int sa = -1, sb = -1;
      source.Find(faces.First(), sa);
      source.Find(faces.Last(), sb);
      if (sa < 0 && sb < 0) continue;  // a straight cell edge
      double f, l;
      Handle(Geom_Curve) c = BRep_Tool::Curve(edge, f, l);
      if (c.IsNull()) continue;
      CutCurve curve;
      curve.subvolume = static_cast<int>(g.subvolumes.size());
      curve.kind = (sa >= 0 && sb >= 0) ? CutCurve::FaceFace : CutCurve::FacePlane;
      curve.sources = {sa, sb};
      curve.order = o.segment_order;
      curve.points.push_back(Vec3(c->Value(f).X(), c->Value(f).Y(), c->Value(f).Z()));
      append_curve<Vec3>([&](double t) { const gp_Pnt p = c->Value(t); return Vec3(p.X(), p.Y(), p.Z()); },
                         f, l, c->DynamicType() == STANDARD_TYPE(Geom_Line), o,
                         o.segment_tolerance * h, curve.points);
      g.curves.push_back(std::move(curve));
    }
    auto [it, fresh] = cut_cell_of.try_emplace(ijk, static_cast<int>(g.cut_cells.size()));
    if (fresh) g.cut_cells.push_back({ijk, {}});
    g.cut_cells[it->second].subvolumes.push_back(static_cast<int>(g.subvolumes.size()));
    solid_id.Bind(solid, static_cast<int>(g.subvolumes.size()));
    g.patches += static_cast<int>(sv.patches.size());
    g.subvolumes.push_back(std::move(sv));
  }
  // Connectivity through shared grid faces.
  for (int i = 1; i <= face_solids.Extent(); ++i) {
    const TopTools_ListOfShape& owners = face_solids(i);
    if (owners.Extent() != 2) continue;
    const int a = solid_id.Find(owners.First()), b = solid_id.Find(owners.Last());
    if (a >= 0 && b >= 0) g.connections.push_back({std::min(a, b), std::max(a, b)});
    else if (a >= 0 || b >= 0) g.interior_connections.push_back({std::max(a, b), -1 - std::min(a, b)});
  }
  g.extract_seconds = seconds_since(t1);
  g.done = true;
  return g;
}

}  // namespace parafab::occ
