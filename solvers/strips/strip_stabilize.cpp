// Thesis §4.5.3 (Algorithm 4.1) and §4.5.4 (Algorithm 4.2, stability recovery).
#include "strips/strip_stabilize.h"

#include <Eigen/Dense>
#include <algorithm>
#include <chrono>
#include <cmath>

#include "common/error.h"
#include "common/plane_curve.h"
#include "strips/curve_fairing.h"
#include "strips/plane_rod_discretization.h"
#include "strips/strip_improve.h"

namespace parafab {

namespace {
using Clock = std::chrono::steady_clock;
double since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }
double unwrap(double angle, double ref) { return angle + 2 * M_PI * std::round((ref - angle) / (2 * M_PI)); }

std::vector<double> arc_length_nodes(const BSplineCurve2& curve, int N) {
  const PlaneCurve pc(curve);
  std::vector<double> u(N + 1);
  for (int k = 0; k <= N; ++k) u[k] = pc.parameter_at(pc.length() * k / N);
  u.front() = curve.first_parameter(), u.back() = curve.last_parameter();
  return u;
}

double max_pole_move(const BSplineCurve2& a, const BSplineCurve2& b) {
  const Eigen::VectorXd d = poles_vector(a) - poles_vector(b);
  double m = 0;
  for (int i = 0; i < a.pole_count(); ++i) m = std::max(m, d.segment<2>(2 * i).norm());
  return m;
}

double min_inflection_dkappa(const BSplineCurve2& c, double l) {
  double m = NAN;
  for (double u : inflection_parameters(c)) {
    const double v = std::abs(pole_jet(c, u).dkappa_ds) * l * l;
    m = std::isnan(m) ? v : std::min(m, v);
  }
  return m;
}

}  // namespace

void project_to_equilibrium(BSplineCurve2& curve, const StripConstraintOptions& options) {
  const std::vector<double> infl = inflection_parameters(curve);
  if (infl.size() < 2) return;
  const Vec2 p = curve.point(infl.front()), q = curve.point(infl.back());
  const Vec2 b = Vec2(-(q - p).y(), (q - p).x()).normalized();
  StripConstraints cons(curve, -b.dot(p), b, infl, options);
  const EnforceResult er = cons.enforce(curve);
  PARAFAB_VERIFY(er.converged, "curve: the inflections cannot be made collinear (EnforceConstraints, App. A.4: "
                                   << er.message << ")");
}

namespace {
StripDesignOptions plain_design() {
  StripDesignOptions d;
  d.tolerance = 1e-3;
  d.max_samples = 4097;
  return d;
}

// The Jacobi verdict of a design at force factors 1 and 1 + margin.
struct Verdict {
  StripDesign design;
  bool stable = false, stable_margin = false;
  double sigma = NAN, sigma_margin = NAN;
};
Verdict verdict(const BSplineCurve2& curve, double margin, int edges) {
  Verdict v;
  const StripDesignOptions o = plain_design();
  v.design = design_strip(curve, o);
  if (!v.design.feasible) return v;
  DiscreteRodState s = rod_state(curve, v.design, o, edges);
  JacobiOptions jo;
  jo.max_samples = 0;
  const JacobiResult j = jacobi_stability(s, jo);
  v.stable = j.stable, v.sigma = j.sigma;
  s.multiplier *= 1 + margin;
  const JacobiResult jm = jacobi_stability(s, jo);
  v.stable_margin = jm.stable, v.sigma_margin = jm.sigma;
  return v;
}
}  // namespace

