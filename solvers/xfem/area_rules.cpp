// Area rules by moment fitting (thesis §6.3.2, Eq. 6.9–6.14), surface rules (Eq. 6.15), and
// their quadrant refinement with loops clipped to the quadrants.
#include "xfem/area_rules.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <limits>

#include "common/error.h"

namespace parafab::xfem {

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
// |measure| / (bounding-box measure) at or below this is round-off: the region is empty.
constexpr double kEmptyFraction = 64 * std::numeric_limits<double>::epsilon();

CurveSegment2 chord(const Vec2& a, const Vec2& b) { return {a, 0.5 * (a + b), b, 1}; }

CurveSegment2 sub_segment(const CurveSegment2& s, double ta, double tb) {
  CurveSegment2 r = s;
  r.start = ta == 0 ? s.start : s.position(ta);
  r.end = tb == 1 ? s.end : s.position(tb);
  r.mid = s.order == 2 ? s.position(0.5 * (ta + tb)) : 0.5 * (r.start + r.end);
  return r;
}

// Parameters t ∈ (0, 1) where coordinate `axis` of the segment equals c, ascending, followed
// by t = 1 (at most 3 entries; no allocation: this runs for every segment of every clip).
struct Cuts {
  double t[3];
  int n = 0;
};
Cuts crossings(const CurveSegment2& s, int axis, double c) {
  const double c0 = s.start[axis] - c;
  const double c1 = s.order == 2 ? -3 * s.start[axis] + 4 * s.mid[axis] - s.end[axis]
                                 : s.end[axis] - s.start[axis];
  const double c2 = s.order == 2 ? 2 * s.start[axis] - 4 * s.mid[axis] + 2 * s.end[axis] : 0;
  double roots[2];
  int count = 0;
  if (c2 == 0) {
    if (c1 != 0) roots[count++] = -c0 / c1;
  } else {
    const double disc = c1 * c1 - 4 * c2 * c0;
    if (disc >= 0) {
      const double q = -0.5 * (c1 + std::copysign(std::sqrt(disc), c1));
      roots[count++] = q / c2;
      if (q != 0) roots[count++] = c0 / q;
    }
  }
  constexpr double margin = 1e-12;
  Cuts t;
  for (int k = 0; k < count; ++k)
    if (roots[k] > margin && roots[k] < 1 - margin) t.t[t.n++] = roots[k];
  if (t.n == 2 && t.t[1] < t.t[0]) std::swap(t.t[0], t.t[1]);
  t.t[t.n++] = 1;
  return t;
}

// Sutherland–Hodgman step: the part of a closed loop where side·(x[axis] − c) ≤ 0.
UvLoop clip_half_plane(const UvLoop& loop, int axis, double c, double side) {
  struct Piece {
    CurveSegment2 segment;
    bool inside;
  };
  std::vector<Piece> pieces;
  pieces.reserve(loop.size() + 4);
  for (const CurveSegment2& s : loop) {
    double ta = 0;
    const Cuts cuts = crossings(s, axis, c);
    for (int k = 0; k < cuts.n; ++k) {
      const double tb = cuts.t[k];
      const CurveSegment2 piece = cuts.n == 1 ? s : sub_segment(s, ta, tb);  // uncut: as is
      pieces.push_back({piece, side * (piece.position(0.5)[axis] - c) <= 0});
      ta = tb;
    }
  }
  const auto inside_count =
      std::count_if(pieces.begin(), pieces.end(), [](const Piece& p) { return p.inside; });
  if (inside_count == static_cast<long>(pieces.size())) return loop;
  if (inside_count == 0) return {};
  // Start at an entry (inside piece after an outside one); replace each outside run by a chord.
  const int n = static_cast<int>(pieces.size());
  int first = 0;
  while (!(pieces[first].inside && !pieces[(first + n - 1) % n].inside)) ++first;
  UvLoop out;
  out.reserve(n + 2);
  bool outside = false;
  for (int k = 0; k < n; ++k) {
    const Piece& p = pieces[(first + k) % n];
    if (!p.inside) {
      outside = true;
      continue;
    }
    if (outside) out.push_back(chord(out.back().end, p.segment.start));
    outside = false;
    out.push_back(p.segment);
  }
  if (outside) out.push_back(chord(out.back().end, out.front().start));
  return out;
}

void check_refinement(const RefinementOptions& o) {
  PARAFAB_VERIFY(o.tolerance >= 0 && o.max_depth >= 0 && o.max_regions >= 1,
                 "RefinementOptions: tolerance " << o.tolerance << " and max_depth " << o.max_depth
                                                 << " must be ≥ 0, max_regions " << o.max_regions << " ≥ 1");
}

}  // namespace

