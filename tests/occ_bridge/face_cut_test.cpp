// Cut by face (thesis §6.3, Fig. 6.12) against the reference, OCCT's Boolean splitter, on every
// sample part, aligned with the grid and turned/shifted against it: the same cut cells,
// subvolumes per cell, interior cells and connections (subvolumes matched by cell and
// centroid, not by index), and the same volume rules (moments of order 0, 1, 2 in cell
// coordinates); the intersection samples lie where their (u, v) say.
#include <gtest/gtest.h>

#include <BRepAlgoAPI_Common.hxx>
#include <BRepAlgoAPI_Cut.hxx>
#include <BRepBuilderAPI_NurbsConvert.hxx>
#include <BRepBuilderAPI_Transform.hxx>
#include <BRepPrimAPI_MakeBox.hxx>
#include <BRepPrimAPI_MakeCone.hxx>
#include <BRepPrimAPI_MakeSphere.hxx>
#include <BRepBndLib.hxx>
#include <BRep_Tool.hxx>
#include <BRepGProp.hxx>
#include <GProp_GProps.hxx>
#include <Bnd_Box.hxx>
#include <TopoDS.hxx>
#include <Geom_Curve.hxx>
#include <gp_Ax1.hxx>
#include <gp_Trsf.hxx>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <set>

#include "face_lookup.h"
#include "grid_cut.h"
#include "grid_model.h"
#include "occt_shape.h"
#include "part_reader.h"
#include "xfem/area_rules.h"
#include "xfem/linear_xfem.h"
#include "xfem/volume_rules.h"

