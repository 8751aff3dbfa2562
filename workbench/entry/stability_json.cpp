// Thesis §4.5: JSON for the stability tests of strips. See stability_json.h.
#include "stability_json.h"

#include <cmath>

#include "common/error.h"
#include "request_schema.h"
#include "strip_json.h"

namespace parafab::entry {

using nlohmann::json;

namespace {
json num(double x) { return std::isfinite(x) ? json(x) : json(nullptr); }

int edges_field(const json& v, const std::string& path, int lo, int hi) {
  if (!v.is_number_integer() || v.get<long long>() < lo || v.get<long long>() > hi)
    PARAFAB_INPUT_ERROR(path << " must be an integer " << lo << ".." << hi << ", got " << v.dump());
  return v.get<int>();
}
}  // namespace

bool parse_stability_options(const json& request, StripStabilityOptions& o) {
  if (!request.contains("stability")) return true;
  const json& v = request["stability"];
  if (v.is_boolean()) return v.get<bool>();
  if (!v.is_object())
    PARAFAB_INPUT_ERROR("stability must be true, false or {\"edges\", \"eigenvalue_check\", \"simulation_edges\"}, got "
                        << v.dump());
  for (auto it = v.begin(); it != v.end(); ++it)
    if (it.key() != "edges" && it.key() != "eigenvalue_check" && it.key() != "simulation_edges")
      PARAFAB_INPUT_ERROR("stability." << it.key()
                                       << " is not a known field (expected edges, eigenvalue_check, simulation_edges)");
  if (v.contains("edges")) o.edges = edges_field(v["edges"], "stability.edges", 8, 1000000);
  if (v.contains("simulation_edges"))
    o.simulation.edges = edges_field(v["simulation_edges"], "stability.simulation_edges", 8, 4000);
  if (v.contains("eigenvalue_check")) {
    if (!v["eigenvalue_check"].is_boolean())
      PARAFAB_INPUT_ERROR("stability.eigenvalue_check must be true or false, got " << v["eigenvalue_check"].dump());
    o.eigenvalue_check = v["eigenvalue_check"].get<bool>();
  }
  return true;
}

json stability_to_json(const StripStability& s, double length) {
  const JacobiResult& j = s.jacobi;
  json out = {{"stable", s.stable},
              {"sigma", num(s.sigma)},
              {"sigma_relative", num(s.sigma / length)},
              {"method", s.method},
              {"constraints", j.constraints},
              {"legendre", j.legendre},
              {"Z_end", num(j.Z_end)},
              {"min_Z", num(j.min_Z)},
              {"s", j.s},
              {"Z", j.Z},
              {"edges", static_cast<int>(j.Z_raw.size()) - 1},
              {"seconds", s.jacobi_seconds},
              {"message", s.message}};
  if (s.checked) {
    json e = {{"method", s.inertia.method},
              {"converged", s.simulation_converged},
              {"edges", s.simulation_converged ? json(s.inertia.negative + s.inertia.zero + s.inertia.positive +
                                                      s.inertia.constraint_rank)
                                               : json(nullptr)},
              {"simulation_seconds", s.simulation_seconds},
              {"seconds", s.eigen_seconds}};
    if (s.simulation_converged) {
      e["stable"] = s.inertia.stable;
      e["negative"] = s.inertia.negative;
      e["zero"] = s.inertia.zero;
      e["positive"] = s.inertia.positive;
      e["constraint_rank"] = s.inertia.constraint_rank;
      e["min_eigenvalue"] = num(s.inertia.min_eigenvalue);
      e["jacobi_on_simulation"] = {{"stable", s.jacobi_on_simulation.stable},
                                   {"sigma", num(s.jacobi_on_simulation.sigma)},
                                   {"seconds", s.jacobi_on_simulation.seconds}};
    } else {
      e["stable"] = nullptr;
    }
    out["eigenvalue"] = e;
    out["agree"] = s.simulation_converged ? json(s.agree) : json(nullptr);
  }
  return out;
}

json strip_stability_json(const json& request) {
  schema::check(request, schema::Format::Strip);
  json req = request;
  json st = req.contains("stability") ? req["stability"] : json::object();
  if (st.is_boolean()) {
    if (!st.get<bool>()) PARAFAB_INPUT_ERROR("stability must not be false for strip-stability");
    st = json::object();
  }
  if (!st.is_object()) PARAFAB_INPUT_ERROR("stability must be an object, got " << st.dump());
  if (!st.contains("eigenvalue_check")) st["eigenvalue_check"] = true;
  req["stability"] = st;
  const json full = design_strip_json(req);
  json out;
  for (const char* key : {"name", "feasible", "reason", "reason_code", "where", "length", "R", "inflections",
                          "line", "general_lp", "gravity", "ends", "stability", "units"})
    if (full.contains(key)) out[key] = full[key];
  if (!out.contains("stability")) out["stability"] = nullptr;
  return out;
}

}  // namespace parafab::entry
