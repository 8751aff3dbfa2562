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
#include <BRepGProp.hxx>
#include <GeomAPI_ProjectPointOnSurf.hxx>
#include <Geom_BSplineSurface.hxx>
#include <GProp_GProps.hxx>
#include <Message_Report.hxx>
#include <TopExp.hxx>
#include <TopExp_Explorer.hxx>
#include <TopTools_DataMapOfShapeInteger.hxx>
#include <TopTools_IndexedDataMapOfShapeListOfShape.hxx>
#include <TopoDS.hxx>
#include <TopoDS_Face.hxx>
#include <TopoDS_Wire.hxx>
#include <BRepAdaptor_Surface.hxx>
#include <gp_Cylinder.hxx>
#include <gp_Pln.hxx>

#include <algorithm>
#include <climits>
#include <set>
#include <chrono>
#include <cmath>
#include <map>
#include <sstream>

#include "common/error.h"
#include "grid_cut_detail.h"
#include "occt_shape.h"

namespace parafab::occ {

using xfem::Box3;
using xfem::Vec2;
using xfem::Vec3;
using detail::OcctSurfaceMap;
using detail::append_curve;
using detail::eval2;
using detail::tight_box;

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
      // The splitter's pcurves of plane ∩ surface edges are B-spline approximations of the
      // exact 3D section curve (a conic for planes against cylinders, cones and spheres); their
      // (u, v) are off by up to the edge tolerance, which moved subvolume moments by ~2e-9 of
      // the cell volume. So the (u, v) of a point is its pcurve value refined by Gauss–Newton
      // onto the 3D curve's point (same parameter: SameParameter edges).
      double c0, c1;
      Handle(Geom_Curve) c3 = BRep_Tool::Curve(e, c0, c1);
      if (o.project_pcurves && !c3.IsNull() && BRep_Tool::SameParameter(e) && !BRep_Tool::Degenerated(e) &&
          std::abs(c0 - f) < 1e-12 * (1 + std::abs(f)) && std::abs(c1 - l) < 1e-12 * (1 + std::abs(l))) {
        const Handle(Geom_Surface) S = BRep_Tool::Surface(face);
        auto at = [&](double t) { return detail::refine_uv(S, eval2(pc, t), c3->Value(t), 1e-6 * (u1 - u0 + v1 - v0)); };
        const bool straight = pc->DynamicType() == STANDARD_TYPE(Geom2d_Line);
        segments += append_curve<Vec2>(at, ta, tb, straight, o, tol, loop.points);
      } else {
        segments += append_pcurve(pc, ta, tb, o, tol, loop.points);
      }
    }
    if (loop.points.size() >= 3) {
      loop.points.back() = loop.points.front();  // close exactly (pcurve ends agree to tolerance)
      loops.push_back(std::move(loop));
    }
  }
  return loops;
}

// A plane at x moved off every coordinate of `avoid` within shift·h: by +1.5, −1.5, ... × shift·h
// (deterministic); `shifted` counts moved planes.
double clear_plane(double x, double h, const std::vector<double>& avoid, double shift, int& shifted) {
  for (int attempt = 0; attempt < 16 && shift > 0; ++attempt) {
    const bool clash = std::any_of(avoid.begin(), avoid.end(), [&](double a) { return std::abs(a - x) <= shift * h; });
    if (!clash) break;
    x += (attempt % 2 == 0 ? 1.0 : -2.0) * 1.5 * shift * h;
    if (attempt == 0) ++shifted;
  }
  return x;
}

// Interior grid planes of one axis, shifted off vertices and face extremes.
std::vector<double> grid_planes(double lo, double h, int n, const std::vector<double>& avoid,
                                double shift, int& shifted) {
  std::vector<double> planes;
  for (int k = 1; k < n; ++k) planes.push_back(clear_plane(lo + k * h, h, avoid, shift, shifted));
  return planes;
}

// What the grid planes must avoid: vertex coordinates and every face's extreme coordinates.
std::array<std::vector<double>, 3> plane_avoid(const PartShape& part) {
  std::array<std::vector<double>, 3> avoid;
  for (TopExp_Explorer ex(part.shape, TopAbs_VERTEX); ex.More(); ex.Next()) {
    const gp_Pnt p = BRep_Tool::Pnt(TopoDS::Vertex(ex.Current()));
    for (int a = 0; a < 3; ++a) avoid[a].push_back(p.Coord(a + 1));
  }
  for (int i = 1; i <= part.faces.Extent(); ++i) {
    const Box3 fb = tight_box(part.faces(i));
    for (int a = 0; a < 3; ++a) avoid[a].push_back(fb.min[a]), avoid[a].push_back(fb.max[a]);
  }
  return avoid;
}

