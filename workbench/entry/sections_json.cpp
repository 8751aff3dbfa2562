#include "sections_json.h"

#include <sstream>
#include <tbb/parallel_for.h>

#include "common/error.h"
#include "request_schema.h"
#include "json_fields.h"
#include "part_reader.h"
#include "plane_sections.h"
#include "strip_improve_json.h"
#include "strip_json.h"
#include "json_write.h"

namespace parafab::entry {

using nlohmann::json;

namespace {

Eigen::Vector3d vec3_field(const json& v, const std::string& path) { return fields::vec3(v, path); }

json vec(const Eigen::Vector3d& v) { return json_write::coordinates(v); }

}  // namespace

json strip_sections_json(const std::string& part_path, const json& job) {
  schema::check(job, schema::Format::Sections);
  occ::ReadOptions ro;
  ro.surfaces_allowed = true;
  const auto shape = occ::read_part(part_path, ro);

  occ::PlaneSectionOptions o;
  const json planes = job.value("planes", json::object());
  if (!planes.is_object()) PARAFAB_INPUT_ERROR("planes must be {\"normal\": [x,y,z], \"offsets\": [...] | \"count\": n}");
  if (planes.contains("normal")) o.normal = vec3_field(planes["normal"], "planes.normal");
  if (o.normal.norm() == 0) PARAFAB_INPUT_ERROR("planes.normal must not be zero");
  if (planes.contains("offsets")) {
    if (!planes["offsets"].is_array() || planes["offsets"].empty())
      PARAFAB_INPUT_ERROR("planes.offsets must be a non-empty list of numbers");
    for (size_t i = 0; i < planes["offsets"].size(); ++i) {
      if (!planes["offsets"][i].is_number()) PARAFAB_INPUT_ERROR("planes.offsets[" << i << "] must be a number");
      o.offsets.push_back(planes["offsets"][i].get<double>());
    }
  }
  if (planes.contains("count")) {
    if (!planes["count"].is_number_integer() || planes["count"].get<int>() < 1)
      PARAFAB_INPUT_ERROR("planes.count must be a positive integer, got " << planes["count"].dump());
    o.count = planes["count"].get<int>();
  }
  if (job.contains("split")) {
    const json& sp = job["split"];
    if (!sp.is_object() || !sp.contains("normal") || !sp.contains("offset") || !sp["offset"].is_number())
      PARAFAB_INPUT_ERROR("split must be {\"normal\": [x,y,z], \"offset\": d}");
    o.split = true;
    o.split_normal = vec3_field(sp["normal"], "split.normal");
    if (o.split_normal.norm() == 0) PARAFAB_INPUT_ERROR("split.normal must not be zero");
    o.split_offset = sp["offset"].get<double>();
  }
  const json samples = job.value("samples", json(60));
  if (!samples.is_number_integer() || samples.get<int>() < 8 || samples.get<int>() > 100000)
    PARAFAB_INPUT_ERROR("samples must be an integer in [8, 100000], got " << samples.dump());
  o.samples = samples.get<int>();
  // The part's length unit in metres (the strip solver works in SI).
  const std::string units = job.value("units", std::string("mm"));
  double scale = 0;
  if (units == "mm") scale = 1e-3;
  else if (units == "cm") scale = 1e-2;
  else if (units == "m") scale = 1.0;
  else PARAFAB_INPUT_ERROR("units must be \"mm\", \"cm\" or \"m\", got \"" << units << "\"");
  const json strip = job.value("strip", json::object());
  if (!strip.is_object()) PARAFAB_INPUT_ERROR("strip must be a strip request without \"curve\" (see resources/doc/strips.md, \"Strips from sections\")");
  if (strip.contains("curve")) PARAFAB_INPUT_ERROR("strip.curve is set by the sections; remove it");

  // §4.8.2 fairing of the section points ("fair"): "auto" (default) designs from the quartic
  // interpolation of the points and, when that design is infeasible (noisy points give spurious
  // inflections), again from a fair B-spline fit with spurious inflections removed; true always
  // fits; an object always fits with those options (strip-improve's improve.fair); false never.
  const json fair = job.value("fair", json("auto"));
  if (!(fair.is_boolean() || fair.is_object() || fair == json("auto")))
    PARAFAB_INPUT_ERROR("fair must be \"auto\", true, false or {\"poles\", \"fairness\", "
                        "\"min_separation\", \"end_separation\"}, got " << fair.dump());
  if (fair.is_object()) check_fair_options(fair, "fair");
  const bool fair_auto = fair.is_string();
  const bool fair_always = fair.is_object() || (fair.is_boolean() && fair.get<bool>());
  const occ::PlaneSectionResult sections = occ::plane_sections(*shape, o);
  if (!sections.done) PARAFAB_INPUT_ERROR("cannot take sections of " << part_path << ": " << sections.message);
  json curves = json::array();
  int designed = 0, infeasible = 0, failed = 0;
  // The strips of the sections are independent: designed on TBB workers, collected in order
  // (each design is the same as alone).
  const size_t count = sections.curves.size();
  std::vector<json> designs(count), fair_reports(count, json(nullptr));
  std::vector<int> outcome(count, 0);  // 1 designed, 2 infeasible, 3 failed
  tbb::parallel_for(size_t(0), count, [&](size_t k) {
    const occ::SectionCurve& c = sections.curves[k];
    if (c.closed) {
      designs[k] = error_json("closed section curve: a strip needs two ends; split it (job \"split\")", "closed_curve");
      outcome[k] = 3;
      return;
    }
    json& design = designs[k];
    json& fair_report = fair_reports[k];
    json request = strip;
    auto fair_fit = [&]() {
      std::vector<Vec2> P;
      for (const auto& x : c.points2d) P.emplace_back(x.x() * scale, x.y() * scale);
      return fair_points_json(P, fair.is_object() ? fair : json(), "fair");
    };
    auto design_fit = [&](std::pair<BSplineCurve2, json> fit, const std::string& why) {
      fit.second["why"] = why;
      request["curve"] = {{"bspline", bspline_json(fit.first)}};
      fair_report = std::move(fit.second);
      return design_strip_json(request);
    };
    auto fair_design = [&](const std::string& why) { return design_fit(fair_fit(), why); };
    try {
      if (fair_always) {
        design = fair_design("requested");
      } else {
        json pts2 = json::array();
        for (const auto& x : c.points2d) pts2.push_back({x.x() * scale, x.y() * scale});
        request["curve"] = {{"points", pts2}, {"degree", 4}};
        if (!fair_auto) {
          design = design_strip_json(request);
        } else {
          std::string why;
          try {
            design = design_strip_json(request);
            if (!design.value("feasible", false)) {
              const json& r = design.contains("reason") ? design["reason"] : json();
              why = "the interpolated curve is infeasible: " + (r.is_string() ? r.get<std::string>() : "no reason");
            } else {
              // Feasible, but possibly on spurious inflections of the noise (a few noisy points
              // can give two inflections whose line the curve never crosses, and R in the
              // hundreds): the fair fit decides; fewer inflections there means they were spurious.
              size_t n_interp = 0;  // sign changes of κ (end zeros and touches are no inflections)
              for (const json& z : design.value("inflections", json::array()))
                n_interp += z.value("kind", std::string()) == "inflection";
              if (n_interp > 0) {
                auto fit = fair_fit();
                const int n_fair = fit.second.value("inflections", static_cast<int>(n_interp));
                if (n_fair < static_cast<int>(n_interp)) {
                  std::ostringstream w;
                  w << "the interpolated curve has " << n_interp << " inflection(s), the fair fit " << n_fair
                    << ": spurious inflections removed (§4.8.2)";
                  json plain = std::move(design);
                  design = design_fit(std::move(fit), w.str());
                  if (!design.value("feasible", false)) {  // the fit fails: keep the feasible interpolation
                    fair_report["kept"] = "interpolation";
                    design = std::move(plain);
                  }
                }
              }
            }
          } catch (const parafab::Error& e) {
            design = error_json(e.what(), "invalid_input");
            why = std::string("the interpolated curve was refused: ") + e.what();
          }
          if (!why.empty()) {
            json plain = std::move(design);
            design = fair_design(why);
            if (!design.value("feasible", false)) {  // neither works: report the plain design
              fair_report["kept"] = "interpolation";
              design = std::move(plain);
              if (design.contains("error")) throw Error(design["error"]["message"].get<std::string>());
            }
          }
        }
      }
      outcome[k] = design.value("feasible", false) ? 1 : 2;
    } catch (const parafab::Error& e) {
      design = error_json(e.what(), "invalid_input");
      outcome[k] = 3;
    }
  });
  for (size_t k = 0; k < count; ++k) {
    const occ::SectionCurve& c = sections.curves[k];
    json pts = json::array();
    for (const auto& X : c.points) pts.push_back(vec(X));
    designed += outcome[k] == 1, infeasible += outcome[k] == 2, failed += outcome[k] == 3;
    curves.push_back({{"plane", c.plane}, {"offset", c.offset}, {"piece", c.piece}, {"closed", c.closed},
                      {"length", c.length * scale},
                      {"frame", {{"origin", vec(c.origin)}, {"u", vec(c.u_axis)}, {"v", vec(c.v_axis)}}},
                      {"points", pts}, {"fair", std::move(fair_reports[k])}, {"strip", std::move(designs[k])}});
  }
  return {{"part", part_path},
          {"offsets", sections.offsets},
          {"empty_planes", sections.empty_planes},
          {"units", units},
          {"curves", curves},
          {"designed", designed},
          {"infeasible", infeasible},
          {"failed", failed}};
}

}  // namespace parafab::entry
