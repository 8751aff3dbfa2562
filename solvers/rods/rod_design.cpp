#include "rods/rod_design.h"

#include <algorithm>
#include <chrono>
#include <cmath>

#include "common/error.h"

namespace parafab {

const char* to_string(RodDesignStatus status) {
  switch (status) {
    case RodDesignStatus::Ok: return "ok";
    case RodDesignStatus::Infeasible: return "infeasible";
    case RodDesignStatus::LoadInfeasible: return "load_infeasible";
    case RodDesignStatus::NotConverged: return "not_converged";
    case RodDesignStatus::SolverFailed: return "solver_failed";
  }
  return "unknown";
}

RodDesign design_rod(const std::vector<RodSample>& samples, const RodDesignOptions& options) {
  const auto t0 = std::chrono::steady_clock::now();
  validate(options.material);
  if (!(options.max_radius > 0) || !std::isfinite(options.max_radius))
    PARAFAB_INPUT_ERROR("rod design: max_radius must be > 0, got " << options.max_radius);
  RodDesign d;
  d.samples = samples;
  d.lp = solve_line_complex_lp(samples, options.lp);
  d.lp_seconds = d.lp.seconds;
  if (!d.lp.ok()) {
    d.status = d.lp.status == LineComplexStatus::Infeasible ? RodDesignStatus::Infeasible
                                                            : RodDesignStatus::SolverFailed;
    d.message = d.lp.message;
    d.total_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    return d;
  }
  const auto tg = std::chrono::steady_clock::now();
  // Unit-scale geometry, then λ from the largest √(ab) ∝ λ^{1/4}.
  std::vector<Vec3> h = complex_field(samples, d.lp.c, d.lp.c_bar);
  RodGeometryResult g = generate_rod_geometry(samples, h, options.material, options.geometry);
  if (!g.ok()) {
    d.status = RodDesignStatus::SolverFailed;
    d.message = g.message;
    return d;
  }
  double rmax = 0;
  for (const auto& s : g.sections) rmax = std::max(rmax, std::sqrt(s.ellipse.a * s.ellipse.b));
  d.scale = std::pow(options.max_radius / rmax, 4);
  d.c = d.scale * d.lp.c;
  d.c_bar = d.scale * d.lp.c_bar;
  for (auto& v : h) v *= d.scale;
  g = generate_rod_geometry(samples, h, options.material, options.geometry);
  d.geometry_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - tg).count();
  d.moment = h;
  d.sections = g.sections;
  d.line_load.assign(samples.size(), Vec3::Zero());
  for (size_t i = 0; i < samples.size(); ++i)
    d.line_load[i] = options.material.density * d.sections[i].area * options.loads.gravity;
  d.status = RodDesignStatus::Ok;
  if (options.loads.any()) {
    DeadLoadOptions dlo = options.dead_load;
    dlo.geometry = options.geometry;
    DeadLoadResult r = solve_dead_load(samples, d.c, d.c_bar, g, options.material, options.loads, dlo);
    d.dead_load_seconds = r.seconds;
    d.fixed_point_history = r.history;
    d.fixed_point_iterations = r.iterations;
    d.c = r.c, d.c_bar = r.c_bar;
    if (r.geometry.sections.size() == samples.size()) {
      d.sections = r.geometry.sections;
      d.moment = r.moment;
      d.line_load = r.line_load;
    }
    if (r.status == DeadLoadStatus::LoadInfeasible) d.status = RodDesignStatus::LoadInfeasible;
    if (r.status == DeadLoadStatus::NotConverged) d.status = RodDesignStatus::NotConverged;
    d.message = r.message;
  }
  d.total_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return d;
}

RodDesign design_rod(const SpaceCurve& curve, int count, const RodDesignOptions& options) {
  std::vector<RodSample> samples = sample_by_arc_length(curve, count);
  require_frenet_curve(curve, samples);
  return design_rod(samples, options);
}

namespace {
// Linear interpolation of section data at arc length s.
struct SectionAt {
  Eigen::Matrix2d I;
  double J, area, angle;
};
SectionAt section_at(const RodDesign& d, double s) {
  const auto& secs = d.sections;
  auto it = std::lower_bound(secs.begin(), secs.end(), s,
                             [](const RodSection& a, double v) { return a.s < v; });
  size_t i = std::clamp<size_t>(size_t(it - secs.begin()), 1, secs.size() - 1);
  const RodSection &a = secs[i - 1], &b = secs[i];
  const double w = std::clamp((s - a.s) / (b.s - a.s), 0.0, 1.0);
  return {(1 - w) * a.I_material + w * b.I_material, (1 - w) * a.J + w * b.J,
          (1 - w) * a.area + w * b.area, (1 - w) * a.frame_angle + w * b.frame_angle};
}
}  // namespace

DiscreteRodModel discrete_rod_model(const RodDesign& design, const SpaceCurve& curve, int edges,
                                    const RodMaterial& material, const RodLoads& loads,
                                    bool with_loads) {
  PARAFAB_VERIFY(edges >= 3, "discrete rod model: edges must be >= 3, got " << edges);
  PARAFAB_VERIFY(design.sections.size() >= 2, "discrete rod model: design has no sections");
  validate(material);
  const double L = curve.length(), E = material.youngs_modulus, mu = material.shear_modulus();
  DiscreteRodModel m;
  for (int k = 0; k <= edges; ++k) m.nodes.push_back(curve.at_arc_length(L * k / edges).point);
  for (int j = 0; j < edges; ++j) {
    const double sm = L * (j + 0.5) / edges;
    const RodSample p = curve.at_arc_length(sm);
    const SectionAt sec = section_at(design, sm);
    m.material_normal.push_back(std::cos(sec.angle) * p.normal + std::sin(sec.angle) * p.binormal);
    m.bending_stiffness.push_back(E * sec.I);
    m.twisting_stiffness.push_back(mu * sec.J);
    m.stretching_stiffness.push_back(E * sec.area);
    m.rest_length.push_back((m.nodes[j + 1] - m.nodes[j]).norm());
    m.line_density.push_back(material.density * sec.area);
  }
  if (with_loads) {
    if (loads.dead_load) m.gravity = loads.gravity;
    for (const auto& f : loads.point_loads)
      m.nodal_forces.emplace_back(int(std::lround(f.s / L * edges)), f.force);
    if (loads.line_load)
      for (int j = 0; j < edges; ++j) {
        const Vec3 f = loads.line_load(L * (j + 0.5) / edges) * m.rest_length[j];
        m.nodal_forces.emplace_back(j, 0.5 * f);
        m.nodal_forces.emplace_back(j + 1, 0.5 * f);
      }
  }
  return m;
}

}  // namespace parafab