// Grid lines (two planes of the other axes) lying on a cylinder whose axis is parallel to a grid
// axis (a ruling: e.g. x = 9, z = 10 on the bracket's r = 5 fillet about (13, 13) at 40 cells; the
// face route then meets a grid vertex on the surface): the second plane is shifted like a plane
// near a vertex (also clear of `avoid`), until no such line is left.
void shift_off_rulings(const PartShape& part, const std::array<std::vector<double>, 3>& avoid, double shift, double h,
                       std::array<std::vector<double>, 3>& planes, int& shifted) {
  if (shift <= 0) return;
  for (int f = 0; f < part.face_count(); ++f) {
    BRepAdaptor_Surface s(part.face(f), false);
    if (s.GetType() != GeomAbs_Cylinder) continue;
    const gp_Cylinder cyl = s.Cylinder();
    const gp_Dir d = cyl.Axis().Direction();
    for (int a = 0; a < 3; ++a) {
      if (std::abs(d.Coord(a + 1)) < 1 - 1e-12) continue;
      const int b1 = (a + 1) % 3, b2 = (a + 2) % 3;
      const double c1 = cyl.Location().Coord(b1 + 1), c2 = cyl.Location().Coord(b2 + 1), r = cyl.Radius();
      for (double& z : planes[b2]) {
        auto clash = [&] {
          for (double x : planes[b1])
            if (std::abs(std::hypot(x - c1, z - c2) - r) <= shift * h) return true;
          return std::any_of(avoid[b2].begin(), avoid[b2].end(), [&](double v) { return std::abs(v - z) <= shift * h; });
        };
        for (int attempt = 0; attempt < 16 && clash(); ++attempt) {
          z += (attempt % 2 == 0 ? 1.0 : -2.0) * 1.5 * shift * h;
          if (attempt == 0) ++shifted;
        }
      }
    }
  }
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


// Face origins: ≥ 0 a B-rep face; −1 − axis a grid plane inside a block; −4 − axis a block plane.
int plane_source(int axis, bool block_plane) { return -1 - axis - (block_plane ? 3 : 0); }
int axis_of_source(int src) { return (-1 - src) % 3; }
bool is_block_plane(int src) { return src <= -4; }

using PlaneList = std::vector<std::pair<int, double>>;  // (axis, coordinate)

// Splits `shape` by the planes; `source` maps the faces of `shape` to their origin on entry and
// the faces of the result on return. Empty result with `error` set if OCCT's splitter fails.
TopoDS_Shape split_by_planes(const TopoDS_Shape& shape, const PlaneList& planes, bool block_planes,
                             double big, bool parallel, TopTools_DataMapOfShapeInteger& source,
                             std::string& error) {
  if (planes.empty()) return shape;
  TopTools_ListOfShape args, tools;
  args.Append(shape);
  std::vector<std::pair<TopoDS_Shape, int>> tool_faces;
  for (const auto& [a, x] : planes) {
    gp_Pnt p(0, 0, 0);
    p.SetCoord(a + 1, x);
    const TopoDS_Face f = BRepBuilderAPI_MakeFace(gp_Pln(p, gp_Dir(a == 0, a == 1, a == 2)), -big, big, -big, big).Face();
    tools.Append(f);
    tool_faces.emplace_back(f, plane_source(a, block_planes));
  }
  BRepAlgoAPI_Splitter splitter;
  splitter.SetArguments(args);
  splitter.SetTools(tools);
  splitter.SetRunParallel(parallel);
  splitter.SetNonDestructive(true);
  splitter.SetUseOBB(true);  // oriented boxes prune more face pairs (l_bracket: −30 %)
  splitter.Build();
  if (splitter.HasErrors() || !splitter.IsDone()) {
    std::ostringstream os;
    splitter.GetReport()->Dump(os);
    error = "OCCT's splitter failed to cut the part by the grid: " + os.str();
    return TopoDS_Shape();
  }
  TopTools_DataMapOfShapeInteger out;
  for (TopExp_Explorer ex(shape, TopAbs_FACE); ex.More(); ex.Next()) {
    int src;
    if (!source.Find(ex.Current(), src)) continue;
    bool modified = false;
    for (const TopoDS_Shape& m : splitter.Modified(ex.Current())) out.Bind(m, src), modified = true;
    if (!modified) out.Bind(ex.Current(), src);
  }
  for (const auto& [f, src] : tool_faces)
    for (const TopoDS_Shape& m : splitter.Modified(f)) out.Bind(m, src);
  source = std::move(out);
  return splitter.Shape();
}

// The grid, its planes and the two-level split, shared by cut_by_grid and recut_by_grid.
class GridCutter {
 public:
  GridCutter(GridCut& g, const GridOptions& o, double big) : g_(g), o_(o), big_(big) {
    m_ = g.block_cells > 0 ? g.block_cells : std::max({g.cells[0], g.cells[1], g.cells[2]});
    for (int a = 0; a < 3; ++a) blocks_[a] = (g.cells[a] + m_ - 1) / m_;
    for (size_t c = 0; c < g.cut_cells.size(); ++c) cut_cell_of_[g.cut_cells[c].index] = static_cast<int>(c);
  }
  int blocks() const { return blocks_[0] * blocks_[1] * blocks_[2]; }
  std::array<int, 3> block_of_cell(const std::array<int, 3>& c) const { return {c[0] / m_, c[1] / m_, c[2] / m_}; }
  Box3 block_box(const std::array<int, 3>& b) const {
    std::array<int, 3> lo, hi;
    for (int a = 0; a < 3; ++a) lo[a] = b[a] * m_, hi[a] = std::min(g_.cells[a], lo[a] + m_) - 1;
    return Box3{g_.cell_box(lo).min, g_.cell_box(hi).max};
  }

  /// Splits `solid` (faces mapped to origins by `source`) into blocks, then every block piece
  /// whose block passes `wanted` into cells, appending subvolumes, interior cells, curves,
  /// connections inside blocks and block faces to the cut. False with g.message on failure.
  template <class Wanted>
  bool cut(const TopoDS_Shape& solid, TopTools_DataMapOfShapeInteger source, const Wanted& wanted) {
    PlaneList block_planes;
    for (int a = 0; a < 3; ++a)
      for (int k = m_; k < g_.cells[a]; k += m_) block_planes.emplace_back(a, g_.planes[a][k - 1]);
    const TopoDS_Shape blocks = split_by_planes(solid, block_planes, true, big_, o_.parallel, source, g_.message);
    if (blocks.IsNull()) return false;
    for (TopExp_Explorer ex(blocks, TopAbs_SOLID); ex.More(); ex.Next()) {
      const TopoDS_Shape& piece = ex.Current();
      const std::array<int, 3> b = block_of_cell(cell_of(representative_point(piece), g_));
      if (!wanted(b)) continue;
      bool brep = false;
      for (TopExp_Explorer fx(piece, TopAbs_FACE); fx.More() && !brep; fx.Next()) {
        int src = -1;
        brep = source.Find(fx.Current(), src) && src >= 0;
      }
      if (!brep) {  // the whole block lies inside the part: interior cells, no splitting
        add_interior_block(b);
        continue;
      }
      ++g_.blocks_cut;
      Bnd_Box pb;
      BRepBndLib::Add(piece, pb);
      double lo[3], hi[3];
      pb.Get(lo[0], lo[1], lo[2], hi[0], hi[1], hi[2]);
      PlaneList inner;
      for (int a = 0; a < 3; ++a)
        for (int k = b[a] * m_ + 1; k < std::min(g_.cells[a], (b[a] + 1) * m_); ++k) {
          const double x = g_.planes[a][k - 1];
          if (x > lo[a] && x < hi[a]) inner.emplace_back(a, x);
        }
      TopTools_DataMapOfShapeInteger piece_source = source;
      const TopoDS_Shape cells = split_by_planes(piece, inner, false, big_, o_.parallel, piece_source, g_.message);
      if (cells.IsNull()) return false;
      if (!extract(cells, piece_source)) return false;
    }
    return true;
  }

 private:
  void add_block_face(int owner, const std::array<int, 3>& c, int axis, bool lower_side, const Vec3& centroid, double area) {
    BlockFace f;
    f.owner = owner;
    f.upper = lower_side;  // a face on the cell's lower side: the owner lies above the plane
    f.cell_face = {axis, lower_side ? c[axis] : c[axis] + 1, c[(axis + 1) % 3], c[(axis + 2) % 3]};
    f.centroid = centroid;
    f.area = area;
    g_.block_faces.push_back(f);
  }

  void add_interior_block(const std::array<int, 3>& b) {
    std::array<int, 3> lo, hi;
    for (int a = 0; a < 3; ++a) lo[a] = b[a] * m_, hi[a] = std::min(g_.cells[a], lo[a] + m_);
    for (int i = lo[0]; i < hi[0]; ++i)
      for (int j = lo[1]; j < hi[1]; ++j)
        for (int k = lo[2]; k < hi[2]; ++k) {
          const std::array<int, 3> c{i, j, k};
          g_.interior_cells.push_back(c);
          const int owner = -static_cast<int>(g_.interior_cells.size());
          const Box3 box = g_.cell_box(c);
          for (int a = 0; a < 3; ++a) {
            const Vec3 d = box.size();
            const double area = d[(a + 1) % 3] * d[(a + 2) % 3];
            Vec3 centre = 0.5 * (box.min + box.max);
            if (c[a] == lo[a] && c[a] > 0) centre[a] = box.min[a], add_block_face(owner, c, a, true, centre, area);
            centre = 0.5 * (box.min + box.max);
            if (c[a] == hi[a] - 1 && c[a] + 1 < g_.cells[a]) centre[a] = box.max[a], add_block_face(owner, c, a, false, centre, area);
          }
        }
  }

  // Subvolumes and interior cells of one block piece split into cells.
  bool extract(const TopoDS_Shape& pieces, const TopTools_DataMapOfShapeInteger& source) {
    const double h = g_.cell_size.maxCoeff();
    TopTools_IndexedDataMapOfShapeListOfShape face_solids;
    TopExp::MapShapesAndAncestors(pieces, TopAbs_FACE, TopAbs_SOLID, face_solids);
    TopTools_DataMapOfShapeInteger solid_id;  // piece → subvolume index, or −1 − cell for interior
    std::vector<TopoDS_Shape> solids;
    for (TopExp_Explorer ex(pieces, TopAbs_SOLID); ex.More(); ex.Next()) solids.push_back(ex.Current());
    for (const TopoDS_Shape& solid : solids) {
      const std::array<int, 3> ijk = cell_of(representative_point(solid), g_);
      xfem::Subvolume sv;
      sv.cell = g_.cell_box(ijk);
      bool cut = false;
      struct Pending { int axis; bool lower; Vec3 centroid; double area; };
      std::vector<Pending> on_block_faces;
      for (TopExp_Explorer fx(solid, TopAbs_FACE); fx.More(); fx.Next()) {
        const TopoDS_Face& face = TopoDS::Face(fx.Current());
        int src = -1;
        if (!source.Find(face, src)) {
          g_.message = "a face of the cut part has no known origin (neither B-rep face nor grid plane)";
          return false;
        }
        if (is_block_plane(src)) {
          GProp_GProps props;
          BRepGProp::SurfaceProperties(face, props);
          const gp_Pnt c = props.CentreOfMass();
          const int a = axis_of_source(src);
          const bool lower = std::abs(c.Coord(a + 1) - sv.cell.min[a]) < std::abs(c.Coord(a + 1) - sv.cell.max[a]);
          on_block_faces.push_back({a, lower, Vec3(c.X(), c.Y(), c.Z()), props.Mass()});
        }
        xfem::CutPatch patch;
        patch.surface = std::make_shared<OcctSurfaceMap>(BRep_Tool::Surface(face));
        patch.loops = face_loops(face, o_, g_.segments);
        patch.orientation = face.Orientation() == TopAbs_REVERSED ? -1 : 1;
        patch.source_face = src >= 0 ? src : -1;
        patch.grid_axis = src >= 0 ? -1 : axis_of_source(src);
        cut |= src >= 0;
        sv.patches.push_back(std::move(patch));
      }
      int owner;
      if (!cut) {  // a whole cell inside the part: tensor Gauss rule later, no patches needed
        g_.interior_cells.push_back(ijk);
        owner = -static_cast<int>(g_.interior_cells.size());
      } else {
        owner = static_cast<int>(g_.subvolumes.size());
        add_curves(solid, source, owner, h);
        auto [it, fresh] = cut_cell_of_.try_emplace(ijk, static_cast<int>(g_.cut_cells.size()));
        if (fresh) g_.cut_cells.push_back({ijk, {}});
        g_.cut_cells[it->second].subvolumes.push_back(owner);
        g_.patches += static_cast<int>(sv.patches.size());
        g_.subvolumes.push_back(std::move(sv));
      }
      solid_id.Bind(solid, owner);
      for (const Pending& p : on_block_faces) add_block_face(owner, ijk, p.axis, p.lower, p.centroid, p.area);
    }
    // Connectivity inside the block through shared grid faces.
    for (int i = 1; i <= face_solids.Extent(); ++i) {
      const TopTools_ListOfShape& owners = face_solids(i);
      if (owners.Extent() != 2) continue;
      const int a = solid_id.Find(owners.First()), b = solid_id.Find(owners.Last());
      if (a >= 0 && b >= 0) g_.connections.push_back({std::min(a, b), std::max(a, b)});
      else if (a >= 0 || b >= 0) g_.interior_connections.push_back({std::max(a, b), -1 - std::min(a, b)});
    }
    return true;
  }

  // Intersection curves of a subvolume: B-rep face ∩ grid plane, and B-rep face ∩ B-rep face.
  void add_curves(const TopoDS_Shape& solid, const TopTools_DataMapOfShapeInteger& source, int subvolume, double h) {
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
      curve.subvolume = subvolume;
      curve.kind = (sa >= 0 && sb >= 0) ? CutCurve::FaceFace : CutCurve::FacePlane;
      curve.sources = {sa >= 0 ? sa : -1 - axis_of_source(sa), sb >= 0 ? sb : -1 - axis_of_source(sb)};
      curve.order = o_.segment_order;
      curve.points.push_back(Vec3(c->Value(f).X(), c->Value(f).Y(), c->Value(f).Z()));
      append_curve<Vec3>([&](double t) { const gp_Pnt p = c->Value(t); return Vec3(p.X(), p.Y(), p.Z()); },
                         f, l, c->DynamicType() == STANDARD_TYPE(Geom_Line), o_,
                         o_.segment_tolerance * h, curve.points);
      g_.curves.push_back(std::move(curve));
    }
  }

  GridCut& g_;
  const GridOptions& o_;
  double big_;
  int m_ = 1;
  std::array<int, 3> blocks_{1, 1, 1};
  std::map<std::array<int, 3>, int> cut_cell_of_;
};