CurveConjugatePoint curve_conjugate_point(const BSplineCurve2& curve, double a, const Vec2& b,
                                          const std::vector<double>& u, double length, double margin,
                                          bool want_gradient) {
  CurveConjugatePoint out;
  const int N = static_cast<int>(u.size()) - 1;
  PARAFAB_VERIFY(N >= 4, "stabilize: at least 4 edges are needed, got " << N);
  std::vector<PoleJet> J(N + 1);
  DiscreteRodState& s = out.state;
  s.length = length;
  s.stiffness.resize(N + 1);
  for (int k = 0; k <= N; ++k) {
    J[k] = pole_jet(curve, u[k]);
    const double K = (a + b.dot(J[k].d[0])) / J[k].kappa;
    if (!(K > 0) || !std::isfinite(K)) {
      out.message = "K = (a + <b, x>)/kappa is not positive at node " + std::to_string(k);
      return out;
    }
    s.stiffness[k] = K;
  }
  double prev = std::atan2(J[0].tangent.y(), J[0].tangent.x());
  s.start_angle = prev;
  s.angles.resize(N);
  for (int j = 0; j < N; ++j) {
    const Vec2 d = J[j + 1].d[0] - J[j].d[0];
    s.angles[j] = prev = unwrap(std::atan2(d.y(), d.x()), prev);
  }
  s.end_angle = unwrap(std::atan2(J[N].tangent.y(), J[N].tangent.x()), prev);
  s.multiplier = (1 + margin) * Vec2(-b.y(), b.x());
  out.valid = true;
  JacobiOptions jo;
  jo.max_samples = 0;
  const JacobiResult jr = jacobi_stability(s, jo);
  out.stable = jr.stable;
  out.sigma = jr.sigma;
  if (jr.stable || !want_gradient) return out;
  const ConjugatePointSensitivity sens = conjugate_point_sensitivity(s, false, jo);
  if (!sens.defined) {
    out.message = sens.message;
    return out;
  }
  out.gradient.setZero(2 * curve.pole_count());
  for (int k = 0; k <= N; ++k) {  // dK_k/dP = (b N₀ − K ∂κ/∂P)/κ
    const PoleJet& P = J[k];
    const double g = sens.dsigma_dK_partial[k], K = s.stiffness[k];
    for (int j = 0; j < P.count; ++j)
      for (int c = 0; c < 2; ++c)
        out.gradient(2 * (P.basis.first + j) + c) += g * (b(c) * P.basis.N[0][j] - K * P.dkappa[j](c)) / P.kappa;
  }
  for (int e = 0; e < N; ++e) {  // dα_e = ⟨n, dd⟩/|d| of the chord d = x_{e+1} − x_e
    const Vec2 d = J[e + 1].d[0] - J[e].d[0];
    const Vec2 n = Vec2(-d.y(), d.x()) / d.squaredNorm();
    const double g = sens.dsigma_dangles[e];
    for (int side = 0; side < 2; ++side) {
      const PoleJet& P = J[e + side];
      const double sg = side ? 1.0 : -1.0;
      for (int j = 0; j < P.count; ++j)
        for (int c = 0; c < 2; ++c) out.gradient(2 * (P.basis.first + j) + c) += sg * g * n(c) * P.basis.N[0][j];
    }
  }
  return out;
}

