#include "rods/dead_load.h"

#include <algorithm>
#include <chrono>
#include <cmath>

#include "common/error.h"

namespace parafab {

const char* to_string(DeadLoadStatus status) {
  switch (status) {
    case DeadLoadStatus::Converged: return "converged";
    case DeadLoadStatus::NotConverged: return "not_converged";
    case DeadLoadStatus::LoadInfeasible: return "load_infeasible";
  }
  return "unknown";
}

namespace {
int nearest_sample(const std::vector<RodSample>& samples, double s) {
  auto it = std::lower_bound(samples.begin(), samples.end(), s,
                             [](const RodSample& p, double v) { return p.s < v; });
  int i = int(it - samples.begin());
  if (i >= int(samples.size())) return int(samples.size()) - 1;
  if (i > 0 && s - samples[i - 1].s < samples[i].s - s) --i;
  return i;
}

std::vector<Vec3> weight_of(const RodGeometryResult& g, double density, const Vec3& gravity) {
  std::vector<Vec3> p;
  p.reserve(g.sections.size());
  for (const auto& s : g.sections) p.push_back(density * s.area * gravity);
  return p;
}
}  // namespace

void accumulate_loads(const std::vector<RodSample>& samples, const std::vector<Vec3>& p,
                      const std::vector<PointLoad>& point_loads, std::vector<Vec3>& Q,
                      std::vector<Vec3>& M) {
  const size_t n = samples.size();
  Q.assign(n, Vec3::Zero());
  M.assign(n, Vec3::Zero());
  for (size_t i = 1; i < n; ++i) {
    const double ds = samples[i].s - samples[i - 1].s;
    Q[i] = Q[i - 1] + 0.5 * ds * (p[i - 1] + p[i]);
    M[i] = M[i - 1] + 0.5 * ds * (samples[i - 1].point.cross(p[i - 1]) + samples[i].point.cross(p[i]));
  }
  for (const auto& f : point_loads) {
    const int k = nearest_sample(samples, f.s);
    const Vec3 m = samples[k].point.cross(f.force);
    for (size_t i = k; i < n; ++i) Q[i] += f.force, M[i] += m;
  }
}

DeadLoadResult solve_dead_load(const std::vector<RodSample>& samples, const Vec3& c0,
                               const Vec3& c_bar0, const RodGeometryResult& load_free,
                               const RodMaterial& material, const RodLoads& loads,
                               const DeadLoadOptions& options) {
  const auto t0 = std::chrono::steady_clock::now();
  validate(material);
  PARAFAB_VERIFY(load_free.sections.size() == samples.size(),
                 "dead load: load-free geometry has " << load_free.sections.size()
                                                      << " sections for " << samples.size() << " samples");
  if (!(options.tolerance > 0))
    PARAFAB_INPUT_ERROR("dead load: tolerance must be > 0, got " << options.tolerance);
  if (!(options.max_iterations >= 1))
    PARAFAB_INPUT_ERROR("dead load: max_iterations must be >= 1, got " << options.max_iterations);
  if (!loads.gravity.allFinite())
    PARAFAB_INPUT_ERROR("dead load: gravity must be finite");
  const double L = samples.back().s;
  for (size_t k = 0; k < loads.point_loads.size(); ++k)
    if (!(loads.point_loads[k].s >= 0 && loads.point_loads[k].s <= L) ||
        !loads.point_loads[k].force.allFinite())
      PARAFAB_INPUT_ERROR("dead load: point_loads[" << k << "] at s = " << loads.point_loads[k].s
                                                     << " is outside [0, " << L << "] or not finite");
  const size_t n = samples.size();
  const double rho = loads.dead_load ? material.density : 0.0;
  DeadLoadResult out;
  std::vector<Vec3> external(n, Vec3::Zero());
  if (loads.line_load)
    for (size_t i = 0; i < n; ++i) {
      external[i] = loads.line_load(samples[i].s);
      if (!external[i].allFinite())
        PARAFAB_INPUT_ERROR("loads: line_load(s) is not finite at s = " << samples[i].s);
    }
  auto total = [&](const std::vector<Vec3>& p) {
    std::vector<Vec3> q(n);
    for (size_t i = 0; i < n; ++i) q[i] = p[i] + external[i];
    return q;
  };
  std::vector<Vec3> p = weight_of(load_free, rho, loads.gravity), Q, M;
  accumulate_loads(samples, total(p), loads.point_loads, Q, M);
  out.c = c0, out.c_bar = c_bar0;
  if (options.shift_constants) {
    Vec3 qmin = Q[0], qmax = Q[0], mmin = M[0], mmax = M[0];
    for (size_t i = 1; i < n; ++i) {
      qmin = qmin.cwiseMin(Q[i]), qmax = qmax.cwiseMax(Q[i]);
      mmin = mmin.cwiseMin(M[i]), mmax = mmax.cwiseMax(M[i]);
    }
    out.c = c0 + 0.5 * (qmin + qmax);
    out.c_bar = c_bar0 + 0.5 * (mmin + mmax);
  }
  out.moment.resize(n);
  for (int it = 1; it <= options.max_iterations; ++it) {
    for (size_t i = 0; i < n; ++i)
      out.moment[i] = (out.c - Q[i]).cross(samples[i].point) + out.c_bar - M[i];
    out.geometry = generate_rod_geometry(samples, out.moment, material, options.geometry);
    out.iterations = it;
    if (!out.geometry.ok()) {
      out.status = DeadLoadStatus::LoadInfeasible;
      out.message = "iteration " + std::to_string(it) + ": " + out.geometry.message;
      break;
    }
    std::vector<Vec3> pn = weight_of(out.geometry, rho, loads.gravity);
    double diff = 0;
    for (size_t i = 0; i < n; ++i) diff = std::max(diff, (pn[i] - p[i]).norm());
    out.history.push_back(diff);
    p = std::move(pn);
    if (diff < options.tolerance) {
      out.status = DeadLoadStatus::Converged;
      break;
    }
    if (!std::isfinite(diff)) break;
    accumulate_loads(samples, total(p), loads.point_loads, Q, M);
  }
  out.line_load = p;
  if (out.status == DeadLoadStatus::NotConverged) {
    out.message = "dead-load fixed point did not converge in " + std::to_string(out.iterations) +
                  " iterations; sup|p_{i+1} - p_i| history:";
    for (double d : out.history) out.message += " " + std::to_string(d);
  }
  out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return out;
}

}  // namespace parafab
