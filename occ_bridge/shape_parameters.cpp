// Shape parameters and c_para of a part from its face model (thesis §6.5.1, Fig. 6.11).
#include "shape_parameters.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <optional>
#include <set>
#include <sstream>
#include <utility>

#include "common/error.h"

namespace parafab::occ {

namespace {

bool kind_of(SurfaceType t, optimize::PrimitiveKind& k) {
  using K = optimize::PrimitiveKind;
  switch (t) {
    case SurfaceType::plane: k = K::plane; return true;
    case SurfaceType::cylinder: k = K::cylinder; return true;
    case SurfaceType::cone: k = K::cone; return true;
    case SurfaceType::sphere: k = K::sphere; return true;
    case SurfaceType::torus: k = K::torus; return true;
    default: return false;
  }
}

void write_block(const optimize::ParameterBlock& b, const Primitive& pr, Eigen::VectorXd& p) {
  using K = optimize::PrimitiveKind;
  double* x = p.data() + b.offset;
  switch (b.kind) {
    case K::plane:
      for (int i = 0; i < 3; ++i) x[i] = pr.axis[i];
      x[3] = pr.axis.dot(pr.location);
      break;
    case K::sphere:
      for (int i = 0; i < 3; ++i) x[i] = pr.location[i];
      x[3] = pr.radius;
      break;
    default:
      for (int i = 0; i < 3; ++i) x[i] = pr.location[i], x[3 + i] = pr.axis[i];
      if (b.kind == K::torus) {
        x[6] = pr.major_radius;
        x[7] = pr.radius;
      } else {
        x[6] = pr.radius;
        if (b.kind == K::cone) x[7] = pr.semi_angle;
      }
  }
}

}  // namespace

Primitive primitive_of_block(const optimize::ParameterBlock& b, const Eigen::VectorXd& p, const Primitive& like) {
  using K = optimize::PrimitiveKind;
  Primitive pr = like;
  const double* x = p.data() + b.offset;
  const Vec3 v0(x[0], x[1], x[2]);
  switch (b.kind) {
    case K::plane: {
      const Vec3 n = v0;
      pr.axis = n.normalized();
      // The point of the new plane nearest the old origin keeps the (u, v) parameterization close.
      pr.location = like.location - (n.dot(like.location) - x[3]) / n.squaredNorm() * n;
      break;
    }
    case K::sphere:
      pr.location = v0;
      pr.radius = x[3];
      break;
    default:
      pr.location = v0;
      pr.axis = Vec3(x[3], x[4], x[5]).normalized();
      if (b.kind == K::torus) {
        pr.major_radius = x[6];
        pr.radius = x[7];
      } else {
        pr.radius = x[6];
        if (b.kind == K::cone) pr.semi_angle = x[7];
      }
  }
  if (b.kind != K::sphere) {  // x direction: the old one made orthogonal to the new axis
    Vec3 xd = like.x_direction - like.x_direction.dot(pr.axis) * pr.axis;
    if (xd.norm() < 1e-9) xd = pr.axis.unitOrthogonal();
    pr.x_direction = xd.normalized();
  }
  return pr;
}

namespace {

// A "g1" relation between a plane and a B-spline face whose two boundary rows of poles on one
// side (i = 1, 2; i = n, n − 1; j = 1, 2 or j = m, m − 1; clamped there) lie in the plane at p:
// the poles those rows hold. Nothing when no side, or more than one, does.
struct PlaneRows {
  const TangencyRelation* relation = nullptr;
  const optimize::ParameterBlock* plane = nullptr;
  const PoleBlock* poles = nullptr;
  std::vector<std::pair<int, int>> rows;  ///< (i, j), 1-based
};

std::optional<PlaneRows> plane_boundary_rows(const ShapeParameters& sp, const TangencyRelation& r, const Eigen::VectorXd& p) {
  PlaneRows out;
  out.relation = &r;
  for (int k = 0; k < 2; ++k) {
    const auto* b = sp.block(r.faces[k]);
    if (b && b->kind == optimize::PrimitiveKind::plane) out.plane = b, out.poles = sp.poles(r.faces[1 - k]);
  }
  if (!out.plane || !out.poles) return std::nullopt;
  const PoleBlock& pb = *out.poles;
  const NurbsSurface& s = pb.surface;
  const Vec3 n(p[out.plane->offset], p[out.plane->offset + 1], p[out.plane->offset + 2]);
  const double d = p[out.plane->offset + 3];
  double scale = 1;
  for (int k = 0; k < pb.size(); ++k) scale = std::max(scale, std::abs(p[pb.offset + k]));
  auto on_plane = [&](int i, int j) {
    const Vec3 P(p[pb.entry(i, j, 0)], p[pb.entry(i, j, 1)], p[pb.entry(i, j, 2)]);
    return std::abs(n.dot(P) - d) <= 1e-9 * scale;
  };
  const int nu = pb.count_u(), nv = pb.count_v();
  // Clamped ends only: the boundary curve is the end row, the cross derivative the next one.
  auto clamped = [](const std::vector<double>& U, int degree, bool periodic, bool start) {
    if (periodic) return false;
    const int n = static_cast<int>(U.size());
    for (int k = 1; k <= degree; ++k)
      if (start ? U[k] != U[0] : U[n - 1 - k] != U[n - 1]) return false;
    return true;
  };
  std::vector<std::vector<std::pair<int, int>>> sides;
  auto try_side = [&](bool along_u, bool start) {
    if (!clamped(along_u ? s.knots_u : s.knots_v, along_u ? s.degree_u : s.degree_v, along_u ? s.periodic_u : s.periodic_v, start))
      return;
    const int count = along_u ? nu : nv, other = along_u ? nv : nu;
    if (count < 3) return;
    std::vector<std::pair<int, int>> rows;
    for (int row : {start ? 1 : count, start ? 2 : count - 1})
      for (int k = 1; k <= other; ++k) {
        const int i = along_u ? row : k, j = along_u ? k : row;
        if (!on_plane(i, j)) return;
        rows.push_back({i, j});
      }
    sides.push_back(rows);
  };
  for (bool along_u : {true, false})
    for (bool start : {true, false}) try_side(along_u, start);
  if (sides.size() != 1) return std::nullopt;
  out.rows = sides[0];
  return out;
}

}  // namespace

ShapeParameters build_shape_parameters(const FaceModel& model, const ShapeParameterOptions& options) {
  ShapeParameters sp;
  const int nf = static_cast<int>(model.faces.size());
  sp.block_of_face.assign(nf, -1);
  int offset = 0;
  for (const FaceInfo& f : model.faces) {
    optimize::PrimitiveKind k;
    if (!kind_of(f.primitive.type, k)) continue;
    sp.block_of_face[f.index] = static_cast<int>(sp.blocks.size());
    sp.blocks.push_back({f.index, k, offset});
    offset += optimize::block_size(k);
  }
  sp.pole_block_of_face.assign(nf, -1);
  const int analytic_entries = offset;
  for (const FaceInfo& f : model.faces) {
    if (f.primitive.type != SurfaceType::bspline) continue;
    if (f.bspline.count_u == 0) {
      sp.notes.push_back("face " + std::to_string(f.index) +
                         ": its surface is a wrapped B-spline (trimmed, offset); its poles are not parameters");
      continue;
    }
    sp.pole_block_of_face[f.index] = static_cast<int>(sp.pole_blocks.size());
    sp.pole_blocks.push_back({f.index, offset, f.bspline});
    offset += sp.pole_blocks.back().size();
  }
  sp.initial.resize(offset);
  sp.lower = Eigen::VectorXd::Constant(offset, -1e19);
  sp.upper = Eigen::VectorXd::Constant(offset, 1e19);
  sp.names.resize(analytic_entries);
  for (const PoleBlock& b : sp.pole_blocks) {
    const NurbsSurface& s = b.surface;
    for (int i = 1; i <= b.count_u(); ++i)
      for (int j = 1; j <= b.count_v(); ++j) {
        const Eigen::Vector4d& q = s.pole(i - 1, j - 1);
        for (int c = 0; c < 3; ++c) sp.initial[b.entry(i, j, c)] = q[c] / q[3];
      }
  }
  for (const auto& b : sp.blocks) {
    write_block(b, model.faces[b.face].primitive, sp.initial);
    const auto& names = optimize::block_parameter_names(b.kind);
    for (int k = 0; k < b.size(); ++k) {
      sp.names[b.offset + k] = "face " + std::to_string(b.face) + " " + optimize::to_string(b.kind) + " " + names[k];
      if (names[k].find("radius") != std::string::npos) sp.lower[b.offset + k] = options.min_radius;
      // OCCT's half-angle is negative for a cone narrowing along its axis (MakeCone(R1 > R2)):
      // the bounds keep its sign (a positive range clamped such a cone flat, its apex 10 m away).
      if (names[k] == "half-angle") {
        const bool narrowing = sp.initial[b.offset + k] < 0;
        sp.lower[b.offset + k] = narrowing ? -(M_PI / 2 - 1e-3) : 1e-3;
        sp.upper[b.offset + k] = narrowing ? -1e-3 : M_PI / 2 - 1e-3;
      }
    }
  }
  for (const PoleBlock& b : sp.pole_blocks)
    for (int i = 1; i <= b.count_u(); ++i)
      for (int j = 1; j <= b.count_v(); ++j)
        for (int c = 0; c < 3; ++c)
          sp.names.push_back("face " + std::to_string(b.face) + " bspline pole " + std::to_string(i) + " " +
                             std::to_string(j) + " " + "xyz"[c]);
  // Fixed faces: the user's, and analytic faces tangent to a face without parameters.
  std::set<int> fixed;
  for (int f : options.fixed_faces) {
    PARAFAB_VERIFY(f >= 0 && f < nf, "fixed face " << f << " does not exist (the part has " << nf << " faces)");
    fixed.insert(f);
  }
  // G1 between a plane and a B-spline face along one of its boundaries, the rows of poles on
  // that boundary and next to it in the plane (what makes a clamped B-spline leave a plane
  // tangentially): kept as equations n·P − d = 0 on those poles (below), not by fixing both.
  std::vector<PlaneRows> plane_rows;
  for (const TangencyRelation& r : model.relations) {
    if (r.kind != "g1") continue;
    if (std::optional<PlaneRows> pr = plane_boundary_rows(sp, r, sp.initial)) plane_rows.push_back(*pr);
  }
  auto plane_rows_of = [&](const TangencyRelation& r) {
    return std::any_of(plane_rows.begin(), plane_rows.end(), [&](const PlaneRows& pr) { return pr.relation == &r; });
  };
  for (const TangencyRelation& r : model.relations) {
    const bool a = sp.block_of_face[r.faces[0]] >= 0, b = sp.block_of_face[r.faces[1]] >= 0;
    if (plane_rows_of(r)) continue;
    if (r.kind == "g1" || !a || !b) {
      std::ostringstream os;
      os << "faces " << r.faces[0] << " and " << r.faces[1] << " (" << to_string(model.faces[r.faces[0]].primitive.type)
         << ", " << to_string(model.faces[r.faces[1]].primitive.type) << ") are tangent without equations in p: both kept fixed";
      sp.notes.push_back(os.str());
      fixed.insert(r.faces[0]);
      fixed.insert(r.faces[1]);
    }
  }
  for (int f : fixed) {
    int first = -1, size = 0;
    if (const auto* b = sp.block(f)) first = b->offset, size = b->size();
    if (const auto* b = sp.poles(f)) first = b->offset, size = b->size();
    if (first < 0) continue;
    sp.fixed_faces.push_back(f);
    for (int k = first; k < first + size; ++k) sp.lower[k] = sp.upper[k] = sp.initial[k];
  }
  auto is_fixed = [&](int face) { return fixed.count(face) > 0; };

  sp.constraints = optimize::ConstraintSystem(offset);
  for (const auto& b : sp.blocks)
    if (!is_fixed(b.face)) optimize::add_unit_axis(sp.constraints, b, "face " + std::to_string(b.face));
  for (const TangencyRelation& r : model.relations) {
    const auto *a = sp.block(r.faces[0]), *b = sp.block(r.faces[1]);
    if (r.kind == "g1" || !a || !b || (is_fixed(r.faces[0]) && is_fixed(r.faces[1]))) continue;
    sp.relation_equations += optimize::add_tangency(sp.constraints, r.kind, *a, *b, r.sign, sp.initial,
                                                    "faces " + std::to_string(r.faces[0]) + "-" +
                                                        std::to_string(r.faces[1]) + " " + r.kind);
  }
  for (const PlaneRows& pr : plane_rows) {
    if (is_fixed(pr.plane->face) && is_fixed(pr.poles->face)) continue;
    const std::string label = "faces " + std::to_string(pr.plane->face) + "-" + std::to_string(pr.poles->face) + " g1";
    for (const auto& [i, j] : pr.rows) {
      std::vector<int> vars;
      for (int k = 0; k < 4; ++k) vars.push_back(pr.plane->offset + k);  // n, d
      for (int c = 0; c < 3; ++c) vars.push_back(pr.poles->entry(i, j, c));
      sp.constraints.add({label + ": pole " + std::to_string(i) + " " + std::to_string(j) + " in the plane", vars,
                          [](const std::vector<optimize::Jet>& x) { return x[0] * x[4] + x[1] * x[5] + x[2] * x[6] - x[3]; }});
      ++sp.relation_equations;
    }
  }
  sp.first_user_constraint = sp.constraints.size();  // ties, symmetries, draft from here on
  for (const auto& tie : options.ties) {
    PARAFAB_VERIFY(tie.size() >= 2, "a tie needs at least two parameters");
    const int first = parameter_index(sp, tie[0].face, tie[0].parameter);
    for (size_t k = 1; k < tie.size(); ++k) {
      const int other = parameter_index(sp, tie[k].face, tie[k].parameter);
      optimize::add_linear(sp.constraints, {first, other}, {1.0, -1.0}, 0.0,
                           "tie " + sp.names[first] + " = " + sp.names[other]);
    }
  }
  // A symmetric copy must hold for the part as read: its equations (rows from `first` on, until
  // the next copy's) vanish at p0 up to round-off of the STEP data (lengths relative to the
  // blocks' largest entry). Checked once all copies are added, in one evaluation of c(p0).
  std::vector<std::pair<int, std::string>> copies;  // (first row, which entry) in row order
  auto holds_at_start = [&](int first_row, const std::string& what) { copies.emplace_back(first_row, what); };
  for (size_t k = 0; k < options.mirrors.size(); ++k) {
    const auto& m = options.mirrors[k];
    const auto *a = sp.block(m.face_a), *b = sp.block(m.face_b);
    if (!(a && b)) PARAFAB_INPUT_ERROR("mirrors[" << k << "]: faces " << m.face_a << " and " << m.face_b << " need analytic surfaces");
    const int first = sp.constraints.size();
    optimize::add_mirror(sp.constraints, *a, *b, m.normal, m.offset, sp.initial,
                         "mirror " + std::to_string(m.face_a) + "/" + std::to_string(m.face_b));
    holds_at_start(first, "mirrors[" + std::to_string(k) + "] (face " + std::to_string(m.face_b) + " the mirror image of face " +
                              std::to_string(m.face_a) + ")");
  }
  for (size_t k = 0; k < options.rotations.size(); ++k) {
    const auto& r = options.rotations[k];
    const std::string at = "rotations[" + std::to_string(k) + "]";
    if (r.faces.size() < 2) PARAFAB_INPUT_ERROR(at << ": needs at least two faces, got " << r.faces.size());
    if (!(r.axis.norm() > 0)) PARAFAB_INPUT_ERROR(at << ": the axis is zero");
    if (!(std::isfinite(r.degrees) && std::abs(r.degrees) > 0 && std::abs(r.degrees) < 360))
      PARAFAB_INPUT_ERROR(at << ": degrees must be in (-360, 360) and not 0, got " << r.degrees);
    for (size_t i = 0; i + 1 < r.faces.size(); ++i) {
      const int fa = r.faces[i], fb = r.faces[i + 1];
      const auto *a = sp.block(fa), *b = sp.block(fb);
      if (!(a && b)) PARAFAB_INPUT_ERROR(at << ": faces " << fa << " and " << fb << " need analytic surfaces");
      if (a->kind != b->kind)
        PARAFAB_INPUT_ERROR(at << ": face " << fb << " (" << optimize::to_string(b->kind) << ") cannot be a turned copy of face "
                               << fa << " (" << optimize::to_string(a->kind) << ")");
      if (is_fixed(fa) != is_fixed(fb))
        sp.notes.push_back(at + ": face " + std::to_string(is_fixed(fa) ? fa : fb) + " is fixed, so face " +
                           std::to_string(is_fixed(fa) ? fb : fa) + " is held too");
      const int first = sp.constraints.size();
      optimize::add_rotation(sp.constraints, *a, *b, r.point, r.axis, r.degrees * M_PI / 180, sp.initial,
                             "rotation " + std::to_string(fa) + "->" + std::to_string(fb));
      std::ostringstream what;
      what << at << " (face " << fb << " = face " << fa << " turned by " << r.degrees << "°)";
      holds_at_start(first, what.str());
    }
  }
  if (!copies.empty()) {
    const Eigen::VectorXd c = sp.constraints.values(sp.initial);
    const int end = sp.constraints.size();
    for (size_t k = 0; k < copies.size(); ++k)
      for (int i = copies[k].first; i < (k + 1 < copies.size() ? copies[k + 1].first : end); ++i) {
        double scale = 1;
        for (int v : sp.constraints.constraints()[i].vars) scale = std::max(scale, std::abs(sp.initial[v]));
        if (!(std::abs(c[i]) <= 1e-7 * scale))
          PARAFAB_INPUT_ERROR(copies[k].second << " does not hold for the part as read: '"
                                               << sp.constraints.constraints()[i].name << "' is " << c[i]);
      }
  }
  for (size_t k = 0; k < options.orthogonal.size(); ++k) {
    const auto& o = options.orthogonal[k];
    const auto* b = sp.block(o.face);
    using K = optimize::PrimitiveKind;
    if (!(b && (b->kind == K::plane || b->kind == K::cylinder || b->kind == K::cone)))
      PARAFAB_INPUT_ERROR("orthogonal[" << k << "]: face " << o.face << " is "
                                        << (b ? optimize::to_string(b->kind) : "not analytic")
                                        << " (a plane keeps its normal orthogonal to the axis, a cylinder or cone its axis parallel to it)");
    if (!(o.axis.norm() > 0)) PARAFAB_INPUT_ERROR("orthogonal[" << k << "]: the axis is zero");
    const Vec3 a = o.axis.normalized();
    const std::string face = "face " + std::to_string(o.face);
    if (b->kind == K::plane) {
      const std::vector<int> n = {parameter_index(sp, o.face, "normal x"), parameter_index(sp, o.face, "normal y"),
                                  parameter_index(sp, o.face, "normal z")};
      const double at_start = a.x() * sp.initial[n[0]] + a.y() * sp.initial[n[1]] + a.z() * sp.initial[n[2]];
      if (!(std::abs(at_start) <= 1e-9)) PARAFAB_INPUT_ERROR("orthogonal[" << k << "]: " << face
                                                                     << "'s normal is not orthogonal to the axis at the start (n·a = "
                                                                     << at_start << ")");
      optimize::add_linear(sp.constraints, n, {a.x(), a.y(), a.z()}, 0.0, face + " normal orthogonal to the axis");
      continue;
    }
    // A cylinder's normals are all orthogonal to `a` exactly when its axis v is parallel to a (a
    // cone's then keep their draft angle to a): v × a = 0, two independent linear rows (the
    // components other than the one along a's largest entry, which follows from them).
    const std::vector<int> v = {parameter_index(sp, o.face, "axis x"), parameter_index(sp, o.face, "axis y"),
                                parameter_index(sp, o.face, "axis z")};
    const Vec3 v0(sp.initial[v[0]], sp.initial[v[1]], sp.initial[v[2]]);
    if (!(v0.normalized().cross(a).norm() <= 1e-9))
      PARAFAB_INPUT_ERROR("orthogonal[" << k << "]: " << face << "'s axis is not parallel to the axis at the start (|v × a| = "
                                        << v0.normalized().cross(a).norm() << ")");
    int largest = 0;
    a.cwiseAbs().maxCoeff(&largest);
    for (int comp = 0; comp < 3; ++comp) {
      if (comp == largest) continue;
      const int i = (comp + 1) % 3, j = (comp + 2) % 3;  // (v × a)_comp = v_i a_j − v_j a_i
      optimize::add_linear(sp.constraints, {v[i], v[j]}, {a[j], -a[i]}, 0.0,
                           face + " axis parallel to the axis (" + "xyz"[comp] + " of v × a)");
    }
  }
  return sp;
}

Eigen::VectorXd projection_weights(const ShapeParameters& sp, const std::vector<int>& design, double follower,
                                   double length) {
  Eigen::VectorXd w = Eigen::VectorXd::Constant(sp.size(), follower);
  for (int i : design) w[i] = 1;
  for (const auto& b : sp.blocks) {
    const auto& names = optimize::block_parameter_names(b.kind);
    for (int k = 0; k < b.size(); ++k)
      if (names[k].rfind("normal", 0) == 0 || (names[k].size() == 6 && names[k].rfind("axis ", 0) == 0) || names[k] == "half-angle")
        w[b.offset + k] = length * length;
  }
  return w;
}

int parameter_index(const ShapeParameters& sp, int face, const std::string& parameter) {
  if (const PoleBlock* pb = sp.poles(face)) {
    std::istringstream in(parameter);
    std::string word, coordinate, rest;
    int i = 0, j = 0;
    if (in >> word >> i >> j >> coordinate && !(in >> rest) && word == "pole" && coordinate.size() == 1 &&
        std::string("xyz").find(coordinate[0]) != std::string::npos && i >= 1 && i <= pb->count_u() && j >= 1 &&
        j <= pb->count_v())
      return pb->entry(i, j, coordinate[0] - 'x');
    PARAFAB_INPUT_ERROR("face " << face << " (bspline, " << pb->count_u() << " x " << pb->count_v()
                                << " poles) has no parameter '" << parameter << "'; its parameters are 'pole i j x|y|z' with i in 1.."
                                << pb->count_u() << " and j in 1.." << pb->count_v());
  }
  const auto* b = sp.block(face);
  PARAFAB_VERIFY(b, "face " << face << " has no shape parameters (not an analytic or non-periodic B-spline face of the part, or absent)");
  const auto& names = optimize::block_parameter_names(b->kind);
  for (int k = 0; k < b->size(); ++k)
    if (names[k] == parameter) return b->offset + k;
  std::ostringstream os;
  for (const auto& n : names) os << " '" << n << "'";
  PARAFAB_INPUT_ERROR("face " << face << " (" << optimize::to_string(b->kind) << ") has no parameter '" << parameter
                              << "'; it has" << os.str());
}

double tangency_residual_max(const FaceModel& model, const ShapeParameters& sp, const Eigen::VectorXd& p) {
  double worst = 0;
  for (const TangencyRelation& r : model.relations) {
    if (r.kind == "g1") continue;
    FaceInfo a = model.faces[r.faces[0]], b = model.faces[r.faces[1]];
    if (const auto* ba = sp.block(a.index)) a.primitive = primitive_of_block(*ba, p, a.primitive);
    if (const auto* bb = sp.block(b.index)) b.primitive = primitive_of_block(*bb, p, b.primitive);
    for (double x : tangency_residuals(r, a, b)) worst = std::max(worst, std::abs(x));
  }
  return worst;
}

}  // namespace parafab::occ