std::vector<UvLoop> clip_loops(const std::vector<UvLoop>& loops, const Vec2& lo, const Vec2& hi) {
  std::vector<UvLoop> out;
  for (UvLoop loop : loops) {
    for (int axis = 0; axis < 2 && !loop.empty(); ++axis) {
      if (std::isfinite(lo[axis])) loop = clip_half_plane(loop, axis, lo[axis], -1);
      if (!loop.empty() && std::isfinite(hi[axis])) loop = clip_half_plane(loop, axis, hi[axis], 1);
    }
    if (!loop.empty()) out.push_back(std::move(loop));
  }
  return out;
}

int area_points_per_direction(const AreaRuleOptions& o) {
  return o.points_per_direction > 0 ? o.points_per_direction : o.degree + 2 - o.degree % 2;
}

AreaRule area_rule(const std::vector<BoundaryLoop>& loops, const AreaRuleOptions& options) {
  return area_rule(to_uv_loops(loops), options);
}

namespace {

void check_area_options(const AreaRuleOptions& o) {
  PARAFAB_VERIFY(o.degree >= 0 && o.points_per_direction >= 0 && o.residual_tolerance >= 0,
                 "AreaRuleOptions: degree " << o.degree << ", points_per_direction "
                                            << o.points_per_direction << ", residual_tolerance "
                                            << o.residual_tolerance);
}

// Moments B(a, b) = ∫ L_a(ξ) L_b(η) over a region mapped from its uv bounding box to the unit
// square, for 0 ≤ a, b ≤ degree; the top-left (p + 1)² block serves every degree p ≤ degree,
// so the degree-p and degree-(p + 1) rules of one refinement step share one pass over the
// loops.
struct RegionMoments {
  bool empty = true;  ///< no loops or a degenerate bounding box
  Vec2 lo{0, 0}, hi{0, 0}, size{0, 0};
  Eigen::MatrixXd B;
};

// Accumulates B += Ix·(DY∘Ly)ᵀ − Lx·(DX∘Iy)ᵀ over chunks of curve points (x, y, ½dx, ½dy).
class MomentAccumulator {
 public:
  static constexpr int kChunk = 128;
  explicit MomentAccumulator(int m) : m_(m), B_(Eigen::MatrixXd::Zero(m, m)) {
    basis_.resize(4 * static_cast<size_t>(m) * kChunk + 3 * kChunk);
  }
  // Room for n more points (flushing when needed); returns the arrays to write them to.
  int reserve(int n) {
    if (count_ + n > kChunk) flush();
    const int at = count_;
    count_ += n;
    return at;
  }
  double* X() { return X_; }
  double* Y() { return Y_; }
  double* DX() { return DX_; }
  double* DY() { return DY_; }
  void flush() {
    if (count_ == 0) return;
    const size_t rows = static_cast<size_t>(m_) * kChunk;
    double* Lx = basis_.data();
    double* Ix = Lx + rows;
    double* Ly = Ix + rows;
    double* Iy = Ly + rows;
    double* work = Iy + rows;
    legendre_basis_rows(X_, count_, kChunk, m_, Lx, Ix, work);
    legendre_basis_rows(Y_, count_, kChunk, m_, Ly, Iy, work);
    for (int b = 0; b < m_; ++b) {
      double* ly = Ly + b * kChunk;
      double* iy = Iy + b * kChunk;
      for (int j = 0; j < count_; ++j) {
        ly[j] *= DY_[j];
        iy[j] *= DX_[j];
      }
    }
    using Row = Eigen::Map<const Eigen::ArrayXd>;
    for (int b = 0; b < m_; ++b) {
      const Row ly(Ly + b * kChunk, count_), iy(Iy + b * kChunk, count_);
      for (int a = 0; a < m_; ++a) {
        const Row ix(Ix + a * kChunk, count_), lx(Lx + a * kChunk, count_);
        B_(a, b) += (ix * ly - lx * iy).sum();
      }
    }
    count_ = 0;
  }
  Eigen::MatrixXd& B() { return B_; }

