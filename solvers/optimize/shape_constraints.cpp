// Parameterization constraints c_para(p) (thesis §6.5.1, Fig. 6.11) with exact Jacobians and
// Hessians by forward-mode jets; the reduced tangency table mirrors occ_bridge/face_model.cpp.
#include "optimize/shape_constraints.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <map>

#include "common/error.h"

namespace parafab::optimize {

const char* to_string(PrimitiveKind kind) {
  static const char* names[] = {"plane", "cylinder", "cone", "sphere", "torus"};
  return names[static_cast<int>(kind)];
}

int block_size(PrimitiveKind kind) {
  static const int sizes[] = {4, 7, 8, 4, 8};
  return sizes[static_cast<int>(kind)];
}

const std::vector<std::string>& block_parameter_names(PrimitiveKind kind) {
  static const std::vector<std::vector<std::string>> names = {
      {"normal x", "normal y", "normal z", "offset"},
      {"axis point x", "axis point y", "axis point z", "axis x", "axis y", "axis z", "radius"},
      {"axis point x", "axis point y", "axis point z", "axis x", "axis y", "axis z", "radius", "half-angle"},
      {"centre x", "centre y", "centre z", "radius"},
      {"centre x", "centre y", "centre z", "axis x", "axis y", "axis z", "major radius", "minor radius"}};
  return names[static_cast<int>(kind)];
}

void ConstraintSystem::add(ScalarConstraint c) {
  for (size_t k = 0; k < c.vars.size(); ++k) {
    PARAFAB_VERIFY(c.vars[k] >= 0 && c.vars[k] < n_,
                   "constraint '" << c.name << "': parameter index " << c.vars[k] << " outside 0.." << n_ - 1);
    for (size_t l = 0; l < k; ++l)
      PARAFAB_VERIFY(c.vars[l] != c.vars[k], "constraint '" << c.name << "': parameter " << c.vars[k] << " twice");
  }
  constraints_.push_back(std::move(c));
  hessian_index_built_ = false;
}

namespace {

Jet evaluate_jet(const ScalarConstraint& c, const Eigen::VectorXd& p) {
  const int m = static_cast<int>(c.vars.size());
  std::vector<Jet> x;
  x.reserve(m);
  for (int k = 0; k < m; ++k) x.push_back(Jet::variable(p[c.vars[k]], k, m));
  Jet r = c.f(x);
  if (r.size() != m) r = Jet(r.v, m);  // a constant
  return r;
}

}  // namespace

Eigen::VectorXd ConstraintSystem::values(const Eigen::VectorXd& p) const {
  Eigen::VectorXd c(size());
  for (int i = 0; i < size(); ++i) {
    const ScalarConstraint& s = constraints_[i];
    std::vector<Jet> x;
    for (int k = 0; k < static_cast<int>(s.vars.size()); ++k) x.push_back(Jet(p[s.vars[k]], 0));
    c[i] = s.f(x).v;
  }
  return c;
}

Eigen::MatrixXd ConstraintSystem::jacobian(const Eigen::VectorXd& p) const {
  Eigen::MatrixXd J = Eigen::MatrixXd::Zero(size(), n_);
  for (int i = 0; i < size(); ++i) {
    const Jet j = evaluate_jet(constraints_[i], p);
    for (size_t k = 0; k < constraints_[i].vars.size(); ++k) J(i, constraints_[i].vars[k]) += j.g[k];
  }
  return J;
}

void ConstraintSystem::jacobian_structure(std::vector<int>& rows, std::vector<int>& cols) const {
  rows.clear();
  cols.clear();
  for (int i = 0; i < size(); ++i)
    for (int v : constraints_[i].vars) rows.push_back(i), cols.push_back(v);
}

void ConstraintSystem::jacobian_values(const Eigen::VectorXd& p, double* values) const {
  for (int i = 0; i < size(); ++i) {
    const Jet j = evaluate_jet(constraints_[i], p);
    for (size_t k = 0; k < constraints_[i].vars.size(); ++k) *values++ = j.g[k];
  }
}

void ConstraintSystem::build_hessian_index() const {
  if (hessian_index_built_) return;
  std::map<std::pair<int, int>, int> slot;
  hessian_rows_.clear();
  hessian_cols_.clear();
  for (int i = 0; i < n_; ++i) {
    slot[{i, i}] = i;
    hessian_rows_.push_back(i);
    hessian_cols_.push_back(i);
  }
  hessian_slot_.assign(constraints_.size(), {});
  for (size_t c = 0; c < constraints_.size(); ++c) {
    const auto& vars = constraints_[c].vars;
    const int m = static_cast<int>(vars.size());
    hessian_slot_[c].assign(m * m, -1);
    for (int k = 0; k < m; ++k)
      for (int l = 0; l <= k; ++l) {
        const std::pair<int, int> key{std::max(vars[k], vars[l]), std::min(vars[k], vars[l])};
        auto [it, inserted] = slot.emplace(key, static_cast<int>(hessian_rows_.size()));
        if (inserted) hessian_rows_.push_back(key.first), hessian_cols_.push_back(key.second);
        hessian_slot_[c][k * m + l] = it->second;
      }
  }
  hessian_index_built_ = true;
}

void ConstraintSystem::hessian_structure(std::vector<int>& rows, std::vector<int>& cols) const {
  build_hessian_index();
  rows = hessian_rows_;
  cols = hessian_cols_;
}

void ConstraintSystem::hessian_values(const Eigen::VectorXd& p, double objective_factor,
                                      const Eigen::VectorXd& lambda, double* values, const Eigen::VectorXd* outer) const {
  build_hessian_index();
  std::fill(values, values + hessian_rows_.size(), 0.0);
  for (int i = 0; i < n_; ++i) values[i] = objective_factor;
  for (int c = 0; c < size(); ++c) {
    const double s = outer ? (*outer)[c] : 0.0;
    if (lambda[c] == 0 && s == 0) continue;
    const Jet j = evaluate_jet(constraints_[c], p);
    const int m = static_cast<int>(constraints_[c].vars.size());
    for (int k = 0; k < m; ++k)
      for (int l = 0; l <= k; ++l) {
        // A repeated global pair (k != l mapping to one diagonal) cannot occur: vars are distinct.
        values[hessian_slot_[c][k * m + l]] += lambda[c] * j.h(k, l) + s * j.g[k] * j.g[l];
      }
  }
}

Eigen::MatrixXd ConstraintSystem::constraint_hessian(const Eigen::VectorXd& p, const Eigen::VectorXd& lambda) const {
  Eigen::MatrixXd H = Eigen::MatrixXd::Zero(n_, n_);
  for (int c = 0; c < size(); ++c) {
    if (lambda[c] == 0) continue;
    const Jet j = evaluate_jet(constraints_[c], p);
    const auto& vars = constraints_[c].vars;
    for (size_t k = 0; k < vars.size(); ++k)
      for (size_t l = 0; l < vars.size(); ++l) H(vars[k], vars[l]) += lambda[c] * j.h(k, l);
  }
  return H;
}

// --- Primitive accessors on a local jet vector ----------------------------------------------

namespace {

using J = Jet;
using JV = V3<J>;

JV vec_at(const std::vector<J>& x, int at) { return {x[at], x[at + 1], x[at + 2]}; }

// Components other than the largest of v (fixed at detection): two independent equations for
// "w ∥ v" when the equations are w × v's components.
std::array<int, 2> reduced_components(const Eigen::Vector3d& v) {
  int big = 0;
  v.cwiseAbs().maxCoeff(&big);
  return {(big + 1) % 3, (big + 2) % 3};
}

Eigen::Vector3d block_vec(const Eigen::VectorXd& p0, const ParameterBlock& b, int at) {
  return p0.segment<3>(b.offset + at);
}

std::vector<int> block_vars(const ParameterBlock& a, const ParameterBlock* b = nullptr) {
  std::vector<int> v;
  for (int k = 0; k < a.size(); ++k) v.push_back(a.offset + k);
  if (b)
    for (int k = 0; k < b->size(); ++k) v.push_back(b->offset + k);
  return v;
}

// Where a block's axis (plane: normal) starts inside the block; −1: none.
int axis_at(PrimitiveKind k) { return k == PrimitiveKind::plane ? 0 : k == PrimitiveKind::sphere ? -1 : 3; }

}  // namespace

void add_unit_axis(ConstraintSystem& system, const ParameterBlock& block, const std::string& label) {
  const int at = axis_at(block.kind);
  if (at < 0) return;
  system.add({label + ": |" + (block.kind == PrimitiveKind::plane ? "n" : "a") + std::to_string(block.face) +
                  "|^2 - 1 = 0",
              {block.offset + at, block.offset + at + 1, block.offset + at + 2},
              [](const std::vector<J>& x) { return x[0] * x[0] + x[1] * x[1] + x[2] * x[2] - 1.0; }});
}

int add_tangency(ConstraintSystem& system, const std::string& kind, const ParameterBlock& a, const ParameterBlock& b,
                 int sign, const Eigen::VectorXd& p0, const std::string& label) {
  using K = PrimitiveKind;
  const double s = sign < 0 ? -1.0 : 1.0;
  const int na = a.size();
  const std::vector<int> vars = block_vars(a, &b);
  const int before = system.size();
  auto need = [&](K ka, K kb) {
    PARAFAB_VERIFY(a.kind == ka && b.kind == kb, label << ": relation " << kind << " needs a " << to_string(ka)
                                                       << " and a " << to_string(kb) << ", got "
                                                       << to_string(a.kind) << " and " << to_string(b.kind));
  };
  auto add = [&](const std::string& eq, std::function<J(const std::vector<J>&)> f) {
    system.add({label + ": " + eq, vars, std::move(f)});
  };
  // Two components of u × w (u, w from the local jets at offsets iu, iw; or a difference).
  auto add_parallel = [&](const std::string& what, const Eigen::Vector3d& u0,
                          std::function<JV(const std::vector<J>&)> u, std::function<JV(const std::vector<J>&)> w) {
    for (int comp : reduced_components(u0))
      add("cross(" + what + ")." + "xyz"[comp] + " = 0", [=](const std::vector<J>& x) { return cross(u(x), w(x))[comp]; });
  };
  auto A = [&](int at) { return [=](const std::vector<J>& x) { return vec_at(x, at); }; };
  auto B = [&](int at) { return [=](const std::vector<J>& x) { return vec_at(x, na + at); }; };

  if (kind == "plane-plane") {
    need(K::plane, K::plane);
    const double sigma = block_vec(p0, a, 0).dot(block_vec(p0, b, 0)) < 0 ? -1.0 : 1.0;
    add_parallel("n_a, n_b", block_vec(p0, a, 0), A(0), B(0));
    add("s d_b - d_a = 0", [=](const std::vector<J>& x) { return sigma * x[na + 3] - x[3]; });
  } else if (kind == "plane-cylinder" || kind == "plane-sphere") {
    need(K::plane, kind == "plane-cylinder" ? K::cylinder : K::sphere);
    const int r = kind == "plane-cylinder" ? 6 : 3;
    add("s(d_a - n_a.c_b) - r_b = 0",
        [=](const std::vector<J>& x) { return s * (x[3] - dot(vec_at(x, 0), vec_at(x, na))) - x[na + r]; });
    if (kind == "plane-cylinder")
      add("n_a.a_b = 0", [=](const std::vector<J>& x) { return dot(vec_at(x, 0), vec_at(x, na + 3)); });
  } else if (kind == "plane-cone") {
    need(K::plane, K::cone);
    add("n_a.(c_b - r_b/tan(alpha_b) a_b) - d_a = 0", [=](const std::vector<J>& x) {
      const JV apex = vec_at(x, na) - (x[na + 6] / tan(x[na + 7])) * vec_at(x, na + 3);
      return dot(vec_at(x, 0), apex) - x[3];
    });
    add("s n_a.a_b - sin(alpha_b) = 0",
        [=](const std::vector<J>& x) { return s * dot(vec_at(x, 0), vec_at(x, na + 3)) - sin(x[na + 7]); });
  } else if (kind == "plane-torus") {
    need(K::plane, K::torus);
    add_parallel("n_a, a_b", block_vec(p0, a, 0), A(0), B(3));
    add("s(d_a - n_a.c_b) - r_b = 0",
        [=](const std::vector<J>& x) { return s * (x[3] - dot(vec_at(x, 0), vec_at(x, na))) - x[na + 7]; });
  } else if (kind == "cylinder-cylinder" &&
             (block_vec(p0, b, 0) - block_vec(p0, a, 0)).cross(block_vec(p0, a, 3)).norm() <=
                 1e-9 * (1 + std::abs(p0[a.offset + 6]))) {
    // One cylinder split into two faces: coaxial with equal radii (the distance form is not
    // differentiable at zero distance).
    need(K::cylinder, K::cylinder);
    add_parallel("a_a, a_b", block_vec(p0, a, 3), A(3), B(3));
    add_parallel("c_b - c_a, a_a", block_vec(p0, a, 3),
                 [=](const std::vector<J>& x) { return vec_at(x, na) - vec_at(x, 0); }, A(3));
    add("r_b - r_a = 0", [=](const std::vector<J>& x) { return x[na + 6] - x[6]; });
  } else if (kind == "cylinder-cylinder") {
    need(K::cylinder, K::cylinder);
    add_parallel("a_a, a_b", block_vec(p0, a, 3), A(3), B(3));
    add("|cross(c_b - c_a, a_a)| - (r_a + s r_b) = 0", [=](const std::vector<J>& x) {
      return norm(cross(vec_at(x, na) - vec_at(x, 0), vec_at(x, 3))) - (x[6] + s * x[na + 6]);
    });
  } else if (kind == "cylinder-sphere") {
    need(K::cylinder, K::sphere);
    add_parallel("c_b - c_a, a_a", block_vec(p0, a, 3),
                 [=](const std::vector<J>& x) { return vec_at(x, na) - vec_at(x, 0); }, A(3));
    add("r_b - r_a = 0", [=](const std::vector<J>& x) { return x[na + 3] - x[6]; });
  } else if (kind == "cylinder-torus") {
    need(K::cylinder, K::torus);
    add_parallel("a_a, a_b", block_vec(p0, a, 3), A(3), B(3));
    add_parallel("c_b - c_a, a_a", block_vec(p0, a, 3),
                 [=](const std::vector<J>& x) { return vec_at(x, na) - vec_at(x, 0); }, A(3));
    add("R_b + s r_b - r_a = 0", [=](const std::vector<J>& x) { return x[na + 6] + s * x[na + 7] - x[6]; });
  } else if (kind == "cylinder-torus-pipe") {
    need(K::cylinder, K::torus);
    add("a_a.a_b = 0", [=](const std::vector<J>& x) { return dot(vec_at(x, 3), vec_at(x, na + 3)); });
    add("(c_a - c_b).a_b = 0",
        [=](const std::vector<J>& x) { return dot(vec_at(x, 0) - vec_at(x, na), vec_at(x, na + 3)); });
    add("|cross(c_a - c_b, a_a)| - R_b = 0", [=](const std::vector<J>& x) {
      return norm(cross(vec_at(x, 0) - vec_at(x, na), vec_at(x, 3))) - x[na + 6];
    });
    add("r_a - r_b = 0", [=](const std::vector<J>& x) { return x[6] - x[na + 7]; });
  } else if (kind == "sphere-torus") {
    need(K::sphere, K::torus);
    add_parallel("c_a - c_b, a_b", block_vec(p0, b, 3),
                 [=](const std::vector<J>& x) { return vec_at(x, 0) - vec_at(x, na); }, B(3));
    add("sqrt(R_b^2 + ((c_a - c_b).a_b)^2) - (r_a + s r_b) = 0", [=](const std::vector<J>& x) {
      const J h = dot(vec_at(x, 0) - vec_at(x, na), vec_at(x, na + 3));
      return sqrt(x[na + 6] * x[na + 6] + h * h) - (x[3] + s * x[na + 7]);
    });
  } else if (kind == "coaxial") {
    // b's axis parallel to a's (unless b is a sphere), b's centre on a's axis: two independent
    // components each (those other than the largest of a's axis at p0).
    PARAFAB_VERIFY(axis_at(a.kind) == 3 && (axis_at(b.kind) == 3 || b.kind == K::sphere),
                   label << ": relation coaxial needs a cylinder, cone or torus and a face of revolution, got "
                         << to_string(a.kind) << " and " << to_string(b.kind));
    if (b.kind != K::sphere) add_parallel("a_a, a_b", block_vec(p0, a, 3), A(3), B(3));
    add_parallel("c_b - c_a, a_a", block_vec(p0, a, 3),
                 [=](const std::vector<J>& x) { return vec_at(x, na) - vec_at(x, 0); }, A(3));
  } else {
    PARAFAB_INPUT_ERROR(label << ": tangency relation '" << kind << "' has no equations in p");
  }
  return system.size() - before;
}

void add_linear(ConstraintSystem& system, const std::vector<int>& vars, const std::vector<double>& coefficients,
                double rhs, const std::string& label) {
  PARAFAB_VERIFY(vars.size() == coefficients.size() && !vars.empty(),
                 label << ": a linear constraint needs as many coefficients as parameters");
  system.add({label, vars, [coefficients, rhs](const std::vector<J>& x) {
                J r(-rhs, static_cast<int>(x.empty() ? 0 : x[0].size()));
                for (size_t k = 0; k < x.size(); ++k) r = r + coefficients[k] * x[k];
                return r;
              }});
}

int add_isometric_copy(ConstraintSystem& system, const ParameterBlock& a, const ParameterBlock& b,
                       const Eigen::Matrix3d& Q, const Eigen::Vector3d& t, const Eigen::VectorXd& p0,
                       const std::string& label) {
  using K = PrimitiveKind;
  PARAFAB_VERIFY(a.kind == b.kind, label << ": a symmetric copy needs faces of one type, got " << to_string(a.kind)
                                         << " and " << to_string(b.kind));
  PARAFAB_VERIFY((Q.transpose() * Q - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff() < 1e-12,
                 label << ": the map is not an isometry (QᵀQ ≠ I)");
  const int na = a.size(), before = system.size();
  const std::vector<int> vars = block_vars(a, &b);
  auto add = [&](const std::string& eq, std::function<J(const std::vector<J>&)> f) {
    system.add({label + ": " + eq, vars, std::move(f)});
  };
  auto map_dir = [Q](const JV& v) {
    return JV{Q(0, 0) * v.x + Q(0, 1) * v.y + Q(0, 2) * v.z, Q(1, 0) * v.x + Q(1, 1) * v.y + Q(1, 2) * v.z,
              Q(2, 0) * v.x + Q(2, 1) * v.y + Q(2, 2) * v.z};
  };
  auto map_point = [map_dir, t](const JV& v) {
    const JV q = map_dir(v);
    return JV{q.x + t.x(), q.y + t.y(), q.z + t.z()};
  };
  const Eigen::Vector3d axis_a0 = a.kind == K::sphere ? Eigen::Vector3d::UnitZ() : block_vec(p0, a, axis_at(a.kind));
  const Eigen::Vector3d qa0 = Q * axis_a0;
  if (a.kind == K::plane) {
    // n_a·X = d_a maps to (Q n_a)·X' = d_a + (Q n_a)·t; b may carry the opposite orientation.
    const double sigma = qa0.dot(block_vec(p0, b, 0)) < 0 ? -1.0 : 1.0;
    for (int comp : reduced_components(qa0))
      add(std::string("cross(Q n_a, n_b).") + "xyz"[comp] + " = 0",
          [=](const std::vector<J>& x) { return cross(map_dir(vec_at(x, 0)), vec_at(x, na))[comp]; });
    add("d_b - s(d_a + (Q n_a).t) = 0", [=](const std::vector<J>& x) {
      const JV qn = map_dir(vec_at(x, 0));
      return x[na + 3] - sigma * (x[3] + qn.x * t.x() + qn.y * t.y() + qn.z * t.z());
    });
    return system.size() - before;
  }
  // Centre / axis point: b's on the mapped axis (cylinder: its point slides), or the image (others).
  if (a.kind == K::cylinder) {
    for (int comp : reduced_components(qa0))
      add(std::string("cross(c_b - (Q c_a + t), a_b).") + "xyz"[comp] + " = 0", [=](const std::vector<J>& x) {
        return cross(vec_at(x, na) - map_point(vec_at(x, 0)), vec_at(x, na + 3))[comp];
      });
  } else {
    for (int comp = 0; comp < 3; ++comp)
      add(std::string("(c_b - (Q c_a + t)).") + "xyz"[comp] + " = 0",
          [=](const std::vector<J>& x) { return (vec_at(x, na) - map_point(vec_at(x, 0)))[comp]; });
  }
  if (a.kind != K::sphere)
    for (int comp : reduced_components(qa0))
      add(std::string("cross(Q a_a, a_b).") + "xyz"[comp] + " = 0",
          [=](const std::vector<J>& x) { return cross(map_dir(vec_at(x, 3)), vec_at(x, na + 3))[comp]; });
  for (int k = a.kind == K::sphere ? 3 : 6; k < na; ++k)
    add(block_parameter_names(a.kind)[k] + " equal", [=](const std::vector<J>& x) { return x[na + k] - x[k]; });
  return system.size() - before;
}

int add_mirror(ConstraintSystem& system, const ParameterBlock& a, const ParameterBlock& b, const Eigen::Vector3d& e,
               double m, const Eigen::VectorXd& p0, const std::string& label) {
  PARAFAB_VERIFY(e.norm() > 0, label << ": the mirror plane's normal is zero");
  const Eigen::Vector3d en = e.normalized();
  // X' = X − 2(e·X − m) e = (I − 2 e eᵀ) X + 2m e
  return add_isometric_copy(system, a, b, Eigen::Matrix3d::Identity() - 2.0 * en * en.transpose(), 2.0 * m * en, p0,
                            label);
}

int add_rotation(ConstraintSystem& system, const ParameterBlock& a, const ParameterBlock& b,
                 const Eigen::Vector3d& point, const Eigen::Vector3d& axis, double angle, const Eigen::VectorXd& p0,
                 const std::string& label) {
  PARAFAB_VERIFY(axis.norm() > 0, label << ": the rotation axis is zero");
  // X' = Q (X − o) + o
  const Eigen::Matrix3d Q = Eigen::AngleAxisd(angle, axis.normalized()).toRotationMatrix();
  return add_isometric_copy(system, a, b, Q, point - Q * point, p0, label);
}

namespace {

// φ(X; block) as a jet over (block parameters, X) in that order, or over X alone (the block held).
template <bool H>
JetT<H> implicit_jet(PrimitiveKind kind, const double* block, const Eigen::Vector3d& X, bool block_variables) {
  using J = JetT<H>;
  const int nb = block_size(kind), first = block_variables ? nb : 0, n = first + 3;
  std::vector<J> x;
  for (int k = 0; k < nb; ++k) x.push_back(block_variables ? J::variable(block[k], k, n) : J(block[k], n));
  const V3<J> P{J::variable(X.x(), first, n), J::variable(X.y(), first + 1, n), J::variable(X.z(), first + 2, n)};
  auto v = [&](int at) { return V3<J>{x[at], x[at + 1], x[at + 2]}; };
  switch (kind) {
    case PrimitiveKind::plane:
      return dot(v(0), P) - x[3];
    case PrimitiveKind::sphere:
      return norm(P - v(0)) - x[3];
    default:
      break;
  }
  const V3<J> w = P - v(0);
  const J alen = norm(v(3));
  const V3<J> a = (1.0 / alen) * v(3);
  const J h = dot(w, a);
  const J rho = norm(cross(w, a));
  switch (kind) {
    case PrimitiveKind::cylinder:
      return rho - x[6];
    case PrimitiveKind::cone:
      return (rho - x[6] - h * tan(x[7])) * cos(x[7]);
    case PrimitiveKind::torus: {
      const J q = rho - x[6];
      return sqrt(q * q + h * h) - x[7];
    }
    default:
      PARAFAB_INPUT_ERROR("implicit_function: no formula for " << to_string(kind));
  }
}

}  // namespace

Dual implicit_function(PrimitiveKind kind, const double* block, const Eigen::Vector3d& X) {
  if (kind == PrimitiveKind::plane) {  // φ = n·X − d in closed form: ∂φ/∂n = X, ∂φ/∂d = −1, ∇_X φ = n
    // (the rule derivatives call this at every boundary quadrature point: the bridge sample's 640
    // walls made the jet arithmetic a quarter of an evaluation)
    Dual phi(block[0] * X.x() + block[1] * X.y() + block[2] * X.z() - block[3], 7);
    phi.g << X.x(), X.y(), X.z(), -1.0, block[0], block[1], block[2];
    return phi;
  }
  return implicit_jet<false>(kind, block, X, true);
}

double implicit_mean_curvature(PrimitiveKind kind, const double* block, const Eigen::Vector3d& X) {
  if (kind == PrimitiveKind::plane) return 0;
  const Jet phi = implicit_jet<true>(kind, block, X, false);
  const double gn = phi.g.norm();
  PARAFAB_VERIFY(gn > 0, "implicit_mean_curvature: ∇φ = 0 at (" << X.transpose() << ") of a " << to_string(kind));
  const Eigen::Vector3d n = phi.g / gn;
  return (phi.h.trace() - n.dot(phi.h * n)) / gn;
}

NormalSpeed implicit_normal_speed(PrimitiveKind kind, const double* block, const Eigen::Vector3d& X) {
  const int nb = block_size(kind);
  const Jet phi = implicit_jet<true>(kind, block, X, true);
  const Eigen::Vector3d grad = phi.g.tail<3>();
  const double gn = grad.norm();
  NormalSpeed r;
  if (!(gn > 0)) return r;  // on an axis or centre: no normal (empty speed)
  // ∇_X |∇φ| = ∇²_X φ ∇φ / |∇φ|; ∇_X (∂φ/∂p_k) = the mixed block of the Hessian.
  const Eigen::Matrix3d hxx = phi.h.bottomRightCorner<3, 3>();
  const Eigen::Vector3d dgn = hxx * grad / gn;
  r.normal = grad / gn;
  r.speed.resize(nb);
  r.gradient.resize(nb, 3);
  for (int k = 0; k < nb; ++k) {
    r.speed[k] = -phi.g[k] / gn;
    const Eigen::Vector3d dphik = phi.h.block<3, 1>(nb, k);
    r.gradient.row(k) = (-(dphik / gn) + phi.g[k] * dgn / (gn * gn)).transpose();
  }
  return r;
}

V3<Dual> spine_point(PrimitiveKind kind, const double* block, const Eigen::Vector3d& X) {
  const int nb = block_size(kind);
  std::vector<Dual> x;
  for (int k = 0; k < nb; ++k) x.push_back(Dual::variable(block[k], k, nb));
  auto v = [&](int at) { return V3<Dual>{x[at], x[at + 1], x[at + 2]}; };
  const V3<Dual> P{Dual(X.x(), nb), Dual(X.y(), nb), Dual(X.z(), nb)};
  switch (kind) {
    case PrimitiveKind::sphere:
      return v(0);
    case PrimitiveKind::cylinder: {
      const V3<Dual> a = v(3);
      return v(0) + (dot(a, P - v(0)) / dot(a, a)) * a;
    }
    case PrimitiveKind::torus: {
      const V3<Dual> w = P - v(0), a = (1.0 / norm(v(3))) * v(3);
      const V3<Dual> radial = w - dot(w, a) * a;
      const Dual rho = norm(radial);
      PARAFAB_VERIFY(rho.v > 1e-12 * (1 + std::abs(x[6].v)), "spine_point: X lies on the torus's axis");
      return v(0) + (x[6] / rho) * radial;
    }
    default:
      PARAFAB_INPUT_ERROR("spine_point: a " << to_string(kind) << " has no spine");
  }
}

}  // namespace parafab::optimize
