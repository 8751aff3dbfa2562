// The `parafab` Python module: the same JSON calls as the CLI, with dicts in and out.
// parafab.Error (a ValueError) is raised for invalid input, with the offending field named.
#include <pybind11/pybind11.h>

#include <cmath>
#include <cstdint>
#include <utility>

#include "request_schema.h"
#include "xfem/petsc_system.h"
#include "common/error.h"
#include "install_paths.h"
#include "occt_version.h"
#include "integrate_json.h"
#include "part_json.h"
#include "revolution_json.h"
#include "sections_json.h"
#include "simulate_json.h"
#include "optimize_json.h"
#include "outline_export.h"
#include "json_write.h"
#include "strip_json.h"
#include "stability_json.h"
#include "strip_improve_json.h"
#include "strip_stabilize_json.h"
#include "rod_json.h"

namespace py = pybind11;

namespace {

// What a Python progress callback returned: None or True go on, False stops; anything else
// ("stop", 0) is an error naming it rather than a guess.
bool keep_going_of(const py::object& r) {
  if (r.is_none()) return true;
  if (py::isinstance<py::bool_>(r)) return r.cast<bool>();
  throw parafab::Error("the progress callback must return True, False or None, got " +
                       py::repr(r).cast<std::string>());
}

// progress(phase, fraction) from Python; returning False cancels the run.
parafab::entry::ProgressFn progress_function(const py::object& progress) {
  if (progress.is_none()) return {};
  return [progress](const char* phase, double fraction) {
    py::gil_scoped_acquire acquire;
    return keep_going_of(progress(phase, fraction));
  };
}
// dict -> nlohmann::json through Python's own json module (exact for floats and ints): the
// reference route, and the fallback for what the direct conversion below does not take.
nlohmann::json to_json_text(const py::object& obj) {
  py::module_ json = py::module_::import("json");
  try {
    return nlohmann::json::parse(py::str(json.attr("dumps")(obj, py::arg("allow_nan") = true))
                                     .cast<std::string>());
  } catch (const nlohmann::json::parse_error&) {
    // NaN / Infinity are not JSON: report them as the invalid numbers they are.
    throw parafab::Error("the request contains NaN or infinite numbers");
  }
}

// The direct conversion gives up (and to_json falls back to the text route, with its errors)
// on anything json.dumps would not write as plain JSON: non-string keys, other types, deep
// or circular nesting.
struct NotPlainJson {};

// Python -> nlohmann::json without text, the same values as json.dumps + parse: float repr
// round-trips exactly, non-negative ints parse as unsigned and negative ones as signed, ints
// beyond 64 bits as the nearest double.
nlohmann::json to_json_direct(PyObject* o, int depth) {
  if (depth > parafab::entry::schema::kMaxDepth)
    throw parafab::Error("the request nests lists or dicts deeper than " +
                         std::to_string(parafab::entry::schema::kMaxDepth) + " levels");
  if (o == Py_None) return nullptr;
  if (PyBool_Check(o)) return o == Py_True;
  if (PyFloat_Check(o)) {
    const double x = PyFloat_AS_DOUBLE(o);
    if (!std::isfinite(x)) throw parafab::Error("the request contains NaN or infinite numbers");
    return x;
  }
  if (PyLong_Check(o)) {
    int overflow = 0;
    const long long v = PyLong_AsLongLongAndOverflow(o, &overflow);
    if (overflow == 0) {
      if (v == -1 && PyErr_Occurred()) throw py::error_already_set();
      if (v >= 0) return static_cast<std::uint64_t>(v);
      return static_cast<std::int64_t>(v);
    }
    if (overflow > 0) {
      const unsigned long long u = PyLong_AsUnsignedLongLong(o);
      if (!PyErr_Occurred()) return static_cast<std::uint64_t>(u);
      PyErr_Clear();
    }
    throw NotPlainJson{};  // beyond 64 bits: the text route decides
  }
  if (PyUnicode_Check(o)) {
    Py_ssize_t n = 0;
    const char* c = PyUnicode_AsUTF8AndSize(o, &n);
    if (!c) throw py::error_already_set();
    return std::string(c, static_cast<size_t>(n));
  }
  if (PyList_Check(o) || PyTuple_Check(o)) {
    const bool list = PyList_Check(o);
    const Py_ssize_t n = list ? PyList_GET_SIZE(o) : PyTuple_GET_SIZE(o);
    nlohmann::json a = nlohmann::json::array();
    a.get_ref<nlohmann::json::array_t&>().reserve(static_cast<size_t>(n));
    for (Py_ssize_t i = 0; i < n; ++i)
      a.push_back(to_json_direct(list ? PyList_GET_ITEM(o, i) : PyTuple_GET_ITEM(o, i), depth + 1));
    return a;
  }
  if (PyDict_Check(o)) {
    nlohmann::json d = nlohmann::json::object();
    PyObject *key = nullptr, *value = nullptr;
    Py_ssize_t pos = 0;
    while (PyDict_Next(o, &pos, &key, &value)) {
      if (!PyUnicode_CheckExact(key)) throw NotPlainJson{};
      Py_ssize_t n = 0;
      const char* c = PyUnicode_AsUTF8AndSize(key, &n);
      if (!c) throw py::error_already_set();
      d[std::string(c, static_cast<size_t>(n))] = to_json_direct(value, depth + 1);
    }
    return d;
  }
  throw NotPlainJson{};
}

nlohmann::json to_json(const py::object& obj) {
  try {
    return to_json_direct(obj.ptr(), 0);
  } catch (const NotPlainJson&) {
    return to_json_text(obj);
  }
}

// nlohmann::json -> Python objects without text, the same values as json.loads(j.dump()):
// non-finite floats become None (dump writes null), objects keep the sorted key order.
// Raw C API (new references; nullptr with a Python error set on failure).
PyObject* to_python_raw(const nlohmann::json& j) {
  using V = nlohmann::json::value_t;
  switch (j.type()) {
    case V::null: Py_RETURN_NONE;
    case V::boolean: if (j.get<bool>()) Py_RETURN_TRUE; else Py_RETURN_FALSE;
    case V::number_integer: return PyLong_FromLongLong(j.get<std::int64_t>());
    case V::number_unsigned: return PyLong_FromUnsignedLongLong(j.get<std::uint64_t>());
    case V::number_float: {
      const double x = j.get<double>();
      if (!std::isfinite(x)) Py_RETURN_NONE;
      return PyFloat_FromDouble(x);
    }
    case V::string: {
      const std::string& t = j.get_ref<const std::string&>();
      return PyUnicode_DecodeUTF8(t.data(), static_cast<Py_ssize_t>(t.size()), "strict");
    }
    case V::array: {  // the underlying vector and doubles directly: nlohmann's iterators and
                      // get<double>() switch on the type at every step
      const auto& elements = j.get_ref<const nlohmann::json::array_t&>();
      PyObject* a = PyList_New(static_cast<Py_ssize_t>(elements.size()));
      if (!a) return nullptr;
      Py_ssize_t i = 0;
      for (const auto& e : elements) {
        const double* x = e.get_ptr<const double*>();
        PyObject* v = x && std::isfinite(*x) ? PyFloat_FromDouble(*x) : to_python_raw(e);
        if (!v) { Py_DECREF(a); return nullptr; }
        PyList_SET_ITEM(a, i++, v);
      }
      return a;
    }
    case V::object: {
      PyObject* d = PyDict_New();
      if (!d) return nullptr;
      for (const auto& [k, value] : j.get_ref<const nlohmann::json::object_t&>()) {
        PyObject* key = PyUnicode_DecodeUTF8(k.data(), static_cast<Py_ssize_t>(k.size()), "strict");
        PyObject* v = key ? to_python_raw(value) : nullptr;
        const int rc = v ? PyDict_SetItem(d, key, v) : -1;
        Py_XDECREF(key);
        Py_XDECREF(v);
        if (rc != 0) { Py_DECREF(d); return nullptr; }
      }
      return d;
    }
    default: {  // binary, discarded: the text route
      py::object o = py::module_::import("json").attr("loads")(j.dump());
      return o.release().ptr();
    }
  }
}

// The cyclic collector paused while a result is built: its thousands of new lists would
// otherwise trigger young-generation passes over objects that cannot form cycles yet (they
// stay tracked, so later passes see them). Restores the previous state.
class CollectorPause {
 public:
#if PY_VERSION_HEX >= 0x030A0000
  CollectorPause() : was_enabled_(PyGC_Disable()) {}
  ~CollectorPause() { if (was_enabled_) PyGC_Enable(); }
 private:
  int was_enabled_;
#endif
};

py::object to_python(const nlohmann::json& j) {
  const CollectorPause pause;
  PyObject* o = to_python_raw(j);
  if (!o) throw py::error_already_set();
  return py::reinterpret_steal<py::object>(o);
}

// A result about to be dropped: converted, then freed bottom-up (json_write::dismantle), which
// is cheaper than nlohmann's destructor on a tree of thousands of small arrays.
py::object to_python(nlohmann::json&& j) {
  py::object o = to_python(static_cast<const nlohmann::json&>(j));
  parafab::entry::json_write::dismantle(j);
  return o;
}

// A column's rows as a list of floats (width 1) or of [x, y(, z)] lists; non-finite numbers
// become None, as in to_python_raw. New reference, nullptr with a Python error set on failure.
PyObject* column_to_python(const parafab::entry::json_write::Column& c) {
  const size_t w = static_cast<size_t>(c.width), rows = c.values.size() / w;
  auto number = [](double x) -> PyObject* {
    if (std::isfinite(x)) return PyFloat_FromDouble(x);
    Py_RETURN_NONE;
  };
  PyObject* list = PyList_New(static_cast<Py_ssize_t>(rows));
  if (!list) return nullptr;
  for (size_t r = 0; r < rows; ++r) {
    PyObject* item = nullptr;
    if (w == 1) {
      item = number(c.values[r]);
    } else if ((item = PyList_New(static_cast<Py_ssize_t>(w)))) {
      for (size_t k = 0; k < w; ++k) {
        PyObject* x = number(c.values[r * w + k]);
        if (!x) { Py_CLEAR(item); break; }
        PyList_SET_ITEM(item, static_cast<Py_ssize_t>(k), x);
      }
    }
    if (!item) { Py_DECREF(list); return nullptr; }
    PyList_SET_ITEM(list, static_cast<Py_ssize_t>(r), item);
  }
  return list;
}

// A columnar result: the tree converted (each column's key holds None there, in its sorted
// place), then every column put in its place; equal to to_python(expand(r)).
py::object to_python(parafab::entry::json_write::ColumnarResult&& r) {
  const CollectorPause pause;
  py::object root = to_python(std::move(r.tree));
  for (const auto& c : r.columns) {
    py::dict parent = root;
    for (size_t k = 0; k + 1 < c.path.size(); ++k) parent = parent[c.path[k].c_str()].cast<py::dict>();
    PyObject* list = column_to_python(c);
    if (!list) throw py::error_already_set();
    parent[c.path.back().c_str()] = py::reinterpret_steal<py::object>(list);
  }
  return root;
}
}  // namespace