 private:
  int m_;
  int count_ = 0;
  alignas(16) double X_[kChunk], Y_[kChunk], DX_[kChunk], DY_[kChunk];
  std::vector<double> basis_;
  Eigen::MatrixXd B_;
};

// The factors of a segment's control points at the nodes of an n-point Gauss rule: position
// x(t_j) = Σ_k P[k][j] c_k and half weighted derivative ½ w_j x'(t_j) = Σ_k D[k][j] c_k, with
// (c_0, c_1, c_2) = (start, mid, end) for parabolas and (start, end) for lines.
struct SegmentNodes {
  int n = 0;
  double P[3][kMaxGaussPoints], D[3][kMaxGaussPoints];
  SegmentNodes(int order, int points) : n(points) {
    const QuadratureRule1& g = gauss_legendre(points);
    for (int j = 0; j < n; ++j) {
      const double t = g.points[j], hw = 0.5 * g.weights[j];
      if (order == 1) {
        P[0][j] = 1 - t, P[1][j] = t, P[2][j] = 0;
        D[0][j] = -hw, D[1][j] = hw, D[2][j] = 0;
      } else {
        P[0][j] = (1 - t) * (1 - 2 * t), P[1][j] = 4 * t * (1 - t), P[2][j] = t * (2 * t - 1);
        D[0][j] = hw * (4 * t - 3), D[1][j] = hw * (4 - 8 * t), D[2][j] = hw * (4 * t - 1);
      }
    }
  }
};

RegionMoments region_moments(const std::vector<UvLoop>& loops, int degree) {
  RegionMoments r;
  Vec2 lo(kInf, kInf), hi(-kInf, -kInf);
  for (const UvLoop& loop : loops)
    for (const CurveSegment2& s : loop) extend_bounding_box(s, lo, hi);
  const Vec2 size = hi - lo;
  if (!(size.minCoeff() > 1e-14 * size.maxCoeff())) return r;  // no loops, or a degenerate box
  r.empty = false;
  r.lo = lo;
  r.hi = hi;
  r.size = size;

  // Green's theorem (Eq. 6.12–6.13): B(a, b) = ∮ n·P_ab ds with
  // P_ab = ½(I_a(ξ) L_b(η), L_a(ξ) I_b(η)), integrated exactly by Gauss rules on the segments
  // (the points curve_rule takes for polynomial degree 2 degree + 1).
  const int d = 2 * degree + 1;
  const int n_line = d / 2 + 1, n_parabola = (2 * d + 1) / 2 + 1;
  PARAFAB_VERIFY(n_parabola <= kMaxGaussPoints && n_parabola <= MomentAccumulator::kChunk,
                 "area_rule: degree " << degree << " too high");
  const SegmentNodes line(1, n_line), parabola(2, n_parabola);
  MomentAccumulator acc(degree + 1);
  for (const UvLoop& loop : loops)
    for (const CurveSegment2& s : loop) {
      PARAFAB_VERIFY(s.order == 1 || s.order == 2, "area_rule: segment of order " << s.order);
      const bool straight = s.order == 1;
      const SegmentNodes& g = straight ? line : parabola;
      // Control points in the unit square.
      const Vec2 c0 = (s.start - lo).cwiseQuotient(size);
      const Vec2 c1 = straight ? Vec2((s.end - lo).cwiseQuotient(size))
                               : Vec2((s.mid - lo).cwiseQuotient(size));
      const Vec2 c2 = straight ? Vec2(0, 0) : Vec2((s.end - lo).cwiseQuotient(size));
      const int at = acc.reserve(g.n);
      double *X = acc.X() + at, *Y = acc.Y() + at, *DX = acc.DX() + at, *DY = acc.DY() + at;
      for (int j = 0; j < g.n; ++j) {
        X[j] = g.P[0][j] * c0.x() + g.P[1][j] * c1.x() + g.P[2][j] * c2.x();
        Y[j] = g.P[0][j] * c0.y() + g.P[1][j] * c1.y() + g.P[2][j] * c2.y();
        DX[j] = g.D[0][j] * c0.x() + g.D[1][j] * c1.x() + g.D[2][j] * c2.x();
        DY[j] = g.D[0][j] * c0.y() + g.D[1][j] * c1.y() + g.D[2][j] * c2.y();
      }
    }
  acc.flush();
  r.B = std::move(acc.B());
  return r;
}

AreaRule fit_area_rule(const RegionMoments& moments, const AreaRuleOptions& o) {
  const int p = o.degree;
  const FittingSystem& system = square_fitting_system(p, area_points_per_direction(o));
  AreaRule r;
  if (moments.empty) {
    r.status = RuleStatus::EmptyDomain;
    return r;
  }
  r.box_min = moments.lo;
  r.box_max = moments.hi;
  Eigen::VectorXd b(system.exponents.size());
  for (size_t i = 0; i < system.exponents.size(); ++i)
    b[i] = moments.B(system.exponents[i][0], system.exponents[i][1]);

  if (std::abs(b[0]) <= kEmptyFraction) {
    r.status = RuleStatus::EmptyDomain;
    return r;
  }
  const Vec2& lo = moments.lo;
  const Vec2& size = moments.size;
  const WeightFitResult fit = fit_weights(system, b, o.fit);
  r.measure = b[0] * size.prod();
  r.moment_residual = fit.residual;
  const int n = static_cast<int>(fit.weights.size());
  r.rule.points.reserve(n);
  r.rule.weights.reserve(n);
  for (int j = 0; j < n; ++j) {
    r.rule.points.push_back(lo + size.cwiseProduct(system.points.col(j)));
    r.rule.weights.push_back(fit.weights[j] * size.prod());
  }
  if (b[0] < 0) {
    r.status = RuleStatus::NegativeMeasure;
  } else if (!(fit.residual <= o.residual_tolerance)) {
    r.status = RuleStatus::ResidualAboveTolerance;
  }
  return r;
}

}  // namespace

