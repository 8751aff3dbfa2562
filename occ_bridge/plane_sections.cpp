#include "plane_sections.h"

#include <BRepAdaptor_CompCurve.hxx>
#include <BRepAlgoAPI_Section.hxx>
#include <BRepBndLib.hxx>
#include <BRep_Builder.hxx>
#include <Bnd_Box.hxx>
#include <GCPnts_QuasiUniformAbscissa.hxx>
#include <GCPnts_AbscissaPoint.hxx>
#include <ShapeAnalysis_FreeBounds.hxx>
#include <Standard_Failure.hxx>
#include <TopExp_Explorer.hxx>
#include <TopTools_HSequenceOfShape.hxx>
#include <TopoDS.hxx>
#include <TopoDS_Wire.hxx>
#include <gp_Pln.hxx>

#include <algorithm>
#include <cmath>

#include "common/error.h"
#include "occt_shape.h"

namespace parafab::occ {

using Eigen::Vector2d;
using Eigen::Vector3d;

namespace {

// A point of the dense polyline and its curve parameter (unwrapped on closed curves).
struct Sample {
  Vector3d X;
  double t;
};

// n curve parameters equally spaced in (polyline) arc length along p; the caller evaluates
// the exact curve there, so the samples lie on the curve, not on the chords.
std::vector<double> resample(const std::vector<Sample>& p, int n) {
  std::vector<double> s(p.size(), 0.0);
  for (size_t i = 1; i < p.size(); ++i) s[i] = s[i - 1] + (p[i].X - p[i - 1].X).norm();
  std::vector<double> out;
  size_t k = 1;
  for (int i = 0; i < n; ++i) {
    const double t = s.back() * i / (n - 1);
    while (k + 1 < p.size() && s[k] < t) ++k;
    const double seg = s[k] - s[k - 1];
    const double a = seg > 0 ? (t - s[k - 1]) / seg : 0.0;
    out.push_back((1 - a) * p[k - 1].t + a * p[k].t);
  }
  return out;
}

double polyline_length(const std::vector<Sample>& p) {
  double l = 0;
  for (size_t i = 1; i < p.size(); ++i) l += (p[i].X - p[i - 1].X).norm();
  return l;
}

}  // namespace

PlaneSectionResult plane_sections(const PartShape& part, const PlaneSectionOptions& o) {
  PARAFAB_VERIFY(o.normal.norm() > 0, "sections: planes.normal must not be zero");
  PARAFAB_VERIFY(o.samples >= 4, "sections: samples must be >= 4, got " << o.samples);
  PARAFAB_VERIFY(!o.split || o.split_normal.norm() > 0, "sections: split.normal must not be zero");
  PlaneSectionResult r;
  const Vector3d n = o.normal.normalized();
  Bnd_Box bb;
  BRepBndLib::Add(part.shape, bb);
  double x0, y0, z0, x1, y1, z1;
  bb.Get(x0, y0, z0, x1, y1, z1);
  const Vector3d lo(x0, y0, z0), hi(x1, y1, z1);
  const double diag = (hi - lo).norm();
  const double min_length = o.min_length > 0 ? o.min_length : 1e-3 * diag;
  // Extent along n from the box corners.
  double dmin = 1e300, dmax = -1e300;
  for (int c = 0; c < 8; ++c) {
    const Vector3d X((c & 1) ? hi.x() : lo.x(), (c & 2) ? hi.y() : lo.y(), (c & 4) ? hi.z() : lo.z());
    dmin = std::min(dmin, n.dot(X)), dmax = std::max(dmax, n.dot(X));
  }
  r.offsets = o.offsets;
  if (r.offsets.empty()) {
    PARAFAB_VERIFY(o.count >= 1, "sections: planes.count must be >= 1, got " << o.count);
    for (int i = 1; i <= o.count; ++i) r.offsets.push_back(dmin + (dmax - dmin) * i / (o.count + 1));
  }
  // The plane frame: u ⟂ n (from the axis least aligned with n), v = n × u.
  Vector3d helper = Vector3d::Unit(0);
  if (std::abs(n.x()) > 0.9) helper = Vector3d::Unit(1);
  const Vector3d u = (helper - helper.dot(n) * n).normalized();
  const Vector3d v = n.cross(u);
  const Vector3d sn = o.split ? o.split_normal.normalized() : Vector3d::Zero();
  try {
    for (size_t pi = 0; pi < r.offsets.size(); ++pi) {
      const Vector3d origin = r.offsets[pi] * n;
      BRepAlgoAPI_Section section(part.shape, gp_Pln(gp_Pnt(origin.x(), origin.y(), origin.z()), gp_Dir(n.x(), n.y(), n.z())),
                                  Standard_False);
      section.Approximation(Standard_True);
      section.Build();
      if (!section.IsDone()) {
        r.message = "OCCT could not intersect the shape with plane " + std::to_string(pi);
        return r;
      }
      Handle(TopTools_HSequenceOfShape) edges = new TopTools_HSequenceOfShape;
      for (TopExp_Explorer ex(section.Shape(), TopAbs_EDGE); ex.More(); ex.Next()) edges->Append(ex.Current());
      if (edges->IsEmpty()) {
        r.empty_planes.push_back(static_cast<int>(pi));
        continue;
      }
      Handle(TopTools_HSequenceOfShape) wires;
      ShapeAnalysis_FreeBounds::ConnectEdgesToWires(edges, 1e-6 * diag, Standard_False, wires);
      int piece = 0;
      for (int w = 1; w <= wires->Length(); ++w) {
        const TopoDS_Wire wire = TopoDS::Wire(wires->Value(w));
        BRepAdaptor_CompCurve curve(wire);
        const double length = GCPnts_AbscissaPoint::Length(curve);
        if (length < min_length) continue;
        const int dense = std::max(8 * o.samples, 400);
        GCPnts_QuasiUniformAbscissa pts(curve, dense);
        if (!pts.IsDone()) continue;
        std::vector<Sample> poly;
        for (int i = 1; i <= pts.NbPoints(); ++i) {
          const gp_Pnt p = curve.Value(pts.Parameter(i));
          poly.push_back({Vector3d(p.X(), p.Y(), p.Z()), pts.Parameter(i)});
        }
        const double t0 = curve.FirstParameter(), period = curve.LastParameter() - curve.FirstParameter();
        auto value = [&](double t) {  // the exact curve; unwrapped parameters folded back
          if (t > curve.LastParameter()) t -= period;
          const gp_Pnt p = curve.Value(std::max(t, t0));
          return Vector3d(p.X(), p.Y(), p.Z());
        };
        const bool closed = (poly.front().X - poly.back().X).norm() <= 1e-6 * diag;
        std::vector<std::vector<Sample>> pieces;
        if (!o.split) {
          pieces.push_back(poly);
        } else {  // cut the polyline where the signed distance to the split plane changes sign
          auto side = [&](const Sample& P) { return sn.dot(P.X) - o.split_offset; };
          // Sides by sign, zero counted as positive, so a sample exactly on the plane is
          // crossed once, not missed.
          auto crosses = [](double a, double b) { return (a < 0) != (b < 0); };
          auto between = [&](const Sample& A, const Sample& B, double a, double b) {
            const double f = a / (a - b);
            return Sample{A.X + (B.X - A.X) * f, A.t + (B.t - A.t) * f};
          };
          std::vector<Sample> ring = poly;
          if (closed) {  // start and end at a crossing point so that no piece wraps around
            ring.pop_back();
            const size_t m = ring.size();
            for (size_t i = 0; i < m; ++i) {
              Sample B = ring[(i + 1) % m];
              if (i + 1 == m) B.t += period;
              const double a = side(ring[i]), b = side(B);
              if (!crosses(a, b)) continue;
              const Sample X = between(ring[i], B, a, b);
              for (size_t k = 0; k <= i; ++k) ring[k].t += period;  // unwrap: they now come last
              std::rotate(ring.begin(), ring.begin() + static_cast<long>((i + 1) % m), ring.end());
              ring.insert(ring.begin(), X);
              break;
            }
            Sample end = ring.front();
            end.t += period;
            ring.push_back(end);
          }
          std::vector<Sample> cur{ring.front()};
          for (size_t i = 1; i < ring.size(); ++i) {
            const double a = side(ring[i - 1]), b = side(ring[i]);
            if (crosses(a, b)) {
              const Sample X = between(ring[i - 1], ring[i], a, b);
              cur.push_back(X);
              pieces.push_back(cur);
              cur = {X};
            }
            cur.push_back(ring[i]);
          }
          pieces.push_back(cur);
        }
        for (const auto& pc : pieces) {
          if (pc.size() < 2 || polyline_length(pc) < min_length) continue;
          SectionCurve c;
          c.plane = static_cast<int>(pi);
          c.offset = r.offsets[pi];
          c.piece = piece++;
          c.closed = closed && !o.split;
          c.origin = origin;
          c.u_axis = u;
          c.v_axis = v;
          for (double t : resample(pc, o.samples)) c.points.push_back(value(t));
          {  // the exact length between the piece's end parameters (across the seam in two parts)
            const double ta = pc.front().t, tb = pc.back().t, t1 = curve.LastParameter();
            c.length = tb <= t1 + 1e-12 * period
                           ? GCPnts_AbscissaPoint::Length(curve, ta, std::min(tb, t1))
                           : GCPnts_AbscissaPoint::Length(curve, ta, t1) + GCPnts_AbscissaPoint::Length(curve, t0, tb - period);
          }
          for (const Vector3d& X : c.points) c.points2d.emplace_back(u.dot(X - origin), v.dot(X - origin));
          r.curves.push_back(std::move(c));
        }
      }
    }
  } catch (const Standard_Failure& e) {
    r.message = std::string("OCCT failed while taking sections: ") + e.GetMessageString();
    return r;
  }
  r.done = true;
  return r;
}

}  // namespace parafab::occ
