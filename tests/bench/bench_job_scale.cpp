// What a many-parameter optimization job costs before the first simulation (issue 12, the
// thesis's 160-parameter case, Table 6.1), on the sample parts up to the bridge's 646 faces:
//  - faces named by points: occ::FaceLocator (bounding boxes, nearest first) against the scan it
//    replaced (BRepExtrema to every face), on the faces' centroids (100 at most);
//  - dp⊥/dp̃ (thesis Eq. 6.29) at the projected start: optimize::projection_derivative, which works
//    per group of coupled entries, against the dense formula on all entries at once (one QR of
//    the whole Jacobian, as before 2026-12-01), both on the part's own parameters and relations.
// Medians of the repeats, baseline and new alternated in the same run; the run stops with exit 1
// if the two disagree (a different face, or derivatives more than 1e-9 apart).
// Usage: bench_job_scale [--quick] --out DIR SAMPLES_DIR  -> DIR/job_scale.json
#include <BRepBuilderAPI_MakeVertex.hxx>
#include <BRepExtrema_DistShapeShape.hxx>
#include <BRepGProp.hxx>
#include <Eigen/Dense>
#include <GProp_GProps.hxx>
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <nlohmann/json.hpp>
#include <string>

#include "bench_arguments.h"
#include "bench_output.h"
#include "face_lookup.h"
#include "occt_shape.h"
#include "optimize/projection.h"
#include "part_reader.h"
#include "shape_parameters.h"

using namespace parafab;
using namespace parafab::occ;

namespace {

double since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

// The baseline: the nearest face by the exact distance to every face.
int scan(const PartShape& part, const Eigen::Vector3d& X) {
  const TopoDS_Vertex v = BRepBuilderAPI_MakeVertex(gp_Pnt(X.x(), X.y(), X.z()));
  int best = -1;
  double best_d = 1e300;
  for (int i = 0; i < part.face_count(); ++i) {
    BRepExtrema_DistShapeShape dist(v, part.face(i));
    if (dist.IsDone() && dist.Value() < best_d) best_d = dist.Value(), best = i;
  }
  return best;
}

// The baseline: Z (ZᵀHZ)⁻¹ Zᵀ on all free entries at once (W = I), Z from one QR of the whole Jᵀ.
Eigen::MatrixXd dense_derivative(const optimize::ConstraintSystem& system, const optimize::ProjectionResult& r,
                                 const Eigen::VectorXd& lower, const Eigen::VectorXd& upper) {
  const int n = system.parameters();
  std::vector<int> free;
  for (int i = 0; i < n; ++i)
    if (upper[i] - lower[i] > 0 && r.p[i] - lower[i] > 1e-9 && upper[i] - r.p[i] > 1e-9) free.push_back(i);
  const Eigen::MatrixXd H = Eigen::MatrixXd::Identity(n, n) + system.constraint_hessian(r.p, r.multipliers);
  const Eigen::MatrixXd J = system.jacobian(r.p)(Eigen::all, free);
  Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr(J.transpose());
  qr.setThreshold(1e-10);
  const Eigen::MatrixXd Q = qr.householderQ();
  const Eigen::MatrixXd Z = Q.rightCols(free.size() - qr.rank());
  const Eigen::MatrixXd Hf = H(free, free);
  Eigen::MatrixXd D = Eigen::MatrixXd::Zero(n, n);
  D(free, free) = Z * (Z.transpose() * Hf * Z).ldlt().solve(Z.transpose());
  return D;
}

}  // namespace

