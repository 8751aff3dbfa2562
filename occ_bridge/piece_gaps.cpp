// Gaps between the material pieces of a grid cell (thesis §6.4.4, the distance d of Eq. 6.24).
#include "piece_gaps.h"

#include <BRepAdaptor_Surface.hxx>
#include <BRepAlgoAPI_Common.hxx>
#include <BRepBndLib.hxx>
#include <BRepBuilderAPI_MakeVertex.hxx>
#include <BRepExtrema_DistShapeShape.hxx>
#include <BRepGProp.hxx>
#include <BRepPrimAPI_MakeBox.hxx>
#include <BRep_Tool.hxx>
#include <Bnd_Box.hxx>
#include <GProp_GProps.hxx>
#include <GeomAPI_ProjectPointOnSurf.hxx>
#include <TopExp_Explorer.hxx>
#include <chrono>
#include <cmath>
#include <limits>
#include <map>
#include <sstream>

#include "common/error.h"
#include "grid_model.h"
#include "occt_shape.h"
#include "optimize/shape_constraints.h"
#include "shape_parameters.h"

namespace parafab::occ {

namespace {

xfem::Vec3 to_vec(const gp_Pnt& P) { return {P.X(), P.Y(), P.Z()}; }

// The faces of the part within `tol` of X; the outward normal of the first one.
GapEnd locate(const PartShape& part, const std::vector<Bnd_Box>& boxes, const xfem::Vec3& X, double tol) {
  GapEnd end;
  end.point = X;
  const gp_Pnt P(X.x(), X.y(), X.z());
  const TopoDS_Vertex v = BRepBuilderAPI_MakeVertex(P).Vertex();
  std::vector<int> on;
  for (int f = 0; f < part.face_count(); ++f) {
    if (boxes[f].IsOut(P)) continue;
    BRepExtrema_DistShapeShape dist(v, part.face(f));
    if (dist.IsDone() && dist.Value() <= tol) on.push_back(f);
  }
  if (on.empty()) return end;  // on the cell's box only
  if (on.size() > 1) {
    end.face = -2;
    return end;
  }
  end.face = on[0];
  const TopoDS_Face& face = part.face(on[0]);
  GeomAPI_ProjectPointOnSurf projection(P, BRep_Tool::Surface(face));
  if (projection.NbPoints() == 0) {
    end.face = -2;  // no foot point: no normal, no derivative
    return end;
  }
  double u, v_;
  projection.LowerDistanceParameters(u, v_);
  gp_Pnt Q;
  gp_Vec du, dv;
  BRep_Tool::Surface(face)->D1(u, v_, Q, du, dv);
  gp_Vec n = du.Crossed(dv);
  if (n.Magnitude() <= 0) {
    end.face = -2;
    return end;
  }
  n.Normalize();
  if (face.Orientation() == TopAbs_REVERSED) n.Reverse();
  end.normal = {n.X(), n.Y(), n.Z()};
  return end;
}

struct OcctPiece {
  TopoDS_Shape solid;
  xfem::Vec3 centroid;
};

}  // namespace

PieceGapResult piece_gaps(const PartShape& part, const GridModel& grid, const PieceGapOptions& options) {
  const auto t0 = std::chrono::steady_clock::now();
  PieceGapResult result;
  std::map<std::array<int, 3>, std::vector<int>> pieces;  // cut cells' elements
  for (int e = 0; e < static_cast<int>(grid.elements.size()); ++e)
    if (grid.elements[e].subvolume) pieces[grid.elements[e].cell].push_back(e);
  std::vector<Bnd_Box> boxes(part.face_count());
  for (int f = 0; f < part.face_count(); ++f) {
    BRepBndLib::Add(part.face(f), boxes[f]);
    boxes[f].Enlarge(1e-6);
  }
  for (const auto& [cell, members] : pieces) {
    if (members.size() < 2) continue;
    ++result.cells_checked;
    const xfem::Box3& box = grid.elements[members[0]].box;
    const double tol = options.face_tolerance * box.size().minCoeff();
    BRepAlgoAPI_Common common(part.shape, BRepPrimAPI_MakeBox(gp_Pnt(box.min.x(), box.min.y(), box.min.z()),
                                                              gp_Pnt(box.max.x(), box.max.y(), box.max.z()))
                                              .Shape());
    if (!common.IsDone()) {
      std::ostringstream m;
      m << "piece_gaps: OCCT's common of the part and cell (" << cell[0] << ", " << cell[1] << ", " << cell[2]
        << ") failed";
      result.message = m.str();
      return result;
    }
    std::vector<OcctPiece> solids;
    for (TopExp_Explorer x(common.Shape(), TopAbs_SOLID); x.More(); x.Next()) {
      GProp_GProps g;
      BRepGProp::VolumeProperties(x.Current(), g);
      if (!(g.Mass() > 0)) continue;
      solids.push_back({x.Current(), to_vec(g.CentreOfMass())});
    }
    if (solids.empty()) {
      std::ostringstream m;
      m << "piece_gaps: OCCT finds no material in cell (" << cell[0] << ", " << cell[1] << ", " << cell[2]
        << "), which the cut gives " << members.size() << " pieces";
      result.message = m.str();
      return result;
    }
    // Each element's OCCT piece: the one with the nearest centroid (the rule's centroid is the
    // piece's to the rule's accuracy; a merged piece sits between its parts').
    std::vector<int> solid_of(members.size());
    for (size_t i = 0; i < members.size(); ++i) {
      const xfem::QuadratureRule3& rule = grid.elements[members[i]].rule;
      double w = 0;
      xfem::Vec3 c = xfem::Vec3::Zero();
      for (size_t q = 0; q < rule.points.size(); ++q) w += rule.weights[q], c += rule.weights[q] * rule.points[q];
      if (w > 0) c /= w;
      double best = std::numeric_limits<double>::infinity();
      for (size_t s = 0; s < solids.size(); ++s) {
        const double dist = (solids[s].centroid - c).norm();
        if (dist < best) best = dist, solid_of[i] = static_cast<int>(s);
      }
      result.max_centroid_mismatch = std::max(result.max_centroid_mismatch, best);
    }
    for (size_t i = 0; i < members.size(); ++i)
      for (size_t j = i + 1; j < members.size(); ++j) {
        PieceGap gap;
        gap.cell = cell;
        gap.element_a = members[i];
        gap.element_b = members[j];
        if (solid_of[i] == solid_of[j]) {
          gap.joined = true;
          result.gaps.push_back(gap);
          continue;
        }
        BRepExtrema_DistShapeShape dist(solids[solid_of[i]].solid, solids[solid_of[j]].solid);
        if (!dist.IsDone() || dist.NbSolution() < 1) {
          std::ostringstream m;
          m << "piece_gaps: no distance between pieces " << members[i] << " and " << members[j] << " of cell ("
            << cell[0] << ", " << cell[1] << ", " << cell[2] << ")";
          result.message = m.str();
          return result;
        }
        gap.distance = dist.Value();
        if (options.critical_distance > 0 && gap.distance >= options.critical_distance) continue;
        gap.a = locate(part, boxes, to_vec(dist.PointOnShape1(1)), tol);
        gap.b = locate(part, boxes, to_vec(dist.PointOnShape2(1)), tol);
        result.gaps.push_back(gap);
      }
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
      // End e with its outward normal n moves by Vₙ/(n·s) along s, s pointing from it to the other end.
      auto add = [&](const GapEnd& end, const xfem::Vec3& s) {
        if (end.face == -1) return;  // on the cell's box: fixed
        if (end.face < 0 || sp.poles(end.face)) {
          whole = false;
          return;
        }
        const optimize::ParameterBlock* block = sp.block(end.face);
        if (!block) return;  // a face without parameters does not move
        const double ns = end.normal.dot(s);
        if (!(ns > 1e-9)) {
          whole = false;  // the gap leaves along the face: no first-order motion
          return;
        }
        const optimize::Dual phi = optimize::implicit_function(block->kind, p.data() + block->offset, end.point);
        const int nb = block->size();
        const xfem::Vec3 grad(phi.g[nb], phi.g[nb + 1], phi.g[nb + 2]);
        const double gn = grad.norm();
        if (!(gn > 0)) {
          whole = false;
          return;
        }
        const double sign = grad.dot(end.normal) >= 0 ? 1.0 : -1.0;
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

}  // namespace parafab::occ