// Connects pieces cut in different blocks: the two sides of a block face hold the same face
// (same cell face, area and centroid). Only pairs with an entry at index ≥ first_new.
void match_block_faces(GridCut& g, size_t first_new) {
  const double h = g.cell_size.maxCoeff();
  std::map<std::array<int, 4>, std::vector<int>> by_face;
  for (size_t i = 0; i < g.block_faces.size(); ++i) by_face[g.block_faces[i].cell_face].push_back(static_cast<int>(i));
  for (const auto& [key, list] : by_face)
    for (int i : list)
      for (int j : list) {
        const BlockFace& lo = g.block_faces[i];
        const BlockFace& up = g.block_faces[j];
        if (lo.upper || !up.upper) continue;
        if (static_cast<size_t>(std::max(i, j)) < first_new) continue;
        if ((lo.centroid - up.centroid).norm() > 1e-6 * h || std::abs(lo.area - up.area) > 1e-6 * h * h) continue;
        const int a = lo.owner, b = up.owner;
        if (a >= 0 && b >= 0) g.connections.push_back({std::min(a, b), std::max(a, b)});
        else if (a >= 0 || b >= 0) g.interior_connections.push_back({std::max(a, b), -1 - std::min(a, b)});
      }
}

double big_size(const Box3& bb) {
  return 2.0 * (bb.max.cwiseAbs().maxCoeff() + bb.min.cwiseAbs().maxCoeff() + bb.size().norm());
}