AreaRule area_rule(const std::vector<UvLoop>& loops, const AreaRuleOptions& o) {
  check_area_options(o);
  square_fitting_system(o.degree, area_points_per_direction(o));  // validates the options
  return fit_area_rule(region_moments(loops, o.degree), o);
}

RefinedAreaRule refined_area_rule(const std::vector<UvLoop>& loops, const AreaRuleOptions& area,
                                  const RefinementOptions& refinement, const UvIntegral& integral) {
  check_refinement(refinement);
  check_area_options(area);
  AreaRuleOptions higher = area;
  ++higher.degree;
  if (area.points_per_direction > 0) ++higher.points_per_direction;

  RefinedAreaRule r;
  r.integral = integral(QuadratureRule2{});
  r.status = RuleStatus::EmptyDomain;
  double tolerance = refinement.tolerance;
  bool root = true, converged = true;
  std::function<void(const std::vector<UvLoop>&, int)> process =
      [&](const std::vector<UvLoop>& region, int depth) {
        ++r.regions;
        const RegionMoments moments = region_moments(region, higher.degree);
        const AreaRule rp = fit_area_rule(moments, area);
        if (rp.status == RuleStatus::EmptyDomain) return;
        const AreaRule rq = fit_area_rule(moments, higher);
        const Eigen::VectorXd ip = integral(rp.rule);
        const Eigen::VectorXd iq = integral(rq.rule);
        if (root && refinement.relative) tolerance *= iq.cwiseAbs().maxCoeff();
        root = false;
        double estimate = (ip - iq).cwiseAbs().maxCoeff();
        const double local = tolerance * std::pow(0.25, depth);
        const AreaRule* leaf = &rp;
        const Eigen::VectorXd* leaf_integral = &iq;
        AreaRule bp, bq;
        Eigen::VectorXd ibq;
        bool boosted = false;
        if (refinement.tolerance > 0 && estimate > local && refinement.degree_boost > 0) {
          // p-refinement first: the same region at degree p + boost and p + boost + 1.
          AreaRuleOptions bo = area, bo1 = higher;
          bo.degree += refinement.degree_boost, bo1.degree += refinement.degree_boost;
          if (area.points_per_direction > 0)
            bo.points_per_direction += refinement.degree_boost, bo1.points_per_direction += refinement.degree_boost;
          const RegionMoments bm = region_moments(region, bo1.degree);
          bp = fit_area_rule(bm, bo);
          bq = fit_area_rule(bm, bo1);
          ibq = integral(bq.rule);
          const double boosted_estimate = (integral(bp.rule) - ibq).cwiseAbs().maxCoeff();
          if (boosted_estimate <= local) {
            estimate = boosted_estimate;
            leaf = &bp;
            leaf_integral = &ibq;
            boosted = true;
          }
        }
        if (!boosted && refinement.tolerance > 0 && estimate > local && depth < refinement.max_depth &&
            r.regions + 4 <= refinement.max_regions) {
          const Vec2 mid = 0.5 * (rp.box_min + rp.box_max);
          for (int qu = 0; qu < 2; ++qu)
            for (int qv = 0; qv < 2; ++qv) {
              const Vec2 lo(qu ? mid.x() : -kInf, qv ? mid.y() : -kInf);
              const Vec2 hi(qu ? kInf : mid.x(), qv ? kInf : mid.y());
              process(clip_loops(region, lo, hi), depth + 1);
            }
          return;
        }
        if (refinement.tolerance > 0 && estimate > local) {
          converged = false;
          ++r.capped_leaves;
        }
        r.rule.points.insert(r.rule.points.end(), leaf->rule.points.begin(), leaf->rule.points.end());
        r.rule.weights.insert(r.rule.weights.end(), leaf->rule.weights.begin(), leaf->rule.weights.end());
        r.integral += *leaf_integral;
        r.error_estimate += estimate;
        r.moment_residual = std::max(r.moment_residual, leaf->moment_residual);
        ++r.leaves;
        r.boosted_leaves += boosted;
        r.depth = std::max(r.depth, depth);
        r.status =
            r.status == RuleStatus::EmptyDomain ? leaf->status : worse_status(r.status, leaf->status);
      };
  process(loops, 0);
  if (!converged && r.status != RuleStatus::EmptyDomain)
    r.status = worse_status(r.status, RuleStatus::NotConverged);
  return r;
}

