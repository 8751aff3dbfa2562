#include "strip_stabilize_json.h"

#include <cmath>

#include "common/error.h"
#include "request_schema.h"
#include "json_fields.h"
#include "strip_improve_json.h"
#include "strip_json.h"
#include "strips/strip_stabilize.h"

namespace parafab::entry {

using nlohmann::json;
using fields::integer;
using fields::only;
using fields::number;

namespace {
json num(double x) { return std::isfinite(x) ? json(x) : json(nullptr); }
}  // namespace

json stabilize_strip_json(const json& request, double R_max) {
  schema::check(request, schema::Format::StripStabilize);
  // Algorithm 4.2 rests on Theorem 1 (no gravity, clamped ends, linear law, κ₀ = 0).
  for (const char* k : {"gravity", "boundary", "natural_curvature"})
    if (request.contains(k))
      PARAFAB_INPUT_ERROR(k << ": stability recovery (thesis §4.5.4) assumes clamped ends without gravity and "
                            "natural curvature (Theorem 1); remove \"" << k << "\" from the request");
  if (request.contains("material") && request["material"].is_object() && request["material"].contains("law"))
    PARAFAB_INPUT_ERROR("material.law: stability recovery (thesis §4.5.4) assumes the linear moment law");
  StripStabilizeOptions o;
  const json st = request.value("stabilize", json::object());
  only(st, "stabilize", {"R_max", "margin", "max_iterations", "edges", "verify_edges", "p", "samples",
                         "initial_step", "max_seconds", "fit_poles", "fix_length"});
  if (st.contains("R_max")) o.R_max = st["R_max"].is_null() ? INFINITY : number(st["R_max"], "stabilize.R_max");
  if (R_max > 0) o.R_max = R_max;
  if (!(o.R_max >= 1)) PARAFAB_INPUT_ERROR("stabilize.R_max (--R-max) must be >= 1 (null: no bound), got " << o.R_max);
  if (st.contains("margin")) {
    o.margin = number(st["margin"], "stabilize.margin");
    if (!(o.margin >= 0 && o.margin < 10)) PARAFAB_INPUT_ERROR("stabilize.margin must lie in [0, 10), got " << o.margin);
  }
  if (st.contains("max_iterations")) o.max_iterations = integer(st["max_iterations"], "stabilize.max_iterations", 0, 100000);
  if (st.contains("edges")) o.edges = integer(st["edges"], "stabilize.edges", 16, 20000);
  if (st.contains("verify_edges")) o.verify_edges = integer(st["verify_edges"], "stabilize.verify_edges", 16, 20000);
  if (st.contains("p")) {
    o.p = number(st["p"], "stabilize.p");
    if (!(o.p >= 2 && o.p <= 200)) PARAFAB_INPUT_ERROR("stabilize.p must lie in [2, 200] (thesis: > 20), got " << o.p);
  }
  if (st.contains("samples")) o.samples = integer(st["samples"], "stabilize.samples", 16, 20000);
  if (st.contains("initial_step")) {
    o.initial_step = number(st["initial_step"], "stabilize.initial_step");
    if (!(o.initial_step > 0 && o.initial_step < 1))
      PARAFAB_INPUT_ERROR("stabilize.initial_step must lie in (0, 1), got " << o.initial_step);
    o.max_step = std::max(o.max_step, o.initial_step);
  }
  if (st.contains("max_seconds")) o.max_seconds = number(st["max_seconds"], "stabilize.max_seconds");
  if (st.contains("fit_poles")) o.fit_poles = integer(st["fit_poles"], "stabilize.fit_poles", 6, 1000);
  if (st.contains("fix_length")) {
    if (!st["fix_length"].is_boolean()) PARAFAB_INPUT_ERROR("stabilize.fix_length must be true or false");
    o.constraints.fix_length = st["fix_length"].get<bool>();
  }
  const BSplineCurve2 curve = parse_strip_curve(request);
  const bool has_design = request.contains("material") && request.contains("min_width");
  const StripStabilizeResult r = stabilize_strip(curve, o);

  json out;
  out["done"] = r.done;
  out["status"] = r.status;
  out["message"] = r.message;
  out["R_max"] = num(o.R_max);
  out["margin"] = o.margin;
  out["stable_before"] = r.stable_before;
  out["stable_after"] = r.stable_after;
  out["stable_margin_after"] = r.stable_margin_after;
  out["sigma_before"] = num(r.sigma_before);
  out["sigma_after"] = num(r.sigma_after);
  out["sigma_margin_before"] = num(r.sigma_margin_before);
  out["sigma_margin_after"] = num(r.sigma_margin_after);
  out["length"] = r.length;
  out["R_before"] = num(r.R_before);
  out["R_after"] = num(r.R_after);
  out["bspline"] = bspline_json(r.curve);
  out["original_bspline"] = bspline_json(r.original);
  out["max_pole_move"] = r.max_pole_move;
  out["deviation"] = r.deviation;
  out["deviation_relative"] = r.deviation_relative;
  out["min_inflection_dkappa"] = num(r.min_inflection_dkappa);
  out["inflections"] = r.inflections;
  out["refit"] = r.refit;
  out["refit_deviation"] = r.refit_deviation;
  out["rejected_steps"] = r.rejected_steps;
  out["bound_returns"] = r.bound_returns;
  out["seconds"] = r.seconds;
  json hist = json::array();
  for (const auto& h : r.history)
    hist.push_back({{"iteration", h.iteration}, {"sigma", num(h.sigma)}, {"sigma_margin", num(h.sigma_margin)},
                    {"R", num(h.R)}, {"R_p", num(h.R_p)}, {"step", h.step}, {"max_pole_move", h.max_pole_move},
                    {"min_inflection_dkappa", num(h.min_inflection_dkappa)}, {"seconds", h.seconds}});
  out["history"] = hist;
  if (has_design && r.design.feasible) {
    json req = request;
    req.erase("stabilize");
    if (!req.contains("tolerance")) req["tolerance"] = 1e-3;
    if (!req.contains("max_samples")) req["max_samples"] = 4097;
    req["curve"] = {{"bspline", bspline_json(r.curve)}};
    out["design"] = design_strip_json(req);
  } else {
    out["design"] = nullptr;
  }
  return out;
}

}  // namespace parafab::entry