// The solid to cut and the origin of its faces (face-model indices), NURBS-converted on request.
bool shape_to_cut(const PartShape& part, const GridOptions& o, TopoDS_Shape& solid,
                  TopTools_DataMapOfShapeInteger& source, std::string& message) {
  solid = part.shape;
  std::vector<TopoDS_Shape> faces(part.face_count());
  for (int i = 0; i < part.face_count(); ++i) faces[i] = part.face(i);
  if (o.nurbs) {
    try {
      BRepBuilderAPI_NurbsConvert convert(part.shape, true);
      solid = convert.Shape();
      for (int i = 0; i < part.face_count(); ++i) faces[i] = convert.ModifiedShape(part.face(i));
    } catch (const Standard_Failure& e) {
      message = std::string("conversion of the faces to NURBS failed: ") + e.GetMessageString();
      return false;
    }
  }
  for (int i = 0; i < part.face_count(); ++i) source.Bind(faces[i], i);
  return true;
}

}  // namespace

namespace {

// One cut on the grid the options define (no shifted retries).
GridCut cut_on_grid(const PartShape& part, const GridOptions& o) {
  PARAFAB_VERIFY(o.cells_longest >= 1, "grid: cells must be >= 1, got " << o.cells_longest);
  PARAFAB_VERIFY(o.cell_size >= 0, "grid: cell size must be >= 0, got " << o.cell_size);
  PARAFAB_VERIFY(o.segment_order == 1 || o.segment_order == 2,
                 "grid: segment order must be 1 or 2, got " << o.segment_order);
  PARAFAB_VERIFY(o.block_cells >= 0, "grid: block_cells must be >= 0, got " << o.block_cells);
  GridCut g;
  const auto t0 = std::chrono::steady_clock::now();
  const Box3 bb = tight_box(part.shape);
  const Vec3 ext = bb.size();
  const double h = o.cell_size > 0 ? o.cell_size : ext.maxCoeff() / o.cells_longest;
  const std::array<std::vector<double>, 3> avoid = plane_avoid(part);
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
    g.origin[a] = lo;
    g.planes[a] = grid_planes(lo, h, g.cells[a], avoid[a], o.perturbation, g.shifted_planes);
  }
  shift_off_rulings(part, avoid, o.perturbation, h, g.planes, g.shifted_planes);
  g.block_cells = o.block_cells;
  if (o.method == CutMethod::FaceCut) {
    GridCut f = g;
    f.block_cells = 0;  // no blocks: re-cutting a face-route cut cuts it again whole
    f.method = CutMethod::FaceCut;
    // With `nurbs`, the face route cuts the NURBS-converted faces (the generic traced path), so
    // its patches are pieces of the face model's NURBS as on the splitter route.
    std::shared_ptr<const PartShape> converted;
    bool ok = true;
    if (o.nurbs) {
      try {
        BRepBuilderAPI_NurbsConvert convert(part.shape, true);
        converted = make_part(convert.Shape(), "NURBS");
        for (int i = 0; i < part.face_count() && ok; ++i)
          ok = converted->face_count() == part.face_count() && convert.ModifiedShape(part.face(i)).IsSame(converted->face(i));
        if (!ok) f.message = "face route: the NURBS conversion renumbered the faces";
      } catch (const Standard_Failure& e) {
        ok = false;
        f.message = std::string("face route: conversion of the faces to NURBS failed: ") + e.GetMessageString();
      } catch (const std::exception& e) {
        ok = false;
        f.message = std::string("face route: the NURBS-converted part is invalid: ") + e.what();
      }
    }
    if (ok && detail::cut_by_faces(converted ? *converted : part, o, f)) {
      f.split_seconds = seconds_since(t0);
      f.done = true;
      return f;
    }
    g.message = f.message;
    g.failed_axis = f.failed_axis;
    g.method = CutMethod::FaceCut;
    return g;
  }
  g.method = CutMethod::Splitter;
  TopoDS_Shape solid;
  TopTools_DataMapOfShapeInteger source;
  if (!shape_to_cut(part, o, solid, source, g.message)) return g;
  GridCutter cutter(g, o, big_size(bb));
  if (!cutter.cut(solid, source, [](const std::array<int, 3>&) { return true; })) return g;
  match_block_faces(g, 0);
  g.split_seconds = seconds_since(t0);  // splitting and extraction interleave per block
  g.done = true;
  return g;
}

}  // namespace

GridOptions shifted_grid(const GridCut& failed, const GridOptions& o, int k) {
  GridOptions so = o;
  const double h = failed.cell_size.maxCoeff();
  so.anchored = true;
  so.cell_size = h;
  xfem::Vec3 step(0.118, 0.141, 0.173);
  if (failed.failed_axis >= 0 && k == 1)  // first along the failing plane's axis, then along all
    for (int a = 0; a < 3; ++a)
      if (a != failed.failed_axis) step[a] = 0;
  so.origin = failed.origin + (k * h) * step;
  so.shift_retries = 0;
  return so;
}