SurfaceRule surface_rule(const CutPatch& patch, const SurfaceRuleOptions& o) {
  PARAFAB_VERIFY(patch.surface, "CutPatch has no surface");
  PARAFAB_VERIFY(patch.orientation == 1 || patch.orientation == -1,
                 "CutPatch.orientation must be +1 or −1, got " << patch.orientation);
  const SurfaceMap& surface = *patch.surface;
  const UvIntegral area = [&](const QuadratureRule2& q) {
    Eigen::VectorXd a = Eigen::VectorXd::Zero(1);
    Vec3 X, Xu, Xv;
    for (size_t j = 0; j < q.points.size(); ++j) {
      surface.evaluate(q.points[j].x(), q.points[j].y(), X, Xu, Xv);
      a[0] += q.weights[j] * Xu.cross(Xv).norm();
    }
    return a;
  };
  const RefinedAreaRule uv =
      refined_area_rule(to_uv_loops(patch.loops), o.area, o.refinement, area);
  SurfaceRule r;
  r.status = uv.status;
  r.error_estimate = uv.error_estimate;
  r.moment_residual = uv.moment_residual;
  r.leaves = uv.leaves;
  r.uv = uv.rule.points;
  Vec3 X, Xu, Xv;
  for (size_t j = 0; j < uv.rule.points.size(); ++j) {
    surface.evaluate(uv.rule.points[j].x(), uv.rule.points[j].y(), X, Xu, Xv);
    const Vec3 n = Xu.cross(Xv);
    const double factor = n.norm();
    r.points.push_back(X);
    r.weights.push_back(uv.rule.weights[j] * factor);
    r.normals.push_back(factor > 0 ? Vec3(patch.orientation * n / factor) : Vec3::Zero());
    r.area += r.weights.back();
  }
  return r;
}

}  // namespace parafab::xfem
