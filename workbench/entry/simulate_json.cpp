#include "simulate_json.h"

#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/global_control.h>
#include <tbb/parallel_for.h>

#include <Eigen/Dense>
#include <filesystem>
#include <functional>
#include <map>
#include <algorithm>
#include <cmath>
#include <limits>
#include <chrono>
#include <fstream>
#include <optional>
#include <charconv>
#include <unordered_map>

#include "common/bit_hash.h"
#include "common/error.h"
#include "output_files.h"
#include "request_schema.h"
#include "simulation_job.h"
#include "json_fields.h"
#include "cut_cell_classifier.h"
#include "face_lookup.h"
#include "grid_estimate.h"
#include "grid_model.h"
#include "local_frame.h"
#include "part_reader.h"
#include "surface_mesh.h"
#include "xfem/mass_properties.h"
#include "xfem/nonlinear_xfem.h"
#include "xfem/sparse_cholesky.h"

namespace parafab::entry {

using nlohmann::json;
using xfem::Vec3;

namespace {

// "ok" only for a result to trust: "not_finite" (a displacement or stress that is not a number),
// "indefinite" (the linear stiffness was not positive definite: solved by LU, see message),
// "rule_failures" (some cut-cell rules failed: rule_failures lists them).
const char* result_status(bool rules_ok, bool indefinite, bool finite) {
  if (!finite) return "not_finite";
  if (indefinite) return "indefinite";
  return rules_ok ? "ok" : "rule_failures";
}

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

using fields::number;
using fields::vec3;


using StressFn = std::function<Eigen::Matrix<double, 6, 1>(int, const Vec3&)>;

// Text as a default std::ostream prints it (doubles as printf's %.6g, integers in decimal),
// through std::to_chars: several times faster than a stream.
struct Text {
  std::string s;
  Text& operator<<(double v) {
    char b[40];
    s.append(b, std::to_chars(b, b + sizeof b, v, std::chars_format::general, 6).ptr);
    return *this;
  }
  /// `v` with `digits` significant digits.
  Text& put(double v, int digits) {
    char b[40];
    s.append(b, std::to_chars(b, b + sizeof b, v, std::chars_format::general, digits).ptr);
    return *this;
  }
  Text& operator<<(int v) {
    char b[16];
    s.append(b, std::to_chars(b, b + sizeof b, v).ptr);
    return *this;
  }
  Text& operator<<(char c) {
    s.push_back(c);
    return *this;
  }
};

// Significant digits that resolve 1e-6 of the part's extent at coordinates as large as those of
// `points` moved by `origin`: 6 (printf's default, what every file had) for a part near the
// origin, up to 17 for one far from it (issue 56: at 1e7 mm, 6 digits would be 10 mm).
int point_digits(const std::vector<Vec3>& points, const Vec3& origin) {
  if (origin.isZero(0) || points.empty()) return 6;
  Vec3 lo = points[0], hi = points[0];
  for (const Vec3& p : points) lo = lo.cwiseMin(p), hi = hi.cwiseMax(p);
  const double extent = (hi - lo).maxCoeff();
  const double largest = std::max((lo + origin).cwiseAbs().maxCoeff(), (hi + origin).cwiseAbs().maxCoeff());
  if (!(extent > 0)) return 17;
  return std::clamp(6 + static_cast<int>(std::ceil(std::log10(std::max(1.0, largest / extent)))), 6, 17);
}

// Lines for items [0, n), formatted by line(i, text) in parallel chunks (TBB) and written in
// order: the same bytes for every thread count.
template <class Line>
void write_lines(std::ostream& f, size_t n, const Line& line) {
  const size_t chunk = 8192, chunks = (n + chunk - 1) / chunk;
  std::vector<Text> text(chunks);
  tbb::parallel_for(size_t(0), chunks, [&](size_t c) {
    for (size_t i = c * chunk; i < std::min(n, (c + 1) * chunk); ++i) line(i, text[c]);
  });
  for (const auto& t : text) f << t.s;
}

void write_vtu(const std::string& path, const std::vector<xfem::GridElement>& elements,
               const xfem::LinearXfemResult& r, const StressFn& stress, const Vec3& origin) {
  // Uncut cells as hexahedra; cut subvolumes as their quadrature points (VTK_VERTEX), each
  // with displacement and von Mises stress.
  std::vector<Vec3> pts;
  std::vector<int> owner;  // element of every point
  std::vector<std::array<int, 8>> hexes;
  std::vector<int> vertices;
  static const int vtk_order[8] = {0, 1, 3, 2, 4, 5, 7, 6};
  for (size_t e = 0; e < elements.size(); ++e) {
    const auto& el = elements[e];
    if (!el.subvolume) {
      std::array<int, 8> h{};
      for (int k = 0; k < 8; ++k) {
        h[k] = static_cast<int>(pts.size());
        pts.push_back(xfem::corner(el.box, vtk_order[k]));
        owner.push_back(static_cast<int>(e));
      }
      hexes.push_back(h);
    } else {
      for (const Vec3& X : el.rule.points) {
        vertices.push_back(static_cast<int>(pts.size()));
        pts.push_back(X);
        owner.push_back(static_cast<int>(e));
      }
    }
  }
  std::vector<Vec3> disp(pts.size());
  std::vector<double> vm(pts.size());
  tbb::parallel_for(tbb::blocked_range<size_t>(0, pts.size(), 1024), [&](const tbb::blocked_range<size_t>& b) {
    for (size_t i = b.begin(); i != b.end(); ++i) {
      disp[i] = r.displacement(elements, owner[i], pts[i]);
      vm[i] = xfem::von_mises(stress(owner[i], pts[i]));
    }
  });
  AtomicFile file(path);  // never a half-written result under the final name
  std::ofstream f(file.temporary());
  if (!f) PARAFAB_INPUT_ERROR("cannot write " << path);
  const size_t ncells = hexes.size() + vertices.size();
  f << "<?xml version=\"1.0\"?>\n<VTKFile type=\"UnstructuredGrid\" version=\"0.1\" byte_order=\"LittleEndian\">\n"
    << "<UnstructuredGrid><Piece NumberOfPoints=\"" << pts.size() << "\" NumberOfCells=\"" << ncells << "\">\n"
    << "<PointData Vectors=\"displacement\" Scalars=\"von_mises\">\n"
    << "<DataArray type=\"Float64\" Name=\"displacement\" NumberOfComponents=\"3\" format=\"ascii\">\n";
  write_lines(f, disp.size(), [&](size_t i, Text& os) { os << disp[i].x() << ' ' << disp[i].y() << ' ' << disp[i].z() << '\n'; });
  f << "</DataArray>\n<DataArray type=\"Float64\" Name=\"von_mises\" format=\"ascii\">\n";
  write_lines(f, vm.size(), [&](size_t i, Text& os) { os << vm[i] << '\n'; });
  f << "</DataArray>\n</PointData>\n<Points><DataArray type=\"Float64\" NumberOfComponents=\"3\" format=\"ascii\">\n";
  const int digits = point_digits(pts, origin);
  write_lines(f, pts.size(), [&](size_t i, Text& os) {
    const Vec3 X = pts[i] + origin;  // in the part's frame
    os.put(X.x(), digits) << ' ';
    os.put(X.y(), digits) << ' ';
    os.put(X.z(), digits) << '\n';
  });
  f << "</DataArray></Points>\n<Cells>\n<DataArray type=\"Int32\" Name=\"connectivity\" format=\"ascii\">\n";
  write_lines(f, hexes.size(), [&](size_t i, Text& os) {
    for (int k : hexes[i]) os << k << ' ';
    os << '\n';
  });
  write_lines(f, vertices.size(), [&](size_t i, Text& os) { os << vertices[i] << '\n'; });
  f << "</DataArray>\n<DataArray type=\"Int32\" Name=\"offsets\" format=\"ascii\">\n";
  const int hex_end = 8 * static_cast<int>(hexes.size());
  write_lines(f, hexes.size(), [&](size_t i, Text& os) { os << 8 * (static_cast<int>(i) + 1) << '\n'; });
  write_lines(f, vertices.size(), [&](size_t i, Text& os) { os << hex_end + static_cast<int>(i) + 1 << '\n'; });
  f << "</DataArray>\n<DataArray type=\"UInt8\" Name=\"types\" format=\"ascii\">\n";
  for (size_t i = 0; i < hexes.size(); ++i) f << "12\n";
  for (size_t i = 0; i < vertices.size(); ++i) f << "1\n";
  f << "</DataArray>\n</Cells>\n</Piece></UnstructuredGrid>\n</VTKFile>\n";
  f.close();
  PARAFAB_VERIFY(f, "cannot write " << path);
  file.commit();
}


// The part's B-rep faces triangulated, each vertex with its displacement and von Mises stress
// (what FreeCAD shows as the deformed, coloured part; ParaView reads it as well).
void write_surface_vtu(const std::string& path, const occ::SurfaceMesh& mesh, const std::vector<Vec3>& disp,
                       const std::vector<double>& vm, const Vec3& origin) {
  AtomicFile file(path);  // never a half-written result under the final name
  std::ofstream f(file.temporary());
  if (!f) PARAFAB_INPUT_ERROR("cannot write " << path);
  f << "<?xml version=\"1.0\"?>\n<VTKFile type=\"UnstructuredGrid\" version=\"0.1\" byte_order=\"LittleEndian\">\n"
    << "<UnstructuredGrid><Piece NumberOfPoints=\"" << mesh.points.size() << "\" NumberOfCells=\""
    << mesh.triangles.size() << "\">\n<PointData Vectors=\"displacement\" Scalars=\"von_mises\">\n"
    << "<DataArray type=\"Float64\" Name=\"displacement\" NumberOfComponents=\"3\" format=\"ascii\">\n";
  write_lines(f, disp.size(), [&](size_t i, Text& os) { os << disp[i].x() << ' ' << disp[i].y() << ' ' << disp[i].z() << '\n'; });
  f << "</DataArray>\n<DataArray type=\"Float64\" Name=\"von_mises\" format=\"ascii\">\n";
  write_lines(f, vm.size(), [&](size_t i, Text& os) { os << vm[i] << '\n'; });
  // The same fields under the names FreeCAD FEM's reader maps to a mechanical result object
  // (Fem.readResult: "Displacement" -> DisplacementVectors, "von Mises Stress" -> vonMises).
  f << "</DataArray>\n<DataArray type=\"Float64\" Name=\"Displacement\" NumberOfComponents=\"3\" format=\"ascii\">\n";
  write_lines(f, disp.size(), [&](size_t i, Text& os) { os << disp[i].x() << ' ' << disp[i].y() << ' ' << disp[i].z() << '\n'; });
  f << "</DataArray>\n<DataArray type=\"Float64\" Name=\"von Mises Stress\" format=\"ascii\">\n";
  write_lines(f, vm.size(), [&](size_t i, Text& os) { os << vm[i] << '\n'; });
  f << "</DataArray>\n</PointData>\n<CellData Scalars=\"face\">\n<DataArray type=\"Int32\" Name=\"face\" format=\"ascii\">\n";
  for (int fi : mesh.triangle_face) f << fi << '\n';
  f << "</DataArray>\n</CellData>\n<Points><DataArray type=\"Float64\" NumberOfComponents=\"3\" format=\"ascii\">\n";
  const int digits = point_digits(mesh.points, origin);
  write_lines(f, mesh.points.size(), [&](size_t i, Text& os) {
    const Vec3 X = mesh.points[i] + origin;  // in the part's frame
    os.put(X.x(), digits) << ' ';
    os.put(X.y(), digits) << ' ';
    os.put(X.z(), digits) << '\n';
  });
  f << "</DataArray></Points>\n<Cells>\n<DataArray type=\"Int32\" Name=\"connectivity\" format=\"ascii\">\n";
  write_lines(f, mesh.triangles.size(), [&](size_t i, Text& os) {
    os << mesh.triangles[i][0] << ' ' << mesh.triangles[i][1] << ' ' << mesh.triangles[i][2] << '\n';
  });
  f << "</DataArray>\n<DataArray type=\"Int32\" Name=\"offsets\" format=\"ascii\">\n";
  for (size_t i = 0; i < mesh.triangles.size(); ++i) f << 3 * (i + 1) << '\n';
  f << "</DataArray>\n<DataArray type=\"UInt8\" Name=\"types\" format=\"ascii\">\n";
  for (size_t i = 0; i < mesh.triangles.size(); ++i) f << "5\n";
  f << "</DataArray>\n</Cells>\n</Piece></UnstructuredGrid>\n</VTKFile>\n";
  f.close();
  PARAFAB_VERIFY(f, "cannot write " << path);
  file.commit();
}

}  // namespace

// Everything of the job that depends on the part (faces named by point are looked up again
// when the part changes), and the run's size estimated from it.
struct SimulationSession::Setup {
  SimulationJob job;
  Vec3 extent{0, 0, 0};
  occ::PartInfo info;  ///< box and area (occ::part_box_and_area), what estimate_grid reads
  JobSize size;        ///< of the current grid (set_estimate)
  void set_estimate() { size = estimate_job_size(info, job.grid.options.grid, job.solver); }
};

// The in/out verdicts of the candidate points of cut elements (8 cell corners, then the rule
// points), kept from run to run of a session. A cut cell is known by its index and a hash of
// the rules of all its subvolumes (moment-fitted to their geometry, copied unchanged when a
// re-cut keeps the cell): a cell whose hash is unchanged holds the same material, so a point's
// verdict still holds. Entries of cells no longer in the model are dropped at every run.
struct SimulationSession::InsideCache {
  struct Key {
    std::array<int, 3> cell;
    uint64_t h1, h2;  ///< BitHash of the boxes and rules of all the cell's elements
    int ordinal;      ///< the element's place among the cell's elements
    bool operator==(const Key& o) const { return cell == o.cell && h1 == o.h1 && h2 == o.h2 && ordinal == o.ordinal; }
  };
  struct KeyHash {
    size_t operator()(const Key& k) const { return static_cast<size_t>(k.h1 ^ (k.h2 << 1) ^ (uint64_t(k.ordinal) << 48)); }
  };
  /// Per point: −1 not classified yet, 0 outside, 1 inside.
  std::unordered_map<Key, std::vector<signed char>, KeyHash> verdicts;

