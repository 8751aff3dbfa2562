#include "face_lookup.h"

#include <BRepBndLib.hxx>
#include <BRepBuilderAPI_MakeVertex.hxx>
#include <BRepClass3d_SolidClassifier.hxx>
#include <BRepExtrema_DistShapeShape.hxx>
#include <BRepGProp.hxx>
#include <Bnd_Box.hxx>
#include <GProp_GProps.hxx>
#include <algorithm>
#include <cmath>
#include <limits>
#include <utility>
#include <vector>

#include "common/error.h"
#include "occt_shape.h"

namespace parafab::occ {

struct FaceLocator::Impl {
  const PartShape& part;
  std::vector<Bnd_Box> boxes;  ///< per face, conservative (BRepBndLib, no triangulation)
};

FaceLocator::FaceLocator(const PartShape& part) : impl_(new Impl{part, {}}) {
  impl_->boxes.resize(part.face_count());
  for (int i = 0; i < part.face_count(); ++i) BRepBndLib::Add(part.face(i), impl_->boxes[i], false);
}

FaceLocator::~FaceLocator() = default;

namespace {

// Distance from X to the box (0 inside it); a void box is infinitely far.
double box_distance(const Bnd_Box& b, const xfem::Vec3& X) {
  if (b.IsVoid()) return std::numeric_limits<double>::infinity();
  double lo[3], hi[3];
  b.Get(lo[0], lo[1], lo[2], hi[0], hi[1], hi[2]);
  double d2 = 0;
  for (int k = 0; k < 3; ++k) {
    const double e = std::max({lo[k] - X[k], X[k] - hi[k], 0.0});
    d2 += e * e;
  }
  return std::sqrt(d2);
}

}  // namespace

int FaceLocator::face_at(const xfem::Vec3& X, double tolerance) const {
  const PartShape& part = impl_->part;
  const TopoDS_Vertex v = BRepBuilderAPI_MakeVertex(gp_Pnt(X.x(), X.y(), X.z()));
  std::vector<std::pair<double, int>> order;  // (box distance, face), nearest box first
  order.reserve(impl_->boxes.size());
  for (int i = 0; i < part.face_count(); ++i) order.emplace_back(box_distance(impl_->boxes[i], X), i);
  std::sort(order.begin(), order.end());
  int best = -1;
  double best_d = std::numeric_limits<double>::infinity();
  for (const auto& [box_d, i] : order) {
    if (box_d > best_d) break;  // a box holds its face: this face and all later ones are farther
    BRepExtrema_DistShapeShape dist(v, part.face(i));
    if (!dist.IsDone()) continue;
    const double d = dist.Value();
    if (d < best_d || (d == best_d && i < best)) best_d = d, best = i;  // ties: the lowest index, as a scan
  }
  if (best < 0 || best_d > tolerance)
    PARAFAB_INPUT_ERROR("no face of " << part.source << " passes within " << tolerance << " of the point ("
                                      << X.x() << ", " << X.y() << ", " << X.z() << "); the nearest is face "
                                      << best << " at distance " << best_d);
  return best;
}

int face_at_point(const PartShape& part, const xfem::Vec3& X, double tolerance) {
  return FaceLocator(part).face_at(X, tolerance);
}

double face_area(const PartShape& part, int index) {
  if (index < 0 || index >= part.face_count())
    PARAFAB_INPUT_ERROR("face " << index << " does not exist: " << part.source << " has faces 0.."
                                << part.face_count() - 1);
  GProp_GProps g;
  BRepGProp::SurfaceProperties(part.face(index), g);
  return g.Mass();
}

struct PointClassifier::Impl {
  mutable BRepClass3d_SolidClassifier classifier;
  double tolerance;
};

PointClassifier::PointClassifier(const PartShape& part, double tolerance) : impl_(new Impl{{}, tolerance}) {
  impl_->classifier.Load(part.shape);
}

PointClassifier::~PointClassifier() = default;

bool PointClassifier::in_material(const xfem::Vec3& X) const { return state(X) != State::Out; }

PointClassifier::State PointClassifier::state(const xfem::Vec3& X) const {
  impl_->classifier.Perform(gp_Pnt(X.x(), X.y(), X.z()), impl_->tolerance);
  const TopAbs_State s = impl_->classifier.State();
  return s == TopAbs_IN ? State::In : s == TopAbs_ON ? State::On : State::Out;
}

}  // namespace parafab::occ