GridCut cut_by_grid(const PartShape& part, const GridOptions& o) {
  PARAFAB_VERIFY(o.shift_retries >= 0, "grid: shift_retries must be >= 0, got " << o.shift_retries);
  GridCut g = cut_on_grid(part, o);
  if (g.done || o.method != CutMethod::FaceCut || o.shift_retries == 0 || g.cell_size.maxCoeff() <= 0) return g;
  const std::string reason = g.message;
  for (int k = 1; k <= o.shift_retries; ++k) {
    const GridOptions so = shifted_grid(g, o, k);
    GridCut s = cut_on_grid(part, so);
    if (s.done) {
      s.retry_reason = reason;
      s.grid_shift = so.origin - g.origin;
      return s;
    }
  }
  g.message = reason + " (and again on grids shifted by up to " + std::to_string(o.shift_retries) +
              " × (0.118, 0.141, 0.173) cells)";
  return g;
}

namespace {

// Change detection. A face whose surface has no old face on the same surface changes as a
// whole; a face on an unchanged surface (a plate whose hole grows) changes only between its
// old and new trimming edges, so only edges without an identical old edge mark it.
struct EdgeSignature {
  double length;
  Vec3 centroid;
  Box3 box;
};

EdgeSignature edge_signature(const TopoDS_Shape& e) {
  GProp_GProps props;
  BRepGProp::LinearProperties(e, props);
  const gp_Pnt c = props.CentreOfMass();
  return {props.Mass(), Vec3(c.X(), c.Y(), c.Z()), tight_box(e)};
}

bool same_edge(const EdgeSignature& a, const EdgeSignature& b, double tol) {
  return std::abs(a.length - b.length) <= tol && (a.centroid - b.centroid).norm() <= tol &&
         (a.box.min - b.box.min).norm() <= tol && (a.box.max - b.box.max).norm() <= tol;
}

// Points of the face's underlying surface over its uv box (they need not lie on the face). A
// B-spline surface adds the centre of every knot span in the box: a moved pole changes the
// surface everywhere inside its support (its basis function is positive there), which holds
// at least one whole span, so a pole moved on an otherwise unchanged surface is seen.
std::vector<gp_Pnt> surface_samples(const TopoDS_Face& f) {
  double u0, u1, v0, v1;
  BRepTools::UVBounds(f, u0, u1, v0, v1);
  const Handle(Geom_Surface) s = BRep_Tool::Surface(f);
  std::vector<gp_Pnt> pts;
  for (double a : {0.1, 0.5, 0.9})
    for (double b : {0.1, 0.5, 0.9}) pts.push_back(s->Value(u0 + a * (u1 - u0), v0 + b * (v1 - v0)));
  if (const auto bs = Handle(Geom_BSplineSurface)::DownCast(s)) {
    auto centres = [](const TColStd_Array1OfReal& knots, double lo, double hi) {
      std::vector<double> c;
      for (int k = knots.Lower(); k < knots.Upper(); ++k) {
        const double a = std::max(knots(k), lo), b = std::min(knots(k + 1), hi);
        if (b > a) c.push_back(0.5 * (a + b));
      }
      return c;
    };
    for (double u : centres(bs->UKnots(), u0, u1))
      for (double v : centres(bs->VKnots(), v0, v1)) pts.push_back(s->Value(u, v));
  }
  return pts;
}

// True if every sample lies on face g's underlying surface.
bool on_surface_of(const std::vector<gp_Pnt>& samples, const TopoDS_Face& g, double tol) {
  const Handle(Geom_Surface) s = BRep_Tool::Surface(g);
  for (const gp_Pnt& p : samples) {
    GeomAPI_ProjectPointOnSurf proj(p, s);
    if (!proj.IsDone() || proj.NbPoints() == 0 || proj.LowerDistance() > tol) return false;
  }
  return true;
}

}  // namespace

