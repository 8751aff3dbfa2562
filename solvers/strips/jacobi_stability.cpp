// Thesis §4.5.2 (Eq. 4.7, isoperimetric stability matrix Z), §4.6.1 (discretization),
// Appendix A.3 (adjoint for δσ/δK). See jacobi_stability.h.
#include "strips/jacobi_stability.h"

#include <Eigen/Dense>
#include <Eigen/SparseLU>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <sstream>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "common/error.h"
#include "strips/plane_rod_discretization.h"
#include "strips/strip_validation.h"

namespace parafab {

namespace {

using Clock = std::chrono::steady_clock;
double since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

using plane_rod::interpolate;

double unwrap_near(double angle, double reference) {
  return angle + 2 * M_PI * std::round((reference - angle) / (2 * M_PI));
}

// The discrete second variation of §4.6.1 as a three-term recurrence: row j of the Hessian
// in the edge angles reads e_{j−1} u_{j−1} + d_j u_j + e_j u_{j+1}, with e_{N−1} the coupling
// to the clamp angle (or −1 for the natural end condition of a free end angle).
struct Jacobi {
  int N = 0, p = 0;
  double h = 0;
  bool act0 = true, actN = true;
  std::vector<double> w, c, d, e;  // nodal Voronoi weights, P_k / w_k, diagonal, coupling
  std::vector<Vec2> t, tp;         // tangent, rotated tangent of each edge
  bool constrained[2] = {true, true}, ref_start[2] = {true, true};
  std::vector<double> Q[2];        // weight carried by the positions that move with edge j
  std::vector<Vec2> mu;            // λ − e∘Q_j
  Eigen::Matrix2d V = Eigen::Matrix2d::Identity();  // constraint basis (columns)
  bool rotated = false;
  std::vector<std::vector<double>> T;  // p constraint tangents per edge
  bool legendre = true;
  // Solutions u^c (c = 0: ζ, c = i: ξ_i = η_i − ζ) at edges −1..N (index + 1) and the running sums
  // Mcum[c][i][m] = Σ_{j<m} h T_i[j] u^c_j.
  std::vector<std::vector<double>> u;
  std::vector<std::vector<std::vector<double>>> Mcum;
};

Jacobi assemble(const DiscreteRodState& s) {
  Jacobi J;
  const int N = s.edges();
  PARAFAB_VERIFY(N >= 4, "stability: at least 4 edges needed, got " << N);
  PARAFAB_VERIFY(std::isfinite(s.length) && s.length > 0, "stability: length must be positive, got " << s.length);
  PARAFAB_VERIFY(static_cast<int>(s.stiffness.size()) == N + 1,
                 "stability: " << s.stiffness.size() << " nodal stiffnesses for " << N << " edges (need N + 1)");
  for (int k = 0; k <= N; ++k)
    PARAFAB_VERIFY(std::isfinite(s.stiffness[k]) && s.stiffness[k] > 0,
                   "stability: stiffness[" << k << "] must be positive, got " << s.stiffness[k]);
  J.N = N;
  J.h = s.length / N;
  const double h = J.h;
  J.w.assign(N + 1, h);
  J.w[0] = J.w[N] = 0.5 * h;
  J.act0 = !s.boundary.start.free_angle;
  J.actN = !s.boundary.end.free_angle;
  auto angle = [&](int j) { return j < 0 ? s.start_angle : (j >= N ? s.end_angle : s.angles[j]); };
  J.c.assign(N + 1, 0.0);
  for (int k = 0; k <= N; ++k) {
    if ((k == 0 && !J.act0) || (k == N && !J.actN)) continue;
    const double kap = (angle(k) - angle(k - 1)) / J.w[k] - s.natural_curvature;
    const double P = s.stiffness[k] * s.law.slope(kap);
    if (!(P > 0)) J.legendre = false;
    J.c[k] = P / J.w[k];
  }
  J.t.resize(N);
  J.tp.resize(N);
  for (int j = 0; j < N; ++j) {
    J.t[j] = Vec2(std::cos(s.angles[j]), std::sin(s.angles[j]));
    J.tp[j] = Vec2(-J.t[j].y(), J.t[j].x());
  }
  PARAFAB_VERIFY(s.weight_ratio.empty() || static_cast<int>(s.weight_ratio.size()) == N + 1,
                 "stability: " << s.weight_ratio.size() << " weight ratios for " << N << " edges (need N + 1)");
  std::vector<double> weight = s.stiffness;  // weight per length / |e|
  for (size_t k = 0; k < s.weight_ratio.size(); ++k) weight[k] *= s.weight_ratio[k];
  const plane_rod::EndReferences ends = plane_rod::end_references(s.boundary, weight, J.w, N);
  for (int d = 0; d < 2; ++d) J.constrained[d] = ends.constrained[d], J.ref_start[d] = ends.ref_start[d], J.Q[d] = ends.Q[d];
  J.mu.resize(N);
  J.d.resize(N);
  J.e.resize(N);
  for (int j = 0; j < N; ++j) {
    Vec2 mu;
    for (int dd = 0; dd < 2; ++dd)
      mu(dd) = (J.constrained[dd] ? s.multiplier(dd) : 0.0) - s.load(dd) * J.Q[dd][j];
    J.mu[j] = mu;
    J.d[j] = J.c[j] + J.c[j + 1] - h * mu.dot(J.t[j]);
    J.e[j] = -J.c[j + 1];
  }
  if (!J.actN) J.e[N - 1] = -1.0;  // natural end: the residual of row N − 1 plays u_N
  // Constraint tangents T_d = (−sin α, cos α) of the held coordinates; if the two are
  // (nearly) dependent, e.g. on a straight rod, keep their dominant combination only.
  std::vector<int> dims;
  for (int dd = 0; dd < 2; ++dd)
    if (J.constrained[dd]) dims.push_back(dd);
  if (dims.size() == 2) {
    Eigen::Matrix2d G = Eigen::Matrix2d::Zero();
    for (int j = 0; j < N; ++j) G += J.tp[j] * J.tp[j].transpose();
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> es(G);
    if (es.eigenvalues()(0) <= 1e-10 * es.eigenvalues()(1)) {
      J.rotated = true;
      J.V = es.eigenvectors();
      J.p = 1;
      J.T.assign(1, std::vector<double>(N));
      for (int j = 0; j < N; ++j) J.T[0][j] = J.tp[j].dot(J.V.col(1));
    } else {
      J.p = 2;
      J.T.assign(2, std::vector<double>(N));
      for (int j = 0; j < N; ++j) J.T[0][j] = J.tp[j](0), J.T[1][j] = J.tp[j](1);
    }
  } else {
    J.p = static_cast<int>(dims.size());
    J.T.assign(J.p, std::vector<double>(N));
    for (int i = 0; i < J.p; ++i)
      for (int j = 0; j < N; ++j) J.T[i][j] = J.tp[j](dims[i]);
  }
  return J;
}

void integrate(Jacobi& J) {
  const int N = J.N, p = J.p;
  const double h = J.h;
  J.u.assign(p + 1, std::vector<double>(N + 2, 0.0));
  J.Mcum.assign(p + 1, std::vector<std::vector<double>>(p, std::vector<double>(N + 1, 0.0)));
  const double u0 = J.act0 ? J.w[0] : 1.0;  // ζ(0) = 0, ζ′(0) = 1 / free: ζ(0) = 1, ζ′(0) = 0
  for (int col = 0; col <= p; ++col) {
    std::vector<double>& u = J.u[col];  // u[j + 1] = u_j
    // Columns ζ and ξ_i = η_i − ζ (ξ_i(0) = ξ_i′(0) = 0): det(ζ, ξ) = det(ζ, η) of the
    // thesis, without the cancellation of nearly parallel columns ζ and η_i.
    u[0] = 0.0;
    u[1] = col == 0 ? u0 : 0.0;
    for (int j = 0; j < N; ++j) {
      const double rhs = col == 0 ? 0.0 : h * J.T[col - 1][j];
      const double prev = j == 0 ? 0.0 : J.e[j - 1] * u[j];
      u[j + 2] = (rhs - prev - J.d[j] * u[j + 1]) / J.e[j];
    }
    for (int i = 0; i < p; ++i) {
      double acc = 0;
      J.Mcum[col][i][0] = 0;
      for (int m = 1; m <= N; ++m) acc += h * J.T[i][m - 1] * u[m], J.Mcum[col][i][m] = acc;
    }
  }
}

// The (p+1)² matrix Z at node m (columns ζ, η_1.., rows value, M_1..).
Eigen::Matrix3d zmatrix(const Jacobi& J, int m) {
  Eigen::Matrix3d A = Eigen::Matrix3d::Identity();
  for (int col = 0; col <= J.p; ++col) {
    A(0, col) = J.u[col][m + 1];
    for (int i = 0; i < J.p; ++i) A(i + 1, col) = J.Mcum[col][i][m];
  }
  return A;
}

// Sign of det Z on the stable side: short pieces are stable (Legendre), and det Z > 0 there
// for p = 0, 1, 2 (checked by the tests against the Hessian inertia and the Euler columns).
double stable_sign(int) { return 1.0; }

double s_length(const Jacobi& J) { return J.N * J.h; }

// Arc length of Z_m: the truncated problem clamps the angle of edge m, whose value sits at the
// edge's centre (m + ½)h (the boundary angles sit at the end nodes, the fictitious edges of
// §4.6.1 have zero length), so s_m = (m + ½)h for m < N and s_N = l.
double node_s(const Jacobi& J, int m) { return m >= J.N ? J.N * J.h : (m + 0.5) * J.h; }

struct Scan {
  std::vector<double> Z, r;  // raw (signed to be > 0 when stable) and normalized, m = 0..N
  int m = -1;                // first node with r < −tol (m ≥ p + 1)
};

Scan scan(const Jacobi& J, double tol) {
  Scan sc;
  const int N = J.N;
  sc.Z.assign(N + 1, 0.0);
  sc.r.assign(N + 1, 0.0);
  const double sg = stable_sign(J.p);
  for (int m = 1; m <= N; ++m) {
    const Eigen::Matrix3d A = zmatrix(J, m);
    const double det = sg * A.determinant();
    double scale = 1;
    for (int col = 0; col <= J.p; ++col) scale *= A.col(col).head(J.p + 1).norm();
    sc.Z[m] = det;
    sc.r[m] = scale > 0 ? det / scale : 0.0;
    if (sc.m < 0 && m >= J.p + 1 && sc.r[m] < -tol) sc.m = m;
  }
  return sc;
}

}  // namespace

JacobiResult jacobi_stability(const DiscreteRodState& state, const JacobiOptions& o) {
  const auto t0 = Clock::now();
  Jacobi J = assemble(state);
  integrate(J);
  const Scan sc = scan(J, o.degenerate_tolerance);
  JacobiResult out;
  out.constraints = J.p;
  out.legendre = J.legendre;
  const int N = J.N;
  out.Z_end = sc.r[N];
  out.min_Z = *std::min_element(sc.r.begin() + 1, sc.r.end());
  out.Z_raw.assign(sc.Z.begin(), sc.Z.end());
  if (sc.m > 0) {
    const int m = sc.m;
    const double z0 = sc.Z[m - 1], z1 = sc.Z[m];
    out.conjugate_index = m;
    const double s0 = node_s(J, m - 1), s1 = node_s(J, m);
    out.sigma = s0 + (z0 - z1 != 0 ? (s1 - s0) * z0 / (z0 - z1) : 0.0);
    out.sigma = std::clamp(out.sigma, s0, s1);
    // A free end angle: the last determinant is that of the natural end condition, so a sign
    // change there alone means instability of the whole strip, σ = l.
    if (!J.actN && m == N) out.sigma = N * J.h;
  }
  out.stable = sc.m < 0 && J.legendre;
  if (!J.legendre) out.message = "the Legendre condition fails: P = K m'(kappa) <= 0 at some node";
  if (J.rotated)
    out.message += std::string(out.message.empty() ? "" : "; ") +
                   "the two end-point constraint tangents are dependent (straight rod): one constraint kept";
  bool nondegenerate = false;
  for (int m = J.p + 1; m <= N; ++m) nondegenerate |= std::abs(sc.r[m]) > o.degenerate_tolerance;
  if (!nondegenerate) {
    out.stable = false;
    out.message += std::string(out.message.empty() ? "" : "; ") +
                   "Z vanishes identically (degenerate constraints): no verdict";
  }
  if (o.max_samples > 0) {
    const int stride = std::max(1, (N + o.max_samples - 1) / o.max_samples);
    out.s.push_back(0.0), out.Z.push_back(0.0);
    for (int m = stride; m < N; m += stride) out.s.push_back(node_s(J, m)), out.Z.push_back(sc.r[m]);
    out.s.push_back(N * J.h), out.Z.push_back(sc.r[N]);
  }
  out.seconds = since(t0);
  return out;
}

ConjugatePointSensitivity conjugate_point_sensitivity(const DiscreteRodState& state, bool equilibrium,
                                                      const JacobiOptions& o) {
  const auto t0 = Clock::now();
  PARAFAB_VERIFY(state.law.linear(),
                 "conjugate_point_sensitivity: only the linear moment law is supported (m'' is not modelled)");
  PARAFAB_VERIFY(state.weight_ratio.empty() || state.load.norm() == 0,
                 "conjugate_point_sensitivity: a weight that does not follow K (weight_ratio, composite strips "
                 "under gravity) is not modelled");
  Jacobi J = assemble(state);
  integrate(J);
  const Scan sc = scan(J, o.degenerate_tolerance);
  ConjugatePointSensitivity out;
  const int N = J.N, p = J.p;
  const double h = J.h;
  out.dsigma_dK_partial.assign(N + 1, 0.0);
  out.dsigma_dangles.assign(N, 0.0);
  if (sc.m < 0) {
    out.message = "stable: no conjugate point in (0, l]";
    out.seconds = since(t0);
    return out;
  }
  PARAFAB_VERIFY(!J.rotated, "conjugate_point_sensitivity: the constraint tangents are dependent (straight rod)");
  const int m = sc.m;
  if (!J.actN && m == N) {  // σ = l from the natural end condition: locally constant
    out.defined = true;
    out.sigma = s_length(J);
    out.message = "sigma = l (the natural end condition of the free end angle fails): zero derivative";
    out.dsigma_dK.assign(N + 1, 0.0);
    out.seconds = since(t0);
    return out;
  }
  const double z0 = sc.Z[m - 1], z1 = sc.Z[m], dz = z0 - z1;
  out.defined = true;
  const double s0 = node_s(J, m - 1), ds = node_s(J, m) - s0;
  out.sigma = s0 + ds * z0 / dz;
  const double sg = stable_sign(p);
  // ∂σ/∂Z at the two bracketing nodes.
  const double g[2] = {-ds * z1 / (dz * dz), ds * z0 / (dz * dz)};
  std::vector<std::vector<double>> ub(p + 1, std::vector<double>(N + 2, 0.0));
  std::vector<std::vector<double>> Tb(p, std::vector<double>(N, 0.0));
  for (int q = 0; q < 2; ++q) {
    const int mm = m - 1 + q;
    if (mm < 1) continue;
    const Eigen::Matrix3d A = zmatrix(J, mm);
    // Cofactors of the top-left (p+1) block: det · A^{-T}.
    const Eigen::Matrix3d cof = A.determinant() * A.inverse().transpose();
    const double gg = g[q] * sg;
    for (int col = 0; col <= p; ++col) {
      ub[col][mm + 1] += gg * cof(0, col);
      for (int i = 0; i < p; ++i) {
        const double G = gg * cof(i + 1, col);
        for (int j = 0; j < mm; ++j) {
          ub[col][j + 1] += G * h * J.T[i][j];
          Tb[i][j] += G * h * J.u[col][j + 1];
        }
      }
    }
  }
  // Reverse sweep of the recurrence u_{j+1} = (rhs_j − e_{j−1} u_{j−1} − d_j u_j) / e_j.
  std::vector<double> db(N, 0.0), eb(N, 0.0);
  for (int col = 0; col <= p; ++col) {
    std::vector<double>& b = ub[col];
    const std::vector<double>& u = J.u[col];
    for (int j = m - 1; j >= 0; --j) {
      const double gj = b[j + 2];
      if (gj == 0) continue;
      const double inv = 1.0 / J.e[j];
      if (j > 0) {
        b[j] -= gj * J.e[j - 1] * inv;
        eb[j - 1] -= gj * u[j] * inv;
      }
      b[j + 1] -= gj * J.d[j] * inv;
      db[j] -= gj * u[j + 1] * inv;
      eb[j] -= gj * u[j + 2] * inv;
      if (col > 0) Tb[col - 1][j] += gj * inv * h;
    }
  }
  // d, e, T → c, μ, α → K, λ, α.
  std::vector<double> cb(N + 1, 0.0);
  std::vector<Vec2> mub(N, Vec2::Zero());
  for (int j = 0; j < N; ++j) {
    if (j < N - 1 || J.actN) cb[j + 1] -= eb[j];
    cb[j] += db[j];
    cb[j + 1] += db[j];
    out.dsigma_dangles[j] += -h * J.mu[j].dot(J.tp[j]) * db[j];
    mub[j] = -h * J.t[j] * db[j];
  }
  for (int k = 0; k <= N; ++k) {
    if ((k == 0 && !J.act0) || (k == N && !J.actN)) continue;
    out.dsigma_dK_partial[k] += cb[k] / J.w[k];
  }
  for (int dd = 0; dd < 2; ++dd) {
    if (J.constrained[dd])
      for (int j = 0; j < N; ++j) out.dsigma_dmultiplier(dd) += mub[j](dd);
    if (state.load(dd) == 0) continue;
    // Q̄ = −e μ̄; Q_j = Σ_{k>j} K_k w_k (or −Σ_{k≤j}).
    if (J.ref_start[dd]) {
      double acc = 0;
      for (int k = 1; k <= N; ++k) acc += -state.load(dd) * mub[k - 1](dd), out.dsigma_dK_partial[k] += J.w[k] * acc;
    } else {
      double acc = 0;
      for (int k = N - 1; k >= 0; --k) acc += -state.load(dd) * mub[k](dd), out.dsigma_dK_partial[k] -= J.w[k] * acc;
    }
  }
  for (int i = 0; i < p; ++i) {
    const int dd = J.constrained[0] && J.constrained[1] ? i : (J.constrained[0] ? 0 : 1);
    for (int j = 0; j < N; ++j) out.dsigma_dangles[j] += -J.t[j](dd) * Tb[i][j];
  }
  if (!equilibrium) {
    out.seconds = since(t0);
    return out;
  }
  // Total derivative through the equilibrium F(α, λ; K) = 0: J_kkt y = ∂σ/∂(α, λ), then
  // dσ/dK = ∂σ/∂K − yᵀ ∂F/∂K (the ᾱ, λ̄ problem of A.3 is this KKT solve).
  std::vector<int> cidx(2, -1);
  int nc = 0;
  for (int dd = 0; dd < 2; ++dd)
    if (J.constrained[dd]) cidx[dd] = nc++;
  std::vector<Eigen::Triplet<double>> tr;
  for (int j = 0; j < N; ++j) {
    tr.emplace_back(j, j, J.d[j]);
    if (j + 1 < N) tr.emplace_back(j, j + 1, J.e[j]), tr.emplace_back(j + 1, j, J.e[j]);
    for (int dd = 0; dd < 2; ++dd)
      if (cidx[dd] >= 0) tr.emplace_back(j, N + cidx[dd], h * J.tp[j](dd)), tr.emplace_back(N + cidx[dd], j, h * J.tp[j](dd));
  }
  Eigen::SparseMatrix<double> K(N + nc, N + nc);
  K.setFromTriplets(tr.begin(), tr.end());
  K.makeCompressed();
  Eigen::SparseLU<Eigen::SparseMatrix<double>> lu(K);
  PARAFAB_VERIFY(lu.info() == Eigen::Success, "conjugate_point_sensitivity: singular KKT matrix");
  Eigen::VectorXd rhs(N + nc);
  for (int j = 0; j < N; ++j) rhs(j) = out.dsigma_dangles[j];
  for (int dd = 0; dd < 2; ++dd)
    if (cidx[dd] >= 0) rhs(N + cidx[dd]) = out.dsigma_dmultiplier(dd);
  const Eigen::VectorXd y = lu.solve(rhs);
  auto angle = [&](int j) { return j < 0 ? state.start_angle : (j >= N ? state.end_angle : state.angles[j]); };
  out.dsigma_dK = out.dsigma_dK_partial;
  for (int k = 0; k <= N; ++k) {
    if ((k == 0 && !J.act0) || (k == N && !J.actN)) continue;
    const double kap = (angle(k) - angle(k - 1)) / J.w[k] - state.natural_curvature;
    out.dsigma_dK[k] -= kap * ((k < N ? y(k) : 0.0) - (k >= 1 ? y(k - 1) : 0.0));
  }
  for (int dd = 0; dd < 2; ++dd) {
    if (state.load(dd) == 0) continue;
    if (J.ref_start[dd]) {
      double acc = 0;
      for (int k = 1; k <= N; ++k) acc += y(k - 1) * h * J.tp[k - 1](dd) * state.load(dd), out.dsigma_dK[k] += J.w[k] * acc;
    } else {
      double acc = 0;
      for (int k = N - 1; k >= 0; --k) acc += y(k) * h * J.tp[k](dd) * state.load(dd), out.dsigma_dK[k] -= J.w[k] * acc;
    }
  }
  // Residual of the state as an equilibrium (scaled like the simulator).
  double kmax = *std::max_element(state.stiffness.begin(), state.stiffness.end());
  double res = 0;
  std::vector<double> F(N, 0.0);
  for (int k = 0; k <= N; ++k) {
    if ((k == 0 && !J.act0) || (k == N && !J.actN)) continue;
    const double mk = state.stiffness[k] * ((angle(k) - angle(k - 1)) / J.w[k] - state.natural_curvature);
    if (k < N) F[k] += mk;
    if (k >= 1) F[k - 1] -= mk;
  }
  for (int j = 0; j < N; ++j) {
    for (int dd = 0; dd < 2; ++dd) {
      F[j] -= h * J.tp[j](dd) * state.load(dd) * J.Q[dd][j];
      if (J.constrained[dd]) F[j] += h * state.multiplier(dd) * J.tp[j](dd);
    }
    res = std::max(res, std::abs(F[j]) * state.length / kmax);
  }
  out.equilibrium_residual = res;
  out.seconds = since(t0);
  return out;
}

ConstrainedInertia constrained_inertia(const Eigen::SparseMatrix<double>& kkt, int n, double zero_tolerance) {
  const auto t0 = Clock::now();
  PARAFAB_VERIFY(kkt.rows() == kkt.cols() && kkt.rows() >= n && n > 0,
                 "constrained_inertia: a square KKT matrix with at least " << n << " rows is needed, got "
                                                                          << kkt.rows() << " x " << kkt.cols());
  const int nc = static_cast<int>(kkt.rows()) - n;
  const Eigen::MatrixXd full(kkt);
  const Eigen::MatrixXd H = full.topLeftCorner(n, n);
  ConstrainedInertia out;
  Eigen::MatrixXd Hr;
  if (nc > 0) {
    const Eigen::MatrixXd Ct = full.bottomLeftCorner(nc, n).transpose();
    Eigen::HouseholderQR<Eigen::MatrixXd> qr(Ct);
    const Eigen::MatrixXd R = qr.matrixQR().topRows(nc).triangularView<Eigen::Upper>();
    double rmax = 0;
    for (int i = 0; i < nc; ++i) rmax = std::max(rmax, std::abs(R(i, i)));
    int rank = 0;
    for (int i = 0; i < nc; ++i) rank += std::abs(R(i, i)) > 1e-10 * rmax;
    out.constraint_rank = rank;
    Eigen::MatrixXd A = qr.householderQ().adjoint() * H;
    A = A * qr.householderQ();
    // Columns of Q beyond the rank span the null space of C (rank deficiency: the dependent
    // column is kept out too, as R(i, i) = 0 for the last ones after Householder).
    Hr = A.bottomRightCorner(n - rank, n - rank);
  } else {
    Hr = H;
  }
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(Hr, Eigen::EigenvaluesOnly);
  const Eigen::VectorXd ev = es.eigenvalues();
  const double scale = ev.cwiseAbs().maxCoeff();
  for (int i = 0; i < ev.size(); ++i) {
    if (std::abs(ev(i)) <= zero_tolerance * scale) ++out.zero;
    else if (ev(i) < 0) ++out.negative;
    else ++out.positive;
  }
  out.min_eigenvalue = ev.size() ? ev(0) : NAN;
  out.max_eigenvalue = ev.size() ? ev(ev.size() - 1) : NAN;
  out.stable = out.negative == 0 && out.zero == 0;
  out.seconds = since(t0);
  return out;
}

DiscreteRodState rod_state(const PlaneRodProblem& p, const PlaneRodResult& r) {
  DiscreteRodState s;
  const int N = static_cast<int>(r.edge_angles.size());
  s.length = p.length;
  s.angles = r.edge_angles;
  s.stiffness.resize(N + 1);
  for (int k = 0; k <= N; ++k) s.stiffness[k] = interpolate(p.stiffness_s, p.stiffness, p.length * k / N);
  s.start_angle = p.start_angle;
  s.end_angle = p.end_angle;
  s.multiplier = r.multiplier;
  s.boundary = p.boundary;
  s.load = p.load;
  if (!p.weight_ratio.empty()) {
    s.weight_ratio.resize(N + 1);
    for (int k = 0; k <= N; ++k) s.weight_ratio[k] = interpolate(p.stiffness_s, p.weight_ratio, p.length * k / N);
  }
  s.law = p.law;
  s.natural_curvature = p.natural_curvature;
  return s;
}

DiscreteRodState rod_state(const BSplineCurve2& bspline, const StripDesign& design,
                           const StripDesignOptions& o, int N) {
  PARAFAB_VERIFY(design.feasible && !design.samples.empty(),
                 "stability: the design is not feasible (" << design.reason << ")");
  PARAFAB_VERIFY(N >= 4, "stability.edges must be >= 4, got " << N);
  // Nodes equally spaced in arc length without inverting the arc length per node: a fine
  // polyline in the parameter (8 points per edge), its cumulative chord length rescaled to
  // the design's length, and linear interpolation (position error ~ κ (l / 8N)² / 8).
  const int M = 8 * N;
  const double u0 = bspline.first_parameter(), u1 = bspline.last_parameter();
  std::vector<Vec2> fine(M + 1);
  std::vector<double> cum(M + 1, 0.0);
  tbb::parallel_for(tbb::blocked_range<int>(0, M + 1, 1024), [&](const tbb::blocked_range<int>& r) {
    for (int i = r.begin(); i != r.end(); ++i) fine[i] = bspline.point(u0 + (u1 - u0) * i / M);
  });
  for (int i = 1; i <= M; ++i) cum[i] = cum[i - 1] + (fine[i] - fine[i - 1]).norm();
  const double l = design.length > 0 ? design.length : cum[M];
  for (double& c : cum) c *= l / cum[M];
  DiscreteRodState s;
  s.length = l;
  std::vector<double> ks, kv;
  for (const auto& q : design.samples) ks.push_back(q.s), kv.push_back(q.K);
  s.stiffness.resize(N + 1);
  std::vector<Vec2> pts(N + 1);
  size_t i = 0;
  for (int k = 0; k <= N; ++k) {
    const double sk = l * k / N;
    s.stiffness[k] = interpolate(ks, kv, sk);
    while (i + 1 < static_cast<size_t>(M) && cum[i + 1] < sk) ++i;
    const double t = std::clamp((sk - cum[i]) / std::max(cum[i + 1] - cum[i], 1e-300), 0.0, 1.0);
    pts[k] = fine[i] + t * (fine[i + 1] - fine[i]);
  }
  const std::array<Vec2, 4> da = bspline.derivatives(u0), db = bspline.derivatives(u1);
  double prev = std::atan2(da[1].y(), da[1].x());
  s.start_angle = prev;
  s.angles.resize(N);
  for (int j = 0; j < N; ++j) {
    const Vec2 d = pts[j + 1] - pts[j];
    s.angles[j] = prev = unwrap_near(std::atan2(d.y(), d.x()), prev);
  }
  s.end_angle = unwrap_near(std::atan2(db[1].y(), db[1].x()), prev);
  // λ: Eq. 4.4 designs satisfy K κ = a + ⟨b, γ⟩, so (Kκ)′ = ⟨b, γ′⟩ = ⟨λ, Rγ′⟩ and λ = R b;
  // the gravity LP reports the internal force n(l) = −λ.
  s.multiplier = design.general_lp ? Vec2(-design.end_force) : Vec2(-design.b.y(), design.b.x());
  s.boundary = o.boundary;
  s.load = o.gravity.load();
  if (!design.weight_ratio.empty()) {  // composite under gravity: the LP's weight of both layers
    s.weight_ratio.resize(N + 1);
    for (int k = 0; k <= N; ++k) s.weight_ratio[k] = interpolate(ks, design.weight_ratio, l * k / N);
  }
  s.law = o.law;
  // Ideal plasticity (H = 0, App. A.5): the bent strip is the elastic one with the permanent
  // set as natural curvature (what validate_strip simulates), so the second variation is that
  // of the linear law, P = K (P = K m′(κ) = 0 beyond the limit would fail Legendre). A
  // hardening law (H > 0) keeps P = K m′(κ), as the simulator keeps that law.
  if (std::isfinite(s.law.curvature_limit) && s.law.plastic_hardening == 0) s.law.curvature_limit = INFINITY;
  s.natural_curvature = o.natural_curvature;
  return s;
}

StripStability strip_stability(const BSplineCurve2& curve, const StripDesign& design,
                               const StripDesignOptions& o, const StripStabilityOptions& so) {
  StripStability out;
  auto t0 = Clock::now();
  const DiscreteRodState state = rod_state(curve, design, o, so.edges);
  out.jacobi = jacobi_stability(state, so.jacobi);
  out.jacobi_seconds = since(t0);
  out.stable = out.jacobi.stable;
  out.sigma = out.jacobi.sigma;
  out.message = out.jacobi.message;
  if (!so.eigenvalue_check) return out;
  out.checked = true;
  StripValidationOptions vo;
  vo.rod = so.simulation;
  vo.rod.hessian = true;
  t0 = Clock::now();
  const StripValidation v = validate_strip(curve, design, o, vo);
  out.simulation_seconds = since(t0);
  out.simulation_converged = v.converged;
  if (!v.converged) {
    out.message += std::string(out.message.empty() ? "" : "; ") +
                   "the simulation did not converge (" + v.message + "): no eigenvalue check";
    return out;
  }
  const PlaneRodResult& r = v.simulation;
  const int N = static_cast<int>(r.edge_angles.size());
  out.inertia = constrained_inertia(r.kkt, N);
  out.eigen_seconds = out.inertia.seconds;
  // The Jacobi test on exactly the simulated equilibrium.
  DiscreteRodState ss = state;
  std::vector<double> ks, kv;
  for (const auto& q : design.samples) ks.push_back(q.s), kv.push_back(q.K);
  ss.angles = r.edge_angles;
  ss.stiffness.resize(N + 1);
  for (int k = 0; k <= N; ++k) ss.stiffness[k] = interpolate(ks, kv, r.node_s[k]);
  if (!design.weight_ratio.empty()) {
    ss.weight_ratio.resize(N + 1);
    for (int k = 0; k <= N; ++k) ss.weight_ratio[k] = interpolate(ks, design.weight_ratio, r.node_s[k]);
  }
  ss.start_angle = unwrap_near(state.start_angle, r.edge_angles.front());
  ss.end_angle = unwrap_near(state.end_angle, r.edge_angles.back());
  ss.multiplier = r.multiplier;
  out.jacobi_on_simulation = jacobi_stability(ss, so.jacobi);
  out.agree = out.inertia.stable == out.jacobi.stable;
  return out;
}

}  // namespace parafab
