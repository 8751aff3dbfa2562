// The `parafab` command line: thin over the same JSON calls as the Python module.
// Exit codes: 0 result written (a strip or rod may still be infeasible: see "feasible"),
// 2 invalid input (JSON error on stdout), 1 internal error.
#include <CLI/CLI.hpp>
#include <unistd.h>

#include <csignal>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <sstream>

#include "common/error.h"
#include "install_paths.h"
#include "occt_version.h"
#include "part_json.h"
#include "integrate_json.h"
#include "revolution_json.h"
#include "sections_json.h"
#include "simulate_json.h"
#include "optimize_json.h"
#include "outline_export.h"
#include "strip_json.h"
#include "stability_json.h"
#include "strip_improve_json.h"
#include "strip_stabilize_json.h"
#include "rod_json.h"
#include "output_files.h"
#include "part_preflight.h"
#include "request_schema.h"
#include "xfem/petsc_system.h"

namespace {

using nlohmann::json;

int emit(const json& j, const std::string& out_path) {
  const std::string text = j.dump(2);
  if (out_path.empty()) {
    if (!(std::cout << text << "\n" << std::flush)) {  // a full disk, a closed pipe: not a success
      std::cerr << "parafab: cannot write the result to standard output\n";
      return 2;
    }
    return 0;
  }
  try {
    parafab::entry::write_text_atomically(out_path, text + "\n");  // temporary name, then rename
  } catch (const parafab::Error&) {
    std::cout << parafab::entry::error_json("cannot write output file " + out_path, "io").dump(2) << "\n";
    return 2;
  }
  return 0;
}

// SIGINT / SIGTERM during `parafab optimize`: the first one asks the run to stop at the next
// evaluation and write its best valid iterate (exit 128 + signal); a second one kills at once.
volatile std::sig_atomic_t interrupt_signal = 0;
extern "C" void on_interrupt(int signal_number) {
  interrupt_signal = signal_number;
  std::signal(signal_number, SIG_DFL);
  const char note[] = "parafab: interrupted; writing the best valid iterate so far (again to stop at once)\n";
  [[maybe_unused]] const auto written = ::write(2, note, sizeof(note) - 1);
}

int fail(const std::string& message, const std::string& kind, int code) {
  std::cout << parafab::entry::error_json(message, kind).dump(2) << "\n";
  return code;
}

json read_json_file(const std::string& path) {
  if (std::filesystem::is_directory(path)) throw parafab::Error("input file " + path + " is a folder, not a file");
  std::ifstream f(path);
  if (!f) throw parafab::Error("cannot open input file " + path);
  std::stringstream ss;
  ss << f.rdbuf();
  if (ss.str().find_first_not_of(" \t\r\n") == std::string::npos)
    throw parafab::Error("input file " + path + " is empty");
  // Nesting deeper than the formats need is refused while parsing (copies of a request nested
  // thousands deep would exhaust the stack).
  const auto depth_limit = [&](int depth, json::parse_event_t event, json&) {
    if (depth > parafab::entry::schema::kMaxDepth && (event == json::parse_event_t::object_start ||
                                                       event == json::parse_event_t::array_start))
      throw parafab::Error("input file " + path + " nests objects or lists deeper than " +
                           std::to_string(parafab::entry::schema::kMaxDepth) + " levels");
    return true;
  };
  try {
    return json::parse(ss.str(), depth_limit);
  } catch (const json::parse_error& e) {
    throw parafab::Error("input file " + path + " is not valid JSON (byte " +
                         std::to_string(e.byte) + "): " + e.what());
  } catch (const json::exception& e) {  // a number out of range (1e400), ...
    throw parafab::Error("input file " + path + " is not valid JSON: " + e.what());
  }
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"ParaFab: fabrication-aware design of bending-active strips, rods and CAD parts"};
  app.require_subcommand(1);
  std::string in_path, out_path;
  auto* strip = app.add_subcommand("strip", "Design a bending-active strip for a plane curve (JSON in, JSON out)");
  strip->add_option("input", in_path, "Strip request JSON (see resources/doc/json-reference.md)")->required();
  strip->add_option("-o,--output", out_path, "Write the result here instead of stdout");
  std::string dxf_path, svg_path;
  strip->add_option("--dxf", dxf_path, "Also write the flat outline (cut sheet, mm) as ASCII DXF R12");
  strip->add_option("--svg", svg_path, "Also write the flat outline (cut sheet, mm) as SVG");
  auto* strip_stability = app.add_subcommand(
      "strip-stability",
      "Stability of a designed strip: Jacobi test (conjugate point sigma, Z(s)) and the simulator's "
      "constrained Hessian inertia, with timings (JSON in, JSON out)");
  strip_stability->add_option("input", in_path, "Strip request JSON (as for `parafab strip`)")->required();
  strip_stability->add_option("-o,--output", out_path, "Write the result here instead of stdout");
  double target_R = 0;
  auto* improve = app.add_subcommand(
      "strip-improve", "Lower the stiffness ratio R of a strip curve by moving its control points (thesis §4.6.2; JSON)");
  improve->add_option("input", in_path, "Strip request JSON, optionally with \"improve\": {...} (see resources/doc/strips.md)")->required();
  improve->add_option("--target-R", target_R, "Target stiffness ratio (overrides improve.target_R; default 3.5)")
      ->check(CLI::PositiveNumber);  // 0 stands for "not given" below: a given value must be > 0
  improve->add_option("-o,--output", out_path, "Write the result here instead of stdout");
  double R_max = 0;
  auto* stabilize = app.add_subcommand(
      "strip-stabilize",
      "Make an unstable strip curve stable by moving its control points (thesis §4.5.4, Algorithm 4.2; JSON)");
  stabilize->add_option("input", in_path, "Strip request JSON, optionally with \"stabilize\": {...} (see resources/doc/strips.md)")->required();
  stabilize->add_option("--R-max", R_max, "Bound on the stiffness ratio R (overrides stabilize.R_max; default 10)")
      ->check(CLI::PositiveNumber);
  stabilize->add_option("-o,--output", out_path, "Write the result here instead of stdout");
  auto* rod = app.add_subcommand("rod", "Design a Kirchhoff rod for a space curve (JSON in, JSON out)");
  rod->add_option("input", in_path, "Rod request JSON (see resources/doc/json-reference.md)")->required();
  rod->add_option("-o,--output", out_path, "Write the result here instead of stdout");
  auto* inspect = app.add_subcommand("inspect", "Face model of a STEP/BREP part: types, NURBS, edges, tangencies (JSON)");
  parafab::entry::InspectOptions inspect_options;
  inspect->add_option("part", in_path, "Part file (.step/.stp/.brep/.brp)")->required();
  inspect->add_option("--solid", inspect_options.read.solid_index, "Index of the solid when the file holds several");
  inspect->add_option("--solid-name", inspect_options.read.solid_name, "Name of the solid (STEP product) to inspect");
  inspect->add_option("-o,--output", out_path, "Write the result here instead of stdout");
  auto* integrate = app.add_subcommand(
      "integrate", "Volume, centre of mass and inertia of a part by cut-cell quadrature on a grid, beside OCCT's (JSON)");
  parafab::entry::IntegrateOptions integrate_options;
  std::string segments = "parabolic";
  integrate->add_option("part", in_path, "Part file (.step/.stp/.brep/.brp)")->required();
  integrate->add_option("--cells", integrate_options.integration.grid.cells_longest,
                        "Cells along the longest side of the bounding box")->check(CLI::Range(1, 100000));
  integrate->add_option("--cell-size", integrate_options.integration.grid.cell_size,
                        "Cell size in model units (overrides --cells)")->check(CLI::NonNegativeNumber);
  integrate->add_option("--segments", segments, "Boundary curve segments: parabolic or linear")
      ->check(CLI::IsMember({"parabolic", "linear"}));
  integrate->add_option("--solid", integrate_options.read.solid_index, "Index of the solid when the file holds several");
  integrate->add_flag("--non-negative", "Non-negative weights (NNLS fit) for the cut-cell rules");
  integrate->add_flag("--nurbs", integrate_options.integration.grid.nurbs,
                      "Convert faces to NURBS before cutting (patches then use the face model's NURBS)");
  integrate->add_flag("--estimate", integrate_options.estimate_only,
                      "Only print the size estimate {cells, cut_cells, memory_mb, seconds, fits}; do not cut");
  integrate->add_flag("--force", integrate_options.force,
                      "Run even when the estimate exceeds 70% of the memory (refused by default)");
  integrate->add_option("-o,--output", out_path, "Write the result here instead of stdout");
  auto* simulate = app.add_subcommand("simulate", "Linear elastic XFEM simulation of a part on a fixed grid (JSON job)");
  std::string job_path, out_dir;
  simulate->add_option("part", in_path, "Part file (.step/.stp/.brep/.brp)")->required();
  simulate->add_option("job", job_path, "Job JSON: material, grid, supports, loads, gravity, probes")->required();
  simulate->add_option("-o,--output", out_dir, "Folder for result.json, result.vtu and surface.vtu");
  bool show_progress = false, estimate_only = false;
  int simulate_threads = -1;
  simulate->add_option("--threads", simulate_threads,
                       "Threads for rules, assembly and result writing (overrides the job's \"threads\"; "
                       "default: all cores)")->check(CLI::PositiveNumber);
  simulate->add_flag("--estimate", estimate_only,
                     "Only print the size estimate {unknowns, factor_mb, factor_mb_min, peak_mb, peak_mb_min, limit_mb, memory_mb, fits, may_fit, cut}; do not run");
  simulate->add_flag("--progress", show_progress,
                     "Print one JSON line per phase to stderr: {\"progress\": {\"phase\": ..., \"fraction\": ...}}");
  auto* sections = app.add_subcommand(
      "sections", "Strips from plane sections of a surface or solid (JSON job: planes, split, strip request)");
  sections->add_option("part", in_path, "Surface or solid (.step/.stp/.brep/.brp)")->required();
  sections->add_option("job", job_path, "Sections job JSON (see resources/doc/strips.md: Strips from sections)")->required();
  sections->add_option("-o,--output", out_path, "Write the result here instead of stdout");
  auto* revolution = app.add_subcommand(
      "revolution", "Meridian of a surface of revolution tiled by strips without gaps, and the strips (JSON)");
  revolution->add_option("job", in_path, "Revolution job JSON (see resources/doc/strips.md)")->required();
  revolution->add_option("-o,--output", out_path, "Write the result here instead of stdout");
  auto* optimize = app.add_subcommand(
      "optimize", "Shape optimization of a part on its own CAD parameters, tangencies kept (JSON job)");
  optimize->add_option("part", in_path, "Part file (.step/.stp/.brep/.brp); only read")->required();
  optimize->add_option("job", job_path, "Job JSON: parameters, objective, constraints, max_iterations")->required();
  optimize->add_option("-o,--output", out_dir, "Folder for optimized.step, history.json and history.png")->required();
  bool optimize_progress = false;
  optimize->add_flag("--progress", optimize_progress, "Print one JSON line per iterate to stderr");
  auto* version = app.add_subcommand(
      "version", "Print the versions and the folder of the chart scripts used, as JSON");
  auto* reference = app.add_subcommand(
      "reference", "Print the JSON reference (Markdown): the known keys of every request and job");
  reference->add_option("-o,--output", out_path, "Write it to this file instead of stdout");
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    if (e.get_exit_code() == 0) return app.exit(e);
    return fail(std::string("command line: ") + e.what() + " (see parafab --help)", "usage", 2);
  }
  try {
    // Parts are read once in a child process first: OCCT crashing on a corrupt STEP file is then
    // an input error (exit 2, JSON), not a segmentation fault.
    // An output that is an input of the same run is refused before any work (a job file in the
    // output folder, `inspect X.step -o X.step`).
    {
      std::vector<std::string> outputs{out_path, dxf_path, svg_path};
      if (*simulate && !out_dir.empty())
        for (const char* name : {"result.json", "result.vtu", "surface.vtu"}) outputs.push_back(out_dir + "/" + name);
      if (*optimize)
        for (const char* name : {"optimized.step", "history.json", "history.png", "nearest_valid.step"})
          outputs.push_back(out_dir + "/" + name);
      for (const std::string& o : outputs)
        for (const std::string& i : {in_path, job_path}) parafab::entry::refuse_output_over_input(o, i);
    }
    if (*inspect || *integrate || *simulate || *optimize || *sections) parafab::entry::preflight_part_read(in_path);
    // Under `mpirun -np N`: every rank runs the job and takes part in the distributed solves
    // (xfem::PetscSystem); rank 0 alone prints and writes.
    if (parafab::xfem::launched_ranks() > 1) {
      parafab::xfem::petsc_initialize();  // collective; an input error in a build without PETSc
      if (parafab::xfem::petsc_rank() > 0) {
        out_path.clear(), dxf_path.clear(), svg_path.clear(), out_dir.clear();
        show_progress = optimize_progress = false;
        if (!std::freopen("/dev/null", "w", stdout)) return 1;
      }
    }
    if (*reference) {
      const std::string md = parafab::entry::schema::reference_markdown();
      if (out_path.empty()) {
        std::cout << md;
        return 0;
      }
      parafab::entry::write_text_atomically(out_path, md);
      return 0;
    }
    if (*version)
      return emit(json{{"parafab", parafab::entry::version()},
                       {"opencascade", parafab::occ::occt_version()},
                       {"scripts", parafab::entry::scripts_dir()}},
                  out_path);
    if (*strip) {
      const json result = parafab::entry::design_strip_json(read_json_file(in_path));
      // Cut sheets first: an infeasible design has no outline (exit 2, JSON error).
      if (!dxf_path.empty()) parafab::entry::write_strip_outline(result, dxf_path);
      if (!svg_path.empty()) parafab::entry::write_strip_outline(result, svg_path);
      return emit(result, out_path);
    }
    if (*strip_stability)
      return emit(parafab::entry::strip_stability_json(read_json_file(in_path)), out_path);
    if (*improve) return emit(parafab::entry::improve_strip_json(read_json_file(in_path), target_R), out_path);
    if (*stabilize) return emit(parafab::entry::stabilize_strip_json(read_json_file(in_path), R_max), out_path);
    if (*rod) return emit(parafab::entry::design_rod_json(read_json_file(in_path)), out_path);
    if (*inspect) return emit(parafab::entry::inspect_part_json(in_path, inspect_options), out_path);
    if (*simulate) {
      parafab::entry::ProgressFn progress;
      if (show_progress)
        progress = [](const char* phase, double fraction) {
          std::cerr << json{{"progress", {{"phase", phase}, {"fraction", fraction}}}}.dump() << std::endl;
          return true;
        };
      json job = read_json_file(job_path);
      if (simulate_threads > 0 && job.is_object()) job["threads"] = simulate_threads;
      if (estimate_only) return emit(parafab::entry::SimulationSession(in_path, job).estimate(), "");
      return emit(parafab::entry::simulate_part_json(in_path, job, out_dir, progress), "");
    }
    if (*optimize) {
      parafab::entry::OptimizeProgressFn progress;
      if (optimize_progress)
        progress = [](const json& it) {
          std::cerr << json{{"progress", it}}.dump() << std::endl;
          return interrupt_signal == 0;
        };
      std::signal(SIGINT, on_interrupt);
      std::signal(SIGTERM, on_interrupt);
      const json history = parafab::entry::optimize_part_json(in_path, read_json_file(job_path), out_dir, progress,
                                                              [] { return interrupt_signal != 0; });
      const int code = emit(history, "");
      return interrupt_signal != 0 ? 128 + interrupt_signal : code;
    }
    if (*revolution) return emit(parafab::entry::revolution_strips_json(read_json_file(in_path)), out_path);
    if (*sections) return emit(parafab::entry::strip_sections_json(in_path, read_json_file(job_path)), out_path);
    if (*integrate) {
      integrate_options.integration.grid.segment_order = segments == "linear" ? 1 : 2;
      if (integrate->count("--non-negative"))
        integrate_options.integration.rule.fit = parafab::xfem::WeightFit::NonNegative;
      return emit(parafab::entry::integrate_part_json(in_path, integrate_options), out_path);
    }
  } catch (const parafab::Error& e) {
    return fail(e.what(), "invalid_input", 2);
  } catch (const std::exception& e) {
    return fail(std::string("internal error: ") + e.what(), "internal", 1);
  }
  return 0;
}