StripStabilizeResult stabilize_strip(const BSplineCurve2& input, const StripStabilizeOptions& o) {
  const auto t0 = Clock::now();
  PARAFAB_VERIFY(!input.rational(), "curve.bspline.weights: stabilization moves the poles of a non-rational "
                                    "B-spline; give the curve without weights");
  PARAFAB_VERIFY(o.R_max >= 1, "stabilize.R_max must be >= 1 (or infinite: no bound), got " << o.R_max);
  PARAFAB_VERIFY(o.margin >= 0 && o.margin < 10, "stabilize.margin must lie in [0, 10), got " << o.margin);
  PARAFAB_VERIFY(o.edges >= 16 && o.verify_edges >= 16,
                 "stabilize.edges / verify_edges must be >= 16, got " << o.edges << " / " << o.verify_edges);
  PARAFAB_VERIFY(o.rounds >= 1, "stabilize.rounds must be >= 1, got " << o.rounds);
  // Checked here too (descend_poles checks them), so that an already stable curve does not hide them.
  PARAFAB_VERIFY(o.quasi_halvings >= 0, "stabilize.quasi_halvings must be >= 0, got " << o.quasi_halvings);
  PARAFAB_VERIFY(o.bound_returns >= 0, "stabilize.bound_returns must be >= 0, got " << o.bound_returns);
  StripStabilizeResult res(input);
  BSplineCurve2 curve = input;
  if (curve.degree() < o.min_degree || curve.pole_count() > o.max_poles) {  // degree ≥ 4 (§4.5.4)
    FairFitOptions fo;
    fo.degree = std::max(o.min_degree, std::min(curve.degree(), 5));
    fo.poles = o.fit_poles > 0 ? o.fit_poles : std::min(curve.pole_count() + 2, 20);
    fo.fairness = 1e-7;
    const PlaneCurve pc(input);
    std::vector<Vec2> pts;
    for (int i = 0; i < 400; ++i) pts.push_back(pc.at_arc_length(pc.length() * i / 399).point);
    curve = fit_fair_bspline(pts, fo).curve;
    project_to_equilibrium(curve, o.constraints);
    res.refit = true;
    res.refit_deviation = curve_deviation(input, curve, o.deviation_samples);
    res.original = curve;
  }
  const Verdict v0 = verdict(curve, o.margin, o.verify_edges);
  if (!v0.design.feasible)
    PARAFAB_INPUT_ERROR("curve: not an equilibrium curve, so there is no stiffness to stabilize ("
                        << v0.design.reason_code << ": " << v0.design.reason << ")");
  res.stable_before = v0.stable, res.sigma_before = v0.sigma, res.sigma_margin_before = v0.sigma_margin;
  res.R_before = v0.design.R;
  const double l = v0.design.length;
  res.length = l;
  Verdict v = v0;
  BSplineCurve2 current = curve;
  if (v0.stable_margin) {
    res.status = "already";
    res.message = "already stable with the margin: the curve is unchanged";
  } else {
    int used = 0;
    for (int round = 0; round < o.rounds; ++round) {
      const std::vector<double> node_u = arc_length_nodes(current, o.edges);
      const PoleObjective F = [&](const BSplineCurve2& c, const StripConstraints& cons, Eigen::VectorXd* grad) {
        const CurveConjugatePoint cp = curve_conjugate_point(c, cons.a(), cons.b(), node_u, l, o.margin, grad != nullptr);
        if (!cp.valid) return static_cast<double>(NAN);
        if (cp.stable) {  // below every unstable value: any step reaching stability is accepted
          if (grad) grad->setZero(2 * c.pole_count());
          return -2.0;
        }
        if (grad) {
          if (cp.gradient.size() == 0) return static_cast<double>(NAN);
          *grad = -cp.gradient / l;
        }
        return -cp.sigma / l;
      };
      PoleDescentOptions po;
      po.max_iterations = std::max(0, o.max_iterations - used);
      po.initial_step = o.initial_step;
      po.max_step = o.max_step;
      po.memory = o.memory;
      po.quasi_halvings = o.quasi_halvings;
      po.R_max = o.R_max;
      po.bound_tolerance = o.bound_tolerance;
      po.bound_returns = o.bound_returns;
      po.p = o.p;
      po.samples = o.samples;
      po.constraints = o.constraints;
      if (o.max_seconds > 0) po.max_seconds = std::max(1e-3, o.max_seconds - since(t0));
      const double offset = since(t0);
      po.on_accept = [&](BSplineCurve2& c, StripConstraints& cons, PoleDescentIteration& rec) {
        if (round > 0 && rec.iteration == 0) return rec.F < -1.5;
        StripStabilizeIteration h;
        h.iteration = static_cast<int>(res.history.size());
        const CurveConjugatePoint plain = curve_conjugate_point(c, cons.a(), cons.b(), node_u, l, 0.0, false);
        h.sigma = plain.valid && !plain.stable ? plain.sigma : NAN;
        h.sigma_margin = rec.F < -1.5 ? NAN : -rec.F * l;
        h.R = rec.R, h.R_p = rec.R_p, h.step = rec.step;
        h.max_pole_move = max_pole_move(c, curve);
        h.min_inflection_dkappa = rec.min_inflection_dkappa;
        h.seconds = offset + rec.seconds;
        res.history.push_back(h);
        return rec.F < -1.5;
      };
      const PoleDescentResult dr = descend_poles(current, F, po);
      used += static_cast<int>(dr.history.size()) - 1;
      res.rejected_steps += dr.rejected_steps;
      res.bound_returns += dr.bound_returns;
      current = dr.curve;
      res.status = dr.status;
      res.message = dr.message.empty() ? dr.last_rejection : dr.message;
      if (dr.status != "target") break;
      v = verdict(current, o.margin, o.verify_edges);
      if (!v.design.feasible || v.stable_margin) break;
      // The loop's discretization (fixed nodes) says stable, the finer test not yet: restart.
      res.status = "max_iterations";
      res.message = "stable on the loop's nodes, not on the final test";
    }
    if (res.status == "target") {
      res.status = "stable";
      res.message = "stable: no conjugate point in (0, l] with the force scaled by 1 + margin";
    }
    v = verdict(current, o.margin, o.verify_edges);
  }
  res.curve = current;
  res.design = v.design;
  res.stable_after = v.stable, res.sigma_after = v.sigma;
  res.stable_margin_after = v.stable_margin, res.sigma_margin_after = v.sigma_margin;
  res.R_after = v.design.feasible ? v.design.R : NAN;
  res.done = v.design.feasible && v.stable_margin;
  if (res.status == "stable" && !res.done) res.status = "max_iterations";
  if (res.status == "stationary" && !res.done)
    res.message = "sigma cannot be pushed further with R_p <= R_max (a KKT point on the bound, sigma/l of the "
                  "margin state " + std::to_string(res.history.empty() ? NAN : res.history.back().sigma_margin / l) +
                  "): raise R_max or start from a curve closer to stability";
  res.max_pole_move = max_pole_move(current, curve);
  res.deviation = curve_deviation(input, current, o.deviation_samples);
  res.deviation_relative = res.deviation / l;
  res.inflections = static_cast<int>(inflection_parameters(current).size());
  res.min_inflection_dkappa = min_inflection_dkappa(current, l);
  res.seconds = since(t0);
  return res;
}

