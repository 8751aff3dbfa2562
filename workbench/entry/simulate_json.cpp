#include "simulate_json.h"

#include <unistd.h>

#include <Eigen/Dense>
#include <filesystem>
#include <functional>
#include <map>
#include <algorithm>
#include <cmath>
#include <limits>
#include <fstream>

#include "common/error.h"
#include "json_fields.h"
#include "face_lookup.h"
#include "grid_model.h"
#include "part_reader.h"
#include "surface_mesh.h"
#include "xfem/mass_properties.h"
#include "xfem/nonlinear_xfem.h"

namespace parafab::entry {

using nlohmann::json;
using xfem::Vec3;

namespace {

bool model_name_is_linear(const std::string& model) { return model == "linear"; }

using fields::number;
using fields::vec3;

// A face named by index or by a point on it.
int face_of(const occ::PartShape& part, const json& item, const std::string& path, double tol) {
  if (item.contains("face")) {
    if (!item["face"].is_number_integer()) PARAFAB_INPUT_ERROR(path << ".face must be a face index");
    const int f = item["face"].get<int>();
    occ::face_area(part, f);  // validates the index
    return f;
  }
  if (item.contains("point")) return occ::face_at_point(part, vec3(item["point"], path + ".point"), tol);
  PARAFAB_INPUT_ERROR(path << " needs \"face\" (index from parafab inspect) or \"point\" (on the face)");
}

using StressFn = std::function<Eigen::Matrix<double, 6, 1>(int, const Vec3&)>;

void write_vtu(const std::string& path, const std::vector<xfem::GridElement>& elements,
               const xfem::LinearXfemResult& r, const StressFn& stress) {
  // Uncut cells as hexahedra; cut subvolumes as their quadrature points (VTK_VERTEX), each
  // with displacement and von Mises stress.
  std::vector<Vec3> pts, disp;
  std::vector<double> vm;
  std::vector<std::array<int, 8>> hexes;
  std::vector<int> vertices;
  static const int vtk_order[8] = {0, 1, 3, 2, 4, 5, 7, 6};
  for (size_t e = 0; e < elements.size(); ++e) {
    const auto& el = elements[e];
    if (!el.subvolume) {
      std::array<int, 8> h{};
      for (int k = 0; k < 8; ++k) {
        const Vec3 X = xfem::corner(el.box, vtk_order[k]);
        h[k] = static_cast<int>(pts.size());
        pts.push_back(X);
        disp.push_back(r.displacement(elements, static_cast<int>(e), X));
        vm.push_back(xfem::von_mises(stress(static_cast<int>(e), X)));
      }
      hexes.push_back(h);
    } else {
      for (const Vec3& X : el.rule.points) {
        vertices.push_back(static_cast<int>(pts.size()));
        pts.push_back(X);
        disp.push_back(r.displacement(elements, static_cast<int>(e), X));
        vm.push_back(xfem::von_mises(stress(static_cast<int>(e), X)));
      }
    }
  }
  std::ofstream f(path);
  if (!f) PARAFAB_INPUT_ERROR("cannot write " << path);
  const size_t ncells = hexes.size() + vertices.size();
  f << "<?xml version=\"1.0\"?>\n<VTKFile type=\"UnstructuredGrid\" version=\"0.1\" byte_order=\"LittleEndian\">\n"
    << "<UnstructuredGrid><Piece NumberOfPoints=\"" << pts.size() << "\" NumberOfCells=\"" << ncells << "\">\n"
    << "<PointData Vectors=\"displacement\" Scalars=\"von_mises\">\n"
    << "<DataArray type=\"Float64\" Name=\"displacement\" NumberOfComponents=\"3\" format=\"ascii\">\n";
  for (const auto& d : disp) f << d.x() << ' ' << d.y() << ' ' << d.z() << '\n';
  f << "</DataArray>\n<DataArray type=\"Float64\" Name=\"von_mises\" format=\"ascii\">\n";
  for (double v : vm) f << v << '\n';
  f << "</DataArray>\n</PointData>\n<Points><DataArray type=\"Float64\" NumberOfComponents=\"3\" format=\"ascii\">\n";
  for (const auto& p : pts) f << p.x() << ' ' << p.y() << ' ' << p.z() << '\n';
  f << "</DataArray></Points>\n<Cells>\n<DataArray type=\"Int32\" Name=\"connectivity\" format=\"ascii\">\n";
  for (const auto& h : hexes) {
    for (int k : h) f << k << ' ';
    f << '\n';
  }
  for (int v : vertices) f << v << '\n';
  f << "</DataArray>\n<DataArray type=\"Int32\" Name=\"offsets\" format=\"ascii\">\n";
  int off = 0;
  for (size_t i = 0; i < hexes.size(); ++i) f << (off += 8) << '\n';
  for (size_t i = 0; i < vertices.size(); ++i) f << (off += 1) << '\n';
  f << "</DataArray>\n<DataArray type=\"UInt8\" Name=\"types\" format=\"ascii\">\n";
  for (size_t i = 0; i < hexes.size(); ++i) f << "12\n";
  for (size_t i = 0; i < vertices.size(); ++i) f << "1\n";
  f << "</DataArray>\n</Cells>\n</Piece></UnstructuredGrid>\n</VTKFile>\n";
}


// The element holding point X: among the elements of X's grid cell (and of the neighbouring
// cells when X lies on a cell face), the one with the rule point nearest to X.
class ElementLocator {
 public:
  explicit ElementLocator(const occ::GridModel& grid) : grid_(grid) {
    for (size_t e = 0; e < grid.elements.size(); ++e) by_cell_[grid.elements[e].cell].push_back(static_cast<int>(e));
  }
  int find(const Vec3& X) const {
    const auto& cut = *grid_.cut;
    std::array<int, 3> c{};
    for (int a = 0; a < 3; ++a) {
      const auto& pl = cut.planes[a];
      c[a] = static_cast<int>(std::upper_bound(pl.begin(), pl.end(), X[a]) - pl.begin());
    }
    int best = -1;
    double best_d = 1e300;
    for (int di = -1; di <= 1; ++di)
      for (int dj = -1; dj <= 1; ++dj)
        for (int dk = -1; dk <= 1; ++dk) {
          const std::array<int, 3> n{c[0] + di, c[1] + dj, c[2] + dk};
          auto it = by_cell_.find(n);
          if (it == by_cell_.end()) continue;
          for (int e : it->second) {
            const auto& el = grid_.elements[e];
            const Vec3 slack = 1e-6 * el.box.size();
            if (((X - el.box.min + slack).array() < 0).any() || ((el.box.max + slack - X).array() < 0).any()) continue;
            for (const Vec3& P : el.rule.points)
              if ((P - X).norm() < best_d) best_d = (P - X).norm(), best = e;
          }
        }
    return best;
  }

