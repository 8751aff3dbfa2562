#include "strip_improve_json.h"

#include <algorithm>
#include <cmath>

#include "common/error.h"
#include "request_schema.h"
#include "json_fields.h"
#include "strip_json.h"
#include "strips/curve_fairing.h"
#include "strips/strip_improve.h"
#include "json_write.h"
#include "stability_json.h"

namespace parafab::entry {

using nlohmann::json;
using fields::integer;
using fields::only;
using fields::number;
using fields::require;

namespace {
json num(double x) { return std::isfinite(x) ? json(x) : json(nullptr); }
json vec(const Vec2& v) { return json_write::coordinates(v); }
std::vector<Vec2> points(const json& v) {
  if (!v.is_array()) PARAFAB_INPUT_ERROR("curve.points must be an array of [x, y] pairs");
  std::vector<Vec2> out;
  for (size_t i = 0; i < v.size(); ++i) {
    const std::string p = "curve.points[" + std::to_string(i) + "]";
    if (!v[i].is_array() || v[i].size() != 2) PARAFAB_INPUT_ERROR(p << " must be a pair [x, y], got " << v[i].dump());
    out.emplace_back(number(v[i][0], p + "[0]"), number(v[i][1], p + "[1]"));
  }
  return out;
}
}  // namespace

json bspline_json(const BSplineCurve2& c) {
  json poles = json::array();
  for (const auto& p : c.poles()) poles.push_back(vec(p));
  return {{"degree", c.degree()}, {"knots", c.knots()}, {"poles", poles}};
}

namespace {
SpuriousInflectionOptions fair_options(const json& fair, const std::string& path, size_t point_count) {
  SpuriousInflectionOptions so;
  so.fit.poles = std::clamp(static_cast<int>(point_count) / 4, 8, 24);
  if (!fair.is_null()) {
    only(fair, path, {"poles", "fairness", "min_separation", "end_separation"});
    if (fair.contains("poles")) so.fit.poles = integer(fair["poles"], path + ".poles", 6, 1000);
    if (fair.contains("fairness")) so.fit.fairness = number(fair["fairness"], path + ".fairness");
    if (fair.contains("min_separation")) so.min_separation = number(fair["min_separation"], path + ".min_separation");
    if (fair.contains("end_separation")) so.end_separation = number(fair["end_separation"], path + ".end_separation");
  }
  return so;
}
}  // namespace

void check_fair_options(const json& fair, const std::string& path) { fair_options(fair, path, 0); }

std::pair<BSplineCurve2, json> fair_points_json(const std::vector<Vec2>& P, const json& fair,
                                                const std::string& path) {
  const SpuriousInflectionOptions so = fair_options(fair, path, P.size());
  SpuriousInflectionResult fr = fair_section_curve(P, so);
  json report = {{"poles", so.fit.poles}, {"fairness", so.fit.fairness}, {"min_separation", so.min_separation},
                 {"inflections_before", fr.inflections_before}, {"inflections", fr.inflections},
                 {"inflection_s", fr.inflection_s}, {"rounds", fr.rounds}, {"done", fr.done},
                 {"max_error", fr.max_error}, {"message", fr.message}};
  return {std::move(fr.curve), std::move(report)};
}

json improve_strip_json(const json& request, double target_R) {
  schema::check(request, schema::Format::StripImprove);
  // The descent lowers R of LP Eq. 4.4 (clamped ends, κ₀ = 0, linear law; thesis §4.6.2), as
  // improve_strip_fabricability does: other designs are refused (as strip-stabilize does), not
  // reported as done on Eq. 4.4. Gravity is designed afterwards (Eq. 4.6) and done tests it.
  for (const char* k : {"boundary", "natural_curvature"})
    if (request.contains(k) && !request[k].is_null())
      PARAFAB_INPUT_ERROR(k << ": fabricability optimization (thesis §4.6.2) lowers R of LP Eq. 4.4 with clamped "
                            "ends and no natural curvature; remove \"" << k << "\" from the request (got "
                            << request[k].dump() << ")");
  if (request.contains("material") && request["material"].is_object() && request["material"].contains("law"))
    PARAFAB_INPUT_ERROR("material.law: fabricability optimization (thesis §4.6.2) lowers R of LP Eq. 4.4 with the "
                        "linear moment law; remove material.law (got " << request["material"]["law"].dump() << ")");
  const bool gravity = request.contains("gravity") && !request["gravity"].is_null() &&
                       !(request["gravity"].is_boolean() && !request["gravity"].get<bool>());
  // The final design: the strip request itself (material, gravity, ...) if it has one.
  const bool has_design = request.contains("material") && request.contains("min_width");
  if (gravity && !has_design)
    PARAFAB_INPUT_ERROR("gravity: strip-improve designs the result under gravity (LP Eq. 4.6) with the request's "
                        "material and min_width; give both (missing "
                        << (request.contains("material") ? "min_width" : "material") << ")");
  StripImproveOptions o;
  const json imp = request.value("improve", json::object());
  only(imp, "improve", {"target_R", "max_iterations", "p", "samples", "max_seconds", "global_every",
                        "initial_step", "fix_length", "fit_poles", "fair"});
  if (imp.contains("target_R")) o.target_R = number(imp["target_R"], "improve.target_R");
  if (target_R > 0) o.target_R = target_R;
  if (!(o.target_R >= 1)) PARAFAB_INPUT_ERROR("improve.target_R (--target-R) must be >= 1, got " << o.target_R);
  if (imp.contains("max_iterations")) o.max_iterations = integer(imp["max_iterations"], "improve.max_iterations", 0, 100000);
  if (imp.contains("p")) {
    o.p = number(imp["p"], "improve.p");
    if (!(o.p >= 2 && o.p <= 200)) PARAFAB_INPUT_ERROR("improve.p must lie in [2, 200] (thesis: > 20), got " << o.p);
  }
  if (imp.contains("samples")) o.samples = integer(imp["samples"], "improve.samples", 16, 20000);
  if (imp.contains("max_seconds")) o.max_seconds = number(imp["max_seconds"], "improve.max_seconds");
  if (imp.contains("global_every")) o.global_every = integer(imp["global_every"], "improve.global_every", 1, 1000);
  if (imp.contains("initial_step")) {
    o.initial_step = number(imp["initial_step"], "improve.initial_step");
    if (!(o.initial_step > 0 && o.initial_step < 1)) PARAFAB_INPUT_ERROR("improve.initial_step must lie in (0, 1), got " << o.initial_step);
  }
  if (imp.contains("fix_length")) {
    if (!imp["fix_length"].is_boolean()) PARAFAB_INPUT_ERROR("improve.fix_length must be true or false");
    o.constraints.fix_length = imp["fix_length"].get<bool>();
  }
  if (imp.contains("fit_poles")) o.fit_poles = integer(imp["fit_poles"], "improve.fit_poles", 6, 1000);

  // The curve: a B-spline as given, or sampled points (sections) through the §4.8.2 fair fit
  // with spurious-inflection removal (improve.fair), not the point interpolation of `strip`.
  const json& curve_j = require(request, "curve", "request");
  json fair_out = nullptr;
  std::vector<Vec2> input_points;  // empty: a B-spline was given
  BSplineCurve2 curve = [&]() -> BSplineCurve2 {
    if (curve_j.is_object() && curve_j.contains("points") && !curve_j.contains("bspline")) {
      input_points = points(curve_j["points"]);
      auto [fitted, report] = fair_points_json(input_points, imp.value("fair", json()), "improve.fair");
      fair_out = std::move(report);
      return std::move(fitted);
    }
    return parse_strip_curve(request);
  }();
  StripStabilityOptions stability_options;  // the result's Jacobi verdict (thesis §4.5)
  const bool stability = parse_stability_options(request, stability_options);
  const StripImproveResult r = improve_strip_fabricability(curve, o);

  json out;
  out["done"] = r.done;
  out["status"] = r.status;
  out["message"] = r.message;
  out["target_R"] = o.target_R;
  out["R_initial"] = num(r.R_initial);
  out["R"] = num(r.R);
  // R_continuous of the result's design: an estimate (sampled extrema refined), not a certified
  // bound. R_upper is the same number under its former, misleading name (deprecated alias).
  out["R_estimate"] = num(r.R_estimate);
  out["R_upper"] = num(r.R_estimate);
  out["bspline"] = bspline_json(r.curve);
  out["original_bspline"] = bspline_json(curve);
  out["max_pole_move"] = r.max_pole_move;
  out["deviation"] = r.deviation;
  out["deviation_relative"] = r.deviation_relative;
  out["length"] = r.design.length;
  out["inflections"] = r.inflections;
  out["refit"] = r.refit;
  out["refit_deviation"] = r.refit_deviation;
  out["fair"] = fair_out;
  // With points input, R_initial, deviation and max_pole_move compare with the fair fit (the
  // descent's start); these compare the result with the points themselves.
  if (!input_points.empty()) {
    const double dp = points_deviation(input_points, r.curve, o.deviation_samples);
    out["points_deviation"] = dp;
    out["points_deviation_relative"] = dp / r.design.length;
    out["fit_points_deviation"] = points_deviation(input_points, curve, o.deviation_samples);
  } else {
    out["points_deviation"] = nullptr;
    out["points_deviation_relative"] = nullptr;
    out["fit_points_deviation"] = nullptr;
  }
  out["seconds"] = r.seconds;
  json hist = json::array();
  for (const auto& h : r.history)
    hist.push_back({{"iteration", h.iteration}, {"R", num(h.R)}, {"R_p", num(h.R_p)}, {"F", num(h.F)},
                    {"step", h.step}, {"max_pole_move", h.max_pole_move}, {"seconds", h.seconds}});
  out["history"] = hist;
  if (has_design) {
    json req = request;
    req.erase("improve");
    // As the improvement's own R (StripImproveOptions::design): tolerance 1e-3 on the estimated
    // gap unless the request sets its own tolerance.
    if (!req.contains("tolerance")) req["tolerance"] = 1e-3;
    if (!req.contains("max_samples")) req["max_samples"] = 4097;
    req["curve"] = {{"bspline", bspline_json(r.curve)}};
    out["design"] = design_strip_json(req);  // gravity, if requested: LP Eq. 4.6 afterwards
    out["R_gravity"] = gravity ? out["design"]["R"] : json(nullptr);
    // done is the requested design's: under gravity its R (null: infeasible) meets the target too
    // (the same rule as improve_strip_fabricability's with StripImproveOptions::design).
    if (gravity && r.done) {
      const json& dj = out["design"];
      const bool feasible = dj.value("feasible", false) && dj["R"].is_number();
      const std::string shortfall = gravity_target_shortfall(
          r.R_estimate, o.target_R, feasible, feasible ? dj["R"].get<double>() : NAN, dj.value("reason", std::string()));
      if (!shortfall.empty()) {
        out["done"] = false;
        out["status"] = "target_without_gravity";
        out["message"] = shortfall;
      }
    }
  } else {
    out["design"] = nullptr;
    out["R_gravity"] = nullptr;
  }
  // The result's stability: the requested design's verdict (under gravity: Eq. 4.6's), else
  // the Jacobi test of the improved curve's Eq. 4.4 design. Null: no feasible design.
  if (!stability) {
    out["stability"] = nullptr;
  } else if (has_design) {
    out["stability"] = out["design"].is_object() ? out["design"].value("stability", json(nullptr)) : json(nullptr);
  } else {
    out["stability"] = r.design.feasible ? stability_to_json(strip_stability(r.curve, r.design, o.design, stability_options),
                                                             r.design.length)
                                         : json(nullptr);
  }
  return out;
}

}  // namespace parafab::entry