int main(int argc, char** argv) {
  const BenchArguments args = bench_arguments(argc, argv);
  std::vector<std::string> parts = {"l_bracket", "wheel", "housing", "plate_holes", "bridge_holes"};
  if (args.quick) parts = {"l_bracket", "housing"};
  const int repeats = args.quick ? 2 : 5;
  nlohmann::json rows = nlohmann::json::array();
  for (const std::string& name : parts) {
    const auto part = read_part(args.samples + "/parts/" + name + ".step");
    std::vector<Eigen::Vector3d> points;
    for (int f = 0; f < part->face_count(); ++f) {
      GProp_GProps g;
      BRepGProp::SurfaceProperties(part->face(f), g);
      points.emplace_back(g.CentreOfMass().X(), g.CentreOfMass().Y(), g.CentreOfMass().Z());
    }
    if (points.size() > 100) {  // the scan of 646 faces costs 0.3 s a point: 100 centroids spread over the part
      std::vector<Eigen::Vector3d> some;
      for (size_t k = 0; some.size() < 100; ++k) some.push_back(points[k * points.size() / 100]);
      points = some;
    }
    // Face lookup: the centroids, the locator built inside the timing (as a job does).
    std::vector<double> t_scan, t_locator;
    const int scan_repeats = part->face_count() > 100 ? 1 : repeats;  // the bridge's scan: 30 s
    for (int r = 0; r < std::max(repeats, scan_repeats); ++r) {
      std::vector<int> a, b;
      if (r < scan_repeats) {
        auto t0 = std::chrono::steady_clock::now();
        for (const auto& X : points) a.push_back(scan(*part, X));
        t_scan.push_back(since(t0));
      }
      auto t0 = std::chrono::steady_clock::now();
      const FaceLocator locator(*part);
      for (const auto& X : points) b.push_back(locator.face_at(X, 1e300));
      t_locator.push_back(since(t0));
      if (!a.empty() && a != b) {
        std::fprintf(stderr, "%s: the locator and the scan disagree\n", name.c_str());
        return 1;
      }
    }
    // Projection derivative at the projected start, on the part's own parameters and relations.
    const FaceModel model = build_face_model(*part);
    const ShapeParameters sp = build_shape_parameters(model);
    const optimize::ProjectionResult start = optimize::project(sp.constraints, sp.initial, sp.initial, sp.lower, sp.upper);
    if (!start.done) {
      std::fprintf(stderr, "%s: projection failed: %s\n", name.c_str(), start.message.c_str());
      return 1;
    }
    std::vector<double> t_dense, t_grouped;
    double difference = 0;
    int groups_rank = 0;
    for (int r = 0; r < repeats; ++r) {
      auto t0 = std::chrono::steady_clock::now();
      const Eigen::MatrixXd D = dense_derivative(sp.constraints, start, sp.lower, sp.upper);
      t_dense.push_back(since(t0));
      t0 = std::chrono::steady_clock::now();
      const optimize::ProjectionDerivative d = optimize::projection_derivative(sp.constraints, start, sp.lower, sp.upper);
      t_grouped.push_back(since(t0));
      difference = std::max(difference, (D - d.jacobian).cwiseAbs().maxCoeff());
      groups_rank = d.rank;
    }
    if (!(difference <= 1e-9)) {
      std::fprintf(stderr, "%s: dense and grouped dp/dp~ differ by %.3g\n", name.c_str(), difference);
      return 1;
    }
    const nlohmann::json row = {{"part", name},
                                {"faces", part->face_count()},
                                {"parameters", sp.size()},
                                {"constraints", sp.constraints.size()},
                                {"rank", groups_rank},
                                {"lookup_points", points.size()},
                                {"lookup_seconds_scan", median(t_scan)},
                                {"lookup_seconds_locator", median(t_locator)},
                                {"lookup_ratio", median(t_scan) / median(t_locator)},
                                {"derivative_seconds_dense", median(t_dense)},
                                {"derivative_seconds_grouped", median(t_grouped)},
                                {"derivative_ratio", median(t_dense) / median(t_grouped)},
                                {"derivative_max_difference", difference},
                                {"repeats", repeats},
                                {"scan_repeats", scan_repeats}};
    std::printf("%-13s %4d faces %5d parameters: lookup of %zu faces scan %.3f s, locator %.4f s (x%.0f); "
                "dp/dp~ dense %.3f s, grouped %.4f s (x%.0f), max difference %.1e\n",
                name.c_str(), part->face_count(), sp.size(), points.size(), median(t_scan), median(t_locator),
                median(t_scan) / median(t_locator), median(t_dense), median(t_grouped),
                median(t_dense) / median(t_grouped), difference);
    rows.push_back(row);
  }
  std::printf("wrote %s\n", write_bench_file(args.out, "job_scale.json", rows.dump(2)).c_str());
  return 0;
}
