#include "rod_json.h"

#include <optional>

#include <cmath>

#include "common/error.h"
#include "request_schema.h"
#include "rods/bspline_curve3.h"
#include "rods/rod_design.h"
#include "rods/rod_stability.h"

#include "json_fields.h"
#include "json_write.h"

namespace parafab::entry {

using nlohmann::json;

namespace {

using fields::require;

// fields::number, with the message rod requests give for null and strings (NaN/inf written
// as null or text by some JSON writers).
double number(const json& v, const std::string& path) {
  if (v.is_null() || v.is_string())
    PARAFAB_INPUT_ERROR(path << " is not a finite number (got " << v.dump() << ")");
  return fields::number(v, path);
}

// obj[key] as a number in the allowed range, or `fallback` when absent.
double optional_number(const json& obj, const char* key, const std::string& path, double fallback,
                       double lo, double hi, bool lo_open) {
  auto it = obj.find(key);
  if (it == obj.end()) return fallback;
  const std::string p = path.empty() ? key : path + "." + key;
  const double x = number(*it, p);
  if ((lo_open ? !(x > lo) : !(x >= lo)) || !(x <= hi)) {
    if (std::isinf(hi)) PARAFAB_INPUT_ERROR(p << " must be " << (lo_open ? "> " : ">= ") << lo << ", got " << x);
    PARAFAB_INPUT_ERROR(p << " must be in " << (lo_open ? "(" : "[") << lo << ", " << hi << "], got " << x);
  }
  return x;
}

int optional_int(const json& obj, const char* key, const std::string& path, int fallback, int lo, int hi) {
  auto it = obj.find(key);
  if (it == obj.end()) return fallback;
  const std::string p = path.empty() ? key : path + "." + key;
  if (!it->is_number_integer()) PARAFAB_INPUT_ERROR(p << " must be an integer, got " << it->dump());
  const long long v = it->get<long long>();
  if (v < lo || v > hi) PARAFAB_INPUT_ERROR(p << " must be in [" << lo << ", " << hi << "], got " << v);
  return int(v);
}

bool optional_bool(const json& obj, const char* key, const std::string& path, bool fallback) {
  auto it = obj.find(key);
  if (it == obj.end()) return fallback;
  if (!it->is_boolean())
    PARAFAB_INPUT_ERROR((path.empty() ? key : path + "." + key) << " must be true or false, got " << it->dump());
  return it->get<bool>();
}

Vec3 vec3(const json& v, const std::string& path) {
  if (!v.is_array() || v.size() != 3) PARAFAB_INPUT_ERROR(path << " must be a triple [x, y, z], got " << v.dump());
  return Vec3(number(v[0], path + "[0]"), number(v[1], path + "[1]"), number(v[2], path + "[2]"));
}

std::vector<Vec3> points3(const json& v, const std::string& path) {
  if (!v.is_array()) PARAFAB_INPUT_ERROR(path << " must be an array of [x, y, z] triples");
  std::vector<Vec3> out;
  out.reserve(v.size());
  for (size_t i = 0; i < v.size(); ++i) out.push_back(vec3(v[i], path + "[" + std::to_string(i) + "]"));
  return out;
}

std::vector<double> numbers(const json& v, const std::string& path) {
  if (!v.is_array()) PARAFAB_INPUT_ERROR(path << " must be an array of numbers");
  std::vector<double> out;
  for (size_t i = 0; i < v.size(); ++i) out.push_back(number(v[i], path + "[" + std::to_string(i) + "]"));
  return out;
}

BSplineCurve3 parse_curve(const json& request) {
  const json& curve = require(request, "curve", "request");
  if (!curve.is_object()) PARAFAB_INPUT_ERROR("curve must be a JSON object, got " << curve.type_name());
  if (curve.contains("bspline")) {
    const json& bs = curve["bspline"];
    const json& deg = require(bs, "degree", "curve.bspline");
    if (!deg.is_number_integer()) PARAFAB_INPUT_ERROR("curve.bspline.degree must be an integer, got " << deg.dump());
    return BSplineCurve3(deg.get<int>(), numbers(require(bs, "knots", "curve.bspline"), "curve.bspline.knots"),
                         points3(require(bs, "poles", "curve.bspline"), "curve.bspline.poles"),
                         bs.contains("weights") ? numbers(bs["weights"], "curve.bspline.weights")
                                                : std::vector<double>{});
  }
  if (curve.contains("points")) {
    // Cubic by default: κ continuous (C²), torsion piecewise continuous.
    const int degree = optional_int(curve, "degree", "curve", 3, 1, 7);
    return interpolate_points3(points3(curve["points"], "curve.points"), degree);
  }
  PARAFAB_INPUT_ERROR("curve must hold either \"bspline\" {degree, knots, poles[, weights]} or "
                      "\"points\" [[x, y, z], ...]");
}

RodMaterial parse_material(const json& request) {
  RodMaterial m = RodMaterial::smooth_sil_960();
  auto it = request.find("material");
  if (it == request.end()) return m;
  const json& mat = *it;
  if (!mat.is_object()) PARAFAB_INPUT_ERROR("material must be a JSON object, got " << mat.type_name());
  if (mat.contains("preset")) {
    const std::string p = mat["preset"].is_string() ? mat["preset"].get<std::string>() : mat["preset"].dump();
    if (p != "SmoothSil 960")
      PARAFAB_INPUT_ERROR("material.preset must be \"SmoothSil 960\" (or give E, nu, density), got " << p);
  }
  m.youngs_modulus = optional_number(mat, "E", "material", m.youngs_modulus, 0, INFINITY, true);
  m.poisson_ratio = optional_number(mat, "nu", "material", m.poisson_ratio, -1, 0.5, true);
  if (m.poisson_ratio == 0.5) PARAFAB_INPUT_ERROR("material.nu must be < 0.5, got 0.5");
  m.density = optional_number(mat, "density", "material", m.density, 0, INFINITY, false);
  return m;
}

json to_json(const Vec3& v) { return json_write::coordinates(v); }
json num(double x) { return std::isfinite(x) ? json(x) : json(nullptr); }

}  // namespace

// Default t/t* of the sections: the most circular ellipse (1) makes the twist-free helix an
// unstable equilibrium (negative Hessian eigenvalue, thesis §4.5.1 test on the discrete rod);
// elongating along the bending axis stabilizes it (see tests/python/test_rod_entry.py).
constexpr double kDefaultSectionFactor = 4.0;

json design_rod_json(const json& request) {
  schema::check(request, schema::Format::Rod);
  RodDesignOptions o;
  o.geometry.circularity_factor = kDefaultSectionFactor;
  o.material = parse_material(request);
  o.max_radius = optional_number(request, "max_radius", "", o.max_radius, 0, INFINITY, true);
  o.lp.regularization_weight = optional_number(request, "w_reg", "", 0.0, 0, INFINITY, false);
  // Second LP stage (stiffness ratio at R ≤ R*(1 + 1e-7)); off: the Eq. 5.19 optimum itself.
  o.lp.minimize_stiffness_ratio = optional_bool(request, "stiffness_ratio_stage", "", true);
  if (request.contains("section")) {
    const json& sec = request["section"];
    if (!sec.is_object()) PARAFAB_INPUT_ERROR("section must be a JSON object, got " << sec.type_name());
    o.geometry.circularity_factor = optional_number(sec, "factor", "section", kDefaultSectionFactor, 0, INFINITY, true);
  }
  const int count = optional_int(request, "samples", "", 200, 3, 100000);
  if (request.contains("loads")) {
    const json& loads = request["loads"];
    if (!loads.is_object()) PARAFAB_INPUT_ERROR("loads must be a JSON object, got " << loads.type_name());
    o.loads.dead_load = optional_bool(loads, "dead_load", "loads", false);
    if (loads.contains("gravity")) o.loads.gravity = vec3(loads["gravity"], "loads.gravity");
    if (loads.contains("point_loads")) {
      const json& pl = loads["point_loads"];
      if (!pl.is_array()) PARAFAB_INPUT_ERROR("loads.point_loads must be an array of {s, force}");
      for (size_t k = 0; k < pl.size(); ++k) {
        const std::string p = "loads.point_loads[" + std::to_string(k) + "]";
        o.loads.point_loads.push_back({number(require(pl[k], "s", p), p + ".s"), vec3(require(pl[k], "force", p), p + ".force")});
      }
    }
  }
  if (request.contains("fixed_point")) {
    const json& fp = request["fixed_point"];
    if (!fp.is_object()) PARAFAB_INPUT_ERROR("fixed_point must be a JSON object, got " << fp.type_name());
    o.dead_load.tolerance = optional_number(fp, "tolerance", "fixed_point", o.dead_load.tolerance, 0, INFINITY, true);
    o.dead_load.max_iterations = optional_int(fp, "max_iterations", "fixed_point", o.dead_load.max_iterations, 1, 10000);
  }
  const bool validate = optional_bool(request, "validate", "", false);
  const int edges = optional_int(request, "validate_edges", "", 100, 3, 5000);
  // Stability (on by default): inertia of the discrete rod's Hessian at the design.
  const bool stability = optional_bool(request, "stability", "", true);
  const int stability_edges = optional_int(request, "stability_edges", "", 100, 8, 2000);
  // Where the Hessian is taken: at the discrete rod's equilibrium found from the target
  // (default; one forward simulation) or at the target itself (faster, blind near bifurcations).
  const json at_j = request.value("stability_at", json("equilibrium"));
  if (!(at_j == json("equilibrium") || at_j == json("target")))
    PARAFAB_INPUT_ERROR("stability_at must be \"equilibrium\" or \"target\", got " << at_j.dump());
  const bool stability_at_equilibrium = at_j == json("equilibrium");

  const BSplineCurve3 bspline = parse_curve(request);
  const SpaceCurve curve = bspline.space_curve();
  const double L = curve.length();
  for (size_t k = 0; k < o.loads.point_loads.size(); ++k)
    if (!(o.loads.point_loads[k].s >= 0 && o.loads.point_loads[k].s <= L))
      PARAFAB_INPUT_ERROR("loads.point_loads[" << k << "].s must be in [0, length = " << L << " m], got "
                                               << o.loads.point_loads[k].s);
  const RodDesign d = design_rod(curve, count, o);  // throws for κ = 0 with its location

  json out;
  if (request.contains("name")) {
    if (!request["name"].is_string()) PARAFAB_INPUT_ERROR("name must be a string, got " << request["name"].dump());
    out["name"] = request["name"];
  }
  out["feasible"] = d.ok();
  out["status"] = to_string(d.status);
  out["reason"] = d.ok() ? (d.lp.parallel ? "parallel curve: twist-free rod (Eq. 5.13)" : "") : d.message;
  out["where"] = d.lp.binding_s.empty() ? json(nullptr) : json{{"s", d.lp.binding_s}};
  out["length"] = L;
  {
    json poles = json::array();
    for (const auto& p : bspline.poles()) poles.push_back(to_json(p));
    out["bspline"] = {{"degree", bspline.degree()}, {"knots", bspline.knots()}, {"poles", poles}};
    if (bspline.rational()) out["bspline"]["weights"] = bspline.weights();
  }
  // The curve samples with their Frénet data (the rows of the LP are built from these).
  json s = json::array(), t = json::array(), pts = json::array(), T = json::array(), N = json::array(),
       B = json::array(), kap = json::array(), tor = json::array();
  for (const auto& p : d.samples) {
    s.push_back(p.s), t.push_back(p.t), pts.push_back(to_json(p.point)), T.push_back(to_json(p.tangent));
    N.push_back(to_json(p.normal)), B.push_back(to_json(p.binormal)), kap.push_back(p.kappa);
    tor.push_back(p.torsion);
  }
  out["s"] = s, out["t"] = t, out["points"] = pts, out["tangent"] = T, out["normal"] = N;
  out["binormal"] = B, out["curvature"] = kap, out["torsion"] = tor;
  out["lp"] = {{"status", to_string(d.lp.status)},
               {"c", to_json(d.lp.c)},
               {"c_bar", to_json(d.lp.c_bar)},
               {"R", d.lp.ok() ? json(d.lp.R) : json(nullptr)},
               {"twist_ratio", num(d.lp.twist_ratio)},
               {"stiffness_ratio", num(d.lp.stiffness_ratio)},
               {"parallel", d.lp.parallel},
               {"w_reg", o.lp.regularization_weight},
               {"stiffness_ratio_stage", o.lp.minimize_stiffness_ratio},
               {"twist_slack_relative", o.lp.twist_slack_relative},
               {"binding_samples", d.lp.binding_samples},
               {"lps_solved", d.lp.lps_solved},
               {"iterations", d.lp.iterations}};
  out["R"] = d.lp.ok() ? json(d.lp.R) : json(nullptr);
  if (d.sections.size() == d.samples.size()) {
    out["c"] = to_json(d.c);
    out["c_bar"] = to_json(d.c_bar);
    out["scale"] = d.scale;
    json tw = json::array(), beta = json::array(), th = json::array(), n1 = json::array(), n2 = json::array(),
         a = json::array(), b = json::array(), ang = json::array(), J = json::array(), area = json::array(),
         h = json::array(), p = json::array();
    for (size_t i = 0; i < d.sections.size(); ++i) {
      const RodSection& q = d.sections[i];
      tw.push_back(q.twist), beta.push_back(q.beta), th.push_back(q.frame_angle);
      n1.push_back(to_json(q.n1)), n2.push_back(to_json(q.n2));
      a.push_back(q.ellipse.a), b.push_back(q.ellipse.b), ang.push_back(q.ellipse.angle);
      J.push_back(q.J), area.push_back(q.area);
      h.push_back(to_json(d.moment[i])), p.push_back(to_json(d.line_load[i]));
    }
    out["twist"] = tw, out["beta"] = beta, out["frame_angle"] = th, out["n1"] = n1, out["n2"] = n2;
    out["section"] = {{"a", a}, {"b", b}, {"angle", ang}, {"J", J}, {"area", area},
                      {"factor", o.geometry.circularity_factor}};
    out["moment"] = h;
    out["line_load"] = p;
    // Where the rod is clamped: position, material frame (x = n1, y = n2, z = tangent) and β.
    json ends = json::array();
    for (size_t i : {size_t(0), d.sections.size() - 1}) {
      const RodSample& q = d.samples[i];
      const RodSection& r = d.sections[i];
      ends.push_back({{"s", q.s}, {"position", to_json(q.point)}, {"tangent", to_json(q.tangent)},
                      {"n1", to_json(r.n1)}, {"n2", to_json(r.n2)}, {"beta", r.beta}, {"twist", r.twist},
                      {"a", r.ellipse.a}, {"b", r.ellipse.b}, {"angle", r.ellipse.angle}});
    }
    out["end_frames"] = ends;
  } else {
    out["c"] = out["c_bar"] = out["end_frames"] = json(nullptr);
  }
  out["load_iterations"] = {{"iterations", d.fixed_point_iterations},
                            {"history", d.fixed_point_history},
                            {"tolerance", o.dead_load.tolerance},
                            {"loads", o.loads.any()}};
  std::optional<DiscreteRodResult> validation;  // reused by the stability verdict on the same rod
  if (validate && d.ok()) {
    const DiscreteRodModel m = discrete_rod_model(d, curve, edges, o.material, o.loads, true);
    const DiscreteRodResult& r = validation.emplace(simulate_discrete_rod(m));
    const double dist = max_node_distance(r.nodes, m.nodes);
    out["simulation"] = {{"deviation", dist / L},      {"max_distance", dist},
                         {"iterations", r.iterations}, {"converged", r.ok()},
                         {"edges", edges},             {"hessian_shifts", r.hessian_shifts},
                         {"seconds", r.seconds},       {"message", r.message}};
  } else if (validate) {
    out["simulation"] = nullptr;
  }
  if (stability && d.ok()) {
    const DiscreteRodModel m = discrete_rod_model(d, curve, stability_edges, o.material, o.loads, true);
    const RodStability st = !stability_at_equilibrium ? rod_stability(m)
                            : validation && edges == stability_edges ? rod_stability_at_equilibrium(m, *validation)
                                                                     : rod_stability_at_equilibrium(m);
    out["stability"] = {{"stable", st.stable},          {"method", st.method},
                        {"verdict", st.verdict},
                        {"moved_away", st.method == "hessian_at_equilibrium" ? json(st.moved_away) : json(nullptr)},
                        {"equilibrium_stable",
                         st.method == "hessian_at_equilibrium" ? json(st.equilibrium_stable) : json(nullptr)},
                        {"equilibrium_distance", num(st.equilibrium_distance)},
                        {"negative", st.negative},      {"zero", st.zero},
                        {"free_dofs", st.free_dofs},    {"min_eigenvalue", num(st.min_eigenvalue)},
                        {"min_relative", num(st.min_relative)}, {"edges", stability_edges},
                        {"seconds", st.seconds},        {"message", st.message}};
  } else {
    out["stability"] = nullptr;
  }
  out["diagnostics"] = {{"samples", count},
                        {"lp_seconds", d.lp_seconds},
                        {"geometry_seconds", d.geometry_seconds},
                        {"dead_load_seconds", d.dead_load_seconds},
                        {"total_seconds", d.total_seconds},
                        {"lp_message", d.lp.message}};
  out["material"] = {{"E", o.material.youngs_modulus}, {"nu", o.material.poisson_ratio},
                     {"density", o.material.density}};
  out["units"] = {{"length", "m"}, {"E", "Pa"}, {"density", "kg/m^3"}, {"c", "N"}, {"c_bar", "N*m"},
                  {"twist", "1/m"}, {"angle", "rad"}, {"J", "m^4"}, {"area", "m^2"}, {"line_load", "N/m"}};
  return out;
}

}  // namespace parafab::entry
