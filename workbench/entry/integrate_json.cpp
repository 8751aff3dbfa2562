#include "integrate_json.h"

#include "common/error.h"
#include "grid_estimate.h"
#include "json_write.h"
#include "local_frame.h"

namespace parafab::entry {

using nlohmann::json;

namespace {
json vec(const Eigen::Vector3d& v) { return json_write::coordinates(v); }
// Inertia about the centre: the same in both frames; the centre shifted back by `origin`.
json properties(const xfem::MassProperties& p, const Eigen::Vector3d& origin) {
  json I = json::array();
  for (int i = 0; i < 3; ++i) I.push_back(json::array({p.inertia(i, 0), p.inertia(i, 1), p.inertia(i, 2)}));
  return {{"volume", p.volume}, {"center", vec(p.center + origin)}, {"inertia", I}};
}
}  // namespace

json integrate_part_json(const std::string& path, const IntegrateOptions& options) {
  const auto part = occ::read_part(path, options.read);
  const occ::PartInfo info = occ::part_info(*part);
  const GridEstimate estimate = estimate_grid(info, options.integration.grid);
  json part_json = {{"source", info.source}, {"name", info.name}, {"faces", info.face_count},
                    {"bbox", {vec(info.bbox_min), vec(info.bbox_max)}}};
  if (options.estimate_only) return {{"part", part_json}, {"estimate", to_json(estimate)}};
  if (!options.force)
    refuse_if_too_big(estimate, "this grid",
                      "use fewer cells (--cells) or a larger --cell-size, or --force (Python: force=True) to run anyway");
  // Cut and integrated in the local frame (local_frame.h); the grid anchor moves into it, the
  // grid box and the centres move back.
  const Eigen::Vector3d origin = local_frame_origin(info.bbox_min, info.bbox_max);
  const bool moved = !origin.isZero(0);
  occ::IntegrationOptions io = options.integration;
  if (io.grid.anchored) io.grid.origin -= origin;
  const auto local = moved ? occ::translated_part(*part, -origin) : part;
  const occ::IntegrationResult r = occ::integrate_part(*local, io);
  if (!r.done) PARAFAB_INPUT_ERROR("cannot cut " << path << " by the grid: " << r.message);
  const occ::GridCut& g = r.cut;
  json out;
  out["part"] = part_json;
  out["estimate"] = to_json(estimate);
  out["grid"] = {{"cells", g.cells},
                 {"cell_size", g.cell_size.x()},
                 {"box", {vec(g.grid.min + origin), vec(g.grid.max + origin)}},
                 {"frame_origin", vec(origin)},
                 {"shifted_planes", g.shifted_planes},
                 {"cut_cells", g.cut_cells.size()},
                 {"subvolumes", g.subvolumes.size()},
                 {"interior_cells", g.interior_cells.size()},
                 {"connections", g.connections.size()},
                 {"patches", g.patches},
                 {"curves", g.curves.size()},
                 {"curve_segments", g.segments},
                 {"segment_order", options.integration.grid.segment_order},
                 {"method", g.method == occ::CutMethod::FaceCut ? "face" : "splitter"},
                 {"retry_reason", g.retry_reason}, {"grid_shift", vec(g.grid_shift)}};
  out["rules"] = properties(r.by_rules, origin);
  if (options.integration.occt_reference) {
    out["occt"] = properties(r.by_occt, origin);
    out["relative_errors"] = {{"volume", r.errors.volume},
                              {"center", r.errors.center},
                              {"inertia", r.errors.inertia},
                              {"note", "center error relative to the grid diagonal"}};
  }
  out["diagnostics"] = {{"rule_points", r.rule_points},
                        {"rules_not_ok", r.rules_not_ok},
                        {"rules_refinement_capped", r.rules_refinement_capped},
                        {"max_moment_residual", r.max_moment_residual},
                        {"max_closure_defect", r.max_closure_defect}};
  out["seconds"] = {{"cut", r.cut_seconds},
                    {"split", g.split_seconds},
                    {"extract", g.extract_seconds},
                    {"rules", r.rule_seconds},
                    {"occt", r.occt_seconds}};
  return out;
}

}  // namespace parafab::entry