 private:
  const occ::GridModel& grid_;
  std::map<std::array<int, 3>, std::vector<int>> by_cell_;
};

// The part's B-rep faces triangulated, each vertex with its displacement and von Mises stress
// (what FreeCAD shows as the deformed, coloured part; ParaView reads it as well).
void write_surface_vtu(const std::string& path, const occ::SurfaceMesh& mesh, const std::vector<Vec3>& disp,
                       const std::vector<double>& vm) {
  std::ofstream f(path);
  if (!f) PARAFAB_INPUT_ERROR("cannot write " << path);
  f << "<?xml version=\"1.0\"?>\n<VTKFile type=\"UnstructuredGrid\" version=\"0.1\" byte_order=\"LittleEndian\">\n"
    << "<UnstructuredGrid><Piece NumberOfPoints=\"" << mesh.points.size() << "\" NumberOfCells=\""
    << mesh.triangles.size() << "\">\n<PointData Vectors=\"displacement\" Scalars=\"von_mises\">\n"
    << "<DataArray type=\"Float64\" Name=\"displacement\" NumberOfComponents=\"3\" format=\"ascii\">\n";
  for (const auto& d : disp) f << d.x() << ' ' << d.y() << ' ' << d.z() << '\n';
  f << "</DataArray>\n<DataArray type=\"Float64\" Name=\"von_mises\" format=\"ascii\">\n";
  for (double v : vm) f << v << '\n';
  f << "</DataArray>\n</PointData>\n<CellData Scalars=\"face\">\n<DataArray type=\"Int32\" Name=\"face\" format=\"ascii\">\n";
  for (int fi : mesh.triangle_face) f << fi << '\n';
  f << "</DataArray>\n</CellData>\n<Points><DataArray type=\"Float64\" NumberOfComponents=\"3\" format=\"ascii\">\n";
  for (const auto& p : mesh.points) f << p.x() << ' ' << p.y() << ' ' << p.z() << '\n';
  f << "</DataArray></Points>\n<Cells>\n<DataArray type=\"Int32\" Name=\"connectivity\" format=\"ascii\">\n";
  for (const auto& t : mesh.triangles) f << t[0] << ' ' << t[1] << ' ' << t[2] << '\n';
  f << "</DataArray>\n<DataArray type=\"Int32\" Name=\"offsets\" format=\"ascii\">\n";
  for (size_t i = 0; i < mesh.triangles.size(); ++i) f << 3 * (i + 1) << '\n';
  f << "</DataArray>\n<DataArray type=\"UInt8\" Name=\"types\" format=\"ascii\">\n";
  for (size_t i = 0; i < mesh.triangles.size(); ++i) f << "5\n";
  f << "</DataArray>\n</Cells>\n</Piece></UnstructuredGrid>\n</VTKFile>\n";
}

}  // namespace

// Everything of the job that depends on the part (faces named by point are looked up again
// when the part changes).
struct SimulationSession::Setup {
  xfem::ElasticMaterial mat;
  std::string model;
  std::unique_ptr<xfem::Material> law;
  occ::GridModelOptions go;
  std::vector<xfem::DirichletCondition> dirichlet;
  std::vector<xfem::TractionCondition> tractions;
  xfem::LinearXfemOptions fo;
  int load_steps = 5;
  double dofs = 0, factor_mb = 0, physical_mb = 0;
  double target = 0;   ///< relative accuracy target (grid.target); 0: the given grid
  int max_cells = 64;  ///< refinement stops here (grid.max_cells)
  Vec3 extent{0, 0, 0};
  void set_estimate();
};

SimulationSession::SimulationSession(const std::string& part_path, const json& job) : job_(job) {
  if (!job.is_object()) PARAFAB_INPUT_ERROR("the job must be a JSON object");
  load_part(part_path);
  setup_ = parse_job();
}

SimulationSession::~SimulationSession() = default;

void SimulationSession::load_part(const std::string& part_path) {
  occ::ReadOptions ro;
  if (job_.contains("solid")) ro.solid_index = static_cast<int>(number(job_["solid"], "solid"));
  auto part = occ::read_part(part_path, ro);
  if (job_.contains("rotate")) {  // {"axis": [..], "center": [..], "degrees": a}: the part inside the grid
    const json& rot = job_["rotate"];
    part = occ::rotated_part(*part, vec3(rot.value("center", json::array({0, 0, 0})), "rotate.center"),
                             vec3(rot.value("axis", json::array({0, 0, 1})), "rotate.axis"),
                             number(rot.value("degrees", json(0.0)), "rotate.degrees"));
  }
  part_path_ = part_path;
  part_ = std::move(part);
}

std::unique_ptr<SimulationSession::Setup> SimulationSession::parse_job() const {
  const json& job = job_;
  auto S = std::make_unique<Setup>();
  const occ::PartInfo info = occ::part_info(*part_);
  const double diag = (info.bbox_max - info.bbox_min).norm();
  const double tol = 1e-3 * diag;

  if (!job.contains("material")) PARAFAB_INPUT_ERROR("missing material {E, nu[, density]}");
  const json& m = job["material"];
  xfem::ElasticMaterial& mat = S->mat;
  mat.youngs_modulus = number(m.value("E", json()), "material.E");
  mat.poisson_ratio = number(m.value("nu", json(0.3)), "material.nu");
  mat.density = number(m.value("density", json(0.0)), "material.density");
  if (!(mat.youngs_modulus > 0)) PARAFAB_INPUT_ERROR("material.E must be positive, got " << mat.youngs_modulus);
  if (!(mat.poisson_ratio > -1 && mat.poisson_ratio < 0.5))
    PARAFAB_INPUT_ERROR("material.nu must be in (-1, 0.5), got " << mat.poisson_ratio);
  // "linear" (small strain, one linear solve) or a hyperelastic law solved by Newton.
  S->model = m.value("model", std::string("linear"));
  S->law = xfem::make_material(S->model, mat.youngs_modulus, mat.poisson_ratio);

  occ::GridModelOptions& go = S->go;
  const json grid_job = job.value("grid", json::object());
  go.grid.cells_longest = static_cast<int>(number(grid_job.value("cells", json(16)), "grid.cells"));
  go.grid.cell_size = number(grid_job.value("cell_size", json(0.0)), "grid.cell_size");
  go.grid.block_cells = static_cast<int>(number(grid_job.value("block_cells", json(8)), "grid.block_cells"));
  if (go.grid.cells_longest < 1) PARAFAB_INPUT_ERROR("grid.cells must be >= 1");
  if (go.grid.block_cells < 0) PARAFAB_INPUT_ERROR("grid.block_cells must be >= 0");
  const std::string cut_method = grid_job.value("method", std::string("splitter"));
  if (cut_method != "splitter" && cut_method != "face")
    PARAFAB_INPUT_ERROR("grid.method must be \"splitter\" or \"face\", got \"" << cut_method << "\"");
  go.grid.method = cut_method == "face" ? occ::CutMethod::FaceCut : occ::CutMethod::Splitter;

  const json supports = job.value("supports", json::array());
  if (!supports.is_array() || supports.empty())
    PARAFAB_INPUT_ERROR("supports must list at least one face ({\"face\": i} or {\"point\": [x,y,z]}), "
                        "or the part floats freely");
  for (size_t i = 0; i < supports.size(); ++i) {
    const std::string path = "supports[" + std::to_string(i) + "]";
    xfem::DirichletCondition d;
    d.face = face_of(*part_, supports[i], path, tol);
    if (supports[i].contains("displacement")) d.offset = vec3(supports[i]["displacement"], path + ".displacement");
    S->dirichlet.push_back(d);
  }
  const json loads = job.value("loads", json::array());
  for (size_t i = 0; i < loads.size(); ++i) {
    const std::string path = "loads[" + std::to_string(i) + "]";
    xfem::TractionCondition t;
    t.face = face_of(*part_, loads[i], path, tol);
    if (loads[i].contains("traction")) t.traction = vec3(loads[i]["traction"], path + ".traction");
    else if (loads[i].contains("force")) t.traction = vec3(loads[i]["force"], path + ".force") / occ::face_area(*part_, t.face);
    else PARAFAB_INPUT_ERROR(path << " needs \"traction\" (per area) or \"force\" (total, spread evenly)");
    S->tractions.push_back(t);
  }
  if (job.contains("gravity")) S->fo.gravity = vec3(job["gravity"], "gravity");
  if (job.contains("nitsche_beta")) S->fo.nitsche_beta = number(job["nitsche_beta"], "nitsche_beta");
  S->load_steps = static_cast<int>(number(job.value("load_steps", json(5)), "load_steps"));
  if (S->load_steps < 1) PARAFAB_INPUT_ERROR("load_steps must be >= 1");

  // An accuracy target instead of a fixed grid: grids refined by 1.5 from grid.cells (default 8)
  // until the estimated relative error of the results is below the target (see run()).
  S->target = number(grid_job.value("target", json(0.0)), "grid.target");
  S->max_cells = static_cast<int>(number(grid_job.value("max_cells", json(64)), "grid.max_cells"));
  if (S->target < 0 || S->target >= 1) PARAFAB_INPUT_ERROR("grid.target must be in (0, 1) (a relative error), got " << S->target);
  if (S->target > 0 && go.grid.cell_size > 0) PARAFAB_INPUT_ERROR("grid.target chooses the cells: drop grid.cell_size");
  if (S->target > 0 && !grid_job.contains("cells")) go.grid.cells_longest = 8;
  S->extent = info.bbox_max - info.bbox_min;
  S->physical_mb = static_cast<double>(sysconf(_SC_PHYS_PAGES)) * sysconf(_SC_PAGE_SIZE) / 1e6;
  S->set_estimate();
  return S;
}

// Estimate before running: DOFs from the cell count, factor memory from a 3D fill model.
void SimulationSession::Setup::set_estimate() {
  const Vec3& ext = extent;
  const double h = go.grid.cell_size > 0 ? go.grid.cell_size : ext.maxCoeff() / go.grid.cells_longest;
  const double nodes = (std::ceil(ext.x() / h) + 1) * (std::ceil(ext.y() / h) + 1) * (std::ceil(ext.z() / h) + 1);
  dofs = 3 * nodes * 1.2;  // enriched copies at cut cells
  factor_mb = 8.0 * dofs * 40.0 * std::cbrt(dofs) / 1e6;  // nested-dissection fill ~ n^{4/3}
}

json SimulationSession::estimate() const {
  return {{"unknowns", setup_->dofs}, {"factor_mb", setup_->factor_mb}, {"memory_mb", setup_->physical_mb},
          {"fits", setup_->factor_mb <= 0.7 * setup_->physical_mb}};
}

void SimulationSession::refuse_if_too_big() const {
  const Setup& S = *setup_;
  if (S.factor_mb > 0.7 * S.physical_mb)
    PARAFAB_INPUT_ERROR("this grid needs about " << S.factor_mb << " MB for the factorization (" << S.dofs
                                                 << " unknowns), more than 70% of the " << S.physical_mb
                                                 << " MB of memory: use fewer cells");
}

json SimulationSession::run(const std::string& out_dir, const ProgressFn& progress) {
  auto report = [&](const char* phase, double fraction) {
    if (progress && !progress(phase, fraction)) PARAFAB_INPUT_ERROR("simulation cancelled by the user (during " << phase << ")");
  };
  refuse_if_too_big();
  if (setup_->target > 0) return run_to_target(out_dir, report);
  report("cut", 0.05);
  auto model = std::make_unique<occ::GridModel>(occ::build_grid_model(*part_, setup_->go));
  if (!model->done) PARAFAB_INPUT_ERROR("cannot cut " << part_path_ << " by the grid: " << model->message);
  model_ = std::move(model);
  return solve(out_dir, report, json(nullptr));
}

// The results q (probe displacements, or the largest displacement without probes) on grids
// refined by r = 1.5. The relative change Δ_k = ‖q_k − q_{k−1}‖ / ‖q_k‖ gives, with the
// observed order p = log(Δ_{k−1}/Δ_k) / log r, clamped to [0.5, 1], the Richardson estimate
// of the error of the finest grid, e_k = Δ_k / (r^p − 1). The cap at first order is on
// purpose: with Nitsche on partly cut faces the bracket converges like h before it converges
// like h², and a higher observed order there underestimated its error 2× (README). Stops when
// e_k ≤ target (at least three grids), or at grid.max_cells / the memory limit (not met).
template <class Report>
json SimulationSession::run_to_target(const std::string& out_dir, const Report& report) {
  Setup& S = *setup_;
  const double ratio = 1.5;
  json levels = json::array(), out;
  std::vector<Eigen::VectorXd> q;
  std::vector<double> change;
  double estimated = std::numeric_limits<double>::infinity(), order = 1;
  bool met = false;
  std::string stop;
  for (int cells = S.go.grid.cells_longest;; cells = static_cast<int>(std::lround(cells * ratio))) {
    if (cells > S.max_cells) {
      stop = "grid.max_cells (" + std::to_string(S.max_cells) + ") reached";
      break;
    }
    S.go.grid.cells_longest = cells;
    S.set_estimate();
    if (S.factor_mb > 0.7 * S.physical_mb) {
      stop = "the next grid (" + std::to_string(cells) + " cells) would not fit in memory";
      break;
    }
    report("cut", 0.05);
    auto model = std::make_unique<occ::GridModel>(occ::build_grid_model(*part_, S.go));
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
    if (estimated <= S.target) {
      met = true;
      break;
    }
  }
  if (q.empty()) PARAFAB_INPUT_ERROR("grid.target: no grid could be run: " << stop);
  out["accuracy"] = {{"target", S.target}, {"met", met}, {"estimated_error", std::isfinite(estimated) ? json(estimated) : json(nullptr)},
                     {"order", order}, {"quantity", out["probes"].empty() ? "max_displacement" : "probe displacements"},
                     {"levels", levels}, {"stopped", met ? "target met" : stop}};
  if (!out_dir.empty()) std::ofstream(out_dir + "/result.json") << out.dump(2) << "\n";
  return out;
}

json SimulationSession::update(const std::string& new_part_path, const std::string& out_dir, const ProgressFn& progress) {
  auto report = [&](const char* phase, double fraction) {
    if (progress && !progress(phase, fraction)) PARAFAB_INPUT_ERROR("simulation cancelled by the user (during " << phase << ")");
  };
  if (!model_) return run(out_dir, progress);
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
  report("cut", 0.05);
  occ::RecutReport rr;
  auto model = std::make_unique<occ::GridModel>(occ::rebuild_grid_model(*part_, *model_, *old_part, setup_->go, &rr));
  if (!model->done) PARAFAB_INPUT_ERROR("cannot cut " << new_part_path << " by the grid: " << model->message);
  model_ = std::move(model);
  const json recut{{"full", rr.full}, {"message", rr.message}, {"changed_faces", rr.changed_faces},
                   {"changed_edges", rr.changed_edges}, {"regions", rr.regions}, {"verified", rr.verified},
                   {"blocks", rr.blocks}, {"blocks_recut", rr.blocks_recut},
                   {"subvolumes_kept", rr.subvolumes_kept}, {"subvolumes_new", rr.subvolumes_new}};
  return solve(out_dir, report, recut);
}

template <class Report>
json SimulationSession::solve(const std::string& out_dir, const Report& report, const json& recut) {
  const Setup& S = *setup_;
  const occ::GridModel& grid = *model_;
  const auto& mat = S.mat;
  const double diag = S.extent.norm();
  report("assemble", 0.6);
  xfem::LinearXfemResult r;
  json newton = nullptr;
  StressFn stress;
  report(model_name_is_linear(S.model) ? "solve" : "newton", 0.65);
  if (model_name_is_linear(S.model)) {
    r = xfem::solve_linear(grid.elements, grid.adjacent, mat, S.dirichlet, S.tractions, S.fo);
    stress = [&](int e, const Vec3& X) { return xfem::stress_at(r, grid.elements, mat, e, X); };
  } else {
    xfem::NonlinearXfemOptions no;
    no.boundary = S.fo;
    no.load_steps = S.load_steps;
    const xfem::NonlinearXfemResult nr =
        xfem::solve_nonlinear(grid.elements, grid.adjacent, *S.law, mat, S.dirichlet, S.tractions, no);
    if (!nr.converged) PARAFAB_INPUT_ERROR("the hyperelastic simulation did not converge: " << nr.message);
    r = nr.as_linear();
    r.solve_seconds = nr.seconds;
    r.energy = nr.energy;
    newton = {{"iterations", nr.iterations}, {"residuals", nr.residuals}, {"load_steps", no.load_steps}};
    const xfem::Material* law = S.law.get();
    stress = [&r, &grid, law](int e, const Vec3& X) {  // Cauchy stress σ = P Fᵀ / J
      const Eigen::Matrix3d F = Eigen::Matrix3d::Identity() + xfem::displacement_gradient(r, grid.elements, e, X);
      const Eigen::Matrix3d sig = law->stress(F) * F.transpose() / F.determinant();
      Eigen::Matrix<double, 6, 1> v;
      v << sig(0, 0), sig(1, 1), sig(2, 2), sig(0, 1), sig(1, 2), sig(0, 2);
      return v;
    };
  }
  if (!r.solved) PARAFAB_INPUT_ERROR("the simulation could not be solved: " << r.message);
  report("results", 0.9);
  double umax = 0, vmmax = 0;
  xfem::MassAccumulator acc;
  for (size_t e = 0; e < grid.elements.size(); ++e) {
    const auto& el = grid.elements[e];
    acc.add(el.rule.points, el.rule.weights);
    for (const Vec3& X : el.rule.points) {
      umax = std::max(umax, r.displacement(grid.elements, static_cast<int>(e), X).norm());
      vmmax = std::max(vmmax, xfem::von_mises(stress(static_cast<int>(e), X)));
    }
  }
  const ElementLocator locator(grid);
  json probes = json::array();
  if (job_.contains("probes"))
    for (size_t i = 0; i < job_["probes"].size(); ++i) {
      const Vec3 X = vec3(job_["probes"][i], "probes[" + std::to_string(i) + "]");
      const int best = locator.find(X);
      if (best < 0) PARAFAB_INPUT_ERROR("probes[" << i << "] lies outside the grid");
      const Vec3 u = r.displacement(grid.elements, best, X);
      const auto s = stress(best, X);
      probes.push_back({{"point", {X.x(), X.y(), X.z()}}, {"displacement", {u.x(), u.y(), u.z()}},
                        {"von_mises", xfem::von_mises(s)},
                        {"stress", {s(0), s(1), s(2), s(3), s(4), s(5)}}});
    }
  const xfem::MassProperties mp = acc.result();
  json out{{"part", part_path_},
           {"grid", {{"cells", grid.cut->cells}, {"cell_size", grid.cut->cell_size.x()},
                     {"cut_cells", grid.cut->cut_cells.size()}, {"subvolumes", grid.cut->subvolumes.size()},
                     {"interior_cells", grid.cut->interior_cells.size()},
                     {"method", grid.cut->method == occ::CutMethod::FaceCut ? "face" : "splitter"},
                     {"fallback_reason", grid.cut->fallback_reason}}},
           {"dofs", r.dofs},
           {"estimate", {{"unknowns", S.dofs}, {"factor_mb", S.factor_mb}}},
           {"max_displacement", umax},
           {"max_von_mises", vmmax},
           {"potential", r.energy},  // the minimized functional (strain energy, Nitsche and load terms), up to a constant
           {"material_model", S.model},
           {"aggregated_nodes", r.aggregated_nodes},
           {"newton", newton},
           {"recut", recut},
           {"mass_properties", {{"volume", mp.volume}, {"mass", mp.volume * mat.density},
                                {"center", {mp.center.x(), mp.center.y(), mp.center.z()}}}},
           {"probes", probes},
           {"message", r.message},
           {"seconds", {{"cut", grid.cut_seconds}, {"rules", grid.rule_seconds},
                        {"assemble", r.assemble_seconds}, {"solve", r.solve_seconds}}},
           {"units", "those of the part and material (e.g. mm, N, MPa)"}};
  if (!out_dir.empty()) {
    std::filesystem::create_directories(out_dir);
    report("write", 0.95);
    write_vtu(out_dir + "/result.vtu", grid.elements, r, stress);
    // The exact boundary, triangulated to a tenth of a cell and to edges of at most half a
    // cell, with the fields at its vertices.
    const double cell = grid.cut->cell_size.x();
    const occ::SurfaceMesh mesh = occ::triangulate_part(*part_, 0.1 * cell, 0.5 * cell);
    std::vector<Vec3> sdisp(mesh.points.size(), Vec3::Zero());
    std::vector<double> svm(mesh.points.size(), 0.0);
    for (size_t i = 0; i < mesh.points.size(); ++i) {
      const int e = locator.find(mesh.points[i]);
      if (e < 0) continue;  // cannot happen for points of the part; keep zero rather than fail
      sdisp[i] = r.displacement(grid.elements, e, mesh.points[i]);
      svm[i] = xfem::von_mises(stress(e, mesh.points[i]));
    }
    write_surface_vtu(out_dir + "/surface.vtu", mesh, sdisp, svm);
    out["files"] = {out_dir + "/result.json", out_dir + "/result.vtu", out_dir + "/surface.vtu"};
    std::ofstream(out_dir + "/result.json") << out.dump(2) << "\n";
  }
  return out;
}

json simulate_part_json(const std::string& part_path, const json& job, const std::string& out_dir,
                        const ProgressFn& progress) {
  if (progress && !progress("read", 0.0)) PARAFAB_INPUT_ERROR("simulation cancelled by the user (during read)");
  SimulationSession session(part_path, job);
  return session.run(out_dir, progress);
}

}  // namespace parafab::entry
