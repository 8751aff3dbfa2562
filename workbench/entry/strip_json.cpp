#include "strip_json.h"

#include <cmath>

#include "common/error.h"
#include "strips/strip_design.h"

namespace parafab::entry {

using nlohmann::json;

namespace {

const json& require(const json& obj, const char* key, const std::string& path) {
  if (!obj.is_object())
    PARAFAB_INPUT_ERROR(path << " must be a JSON object, got " << obj.type_name());
  auto it = obj.find(key);
  if (it == obj.end()) PARAFAB_INPUT_ERROR("missing " << path << "." << key);
  return *it;
}

double number(const json& v, const std::string& path) {
  if (!v.is_number()) PARAFAB_INPUT_ERROR(path << " must be a number, got " << v.dump());
  const double x = v.get<double>();
  if (!std::isfinite(x)) PARAFAB_INPUT_ERROR(path << " is not finite");
  return x;
}

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

std::vector<Vec2> points2(const json& v, const std::string& path) {
  if (!v.is_array()) PARAFAB_INPUT_ERROR(path << " must be an array of [x, y] pairs");
  std::vector<Vec2> out;
  out.reserve(v.size());
  for (size_t i = 0; i < v.size(); ++i) {
    const std::string p = path + "[" + std::to_string(i) + "]";
    if (!v[i].is_array() || v[i].size() != 2)
      PARAFAB_INPUT_ERROR(p << " must be a pair [x, y] (a plane curve), got " << v[i].dump());
    out.emplace_back(coordinate(v[i][0], p + "[0]"), coordinate(v[i][1], p + "[1]"));
  }
  return out;
}

std::vector<double> numbers(const json& v, const std::string& path) {
  if (!v.is_array()) PARAFAB_INPUT_ERROR(path << " must be an array of numbers");
  std::vector<double> out;
  for (size_t i = 0; i < v.size(); ++i)
    out.push_back(coordinate(v[i], path + "[" + std::to_string(i) + "]"));
  return out;
}

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

json to_json(const Vec2& v) { return json::array({v.x(), v.y()}); }

}  // namespace

json error_json(const std::string& message, const std::string& kind) {
  return json{{"error", {{"message", message}, {"kind", kind}}}};
}

json design_strip_json(const json& request) {
  if (!request.is_object()) PARAFAB_INPUT_ERROR("the request must be a JSON object");
  StripDesignOptions o;
  const json& material = require(request, "material", "request");
  o.youngs_modulus = number(require(material, "E", "material"), "material.E");
  o.thickness = number(require(material, "thickness", "material"), "material.thickness");
  o.min_width = number(require(request, "min_width", "request"), "min_width");
  o.tolerance = optional_number(request, "tolerance", "request", o.tolerance);
  if (request.contains("max_samples"))
    o.max_samples = static_cast<int>(number(request["max_samples"], "max_samples"));
  if (request.contains("lp_form")) {
    const std::string f = request["lp_form"].is_string() ? request["lp_form"].get<std::string>() : "";
    if (f != "dual" && f != "primal") PARAFAB_INPUT_ERROR("lp_form must be \"dual\" or \"primal\"");
    o.lp_form = f == "dual" ? LpForm::Dual : LpForm::Primal;
  }
  const BSplineCurve2 curve = parse_curve(request);
  const StripDesign d = design_strip(curve, o);

  json out;
  out["feasible"] = d.feasible;
  out["reason"] = d.reason;
  out["reason_code"] = d.reason_code;
  out["where"] = d.reason_s >= 0 ? json{{"s", d.reason_s}} : json(nullptr);
  out["length"] = d.length;
  {  // the curve as designed (the interpolant when points were given)
    json poles = json::array();
    for (const auto& p : curve.poles()) poles.push_back(to_json(p));
    out["bspline"] = {{"degree", curve.degree()}, {"knots", curve.knots()}, {"poles", poles}};
    if (curve.rational()) out["bspline"]["weights"] = curve.weights();
  }
  json infl = json::array();
  for (const auto& z : d.zeros)
    infl.push_back({{"s", z.at.s}, {"point", to_json(z.at.point)}, {"kind", to_string(z.kind)},
                    {"tangent", to_json(z.at.tangent)}, {"dkappa_ds", z.at.dkappa_ds}});
  out["inflections"] = infl;
  out["line"] = {{"a", d.a}, {"b", to_json(d.b)}};
  out["R"] = d.feasible ? json(d.R) : json(nullptr);
  json s = json::array(), pts = json::array(), kap = json::array(), K = json::array();
  for (const auto& p : d.samples) {
    s.push_back(p.s);
    pts.push_back(to_json(p.point));
    kap.push_back(p.kappa);
    K.push_back(p.K);
  }
  out["s"] = s;
  out["points"] = pts;
  out["curvature"] = kap;
  out["K"] = K;
  out["width"] = d.width;
  out["bending_stiffness"] = d.bending_stiffness;
  json outline = json::array();
  for (const auto& p : d.outline) outline.push_back(to_json(p));
  out["outline"] = outline;
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
  out["units"] = {{"length", "m"}, {"E", "Pa"}, {"bending_stiffness", "N*m^2"}};
  return out;
}

}  // namespace parafab::entry
