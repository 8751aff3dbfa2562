#include "face_lookup.h"

#include <BRepBuilderAPI_MakeVertex.hxx>
#include <BRepClass3d_SolidClassifier.hxx>
#include <BRepExtrema_DistShapeShape.hxx>
#include <BRepGProp.hxx>
#include <GProp_GProps.hxx>

#include "common/error.h"
#include "occt_shape.h"

namespace parafab::occ {

int face_at_point(const PartShape& part, const xfem::Vec3& X, double tolerance) {
  const TopoDS_Vertex v = BRepBuilderAPI_MakeVertex(gp_Pnt(X.x(), X.y(), X.z()));
  int best = -1;
  double best_d = 1e300;
  for (int i = 0; i < part.face_count(); ++i) {
    BRepExtrema_DistShapeShape dist(v, part.face(i));
    if (dist.IsDone() && dist.Value() < best_d) best_d = dist.Value(), best = i;
  }
  if (best < 0 || best_d > tolerance)
    PARAFAB_INPUT_ERROR("no face of " << part.source << " passes within " << tolerance << " of the point ("
                                      << X.x() << ", " << X.y() << ", " << X.z() << "); the nearest is face "
                                      << best << " at distance " << best_d);
  return best;
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
