#include "strip_json.h"

#include <algorithm>
#include <chrono>
#include <cmath>

#include "common/error.h"
#include "request_schema.h"
#include "strips/composite_strip.h"
#include "strips/perforated_strip.h"
#include "strips/strip_design.h"
#include "strips/strip_robustness.h"
#include "strips/strip_validation.h"

#include "json_fields.h"
#include "json_write.h"
#include "stability_json.h"

namespace parafab::entry {

using nlohmann::json;

namespace {

using fields::number;
using fields::require;

double optional_number(const json& obj, const char* key, const std::string& path, double fallback) {
  auto it = obj.find(key);
  return it == obj.end() ? fallback : number(*it, path + "." + key);
}

// Non-finite values (NaN) cannot be written in JSON; clients send null or strings for them.
double coordinate(const json& v, const std::string& path) {
  if (v.is_null() || v.is_string())
    PARAFAB_INPUT_ERROR(path << " is not a finite number (got " << v.dump() << ")");
  return number(v, path);
}

// A finite number at element i of `path`; the element's path is spelled out only for the error
// (building it for every element of a 400-point curve cost more than interpolating it).
double coordinate_at(const json& v, const std::string& path, size_t i, const char* suffix = "") {
  if (v.is_number()) {
    const double x = v.get<double>();
    if (std::isfinite(x)) return x;
  }
  return coordinate(v, path + "[" + std::to_string(i) + "]" + suffix);
}

std::vector<Vec2> points2(const json& v, const std::string& path) {
  if (!v.is_array()) PARAFAB_INPUT_ERROR(path << " must be an array of [x, y] pairs");
  std::vector<Vec2> out;
  out.reserve(v.size());
  for (size_t i = 0; i < v.size(); ++i) {
    const json& p = v[i];
    if (!p.is_array() || p.size() != 2)
      PARAFAB_INPUT_ERROR(path << "[" << i << "] must be a pair [x, y] (a plane curve), got " << p.dump());
    out.emplace_back(coordinate_at(p[0], path, i, "[0]"), coordinate_at(p[1], path, i, "[1]"));
  }
  return out;
}

std::vector<double> numbers(const json& v, const std::string& path) {
  if (!v.is_array()) PARAFAB_INPUT_ERROR(path << " must be an array of numbers");
  std::vector<double> out;
  out.reserve(v.size());
  for (size_t i = 0; i < v.size(); ++i) out.push_back(coordinate_at(v[i], path, i));
  return out;
}

bool boolean(const json& v, const std::string& path) {
  if (!v.is_boolean()) PARAFAB_INPUT_ERROR(path << " must be true or false, got " << v.dump());
  return v.get<bool>();
}

// Objects of the extensions reject unknown keys, so a typo is an error, not a silent default.
void only_keys(const json& obj, const std::string& path, std::initializer_list<const char*> keys) {
  if (!obj.is_object()) PARAFAB_INPUT_ERROR(path << " must be a JSON object, got " << obj.dump());
  for (auto it = obj.begin(); it != obj.end(); ++it) {
    bool known = false;
    for (const char* k : keys) known |= it.key() == k;
    if (!known) {
      std::string list;
      for (const char* k : keys) list += std::string(list.empty() ? "" : ", ") + k;
      PARAFAB_INPUT_ERROR(path << "." << it.key() << " is not a known field (expected " << list << ")");
    }
  }
}

double positive(const json& v, const std::string& path) {
  const double x = number(v, path);
  if (!(x > 0)) PARAFAB_INPUT_ERROR(path << " must be positive, got " << x);
  return x;
}

Vec2 direction2(const json& v, const std::string& path) {
  if (!v.is_array() || v.size() != 2 || !v[0].is_number() || !v[1].is_number())
    PARAFAB_INPUT_ERROR(path << " must be [x, y], got " << v.dump());
  const Vec2 d(number(v[0], path + "[0]"), number(v[1], path + "[1]"));
  if (!(d.norm() > 0)) PARAFAB_INPUT_ERROR(path << " must be a non-zero vector, got " << v.dump());
  return d;
}

// "gravity": {"direction": [gx, gy], "beta_l3": m³} or {"direction", "density"[, "g"]}
// (E and thickness from the material); false or null: no gravity.
StripGravity parse_gravity(const json& v, const std::string& path, double E, double h) {
  StripGravity g;
  if (v.is_null() || (v.is_boolean() && !v.get<bool>())) return g;
  only_keys(v, path, {"direction", "beta_l3", "density", "g"});
  if (v.contains("direction")) g.direction = direction2(v["direction"], path + ".direction");
  const bool beta = v.contains("beta_l3"), rho = v.contains("density");
  if (beta == rho)
    PARAFAB_INPUT_ERROR(path << " needs exactly one of \"beta_l3\" (m³) or \"density\" (kg/m³, "
                             "or material.density), got " << v.dump());
  if (beta) {
    if (v.contains("g")) PARAFAB_INPUT_ERROR(path << ".g is only used with density, not with beta_l3");
    g.gravito_bending = positive(v["beta_l3"], path + ".beta_l3");
    g.enabled = true;
    return g;
  }
  const double density = positive(v["density"], path + ".density");
  const double acc = v.contains("g") ? positive(v["g"], path + ".g") : 9.81;
  return StripGravity::from_material(E, h, density, acc, g.direction);
}

StripBoundary parse_boundary(const json& v) {
  StripBoundary b;
  only_keys(v, "boundary", {"start", "end"});
  for (const char* which : {"start", "end"}) {
    if (!v.contains(which)) continue;
    const std::string p = std::string("boundary.") + which;
    const json& e = v[which];
    only_keys(e, p, {"free_x", "free_y", "free_angle"});
    StripEnd& end = std::string(which) == "start" ? b.start : b.end;
    if (e.contains("free_x")) end.free_x = boolean(e["free_x"], p + ".free_x");
    if (e.contains("free_y")) end.free_y = boolean(e["free_y"], p + ".free_y");
    if (e.contains("free_angle")) end.free_angle = boolean(e["free_angle"], p + ".free_angle");
  }
  return b;
}

MomentLaw parse_law(const json& v) {
  MomentLaw law;
  const std::string p = "material.law";
  only_keys(v, p, {"cubic", "table_curvature", "table_moment", "curvature_limit", "hardening"});
  if (v.contains("cubic")) law.cubic = number(v["cubic"], p + ".cubic");
  if (v.contains("table_curvature") != v.contains("table_moment"))
    PARAFAB_INPUT_ERROR(p << " needs both table_curvature and table_moment (a table of (|κ|, m) pairs)");
  if (v.contains("table_curvature")) {
    law.table_curvature = numbers(v["table_curvature"], p + ".table_curvature");
    law.table_moment = numbers(v["table_moment"], p + ".table_moment");
  }
  if (v.contains("curvature_limit")) law.curvature_limit = positive(v["curvature_limit"], p + ".curvature_limit");
  if (v.contains("hardening")) {
    if (!v.contains("curvature_limit"))
      PARAFAB_INPUT_ERROR(p << ".hardening needs " << p << ".curvature_limit (the plastic slope applies beyond it)");
    law.plastic_hardening = number(v["hardening"], p + ".hardening");
    if (law.plastic_hardening < 0) PARAFAB_INPUT_ERROR(p << ".hardening must be >= 0, got " << law.plastic_hardening);
  }
  law.validate();
  return law;
}

// gravity, with material.density filling in when the object gives only the direction.
StripGravity gravity_field(json g, const std::string& path, const json& material, double E, double h) {
  if (g.is_object() && !g.contains("density") && !g.contains("beta_l3") && material.contains("density"))
    g["density"] = material["density"];
  return parse_gravity(g, path, E, h);
}

json num_or_null(double x) { return std::isfinite(x) ? json(x) : json(nullptr); }

BSplineCurve2 parse_curve(const json& request) {
  const json& curve = require(request, "curve", "request");
  if (curve.contains("bspline")) {
    const json& bs = curve["bspline"];
    const json& deg = require(bs, "degree", "curve.bspline");
    if (!deg.is_number_integer()) PARAFAB_INPUT_ERROR("curve.bspline.degree must be an integer");
    return BSplineCurve2(deg.get<int>(), numbers(require(bs, "knots", "curve.bspline"), "curve.bspline.knots"),
                         points2(require(bs, "poles", "curve.bspline"), "curve.bspline.poles"),
                         bs.contains("weights") ? numbers(bs["weights"], "curve.bspline.weights")
                                                : std::vector<double>{});
  }
  if (curve.contains("points")) {
    int degree = 4;  // quartic: K stays continuous through inflections (§4.3.3)
    if (curve.contains("degree")) {
      if (!curve["degree"].is_number_integer())
        PARAFAB_INPUT_ERROR("curve.degree must be an integer");
      degree = curve["degree"].get<int>();
      if (degree < 1 || degree > 7) PARAFAB_INPUT_ERROR("curve.degree must be 1..7, got " << degree);
    }
    return interpolate_points(points2(curve["points"], "curve.points"), degree);
  }
  PARAFAB_INPUT_ERROR("curve must hold either \"bspline\" {degree, knots, poles[, weights]} or "
                      "\"points\" [[x, y], ...]");
}

json to_json(const Vec2& v) { return json_write::coordinates(v); }

}  // namespace

json error_json(const std::string& message, const std::string& kind) {
  return json{{"error", {{"message", message}, {"kind", kind}}}};
}

json design_strip_json(const json& request) { return json_write::expand(design_strip_columns(request)); }

json_write::ColumnarResult design_strip_columns(const json& request) {
  const auto t_entry = std::chrono::steady_clock::now();
  auto since = [](std::chrono::steady_clock::time_point t) {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - t).count();
  };
  schema::check(request, schema::Format::Strip);
  StripDesignOptions o;
  const json& material = require(request, "material", "request");
  o.youngs_modulus = number(require(material, "E", "material"), "material.E");
  o.thickness = number(require(material, "thickness", "material"), "material.thickness");
  o.min_width = number(require(request, "min_width", "request"), "min_width");
  // ---- issue 5 extensions (all optional; absent = the plain Eq. 4.4 design)
  if (material.contains("density")) positive(material["density"], "material.density");
  if (material.contains("law")) o.law = parse_law(material["law"]);
  if (material.contains("yield_strain") && material.contains("yield_stress"))
    PARAFAB_INPUT_ERROR("material: give yield_strain or yield_stress (Pa), not both");
  if (material.contains("yield_strain")) o.yield_strain = positive(material["yield_strain"], "material.yield_strain");
  if (material.contains("yield_stress"))
    o.yield_strain = positive(material["yield_stress"], "material.yield_stress") / o.youngs_modulus;
  if (material.contains("name")) {
    if (!material["name"].is_string()) PARAFAB_INPUT_ERROR("material.name must be a string, got " << material["name"].dump());
    o.material_name = material["name"].get<std::string>();
  }
  if (request.contains("gravity"))
    o.gravity = gravity_field(request["gravity"], "gravity", material, o.youngs_modulus, o.thickness);
  if (request.contains("boundary")) o.boundary = parse_boundary(request["boundary"]);
  if (request.contains("natural_curvature"))
    o.natural_curvature = number(request["natural_curvature"], "natural_curvature");
  if (request.contains("smooth")) o.smooth = boolean(request["smooth"], "smooth");
  if (request.contains("samples")) {
    const json& n = request["samples"];
    if (!n.is_number_integer() || n.get<long long>() < 4 || n.get<long long>() > (1 << 20))
      PARAFAB_INPUT_ERROR("samples must be an integer 4..1048576 (a fixed sample count), got " << n.dump());
    o.fixed_samples = n.get<int>();
  }
  bool validate = false;
  StripValidationOptions vo;
  bool sim_gravity = false;  // simulate under another gravity than the design's
  StripGravity sim_g;
  if (request.contains("validate")) {
    const json& v = request["validate"];
    if (v.is_boolean()) {
      validate = v.get<bool>();
    } else if (v.is_object()) {
      only_keys(v, "validate", {"edges", "gravity"});
      validate = true;
      if (v.contains("edges")) {
        if (!v["edges"].is_number_integer() || v["edges"].get<long long>() < 4 || v["edges"].get<long long>() > 100000)
          PARAFAB_INPUT_ERROR("validate.edges must be an integer 4..100000, got " << v["edges"].dump());
        vo.rod.edges = v["edges"].get<int>();
      }
      if (v.contains("gravity")) {
        sim_g = gravity_field(v["gravity"], "validate.gravity", material, o.youngs_modulus, o.thickness);
        sim_gravity = true;
      }
    } else {
      PARAFAB_INPUT_ERROR("validate must be true, false or {\"edges\": n, \"gravity\": {...}}, got " << v.dump());
    }
  }
  bool robustness = false;
  StripRobustnessOptions ro;
  if (request.contains("robustness")) {
    const json& v = request["robustness"];
    if (v.is_boolean()) {
      robustness = v.get<bool>();
    } else if (v.is_object()) {
      const std::string p = "robustness";
      only_keys(v, p, {"stiffness_change", "gravity_change", "angle_deg", "plastic_fractions",
                       "plastic_hardening", "edges"});
      robustness = true;
      auto fraction = [&](const char* key, double& x) {
        if (!v.contains(key)) return;
        x = number(v[key], p + "." + key);
        if (!(x > 0 && x < 1)) PARAFAB_INPUT_ERROR(p << "." << key << " must lie in (0, 1), got " << x);
      };
      fraction("stiffness_change", ro.stiffness_change);
      fraction("gravity_change", ro.gravity_change);
      if (v.contains("angle_deg")) {
        const double a = number(v["angle_deg"], p + ".angle_deg");
        if (!(a > 0 && a < 90)) PARAFAB_INPUT_ERROR(p << ".angle_deg must lie in (0, 90), got " << a);
        ro.angle_change = a * M_PI / 180;
      }
      if (v.contains("plastic_fractions")) {
        ro.plastic_fractions = numbers(v["plastic_fractions"], p + ".plastic_fractions");
        for (size_t i = 0; i < ro.plastic_fractions.size(); ++i)
          if (!(ro.plastic_fractions[i] > 0 && ro.plastic_fractions[i] < 1))
            PARAFAB_INPUT_ERROR(p << ".plastic_fractions[" << i << "] must lie in (0, 1), got "
                                  << ro.plastic_fractions[i]);
      }
      if (v.contains("plastic_hardening"))
        ro.plastic_hardening = positive(v["plastic_hardening"], p + ".plastic_hardening");
      if (v.contains("edges")) {
        if (!v["edges"].is_number_integer() || v["edges"].get<long long>() < 4 || v["edges"].get<long long>() > 100000)
          PARAFAB_INPUT_ERROR(p << ".edges must be an integer 4..100000, got " << v["edges"].dump());
        ro.validation.rod.edges = v["edges"].get<int>();
      }
    } else {
      PARAFAB_INPUT_ERROR("robustness must be true, false or {\"stiffness_change\", \"gravity_change\", "
                          "\"angle_deg\", \"plastic_fractions\", \"plastic_hardening\", \"edges\"}, got "
                          << v.dump());
    }
  }
  CompositeStripOptions co;
  double composite_w1 = 0;
  if (request.contains("composite")) {
    const json& c = request["composite"];
    only_keys(c, "composite", {"h1", "h2", "outer_width", "inner_density_ratio"});
    co.outer_thickness = positive(require(c, "h1", "composite"), "composite.h1");
    co.inner_thickness = positive(require(c, "h2", "composite"), "composite.h2");
    composite_w1 = positive(require(c, "outer_width", "composite"), "composite.outer_width");
    o.composite.enabled = true;  // under gravity: the weight of both layers
    o.composite.outer_thickness = co.outer_thickness;
    o.composite.inner_thickness = co.inner_thickness;
    o.composite.outer_width = composite_w1;
    if (c.contains("inner_density_ratio"))
      o.composite.inner_density_ratio = positive(c["inner_density_ratio"], "composite.inner_density_ratio");
    // The glued laminate's outer fibre: the stiffness cK = h₁³w₁ + ((h₁+h₂)³ − h₁³)w₂ (§4.7.1,
    // composite_strip.h) bends the full h₁ + h₂ about its mid-plane, so ε = (h₁ + h₂)·|κ|/2
    // (before: the thicker layer alone, max(h₁, h₂), half the strain for equal layers).
    o.strain_thickness = co.outer_thickness + co.inner_thickness;
  }
  PerforatedStripOptions po;
  double perforated_w = 0;
  if (request.contains("perforated")) {
    const json& c = request["perforated"];
    only_keys(c, "perforated", {"outer_width", "min_ligament", "columns", "cell_aspect"});
    perforated_w = positive(require(c, "outer_width", "perforated"), "perforated.outer_width");
    if (c.contains("min_ligament")) po.min_ligament = positive(c["min_ligament"], "perforated.min_ligament");
    if (c.contains("cell_aspect")) po.cell_aspect = positive(c["cell_aspect"], "perforated.cell_aspect");
    if (c.contains("columns")) {
      const json& m = c["columns"];
      if (!m.is_number_integer() || (m.get<long long>() != 0 && m.get<long long>() < 2) || m.get<long long>() > 1000)
        PARAFAB_INPUT_ERROR("perforated.columns must be 0 (automatic) or an integer 2..1000, got " << m.dump());
      po.columns = m.get<int>();
    }
  }
  if (request.contains("composite") && request.contains("perforated"))
    PARAFAB_INPUT_ERROR("composite and perforated are exclusive: a strip is one or the other");
  if (request.contains("name") && !request["name"].is_string())
    PARAFAB_INPUT_ERROR("name must be a string, got " << request["name"].dump());
  o.tolerance = optional_number(request, "tolerance", "request", o.tolerance);
  if (request.contains("max_samples"))
    o.max_samples = static_cast<int>(number(request["max_samples"], "max_samples"));
  if (request.contains("lp_form")) {
    const std::string f = request["lp_form"].is_string() ? request["lp_form"].get<std::string>() : "";
    if (f != "dense" && f != "dual" && f != "primal")
      PARAFAB_INPUT_ERROR("lp_form must be \"dense\", \"dual\" or \"primal\", got " << request["lp_form"].dump());
    o.lp_form = f == "dense" ? LpForm::Dense : f == "dual" ? LpForm::Dual : LpForm::Primal;
  }
  StripStabilityOptions stability_options;  // thesis §4.5: on by default (the Jacobi test)
  const bool stability = parse_stability_options(request, stability_options);
  const auto t_curve = std::chrono::steady_clock::now();
  const BSplineCurve2 curve = parse_curve(request);
  const double interpolation_seconds = since(t_curve);
  const StripDesign d = design_strip(curve, o);

