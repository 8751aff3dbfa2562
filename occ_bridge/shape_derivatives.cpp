// Hadamard shape derivatives of volume moments over trimmed B-rep faces (thesis §6.2.3,
// Eq. 6.5; boundary velocity from the face's surface parameters, §6.5.1).
#include "shape_derivatives.h"

#include <BRepAdaptor_Surface.hxx>
#include <BRepGProp.hxx>
#include <BRepTools.hxx>
#include <BRep_Tool.hxx>
#include <GProp_GProps.hxx>
#include <Geom2dAdaptor_Curve.hxx>
#include <Geom2d_Curve.hxx>
#include <TColStd_Array1OfReal.hxx>
#include <algorithm>
#include <TopExp_Explorer.hxx>
#include <TopoDS.hxx>
#include <chrono>
#include <cmath>

#include "common/error.h"
#include "occt_shape.h"

namespace parafab::occ {

namespace {

// n-point Gauss-Legendre on [0, 1] by Newton on P_n.
void gauss01(int n, std::vector<double>& x, std::vector<double>& w) {
  x.resize(n);
  w.resize(n);
  for (int i = 0; i < n; ++i) {
    double z = std::cos(M_PI * (i + 0.75) / (n + 0.5)), dp = 0;
    for (int it = 0; it < 100; ++it) {
      double p0 = 1, p1 = 0;
      for (int k = 1; k <= n; ++k) {
        const double p2 = p1;
        p1 = p0;
        p0 = ((2.0 * k - 1) * z * p1 - (k - 1.0) * p2) / k;
      }
      dp = n * (z * p0 - p1) / (z * z - 1);
      const double dz = p0 / dp;
      z -= dz;
      if (std::abs(dz) < 1e-16) break;
    }
    x[i] = 0.5 * (1 - z);
    w[i] = 1.0 / ((1 - z * z) * dp * dp);  // 2/((1−z²)P'²) on [−1,1], halved
  }
}

Moments monomials(const Vec3& X) {
  Moments m;
  m << 1, X.x(), X.y(), X.z(), X.x() * X.x(), X.y() * X.y(), X.z() * X.z(), X.x() * X.y(), X.y() * X.z(),
      X.x() * X.z();
  return m;
}

// ∫_Ω g dV = ∫_∂Ω G·n dA with div G = g: G = (X g_X-antiderivative) per monomial.
Moments flux(const Vec3& X, const Vec3& n) {
  const double x = X.x(), y = X.y(), z = X.z();
  Moments m;
  m << X.dot(n) / 3,             // 1: G = X/3
      0.5 * x * x * n.x(),       // X: G = (x²/2, 0, 0)
      0.5 * y * y * n.y(),       // Y
      0.5 * z * z * n.z(),       // Z
      x * x * x / 3 * n.x(),     // XX
      y * y * y / 3 * n.y(),     // YY
      z * z * z / 3 * n.z(),     // ZZ
      0.5 * x * x * y * n.x(),   // XY: G = (x²y/2, 0, 0)
      0.5 * y * y * z * n.y(),   // YZ
      0.5 * x * x * z * n.x();   // XZ
  return m;
}

// The surface's knots (breaks of every continuity order) strictly inside (lo, hi) along u (or v): the knots of a B-spline.
std::vector<double> interior_breaks(const BRepAdaptor_Surface& s, bool along_u, double lo, double hi) {
  const int n = along_u ? s.NbUIntervals(GeomAbs_CN) : s.NbVIntervals(GeomAbs_CN);
  std::vector<double> r;
  if (n <= 1) return r;
  TColStd_Array1OfReal t(1, n + 1);
  if (along_u)
    s.UIntervals(t, GeomAbs_CN);
  else
    s.VIntervals(t, GeomAbs_CN);
  const double eps = 1e-12 * (1 + std::abs(hi - lo));
  for (int i = 1; i <= n + 1; ++i)
    if (t(i) > lo + eps && t(i) < hi - eps) r.push_back(t(i));
  return r;
}

// [f, ..., l]: the pcurve's own knots and the parameters where its u crosses one of `u_knots`
// or its v one of `v_knots` (sign changes on 64 samples, then bisection), sorted.
std::vector<double> edge_pieces(const Handle(Geom2d_Curve)& c, double f, double l, const std::vector<double>& u_knots,
                                const std::vector<double>& v_knots) {
  std::vector<double> t = {f, l};
  const Geom2dAdaptor_Curve a(c, f, l);
  if (const int n = a.NbIntervals(GeomAbs_CN); n > 1) {
    TColStd_Array1OfReal T(1, n + 1);
    a.Intervals(T, GeomAbs_CN);
    for (int i = 2; i <= n; ++i) t.push_back(T(i));
  }
  const int samples = 64;
  for (int coordinate = 0; coordinate < 2; ++coordinate)
    for (double knot : coordinate == 0 ? u_knots : v_knots) {
      auto side = [&](double x) { return c->Value(x).Coord(coordinate + 1) - knot; };
      double prev = side(f);
      for (int k = 1; k <= samples; ++k) {
        const double t1 = f + (l - f) * k / samples, now = side(t1);
        if (prev == 0 && k > 1) t.push_back(t1 - (l - f) / samples);
        if ((prev < 0 && now > 0) || (prev > 0 && now < 0)) {
          double lo = t1 - (l - f) / samples, hi = t1;
          for (int it = 0; it < 60; ++it) {
            const double mid = 0.5 * (lo + hi);
            ((side(mid) < 0) == (prev < 0) ? lo : hi) = mid;
          }
          t.push_back(0.5 * (lo + hi));
        }
        prev = now;
      }
    }
  std::sort(t.begin(), t.end());
  const double eps = 1e-12 * (1 + std::abs(l - f));
  std::vector<double> r;
  for (double x : t)
    if (r.empty() || x > r.back() + eps) r.push_back(x);
  if (r.size() < 2) r = {f, l};
  r.back() = l;
  return r;
}

}  // namespace

MomentDerivatives moment_derivatives(const PartShape& part, const ShapeParameters& sp, const Eigen::VectorXd& p,
                                     const BoundaryQuadratureOptions& options) {
  PARAFAB_VERIFY(p.size() == sp.size(), "moment_derivatives: p has " << p.size() << " entries, the parameters "
                                                                     << sp.size());
  PARAFAB_VERIFY(static_cast<int>(sp.block_of_face.size()) == part.face_count(),
                 "moment_derivatives: the parameters describe " << sp.block_of_face.size() << " faces, the part has "
                                                                << part.face_count());
  const auto t0 = std::chrono::steady_clock::now();
  MomentDerivatives r;
  r.gradient = Eigen::MatrixXd::Zero(10, sp.size());
  std::vector<double> ex, ew, ix, iw;
  gauss01(options.edge_points, ex, ew);
  gauss01(options.inner_points, ix, iw);
  for (int fi = 0; fi < part.face_count(); ++fi) {
    const TopoDS_Face& original = part.face(fi);
    const double orient = original.Orientation() == TopAbs_REVERSED ? -1.0 : 1.0;
    const TopoDS_Face face = TopoDS::Face(original.Oriented(TopAbs_FORWARD));
    const BRepAdaptor_Surface surface(face, false);
    const optimize::ParameterBlock* block = sp.block(fi);
    const PoleBlock* poles = sp.poles(fi);
    double u0, u1, v0, v1;
    BRepTools::UVBounds(face, u0, u1, v0, v1);
    // h(u, v)·du dv summed into the moments and gradient.
    auto point = [&](double u, double v, double weight) {
      gp_Pnt P;
      gp_Vec du, dv;
      surface.D1(u, v, P, du, dv);
      const gp_Vec N = du.Crossed(dv);
      const double jac = N.Magnitude();
      if (jac < 1e-300) return;
      const Vec3 X(P.X(), P.Y(), P.Z()), n = orient * Vec3(N.X(), N.Y(), N.Z()) / jac;
      const double dA = weight * jac;
      r.moments += dA * flux(X, n);
      ++r.points;
      if (poles) {  // ∂X/∂P_ij = R_ij(u, v) I: V_n = R_ij n_c for coordinate c of pole (i, j)
        const Moments g = monomials(X);
        for (const PoleInfluence& w : pole_influence(poles->surface, u, v))
          for (int c = 0; c < 3; ++c)
            if (const double vn = w.value * n[c]; vn != 0) r.gradient.col(poles->offset + 3 * w.index + c) += (dA * vn) * g;
      }
      if (!block) return;
      const optimize::Dual phi = optimize::implicit_function(block->kind, p.data() + block->offset, X);
      const int nb = block->size();
      const Vec3 grad(phi.g[nb], phi.g[nb + 1], phi.g[nb + 2]);
      const double gn = grad.norm();
      const double s = grad.dot(n) >= 0 ? 1.0 : -1.0;
      const Moments g = monomials(X);
      for (int k = 0; k < nb; ++k) {
        const double vn = -s * phi.g[k] / gn;  // ∂X/∂p_k · n
        if (vn != 0) r.gradient.col(block->offset + k) += (dA * vn) * g;
      }
    };
    // Knots of a B-spline surface (where h is only C¹ or less) split the Gauss rules: the inner
    // integral at the u knots, each edge where its pcurve crosses a knot or has its own knot.
    const std::vector<double> u_knots = interior_breaks(surface, true, u0, u1), v_knots = interior_breaks(surface, false, v0, v1);
    for (TopExp_Explorer e(face, TopAbs_EDGE); e.More(); e.Next()) {
      const TopoDS_Edge& edge = TopoDS::Edge(e.Current());
      double f, l;
      const Handle(Geom2d_Curve) c = BRep_Tool::CurveOnSurface(edge, face, f, l);
      PARAFAB_VERIFY(!c.IsNull(), part.source << ": face " << fi << ": an edge has no pcurve");
      const double dir = edge.Orientation() == TopAbs_REVERSED ? -1.0 : 1.0;
      const std::vector<double> pieces = edge_pieces(c, f, l, u_knots, v_knots);
      for (size_t piece = 0; piece + 1 < pieces.size(); ++piece) {
        const double a = pieces[piece], b = pieces[piece + 1];
        for (int sgm = 0; sgm < options.edge_segments; ++sgm)
          for (int q = 0; q < options.edge_points; ++q) {
            const double t = a + (b - a) * (sgm + ex[q]) / options.edge_segments;
            gp_Pnt2d uv;
            gp_Vec2d d;
            c->D1(t, uv, d);
            const double dvdt = d.Y() * dir * (b - a) / options.edge_segments * ew[q];
            if (dvdt == 0) continue;
            // ∫_{u0}^{u} h(s, v) ds by Gauss in s, piece by piece between the u knots.
            double lo = u0;
            for (size_t k = 0; k <= u_knots.size(); ++k) {
              const double hi = k < u_knots.size() ? std::min(u_knots[k], uv.X()) : uv.X();
              if (hi <= lo) continue;
              const double span = hi - lo;
              for (int j = 0; j < options.inner_points; ++j) point(lo + span * ix[j], uv.Y(), dvdt * span * iw[j]);
              lo = hi;
            }
          }
      }
    }
  }
  r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return r;
}

Moments occt_moments(const PartShape& part, double eps) {
  GProp_GProps g;
  BRepGProp::VolumeProperties(part.shape, g, eps, Standard_True);
  const double m0 = g.Mass();
  const gp_Pnt c = g.CentreOfMass();
  const Vec3 C(c.X(), c.Y(), c.Z());
  const gp_Mat I = g.MatrixOfInertia();
  Eigen::Matrix3d inertia;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) inertia(i, j) = I.Value(i + 1, j + 1);
  // inertia = tr(S) I − S with S the central second moments: tr(S) = tr(inertia) / 2.
  const Eigen::Matrix3d S = 0.5 * inertia.trace() * Eigen::Matrix3d::Identity() - inertia;
  const Eigen::Matrix3d M2 = S + m0 * C * C.transpose();
  Moments m;
  m << m0, m0 * C.x(), m0 * C.y(), m0 * C.z(), M2(0, 0), M2(1, 1), M2(2, 2), M2(0, 1), M2(1, 2), M2(0, 2);
  return m;
}

}  // namespace parafab::occ
