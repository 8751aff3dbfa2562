#include "occt_mass_properties.h"

#include <BRepAlgoAPI_Common.hxx>
#include <BRepGProp.hxx>
#include <BRepPrimAPI_MakeBox.hxx>
#include <GProp_GProps.hxx>
#include <TopExp_Explorer.hxx>

#include "occt_shape.h"

namespace parafab::occ {

namespace {
xfem::MassProperties from_gprops(const GProp_GProps& g) {
  xfem::MassProperties p;
  p.volume = g.Mass();
  const gp_Pnt c = g.CentreOfMass();
  p.center = Eigen::Vector3d(c.X(), c.Y(), c.Z());
  const gp_Mat m = g.MatrixOfInertia();  // about the centre of mass
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) p.inertia(i, j) = m.Value(i + 1, j + 1);
  return p;
}
}  // namespace

xfem::MassProperties occt_mass_properties(const PartShape& part, double eps) {
  GProp_GProps g;
  BRepGProp::VolumeProperties(part.shape, g, eps, /*OnlyClosed=*/Standard_True);
  return from_gprops(g);
}

CellBooleanResult occt_cell_properties(const PartShape& part, const xfem::Box3& cell, double eps) {
  CellBooleanResult r;
  const TopoDS_Shape box = BRepPrimAPI_MakeBox(gp_Pnt(cell.min.x(), cell.min.y(), cell.min.z()),
                                               gp_Pnt(cell.max.x(), cell.max.y(), cell.max.z())).Shape();
  BRepAlgoAPI_Common common(part.shape, box);
  if (!common.IsDone() || common.HasErrors()) return r;
  GProp_GProps g;
  BRepGProp::VolumeProperties(common.Shape(), g, eps, Standard_True);
  r.properties = from_gprops(g);
  for (TopExp_Explorer ex(common.Shape(), TopAbs_SOLID); ex.More(); ex.Next()) ++r.solids;
  r.done = true;
  return r;
}

}  // namespace parafab::occ