namespace {

// The boxes of the changes between old_part and part (merged until no two overlap), counted in R.
// `shapes`, if given, receives the changed faces and edges themselves (of both parts).
std::vector<Box3> changed_regions(const PartShape& part, const PartShape& old_part, double tol, RecutReport& R,
                                  std::vector<TopoDS_Shape>* shapes = nullptr) {
  // Changed regions: faces on a surface no old face lies on (and old ones gone), and edges
  // without an identical old edge (and old ones gone); the dirty box holds them all.
  // Each changed face or edge adds its box; overlapping boxes are merged into the box around
  // them (one region per connected change: a hole that grows, a face that moves together with
  // the faces beside it), so the region between old and new positions is covered.
  std::vector<Box3> changes;
  auto grow = [&](const Box3& b) { changes.push_back(b); };
  auto face_boxes = [](const PartShape& p) {
    std::vector<Box3> boxes;
    for (int i = 0; i < p.face_count(); ++i) boxes.push_back(tight_box(p.face(i)));
    return boxes;
  };
  const std::vector<Box3> new_boxes = face_boxes(part), old_boxes = face_boxes(old_part);
  auto unmatched_faces = [&](const PartShape& from, const std::vector<Box3>& from_boxes, const PartShape& to,
                             const std::vector<Box3>& to_boxes) {
    for (int i = 0; i < from.face_count(); ++i) {
      const Box3& fb = from_boxes[i];
      const std::vector<gp_Pnt> samples = surface_samples(from.face(i));
      bool found = false;
      for (int j = 0; j < to.face_count() && !found; ++j) {
        const Box3& tb = to_boxes[j];  // cheap reject: boxes must overlap
        if (((fb.max - tb.min).array() < -tol).any() || ((tb.max - fb.min).array() < -tol).any()) continue;
        found = on_surface_of(samples, to.face(j), tol);
      }
      if (!found) {
        ++R.changed_faces, grow(fb);
        if (shapes) shapes->push_back(from.face(i));
      }
    }
  };
  unmatched_faces(part, new_boxes, old_part, old_boxes);
  unmatched_faces(old_part, old_boxes, part, new_boxes);
  std::vector<EdgeSignature> old_edges, new_edges;
  for (int i = 0; i < old_part.edge_count(); ++i) old_edges.push_back(edge_signature(old_part.edge(i)));
  for (int i = 0; i < part.edge_count(); ++i) new_edges.push_back(edge_signature(part.edge(i)));
  std::vector<bool> old_matched(old_edges.size(), false);
  for (const auto& n : new_edges) {
    bool found = false;
    for (size_t j = 0; j < old_edges.size() && !found; ++j)
      if (!old_matched[j] && same_edge(n, old_edges[j], tol)) old_matched[j] = found = true;
    if (!found) {
      ++R.changed_edges, grow(n.box);
      if (shapes) shapes->push_back(part.edge(static_cast<int>(&n - new_edges.data())));
    }
  }
  for (size_t j = 0; j < old_edges.size(); ++j)
    if (!old_matched[j]) {
      ++R.changed_edges, grow(old_edges[j].box);
      if (shapes) shapes->push_back(old_part.edge(static_cast<int>(j)));
    }
  auto overlap = [&](const Box3& a, const Box3& b) {
    return !(((a.max - b.min).array() < -tol).any() || ((b.max - a.min).array() < -tol).any());
  };
  std::vector<Box3> dirty;  // merged until no two overlap
  for (Box3 b : changes) {
    for (bool merged = true; merged;) {
      merged = false;
      for (size_t k = 0; k < dirty.size(); ++k)
        if (overlap(dirty[k], b)) {
          b.min = b.min.cwiseMin(dirty[k].min), b.max = b.max.cwiseMax(dirty[k].max);
          dirty.erase(dirty.begin() + static_cast<long>(k));
          merged = true;
          break;
        }
    }
    dirty.push_back(b);
  }
  R.regions = static_cast<int>(dirty.size());
  return dirty;
}

bool boxes_overlap(const Box3& a, const Box3& b, double tol) {
  return !(((a.max - b.min).array() < -tol).any() || ((b.max - a.min).array() < -tol).any());
}

// Face route re-cut (thesis §6.3 per face, issue 11 §1): the cells whose boxes meet a changed
// region are cut again by the face route; every other cell keeps its subvolumes, curves and
// connections; pieces meeting across a kept/re-cut cell face are matched by that face.
// Points on a changed face (its surface over its uv box) or edge, at most `spacing` apart
// (chord estimate), for marking the cells it meets.
std::vector<Vec3> shape_samples(const TopoDS_Shape& shape, double spacing) {
  std::vector<Vec3> out;
  auto v3 = [](const gp_Pnt& p) { return Vec3(p.X(), p.Y(), p.Z()); };
  if (shape.ShapeType() == TopAbs_FACE) {
    const TopoDS_Face& f = TopoDS::Face(shape);
    double u0, u1, v0, v1;
    BRepTools::UVBounds(f, u0, u1, v0, v1);
    const Handle(Geom_Surface) S = BRep_Tool::Surface(f);
    auto chord = [&](bool along_u, double w) {
      double L = 0;
      gp_Pnt prev = along_u ? S->Value(u0, w) : S->Value(w, v0);
      for (int i = 1; i <= 64; ++i) {
        const double t = i / 64.0;
        const gp_Pnt q = along_u ? S->Value(u0 + t * (u1 - u0), w) : S->Value(w, v0 + t * (v1 - v0));
        L += prev.Distance(q), prev = q;
      }
      return L;
    };
    double Lu = 0, Lv = 0;
    for (double t : {0.0, 0.5, 1.0}) {
      Lu = std::max(Lu, chord(true, v0 + t * (v1 - v0)));
      Lv = std::max(Lv, chord(false, u0 + t * (u1 - u0)));
    }
    const int nu = std::clamp(static_cast<int>(std::ceil(2 * Lu / spacing)), 1, 1000);
    const int nv = std::clamp(static_cast<int>(std::ceil(2 * Lv / spacing)), 1, 1000);
    for (int i = 0; i <= nu; ++i)
      for (int j = 0; j <= nv; ++j) out.push_back(v3(S->Value(u0 + (u1 - u0) * i / nu, v0 + (v1 - v0) * j / nv)));
  } else if (shape.ShapeType() == TopAbs_EDGE) {
    const TopoDS_Edge& e = TopoDS::Edge(shape);
    if (BRep_Tool::Degenerated(e)) return out;
    double a, b;
    const Handle(Geom_Curve) c = BRep_Tool::Curve(e, a, b);
    if (c.IsNull()) return out;
    GProp_GProps props;
    BRepGProp::LinearProperties(e, props);
    const int n = std::clamp(static_cast<int>(std::ceil(4 * props.Mass() / spacing)), 2, 20000);
    for (int i = 0; i <= n; ++i) {
      gp_Pnt p = c->Value(a + (b - a) * i / n);
      p.Transform(e.Location().Transformation());
      out.push_back(v3(p));
    }
  }
  return out;
}

GridCut recut_by_faces(const PartShape& part, const GridCut& old, const std::vector<Box3>& dirty_boxes,
                       const std::vector<TopoDS_Shape>& changed, const GridOptions& o, RecutReport& R,
                       std::string& why_not) {
  const double h = old.cell_size.maxCoeff();
  const double tol = 1e-7 * h;
  const auto& n = old.cells;
  auto lin = [&](const std::array<int, 3>& c) { return c[0] + n[0] * (c[1] + n[1] * c[2]); };
  const int ncells = n[0] * n[1] * n[2];
  detail::FaceRecut fr;
  fr.dirty.assign(ncells, 0);
  fr.status.assign(ncells, 0);
  for (const auto& c : old.interior_cells) fr.status[lin(c)] = 1;
  for (const auto& c : old.cut_cells) fr.status[lin(c.index)] = 2;
  // Cells the changed faces and edges (old and new) meet: every sample marks the cells within
  // `margin` of it (samples are at most a quarter cell apart on the chord estimate).
  const double spacing = 0.25 * h, margin = 0.5 * spacing + 1e-7 * h;
  for (const TopoDS_Shape& shape : changed)
    for (const Vec3& p : shape_samples(shape, spacing)) {
      std::array<int, 3> lo{}, hi{};
      for (int a = 0; a < 3; ++a) {
        const auto& pl = old.planes[a];
        lo[a] = static_cast<int>(std::upper_bound(pl.begin(), pl.end(), p[a] - margin) - pl.begin());
        hi[a] = std::min(n[a] - 1, static_cast<int>(std::upper_bound(pl.begin(), pl.end(), p[a] + margin) - pl.begin()));
      }
      for (int i = lo[0]; i <= hi[0]; ++i)
        for (int j = lo[1]; j <= hi[1]; ++j)
          for (int k = lo[2]; k <= hi[2]; ++k) fr.dirty[lin({i, j, k})] = 1;
    }
  // Uncut cells inside a change region may have been swept through whole (a face moving more
  // than a cell): their state is tested again (one point test per connected run).
  for (int k = 0; k < n[2]; ++k)
    for (int j = 0; j < n[1]; ++j)
      for (int i = 0; i < n[0]; ++i) {
        if (fr.status[lin({i, j, k})] == 2) continue;
        const Box3 cb = old.cell_box({i, j, k});
        for (const Box3& d : dirty_boxes)
          if (boxes_overlap(cb, d, tol)) fr.dirty[lin({i, j, k})] = 1;
      }
  // The planes a fresh cut of the new part would pick on this grid: a plane the old part let
  // stand may now pass through a new vertex or face extreme (l_bracket r 4 → 5 at 24 cells: x = 35
  // touches the hole, a tangent crossing), so it is shifted as cut_by_grid does, and the cells on
  // both sides of every moved plane are cut again (their boxes changed).
  // With a recut_clearance the old planes stay, moved only off features closer than it.
  std::array<std::vector<double>, 3> planes;
  int shifted = 0;
  const auto avoid = plane_avoid(part);
  const bool keep = o.recut_clearance > 0 && o.perturbation > 0;
  for (int a = 0; a < 3; ++a)
    if (keep) {
      planes[a] = old.planes[a];
      for (double& x : planes[a]) x = clear_plane(x, old.cell_size[a], avoid[a], o.recut_clearance, shifted);
    } else {
      planes[a] = grid_planes(old.grid.min[a], old.cell_size[a], n[a], avoid[a], o.perturbation, shifted);
    }
  shift_off_rulings(part, avoid, keep ? o.recut_clearance : o.perturbation, h, planes, shifted);
  for (int a = 0; a < 3; ++a)
    for (size_t j = 0; j < planes[a].size(); ++j) {
      if (std::abs(planes[a][j] - old.planes[a][j]) <= 1e-9 * h) {
        planes[a][j] = old.planes[a][j];  // unchanged: kept cells keep their exact boxes
        continue;
      }
      ++R.planes_moved;
      for (int k = 0; k < n[(a + 2) % 3]; ++k)
        for (int i = 0; i < n[(a + 1) % 3]; ++i)
          for (int side = 0; side < 2; ++side) {
            std::array<int, 3> c{};
            c[a] = static_cast<int>(j) + side, c[(a + 1) % 3] = i, c[(a + 2) % 3] = k;
            fr.dirty[lin(c)] = 1;
          }
    }
  for (int i = 0; i < ncells; ++i) R.cells_recut += fr.dirty[i] && fr.status[i] == 2;
  R.cells = ncells;

  GridCut g;
  g.grid = old.grid;
  g.cells = old.cells;
  g.cell_size = old.cell_size;
  g.planes = planes;
  g.shifted_planes = shifted;
  g.block_cells = 0;
  g.method = CutMethod::FaceCut;
  // Keep the clean cut cells.
  std::vector<int> new_sv(old.subvolumes.size(), -1);
  for (const CutCell& c : old.cut_cells) {
    if (fr.dirty[lin(c.index)]) continue;
    CutCell kept{c.index, {}};
    for (int s : c.subvolumes) {
      new_sv[s] = static_cast<int>(g.subvolumes.size());
      kept.subvolumes.push_back(new_sv[s]);
      g.subvolumes.push_back(old.subvolumes[s]);
      g.patches += static_cast<int>(old.subvolumes[s].patches.size());
      R.kept_from.push_back(s);
    }
    g.cut_cells.push_back(std::move(kept));
  }
  R.subvolumes_kept = static_cast<int>(g.subvolumes.size());
  for (const auto& [a, b] : old.connections)
    if (new_sv[a] >= 0 && new_sv[b] >= 0) g.connections.push_back({new_sv[a], new_sv[b]});
  std::vector<std::pair<int, std::array<int, 3>>> to_interior;  // (kept subvolume, interior cell)
  for (const auto& [s, c] : old.interior_connections)
    if (new_sv[s] >= 0 && !fr.dirty[lin(old.interior_cells[c])]) to_interior.push_back({new_sv[s], old.interior_cells[c]});
  for (const CutCurve& c : old.curves)
    if (new_sv[c.subvolume] >= 0) {
      g.curves.push_back(c);
      g.curves.back().subvolume = new_sv[c.subvolume];
    }
  if (!detail::cut_by_faces(part, o, g, &fr)) {
    why_not = g.message;
    return g;
  }
  R.faces_recut = fr.faces_cut;
  R.cut_cells_recut = fr.cells_cut;
  std::map<std::array<int, 3>, int> interior_of;
  for (size_t i = 0; i < g.interior_cells.size(); ++i) interior_of[g.interior_cells[i]] = static_cast<int>(i);
  for (const auto& [s, c] : to_interior) {
    auto it = interior_of.find(c);
    if (it == interior_of.end()) {
      why_not = "a kept interior cell is no longer interior";
      return g;
    }
    g.interior_connections.push_back({s, it->second});
  }
  // Grid-face patches of kept subvolumes facing a re-cut cell: connected to the new interior
  // cell there, or matched with the new subvolume's patch on that cell face.
  const size_t new_faces = g.block_faces.size();
  for (const CutCell& c : g.cut_cells) {
    if (fr.dirty[lin(c.index)]) continue;
    for (int s : c.subvolumes)
      for (const xfem::CutPatch& p : g.subvolumes[s].patches) {
        const int a = p.grid_axis;
        if (a < 0) continue;
        std::array<int, 3> nb = c.index;
        nb[a] += p.orientation > 0 ? 1 : -1;
        if (nb[a] < 0 || nb[a] >= n[a] || !fr.dirty[lin(nb)]) continue;
        auto it = interior_of.find(nb);
        if (it != interior_of.end()) {
          g.interior_connections.push_back({s, it->second});
          continue;
        }
        BlockFace bf;
        bf.owner = s;
        const int plane = p.orientation > 0 ? c.index[a] + 1 : c.index[a];
        bf.cell_face = {a, plane, c.index[(a + 1) % 3], c.index[(a + 2) % 3]};
        bf.upper = p.orientation < 0;
        detail::grid_patch_area_centroid(p, a, g.planes[a][plane - 1], bf.area, bf.centroid);
        g.block_faces.push_back(bf);
      }
  }
  const size_t connections_before = g.connections.size();
  match_block_faces(g, 0);
  const size_t matched = g.connections.size() - connections_before;
  if (2 * matched != g.block_faces.size() || new_faces * 2 != g.block_faces.size()) {
    why_not = "the pieces on the faces between kept and re-cut cells do not match (" + std::to_string(matched) +
              " pairs of " + std::to_string(new_faces) + " new and " + std::to_string(g.block_faces.size() - new_faces) +
              " kept)";
    return g;
  }
  g.block_faces.clear();
  R.subvolumes_new = static_cast<int>(g.subvolumes.size()) - R.subvolumes_kept;
  R.kept_from.resize(g.subvolumes.size(), -1);
  g.done = true;
  return g;
}

}  // namespace