PlaneRodProblem strip_rod_problem(const BSplineCurve2& bspline, const StripDesign& d, const StripDesignOptions& o,
                                  int N, std::vector<Vec2>* target) {
  const PlaneCurve curve(bspline);
  const double l = curve.length();
  PlaneRodProblem p;
  p.length = l;
  for (const auto& s : d.samples) p.stiffness_s.push_back(s.s), p.stiffness.push_back(s.K);
  const CurvePoint a = curve.at_arc_length(0), b = curve.at_arc_length(l);
  p.start_point = a.point;
  p.end_point = b.point;
  p.boundary = o.boundary;
  p.load = o.gravity.load();
  p.law = o.law;
  p.natural_curvature = o.natural_curvature;
  target->resize(N + 1);
  for (int k = 0; k <= N; ++k) (*target)[k] = curve.at_arc_length(l * k / N).point;
  double prev = std::atan2(a.tangent.y(), a.tangent.x());
  p.start_angle = prev;
  p.initial_angles.resize(N);
  for (int j = 0; j < N; ++j) {
    const Vec2 dd = (*target)[j + 1] - (*target)[j];
    p.initial_angles[j] = prev = unwrap(std::atan2(dd.y(), dd.x()), prev);
  }
  p.end_angle = unwrap(std::atan2(b.tangent.y(), b.tangent.x()), prev);
  return p;
}