  /// Per element of the model its verdict vector (null for uncut elements), carried over from
  /// the last run where the cell is unchanged, fresh (all −1) otherwise.
  std::vector<std::vector<signed char>*> bind(const std::vector<xfem::GridElement>& elements) {
    std::map<std::array<int, 3>, std::vector<size_t>> cells;  // cut elements by cell, in model order
    for (size_t e = 0; e < elements.size(); ++e)
      if (elements[e].subvolume) cells[elements[e].cell].push_back(e);
    std::unordered_map<Key, std::vector<signed char>, KeyHash> next;
    std::vector<std::vector<signed char>*> of(elements.size(), nullptr);
    for (const auto& [cell, members] : cells) {
      BitHash h;
      for (size_t e : members) {
        const auto& rule = elements[e].rule;
        h.add(elements[e].box.min), h.add(elements[e].box.max);
        h.add(uint64_t(rule.points.size()));
        for (const Vec3& p : rule.points) h.add(p);
        for (double w : rule.weights) h.add(w);
      }
      for (size_t k = 0; k < members.size(); ++k) {
        const size_t e = members[k];
        const Key key{cell, h.h1, h.h2, static_cast<int>(k)};
        const size_t n = 8 + elements[e].rule.points.size();
        auto old = verdicts.find(key);
        auto& v = next[key];  // nodes stay put when `next` moves into `verdicts`
        if (old != verdicts.end() && old->second.size() == n) v = std::move(old->second);
        else v.assign(n, -1);
        of[e] = &v;
      }
    }
    verdicts = std::move(next);
    return of;
  }
};

SimulationSession::SimulationSession(const std::string& part_path, const json& job) : job_(job) {
  schema::check(job, schema::Format::Simulation);
  load_part(part_path);
  setup_ = parse_job();
}

SimulationSession::~SimulationSession() = default;

void SimulationSession::load_part(const std::string& part_path) {
  occ::ReadOptions ro;
  if (job_.contains("solid")) ro.solid_index = static_cast<int>(number(job_["solid"], "solid"));
  auto part = occ::read_part(part_path, ro);
  // Into the local frame first (exact), then rotated about the centre moved into it: the same
  // part as rotating in the part's frame, without rotating coordinates of 1e7.
  Eigen::Vector3d origin = frame_origin_;
  if (!frame_set_) {
    const occ::PartBox box = occ::part_box(*part);
    origin = local_frame_origin(box.min, box.max);
  }
  if (!origin.isZero(0)) part = occ::translated_part(*part, -origin);
  if (job_.contains("rotate")) {  // {"axis": [..], "center": [..], "degrees": a}: the part inside the grid
    const json& rot = job_["rotate"];
    part = occ::rotated_part(*part, vec3(rot.value("center", json::array({0, 0, 0})), "rotate.center") - origin,
                             vec3(rot.value("axis", json::array({0, 0, 1})), "rotate.axis"),
                             number(rot.value("degrees", json(0.0)), "rotate.degrees"));
  }
  part_path_ = part_path;
  part_ = std::move(part);
  frame_origin_ = origin;
  frame_set_ = true;
}

std::unique_ptr<SimulationSession::Setup> SimulationSession::parse_job() const {
  auto S = std::make_unique<Setup>();
  // The box and area only (the estimate's inputs); part_info's adaptive volume and area integrals
  // would cost ~10 ms of every run and update.
  const occ::PartBoxArea size = occ::part_box_and_area(*part_);
  const double diag = (size.max - size.min).norm();
  // Points on faces within 1e-3 of the diagonal, in the part's frame (moved into the local one).
  const NamedPart named(*part_, 1e-3 * diag, frame_origin_, /*entry_in_errors=*/false);
  S->job = parse_simulation_job(named, job_, SimulationJobOptions::simulate());
  S->extent = size.max - size.min;
  S->info = size_info(size);
  S->set_estimate();
  return S;
}

json SimulationSession::estimate() const {
  const JobSize& s = setup_->size;
  const SolveEstimate& e = s.solve;
  return {{"unknowns", e.dofs},
          {"factor_mb", e.factor_mb},
          {"factor_mb_min", e.factor_mb_min},
          {"peak_mb", e.peak_mb},
          {"peak_mb_min", e.peak_mb_min},
          {"limit_mb", s.limit_mb},
          {"memory_mb", s.physical_mb},
          {"fits", e.peak_mb <= s.limit_mb && s.cut.fits},
          {"may_fit", e.peak_mb_min <= s.limit_mb && s.cut.fits},
          {"cut", to_json(s.cut)}};
}

void SimulationSession::refuse_if_too_big() const { entry::refuse_if_too_big(setup_->size, JobCommand::Simulate); }
json SimulationSession::run(const std::string& out_dir, const ProgressFn& progress) {
  auto report = [&](const char* phase, double fraction) {
    if (progress && !progress(phase, fraction))
      throw Cancelled("simulation cancelled by the user (during " + std::string(phase) + ")");
  };
  std::optional<FolderLock> lock;  // one run at a time in a folder
  if (!out_dir.empty()) require_writable_folder(out_dir), lock.emplace(out_dir);  // before the work
  refuse_if_too_big();
  std::optional<tbb::global_control> threads;  // for the whole run
  if (setup_->job.run.threads > 0) threads.emplace(tbb::global_control::max_allowed_parallelism, setup_->job.run.threads);
  if (setup_->job.run.target > 0) return run_to_target(out_dir, report);
  report("cut", 0.05);
  auto model = std::make_unique<occ::GridModel>(occ::build_grid_model(*part_, setup_->job.grid.options));
  if (!model->done) PARAFAB_INPUT_ERROR("cannot cut " << part_path_ << " by the grid: " << model->message);
  model_ = std::move(model);
  return solve(out_dir, report, json(nullptr));
}

// The results q (probe displacements, or the largest displacement without probes) on grids
// refined by r = 1.5. The relative change Δ_k = ‖q_k − q_{k−1}‖ / ‖q_k‖ gives, with the
// observed order p = log(Δ_{k−1}/Δ_k) / log r, clamped to [0.5, 1], the Richardson estimate
// of the error of the finest grid, e_k = Δ_k / (r^p − 1). The cap at first order is on
// purpose: with Nitsche on partly cut faces the bracket converges like h before it converges
// like h², and a higher observed order there underestimated its error 2×
// (resources/doc/simulation.md, "An accuracy target"). Stops when e_k ≤ target (at least
// three grids), or at grid.max_cells / the memory limit (not met).
template <class Report>
json SimulationSession::run_to_target(const std::string& out_dir, const Report& report) {
  Setup& S = *setup_;
  const double ratio = 1.5;
  json levels = json::array(), out;
  std::vector<Eigen::VectorXd> q;
  std::vector<double> change;
  double estimated = std::numeric_limits<double>::infinity(), order = 1;
  double analyzed_before = 0;  // the session solver's analysis seconds before this level
  bool met = false;
  std::string stop;
  for (int cells = S.job.grid.options.grid.cells_longest;; cells = static_cast<int>(std::lround(cells * ratio))) {
    if (cells > S.job.run.max_cells) {
      stop = "grid.max_cells (" + std::to_string(S.job.run.max_cells) + ") reached";
      break;
    }
    S.job.grid.options.grid.cells_longest = cells;
    S.set_estimate();
    if (S.size.solve.peak_mb > S.size.limit_mb || !S.size.cut.fits) {  // the safe figure: a refusal would lose the levels
      stop = "the next grid (" + std::to_string(cells) + " cells) would not fit in memory";
      break;
    }
    report("cut", 0.05);
    auto model = std::make_unique<occ::GridModel>(occ::build_grid_model(*part_, S.job.grid.options));
    if (!model->done) PARAFAB_INPUT_ERROR("cannot cut " << part_path_ << " by the grid: " << model->message);
    model_ = std::move(model);
    out = solve(out_dir, report, json(nullptr));
    Eigen::VectorXd qk;
    if (!out["probes"].empty()) {
      qk.resize(3 * out["probes"].size());
      for (size_t i = 0; i < out["probes"].size(); ++i)
        for (int c = 0; c < 3; ++c) qk(3 * i + c) = out["probes"][i]["displacement"][c].get<double>();
    } else {
      qk = Eigen::VectorXd::Constant(1, out["max_displacement"].get<double>());
    }
    json level{{"cells", cells}, {"dofs", out["dofs"]}, {"seconds", out["seconds"]}};
    // This level's symbolic analysis: each grid has its own sparsity pattern, so it cannot reuse
    // the previous level's (resources/doc/simulation.md, "No repeated work").
    if (out.contains("solver")) {
      const double analyzed = out["solver"]["analyze_seconds"].get<double>();
      level["analyze_seconds"] = analyzed - analyzed_before;
      analyzed_before = analyzed;
    }
    if (!q.empty()) {
      change.push_back((qk - q.back()).norm() / std::max(qk.norm(), 1e-300));
      level["change"] = change.back();
      if (change.size() >= 2) {
        order = std::clamp(std::log(change[change.size() - 2] / std::max(change.back(), 1e-300)) / std::log(ratio), 0.5, 1.0);
        estimated = change.back() / (std::pow(ratio, order) - 1);
        level["order"] = order;
        level["estimated_error"] = estimated;
      }
    }
    q.push_back(qk);
    levels.push_back(level);
    if (estimated <= S.job.run.target) {
      met = true;
      break;
    }
  }
  if (q.empty()) PARAFAB_INPUT_ERROR("grid.target: no grid could be run: " << stop);
  out["accuracy"] = {{"target", S.job.run.target}, {"met", met}, {"estimated_error", std::isfinite(estimated) ? json(estimated) : json(nullptr)},
                     {"order", order}, {"quantity", out["probes"].empty() ? "max_displacement" : "probe displacements"},
                     {"levels", levels}, {"stopped", met ? "target met" : stop}};
  if (!out_dir.empty()) write_text_atomically(out_dir + "/result.json", out.dump(2) + "\n");
  return out;
}

json SimulationSession::update(const std::string& new_part_path, const std::string& out_dir, const ProgressFn& progress) {
  auto report = [&](const char* phase, double fraction) {
    if (progress && !progress(phase, fraction))
      throw Cancelled("simulation cancelled by the user (during " + std::string(phase) + ")");
  };
  if (!model_) {  // nothing solved yet: the new part is the one to run (not the one of the constructor)
    load_part(new_part_path);
    setup_ = parse_job();
    return run(out_dir, progress);
  }
  std::optional<FolderLock> lock;
  if (!out_dir.empty()) require_writable_folder(out_dir), lock.emplace(out_dir);
  std::shared_ptr<const occ::PartShape> old_part = part_;
  std::unique_ptr<Setup> old_setup = std::move(setup_);
  try {
    load_part(new_part_path);
    setup_ = parse_job();
  } catch (...) {  // keep the session usable on the old part
    part_ = old_part;
    setup_ = std::move(old_setup);
    throw;
  }
  refuse_if_too_big();
  std::optional<tbb::global_control> threads;  // for the whole update
  if (setup_->job.run.threads > 0) threads.emplace(tbb::global_control::max_allowed_parallelism, setup_->job.run.threads);
  report("cut", 0.05);
  occ::RecutReport rr;
  auto model = std::make_unique<occ::GridModel>(occ::rebuild_grid_model(*part_, *model_, *old_part, setup_->job.grid.options, &rr));
  if (!model->done) PARAFAB_INPUT_ERROR("cannot cut " << new_part_path << " by the grid: " << model->message);
  model_ = std::move(model);
  const json recut{{"full", rr.full}, {"message", rr.message}, {"changed_faces", rr.changed_faces},
                   {"changed_edges", rr.changed_edges}, {"regions", rr.regions}, {"verified", rr.verified},
                   {"blocks", rr.blocks}, {"blocks_recut", rr.blocks_recut},
                   {"subvolumes_kept", rr.subvolumes_kept}, {"subvolumes_new", rr.subvolumes_new},
                   {"method", model_->cut->method == occ::CutMethod::FaceCut ? "face" : "splitter"},
                   {"cells", rr.cells}, {"cells_recut", rr.cells_recut}, {"cut_cells", model_->cut->cut_cells.size()},
                   {"old_cut_cells", rr.old_cut_cells}, {"planes_moved", rr.planes_moved},
                   {"faces_recut", rr.faces_recut}};
  return solve(out_dir, report, recut);
}

template <class Report>
json SimulationSession::solve(const std::string& out_dir, const Report& report, const json& recut) {
  const Setup& S = *setup_;
  const occ::GridModel& grid = *model_;
  const auto& mat = S.job.material.elastic;
  const double diag = S.extent.norm();
  report("assemble", 0.6);
  xfem::LinearXfemResult r;
  json newton = nullptr;
  StressFn stress;
  std::function<Eigen::Matrix<double, 6, 1>(const Eigen::Matrix3d&)> stress_of_gradient;  // σ from ∇u
  report(S.job.material.linear() ? "solve" : "newton", 0.65);
  if (S.job.material.linear()) {
    if (!linear_solver_) linear_solver_ = std::make_unique<xfem::LinearXfemSolver>();
    r = linear_solver_->solve(grid.elements, grid.adjacent, mat, S.job.conditions.supports, S.job.conditions.loads, S.job.solver);
    stress = [&](int e, const Vec3& X) { return xfem::stress_at(r, grid.elements, mat, e, X); };
    stress_of_gradient = [&mat](const Eigen::Matrix3d& H) { return xfem::stress_from_gradient(mat, H); };
  } else {
    xfem::NonlinearXfemOptions no;
    no.boundary = S.job.solver;
    no.load_steps = S.job.material.load_steps;
    const xfem::NonlinearXfemResult nr =
        xfem::solve_nonlinear(grid.elements, grid.adjacent, *S.job.material.law, mat, S.job.conditions.supports, S.job.conditions.loads, no);
    if (!nr.converged)
      PARAFAB_INPUT_ERROR("the hyperelastic simulation did not converge: "
                          << nr.message
                          << (S.job.solver.nitsche_penalty == xfem::LinearXfemOptions::NitschePenalty::Fixed
                                  ? " (a fixed Nitsche penalty that is not coercive on some cut cell makes the energy "
                                    "non-convex there: try \"nitsche_penalty\": \"local\")"
                                  : ""));
    r = nr.as_linear();
    r.solve_seconds = nr.seconds;
    r.energy = nr.energy;
    newton = {{"iterations", nr.iterations}, {"residuals", nr.residuals}, {"load_steps", no.load_steps}};
    const xfem::Material* law = S.job.material.law.get();
    stress = [&r, &grid, law](int e, const Vec3& X) {  // Cauchy stress σ = P Fᵀ / J
      const Eigen::Matrix3d F = Eigen::Matrix3d::Identity() + xfem::displacement_gradient(r, grid.elements, e, X);
      const Eigen::Matrix3d sig = law->stress(F) * F.transpose() / F.determinant();
      Eigen::Matrix<double, 6, 1> v;
      v << sig(0, 0), sig(1, 1), sig(2, 2), sig(0, 1), sig(1, 2), sig(0, 2);
      return v;
    };
    stress_of_gradient = [law](const Eigen::Matrix3d& H) {  // the same from ∇u
      const Eigen::Matrix3d F = Eigen::Matrix3d::Identity() + H;
      const Eigen::Matrix3d sig = law->stress(F) * F.transpose() / F.determinant();
      Eigen::Matrix<double, 6, 1> v;
      v << sig(0, 0), sig(1, 1), sig(2, 2), sig(0, 1), sig(1, 2), sig(0, 2);
      return v;
    };
  }
  if (!r.solved) PARAFAB_INPUT_ERROR("the simulation could not be solved: " << r.message);
  report("results", 0.9);
  const auto t_results = std::chrono::steady_clock::now();
  // Largest displacement (at element corners and quadrature points) and von Mises stress (at
  // quadrature points), from points in the material only: uncut cells lie inside; the corners
  // of cut cells and the rule points of cut subvolumes (which fill the fitting box, not the
  // subvolume) count only where they lie inside or on the part (CutCellClassifier). The field
  // extrapolated outside the part can exceed anything the material sees.
  struct Candidate {
    double value;
    int element;
    int point;  ///< 0–7 the cell corners, 8 + k rule point k
    Vec3 X;
  };
  xfem::MassAccumulator acc;
  for (const auto& el : grid.elements) acc.add(el.rule.points, el.rule.weights);
  // The maxima over uncut elements first (they lie inside), in parallel (TBB), one partial
  // result per chunk of elements.
  const size_t n_el = grid.elements.size();
  const size_t grain = 64;
  double umax = 0, vmmax = 0;
  {
    std::vector<std::array<double, 2>> partial((n_el + grain - 1) / grain, {0.0, 0.0});
    tbb::parallel_for(tbb::blocked_range<size_t>(0, partial.size()), [&](const tbb::blocked_range<size_t>& range) {
      std::vector<Vec3> X, U;
      std::vector<Eigen::Matrix3d> H;
      for (size_t c = range.begin(); c != range.end(); ++c)
        for (size_t e = c * grain; e < std::min(n_el, (c + 1) * grain); ++e) {
          const auto& el = grid.elements[e];
          if (el.subvolume) continue;
          X.clear();
          for (int k = 0; k < 8; ++k) X.push_back(xfem::corner(el.box, k));
          X.insert(X.end(), el.rule.points.begin(), el.rule.points.end());
          xfem::displacement_and_gradient(r, grid.elements, static_cast<int>(e), X, U, H);
          for (size_t i = 0; i < X.size(); ++i) {
            partial[c][0] = std::max(partial[c][0], U[i].norm());
            if (i >= 8) partial[c][1] = std::max(partial[c][1], xfem::von_mises(stress_of_gradient(H[i])));
          }
        }
    });
    for (const auto& p : partial) umax = std::max(umax, p[0]), vmmax = std::max(vmmax, p[1]);
  }
  // Cut elements by branch and bound: bounds of |u| and σ_vm over each cut cell
  // (xfem::field_bounds: Bernstein control points of u and ∇u; linear elasticity, points in the
  // cell's box), cells in decreasing bound, evaluated a batch at a time; after each batch the
  // largest candidate inside the material (below) raises the maximum, and the search stops at
  // the first cell whose bound cannot beat it. Cells without a bound (hyperelastic, points
  // outside the box) come first. The maxima do not depend on the batches.
  const bool linear = S.job.material.linear();
  std::vector<int> cut_elements;
  for (size_t e = 0; e < n_el; ++e)
    if (grid.elements[e].subvolume) cut_elements.push_back(static_cast<int>(e));
  std::vector<std::array<double, 2>> bound(n_el, {HUGE_VAL, HUGE_VAL});  // |u|, σ_vm
  tbb::parallel_for(tbb::blocked_range<size_t>(0, cut_elements.size(), 16), [&](const tbb::blocked_range<size_t>& range) {
    for (size_t k = range.begin(); k != range.end(); ++k) {
      const int e = cut_elements[k];
      const auto& el = grid.elements[e];
      if (!linear) continue;
      const Vec3 slack = 1e-12 * el.box.size();
      bool in_box = true;  // the bounds hold in the box (rule points of a fitting box lie in it)
      for (const Vec3& q : el.rule.points)
        in_box &= (q.array() >= (el.box.min - slack).array()).all() && (q.array() <= (el.box.max + slack).array()).all();
      if (!in_box) continue;
      const xfem::FieldBounds b = xfem::field_bounds(r, grid.elements, e, &mat);
      bound[e] = {b.displacement * (1 + 1e-9), b.von_mises * (1 + 1e-9)};  // round-off margin
    }
  });
  // The largest candidate inside the material: candidates in decreasing order (ties by element
  // and position, so the order is that of any thread count), classified by OCCT a batch at a
  // time in parallel, one classifier per task; the first inside in that order wins. Verdicts
  // of earlier runs on unchanged cells are reused (InsideCache), so an update classifies only
  // points of cells it re-cut.
  int classified = 0, reused_verdicts = 0;
  if (!inside_cache_) inside_cache_ = std::make_unique<InsideCache>();
  const std::vector<std::vector<signed char>*> verdict = inside_cache_->bind(grid.elements);
  // One per thread, made on first use: crossing parity inside the cut cell, OCCT where undecided.
  tbb::enumerable_thread_specific<std::unique_ptr<occ::CutCellClassifier>> classifiers;
  auto largest_inside = [&](std::vector<Candidate>& c, double& best) {
    c.erase(std::remove_if(c.begin(), c.end(), [&](const Candidate& k) { return k.value <= best; }), c.end());
    std::sort(c.begin(), c.end(), [](const Candidate& a, const Candidate& b) {
      if (a.value != b.value) return a.value > b.value;
      if (a.element != b.element) return a.element < b.element;
      return std::lexicographical_compare(a.X.data(), a.X.data() + 3, b.X.data(), b.X.data() + 3);
    });
    // Batches grow (32, 64, ... 1024) so a long run of outside points costs few task launches.
    size_t batch = 32;
    std::vector<size_t> unknown;  // candidates of the batch without a verdict yet
    std::vector<char> known;      // per candidate of the batch: verdict from an earlier run
    for (size_t begin = 0; begin < c.size(); begin += batch, batch = std::min<size_t>(2 * batch, 1024)) {
      const size_t end = std::min(c.size(), begin + batch);
      unknown.clear();
      known.assign(end - begin, 0);
      for (size_t i = begin; i < end; ++i) {
        known[i - begin] = (*verdict[c[i].element])[c[i].point] >= 0;
        if (!known[i - begin]) unknown.push_back(i);
      }
      tbb::parallel_for(tbb::blocked_range<size_t>(0, unknown.size(), 8), [&](const tbb::blocked_range<size_t>& range) {
        auto& mine = classifiers.local();
        if (!mine) mine = std::make_unique<occ::CutCellClassifier>(*part_, *grid.cut, 1e-7 * diag);
        for (size_t k = range.begin(); k != range.end(); ++k) {
          const Candidate& q = c[unknown[k]];
          (*verdict[q.element])[q.point] = mine->in_material(grid.elements[q.element].cell, q.X) ? 1 : 0;  // distinct points per task
        }
      });
      classified += static_cast<int>(unknown.size());
      for (size_t i = begin; i < end; ++i) {
        reused_verdicts += known[i - begin];
        if ((*verdict[c[i].element])[c[i].point] == 1) {
          best = c[i].value;
          return;
        }
      }
    }
  };
  std::vector<char> evaluated(n_el, 0);  // bit 0: for |u|, bit 1: for σ_vm
  auto maximize = [&](int q, double& best) {
    std::vector<int> order = cut_elements;
    std::sort(order.begin(), order.end(), [&](int x, int y) {
      return bound[x][q] != bound[y][q] ? bound[x][q] > bound[y][q] : x < y;
    });
    size_t next = 0, batch = 16;
    while (next < order.size() && !(bound[order[next]][q] < best)) {
      size_t end = next;
      while (end < order.size() && end - next < batch && !(bound[order[end]][q] < best)) ++end;
      std::vector<std::vector<Candidate>> found(end - next);
      tbb::parallel_for(tbb::blocked_range<size_t>(next, end, 1), [&](const tbb::blocked_range<size_t>& range) {
        std::vector<Vec3> X, U;
        std::vector<Eigen::Matrix3d> H;
        for (size_t k = range.begin(); k != range.end(); ++k) {
          const int e = order[k];
          const auto& el = grid.elements[e];
          X.clear();
          if (q == 0)
            for (int c = 0; c < 8; ++c) X.push_back(xfem::corner(el.box, c));
          X.insert(X.end(), el.rule.points.begin(), el.rule.points.end());
          const int first = q == 0 ? 0 : 8;  // point numbering: corners 0–7, rule point i at 8 + i
          if (q == 0) xfem::displacement_at(r, grid.elements, e, X, U);
          else xfem::displacement_and_gradient(r, grid.elements, e, X, U, H);
          for (size_t i = 0; i < X.size(); ++i) {
            const double v = q == 0 ? U[i].norm() : xfem::von_mises(stress_of_gradient(H[i]));
            if (v > best) found[k - next].push_back({v, e, first + static_cast<int>(i), X[i]});
          }
        }
      });
      std::vector<Candidate> candidates;
      for (size_t k = next; k < end; ++k) {
        evaluated[order[k]] |= 1 << q;
        candidates.insert(candidates.end(), found[k - next].begin(), found[k - next].end());
      }
      largest_inside(candidates, best);
      next = end;
      batch = std::min<size_t>(2 * batch, 256);
    }
  };
  maximize(0, umax);
  maximize(1, vmmax);
  int skipped_elements = 0, displacement_only_elements = 0;
  for (int e : cut_elements) skipped_elements += evaluated[e] == 0, displacement_only_elements += evaluated[e] == 1;
  long occt_calls = 0;  // OCCT classifications, the cells' reference corners included
  for (const auto& mine : classifiers)
    if (mine) occt_calls += mine->counts().by_occt;
  const occ::ElementLocator locator(grid);
  json probes = json::array();
  if (job_.contains("probes"))
    for (size_t i = 0; i < job_["probes"].size(); ++i) {
      const Vec3 P = vec3(job_["probes"][i], "probes[" + std::to_string(i) + "]");  // the part's frame
      const Vec3 X = P - frame_origin_;
      const int best = locator.find(X);
      if (best < 0) PARAFAB_INPUT_ERROR("probes[" << i << "] lies outside the grid");
      const Vec3 u = r.displacement(grid.elements, best, X);
      const auto s = stress(best, X);
      probes.push_back({{"point", {P.x(), P.y(), P.z()}}, {"displacement", {u.x(), u.y(), u.z()}},
                        {"von_mises", xfem::von_mises(s)},
                        {"stress", {s(0), s(1), s(2), s(3), s(4), s(5)}}});
    }
  json rule_failures = json::array();
  for (const auto& f : grid.rule_failures)
    rule_failures.push_back({{"cell", f.cell}, {"subvolume", f.subvolume}, {"message", f.message}});
  const xfem::MassProperties mp = acc.result();
  json out{{"part", part_path_},
           {"grid", {{"cells", grid.cut->cells}, {"cell_size", grid.cut->cell_size.x()},
                     {"cut_cells", grid.cut->cut_cells.size()}, {"subvolumes", grid.cut->subvolumes.size()},
                     {"interior_cells", grid.cut->interior_cells.size()},
                     {"method", grid.cut->method == occ::CutMethod::FaceCut ? "face" : "splitter"},
                     {"retry_reason", grid.cut->retry_reason},
                     {"grid_shift", {grid.cut->grid_shift.x(), grid.cut->grid_shift.y(), grid.cut->grid_shift.z()}},
                     {"frame_origin", {frame_origin_.x(), frame_origin_.y(), frame_origin_.z()}}}},
           {"dofs", r.dofs},
           {"element", xfem::element_type_name(S.job.solver.element)},
           {"nitsche_penalty", S.job.solver.nitsche_penalty == xfem::LinearXfemOptions::NitschePenalty::Local ? "local" : "fixed"},
           {"nitsche_surface_degree", S.job.solver.dirichlet_surface_degree},
           {"estimate", {{"unknowns", S.size.solve.dofs}, {"factor_mb", S.size.solve.factor_mb},
                         {"factor_mb_min", S.size.solve.factor_mb_min}, {"peak_mb", S.size.solve.peak_mb},
                         {"peak_mb_min", S.size.solve.peak_mb_min}, {"cut", to_json(S.size.cut)}}},
           {"max_displacement", umax},
           {"max_von_mises", vmmax},
           {"points_classified", classified},
           {"points_classified_before", reused_verdicts},  // verdicts reused from earlier runs of the session
           {"points_classified_by_occt", occt_calls},      // the rest by crossing parity in their cut cell
           {"cut_elements_skipped", skipped_elements},     // bounded below the uncut maxima: not evaluated
           {"cut_elements_displacement_only", displacement_only_elements},  // their stress bounded below: u only
           {"status", result_status(grid.rule_failures.empty(), r.indefinite && S.job.material.linear(),
                                    r.u.allFinite() && std::isfinite(umax) && std::isfinite(vmmax) && std::isfinite(r.energy))},
           {"rule_failures", rule_failures},
           {"rules_refinement_capped", grid.rules_refinement_capped},  // flux refinement stopped at quadrature.max_depth
           {"potential", r.energy},  // the minimized functional (strain energy, Nitsche and load terms), up to a constant
           {"material_model", S.job.material.model},
           {"aggregated_nodes", r.aggregated_nodes},
           {"newton", newton},
           {"recut", recut},
           {"mass_properties", {{"volume", mp.volume}, {"mass", mp.volume * mat.density},
                                {"center", {mp.center.x() + frame_origin_.x(), mp.center.y() + frame_origin_.y(),
                                            mp.center.z() + frame_origin_.z()}}}},
           {"probes", probes},
           {"message", r.message},
           {"seconds", {{"cut", grid.cut_seconds}, {"rules", grid.rule_seconds},
                        {"assemble", r.assemble_seconds}, {"solve", r.solve_seconds}}},
           {"units", "those of the part and material (e.g. mm, N, MPa)"}};
  out["seconds"]["results"] = seconds_since(t_results);
  out["threads"] = tbb::global_control::active_value(tbb::global_control::max_allowed_parallelism);
  if (linear_solver_ && S.job.material.linear()) {
    const xfem::SolveInfo& si = r.solve_info;
    out["solver"] = {{"analyses", linear_solver_->cholesky().analyses},
                     {"factorizations", linear_solver_->cholesky().factorizations},
                     {"reused_element_matrices", r.reused_element_matrices},
                     {"cached_element_matrices", r.cached_element_matrices},
                     {"method", si.method}, {"fallback", si.fallback}, {"iterations", si.iterations},
                     {"residual", si.residual}, {"mapped_dofs", si.mapped_dofs}, {"changed_dofs", si.changed_dofs},
                     {"local_dofs", si.local_dofs},
                     {"krylov", si.krylov}, {"ranks", si.ranks}, {"petsc_memory_mb", si.petsc_memory_mb},
                     {"factor_mb", linear_solver_->cholesky().factor_mb()},
                     // CHOLMOD's symbolic analyses and numeric factorizations, seconds over the session
                     {"analyze_seconds", linear_solver_->cholesky().analyze_seconds},
                     {"numeric_seconds", linear_solver_->cholesky().factorize_seconds},
                     {"factor_flops", linear_solver_->cholesky().factor_flops()}};
    out["seconds"]["assemble_parts"] = {{"number", r.number_seconds}, {"integrate", r.integrate_seconds},
                                        {"scatter", r.scatter_seconds}, {"aggregate", r.aggregate_seconds}};
    out["seconds"]["solve_parts"] = {{"pcg", si.pcg_seconds}, {"pcg_setup", si.pcg_setup_seconds}, {"factorize", si.factorize_seconds},
                                     {"petsc", si.petsc_seconds}, {"petsc_copy", si.petsc_copy_seconds},
                                     {"petsc_setup", si.petsc_setup_seconds}};
  }
  // Probes (and below surface vertices) in no element known to hold them (ElementLocator).
  out["points_located_by_nearest_rule_point"] = locator.nearest_rule_point_fallbacks();
  if (!out_dir.empty()) {
    const auto t_write = std::chrono::steady_clock::now();
    require_writable_folder(out_dir);
    report("write", 0.95);
    write_vtu(out_dir + "/result.vtu", grid.elements, r, stress, frame_origin_);
    // The exact boundary, triangulated to a tenth of a cell and to edges of at most half a
    // cell, with the fields at its vertices (located through the grid, evaluated in parallel).
    const double cell = grid.cut->cell_size.x();
    const occ::SurfaceMesh mesh = occ::triangulate_part(*part_, 0.1 * cell, 0.5 * cell, out["threads"].get<int>() > 1);
    std::vector<Vec3> sdisp(mesh.points.size(), Vec3::Zero());
    std::vector<double> svm(mesh.points.size(), 0.0);
    // Outward vertex normals (a face's triangles run counter-clockwise seen from outside; vertices
    // are not shared between faces): the locator looks just inside, where the material is.
    std::vector<Vec3> normal(mesh.points.size(), Vec3::Zero());
    for (const auto& t : mesh.triangles) {
      const Vec3 n = (mesh.points[t[1]] - mesh.points[t[0]]).cross(mesh.points[t[2]] - mesh.points[t[0]]);
      for (int k : t) normal[k] += n;
    }
    tbb::parallel_for(tbb::blocked_range<size_t>(0, mesh.points.size(), 256), [&](const tbb::blocked_range<size_t>& b) {
      for (size_t i = b.begin(); i != b.end(); ++i) {
        const int e = locator.find_on_surface(mesh.points[i], normal[i]);
        if (e < 0) continue;  // cannot happen for points of the part; keep zero rather than fail
        sdisp[i] = r.displacement(grid.elements, e, mesh.points[i]);
        svm[i] = xfem::von_mises(stress(e, mesh.points[i]));
      }
    });
    write_surface_vtu(out_dir + "/surface.vtu", mesh, sdisp, svm, frame_origin_);
    out["files"] = {out_dir + "/result.json", out_dir + "/result.vtu", out_dir + "/surface.vtu"};
    out["surface_vertices"] = mesh.points.size();
    out["points_located_by_nearest_rule_point"] = locator.nearest_rule_point_fallbacks();
    out["seconds"]["write"] = seconds_since(t_write);
    write_text_atomically(out_dir + "/result.json", out.dump(2) + "\n");
  }
  return out;
}

json simulate_part_json(const std::string& part_path, const json& job, const std::string& out_dir,
                        const ProgressFn& progress) {
  if (progress && !progress("read", 0.0)) throw Cancelled("simulation cancelled by the user (during read)");
  SimulationSession session(part_path, job);
  return session.run(out_dir, progress);
}

}  // namespace parafab::entry