GridCut recut_by_grid(const PartShape& part, const GridCut& old, const PartShape& old_part,
                      const GridOptions& o, RecutReport* report) {
  RecutReport local;
  RecutReport& R = report ? *report : local;
  R = RecutReport{};
  const auto t0 = std::chrono::steady_clock::now();
  PARAFAB_VERIFY(old.done, "recut: the old cut is not done");
  const double h = old.cell_size.maxCoeff();
  const double tol = 1e-7 * h;
  const Box3 bb = tight_box(part.shape);
  R.old_cut_cells = static_cast<int>(old.cut_cells.size());
  auto full_cut = [&](const std::string& why) {
    R.full = true;
    R.message = why;
    R.cells_recut = R.old_cut_cells;  // all of them
    GridOptions fo = o;
    fo.anchored = true;
    fo.origin = old.grid.min;
    fo.cell_size = h;
    fo.shift_retries = 0;  // the kept grid
    return cut_by_grid(part, fo);
  };
  if (((bb.min - old.grid.min).array() < -tol).any() || ((old.grid.max - bb.max).array() < -tol).any())
    return full_cut("the changed part leaves the old grid");

  std::vector<TopoDS_Shape> changed_shapes;
  const std::vector<Box3> dirty = changed_regions(part, old_part, tol, R, &changed_shapes);
  const bool changed = R.changed_faces + R.changed_edges > 0;
  auto overlap = [&](const Box3& a, const Box3& b) { return boxes_overlap(a, b, tol); };
  if (old.method == CutMethod::FaceCut && o.method == CutMethod::FaceCut) {
    if (o.nurbs) return full_cut("the face route re-cut does not convert to NURBS");
    std::string why;
    GridCut g = recut_by_faces(part, old, dirty, changed_shapes, o, R, why);
    if (!g.done) {
      const RecutReport counts = R;
      R = RecutReport{};
      R.changed_faces = counts.changed_faces, R.changed_edges = counts.changed_edges, R.regions = counts.regions;
      R.cells = counts.cells, R.old_cut_cells = counts.old_cut_cells;
      return full_cut("face route re-cut failed: " + why);
    }
    g.split_seconds = seconds_since(t0);
    return g;
  }
  if (old.block_cells <= 0) return full_cut("the old cut has no blocks (block_cells = 0)");

  GridCut g;
  g.grid = old.grid;
  g.cells = old.cells;
  g.cell_size = old.cell_size;
  g.planes = old.planes;
  g.shifted_planes = old.shifted_planes;
  g.block_cells = old.block_cells;
  GridCutter blocks_of(g, o, big_size(old.grid));
  R.blocks = blocks_of.blocks();
  auto dirty_block = [&](const std::array<int, 3>& b) {
    if (!changed) return false;
    const Box3 box = blocks_of.block_box(b);
    for (const Box3& d : dirty)
      if (overlap(box, d)) return true;
    return false;
  };
  // Keep what lies in clean blocks.
  std::vector<int> new_sv(old.subvolumes.size(), -1), new_interior(old.interior_cells.size(), -1);
  std::set<std::array<int, 3>> recut_blocks;
  for (const CutCell& c : old.cut_cells) {
    const auto b = blocks_of.block_of_cell(c.index);
    if (dirty_block(b)) {
      recut_blocks.insert(b);
      continue;
    }
    CutCell kept{c.index, {}};
    for (int s : c.subvolumes) {
      new_sv[s] = static_cast<int>(g.subvolumes.size());
      kept.subvolumes.push_back(new_sv[s]);
      g.subvolumes.push_back(old.subvolumes[s]);
      R.kept_from.push_back(s);
    }
    g.cut_cells.push_back(std::move(kept));
  }
  for (size_t i = 0; i < old.interior_cells.size(); ++i)
    if (!dirty_block(blocks_of.block_of_cell(old.interior_cells[i]))) {
      new_interior[i] = static_cast<int>(g.interior_cells.size());
      g.interior_cells.push_back(old.interior_cells[i]);
    }
  auto owner_of = [&](int owner) { return owner >= 0 ? new_sv[owner] : (new_interior[-1 - owner] < 0 ? INT_MIN : -1 - new_interior[-1 - owner]); };
  for (const auto& [a, b] : old.connections)
    if (new_sv[a] >= 0 && new_sv[b] >= 0) g.connections.push_back({new_sv[a], new_sv[b]});
  for (const auto& [s, c] : old.interior_connections)
    if (new_sv[s] >= 0 && new_interior[c] >= 0) g.interior_connections.push_back({new_sv[s], new_interior[c]});
  for (const CutCurve& c : old.curves)
    if (new_sv[c.subvolume] >= 0) {
      g.curves.push_back(c);
      g.curves.back().subvolume = new_sv[c.subvolume];
    }
  for (const BlockFace& f : old.block_faces) {
    const int owner = owner_of(f.owner);
    if (owner == INT_MIN || (f.owner >= 0 && owner < 0)) continue;
    g.block_faces.push_back(f);
    g.block_faces.back().owner = owner;
  }
  for (const auto& s : g.subvolumes) g.patches += static_cast<int>(s.patches.size());
  R.subvolumes_kept = static_cast<int>(g.subvolumes.size());
  const size_t first_new = g.block_faces.size();

  // Split the changed part again, in the dirty blocks only.
  TopoDS_Shape solid;
  TopTools_DataMapOfShapeInteger source;
  if (!shape_to_cut(part, o, solid, source, g.message)) return g;
  GridCutter cutter(g, o, big_size(old.grid));
  if (!cutter.cut(solid, source, dirty_block)) return g;
  match_block_faces(g, first_new);
  R.blocks_recut = g.blocks_cut;
  R.subvolumes_new = static_cast<int>(g.subvolumes.size()) - R.subvolumes_kept;
  R.kept_from.resize(g.subvolumes.size(), -1);
  g.split_seconds = seconds_since(t0);
  g.done = true;
  return g;
}

}  // namespace parafab::occ
