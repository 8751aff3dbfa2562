// Agreement of the exact (Hadamard) mass-property shape derivatives with central finite
// differences of OCCT's mass properties against the FD step (thesis §6.2.3 Eq. 6.5, §6.5.2):
// for a few parameters of the sample parts, max relative error over the ten moments per step.
// Usage: bench_shape_gradient [--quick] --out DIR SAMPLES_DIR  -> DIR/shape_gradient.json
#include <cmath>
#include <cstdio>
#include <nlohmann/json.hpp>
#include <string>

#include "bench_arguments.h"
#include "occt_mass_properties.h"
#include "optimize/projection.h"
#include "part_reader.h"
#include "shape_derivatives.h"
#include "shape_modify.h"
#include "shape_parameters.h"
#include "bench_output.h"

using namespace parafab;
using namespace parafab::occ;

int main(int argc, char** argv) {
  const BenchArguments args = bench_arguments(argc, argv);
  const bool quick = args.quick;
  const std::string &out = args.out, &samples = args.samples;
  struct Case {
    std::string part, face_type;
    double radius;  // cylinder radius or plane offset |d| to pick the face
    std::string parameter;
  };
  std::vector<Case> cases = {{"l_bracket", "cylinder", 4, "radius"},
                             {"l_bracket", "cylinder", 5, "radius"},  // the inner fillet (tangent planes follow)
                             {"wheel", "cylinder", 50, "radius"},
                             {"housing", "cylinder", 6, "radius"}};   // the boss (its torus fillet follows)
  if (quick) cases.resize(1);
  std::vector<double> steps = {1e-1, 3e-2, 1e-2, 3e-3, 1e-3, 3e-4, 1e-4, 3e-5, 1e-5, 1e-6};
  if (quick) steps = {1e-2, 1e-3};
  nlohmann::json result = nlohmann::json::array();
  for (const Case& c : cases) {
    const auto part = read_part(samples + "/parts/" + c.part + ".step");
    const FaceModel model = build_face_model(*part);
    ShapeParameters sp = build_shape_parameters(model);
    int face = -1;
    for (const FaceInfo& f : model.faces)
      if (to_string(f.primitive.type) == c.face_type && std::abs(f.primitive.radius - c.radius) < 1e-6) face = f.index;
    if (face < 0) continue;
    const int i = parameter_index(sp, face, c.parameter);
    const PartInfo info = part_info(*part);
    const Eigen::VectorXd w = projection_weights(sp, {i}, 1e-6, (info.bbox_max - info.bbox_min).norm());
    optimize::ProjectionOptions po;
    po.weights = w;
    const auto base = optimize::project(sp.constraints, sp.initial, sp.initial, sp.lower, sp.upper, {}, po);
    const auto D = optimize::projection_derivative(sp.constraints, base, sp.lower, sp.upper, w);
    const MomentDerivatives md = moment_derivatives(*part, sp, base.p);
    const Eigen::VectorXd exact = md.gradient * D.jacobian.col(i);
    nlohmann::json row = {{"part", c.part}, {"parameter", sp.names[i]}, {"steps", steps}, {"max_relative_error", nlohmann::json::array()}};
    for (double h : steps) {
      Moments m[2];
      bool ok = true;
      for (int side = 0; side < 2 && ok; ++side) {
        Eigen::VectorXd t = base.p;
        t[i] += side ? -h : h;
        const auto p = optimize::project(sp.constraints, t, base.p, sp.lower, sp.upper, {}, po);
        const ModifyResult mod = p.done ? modify_part(*part, model, sp, p.p) : ModifyResult{};
        ok = mod.done;
        if (ok) m[side] = occt_moments(*mod.part);
      }
      double worst = std::nan("");
      if (ok) {
        const Moments fd = (m[0] - m[1]) / (2 * h);
        worst = 0;
        for (int k = 0; k < 10; ++k) {
          const int lo = k == 0 ? 0 : k < 4 ? 1 : 4, n = k == 0 ? 1 : k < 4 ? 3 : 6;
          const double scale = std::max(fd.segment(lo, n).cwiseAbs().maxCoeff(), 1e-6 * fd.cwiseAbs().maxCoeff());
          worst = std::max(worst, std::abs(exact[k] - fd[k]) / scale);
        }
      }
      row["max_relative_error"].push_back(worst);
      std::printf("%-10s %-32s h=%-7g max rel error %.3g\n", c.part.c_str(), sp.names[i].c_str(), h, worst);
    }
    result.push_back(row);
  }
  write_bench_file(out, "shape_gradient.json", result.dump(2) + "\n");
  return 0;
}
