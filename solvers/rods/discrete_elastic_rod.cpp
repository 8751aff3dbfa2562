#include "rods/discrete_elastic_rod.h"

#include <Eigen/Sparse>
#include <Eigen/SparseCholesky>
#include <algorithm>
#include <chrono>
#include <cmath>

#include "common/error.h"

namespace parafab {

namespace {

// Second-order forward-mode number: value, gradient and Hessian over N inputs.
template <int N>
struct Jet {
  double v = 0;
  Eigen::Matrix<double, N, 1> g = Eigen::Matrix<double, N, 1>::Zero();
  Eigen::Matrix<double, N, N> H = Eigen::Matrix<double, N, N>::Zero();
  Jet() = default;
  Jet(double value) : v(value) {}  // NOLINT: constants convert implicitly
  static Jet variable(double value, int i) {
    Jet j(value);
    j.g(i) = 1;
    return j;
  }
};
template <int N>
Jet<N> chain(const Jet<N>& a, double f, double f1, double f2) {
  Jet<N> r;
  r.v = f;
  r.g = f1 * a.g;
  r.H = f1 * a.H + f2 * a.g * a.g.transpose();
  return r;
}
template <int N> Jet<N> operator+(const Jet<N>& a, const Jet<N>& b) { Jet<N> r; r.v = a.v + b.v; r.g = a.g + b.g; r.H = a.H + b.H; return r; }
template <int N> Jet<N> operator-(const Jet<N>& a, const Jet<N>& b) { Jet<N> r; r.v = a.v - b.v; r.g = a.g - b.g; r.H = a.H - b.H; return r; }
template <int N> Jet<N> operator-(const Jet<N>& a) { Jet<N> r; r.v = -a.v; r.g = -a.g; r.H = -a.H; return r; }
template <int N> Jet<N> operator+(const Jet<N>& a, double b) { Jet<N> r = a; r.v += b; return r; }
template <int N> Jet<N> operator+(double b, const Jet<N>& a) { return a + b; }
template <int N> Jet<N> operator-(const Jet<N>& a, double b) { return a + (-b); }
template <int N> Jet<N> operator-(double b, const Jet<N>& a) { return (-a) + b; }
template <int N> Jet<N> operator*(const Jet<N>& a, double b) { Jet<N> r; r.v = a.v * b; r.g = a.g * b; r.H = a.H * b; return r; }
template <int N> Jet<N> operator*(double b, const Jet<N>& a) { return a * b; }
template <int N> Jet<N> operator*(const Jet<N>& a, const Jet<N>& b) {
  Jet<N> r;
  r.v = a.v * b.v;
  r.g = a.v * b.g + b.v * a.g;
  const Eigen::Matrix<double, N, N> o = a.g * b.g.transpose();
  r.H = a.v * b.H + b.v * a.H + o + o.transpose();
  return r;
}
template <int N> Jet<N> inv(const Jet<N>& a) { return chain(a, 1 / a.v, -1 / (a.v * a.v), 2 / (a.v * a.v * a.v)); }
template <int N> Jet<N> operator/(const Jet<N>& a, const Jet<N>& b) { return a * inv(b); }
template <int N> Jet<N> operator/(const Jet<N>& a, double b) { return a * (1 / b); }
template <int N> Jet<N> operator/(double a, const Jet<N>& b) { return a * inv(b); }
template <int N> Jet<N> sqrt(const Jet<N>& a) { const double s = std::sqrt(a.v); return chain(a, s, 0.5 / s, -0.25 / (s * a.v)); }
template <int N> Jet<N> sin(const Jet<N>& a) { return chain(a, std::sin(a.v), std::cos(a.v), -std::sin(a.v)); }
template <int N> Jet<N> cos(const Jet<N>& a) { return chain(a, std::cos(a.v), -std::sin(a.v), -std::cos(a.v)); }
// atan2 through a rotation to angle ≈ 0 and atan (smooth for (x, y) ≠ 0).
template <int N> Jet<N> atan2(const Jet<N>& y, const Jet<N>& x) {
  const double th = std::atan2(y.v, x.v), x0 = x.v, y0 = y.v;
  const Jet<N> X = x0 * x + y0 * y, Y = x0 * y - y0 * x;
  const Jet<N> z = Y / X;
  const double q = 1 + z.v * z.v;
  Jet<N> r = chain(z, std::atan(z.v), 1 / q, -2 * z.v / (q * q));
  r.v = th;
  return r;
}
using std::atan2;
using std::cos;
using std::sin;
using std::sqrt;

template <class T>
struct V3 {
  T x, y, z;
};
template <class T> V3<T> operator+(const V3<T>& a, const V3<T>& b) { return {a.x + b.x, a.y + b.y, a.z + b.z}; }
template <class T> V3<T> operator-(const V3<T>& a, const V3<T>& b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }
template <class T, class S> V3<T> scale(const S& s, const V3<T>& a) { return {s * a.x, s * a.y, s * a.z}; }
template <class T> T dot(const V3<T>& a, const V3<T>& b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
template <class T> V3<T> cross(const V3<T>& a, const V3<T>& b) {
  return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
template <class T> V3<T> lift(const Vec3& v) { return {T(v.x()), T(v.y()), T(v.z())}; }
template <class T> T norm(const V3<T>& a) { return sqrt(dot(a, a)); }

// Parallel transport of x along the rotation taking unit a to unit b.
template <class T>
V3<T> transport(const V3<T>& a, const V3<T>& b, const V3<T>& x) {
  const V3<T> c = cross(a, b);
  const T d = dot(a, b);
  return scale(d, x) + cross(c, x) + scale(dot(c, x) / (1.0 + d), c);
}

// Constant data of one bending–twisting stencil (vertex between edges i−1 and i).
struct Stencil {
  Vec3 t_old[2], u_old[2];
  Eigen::Matrix2d B[2];
  double twist_stiffness;  // mean μJ of the two edges
  double voronoi;          // l̄ = ē_{i−1} + ē_i
};

// q = (x_{i−1}, x_i, x_{i+1}, θ_{i−1}, θ_i).
template <class T>
T stencil_energy(const T* q, const Stencil& st) {
  const V3<T> x0{q[0], q[1], q[2]}, x1{q[3], q[4], q[5]}, x2{q[6], q[7], q[8]};
  V3<T> e[2] = {x1 - x0, x2 - x1};
  V3<T> t[2], m1[2], m2[2], u[2];
  for (int j = 0; j < 2; ++j) {
    t[j] = scale(1.0 / norm(e[j]), e[j]);
    u[j] = transport(lift<T>(st.t_old[j]), t[j], lift<T>(st.u_old[j]));
    const V3<T> v = cross(t[j], u[j]);
    const T c = cos(q[9 + j]), s = sin(q[9 + j]);
    m1[j] = scale(c, u[j]) + scale(s, v);
    m2[j] = scale(-s, u[j]) + scale(c, v);
  }
  const V3<T> kb = scale(2.0 / (1.0 + dot(t[0], t[1])), cross(t[0], t[1]));
  T E = T(0.0);
  for (int j = 0; j < 2; ++j) {
    const T w1 = dot(kb, m1[j]), w2 = dot(kb, m2[j]);
    const Eigen::Matrix2d& B = st.B[j];
    E = E + (0.5 / st.voronoi) * (B(0, 0) * w1 * w1 + 2 * B(0, 1) * w1 * w2 + B(1, 1) * w2 * w2);
  }
  const V3<T> pu = transport(t[0], t[1], u[0]);
  const T ref = atan2(dot(cross(pu, u[1]), t[1]), dot(pu, u[1]));
  const T m = q[10] - q[9] + ref;
  E = E + (st.twist_stiffness / st.voronoi) * m * m;
  return E;
}

template <class T>
T stretch_energy(const T* q, double k, double rest) {
  const V3<T> e{q[3] - q[0], q[4] - q[1], q[5] - q[2]};
  const T strain = norm(e) / rest - 1.0;
  return 0.5 * k * rest * strain * strain;
}

struct Rod {
  const DiscreteRodModel& m;
  int N;  // edges
  std::vector<Vec3> t_old, u_old;
  std::vector<double> node_mass;
  int dofs() const { return 3 * (N + 1) + N; }
  int theta_index(int j) const { return 3 * (N + 1) + j; }

  Stencil stencil(int i) const {
    Stencil st;
    for (int j = 0; j < 2; ++j) {
      st.t_old[j] = t_old[i - 1 + j];
      st.u_old[j] = u_old[i - 1 + j];
      st.B[j] = m.bending_stiffness[i - 1 + j];
    }
    st.twist_stiffness = 0.5 * (m.twisting_stiffness[i - 1] + m.twisting_stiffness[i]);
    st.voronoi = m.rest_length[i - 1] + m.rest_length[i];
    return st;
  }
  void gather(const Eigen::VectorXd& q, int i, double* out) const {
    for (int k = 0; k < 9; ++k) out[k] = q(3 * (i - 1) + k);
    out[9] = q(theta_index(i - 1));
    out[10] = q(theta_index(i));
  }
  int index(int i, int k) const { return k < 9 ? 3 * (i - 1) + k : theta_index(i - 1 + (k - 9)); }

  double energy(const Eigen::VectorXd& q) const {
    double E = 0;
    double loc[11];
    for (int i = 1; i < N; ++i) {
      gather(q, i, loc);
      E += stencil_energy<double>(loc, stencil(i));
    }
    for (int j = 0; j < N; ++j)
      E += stretch_energy<double>(q.data() + 3 * j, m.stretching_stiffness[j], m.rest_length[j]);
    for (int k = 0; k <= N; ++k) E -= node_mass[k] * m.gravity.dot(q.segment<3>(3 * k));
    for (const auto& f : m.nodal_forces) E -= f.second.dot(q.segment<3>(3 * f.first));
    return E;
  }

  // Gradient and Hessian triplets.
  double derivatives(const Eigen::VectorXd& q, Eigen::VectorXd& g,
                     std::vector<Eigen::Triplet<double>>* trip) const {
    g.setZero(dofs());
    double E = 0;
    double loc[11];
    for (int i = 1; i < N; ++i) {
      gather(q, i, loc);
      Jet<11> v[11];
      for (int k = 0; k < 11; ++k) v[k] = Jet<11>::variable(loc[k], k);
      const Jet<11> e = stencil_energy<Jet<11>>(v, stencil(i));
      E += e.v;
      for (int a = 0; a < 11; ++a) {
        g(index(i, a)) += e.g(a);
        if (trip)
          for (int b = 0; b < 11; ++b) trip->emplace_back(index(i, a), index(i, b), e.H(a, b));
      }
    }
    for (int j = 0; j < N; ++j) {
      Jet<6> v[6];
      for (int k = 0; k < 6; ++k) v[k] = Jet<6>::variable(q(3 * j + k), k);
      const Jet<6> e = stretch_energy<Jet<6>>(v, m.stretching_stiffness[j], m.rest_length[j]);
      E += e.v;
      for (int a = 0; a < 6; ++a) {
        g(3 * j + a) += e.g(a);
        if (trip)
          for (int b = 0; b < 6; ++b) trip->emplace_back(3 * j + a, 3 * j + b, e.H(a, b));
      }
    }
    for (int k = 0; k <= N; ++k) {
      E -= node_mass[k] * m.gravity.dot(q.segment<3>(3 * k));
      g.segment<3>(3 * k) -= node_mass[k] * m.gravity;
    }
    for (const auto& f : m.nodal_forces) {
      E -= f.second.dot(q.segment<3>(3 * f.first));
      g.segment<3>(3 * f.first) -= f.second;
    }
    return E;
  }

  void update_references(const Eigen::VectorXd& q) {
    for (int j = 0; j < N; ++j) {
      const Vec3 t = (q.segment<3>(3 * j + 3) - q.segment<3>(3 * j)).normalized();
      const V3<double> u = transport(lift<double>(t_old[j]), lift<double>(t), lift<double>(u_old[j]));
      Vec3 uu(u.x, u.y, u.z);
      uu = (uu - uu.dot(t) * t).normalized();
      t_old[j] = t;
      u_old[j] = uu;
    }
  }
};

Rod make_rod(const DiscreteRodModel& m) {
  const size_t N = m.material_normal.size();
  PARAFAB_VERIFY(m.nodes.size() >= 4 && m.nodes.size() == N + 1,
                 "discrete rod: need N+1 >= 4 nodes and N material normals, got "
                     << m.nodes.size() << " nodes and " << N << " normals");
  PARAFAB_VERIFY(m.bending_stiffness.size() == N && m.twisting_stiffness.size() == N &&
                     m.stretching_stiffness.size() == N && m.rest_length.size() == N &&
                     m.line_density.size() == N,
                 "discrete rod: per-edge arrays must have " << N << " entries");
  Rod r{m, int(N), {}, {}, {}};
  r.node_mass.assign(N + 1, 0.0);
  for (size_t j = 0; j < N; ++j) {
    const Vec3 e = m.nodes[j + 1] - m.nodes[j];
    if (!(e.norm() > 0)) PARAFAB_INPUT_ERROR("discrete rod: edge " << j << " has zero length");
    if (!(m.rest_length[j] > 0))
      PARAFAB_INPUT_ERROR("discrete rod: rest_length[" << j << "] must be > 0, got " << m.rest_length[j]);
    if (!(m.stretching_stiffness[j] > 0) || !(m.twisting_stiffness[j] > 0) ||
        !(m.bending_stiffness[j].determinant() > 0) || !(m.bending_stiffness[j](0, 0) > 0))
      PARAFAB_INPUT_ERROR("discrete rod: stiffness of edge " << j << " is not positive");
    const Vec3 t = e.normalized();
    Vec3 u = m.material_normal[j] - m.material_normal[j].dot(t) * t;
    if (!(u.norm() > 1e-6))
      PARAFAB_INPUT_ERROR("discrete rod: material_normal[" << j << "] is parallel to its edge");
    r.t_old.push_back(t);
    r.u_old.push_back(u.normalized());
    const double mass = m.line_density[j] * m.rest_length[j];
    r.node_mass[j] += 0.5 * mass;
    r.node_mass[j + 1] += 0.5 * mass;
  }
  for (const auto& f : m.nodal_forces)
    if (f.first < 0 || f.first > int(N))
      PARAFAB_INPUT_ERROR("discrete rod: nodal force at node " << f.first << " out of range");
  return r;
}

Eigen::VectorXd initial_dofs(const DiscreteRodModel& m) {
  const int N = int(m.material_normal.size());
  Eigen::VectorXd q = Eigen::VectorXd::Zero(3 * (N + 1) + N);
  for (int k = 0; k <= N; ++k) q.segment<3>(3 * k) = m.nodes[k];
  return q;
}

}  // namespace

double discrete_rod_energy(const DiscreteRodModel& model, const Eigen::VectorXd& dq,
                           Eigen::VectorXd* gradient, Eigen::MatrixXd* hessian) {
  Rod rod = make_rod(model);
  Eigen::VectorXd q = initial_dofs(model);
  PARAFAB_VERIFY(dq.size() == q.size(), "discrete_rod_energy: dq has " << dq.size()
                                                                       << " entries, expected " << q.size());
  q += dq;
  if (!gradient && !hessian) return rod.energy(q);
  Eigen::VectorXd g;
  std::vector<Eigen::Triplet<double>> trip;
  const double E = rod.derivatives(q, g, hessian ? &trip : nullptr);
  if (gradient) *gradient = g;
  if (hessian) {
    Eigen::SparseMatrix<double> H(q.size(), q.size());
    H.setFromTriplets(trip.begin(), trip.end());
    *hessian = Eigen::MatrixXd(H);
  }
  return E;
}

DiscreteRodResult simulate_discrete_rod(const DiscreteRodModel& model,
                                        const DiscreteRodOptions& options) {
  const auto t0 = std::chrono::steady_clock::now();
  Rod rod = make_rod(model);
  const int N = rod.N, n = rod.dofs();
  Eigen::VectorXd q = initial_dofs(model);
  // Free DOFs: nodes 2..N−2 and angles 1..N−2.
  std::vector<int> free_of(n, -1), dof_of;
  for (int k = 2; k <= N - 2; ++k)
    for (int c = 0; c < 3; ++c) free_of[3 * k + c] = int(dof_of.size()), dof_of.push_back(3 * k + c);
  for (int j = 1; j <= N - 2; ++j) free_of[rod.theta_index(j)] = int(dof_of.size()), dof_of.push_back(rod.theta_index(j));
  const int nf = int(dof_of.size());
  double L = 0, Bmax = 0, weight = 0, fsum = 0;
  for (int j = 0; j < N; ++j) {
    L += model.rest_length[j];
    Bmax = std::max(Bmax, model.bending_stiffness[j].norm());
    weight += model.line_density[j] * model.rest_length[j] * model.gravity.norm();
  }
  for (const auto& f : model.nodal_forces) fsum += f.second.norm();
  const double force_scale = Bmax / (L * L) + weight + fsum;

  DiscreteRodResult out;
  Eigen::VectorXd g, gf(nf), d(nf), step(n);
  std::vector<Eigen::Triplet<double>> trip, tf;
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> ldlt;
  double E = 0, shift = 0;
  for (int it = 0;; ++it) {
    trip.clear();
    E = rod.derivatives(q, g, &trip);
    for (int a = 0; a < nf; ++a) gf(a) = g(dof_of[a]);
    out.gradient_norm = nf ? gf.cwiseAbs().maxCoeff() / force_scale : 0.0;
    out.iterations = it;
    if (out.gradient_norm <= options.gradient_tolerance) {
      out.status = DiscreteRodStatus::Converged;
      break;
    }
    if (it >= options.max_iterations) {
      out.message = "Newton did not converge in " + std::to_string(it) + " iterations";
      break;
    }
    tf.clear();
    double maxdiag = 0;
    for (const auto& t : trip) {
      const int a = free_of[t.row()], b = free_of[t.col()];
      if (a >= 0 && b >= 0) {
        tf.emplace_back(a, b, t.value());
        if (a == b) maxdiag = std::max(maxdiag, std::abs(t.value()));
      }
    }
    Eigen::SparseMatrix<double> H(nf, nf);
    H.setFromTriplets(tf.begin(), tf.end());
    // Factor; shift the diagonal until positive definite (descent direction).
    shift = 0;
    bool shifted = false;
    for (int attempt = 0; attempt < 40; ++attempt) {
      Eigen::SparseMatrix<double> Hs = H;
      if (shift > 0) {
        for (int a = 0; a < nf; ++a) Hs.coeffRef(a, a) += shift;
      }
      ldlt.compute(Hs);
      if (ldlt.info() == Eigen::Success && ldlt.vectorD().minCoeff() > 0) break;
      shift = shift == 0 ? 1e-10 * maxdiag : shift * 10;
      shifted = true;
    }
    if (shifted) ++out.hessian_shifts;
    d = -ldlt.solve(gf);
    const double slope = gf.dot(d);
    if (!(slope < 0)) d = -gf;  // fallback: steepest descent
    step.setZero(n);
    for (int a = 0; a < nf; ++a) step(dof_of[a]) = d(a);
    // Round-off floor (stiff stretching): a full Newton step below 1e-13·L in every position
    // and 1e-13 rad in every angle, with a small gradient, is convergence.
    if (!shifted && out.gradient_norm <= 1e3 * options.gradient_tolerance &&
        step.head(3 * (N + 1)).cwiseAbs().maxCoeff() <= 1e-13 * L &&
        step.tail(N).cwiseAbs().maxCoeff() <= 1e-13) {
      out.status = DiscreteRodStatus::Converged;
      break;
    }
    // Backtracking (Armijo) line search on the total energy.
    double alpha = 1;
    bool accepted = false;
    for (int ls = 0; ls < 40; ++ls) {
      const Eigen::VectorXd qt = q + alpha * step;
      const double Et = rod.energy(qt);
      if (std::isfinite(Et) && Et <= E + 1e-4 * alpha * gf.dot(d) + 1e-14 * std::abs(E)) {
        q = qt;
        accepted = true;
        break;
      }
      alpha *= 0.5;
    }
    if (!accepted) {
      out.message = "line search failed at iteration " + std::to_string(it);
      break;
    }
    rod.update_references(q);
  }
  out.energy = E;
  out.nodes.resize(N + 1);
  for (int k = 0; k <= N; ++k) out.nodes[k] = q.segment<3>(3 * k);
  out.theta.resize(N);
  out.material_normal.resize(N);
  for (int j = 0; j < N; ++j) {
    const double th = q(rod.theta_index(j));
    const Vec3 v = rod.t_old[j].cross(rod.u_old[j]);
    out.theta[j] = th;
    out.material_normal[j] = std::cos(th) * rod.u_old[j] + std::sin(th) * v;
  }
  out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return out;
}

double max_node_distance(const std::vector<Vec3>& a, const std::vector<Vec3>& b) {
  PARAFAB_VERIFY(a.size() == b.size(), "max_node_distance: " << a.size() << " vs " << b.size()
                                                             << " nodes");
  double d = 0;
  for (size_t i = 0; i < a.size(); ++i) d = std::max(d, (a[i] - b[i]).norm());
  return d;
}

}  // namespace parafab