StiffnessAscentResult stabilize_by_stiffness(const BSplineCurve2& curve, const StiffnessAscentOptions& o) {
  const auto t0 = Clock::now();
  PARAFAB_VERIFY(o.edges >= 16, "stiffness ascent: edges must be >= 16, got " << o.edges);
  PARAFAB_VERIFY(o.step > 0 && o.step < 1, "stiffness ascent: step must lie in (0, 1), got " << o.step);
  StiffnessAscentResult res;
  const StripDesignOptions so = plain_design();
  const StripDesign d = design_strip(curve, so);
  if (!d.feasible) PARAFAB_INPUT_ERROR("curve: not an equilibrium curve (" << d.reason_code << ": " << d.reason << ")");
  const int N = o.edges;
  std::vector<Vec2> target;
  PlaneRodProblem p = strip_rod_problem(curve, d, so, N, &target);
  const double l = p.length;
  // K on the nodes: the variable of Algorithm 4.1.
  std::vector<double> K(N + 1), ks;
  for (int k = 0; k <= N; ++k) K[k] = plane_rod::interpolate(p.stiffness_s, p.stiffness, l * k / N), ks.push_back(l * k / N);
  p.stiffness_s = ks;
  p.stiffness = K;
  PlaneRodOptions po{N};
  po.tolerance = 1e-12;
  PlaneRodResult r = simulate_plane_rod(p, po);
  if (!r.converged) {
    res.status = "simulation_failed";
    res.message = "the designed stiffness does not simulate: " + r.message;
    res.seconds = since(t0);
    return res;
  }
  auto deviation = [&](const PlaneRodResult& x) {
    double m = 0;
    for (int k = 0; k <= N; ++k) m = std::max(m, (x.nodes[k] - target[k]).norm());
    return m / l;
  };
  for (int it = 0;; ++it) {
    const DiscreteRodState s = rod_state(p, r);
    const JacobiResult jr = jacobi_stability(s);
    StiffnessAscentIteration h;
    h.iteration = it;
    h.sigma = jr.sigma;
    h.deviation = deviation(r);
    if (it == 0) res.sigma_before = jr.sigma;
    res.sigma = jr.sigma, res.stable = jr.stable, res.deviation = h.deviation;
    res.stiffness = p.stiffness, res.nodes = r.nodes;
    if (jr.stable) {
      res.history.push_back(h);
      res.status = h.deviation <= o.lost_shape ? "stable" : "lost_shape";
      break;
    }
    if (h.deviation > o.lost_shape) {
      res.history.push_back(h);
      res.status = "lost_shape";
      break;
    }
    if (it >= o.max_iterations) {
      res.history.push_back(h);
      res.status = "max_iterations";
      break;
    }
    const ConjugatePointSensitivity sens = conjugate_point_sensitivity(s, true);
    double gmax = 0, kmean = 0;
    for (int k = 0; k <= N; ++k) gmax = std::max(gmax, std::abs(sens.dsigma_dK[k])), kmean += p.stiffness[k] / (N + 1);
    h.gradient_norm = gmax;
    res.history.push_back(h);
    if (!(gmax > 0) || !std::isfinite(gmax)) {
      res.status = "simulation_failed";
      res.message = "δσ/δK is not finite (singular equilibrium)";
      break;
    }
    for (int k = 0; k <= N; ++k)
      p.stiffness[k] = std::max(1e-3 * kmean, p.stiffness[k] + o.step * kmean * sens.dsigma_dK[k] / gmax);
    p.initial_angles = r.edge_angles;
    const PlaneRodResult rn = simulate_plane_rod(p, po);
    if (!rn.converged) {
      res.status = "simulation_failed";
      res.message = "iteration " + std::to_string(it + 1) + ": the simulation from the previous equilibrium failed (" +
                    rn.message + ")";
      res.history.back().converged = false;
      break;
    }
    r = rn;
  }
  res.seconds = since(t0);
  return res;
}

}  // namespace parafab