PYBIND11_MODULE(parafab, m) {
  m.doc() = "ParaFab: bending-active strips (thesis ch. 4); rods and X-CAD follow.";
  const auto error = py::register_exception<parafab::Error>(m, "Error", PyExc_ValueError);
  // Registered after Error, so tried first: a cancelled run is parafab.Cancelled (a parafab.Error).
  py::register_exception<parafab::Cancelled>(m, "Cancelled", error.ptr());
  parafab::xfem::disallow_petsc_in_process(
      "solver.type \"petsc\": the PETSc solver runs in the CLI (parafab simulate / optimize, also under "
      "mpirun -np N), not inside Python; \"auto\" and \"cholmod\" solve here with CHOLMOD");
  m.def(
      "strip_stability",
      [](const py::dict& request) {
        const nlohmann::json in = to_json(request);
        nlohmann::json out;
        {
          py::gil_scoped_release release;
          out = parafab::entry::strip_stability_json(in);
        }
        return to_python(std::move(out));
      },
      py::arg("request"),
      "Stability of a designed strip (thesis 4.5): a strip request as for design_strip; returns "
      "feasible, R, ... and `stability` {stable, sigma, method, s, Z, eigenvalue {stable, negative, "
      "min_eigenvalue, ...}, agree, seconds}. Optional request field stability: {edges, "
      "eigenvalue_check (default true here), simulation_edges}.");
  m.def(
      "strip_improve",
      [](const py::dict& request, double target_R) {
        const nlohmann::json in = to_json(request);
        nlohmann::json out;
        {
          py::gil_scoped_release release;
          out = parafab::entry::improve_strip_json(in, target_R);
        }
        return to_python(std::move(out));
      },
      py::arg("request"), py::arg("target_R") = 0.0,
      "Fabricability optimization (thesis §4.6.2): move the control points of the request's curve "
      "until the stiffness ratio R is at most target_R (> 0 overrides request['improve']['target_R'], "
      "default 3.5). Returns done, status, R_initial, R, bspline, original_bspline, max_pole_move, "
      "deviation, history and the strip designed for the new curve (design; with the request's "
      "gravity, LP Eq. 4.6 afterwards).");
  m.def(
      "stabilize_strip",
      [](const py::dict& request, double R_max) {
        const nlohmann::json in = to_json(request);
        nlohmann::json out;
        {
          py::gil_scoped_release release;
          out = parafab::entry::stabilize_strip_json(in, R_max);
        }
        return to_python(std::move(out));
      },
      py::arg("request"), py::arg("R_max") = 0.0,
      "Stability recovery (thesis §4.5.4, Algorithm 4.2): move the control points of the request's "
      "curve until its first conjugate point lies beyond the end (stable with request['stabilize']"
      "['margin'], default 0.05), keeping R <= R_max (> 0 overrides request['stabilize']['R_max'], "
      "default 10). Returns done, status, stable_before/after, sigma_before/after [m], R_before/after, "
      "bspline, original_bspline, max_pole_move, deviation, history and the strip designed for the "
      "new curve (design).");
  m.def(
      "design_strip",
      [](const py::dict& request) {
        const nlohmann::json in = to_json(request);
        parafab::entry::json_write::ColumnarResult out;
        {
          py::gil_scoped_release release;
          out = parafab::entry::design_strip_columns(in);
        }
        return to_python(std::move(out));
      },
      py::arg("request"),
      "Design a bending-active strip. `request` and the returned dict follow the strip JSON "
      "format (resources/doc/json-reference.md; SI units): curve (bspline or points), material {E, thickness}, "
      "min_width, tolerance; optional gravity, boundary, natural_curvature, material.law, "
      "smooth, validate, composite, perforated.");
  m.def(
      "design_strip_json",
      [](const std::string& text) {
        nlohmann::json in;
        try {
          in = nlohmann::json::parse(text);
        } catch (const nlohmann::json::parse_error& e) {
          throw parafab::Error(std::string("the request is not valid JSON: ") + e.what());
        }
        py::gil_scoped_release release;
        return parafab::entry::design_strip_json(in).dump();
      },
      py::arg("text"),
      "design_strip with JSON text in and out (the CLI's format): for callers that hold the "
      "request as text; json.loads(design_strip_json(json.dumps(r))) equals design_strip(r).");
  m.def(
      "export_strip_outline",
      [](const py::dict& result, const std::string& path) {
        const nlohmann::json in = to_json(result);
        py::gil_scoped_release release;
        parafab::entry::write_strip_outline(in, path);
      },
      py::arg("result"), py::arg("path"),
      "Write the flat outline of a design_strip result (cut sheet at true scale, mm) to `path`: "
      "ASCII DXF R12 for .dxf, SVG for .svg. Composite strips get both layers, perforated strips "
      "their holes; clamp positions and end angles are annotated. Raises parafab.Error for an "
      "infeasible result.");
  m.def(
      "design_rod",
      [](const py::dict& request) {
        const nlohmann::json in = to_json(request);
        nlohmann::json out;
        {
          py::gil_scoped_release release;
          out = parafab::entry::design_rod_json(in);
        }
        return to_python(std::move(out));
      },
      py::arg("request"),
      "Design a Kirchhoff rod (thesis ch. 5). `request` and the returned dict follow the rod JSON "
      "format (resources/doc/json-reference.md; SI units): curve (3D bspline or points), material, max_radius, w_reg, "
      "section {factor}, loads, samples, validate.");
  m.def(
      "inspect_part",
      [](const std::string& path, int solid) {
        parafab::entry::InspectOptions o;
        o.read.solid_index = solid;
        nlohmann::json out;
        {
          py::gil_scoped_release release;
          out = parafab::entry::inspect_part_json(path, o);
        }
        return to_python(std::move(out));
      },
      py::arg("path"), py::arg("solid") = -1,
      "Face model of a STEP/BREP part (same JSON as `parafab inspect`).");
  m.def(
      "integrate_part",
      [](const std::string& path, int cells, double cell_size, const std::string& segments, int solid,
         bool estimate_only, bool force) {
        parafab::entry::IntegrateOptions o;
        o.read.solid_index = solid;
        o.estimate_only = estimate_only;
        o.force = force;
        o.integration.grid.cells_longest = cells;
        o.integration.grid.cell_size = cell_size;
        if (segments != "parabolic" && segments != "linear")
          throw parafab::Error("segments must be \"parabolic\" or \"linear\", got \"" + segments + "\"");
        o.integration.grid.segment_order = segments == "linear" ? 1 : 2;
        nlohmann::json out;
        {
          py::gil_scoped_release release;
          out = parafab::entry::integrate_part_json(path, o);
        }
        return to_python(std::move(out));
      },
      py::arg("path"), py::arg("cells") = 8, py::arg("cell_size") = 0.0, py::arg("segments") = "parabolic",
      py::arg("solid") = -1, py::arg("estimate_only") = false, py::arg("force") = false,
      "Mass properties of a part by cut-cell quadrature beside OCCT's (same JSON as `parafab integrate`), "
      "the part cut face by face (a grid the cut fails on is shifted and cut again: grid.retry_reason). "
      "A grid estimated above 70% of the memory is refused (parafab.Error with the estimate) unless "
      "force=True; estimate_only=True returns only {part, estimate}.");
  m.def(
      "simulate",
      [](const std::string& path, const py::dict& job, const std::string& out_dir, const py::object& progress,
         int threads) {
        nlohmann::json in = to_json(job);
        if (threads < 0) throw parafab::Error("simulate: threads must be >= 0 (0: the job's, else all cores), got " + std::to_string(threads));
        if (threads > 0) in["threads"] = threads;
        const auto report = progress_function(progress);
        nlohmann::json out;
        {
          py::gil_scoped_release release;
          out = parafab::entry::simulate_part_json(path, in, out_dir, report);
        }
        return to_python(std::move(out));
      },
      py::arg("path"), py::arg("job"), py::arg("out_dir") = "", py::arg("progress") = py::none(),
      py::arg("threads") = 0,
      "Linear elastic or hyperelastic XFEM simulation of a part (same job and result JSON as `parafab "
      "simulate`); writes result.json, result.vtu and surface.vtu into out_dir when given. "
      "threads > 0 overrides the job's \"threads\" (default: all cores). "
      "progress(phase, fraction) is called at phase boundaries; returning False cancels the run "
      "(parafab.Cancelled, a parafab.Error: 'simulation cancelled by the user').");
  m.def(
      "optimize",
      [](const std::string& path, const py::dict& job, const std::string& out_dir, const py::object& progress) {
        const nlohmann::json in = to_json(job);
        parafab::entry::OptimizeProgressFn report;
        if (!progress.is_none())
          report = [progress](const nlohmann::json& it) {
            py::gil_scoped_acquire acquire;
            return keep_going_of(progress(to_python(it)));
          };
        // Ctrl-C in Python (SIGINT, seen by PyErr_CheckSignals in the main thread) interrupts the
        // run as the callback's False does; once the files are written, KeyboardInterrupt is raised.
        bool keyboard_interrupt = false;
        auto interrupted = [&keyboard_interrupt]() {
          if (keyboard_interrupt) return true;
          py::gil_scoped_acquire acquire;
          if (PyErr_CheckSignals() != 0) {
            PyErr_Clear();
            keyboard_interrupt = true;
          }
          return keyboard_interrupt;
        };
        nlohmann::json out;
        {
          py::gil_scoped_release release;
          out = parafab::entry::optimize_part_json(path, in, out_dir, report, interrupted);
        }
        if (keyboard_interrupt) {
          PyErr_SetString(PyExc_KeyboardInterrupt, ("optimization interrupted; the best valid iterate so far is in " +
                                                    (out_dir.empty() ? std::string("the history only") : out_dir))
                                                       .c_str());
          throw py::error_already_set();
        }
        return to_python(std::move(out));
      },
      py::arg("path"), py::arg("job"), py::arg("out_dir") = "", py::arg("progress") = py::none(),
      "Shape optimization of a part on its own CAD parameters (same job and history JSON as `parafab optimize`); "
      "writes optimized.step, history.json and history.png into out_dir when given. progress(iterate) is called "
      "after every accepted iterate with {iteration, objective, constraint_violation, seconds}; returning False "
      "interrupts (status 'interrupted', the best valid iterate so far written). Ctrl-C does the same, then "
      "raises KeyboardInterrupt. The part file is only read.");
  // A simulation that keeps its grid: update(new_part) re-cuts only the blocks a change touches.
  py::class_<parafab::entry::SimulationSession>(
      m, "Simulation",
      "Simulation(path, job): a part and a simulate job kept in memory. run(out_dir='', progress=None) "
      "cuts and solves; update(path, out_dir='', progress=None) takes a changed part (e.g. after a "
      "parameter edit), re-cuts only the grid blocks the change touches and solves again. Both return "
      "the JSON of parafab.simulate; update's carries 'recut'.")
      .def(py::init([](const std::string& path, const py::dict& job) {
             return std::make_unique<parafab::entry::SimulationSession>(path, to_json(job));
           }),
           py::arg("path"), py::arg("job"))
      .def("estimate", [](const parafab::entry::SimulationSession& s) { return to_python(s.estimate()); },
           "Size of the run before running it: unknowns, factor_mb (a compact part) and factor_mb_min (a thin-walled one), peak_mb and peak_mb_min (the whole run), limit_mb, memory_mb (physical), fits, may_fit, cut.")
      .def(
          "run",
          [](parafab::entry::SimulationSession& s, const std::string& out_dir, const py::object& progress) {
            const auto report = progress_function(progress);
            nlohmann::json out;
            {
              py::gil_scoped_release release;
              out = s.run(out_dir, report);
            }
            return to_python(std::move(out));
          },
          py::arg("out_dir") = "", py::arg("progress") = py::none())
      .def(
          "update",
          [](parafab::entry::SimulationSession& s, const std::string& path, const std::string& out_dir,
             const py::object& progress) {
            const auto report = progress_function(progress);
            nlohmann::json out;
            {
              py::gil_scoped_release release;
              out = s.update(path, out_dir, report);
            }
            return to_python(std::move(out));
          },
          py::arg("path"), py::arg("out_dir") = "", py::arg("progress") = py::none());
  m.def(
      "revolution_strips",
      [](const py::dict& job) { return to_python(parafab::entry::revolution_strips_json(to_json(job))); },
      py::arg("job"),
      "Meridian of a surface of revolution tiled by strips, and the strips (same JSON as `parafab revolution`).");
  m.def(
      "strip_sections",
      [](const std::string& path, const py::dict& job) {
        const nlohmann::json in = to_json(job);
        nlohmann::json out;
        {
          py::gil_scoped_release release;
          out = parafab::entry::strip_sections_json(path, in);
        }
        return to_python(std::move(out));
      },
      py::arg("path"), py::arg("job"),
      "Strips from plane sections of a surface or solid (same job and result JSON as `parafab sections`).");
  m.def("occt_version", &parafab::occ::occt_version, "OpenCASCADE version ParaFab links against.");
  m.def("scripts_dir", &parafab::entry::scripts_dir,
        "Folder of the chart scripts this module runs (the installed copy, $PARAFAB_SCRIPTS_DIR, "
        "or the source tree's for a build tree).");
  m.def("json_reference", &parafab::entry::schema::reference_markdown,
        "The JSON reference (Markdown): the known keys of every request and job, as `parafab reference` prints.");
  m.attr("__version__") = parafab::entry::version();
}
