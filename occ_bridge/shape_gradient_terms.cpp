// The terms of the exact shape gradient by the rule derivatives of Eq. 6.30–6.31 (thesis
// §6.5.3): compliance_gradient and adjoint_shape_gradient; see shape_gradient_terms.h and
// shape_compliance.h. Each term keeps its own summation order (quadrature points, then edges),
// so the driver's sum in element order is bit-identical for every thread count.
#include "shape_gradient_terms.h"

#include <BRepAdaptor_Surface.hxx>
#include <Eigen/Geometry>
#include <BRepTools.hxx>
#include <BRep_Tool.hxx>
#include <Geom2d_Curve.hxx>
#include <TopExp.hxx>
#include <TopTools_IndexedDataMapOfShapeListOfShape.hxx>
#include <TopTools_ListOfShape.hxx>
#include <TopoDS.hxx>

#include <algorithm>
#include <array>
#include <cmath>
#include <functional>

#include "common/error.h"
#include "occt_shape.h"
#include "xfem/curve_rules.h"
#include "xfem/nonlinear_xfem.h"

namespace parafab::occ::detail {

namespace {

// Σ N_k(X) v_k over an element's nodes (8 or 27, by v's size): the field the solve's load sees.
xfem::Vec3 nodal_field(const xfem::GridElement& el, const Eigen::VectorXd& v, const xfem::Vec3& X) {
  xfem::Vec3 d = xfem::Vec3::Zero();
  if (v.size() == 3 * 27) {
    Eigen::Matrix<double, 27, 1> N;
    Eigen::Matrix<double, 27, 3> G;
    xfem::triquadratic_shape(el.box, X, N, G);
    for (int k = 0; k < 27; ++k) d += N(k) * v.segment<3>(3 * k);
  } else {
    Eigen::Matrix<double, 8, 1> N;
    Eigen::Matrix<double, 8, 3> G;
    xfem::trilinear_shape(el.box, X, N, G);
    for (int k = 0; k < 8; ++k) d += N(k) * v.segment<3>(3 * k);
  }
  return d;
}

// Sign s of a face's implicit function: ∇φ·n_out = s|∇φ| over the face (φ of its parameter block
// at p; constant on a face). Evaluated at the centre of its uv bounds.
double implicit_sign(const PartShape& part, int face, const optimize::ParameterBlock& block, const Eigen::VectorXd& p) {
  const TopoDS_Face& original = part.face(face);
  const double orient = original.Orientation() == TopAbs_REVERSED ? -1.0 : 1.0;
  const TopoDS_Face forward = TopoDS::Face(original.Oriented(TopAbs_FORWARD));
  const BRepAdaptor_Surface surface(forward, false);
  double u0, u1, v0, v1;
  BRepTools::UVBounds(forward, u0, u1, v0, v1);
  gp_Pnt P;
  gp_Vec du, dv;
  surface.D1(0.5 * (u0 + u1), 0.5 * (v0 + v1), P, du, dv);
  const gp_Vec N = du.Crossed(dv);
  const optimize::Dual phi = optimize::implicit_function(block.kind, p.data() + block.offset, xfem::Vec3(P.X(), P.Y(), P.Z()));
  const int nb = block.size();
  const double dot = orient * (phi.g[nb] * N.X() + phi.g[nb + 1] * N.Y() + phi.g[nb + 2] * N.Z());
  return dot >= 0 ? 1.0 : -1.0;
}

// Supports and loads, and the faces sharing an edge with one of them: when such a neighbour
// moves, the support's or load's patch gains or loses a strip along that edge. A support's or
// load's own motion is differentiated where its face is analytic, carries one kind of
// condition (not a support and a load), a support's value is not a `field`, and every face
// across its edges has a parameter block (whose normal gives the edge's slide) and carries no
// condition (a neighbouring support's or load's patch would gain a strip not computed here).
// Those that fail this are flagged. Fills c.neighbours, c.own_sides, c.sign, c.surface_sides and
// c.surface_own.
void condition_coverage(GradientContext& c, std::vector<char>& incomplete) {
  const PartShape& part = *c.at.part;
  const ShapeParameters& sp = c.sp;
  const Eigen::VectorXd& p = c.p;
  const std::set<int>& conditioned = c.conditioned;
  const std::set<int>& supports = c.supports;
  const int surface_face = c.surface_face;
  std::vector<double>& sign = c.sign;
  const auto flag = [&](int face) { flag_face(sp, face, incomplete); };
  TopTools_IndexedDataMapOfShapeListOfShape edge_faces;
  TopExp::MapShapesAndAncestors(part.shape, TopAbs_EDGE, TopAbs_FACE, edge_faces);
  std::map<int, std::set<int>> sets, sides;
  std::set<int> refused;  // supports and loads with a neighbour that has no block or carries a condition
  std::set<int> surface_neighbours;
  // A B-spline face f next to a support or load (or F): the poles whose basis functions reach
  // the shared edge i move it (a strip term not computed here), flagged; the others (interior
  // poles of a clamped surface whose edges are its iso-boundaries) leave the edge in place and
  // are exact. Checked at 16 points of the edge's pcurve per knot span of the surface.
  const auto flag_edge_poles = [&](int i, int f) {
    const PoleBlock* pb = sp.poles(f);
    if (!pb) return;
    double t0, t1;
    const Handle(Geom2d_Curve) pc = BRep_Tool::CurveOnSurface(TopoDS::Edge(edge_faces.FindKey(i)), part.face(f), t0, t1);
    if (pc.IsNull()) {
      flag(f);
      return;
    }
    const int samples = 16 * (pb->surface.count_u - pb->surface.degree_u + pb->surface.count_v - pb->surface.degree_v);
    for (int k = 0; k <= samples; ++k) {
      const gp_Pnt2d uv = pc->Value(t0 + (t1 - t0) * k / samples);
      for (const PoleInfluence& w : pole_influence(pb->surface, uv.X(), uv.Y()))
        if (std::abs(w.value) > 1e-12)
          for (int j = 0; j < 3; ++j) incomplete[pb->offset + 3 * w.index + j] = 1;
    }
  };
  for (int i = 1; i <= edge_faces.Extent(); ++i) {
    std::vector<int> faces;
    for (TopTools_ListOfShape::Iterator it(edge_faces(i)); it.More(); it.Next()) faces.push_back(part.face_index(it.Value()));
    for (int g : faces)
      if (conditioned.count(g))
        for (int f : faces) {
          if (f != g) {
            if (!sp.block(f) || conditioned.count(f)) refused.insert(g);
            else sides[g].insert(f);
          }
          if (f != g && sp.block(f) && !conditioned.count(f)) sets[g].insert(f);
          if (f != g && !conditioned.count(f)) flag_edge_poles(i, f);
        }
    if (surface_face >= 0 && std::count(faces.begin(), faces.end(), surface_face))
      for (int f : faces)
        if (f != surface_face) {
          surface_neighbours.insert(f);
          flag_edge_poles(i, f);
        }
  }
  if (surface_face >= 0) {
    c.surface_own = sp.block(surface_face) != nullptr;
    for (int f : surface_neighbours) {
      if (!sp.block(f)) {
        c.surface_own = false;
        continue;
      }
      c.surface_sides.push_back(f);
      if (sign[f] == 0) sign[f] = implicit_sign(part, f, *sp.block(f), p);
    }
    if (!c.surface_own) flag(surface_face);
  }
  for (auto& [g, fs] : sets) {
    c.neighbours[g].assign(fs.begin(), fs.end());
    for (int f : fs)
      if (sign[f] == 0) sign[f] = implicit_sign(part, f, *sp.block(f), p);
  }
  std::set<int> loaded, fields;
  for (const auto& t : c.at.tractions) loaded.insert(t.face);
  for (const auto& d : c.setup.dirichlet)
    if (d.field) fields.insert(d.face);
  for (int g : conditioned) {
    if ((supports.count(g) && loaded.count(g)) || fields.count(g) || !sp.block(g) || refused.count(g)) flag(g);
    else c.own_sides[g].assign(sides[g].begin(), sides[g].end());
  }
}

// `own`: the element's BulkShapeDensity, built on its first moving patch and kept for the rest.
std::vector<double> bulk_density(const GradientContext& c, int e, const Eigen::VectorXd& ue,
                                 const std::vector<xfem::Vec3>& points, std::optional<xfem::BulkShapeDensity>& own) {
  const ComplianceState& at = c.at;
  const ComplianceSetup& setup = c.setup;
  const std::vector<xfem::GridElement>& elements = at.model->elements;
  const auto it = c.tied_side.find(e);
  if (it == c.tied_side.end()) {
    if (!own) own.emplace(elements[e], ue, ue, setup.material, setup.solver);
    return (*own)(points);
  }
  const xfem::PieceTie& tie = at.ties[it->second.first];
  return xfem::tied_mode_shape_terms(elements, tie, element_values(at.solution.u, at.solution.node[tie.element_a]),
                                     element_values(at.solution.u, at.solution.node[tie.element_b]), setup.material,
                                     setup.solver, it->second.second, points)
      .density;
}

// The density of dJ on a moving patch, times Vₙ: −ψ(u, u) + 2ρg·u for the compliance;
// ψ(λ, u) − ρg·λ + j (J's own density) for an adjoint (a mode-tied pair's ψ(λ, u) by
// polarization of its quadratic form: ¼[ψ(u + λ) − ψ(u − λ)]).
std::vector<double> moving_density(const GradientContext& c, int e, const Eigen::VectorXd& ue, const Eigen::VectorXd& le,
                                   const std::vector<xfem::Vec3>& points, std::optional<xfem::BulkShapeDensity>& own) {
  const ComplianceState& at = c.at;
  const ComplianceSetup& setup = c.setup;
  const ShapeAdjoint* adj = c.adj;
  const char* who = c.who;
  const bool gravity = c.gravity;
  const std::vector<xfem::GridElement>& elements = at.model->elements;
  std::vector<double> d(points.size(), 0.0);
  if (points.empty()) return d;
  if (!adj) {
    const std::vector<double> psi = bulk_density(c, e, ue, points, own);
    for (size_t q = 0; q < points.size(); ++q) {
      d[q] = -psi[q];
      if (gravity) d[q] += 2 * setup.material.density * setup.solver.gravity.dot(at.solution.displacement(elements, e, points[q]));
    }
    return d;
  }
  std::vector<double> psi;
  const auto it = c.tied_side.find(e);
  if (it == c.tied_side.end()) {
    if (!own) own.emplace(elements[e], le, ue, setup.material, setup.solver);
    psi = (*own)(points);
  } else {
    const xfem::PieceTie& tie = at.ties[it->second.first];
    const std::vector<int>& na = at.solution.node[tie.element_a], &nb = at.solution.node[tie.element_b];
    const Eigen::VectorXd ua = element_values(at.solution.u, na), ub = element_values(at.solution.u, nb);
    const Eigen::VectorXd la = element_values(adj->lambda, na), lb = element_values(adj->lambda, nb);
    const std::vector<double> plus = xfem::tied_mode_shape_terms(elements, tie, ua + la, ub + lb, setup.material,
                                                                 setup.solver, it->second.second, points).density;
    const std::vector<double> minus = xfem::tied_mode_shape_terms(elements, tie, ua - la, ub - lb, setup.material,
                                                                  setup.solver, it->second.second, points).density;
    psi.resize(points.size());
    for (size_t q = 0; q < points.size(); ++q) psi[q] = 0.25 * (plus[q] - minus[q]);
  }
  const std::vector<double> own_density = adj->density ? adj->density(e, points) : std::vector<double>(points.size(), 0.0);
  PARAFAB_VERIFY(own_density.size() == points.size(),
                 who << ": the objective's density gives " << own_density.size() << " values for " << points.size() << " points");
  for (size_t q = 0; q < points.size(); ++q) {
    d[q] = psi[q] + own_density[q];
    if (gravity) d[q] -= setup.material.density * setup.solver.gravity.dot(nodal_field(elements[e], le, points[q]));
  }
  return d;
}

// The face of `faces` on whose surface a patch's loop segment lies (its ends and middle within
// `tol` of the face's implicit zero set), or −1.
int segment_face(const GradientContext& c, const xfem::CutPatch& patch, const xfem::CurveSegment2& seg,
                 const std::vector<int>& faces, double tol) {
  const ShapeParameters& sp = c.sp;
  const Eigen::VectorXd& p = c.p;
  for (int f : faces) {
    const optimize::ParameterBlock& b = *sp.block(f);
    const int nb = b.size();
    bool all = true;
    for (const xfem::Vec2& uv : {seg.start, seg.position(0.5), seg.end}) {
      xfem::Vec3 X, Xu, Xv;
      patch.surface->evaluate(uv.x(), uv.y(), X, Xu, Xv);
      const optimize::Dual phi = optimize::implicit_function(b.kind, p.data() + b.offset, X);
      const double gn = xfem::Vec3(phi.g[nb], phi.g[nb + 1], phi.g[nb + 2]).norm();
      if (!(gn > 0) || std::abs(phi.v) / gn > tol) { all = false; break; }
    }
    if (all) return f;
  }
  return -1;
}

// The cell wall (axis 0, 1, 2) on which a patch's loop segment lies (its ends and middle within
// `tol` of one face of `box`), or −1.
// A patch lying in a wall (its normal along the wall's) has no edge sliding along it.
int segment_wall(const xfem::CutPatch& patch, const xfem::CurveSegment2& seg, const xfem::Box3& box, double tol) {
  xfem::Vec3 M, Mu, Mv;
  const xfem::Vec2 mid = seg.position(0.5);
  patch.surface->evaluate(mid.x(), mid.y(), M, Mu, Mv);
  const xfem::Vec3 normal = Mu.cross(Mv).normalized();
  for (int c = 0; c < 3; ++c)
    for (const double wall : {box.min[c], box.max[c]}) {
      if (std::abs(normal[c]) > 0.999) continue;
      bool all = true;
      for (const xfem::Vec2& uv : {seg.start, seg.position(0.5), seg.end}) {
        xfem::Vec3 X, Xu, Xv;
        patch.surface->evaluate(uv.x(), uv.y(), X, Xu, Xv);
        if (std::abs(X[c] - wall) > tol) { all = false; break; }
      }
      if (all) return c;
    }
  return -1;
}

// visit(X, n_Γ, speeds per entry of a block, ds) at a Gauss point of a loop segment.
using EdgeVisit = std::function<void(const xfem::Vec3&, const xfem::Vec3&, const std::vector<double>&, double)>;

// The own motion's edge term of a support's, load's (or F's) patch: Γ's edges slide along the
// faces across them (`sides`), and with `walls` its piece's edges slide along the cell's walls.
// At each Gauss point of such a loop segment, visit(X, n_Γ, α, ds) with α_k =
// −Vₙ,k (n_Γ·n_F)/(ν·n_F) per entry of Γ's block (ν the outward conormal). Returns false (and
// visits nothing more) where Γ runs (nearly) tangent into F (|n_F·ν| < 0.2) or along a wall
// (< 0.05): the slide is ill-posed there. With `spine`, a plane Γ into which a swept F (a
// fillet) runs tangent is the exception: with the tangency kept the edge is the foot on Γ of
// F's spine point S, E = S − φ_Γ(S) n_Γ/|n_Γ|², so α_k = ν·∂E/∂p_k = −φ_Γ(S) ν·∂n_Γ/∂p_k/|n_Γ|²
// (ν ⊥ n_Γ; ν·∂n_Γ/∂p_k = ∂φ_Γ/∂p_k(X + ν) − ∂φ_Γ/∂p_k(X), φ_Γ linear in X); F's own share
// is its strip (ν·∂S/∂p of F's entries).
bool own_edges(const GradientContext& c, const xfem::CutPatch& patch, const xfem::Box3& box,
               const optimize::ParameterBlock& b, const std::vector<int>& sides, bool walls, bool spine,
               const EdgeVisit& visit) {
  const ShapeParameters& sp = c.sp;
  const Eigen::VectorXd& p = c.p;
  const xfem::QuadratureRule1& gauss = *c.gauss;
  const double h = box.size().minCoeff();
  const int nb = b.size();
  std::vector<double> alpha(nb);
  for (const xfem::UvLoop& loop : xfem::to_uv_loops(patch.loops))
    for (const xfem::CurveSegment2& seg : loop) {
      const int on = segment_face(c, patch, seg, sides, 1e-6 * h);
      const int wall = on < 0 && walls ? segment_wall(patch, seg, box, 1e-6 * h) : -1;
      if (on < 0 && wall < 0) continue;
      const optimize::ParameterBlock* bf = on >= 0 ? sp.block(on) : nullptr;
      for (size_t q = 0; q < gauss.points.size(); ++q) {
        xfem::Vec3 X, Xu, Xv;
        const double t = gauss.points[q];
        const xfem::Vec2 uv = seg.position(t), duv = seg.derivative(t);
        patch.surface->evaluate(uv.x(), uv.y(), X, Xu, Xv);
        const xfem::Vec3 dX = Xu * duv.x() + Xv * duv.y();
        const double speed = dX.norm();
        if (!(speed > 0)) continue;
        const xfem::Vec3 n_uv = Xu.cross(Xv).normalized();
        const xfem::Vec3 conormal = (dX / speed).cross(n_uv);  // outward: the region is on the left
        const xfem::Vec3 n_g = patch.orientation * n_uv;
        xfem::Vec3 n_f = xfem::Vec3::Unit(std::max(wall, 0));
        if (bf) {
          const int nf = bf->size();
          const optimize::Dual phf = optimize::implicit_function(bf->kind, p.data() + bf->offset, X);
          n_f = xfem::Vec3(phf.g[nf], phf.g[nf + 1], phf.g[nf + 2]).normalized();
        }
        const double across = n_f.dot(conormal);
        const optimize::Dual phi = optimize::implicit_function(b.kind, p.data() + b.offset, X);
        const xfem::Vec3 grad(phi.g[nb], phi.g[nb + 1], phi.g[nb + 2]);
        const double gn = grad.norm();
        if (std::abs(across) < (bf ? 0.2 : 0.05)) {
          const bool swept = bf && (bf->kind == optimize::PrimitiveKind::cylinder ||
                                    bf->kind == optimize::PrimitiveKind::torus || bf->kind == optimize::PrimitiveKind::sphere);
          if (!spine || !swept || b.kind != optimize::PrimitiveKind::plane || !(gn > 0)) return false;
          const optimize::V3<optimize::Dual> S = optimize::spine_point(bf->kind, p.data() + bf->offset, X);
          const xfem::Vec3 Sv(S.x.v, S.y.v, S.z.v);
          const double depth = optimize::implicit_function(b.kind, p.data() + b.offset, Sv).v;
          const optimize::Dual shifted = optimize::implicit_function(b.kind, p.data() + b.offset, X + conormal);
          for (int k = 0; k < nb; ++k) alpha[k] = -depth * (shifted.g[k] - phi.g[k]) / (gn * gn);
          visit(X, patch.orientation * n_uv, alpha, gauss.weights[q] * speed);
          continue;
        }
        if (!(gn > 0)) continue;
        const double s = grad.dot(n_g) >= 0 ? 1.0 : -1.0;
        for (int k = 0; k < nb; ++k) alpha[k] = -(-s * phi.g[k] / gn) * n_g.dot(n_f) / across;
        visit(X, n_g, alpha, gauss.weights[q] * speed);
      }
    }
  return true;
}

// A loop segment of a patch lying on a moving neighbour F (`on`, with a block): at each Gauss
// point visit(X, n_Γ, a, ds), a_k the edge's conormal speed inside Γ per entry of F's block. A
// transversal edge moves with F's normal speed over n_F·ν. A swept face running tangent into
// Γ (a fillet into a support: cylinder or torus; a ball end: sphere) touches it along its spine
// offset onto Γ, so on the constraint manifold (tangency kept) the edge moves with the spine
// point S nearest X: a = ν·∂S/∂p (optimize::spine_point; the null-space completion of
// Fig. 6.12, case 2). Returns false (visiting nothing more) where a plane or cone runs tangent
// into Γ.
bool neighbour_slide(const GradientContext& c, const xfem::CutPatch& patch, const xfem::CurveSegment2& seg, int on,
                     const EdgeVisit& visit) {
  const Eigen::VectorXd& p = c.p;
  const std::vector<double>& sign = c.sign;
  const xfem::QuadratureRule1& gauss = *c.gauss;
  const optimize::ParameterBlock& b = *c.sp.block(on);
  const int nb = b.size();
  std::vector<double> speed_k(nb, 0.0);
  for (size_t q = 0; q < gauss.points.size(); ++q) {
    xfem::Vec3 X, Xu, Xv;
    const double t = gauss.points[q];
    const xfem::Vec2 uv = seg.position(t), duv = seg.derivative(t);
    patch.surface->evaluate(uv.x(), uv.y(), X, Xu, Xv);
    const xfem::Vec3 dX = Xu * duv.x() + Xv * duv.y();
    const double speed = dX.norm();
    if (!(speed > 0)) continue;
    const xfem::Vec3 n_uv = Xu.cross(Xv).normalized();
    const xfem::Vec3 tangent_dir = dX / speed, conormal = tangent_dir.cross(n_uv);  // region on the left
    const optimize::Dual phi = optimize::implicit_function(b.kind, p.data() + b.offset, X);
    const xfem::Vec3 grad(phi.g[nb], phi.g[nb + 1], phi.g[nb + 2]);
    const double gn = grad.norm();
    const xfem::Vec3 n_f = sign[on] * grad / gn;
    const double cs = n_f.dot(conormal);
    if (std::abs(cs) >= 0.2) {
      for (int k = 0; k < nb; ++k) speed_k[k] = (-sign[on] * phi.g[k] / gn) / cs;
    } else if (b.kind == optimize::PrimitiveKind::cylinder || b.kind == optimize::PrimitiveKind::torus ||
               b.kind == optimize::PrimitiveKind::sphere) {
      const optimize::V3<optimize::Dual> S = optimize::spine_point(b.kind, p.data() + b.offset, X);
      for (int k = 0; k < nb; ++k) speed_k[k] = conormal.x() * S.x.g[k] + conormal.y() * S.y.g[k] + conormal.z() * S.z.g[k];
    } else {
      return false;
    }
    visit(X, patch.orientation * n_uv, speed_k, gauss.weights[q] * speed);
  }
  return true;
}

}  // namespace

void flag_face(const ShapeParameters& sp, int face, std::vector<char>& incomplete) {
  if (const optimize::ParameterBlock* b = sp.block(face))
    for (int k = 0; k < b->size(); ++k) incomplete[b->offset + k] = 1;
  if (const PoleBlock* b = sp.poles(face))
    for (int k = 0; k < b->size(); ++k) incomplete[b->offset + k] = 1;
}

GradientContext gradient_context(const ComplianceState& at, const ComplianceSetup& setup, const ShapeParameters& sp,
                                 const Eigen::VectorXd& p, const std::vector<char>* moving, const ShapeAdjoint* adj,
                                 const char* who, std::vector<char>& incomplete) {
  PARAFAB_VERIFY(at.done && at.model, who << ": the state is not solved");
  PARAFAB_VERIFY(p.size() == sp.size(), who << ": p has " << p.size() << " entries, the parameters " << sp.size());
  const PartShape& part = *at.part;
  PARAFAB_VERIFY(static_cast<int>(sp.block_of_face.size()) == part.face_count(),
                 who << ": the parameters describe " << sp.block_of_face.size() << " faces, the part has "
                     << part.face_count());
  PARAFAB_VERIFY(!moving || static_cast<int>(moving->size()) == sp.size(),
                 who << ": `moving` has " << moving->size() << " entries, p " << sp.size());
  PARAFAB_VERIFY(!adj || adj->lambda.size() == at.solution.u.size(),
                 who << ": an adjoint of size " << (adj ? adj->lambda.size() : 0) << ", the state has "
                     << at.solution.u.size() << " unknowns");
  PARAFAB_VERIFY(!adj || !setup.hyperelastic, who << ": the adjoint form is built for linear elasticity only");
  GradientContext c{at, setup, sp, p, adj, who};
  c.np = sp.size();
  // Faces whose motion is wanted: some entry of their block (or pole block) is `moving`.
  c.face_moves.assign(part.face_count(), 1);
  if (moving)
    for (int f = 0; f < part.face_count(); ++f) {
      int offset = 0, size = 0;
      if (const optimize::ParameterBlock* b = sp.block(f)) offset = b->offset, size = b->size();
      else if (const PoleBlock* pb = sp.poles(f)) offset = pb->offset, size = pb->size();
      c.face_moves[f] = std::any_of(moving->begin() + offset, moving->begin() + offset + size, [](char m) { return m != 0; });
    }
  for (const auto& d : setup.dirichlet) c.conditioned.insert(d.face);
  for (const auto& t : at.tractions) c.conditioned.insert(t.face);
  // The local Nitsche penalty (xfem::LinearXfemOptions::NitschePenalty::Local) of a clamped cut
  // cell is κΛ, Λ the top eigenvalue of that cell's flux matrix B against its bulk stiffness Â,
  // so it changes with every face that cuts the cell: dΛ = vᵀdBv − Λ vᵀdÂv (xfem::LocalPenaltyParts),
  // vᵀdÂv by Reynolds over the moving patches as the bulk term, vᵀdBv along the clamped
  // patch's moving edges as the strip terms; then C changes by κ dΛ (2uᵀg − uᵀPu). Where Λ is
  // not a simple eigenvalue (gap ≤ 1e-6) the cell's moving faces are flagged instead (on a
  // B-spline face, the poles whose basis functions reach its patches): the optimizer then takes
  // the semi-analytic route, which re-evaluates whole element systems, penalty included.
  c.local_penalty = setup.solver.nitsche_penalty == xfem::LinearXfemOptions::NitschePenalty::Local;
  for (const auto& d : setup.dirichlet) c.supports.insert(d.face);
  c.sign.assign(part.face_count(), 0.0);
  c.surface_face = adj && adj->surface_density ? adj->surface_face : -1;
  PARAFAB_VERIFY(c.surface_face < part.face_count(), who << ": the surface density's face " << c.surface_face
                                                          << " is outside 0.." << part.face_count() - 1);
  condition_coverage(c, incomplete);
  // Loads given as total forces: traction F/A, so a change of the face's area A changes it.
  c.load_area.assign(at.tractions.size(), 0.0);
  for (size_t i = 0; i < at.tractions.size() && i < setup.forces.size(); ++i)
    if (setup.forces[i].norm() > 0) c.load_area[i] = setup.forces[i].norm() / at.tractions[i].traction.norm();
  // The integrand ψ Vₙ is a polynomial of degree ≤ 4 (hex8) or 8 (hex27) per coordinate times a
  // velocity of degree ≤ 1 on planar patches; curved patches refine on their area.
  c.so.area.degree = setup.solver.element == xfem::ElementType::Hex27 ? 10 : 6;
  c.so.refinement = xfem::RefinementOptions{1e-10, true, 6, 4};
  // A support's own motion integrates ∂ₙ(σ(u)n·u)-like densities: on a curved support degree 6
  // left 1e-4 of the derivative (the turned bracket's hole, the countersink: measured against
  // the pipeline's differences with its patch rules at degree 12), degree 10 agrees to 1e-6.
  c.so_support = c.so;
  c.so_support.area.degree = setup.solver.element == xfem::ElementType::Hex27 ? 14 : 10;
  c.gauss = &xfem::gauss_legendre(8);
  c.gravity = setup.material.density != 0 && setup.solver.gravity.squaredNorm() > 0;
  // Pieces whose incompatible modes a tie condenses jointly: their ψ is the pair's.
  c.modes_tied = xfem::mode_tied(at.model->elements, at.ties, setup.material, setup.solver);
  for (size_t t = 0; t < at.ties.size(); ++t)
    if (c.modes_tied[t]) {
      c.tied_side[at.ties[t].element_a] = {static_cast<int>(t), 0};
      c.tied_side[at.ties[t].element_b] = {static_cast<int>(t), 1};
    }
  return c;
}

std::vector<int> moving_elements(const GradientContext& c) {
  const std::vector<xfem::GridElement>& elements = c.at.model->elements;
  std::vector<int> work;
  for (size_t e = 0; e < elements.size(); ++e)
    if (elements[e].subvolume)
      for (const xfem::CutPatch& patch : elements[e].subvolume->patches)
        if (c.sp.block(patch.source_face) || c.sp.poles(patch.source_face) || c.conditioned.count(patch.source_face) ||
            (patch.source_face >= 0 && patch.source_face == c.surface_face)) {  // grid patches: −1
          work.push_back(static_cast<int>(e));
          break;
        }
  return work;
}

ElementFields element_fields(const GradientContext& c, int e) {
  const ComplianceState& at = c.at;
  const ComplianceSetup& setup = c.setup;
  ElementFields f;
  f.e = e;
  f.el = &at.model->elements[e];
  const xfem::GridElement& el = *f.el;
  f.ue = element_values(at.solution.u, at.solution.node[e]);
  // λₑ, and the field the load's change is contracted with: zₑ = 2uₑ (compliance), −λₑ (adjoint).
  f.le = c.adj ? element_values(c.adj->lambda, at.solution.node[e]) : Eigen::VectorXd();
  f.ze = c.adj ? Eigen::VectorXd(-f.le) : Eigen::VectorXd(2 * f.ue);
  f.h = el.box.size().minCoeff();
  f.penalised =
      c.local_penalty && std::any_of(el.subvolume->patches.begin(), el.subvolume->patches.end(),
                                     [&](const xfem::CutPatch& patch) { return c.supports.count(patch.source_face) > 0; });
  // The local penalty's parts on this cell: dΛ per entry of p is gathered in `d_lambda`.
  if (f.penalised) f.parts = xfem::local_penalty_parts(el, setup.material, setup.dirichlet, setup.solver);
  f.simple = f.penalised && f.parts.clamped && f.parts.gap > 1e-6 && f.parts.mode.size() == f.ue.size();
  f.lambda = f.parts.flux_eigenvalue;
  return f;
}

PatchConditions patch_conditions(const GradientContext& c, int g) {
  PatchConditions pc;
  for (const auto& d : c.setup.dirichlet) if (d.face == g) pc.dc = &d;
  for (size_t i = 0; i < c.at.tractions.size(); ++i)
    if (c.at.tractions[i].face == g) pc.tc = &c.at.tractions[i], pc.load = static_cast<int>(i);
  pc.spread_load = pc.load >= 0 && c.load_area[pc.load] > 0;
  return pc;
}

void bulk_term(const GradientContext& c, ElementFields& ef, const xfem::CutPatch& patch,
               const optimize::ParameterBlock& b, ElementTerms& out) {
  const ComplianceSetup& setup = c.setup;
  const Eigen::VectorXd& p = c.p;
  const xfem::GridElement& el = *ef.el;
  const optimize::ParameterBlock* block = &b;
  const bool simple = ef.simple;
  const double lambda = ef.lambda;
  const xfem::SurfaceRule sr = xfem::surface_rule(patch, c.so);
  if (sr.points.empty()) return;
  out.used = true;
  out.points += static_cast<int>(sr.points.size());
  const std::vector<double> dj = moving_density(c, ef.e, ef.ue, ef.le, sr.points, ef.density);
  const std::vector<double> psi_mode =
      simple ? xfem::bulk_shape_density(el, ef.parts.mode, ef.parts.mode, setup.material, setup.solver, sr.points)
             : std::vector<double>{};
  const int nb = block->size();
  std::vector<double> sum(nb, 0.0);
  for (size_t q = 0; q < sr.points.size(); ++q) {
    const double density = dj[q];
    const optimize::Dual phi = optimize::implicit_function(block->kind, p.data() + block->offset, sr.points[q]);
    const xfem::Vec3 grad(phi.g[nb], phi.g[nb + 1], phi.g[nb + 2]);
    const double gn = grad.norm();
    if (!(gn > 0)) continue;
    const double s = grad.dot(sr.normals[q]) >= 0 ? 1.0 : -1.0;
    for (int k = 0; k < nb; ++k) sum[k] += sr.weights[q] * density * (-s * phi.g[k] / gn);  // Vₙ = ∂X/∂p_k·n
    if (simple)  // −Λ vᵀdÂv
      for (int k = 0; k < nb; ++k) ef.d_lambda[block->offset + k] -= lambda * sr.weights[q] * psi_mode[q] * (-s * phi.g[k] / gn);
  }
  for (int k = 0; k < nb; ++k)
    if (sum[k] != 0) out.gradient.emplace_back(block->offset + k, sum[k]);
}

void pole_bulk_term(const GradientContext& ctx, ElementFields& ef, const xfem::CutPatch& patch, const PoleBlock& pb,
                    ElementTerms& out) {
  const ComplianceSetup& setup = ctx.setup;
  const xfem::GridElement& el = *ef.el;
  const PoleBlock* poles = &pb;
  const bool simple = ef.simple, penalised = ef.penalised;
  const double lambda = ef.lambda;
  // At the rule's (u, v) on the B-rep's own surface (the patch's surface; the pole block's knots).
  const xfem::SurfaceRule sr = xfem::surface_rule(patch, ctx.so);
  out.used = out.used || !sr.points.empty();
  out.points += static_cast<int>(sr.points.size());
  const std::vector<double> dj = moving_density(ctx, ef.e, ef.ue, ef.le, sr.points, ef.density);
  const std::vector<double> psi_mode =
      simple && !sr.points.empty()
          ? xfem::bulk_shape_density(el, ef.parts.mode, ef.parts.mode, setup.material, setup.solver, sr.points)
          : std::vector<double>{};
  std::map<int, double> sum;  // entry of p → contribution
  for (size_t q = 0; q < sr.points.size(); ++q) {
    const double density = dj[q];
    for (const PoleInfluence& w : pole_influence(poles->surface, sr.uv[q].x(), sr.uv[q].y())) {
      for (int c = 0; c < 3; ++c) sum[poles->offset + 3 * w.index + c] += sr.weights[q] * density * w.value * sr.normals[q][c];
      if (simple)  // −Λ vᵀdÂv
        for (int c = 0; c < 3; ++c)
          ef.d_lambda[poles->offset + 3 * w.index + c] -= lambda * sr.weights[q] * psi_mode[q] * w.value * sr.normals[q][c];
      else if (penalised && std::abs(w.value) > 1e-12)  // this pole moves the penalised cell's patch
        for (int c = 0; c < 3; ++c) out.penalised_poles.insert(poles->offset + 3 * w.index + c);
    }
  }
  for (const auto& [i, v] : sum)
    if (v != 0) out.gradient.emplace_back(i, v);
}

void surface_density_term(const GradientContext& c, ElementFields& ef, const xfem::CutPatch& patch, ElementTerms& out) {
  const ShapeParameters& sp = c.sp;
  const Eigen::VectorXd& p = c.p;
  const ShapeAdjoint* adj = c.adj;
  const char* who = c.who;
  const int e = ef.e, surface_face = c.surface_face;
  const double h = ef.h;
  // J's own surface integral ∫_F g dA over the moving F (u_h frozen, g continuous across
  // cell walls: no wall terms): ∫_F (∂ₙg + κg) Vₙ dA + ∮ g α ds for F's own motion, as for
  // a load's, and ∮ g a ds where a neighbour's motion slides F's edges (its strips).
  std::vector<double> g;
  std::vector<xfem::Vec3> dg;
  const auto density_at = [&](const std::vector<xfem::Vec3>& points) {
    adj->surface_density(e, points, g, dg);
    PARAFAB_VERIFY(g.size() == points.size() && dg.size() == points.size(),
                   who << ": the surface density gives " << g.size() << " values and " << dg.size()
                       << " gradients for " << points.size() << " points");
  };
  out.used = true;
  if (c.surface_own && c.face_moves[surface_face]) {
    const optimize::ParameterBlock& b = *sp.block(surface_face);
    const int nb = b.size();
    std::vector<double> sum(nb, 0.0);
    const xfem::SurfaceRule sr = xfem::surface_rule(patch, c.so);
    out.points += static_cast<int>(sr.points.size());
    density_at(sr.points);
    for (size_t q = 0; q < sr.points.size(); ++q) {
      const optimize::Dual phi = optimize::implicit_function(b.kind, p.data() + b.offset, sr.points[q]);
      const xfem::Vec3 grad(phi.g[nb], phi.g[nb + 1], phi.g[nb + 2]);
      const double gn = grad.norm();
      if (!(gn > 0)) continue;
      const double s = grad.dot(sr.normals[q]) >= 0 ? 1.0 : -1.0;
      const double kappa = s * optimize::implicit_mean_curvature(b.kind, p.data() + b.offset, sr.points[q]);
      const double density = dg[q].dot(sr.normals[q]) + kappa * g[q];
      for (int k = 0; k < nb; ++k) sum[k] += sr.weights[q] * density * (-s * phi.g[k] / gn);
    }
    const bool tangent = !own_edges(c, patch, ef.el->box, b, c.surface_sides, false, true,
                                    [&](const xfem::Vec3& X, const xfem::Vec3&, const std::vector<double>& alpha,
                                        double ds) {
                                      density_at({X});
                                      for (int k = 0; k < nb; ++k) sum[k] += g[0] * alpha[k] * ds;
                                      ++out.edge_points;
                                    });
    if (tangent) {
      out.tangent.push_back(surface_face);
    } else {
      for (int k = 0; k < nb; ++k)
        if (sum[k] != 0) out.gradient.emplace_back(b.offset + k, sum[k]);
    }
  }
  for (const xfem::UvLoop& loop : xfem::to_uv_loops(patch.loops))
    for (const xfem::CurveSegment2& seg : loop) {
      const int on = segment_face(c, patch, seg, c.surface_sides, 1e-6 * h);
      if (on < 0 || !c.face_moves[on]) continue;
      const int nb = sp.block(on)->size();
      std::vector<double> sum(nb, 0.0);
      const bool tangent = !neighbour_slide(c, patch, seg, on, [&](const xfem::Vec3& X, const xfem::Vec3&,
                                                                   const std::vector<double>& speed_k, double ds) {
        density_at({X});
        for (int k = 0; k < nb; ++k) sum[k] += g[0] * speed_k[k] * ds;
        ++out.edge_points;
      });
      if (tangent) {
        out.tangent.push_back(on);
        continue;
      }
      for (int k = 0; k < nb; ++k)
        if (sum[k] != 0) out.gradient.emplace_back(sp.block(on)->offset + k, sum[k]);
    }
}

void load_work_term(const GradientContext& c, const ElementFields& ef, const xfem::CutPatch& patch,
                    const PatchConditions& pc, ElementTerms& out) {
  const ComplianceSetup& setup = c.setup;
  const xfem::GridElement& el = *ef.el;
  const xfem::SurfaceRule sr = xfem::surface_rule(patch, c.so);
  double sum = 0;
  for (size_t q = 0; q < sr.points.size(); ++q)
    sum += sr.weights[q] * xfem::boundary_term_density(el, ef.ze, setup.material, setup.solver, nullptr, pc.tc, sr.points[q], sr.normals[q]).load;
  out.work.emplace_back(pc.load, sum);
}

void moving_load_term(const GradientContext& c, const ElementFields& ef, const xfem::CutPatch& patch,
                      const PatchConditions& pc, ElementTerms& out) {
  const ComplianceSetup& setup = c.setup;
  const Eigen::VectorXd& p = c.p;
  const xfem::GridElement& el = *ef.el;
  const Eigen::VectorXd& ze = ef.ze;
  const xfem::TractionCondition* tc = pc.tc;
  const int g = patch.source_face, load = pc.load, np = c.np;
  // The load's own motion (the surface-integral form of Eq. 6.30): with uₕ frozen,
  //   d/ds ∫_Γ uₕ·t dA = ∫_Γ (∂ₙ(uₕ·t) + κ uₕ·t) Vₙ dA + ∮_∂Γ uₕ·t α ds,
  // κ = div n (implicit_mean_curvature), and along an edge where Γ slides on its neighbour
  // F, α = −Vₙ (n_Γ·n_F)/(ν·n_F) across the edge (ν the outward conormal). C gains twice
  // that (2uᵀdf); a total force's traction F/A also changes with dA = ∫ κ Vₙ dA + ∮ α ds.
  const optimize::ParameterBlock& b = *c.sp.block(g);
  const int nb = b.size();
  std::vector<double> sum(nb, 0.0), dA(nb, 0.0);
  const xfem::SurfaceRule sr = xfem::surface_rule(patch, c.so);  // its points are counted by the bulk term
  for (size_t q = 0; q < sr.points.size(); ++q) {
    const optimize::Dual phi = optimize::implicit_function(b.kind, p.data() + b.offset, sr.points[q]);
    const xfem::Vec3 grad(phi.g[nb], phi.g[nb + 1], phi.g[nb + 2]);
    const double gn = grad.norm();
    if (!(gn > 0)) continue;
    const double s = grad.dot(sr.normals[q]) >= 0 ? 1.0 : -1.0;
    const double kappa = s * optimize::implicit_mean_curvature(b.kind, p.data() + b.offset, sr.points[q]);
    const xfem::BoundaryTermDensity d =  // of z: 2u (compliance) or −λ
        xfem::boundary_term_density(el, ze, setup.material, setup.solver, nullptr, tc, sr.points[q], sr.normals[q]);
    const double density = d.load_gradient.dot(sr.normals[q]) + kappa * d.load;
    for (int k = 0; k < nb; ++k) {
      const double vn = -s * phi.g[k] / gn;
      sum[k] += sr.weights[q] * density * vn;
      dA[k] += sr.weights[q] * kappa * vn;
    }
  }
  // Its edges: loop segments on a face across one of Γ's edges (all three sample points on
  // that face's surface, within 1e-6·h). The others lie on cell walls or on Γ's own seam,
  // whose terms cancel between their two sides.
  const bool tangent = !own_edges(c, patch, el.box, b, c.own_sides.at(g), false, true,
                                  [&](const xfem::Vec3& X, const xfem::Vec3& n_g, const std::vector<double>& alpha,
                                      double ds) {
    const double load = xfem::boundary_term_density(el, ze, setup.material, setup.solver, nullptr, tc, X, n_g).load;
    for (int k = 0; k < nb; ++k) {
      sum[k] += load * alpha[k] * ds;
      dA[k] += alpha[k] * ds;
    }
    ++out.edge_points;
  });
  if (tangent) {
    out.tangent.push_back(g);
  } else {
    for (int k = 0; k < nb; ++k) {
      if (sum[k] != 0) out.gradient.emplace_back(b.offset + k, sum[k]);
      if (pc.spread_load && dA[k] != 0) out.area.emplace_back(load * np + b.offset + k, dA[k]);
    }
  }
}

void moving_support_term(const GradientContext& c, ElementFields& ef, const xfem::CutPatch& patch,
                         const PatchConditions& pc, ElementTerms& out) {
  const ComplianceSetup& setup = c.setup;
  const Eigen::VectorXd& p = c.p;
  const ShapeAdjoint* adj = c.adj;
  const xfem::GridElement& el = *ef.el;
  const Eigen::VectorXd &ue = ef.ue, &le = ef.le, &ze = ef.ze;
  const xfem::LocalPenaltyParts& parts = ef.parts;
  const bool simple = ef.simple;
  const xfem::DirichletCondition* dc = pc.dc;
  const int g = patch.source_face;
  // A support's own motion (its Nitsche terms, Eq. 6.22, on a moving Γ): with uₕ frozen,
  //   d/ds ∫_Γ F(X, n) dA = ∫_Γ [(∂ₙF + κF) Vₙ − ∂F/∂n·∇_Γ Vₙ] dA + ∮_∂Γ F α ds,
  // the normal turning by n' = −∇_Γ Vₙ (optimize::implicit_normal_speed), α as for a load.
  // F = 2 l − k (2uᵀdf − uᵀdKu) for the compliance, l(z) + k(λ, u) for an adjoint (k's
  // bilinear form by polarization); with the local penalty (Λ simple) vᵀdBv is the same
  // integral of the flux density f = |Mσ(v)n|² of Λ's mode v.
  const optimize::ParameterBlock& b = *c.sp.block(g);
  const int nb = b.size();
  const double penalty = simple ? parts.penalty : -1;
  struct Field {
    double value = 0;
    xfem::Vec3 gradient = xfem::Vec3::Zero(), normal = xfem::Vec3::Zero();
  };
  const auto objective_field = [&](const xfem::Vec3& X, const xfem::Vec3& n) {
    const auto at_ = [&](const Eigen::VectorXd& v) {
      return xfem::boundary_term_density(el, v, setup.material, setup.solver, dc, nullptr, X, n, penalty);
    };
    Field F;
    if (!adj) {
      const xfem::BoundaryTermDensity d = at_(ue);
      F.value = 2 * d.load - d.stiffness;
      F.gradient = 2 * d.load_gradient - d.stiffness_gradient;
      F.normal = 2 * d.load_normal - d.stiffness_normal;
    } else {
      const xfem::BoundaryTermDensity dz = at_(ze), kp = at_(ue + le), km = at_(ue - le);
      F.value = dz.load + 0.25 * (kp.stiffness - km.stiffness);
      F.gradient = dz.load_gradient + 0.25 * (kp.stiffness_gradient - km.stiffness_gradient);
      F.normal = dz.load_normal + 0.25 * (kp.stiffness_normal - km.stiffness_normal);
    }
    return F;
  };
  const auto flux_field = [&](const xfem::Vec3& X, const xfem::Vec3& n) {
    const xfem::BoundaryTermDensity d =
        xfem::boundary_term_density(el, parts.mode, setup.material, setup.solver, dc, nullptr, X, n, penalty);
    return Field{d.flux, d.flux_gradient, d.flux_normal};
  };
  std::vector<double> sum(nb, 0.0), dB(nb, 0.0);
  const xfem::SurfaceRule sr = xfem::surface_rule(patch, c.so_support);  // degree 10/14, not counted in `points`
  for (size_t q = 0; q < sr.points.size(); ++q) {
    const xfem::Vec3& X = sr.points[q], &n = sr.normals[q];
    const optimize::NormalSpeed ns = optimize::implicit_normal_speed(b.kind, p.data() + b.offset, X);
    if (ns.speed.size() == 0) continue;  // ∇φ = 0 (an axis): no normal speed, as the bulk term skips
    const double s = ns.normal.dot(n) >= 0 ? 1.0 : -1.0;
    const double kappa = s * optimize::implicit_mean_curvature(b.kind, p.data() + b.offset, X);
    const Eigen::Matrix3d tangential = Eigen::Matrix3d::Identity() - n * n.transpose();
    const Field F = objective_field(X, n);
    const Field f = simple ? flux_field(X, n) : Field{};
    for (int k = 0; k < nb; ++k) {
      const double vn = s * ns.speed[k];
      const xfem::Vec3 dvn = s * (tangential * ns.gradient.row(k).transpose());
      sum[k] += sr.weights[q] * ((F.gradient.dot(n) + kappa * F.value) * vn - F.normal.dot(dvn));
      if (simple) dB[k] += sr.weights[q] * ((f.gradient.dot(n) + kappa * f.value) * vn - f.normal.dot(dvn));
    }
  }
  // Its edges: loop segments on a face across one of Γ's edges (as for a load's own
  // motion), and on the cell's walls: there the patch's piece in this cell slides along
  // the wall, and unlike a load's uₕ·t, F (σ(u)) jumps across the wall, so the two cells'
  // strips do not cancel (nor does a cell's own flux, whose B is its own).
  const bool tangent = !own_edges(c, patch, el.box, b, c.own_sides.at(g), true, true,
                                  [&](const xfem::Vec3& X, const xfem::Vec3& n_g, const std::vector<double>& alpha,
                                      double ds) {
    const Field F = objective_field(X, n_g);
    const Field f = simple ? flux_field(X, n_g) : Field{};
    for (int k = 0; k < nb; ++k) {
      sum[k] += F.value * alpha[k] * ds;
      dB[k] += f.value * alpha[k] * ds;
    }
    ++out.edge_points;
  });
  if (tangent) {
    out.tangent.push_back(g);
  } else {
    for (int k = 0; k < nb; ++k) {
      if (sum[k] != 0) out.gradient.emplace_back(b.offset + k, sum[k]);
      if (dB[k] != 0) ef.d_lambda[b.offset + k] += dB[k];
    }
  }
}

void neighbour_strips_term(const GradientContext& c, ElementFields& ef, const xfem::CutPatch& patch,
                           const PatchConditions& pc, ElementTerms& out) {
  const ComplianceSetup& setup = c.setup;
  const ShapeParameters& sp = c.sp;
  const ShapeAdjoint* adj = c.adj;
  const xfem::GridElement& el = *ef.el;
  const Eigen::VectorXd &ue = ef.ue, &le = ef.le, &ze = ef.ze;
  const xfem::LocalPenaltyParts& parts = ef.parts;
  const bool simple = ef.simple;
  const xfem::DirichletCondition* dc = pc.dc;
  const xfem::TractionCondition* tc = pc.tc;
  const int load = pc.load, np = c.np;
  const double h = ef.h;
  const auto it = c.neighbours.find(patch.source_face);
  // With the local penalty and Λ not simple the strips along a support's edges are not
  // integrated: the neighbours' patches in this (clamped, cut) cell are flagged above.
  if (it == c.neighbours.end() || (ef.penalised && dc && !simple)) return;
  // Loop segments of the patch that lie on a moving neighbour F (all three sample points on
  // F's surface): that edge moves inside the face with conormal speed a = Vₙ,F / (n_F·ν).
  for (const xfem::UvLoop& loop : xfem::to_uv_loops(patch.loops))
    for (const xfem::CurveSegment2& seg : loop) {
      const int on = segment_face(c, patch, seg, it->second, 1e-6 * h);
      if (on < 0) continue;
      const int nb = sp.block(on)->size();
      std::vector<double> sum(nb, 0.0), dA(nb, 0.0), dB(nb, 0.0);
      const double penalty = simple ? parts.penalty : -1;
      const bool tangent = !neighbour_slide(c, patch, seg, on, [&](const xfem::Vec3& X, const xfem::Vec3& n_g,
                                                                   const std::vector<double>& speed_k, double ds) {
        // (2 f_Γ − k_Γ)(u) for the compliance; f_Γ(z) + k_Γ(λ, u) for an adjoint (k_Γ's
        // bilinear form by polarization of its quadratic one).
        double strip = 0;
        if (!adj) {
          const xfem::BoundaryTermDensity d =
              xfem::boundary_term_density(el, ue, setup.material, setup.solver, dc, tc, X, n_g, penalty);
          strip = 2 * d.load - d.stiffness;
        } else {
          const auto k = [&](const Eigen::VectorXd& v) {
            return xfem::boundary_term_density(el, v, setup.material, setup.solver, dc, nullptr, X, n_g, penalty).stiffness;
          };
          strip = xfem::boundary_term_density(el, ze, setup.material, setup.solver, dc, tc, X, n_g, penalty).load +
                  0.25 * (k(ue + le) - k(ue - le));
        }
        const double flux_mode =  // vᵀdBv density
            simple && dc ? xfem::boundary_term_density(el, parts.mode, setup.material, setup.solver, dc, nullptr, X,
                                                       n_g, penalty)
                               .flux
                         : 0.0;
        for (int k = 0; k < nb; ++k) {
          sum[k] += strip * speed_k[k] * ds;
          dA[k] += speed_k[k] * ds;
          dB[k] += flux_mode * speed_k[k] * ds;
        }
        ++out.edge_points;
      });
      if (tangent) {
        out.tangent.push_back(on);
        continue;
      }
      const int offset = sp.block(on)->offset;
      for (int k = 0; k < nb; ++k) {
        if (sum[k] != 0) out.gradient.emplace_back(offset + k, sum[k]);
        if (pc.spread_load && dA[k] != 0) out.area.emplace_back(load * np + offset + k, dA[k]);
        if (dB[k] != 0) ef.d_lambda[offset + k] += dB[k];
      }
    }
}

void penalty_term(const GradientContext& c, const ElementFields& ef, ElementTerms& out) {
  // The penalty's change: dC = κ dΛ (2uᵀg − uᵀPu); for an adjoint dJ = κ dΛ (zᵀg + λᵀPu).
  if (!ef.simple) return;
  const Eigen::VectorXd &ue = ef.ue, &le = ef.le, &ze = ef.ze;
  const xfem::LocalPenaltyParts& parts = ef.parts;
  const double weight = c.adj ? ze.dot(parts.load) + le.dot(parts.mass * ue) : 2 * ue.dot(parts.load) - ue.dot(parts.mass * ue);
  for (const auto& [i, dl] : ef.d_lambda)
    if (dl != 0) out.gradient.emplace_back(i, c.setup.solver.nitsche_local_factor * dl * weight);
}

ElementTerms element_terms(const GradientContext& c, int e) {
  ElementTerms out;
  ElementFields ef = element_fields(c, e);
  for (const xfem::CutPatch& patch : ef.el->subvolume->patches) {
    const int face = patch.source_face;
    const bool own = c.own_sides.count(face) > 0;  // a support or load whose own motion counts
    if (ef.penalised && !ef.simple && (!c.conditioned.count(face) || own) && c.sp.block(face))
      out.penalised.push_back(face);
    // Bulk: Reynolds over the patches of moving faces (a support's or load's own motion that
    // is flagged by gradient_context is not integrated here).
    const bool wanted = face >= 0 && c.face_moves[face] && (!c.conditioned.count(face) || own);  // grid patches: −1
    if (const optimize::ParameterBlock* block = wanted ? c.sp.block(face) : nullptr) bulk_term(c, ef, patch, *block, out);
    if (const PoleBlock* poles = wanted ? c.sp.poles(face) : nullptr) pole_bulk_term(c, ef, patch, *poles, out);
    if (face >= 0 && face == c.surface_face) surface_density_term(c, ef, patch, out);
    if (!c.conditioned.count(face)) continue;
    // A support's or load's patch: its Nitsche / traction terms.
    const PatchConditions pc = patch_conditions(c, face);
    out.used = true;
    if (pc.spread_load) load_work_term(c, ef, patch, pc, out);  // ∫ z_h·t dA over the load face, for the area term
    if (own && wanted && pc.tc) moving_load_term(c, ef, patch, pc, out);
    // (With the local penalty and Λ not simple, the patch is flagged above: no penalty to use.)
    if (own && wanted && pc.dc && !(ef.penalised && !ef.simple)) moving_support_term(c, ef, patch, pc, out);
    neighbour_strips_term(c, ef, patch, pc, out);
  }
  penalty_term(c, ef, out);
  return out;
}

void sum_terms(const GradientContext& c, const std::vector<ElementTerms>& terms, ComplianceGradient& r) {
  const int np = c.np;
  std::vector<double> load_work(c.at.tractions.size(), 0.0);
  std::map<int, double> area_change;  // load · size(p) + entry → dA
  for (size_t w = 0; w < terms.size(); ++w) {  // in element order: deterministic
    const ElementTerms& t = terms[w];
    for (const auto& [i, v] : t.gradient) r.gradient[i] += v;
    for (const auto& [i, v] : t.area) area_change[i] += v;
    for (const auto& [i, v] : t.work) load_work[i] += v;
    for (int f : t.tangent) flag_face(c.sp, f, r.incomplete);
    for (int f : t.penalised) flag_face(c.sp, f, r.incomplete);
    for (int i : t.penalised_poles) r.incomplete[i] = 1;
    r.points += t.points + t.edge_points;
    r.edge_points += t.edge_points;
    if (t.used) ++r.elements;
  }
  // Total forces: t = F/A, so zᵀdf ∋ ∫ z_h·dt dA = −W dA/A with W = ∫ z_h·t dA (compliance:
  // z = 2u, the 2uᵀdf of dC; adjoint: z = −λ, the −λᵀdf of dJ).
  for (const auto& [key, dA] : area_change) {
    const int load = key / np, i = key % np;
    r.gradient[i] -= load_work[load] * dA / c.load_area[load];
  }
}

void tie_terms(const GradientContext& c, ComplianceGradient& r) {
  const ComplianceState& at = c.at;
  const ComplianceSetup& setup = c.setup;
  const ShapeAdjoint* adj = c.adj;
  const std::vector<xfem::GridElement>& elements = at.model->elements;
  const std::vector<char>& modes_tied = c.modes_tied;
  // Eq. 6.24's ties: the energy ½Σ w‖u_a − u_b‖² with w = E·h·b(d(p)), so
  // dC = −Σ E·h·b'(d) d' ‖u_a − u_b‖² (d' from the faces at the gap's ends: piece_gap_gradient).
  // A mode-tied pair adds ‖α_a − α_b‖² to that factor and −θ'·∂(uᵀKu)/∂θ, θ = 1 − e^(−b).
  // For an adjoint, λᵀdK u: the same with −(λ_a − λ_b)·(u_a − u_b) for ‖u_a − u_b‖² (and the
  // mode-tied quadratic forms polarized).
  if (at.ties.empty()) return;
  std::vector<char> complete;
  const Eigen::MatrixXd dd = piece_gap_gradient(at.gaps, c.sp, c.p, &complete);
  for (size_t i = 0; i < at.ties.size(); ++i) {
    const PieceGap& gap = at.gaps[i];
    const double h = at.model->elements[gap.element_a].box.size().minCoeff();
    double db = 0;
    const double b = merge_penalty_b(gap.joined ? 0.0 : gap.distance, setup.merge.critical_fraction * h, setup.merge, &db);
    if (db == 0) continue;
    const std::vector<char>& floating = at.solution.floating;
    const std::vector<std::array<int, 2>> pairs = xfem::tied_nodes(at.model->elements, at.solution.node, at.ties[i]);
    bool blended = false;  // a floating node blended towards an unknown: T changes with d (no term here)
    for (const auto& [ia, ib] : pairs) blended |= !floating.empty() && floating[ia] != floating[ib];
    if (!complete[i] || blended) {
      ++r.ties_without_derivative;
      for (const GapEnd* end : {&gap.a, &gap.b})
        for (int f : end->faces) flag_face(c.sp, f, r.incomplete);
      continue;
    }
    const Eigen::VectorXd& u = at.solution.u;
    double squared = 0;
    for (const auto& [ia, ib] : pairs)
      if (floating.empty() || (!floating[ia] && !floating[ib])) {  // as the solve ties them
        const Eigen::Vector3d du = u.segment<3>(3 * ia) - u.segment<3>(3 * ib);
        squared += adj ? -(adj->lambda.segment<3>(3 * ia) - adj->lambda.segment<3>(3 * ib)).dot(du) : du.squaredNorm();
      }
    double blend_factor = 0;  // ∂(uᵀKu)/∂θ · dθ/db
    if (modes_tied[i]) {
      const xfem::PieceTie& tie = at.ties[i];
      const std::vector<int>& na = at.solution.node[tie.element_a], &nb = at.solution.node[tie.element_b];
      const auto terms_of = [&](const Eigen::VectorXd& va, const Eigen::VectorXd& vb) {
        return xfem::tied_mode_shape_terms(elements, tie, va, vb, setup.material, setup.solver, 0, {});
      };
      const Eigen::VectorXd ua = element_values(u, na), ub = element_values(u, nb);
      if (!adj) {
        const xfem::TiedModeShapeTerms m = terms_of(ua, ub);
        squared += m.d_weight;
        blend_factor = m.d_blend * std::exp(-b);
      } else {
        const Eigen::VectorXd la = element_values(adj->lambda, na), lb = element_values(adj->lambda, nb);
        const xfem::TiedModeShapeTerms plus = terms_of(ua + la, ub + lb), minus = terms_of(ua - la, ub - lb);
        squared -= 0.25 * (plus.d_weight - minus.d_weight);
        blend_factor = -0.25 * (plus.d_blend - minus.d_blend) * std::exp(-b);
      }
    }
    r.gradient -= (setup.material.youngs_modulus * h * squared + blend_factor) * db *
                  dd.row(static_cast<Eigen::Index>(i)).transpose();
  }
}

}  // namespace parafab::occ::detail