namespace parafab::occ {
namespace {

std::string sample(const std::string& name) { return std::string(PARAFAB_SAMPLES_DIR) + "/parts/" + name + ".step"; }

// The part turned by `degrees` about the skew axis (1, 2, 3) through its box centre and
// shifted by `shift` × its box diagonal (0°: the part as read).
// Parts built here for surfaces the samples lack: a cone frustum with a conical bore, a sphere
// (poles: degenerated edges) with a box notch, and the cylinder with every face converted to
// a B-spline surface.
std::shared_ptr<const PartShape> built(const std::string& name) {
  TopoDS_Shape s;
  if (name == "cone") {
    s = BRepAlgoAPI_Cut(BRepPrimAPI_MakeCone(20, 8, 30).Shape(), BRepPrimAPI_MakeCone(gp_Ax2(gp_Pnt(0, 0, -1), gp_Dir(0, 0, 1)), 6, 3, 32).Shape()).Shape();
  } else if (name == "sphere") {
    s = BRepAlgoAPI_Cut(BRepPrimAPI_MakeSphere(20).Shape(), BRepPrimAPI_MakeBox(gp_Pnt(3, 4, 5), 30, 30, 30).Shape()).Shape();
  } else if (name == "bspline_cylinder") {
    s = BRepBuilderAPI_NurbsConvert(read_part(sample("cylinder"))->shape).Shape();
  }
  return make_part(s, name);
}

std::shared_ptr<const PartShape> posed(const std::string& name, double degrees, double shift, int solid = -1) {
  ReadOptions ro;
  ro.solid_index = solid;
  const auto part = name == "cone" || name == "sphere" || name == "bspline_cylinder" ? built(name) : read_part(sample(name), ro);
  if (degrees == 0 && shift == 0) return part;
  Bnd_Box bb;
  BRepBndLib::Add(part->shape, bb);
  double x0, y0, z0, x1, y1, z1;
  bb.Get(x0, y0, z0, x1, y1, z1);
  const gp_Pnt c(0.5 * (x0 + x1), 0.5 * (y0 + y1), 0.5 * (z0 + z1));
  const double diag = std::sqrt((x1 - x0) * (x1 - x0) + (y1 - y0) * (y1 - y0) + (z1 - z0) * (z1 - z0));
  gp_Trsf rot, move;
  rot.SetRotation(gp_Ax1(c, gp_Dir(1, 2, 3)), degrees * M_PI / 180);
  move.SetTranslation(gp_Vec(0.37 * shift * diag, -0.21 * shift * diag, 0.13 * shift * diag));
  const TopoDS_Shape s = BRepBuilderAPI_Transform(part->shape, move * rot, true).Shape();
  return make_part(s, name + " posed");
}

// Moments ∫1, ∫ξ, ∫ξξᵀ (upper triangle) of a subvolume's volume rule, ξ = (X − cell.min)/h.
std::array<double, 10> moments(const xfem::Subvolume& sv) {
  const xfem::VolumeRule r = xfem::volume_rule(sv);
  const double h = sv.cell.size().maxCoeff();
  std::array<double, 10> m{};
  for (size_t j = 0; j < r.rule.weights.size(); ++j) {
    const double w = r.rule.weights[j] / (h * h * h);
    const Eigen::Vector3d x = (r.rule.points[j] - sv.cell.min) / h;
    m[0] += w;
    for (int a = 0; a < 3; ++a) m[1 + a] += w * x[a];
    int k = 4;
    for (int a = 0; a < 3; ++a)
      for (int b = a; b < 3; ++b) m[k++] += w * x[a] * x[b];
  }
  return m;
}

struct Compared {
  double worst_moment = 0;  ///< largest moment difference, relative to the cell volume
  int subvolumes = 0;
  double face_volume = 0, ref_volume = 0;  ///< Σ subvolume rules + interior cells
  int splitter_missed = 0;  ///< cells only the face route cuts (checked against a per-cell Boolean)
};

// Asserts the two cuts agree; returns the largest moment difference.
// A third reference for a cell the two routes disagree on: OCCT's Boolean common of the part
// and the cell box, as a fraction of the cell volume.
double boolean_fraction(const PartShape& part, const GridCut& g, const std::array<int, 3>& k) {
  const xfem::Box3 b = g.cell_box(k);
  const TopoDS_Shape box = BRepPrimAPI_MakeBox(gp_Pnt(b.min.x(), b.min.y(), b.min.z()), gp_Pnt(b.max.x(), b.max.y(), b.max.z())).Shape();
  GProp_GProps props;
  BRepGProp::VolumeProperties(BRepAlgoAPI_Common(part.shape, box).Shape(), props, 1e-13);
  return props.Mass() / b.volume();
}

Compared compare_cuts(const GridCut& face, const GridCut& ref, const std::string& what, double moment_tol,
                      const PartShape* part = nullptr) {
  Compared out;
  // Cells.
  std::map<std::array<int, 3>, const CutCell*> fc, rc;
  for (const auto& c : face.cut_cells) fc[c.index] = &c;
  for (const auto& c : ref.cut_cells) rc[c.index] = &c;
  std::set<std::array<int, 3>> fk, rk;
  for (const auto& [k, c] : fc) fk.insert(k);
  for (const auto& [k, c] : rc) rk.insert(k);
  // A cell only the face route cuts must hold the material OCCT's per-cell Boolean finds there
  // (the splitter drops some slivers of 1e-5 of a cell: cone turned 17°); it is then left out
  // of the comparison. A cell only the splitter cuts is a failure.
  for (const auto& k : fk)
    if (!rk.count(k)) {
      double fraction = 0;
      for (int sv : fc.at(k)->subvolumes) fraction += moments(face.subvolumes[sv])[0];
      const double boolean = part ? boolean_fraction(*part, face, k) : -1.0;
      EXPECT_NEAR(fraction, boolean, 1e-9) << what << ": only the face route cuts cell " << k[0] << " " << k[1] << " " << k[2];
      std::printf("  cell %d %d %d: only the face route cuts it (fraction %.3e, OCCT's Boolean %.3e)\n", k[0], k[1], k[2],
                  fraction, boolean);
      ++out.splitter_missed;
      fc.erase(k);
    }
  for (const auto& k : rk)
    if (!fk.count(k)) ADD_FAILURE() << what << ": only the splitter cuts cell " << k[0] << " " << k[1] << " " << k[2];
  fk.clear();
  for (const auto& [k, c] : fc) fk.insert(k);
  using CellSet = std::set<std::array<int, 3>>;
  const CellSet fi(face.interior_cells.begin(), face.interior_cells.end()), ri(ref.interior_cells.begin(), ref.interior_cells.end());
  EXPECT_EQ(fi, ri) << what << ": interior cells";
  if (fk != rk) return out;
  // Subvolumes matched by centroid within each cell: face index → reference index.
  std::vector<int> match(face.subvolumes.size(), -1);
  for (const auto& [k, c] : fc) {
    const CutCell& r = *rc.at(k);
    EXPECT_EQ(c->subvolumes.size(), r.subvolumes.size()) << what << ": subvolumes of cell " << k[0] << " " << k[1] << " " << k[2];
    if (c->subvolumes.size() != r.subvolumes.size()) continue;
    std::vector<std::array<double, 10>> mf, mr;
    for (int s : c->subvolumes) mf.push_back(moments(face.subvolumes[s]));
    for (int s : r.subvolumes) mr.push_back(moments(ref.subvolumes[s]));
    std::vector<bool> taken(mr.size(), false);
    for (size_t i = 0; i < mf.size(); ++i) {
      int best = -1;
      double best_d = 1e300;
      for (size_t j = 0; j < mr.size(); ++j) {
        if (taken[j]) continue;
        double d = 0;
        for (int a = 1; a < 4; ++a) d += std::pow(mf[i][a] / mf[i][0] - mr[j][a] / mr[j][0], 2);
        if (d < best_d) best_d = d, best = static_cast<int>(j);
      }
      if (best < 0) continue;
      taken[best] = true;
      const double h3 = std::pow(face.subvolumes[c->subvolumes[i]].cell.size().maxCoeff(), 3);
      match[c->subvolumes[i]] = r.subvolumes[best];
      double worst = 0;
      for (int m = 0; m < 10; ++m) worst = std::max(worst, std::abs(mf[i][m] - mr[best][m]));
      EXPECT_LT(worst, moment_tol) << what << ": moments of a subvolume of cell " << k[0] << " " << k[1] << " " << k[2]
                                   << " (volume fraction " << mr[best][0] << ")";
      out.worst_moment = std::max(out.worst_moment, worst);
      ++out.subvolumes;
    }
  }
  // Connections through grid faces, in reference numbering.
  std::multiset<std::array<int, 2>> fcon, rcon;
  for (const auto& [a, b] : face.connections)
    if (match[a] >= 0 && match[b] >= 0) fcon.insert({std::min(match[a], match[b]), std::max(match[a], match[b])});
  for (const auto& c : ref.connections) rcon.insert(c);
  EXPECT_EQ(fcon, rcon) << what << ": connections";
  std::multiset<std::pair<int, std::array<int, 3>>> fic, ric;
  for (const auto& [s, c] : face.interior_connections)
    if (match[s] >= 0) fic.insert({match[s], face.interior_cells[c]});
  for (const auto& [s, c] : ref.interior_connections) ric.insert({s, ref.interior_cells[c]});
  EXPECT_EQ(fic, ric) << what << ": interior connections";
  return out;
}

// Every sample of the face route lies on the surfaces its (u, v) name, and on its grid planes.
void expect_samples_on_their_surfaces(const PartShape& part, const GridCut& g, const std::string& what) {
  const double h = g.cell_size.maxCoeff();
  int checked = 0;
  double worst = 0;
  for (const CutCurve& c : g.curves) {
    ASSERT_EQ(c.samples.size(), c.points.size()) << what;
    for (size_t i = 0; i < c.points.size(); ++i)
      for (const CutSample::On& on : c.samples[i].on) {
        xfem::Vec3 X;
        if (on.source >= 0) {
          const gp_Pnt p = BRep_Tool::Surface(part.face(on.source))->Value(on.uv.x(), on.uv.y());
          X = xfem::Vec3(p.X(), p.Y(), p.Z());
        } else {
          const int a = -1 - on.source;
          X = c.points[i];
          X[(a + 1) % 3] = on.uv.x(), X[(a + 2) % 3] = on.uv.y();
          bool on_plane = false;
          for (double q : g.planes[a]) on_plane |= std::abs(c.points[i][a] - q) < 1e-9 * h;
          EXPECT_TRUE(on_plane) << what << ": a sample off its grid plane";
        }
        worst = std::max(worst, (X - c.points[i]).norm() / h);
        ++checked;
      }
  }
  EXPECT_GT(checked, 0) << what;
  EXPECT_LT(worst, 1e-9) << what;
  // The class and the edge data (Fig. 6.12): a sample on a B-rep edge (EdgePlane, OnEdge) lies on
  // the edge's 3D curve at edge_param; a Vertex sample is the vertex; a FacePlanePlane sample lies
  // on two grid planes; faces and grid planes listed as the class says.
  std::map<int, int> kinds;
  double worst_edge = 0;
  int vertices = 0;
  for (const CutCurve& c : g.curves)
    for (size_t i = 0; i < c.points.size(); ++i) {
      const CutSample& smp = c.samples[i];
      ++kinds[smp.kind];
      int faces = 0, planes = 0;
      for (const CutSample::On& on : smp.on) (on.source >= 0 ? faces : planes)++;
      switch (smp.kind) {
        case CutSample::FacePlane: EXPECT_EQ(faces, 1) << what; EXPECT_EQ(planes, 1) << what; break;
        case CutSample::FacePlanePlane: {
          EXPECT_EQ(faces, 1) << what;
          double off = 1e300;  // distance to the nearest plane of an axis not listed
          for (int b = 0; b < 3; ++b) {
            bool listed = false;
            for (const CutSample::On& on : smp.on) listed |= on.source == -1 - b;
            if (!listed)
              for (double q : g.planes[b]) off = std::min(off, std::abs(c.points[i][b] - q) / h);
          }
          EXPECT_EQ(planes, 2) << what << ": the nearest unlisted plane is " << off << " cells away";
          break;
        }
        case CutSample::OnEdge: EXPECT_EQ(faces, 2) << what; EXPECT_EQ(planes, 0) << what; break;
        case CutSample::EdgePlane: EXPECT_GE(faces, 1) << what; EXPECT_EQ(planes, 1) << what; break;
        case CutSample::Vertex: break;
        case CutSample::Tangent: ADD_FAILURE() << what << ": a Tangent sample (never produced)"; break;
      }
      if (smp.kind == CutSample::OnEdge || smp.kind == CutSample::EdgePlane) {
        ASSERT_GE(smp.edge, 0) << what;
        double f, l;
        const Handle(Geom_Curve) curve = BRep_Tool::Curve(part.edge(smp.edge), f, l);
        ASSERT_FALSE(curve.IsNull()) << what;
        const gp_Pnt p = curve->Value(smp.edge_param);
        // On an exact curve to 1e-9 h; an approximated intersection curve (the notched sphere's)
        // holds its points within the edge's own tolerance.
        const double d = (xfem::Vec3(p.X(), p.Y(), p.Z()) - c.points[i]).norm();
        EXPECT_LE(d, std::max(1e-9 * h, BRep_Tool::Tolerance(part.edge(smp.edge)))) << what << ": a sample off its edge";
        worst_edge = std::max(worst_edge, d / h);
      } else if (smp.kind == CutSample::Vertex) {  // within the vertex's own tolerance
        ASSERT_GE(smp.edge, 0) << what;
        const TopoDS_Vertex& v = TopoDS::Vertex(part.vertices(smp.edge + 1));
        const gp_Pnt p = BRep_Tool::Pnt(v);
        EXPECT_LE((xfem::Vec3(p.X(), p.Y(), p.Z()) - c.points[i]).norm(), BRep_Tool::Tolerance(v)) << what;
        ++vertices;
      }
    }
  EXPECT_GT(kinds[CutSample::FacePlane], 0) << what;
  EXPECT_GT(kinds[CutSample::EdgePlane], 0) << what;
  if (worst_edge > 1e-9) std::printf("  %s: samples up to %.1e cells off approximated edges (within their tolerance)\n", what.c_str(), worst_edge);
  EXPECT_EQ(vertices, kinds[CutSample::Vertex]) << what;
}

struct Case {
  const char* part;
  int cells;
  int solid = -1;
};

void expect_face_route_matches(const Case& c, double degrees, double shift, double moment_tol, GridOptions o = {}) {
  const auto part = posed(c.part, degrees, shift, c.solid);
  o.cells_longest = c.cells;
  o.method = CutMethod::Splitter;  // the reference
  const GridCut ref = cut_by_grid(*part, o);
  o.method = CutMethod::FaceCut;
  const GridCut face = cut_by_grid(*part, o);
  const std::string what = std::string(c.part) + " at " + std::to_string(degrees) + "°";
  ASSERT_TRUE(ref.done && face.done) << what << ": " << ref.message << " / " << face.message;
  ASSERT_EQ(face.method, CutMethod::FaceCut) << what << ": retried: " << face.retry_reason;
  Compared cmp = compare_cuts(face, ref, what, moment_tol, part.get());
  for (const auto& c : face.interior_cells) cmp.face_volume += face.cell_box(c).volume();
  for (const auto& c : ref.interior_cells) cmp.ref_volume += ref.cell_box(c).volume();
  for (const auto& sv : face.subvolumes) cmp.face_volume += moments(sv)[0] * std::pow(sv.cell.size().maxCoeff(), 3);
  for (const auto& sv : ref.subvolumes) cmp.ref_volume += moments(sv)[0] * std::pow(sv.cell.size().maxCoeff(), 3);
  GProp_GProps props;
  // The B-spline cylinder: the exact volume is the analytic cylinder's (OCCT's volume of the
  // converted solid is itself off by ~2e-9).
  BRepGProp::VolumeProperties(std::string(c.part) == "bspline_cylinder" ? posed("cylinder", degrees, shift)->shape : part->shape, props, 1e-13);
  const double v_face = std::abs(cmp.face_volume / props.Mass() - 1), v_ref = std::abs(cmp.ref_volume / props.Mass() - 1);
  for (const auto* cut : {&face, &ref})
    for (const auto& cc : cut->cut_cells)
      for (int sv : cc.subvolumes) {
        const auto m = moments(cut->subvolumes[sv]);
        for (int a = 0; a < 3; ++a)
          if (m[1 + a] / m[0] < -1e-9 || m[1 + a] / m[0] > cut->subvolumes[sv].cell.size()[a] / cut->subvolumes[sv].cell.size().maxCoeff() + 1e-9)
            std::printf("  %s: subvolume %d (fraction %.2e) of cell %d %d %d has its centroid outside the cell\n",
                        cut == &face ? "face" : "splitter", sv, m[0], cc.index[0], cc.index[1], cc.index[2]);
      }
  std::printf("  volume vs OCCT: face route %.2e, splitter %.2e\n", v_face, v_ref);
  // The B-spline cylinder: both routes hold the analytic volume only to ≤ 3.2e-9 (face) and
  // 3.7e-9 (splitter), measured; the other parts to ≤ 1.4e-11.
  EXPECT_LT(v_face, std::string(c.part) == "bspline_cylinder" ? 4e-9 : 2e-11) << what << ": the face route's rules miss OCCT's volume of the whole part";
  expect_samples_on_their_surfaces(*part, face, what);
  std::printf("%-12s %5.1f°: %zu cut cells, %d subvolumes, worst moment difference %.2e; "
              "face %.3f s (check %.4f s), splitter %.3f s\n",
              c.part, degrees, face.cut_cells.size(), cmp.subvolumes, cmp.worst_moment, face.split_seconds, face.verify_seconds, ref.split_seconds);
}

// Moments agree to round-off where both routes have exact curves (planar parts). Where planes
// meet cylinders the splitter's pcurves are B-spline approximations of exact conics; with the
// splitter route's (u, v) refined onto the edges' 3D curves (GridOptions::project_pcurves)
// subvolumes differ by ≤ 4.2e-10 of the cell volume (ring aligned; ≤ 3.5e-11 on the turned
// parts; without the refinement 2.4e-9), the volume rules' flux tolerance (1e-10) being the
// floor. Plane ∩ torus and ∩ B-spline sections are approximated 3D curves in OCCT too:
// 5.4e-9 (housing), 3.9e-9 (cone aligned), 5.4e-9 (B-spline cylinder), 1.3e-9 (sphere), while the face route's
// total volume matches OCCT's analytic volume to ≤ 1.4e-11 (the splitter's to ≤ 9e-10).
constexpr double kPlanar = 1e-14, kCurved = 5e-10, kToric = 6e-9, kCone = 4.5e-9, kBSpline = 6e-9, kSphere = 1.5e-9;

TEST(FaceCut, PlanarPartsMatchTheSplitter) {
  for (const Case c : {Case{"box", 4}, Case{"two_blocks", 6, 0}})
    for (double deg : {0.0, 17.0, 31.0}) expect_face_route_matches(c, deg, deg == 0 ? 0 : 0.013, kPlanar);
}

TEST(FaceCut, CylinderAndBracketMatchTheSplitter) {
  for (const Case c : {Case{"cylinder", 6}, Case{"l_bracket", 6}})
    for (double deg : {0.0, 17.0, 31.0}) expect_face_route_matches(c, deg, deg == 0 ? 0 : 0.013, kCurved);
}

TEST(FaceCut, CurvedPartsMatchTheSplitter) {
  for (const Case c : {Case{"ring", 6}, Case{"wheel", 8}, Case{"wrench", 8}, Case{"two_blocks", 6, 1}})
    for (double deg : {0.0, 17.0, 31.0}) expect_face_route_matches(c, deg, deg == 0 ? 0 : 0.013, kCurved);
}

// The sample parts added after the comparisons above: the flange (bolt holes round a boss) and
// the plate with 40 holes (cylinders), and the bump block (a B-spline top face).
TEST(FaceCut, LaterSamplePartsMatchTheSplitter) {
  for (double deg : {0.0, 17.0}) expect_face_route_matches(Case{"flange", 8}, deg, deg == 0 ? 0 : 0.013, kCurved);
  // The plate's holes are cut by the closed forms on both routes: measured 8.3e-15 / 9.3e-13.
  for (double deg : {0.0, 17.0}) expect_face_route_matches(Case{"plate_holes", 12}, deg, deg == 0 ? 0 : 0.013, 2e-12);
  for (double deg : {0.0, 17.0}) expect_face_route_matches(Case{"bump_block", 6}, deg, deg == 0 ? 0 : 0.013, kBSpline);
}

// The un-turned L-bracket (60 x 40 x 50) at 18, 24 and 30 cells: the grid's box equals the
// part's box in y, so the y = 0 and y = 40 faces lie on the grid's box and their level curves
// run along cell-face sides, ending at cell-face corners. Before the corner snap in the closing
// of cell-face loops the face route failed its closure check here (24 cells: 216 unmatched
// curves; also 36, 42, 48, 54) and fell back to the splitter (issue 11). 48 cells (same case,
// splitter 12 s) was checked by hand with the same helper: worst moment difference 9.6e-14.
TEST(FaceCut, AlignedBracketWithFacesOnTheGridBoxMatchesTheSplitter) {
  for (const Case c : {Case{"l_bracket", 18}, Case{"l_bracket", 24}, Case{"l_bracket", 30}})
    expect_face_route_matches(c, 0.0, 0.0, kCurved);
}

// A grid line on a cylinder (a ruling): the bracket's r = 5 fillet about (x, z) = (13, 13) holds
// the line x = 9, z = 10 of a 5 mm grid anchored there (also the 40-cell grid of the un-turned
// bracket). Without shifting a plane off it the face route met "a grid vertex on the surface"
// and fell back; the planes are shifted (GridCut::shifted_planes) and the cut matches the splitter.
TEST(FaceCut, GridLineOnACylinderIsShiftedOff) {
  GridOptions o;
  o.cell_size = 5;
  o.anchored = true;
  o.origin = xfem::Vec3(9, 0, 10);
  expect_face_route_matches(Case{"l_bracket", 12}, 0.0, 0.0, kCurved, o);  // cell_size overrides the 12
  o.method = CutMethod::FaceCut;
  const GridCut g = cut_by_grid(*read_part(sample("l_bracket")), o);
  EXPECT_GE(g.shifted_planes, 1);
}

// Tori (the half torus; the housing's boss fillet) and, built here, a cone frustum, a notched
// sphere and a B-spline cylinder: the traced level curves of the generic path.
TEST(FaceCut, ToriMatchTheSplitter) {
  for (const Case c : {Case{"half_torus", 6}, Case{"housing", 8}})
    for (double deg : {0.0, 17.0, 31.0}) expect_face_route_matches(c, deg, deg == 0 ? 0 : 0.013, kToric);
}

// Cones: turned 17°, the splitter misses two slivers of 1.8e-5
// and 8.4e-6 of a cell that OCCT's per-cell Boolean confirms; then neighbouring subvolumes
// and connections differ, so that pose is checked in ConeSliversTheSplitterMisses.
TEST(FaceCut, ConesAndSpheresMatchTheSplitter) {
  for (double deg : {0.0, 31.0}) expect_face_route_matches(Case{"cone", 6}, deg, deg == 0 ? 0 : 0.013, kCone);
  for (double deg : {0.0, 17.0, 31.0}) expect_face_route_matches(Case{"sphere", 7}, deg, deg == 0 ? 0 : 0.013, kSphere);
}

TEST(FaceCut, BSplinesMatchTheSplitter) {
  for (double deg : {0.0, 17.0, 31.0}) expect_face_route_matches(Case{"bspline_cylinder", 6}, deg, deg == 0 ? 0 : 0.013, kBSpline);
}

TEST(FaceCut, ConeSliversTheSplitterMisses) {
  const auto part = posed("cone", 17, 0.013);
  GridOptions o;
  o.cells_longest = 6;
  o.method = CutMethod::Splitter;  // the reference
  const GridCut ref = cut_by_grid(*part, o);
  o.method = CutMethod::FaceCut;
  const GridCut face = cut_by_grid(*part, o);
  ASSERT_EQ(face.method, CutMethod::FaceCut) << face.retry_reason;
  std::set<std::array<int, 3>> rk;
  for (const auto& c : ref.cut_cells) rk.insert(c.index);
  int only_face = 0;
  for (const auto& c : face.cut_cells) {
    double fraction = 0;
    for (int sv : c.subvolumes) fraction += moments(face.subvolumes[sv])[0];
    if (!rk.count(c.index)) {
      ++only_face;
      EXPECT_NEAR(fraction, boolean_fraction(*part, face, c.index), 1e-10);
    }
  }
  EXPECT_EQ(only_face, 2);
  EXPECT_EQ(face.cut_cells.size(), ref.cut_cells.size() + 2);
}

// The ring turned 20° about its own axis on 12 cells: the grid planes x = ±20 touch the inner
// cylinder (r = 20) and are shifted 1e-4 cells off it, so they cut the bottom and top annuli
// twice within 0.8° of arc near the extreme point, between two of the 64 samples of the
// circle's root search. Before 2026-11-28 the search missed that pair unless the extreme fell
// on a sample (turns by multiples of 45°); the cut then failed ("crossings … do not alternate")
// and went to the splitter. Now the extremum is searched where |g| is smallest at a sample.
TEST(FaceCut, PlaneNearlyTangentToACircleBetweenSamplesIsCutTwice) {
  const auto ring = read_part(sample("ring"));
  for (double deg : {20.0, 3.7}) {
    const auto part = rotated_part(*ring, xfem::Vec3::Zero(), xfem::Vec3(0, 0, 1), deg);
    GridOptions o;
    o.cells_longest = 12;
    o.shift_retries = 0;
    const GridCut face = cut_by_grid(*part, o);
    ASSERT_TRUE(face.done) << deg << "°: " << face.message;
    o.method = CutMethod::Splitter;  // the reference
    const GridCut ref = cut_by_grid(*part, o);
    ASSERT_TRUE(ref.done) << ref.message;
    // measured 4.3e-13 / 7.0e-13 of the cell
    const Compared cmp = compare_cuts(face, ref, "ring turned " + std::to_string(deg) + "° about z", 2e-12, part.get());
    std::printf("ring turned %.1f° about z: %d subvolumes, worst moment difference %.1e\n", deg, cmp.subvolumes,
                cmp.worst_moment);
  }
}

// The notched sphere on 6 cells: the grid is centred on the sphere and R = 3h, so grid vertices
// at (±2, ±2, ±1)h from the centre lie on the sphere (2² + 2² + 1² = 3²). The face route
// refuses that grid (three planes meeting on the surface); the grid is then shifted along the
// failing plane's axis and cut again, with the reason kept, and that cut matches the
// splitter's on the shifted grid. A grid that must not move (shift_retries = 0) fails with the reason.
TEST(FaceCut, SphereWithGridVerticesOnItIsCutOnAShiftedGrid) {
  const auto part = posed("sphere", 17, 0.013);
  GridOptions o;
  o.cells_longest = 6;
  const GridCut g = cut_by_grid(*part, o);
  ASSERT_TRUE(g.done) << g.message;
  EXPECT_EQ(g.method, CutMethod::FaceCut);
  EXPECT_NE(g.retry_reason.find("a grid vertex on the surface"), std::string::npos) << g.retry_reason;
  // Shifted along the failing plane's axis only, by 0.118 / 0.141 / 0.173 cells for x / y / z.
  const double h = g.cell_size.maxCoeff();
  int moved = 0;
  for (int a = 0; a < 3; ++a)
    if (g.grid_shift[a] != 0) {
      ++moved;
      EXPECT_NEAR(g.grid_shift[a], h * xfem::Vec3(0.118, 0.141, 0.173)[a], 1e-12 * h) << g.grid_shift.transpose();
    }
  EXPECT_EQ(moved, 1) << g.grid_shift.transpose();
  std::printf("sphere: grid shifted by (%g, %g, %g) cells\n", g.grid_shift.x() / h, g.grid_shift.y() / h, g.grid_shift.z() / h);

  GridOptions fixed = o;
  fixed.shift_retries = 0;
  const GridCut refused = cut_by_grid(*part, fixed);
  EXPECT_FALSE(refused.done);
  EXPECT_NE(refused.message.find("a grid vertex on the surface"), std::string::npos) << refused.message;

  GridOptions shifted = shifted_grid(refused, o, 1);
  shifted.method = CutMethod::Splitter;  // the reference, on the same shifted grid
  const GridCut ref = cut_by_grid(*part, shifted);
  ASSERT_TRUE(ref.done) << ref.message;
  const Compared cmp = compare_cuts(g, ref, "sphere on the shifted grid", kSphere, part.get());
  std::printf("sphere on the shifted grid: %d subvolumes, worst moment difference %.1e\n", cmp.subvolumes,
              cmp.worst_moment);
}

// The same in the simulation path: the grid model on the shifted grid says why, and its rules
// hold OCCT's volume.
TEST(FaceCut, GridModelOnAShiftedGridSaysWhyAndHoldsOcctsVolume) {
  const auto part = posed("sphere", 17, 0.013);
  GridModelOptions o;
  o.grid.cells_longest = 6;
  const GridModel m = build_grid_model(*part, o);
  ASSERT_TRUE(m.done) << m.message;
  EXPECT_EQ(m.cut->method, CutMethod::FaceCut);
  EXPECT_NE(m.cut->retry_reason.find("face route"), std::string::npos) << m.cut->retry_reason;
  double v = 0;
  for (const auto& e : m.elements)
    for (double w : e.rule.weights) v += w;
  GProp_GProps props;
  BRepGProp::VolumeProperties(part->shape, props, 1e-13);
  std::printf("sphere on the shifted grid: volume error %.1e\n", std::abs(v / props.Mass() - 1));
  EXPECT_NEAR(v, props.Mass(), 1e-12 * props.Mass());  // measured 3.0e-13
}

// The simulation path: a grid model on the face route has the splitter model's elements and
// adjacency, and its rules hold OCCT's volume.
TEST(FaceCut, GridModelOnTheFaceRouteMatchesTheSplitterModel) {
  const auto part = posed("l_bracket", 17, 0.013);
  GridModelOptions o;
  o.grid.cells_longest = 8;
  o.grid.method = CutMethod::Splitter;  // the reference
  const GridModel ref = build_grid_model(*part, o);
  o.grid.method = CutMethod::FaceCut;
  const GridModel face = build_grid_model(*part, o);
  ASSERT_TRUE(ref.done && face.done) << ref.message << face.message;
  ASSERT_EQ(face.cut->method, CutMethod::FaceCut) << face.cut->retry_reason;
  EXPECT_EQ(face.elements.size(), ref.elements.size());
  EXPECT_EQ(face.adjacent.size(), ref.adjacent.size());
  double v = 0;
  for (const auto& e : face.elements)
    for (double w : e.rule.weights) v += w;
  GProp_GProps props;
  BRepGProp::VolumeProperties(part->shape, props, 1e-13);
  EXPECT_NEAR(v, props.Mass(), 1e-11 * props.Mass());
  std::printf("grid model: %zu elements, %zu adjacent pairs, volume error %.1e\n", face.elements.size(),
              face.adjacent.size(), std::abs(v / props.Mass() - 1));
  // The same solution: the upright's end face clamped (the sample job's support), the part
  // under gravity, hex8 (the splitter's model is the reference of the simulation's own route).
  const int clamped = face_at_point(*read_part(sample("l_bracket")), xfem::Vec3(0, 20, 30), 1e-6);
  ASSERT_GE(clamped, 0);
  const xfem::ElasticMaterial steel{210000, 0.3, 7.85e-9};
  xfem::LinearXfemOptions lo;
  lo.gravity = xfem::Vec3(0, 0, -9810);
  const std::vector<xfem::DirichletCondition> clamp{{clamped, Eigen::Matrix3d::Zero(), xfem::Vec3::Zero()}};
  const xfem::LinearXfemResult a = xfem::solve_linear(face.elements, face.adjacent, steel, clamp, {}, lo);
  const xfem::LinearXfemResult b = xfem::solve_linear(ref.elements, ref.adjacent, steel, clamp, {}, lo);
  ASSERT_TRUE(a.solved && b.solved) << a.message << b.message;
  const double ua = a.u.cwiseAbs().maxCoeff(), ub = b.u.cwiseAbs().maxCoeff();
  std::printf("face / splitter route: max |u| %.9e / %.9e (relative %.1e), |u| %.1e apart\n", ua, ub,
              std::abs(ua / ub - 1), std::abs(a.u.norm() / b.u.norm() - 1));
  EXPECT_LT(std::abs(ua / ub - 1), 2e-12);  // measured 4.9e-13
  EXPECT_LT(std::abs(a.u.norm() / b.u.norm() - 1), 2e-12);  // measured 5.1e-13
}

}  // namespace
}  // namespace parafab::occ
