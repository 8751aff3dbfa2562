// Cost of the B-rep write-back (thesis §6.5.1, q = q(p⊥); occ_bridge/shape_modify.h) without a
// self-interference test, with the face-pair test (ModifyOptions::check_self_interference) and
// with the full test it replaced (BOPAlgo_ArgumentAnalyzer on all sub-shapes), on the sample
// parts: every cylinder, cone and torus radius moved by +0.05 mm through the projection (the
// bridge, all planes: every plane offset), the median of the repeats, the three variants
// alternated in the same run (ratios = with / without). The two tests must agree (both accept).
// Usage: bench_write_back [--quick] --out DIR SAMPLES_DIR  -> DIR/write_back.json
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <nlohmann/json.hpp>
#include <string>

#include "bench_arguments.h"
#include "bench_output.h"
#include "occt_shape.h"
#include "optimize/projection.h"
#include "part_reader.h"
#include "shape_modify.h"
#include "shape_parameters.h"

using namespace parafab;
using namespace parafab::occ;

int main(int argc, char** argv) {
  const BenchArguments args = bench_arguments(argc, argv);
  std::vector<std::string> parts = {"flange", "l_bracket", "wrench", "wheel", "housing", "plate_holes", "bridge_holes"};
  const int repeats = args.quick ? 3 : 15;
  if (args.quick) parts.resize(1);
  nlohmann::json result = nlohmann::json::array();
  for (const std::string& name : parts) {
    const auto part = read_part(args.samples + "/parts/" + name + ".step");
    const FaceModel model = build_face_model(*part);
    const ShapeParameters sp = build_shape_parameters(model);
    const optimize::ProjectionResult start = optimize::project(sp.constraints, sp.initial, sp.initial, sp.lower, sp.upper);
    Eigen::VectorXd target = start.p;
    int moved = 0;
    for (int k = 0; k < sp.size(); ++k)
      if (sp.names[k].find("radius") != std::string::npos) target[k] += 0.05, ++moved;
    const bool planes = moved == 0;  // a part of planes only: its plane offsets
    for (int k = 0; planes && k < sp.size(); ++k)
      if (sp.names[k].find("plane offset") != std::string::npos) target[k] += 0.05, ++moved;
    const optimize::ProjectionResult p = optimize::project(sp.constraints, target, start.p, sp.lower, sp.upper);
    if (!p.done) {
      std::fprintf(stderr, "%s: projection failed: %s\n", name.c_str(), p.message.c_str());
      return 1;
    }
    enum Variant { Without, FacePairs, Full };
    std::vector<double> seconds[3];
    for (int r = 0; r < repeats; ++r)
      for (const Variant v : {Without, FacePairs, Full}) {
        ModifyOptions options;
        options.check_self_interference = v != Without;
        options.full_self_interference = v == Full;
        const auto t0 = std::chrono::steady_clock::now();
        const ModifyResult m = modify_part(*part, model, sp, p.p, options);
        seconds[v].push_back(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
        if (!m.done) {
          std::fprintf(stderr, "%s: write-back (variant %d) failed: %s\n", name.c_str(), int(v), m.message.c_str());
          return 1;
        }
      }
    double median[3];
    for (int c = 0; c < 3; ++c) {
      std::sort(seconds[c].begin(), seconds[c].end());
      median[c] = seconds[c][seconds[c].size() / 2];
    }
    std::printf("%-12s %3d faces, %3d %s moved: write-back %7.2f ms, + face-pair test %7.2f ms (x%.2f), + full test %7.2f ms (x%.2f)\n",
                name.c_str(), part->face_count(), moved, planes ? "offsets" : "radii", 1e3 * median[0], 1e3 * median[1],
                median[1] / median[0], 1e3 * median[2], median[2] / median[0]);
    result.push_back({{"part", name},
                      {"faces", part->face_count()},
                      {"moved", moved},
                      {"moved_kind", planes ? "plane offsets" : "radii"},
                      {"repeats", repeats},
                      {"seconds_without", median[0]},
                      {"seconds_with", median[1]},
                      {"seconds_full", median[2]},
                      {"ratio", median[1] / median[0]},
                      {"ratio_full", median[2] / median[0]}});
  }
  std::printf("wrote %s\n", write_bench_file(args.out, "write_back.json", result.dump(2)).c_str());
  return 0;
}
