// Gaps between the material pieces of a grid cell (thesis §6.4.4, the distance d of Eq. 6.24).
#include "piece_gaps.h"

#include <BRepAlgoAPI_Common.hxx>
#include <BRepBndLib.hxx>
#include <BRepBuilderAPI_MakeVertex.hxx>
#include <BRepExtrema_DistShapeShape.hxx>
#include <BRepGProp.hxx>
#include <BRepPrimAPI_MakeBox.hxx>
#include <BRep_Tool.hxx>
#include <Bnd_Box.hxx>
#include <Standard_Failure.hxx>
#include <GProp_GProps.hxx>
#include <GeomAPI_ProjectPointOnSurf.hxx>
#include <TopExp_Explorer.hxx>
#include <TopTools_ListOfShape.hxx>
#include <chrono>
#include <cmath>
#include <limits>
#include <algorithm>
#include <map>
#include <set>
#include <sstream>

#include "common/error.h"
#include "grid_model.h"
#include "occt_shape.h"
#include "optimize/shape_constraints.h"
#include "shape_parameters.h"

namespace parafab::occ {

namespace {

xfem::Vec3 to_vec(const gp_Pnt& P) { return {P.X(), P.Y(), P.Z()}; }

// The faces of the part within `tol` of X, with the solid's outward normals there.
GapEnd locate(const PartShape& part, const std::vector<Bnd_Box>& boxes, const xfem::Vec3& X, double tol,
              const xfem::Box3& cell) {
  GapEnd end;
  end.point = X;
  for (int k = 0; k < 3; ++k)
    if (std::abs(X[k] - cell.min[k]) <= tol || std::abs(X[k] - cell.max[k]) <= tol) end.box_axes.push_back(k);
  const gp_Pnt P(X.x(), X.y(), X.z());
  const TopoDS_Vertex v = BRepBuilderAPI_MakeVertex(P).Vertex();
  for (int f = 0; f < part.face_count(); ++f) {
    if (boxes[f].IsOut(P)) continue;
    BRepExtrema_DistShapeShape dist(v, part.face(f));
    if (!dist.IsDone() || dist.Value() > tol) continue;
    const TopoDS_Face& face = part.face(f);
    GeomAPI_ProjectPointOnSurf projection(P, BRep_Tool::Surface(face));
    xfem::Vec3 normal = xfem::Vec3::Zero();  // stays zero without a foot point or a normal
    if (projection.NbPoints() > 0) {
      double u, w;
      projection.LowerDistanceParameters(u, w);
      gp_Pnt Q;
      gp_Vec du, dv;
      BRep_Tool::Surface(face)->D1(u, w, Q, du, dv);
      const gp_Vec n = du.Crossed(dv);
      if (n.Magnitude() > 0) normal = xfem::Vec3(n.X(), n.Y(), n.Z()).normalized() * (face.Orientation() == TopAbs_REVERSED ? -1 : 1);
    }
    end.faces.push_back(f);
    end.normals.push_back(normal);
  }
  return end;
}

struct OcctPiece {
  TopoDS_Shape solid;
  xfem::Vec3 centroid;
  double volume = 0;
};

}  // namespace

namespace {

// OCCT's pieces of one cell (the solid's common with the cell box) and which is each element's.
struct CellPieces {
  std::vector<OcctPiece> solids;
  std::vector<int> solid_of;  ///< per element of the cell (members order)
};

std::string cell_name(const std::array<int, 3>& c) {
  std::ostringstream m;
  m << "(" << c[0] << ", " << c[1] << ", " << c[2] << ")";
  return m.str();
}

// OCCT's pieces of one cell and each element's (nearest centroid; the rule's centroid is the
// piece's to the rule's accuracy; a merged piece sits between its parts'), each solid's volume
// checked against its elements' (several elements on one solid: pieces the cut still separates
// and OCCT joins). "" when they match, else why not.
std::string match_cell(const TopoDS_Shape& part, const xfem::Box3& box, const GridModel& grid,
                       const std::vector<int>& members, double fuzzy, double tolerance, CellPieces& cp,
                       double& max_centroid_mismatch) {
  cp = CellPieces{};
  try {
    BRepAlgoAPI_Common common;
    TopTools_ListOfShape arguments, tools;
    arguments.Append(part);
    tools.Append(BRepPrimAPI_MakeBox(gp_Pnt(box.min.x(), box.min.y(), box.min.z()), gp_Pnt(box.max.x(), box.max.y(), box.max.z()))
                     .Shape());
    common.SetArguments(arguments);
    common.SetTools(tools);
    if (fuzzy > 0) common.SetFuzzyValue(fuzzy);
    common.Build();
    if (!common.IsDone() || common.HasErrors()) return "OCCT's common of the part and the cell failed";
    for (TopExp_Explorer x(common.Shape(), TopAbs_SOLID); x.More(); x.Next()) {
      GProp_GProps g;
      BRepGProp::VolumeProperties(x.Current(), g);
      if (g.Mass() > 0) cp.solids.push_back({x.Current(), to_vec(g.CentreOfMass()), g.Mass()});
    }
  } catch (const Standard_Failure& f) {
    return std::string("OCCT's common of the part and the cell threw: ") + f.GetMessageString();
  }
  std::vector<double> volume(members.size(), 0.0);
  std::vector<xfem::Vec3> centroid(members.size(), xfem::Vec3::Zero());
  for (size_t i = 0; i < members.size(); ++i) {
    const xfem::QuadratureRule3& rule = grid.elements[members[i]].rule;
    for (size_t q = 0; q < rule.points.size(); ++q) volume[i] += rule.weights[q], centroid[i] += rule.weights[q] * rule.points[q];
    if (volume[i] > 0) centroid[i] /= volume[i];
  }
  std::ostringstream m;
  if (cp.solids.empty()) {
    m << "OCCT finds no material in the cell, which the cut gives " << members.size() << " pieces";
    return m.str();
  }
  cp.solid_of.assign(members.size(), 0);
  for (size_t i = 0; i < members.size(); ++i) {
    double best = std::numeric_limits<double>::infinity();
    for (size_t k = 0; k < cp.solids.size(); ++k) {
      const double dist = (cp.solids[k].centroid - centroid[i]).norm();
      if (dist < best) best = dist, cp.solid_of[i] = static_cast<int>(k);
    }
    max_centroid_mismatch = std::max(max_centroid_mismatch, best);
  }
  std::vector<double> rules(cp.solids.size(), 0.0);
  for (size_t i = 0; i < members.size(); ++i) rules[cp.solid_of[i]] += volume[i];
  for (size_t k = 0; k < cp.solids.size(); ++k)
    if (rules[k] > 0 && std::abs(rules[k] - cp.solids[k].volume) > tolerance * box.volume()) {
      m << "the cut's pieces do not match OCCT's common" << (fuzzy > 0 ? " (fuzzy)" : "") << " (a solid of volume "
        << cp.solids[k].volume << " against " << rules[k] << " in the elements nearest to it; OCCT's solids:";
      for (const OcctPiece& q : cp.solids) m << " " << q.volume << " at (" << q.centroid.transpose() << ")";
      m << "; the cut's:";
      for (size_t i = 0; i < members.size(); ++i) m << " " << volume[i] << " at (" << centroid[i].transpose() << ")";
      m << ")";
      return m.str();
    }
  return "";
}


}  // namespace

PieceGapResult piece_gaps(const PartShape& part, const GridModel& grid, const PieceGapOptions& options) {
  const auto t0 = std::chrono::steady_clock::now();
  PieceGapResult result;
  std::map<std::array<int, 3>, std::vector<int>> pieces;  // cut cells' elements
  for (int e = 0; e < static_cast<int>(grid.elements.size()); ++e)
    if (grid.elements[e].subvolume) pieces[grid.elements[e].cell].push_back(e);
  // Candidate pairs: two pieces of one cell; pieces of face-neighbour cells that share no grid face
  // region (not in grid.adjacent).
  std::set<std::pair<int, int>> adjacent;
  for (const auto& [a, b] : grid.adjacent) adjacent.emplace(std::min(a, b), std::max(a, b));
  std::vector<std::array<int, 2>> pairs;
  for (const auto& [cell, members] : pieces) {
    for (size_t i = 0; i < members.size(); ++i)
      for (size_t j = i + 1; j < members.size(); ++j) pairs.push_back({members[i], members[j]});
    if (!options.neighbour_cells) continue;
    for (int axis = 0; axis < 3; ++axis) {
      std::array<int, 3> next = cell;
      ++next[axis];
      const auto it = pieces.find(next);
      if (it == pieces.end()) continue;
      for (int a : members)
        for (int b : it->second)
          if (!adjacent.count({std::min(a, b), std::max(a, b)})) pairs.push_back({std::min(a, b), std::max(a, b)});
    }
  }
  std::vector<Bnd_Box> boxes(part.face_count());
  for (int f = 0; f < part.face_count(); ++f) {
    BRepBndLib::Add(part.face(f), boxes[f]);
    boxes[f].Enlarge(1e-6);
  }
  std::map<std::array<int, 3>, CellPieces> occt;
  // Element e's OCCT piece (its cell's common computed once).
  auto piece_of = [&](int e) -> const TopoDS_Shape* {
    const std::array<int, 3>& cell = grid.elements[e].cell;
    const std::vector<int>& members = pieces.at(cell);
    auto it = occt.find(cell);
    if (it == occt.end()) {
      ++result.cells_checked;
      const xfem::Box3& box = grid.elements[e].box;
      // OCCT's common can drop a piece at a near-tangent contact (seen 1.6e-7 mm before the
      // turned bracket's join): then once more with a fuzzy value of 1e-5 of the cell, which
      // takes such a contact as touching.
      CellPieces cp;
      std::string why;
      for (const double fuzzy : {0.0, 1e-5 * box.size().minCoeff()}) {
        why = match_cell(part.shape, box, grid, members, fuzzy, options.match_tolerance, cp, result.max_centroid_mismatch);
        if (why.empty()) break;
      }
      if (!why.empty()) {
        result.message = "piece_gaps: cell " + cell_name(cell) + ": " + why;
        return nullptr;
      }
      it = occt.emplace(cell, std::move(cp)).first;
    }
    const size_t i = std::find(members.begin(), members.end(), e) - members.begin();
    return &it->second.solids[it->second.solid_of[i]].solid;
  };
  for (const auto& [ea, eb] : pairs) {
    const TopoDS_Shape* sa = piece_of(ea);
    const TopoDS_Shape* sb = sa ? piece_of(eb) : nullptr;
    if (!sa || !sb) return result;
    PieceGap gap;
    gap.cell = grid.elements[ea].cell;
    gap.cell_b = grid.elements[eb].cell;
    gap.element_a = ea;
    gap.element_b = eb;
    if (sa == sb) {
      gap.joined = true;
      result.gaps.push_back(gap);
      continue;
    }
    BRepExtrema_DistShapeShape dist;
    try {
      dist.LoadS1(*sa), dist.LoadS2(*sb), dist.Perform();
    } catch (const Standard_Failure& f) {
      result.message = "piece_gaps: OCCT's distance between elements " + std::to_string(ea) + " and " + std::to_string(eb) +
                       " threw: " + f.GetMessageString();
      return result;
    }
    if (!dist.IsDone() || dist.NbSolution() < 1) {
      result.message = "piece_gaps: no distance between elements " + std::to_string(ea) + " (cell " + cell_name(gap.cell) +
                       ") and " + std::to_string(eb) + " (cell " + cell_name(gap.cell_b) + ")";
      return result;
    }
    gap.distance = dist.Value();
    if (options.critical_distance > 0 && gap.distance >= options.critical_distance) continue;
    const double tol = options.face_tolerance * grid.elements[ea].box.size().minCoeff();
    gap.a = locate(part, boxes, to_vec(dist.PointOnShape1(1)), tol, grid.elements[ea].box);
    gap.b = locate(part, boxes, to_vec(dist.PointOnShape2(1)), tol, grid.elements[eb].box);
    result.gaps.push_back(gap);
  }
  result.done = true;
  result.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return result;
}

Eigen::MatrixXd piece_gap_gradient(const std::vector<PieceGap>& gaps, const ShapeParameters& sp, const Eigen::VectorXd& p,
                                   std::vector<char>* complete) {
  PARAFAB_VERIFY(p.size() == sp.size(), "piece_gap_gradient: p has " << p.size() << " entries, the parameters " << sp.size());
  Eigen::MatrixXd g = Eigen::MatrixXd::Zero(static_cast<Eigen::Index>(gaps.size()), sp.size());
  if (complete) complete->assign(gaps.size(), 1);
  for (size_t i = 0; i < gaps.size(); ++i) {
    const PieceGap& gap = gaps[i];
    bool whole = !gap.joined && gap.distance > 0;
    if (whole) {
      const xfem::Vec3 t = (gap.b.point - gap.a.point) / gap.distance;
      // An end moves by Vₙ/(n·s) along s (pointing from it to the other end), from the one face
      // at it that is not along s.
      auto add = [&](const GapEnd& end, const xfem::Vec3& s) {
        int moving = -1;
        for (size_t k = 0; k < end.faces.size(); ++k) {
          if (end.normals[k].isZero()) {
            whole = false;  // no normal there
            return;
          }
          if (std::abs(end.normals[k].dot(s)) < 1e-9) continue;  // the gap runs along this face
          if (moving >= 0) {
            whole = false;  // an edge or vertex of the part: two faces move it
            return;
          }
          moving = static_cast<int>(k);
        }
        if (moving < 0) return;  // on the cell's box (or along faces only): fixed
        const int face = end.faces[moving];
        const xfem::Vec3& n = end.normals[moving];
        if (sp.poles(face)) {
          whole = false;
          return;
        }
        const optimize::ParameterBlock* block = sp.block(face);
        if (!block) return;  // a face without parameters does not move
        if (!(n.dot(s) > 0)) {
          whole = false;  // the solid's normal points away from the gap: not a closest point of this face
          return;
        }
        Eigen::Matrix3d P = Eigen::Matrix3d::Identity();  // the directions the end may move in
        for (int k : end.box_axes) P -= xfem::Vec3::Unit(k) * xfem::Vec3::Unit(k).transpose();
        const xfem::Vec3 Pn = P * n;
        const double nPn = n.dot(Pn);
        if (!(nPn > 1e-12)) return;  // a box corner, or a box edge along the face: fixed
        const double ps = Pn.dot(s);
        if (ps == 0) return;  // it moves across the gap direction only
        const double ns = nPn / ps;  // the end moves by Vₙ Pn/nPn: d' ∋ −Vₙ (Pn·s)/nPn
        const optimize::Dual phi = optimize::implicit_function(block->kind, p.data() + block->offset, end.point);
        const int nb = block->size();
        const xfem::Vec3 grad(phi.g[nb], phi.g[nb + 1], phi.g[nb + 2]);
        const double gn = grad.norm();
        if (!(gn > 0)) {
          whole = false;
          return;
        }
        const double sign = grad.dot(n) >= 0 ? 1.0 : -1.0;
        for (int k = 0; k < nb; ++k) g(static_cast<Eigen::Index>(i), block->offset + k) -= (-sign * phi.g[k] / gn) / ns;
      };
      add(gap.a, t);
      add(gap.b, -t);
    }
    if (!whole) g.row(static_cast<Eigen::Index>(i)).setZero();
    if (complete) (*complete)[i] = whole;
  }
  return g;
}

double merge_penalty_b(double d, double critical, const MergePenaltyOptions& options, double* derivative) {
  const bool log2 = options.law == MergePenaltyOptions::Law::Log2;
  const double cap = options.cap > 0 ? options.cap : log2 ? 1e3 : 1e4;
  PARAFAB_VERIFY(critical > 0, "merge penalty: critical distance " << critical);
  if (derivative) *derivative = 0;
  if (d >= critical) return 0;
  if (!(d > 0)) return cap;
  double b, db;
  if (log2) {
    const double l = std::log(d / critical);
    b = l * l, db = 2 * l / d;
  } else {
    const double q = critical / d - 1;
    b = q * q, db = -2 * q * critical / (d * d);
  }
  if (b >= cap) return cap;
  if (derivative) *derivative = db;
  return b;
}

std::vector<xfem::PieceTie> piece_ties(const std::vector<PieceGap>& gaps, const GridModel& grid, double youngs_modulus,
                                       const MergePenaltyOptions& options) {
  std::vector<xfem::PieceTie> ties;
  for (const PieceGap& gap : gaps) {
    const double h = grid.elements[gap.element_a].box.size().minCoeff();
    const double b = merge_penalty_b(gap.joined ? 0.0 : gap.distance, options.critical_fraction * h, options);
    if (b > 0) ties.push_back({gap.element_a, gap.element_b, youngs_modulus * h * b, 1 - std::exp(-b)});
  }
  return ties;
}

}  // namespace parafab::occ