  json_write::ColumnarResult result;
  json& out = result.tree;
  out["feasible"] = d.feasible;
  out["reason"] = d.reason;
  out["reason_code"] = d.reason_code;
  out["where"] = d.reason_s >= 0 ? json{{"s", d.reason_s}} : json(nullptr);
  out["length"] = d.length;
  auto xy = [](const std::vector<Vec2>& v) {
    std::vector<double> flat;
    flat.reserve(2 * v.size());
    for (const auto& p : v) flat.push_back(p.x()), flat.push_back(p.y());
    return flat;
  };
  {  // the curve as designed (the interpolant when points were given)
    json& bspline = out["bspline"];
    bspline["degree"] = curve.degree();
    if (curve.rational()) bspline["weights"] = curve.weights();
    result.put({"bspline", "knots"}, curve.knots());
    result.put({"bspline", "poles"}, xy(curve.poles()), 2);
  }
  json infl = json::array();
  for (const auto& z : d.zeros)
    infl.push_back({{"s", z.at.s}, {"point", to_json(z.at.point)}, {"kind", to_string(z.kind)},
                    {"tangent", to_json(z.at.tangent)}, {"dkappa_ds", z.at.dkappa_ds}});
  out["inflections"] = std::move(infl);
  out["line"] = {{"a", d.a}, {"b", to_json(d.b)}};
  out["R"] = d.feasible ? json(d.R) : json(nullptr);
  {
    const size_t n = d.samples.size();
    std::vector<double> s(n), pts(2 * n), kap(n), K(n);
    for (size_t i = 0; i < n; ++i) {
      const StripSample& p = d.samples[i];
      s[i] = p.s, pts[2 * i] = p.point.x(), pts[2 * i + 1] = p.point.y(), kap[i] = p.kappa, K[i] = p.K;
    }
    result.put({"s"}, std::move(s));
    result.put({"points"}, std::move(pts), 2);
    result.put({"curvature"}, std::move(kap));
    result.put({"K"}, std::move(K));
    result.put({"width"}, d.width);
    result.put({"bending_stiffness"}, d.bending_stiffness);
    result.put({"outline"}, xy(d.outline), 2);
  }
  json refinement = json::array();
  auto num = [](double x) { return std::isfinite(x) ? json(x) : json(nullptr); };
  for (const auto& r : d.refinement)
    refinement.push_back({{"samples", r.samples}, {"R", num(r.R)}, {"R_continuous", num(r.R_continuous)}});
  out["diagnostics"] = {{"converged", d.converged},
                        {"samples", d.lp_samples},
                        {"R_continuous", num(d.R_continuous)},
                        {"refinement", refinement},
                        {"lp_iterations", d.lp_iterations},
                        {"lp_seconds", d.lp_seconds},
                        {"total_seconds", d.total_seconds},
                        {"lp_message", d.lp_message},
                        {"collinearity_error", d.collinearity_error}};
  if (request.contains("name")) out["name"] = request["name"];
  out["thickness"] = o.thickness;
  out["min_width"] = o.min_width;
  // Gravity / general LP fields (null / defaults for the plain Eq. 4.4 design).
  out["general_lp"] = d.general_lp;
  out["R_first"] = d.feasible ? num_or_null(d.R_first) : json(nullptr);
  out["smoothed"] = d.smoothed;
  out["tv_first"] = num_or_null(d.tv_first);
  out["tv"] = num_or_null(d.tv);
  out["start_force"] = d.general_lp && d.feasible ? to_json(d.start_force) : json(nullptr);
  out["end_force"] = d.general_lp && d.feasible ? to_json(d.end_force) : json(nullptr);
  out["zero_consistency"] = d.zero_consistency;
  out["max_plastic_curvature"] = d.max_plastic_curvature;
  out["weight_per_length"] = d.weight_per_length;
  out["weight_iterations"] = d.weight_iterations;
  out["strain"] = {{"max", d.max_strain}, {"s", d.max_strain_s},
                   {"thickness", o.strain_thickness > 0 ? o.strain_thickness : o.thickness},
                   {"yield_strain", num_or_null(o.yield_strain)}, {"yield_ratio", num_or_null(d.yield_ratio)}};
  if (o.gravity.enabled) {
    const Vec2 dir = o.gravity.direction / o.gravity.direction.norm();
    out["gravity"] = {{"direction", to_json(dir)}, {"beta_l3", o.gravity.gravito_bending},
                      {"load", to_json(o.gravity.load())}};
  } else {
    out["gravity"] = nullptr;
  }
  {  // the clamp (or support) at each end: position and tangent angle of the curve
    json ends = json::array();
    for (int e = 0; e < 2; ++e) {
      const auto dv = curve.derivatives(e == 0 ? curve.first_parameter() : curve.last_parameter());
      CurvePoint p;
      p.point = dv[0];
      p.tangent = dv[1].normalized();
      const StripEnd& be = e == 0 ? o.boundary.start : o.boundary.end;
      ends.push_back({{"which", e == 0 ? "start" : "end"}, {"s", e == 0 ? 0.0 : d.length},
                      {"point", to_json(p.point)},
                      {"angle_deg", std::atan2(p.tangent.y(), p.tangent.x()) * 180.0 / M_PI},
                      {"free_x", be.free_x}, {"free_y", be.free_y}, {"free_angle", be.free_angle}});
    }
    out["ends"] = ends;
  }
  if (validate) {
    if (!d.feasible) {
      out["simulation"] = nullptr;
    } else {
      StripDesignOptions so = o;
      if (sim_gravity) so.gravity = sim_g;
      const StripValidation v = validate_strip(curve, d, so, vo);
      json nodes = json::array();
      for (const auto& p : v.simulation.nodes) nodes.push_back(to_json(p));
      out["simulation"] = {{"deviation", num_or_null(v.deviation)},
                           {"max_distance", num_or_null(v.max_distance)},
                           {"worst_s", v.worst_s},
                           {"iterations", v.iterations},
                           {"load_steps", v.load_steps},
                           {"converged", v.converged},
                           {"seconds", v.seconds},
                           {"message", v.message},
                           {"gravity", so.gravity.enabled},
                           {"edges", vo.rod.edges},
                           {"nodes", nodes}};
    }
  }
  if (robustness) {
    if (!d.feasible) {
      out["robustness"] = nullptr;
    } else {
      const StripRobustness r = strip_robustness_study(curve, d, o, ro);
      json cases = json::array();
      double baseline = NAN;
      size_t plastic = 0;
      for (const auto& c : r.cases) {
        // Which defect and its signed size: relative change, degrees, or the plastic fraction
        // (the plastic cases follow the order of plastic_fractions).
        const StripPerturbation& q = c.perturbation;
        std::string parameter = "none";
        double value = 0;
        if (q.stiffness_ratio_scale != 1) parameter = "stiffness_range", value = q.stiffness_ratio_scale - 1;
        else if (q.gravity_scale != 1) parameter = "gravity", value = q.gravity_scale - 1;
        else if (q.end_angle_offset != 0) parameter = "end_angles", value = q.end_angle_offset * 180 / M_PI;
        else if (std::isfinite(q.curvature_limit))
          parameter = "plastic", value = plastic < ro.plastic_fractions.size() ? ro.plastic_fractions[plastic++] : NAN;
        if (c.name == "baseline") baseline = c.deviation;
        json cj = {{"name", c.name}, {"parameter", parameter}, {"value", num_or_null(value)},
                   {"deviation", num_or_null(c.deviation)}, {"max_distance", num_or_null(c.max_distance)},
                   {"converged", c.converged}, {"message", c.message}};
        if (parameter == "plastic")
          cj["curvature_limit"] = q.curvature_limit, cj["hardening"] = q.plastic_hardening;
        json nodes = json::array();
        for (const auto& p : c.nodes) nodes.push_back(to_json(p));
        cj["nodes"] = nodes;
        cases.push_back(cj);
      }
      out["robustness"] = {{"baseline", num_or_null(baseline)},
                           {"worst_deviation", r.worst_deviation},
                           {"worst_case", r.worst_case},
                           {"edges", ro.validation.rod.edges},
                           {"seconds", r.seconds},
                           {"cases", cases}};
    }
  }
  if (request.contains("composite")) {
    if (!d.feasible) {
      out["composite"] = nullptr;
    } else {
      std::vector<double> sv, K, w1;
      for (const auto& p : d.samples) sv.push_back(p.s), K.push_back(p.K), w1.push_back(composite_w1);
      const CompositeStripResult c = design_composite_strip(sv, K, w1, co);
      out["composite"] = {{"feasible", c.feasible},
                          {"h1", co.outer_thickness},
                          {"h2", co.inner_thickness},
                          {"outer_width", composite_w1},
                          {"w2", c.inner_width},
                          {"scale", c.scale},
                          {"worst_s", c.worst_s},
                          {"max_thickness_ratio", num_or_null(c.max_thickness_ratio)},
                          {"message", c.message}};
    }
  }
  if (request.contains("perforated")) {
    if (!d.feasible) {
      out["perforations"] = nullptr;
    } else {
      std::vector<double> sv, w;
      for (const auto& p : d.samples) sv.push_back(p.s), w.push_back(perforated_w);
      const PerforatedStripResult r = design_perforated_strip(sv, w, d.width, po);
      json diamonds = json::array();
      for (const auto& dm : r.diamonds) {
        json corners = json::array();
        for (const auto& c : dm.corners()) corners.push_back(to_json(c));
        diamonds.push_back({{"s", dm.s}, {"offset", dm.offset}, {"length", dm.length},
                            {"width", dm.width}, {"corners", corners}});
      }
      out["perforations"] = {{"feasible", r.feasible},
                             {"outer_width", perforated_w},
                             {"columns", r.columns},
                             {"pitch", r.pitch},
                             {"from", r.perforated_from},
                             {"to", r.perforated_to},
                             {"worst_s", r.worst_s},
                             {"message", r.message},
                             {"max_width_deviation", r.max_width_deviation},
                             {"max_width_deviation_s", r.max_width_deviation_s},
                             {"max_stiffness_deviation", r.max_stiffness_deviation},
                             {"max_stiffness_deviation_s", r.max_stiffness_deviation_s},
                             {"end_zone_deviation", r.end_zone_deviation},
                             {"interior_width_deviation", r.interior_width_deviation},
                             {"interior_width_deviation_s", r.interior_width_deviation_s},
                             {"interior_stiffness_deviation", r.interior_stiffness_deviation},
                             {"interior_stiffness_deviation_s", r.interior_stiffness_deviation_s},
                             {"diamonds", diamonds}};
    }
  }
  const auto t_stability = std::chrono::steady_clock::now();
  if (stability)
    out["stability"] = d.feasible ? stability_to_json(strip_stability(curve, d, o, stability_options), d.length)
                                  : json(nullptr);
  const double stability_seconds = since(t_stability);
  out["units"] = {{"length", "m"}, {"E", "Pa"}, {"bending_stiffness", "N*m^2"}};
  // Wall time per phase (benchmarks): the curve from the request (interpolation of points),
  // the design's phases, the stability verdict, and everything in this call (`entry`:
  // request parsing, design, stability, validation and building this JSON).
  const StripDesign::Phases& ph = d.phases;
  out["diagnostics"]["phases"] = {{"interpolation", interpolation_seconds}, {"curve", ph.curve},
                                  {"zeros", ph.zeros}, {"check", ph.check}, {"sampling", ph.sampling},
                                  {"lp", ph.lp}, {"ratio", ph.ratio}, {"outputs", ph.outputs},
                                  {"stability", stability_seconds}, {"entry", since(t_entry)}};
  return result;
}

}  // namespace parafab::entry

namespace parafab::entry {
BSplineCurve2 parse_strip_curve(const nlohmann::json& request) { return parse_curve(request); }
}  // namespace parafab::entry
