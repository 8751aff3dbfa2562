#include "xfem/linear_xfem.h"
#include "xfem/reduced_assembly.h"

#include <Eigen/Dense>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <atomic>
#include <chrono>
#include <cstdint>
#include <cstring>
#include <limits>
#include <map>
#include <numeric>
#include <string>
#include <unordered_map>

#include "common/bit_hash.h"
#include "common/error.h"
#include "xfem/area_rules.h"

namespace parafab::xfem {

namespace {

using Mat24 = Eigen::Matrix<double, 24, 24>;
using Mat6x24 = Eigen::Matrix<double, 6, 24>;

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

// Strain–displacement matrix, Voigt order (xx, yy, zz, xy, yz, xz) with engineering shears.
template <int NN>
Eigen::Matrix<double, 6, 3 * NN> strain_matrix(const Eigen::Matrix<double, NN, 3>& G) {
  Eigen::Matrix<double, 6, 3 * NN> B = Eigen::Matrix<double, 6, 3 * NN>::Zero();
  for (int k = 0; k < NN; ++k) {
    const int c = 3 * k;
    B(0, c) = G(k, 0);
    B(1, c + 1) = G(k, 1);
    B(2, c + 2) = G(k, 2);
    B(3, c) = G(k, 1), B(3, c + 1) = G(k, 0);
    B(4, c + 1) = G(k, 2), B(4, c + 2) = G(k, 1);
    B(5, c) = G(k, 2), B(5, c + 2) = G(k, 0);
  }
  return B;
}

template <int NN>
Eigen::Matrix<double, 3, 3 * NN> value_matrix(const Eigen::Matrix<double, NN, 1>& N) {
  Eigen::Matrix<double, 3, 3 * NN> M = Eigen::Matrix<double, 3, 3 * NN>::Zero();
  for (int k = 0; k < NN; ++k)
    for (int d = 0; d < 3; ++d) M(d, 3 * k + d) = N(k);
  return M;
}

template <int NN>
void shape(const Box3& box, const Vec3& X, Eigen::Matrix<double, NN, 1>& N, Eigen::Matrix<double, NN, 3>& G) {
  if constexpr (NN == 8) trilinear_shape(box, X, N, G);
  else triquadratic_shape(box, X, N, G);
}

// Shape functions of an element with `nodes` nodes (8 or 27), dynamic size.
void shape_dynamic(const Box3& box, int nodes, const Vec3& X, Eigen::VectorXd& N, Eigen::MatrixXd& G) {
  if (nodes == 27) {
    Eigen::Matrix<double, 27, 1> n;
    Eigen::Matrix<double, 27, 3> g;
    triquadratic_shape(box, X, n, g);
    N = n, G = g;
  } else {
    PARAFAB_VERIFY(nodes == 8, "element with " << nodes << " nodes (8 or 27 expected)");
    Eigen::Matrix<double, 8, 1> n;
    Eigen::Matrix<double, 8, 3> g;
    trilinear_shape(box, X, n, g);
    N = n, G = g;
  }
}

// Lamé constants of an isotropic material.
struct Lame {
  double lambda, mu;
};
Lame lame(const ElasticMaterial& m) {
  const double E = m.youngs_modulus, nu = m.poisson_ratio;
  return {E * nu / ((1 + nu) * (1 - 2 * nu)), E / (2 * (1 + nu))};
}

Eigen::Matrix<double, 6, 6> elasticity(const ElasticMaterial& m) {
  const auto [lambda, mu] = lame(m);
  Eigen::Matrix<double, 6, 6> D = Eigen::Matrix<double, 6, 6>::Zero();
  D.topLeftCorner<3, 3>().setConstant(lambda);
  D.topLeftCorner<3, 3>().diagonal().array() += 2 * mu;
  D.bottomRightCorner<3, 3>().diagonal().setConstant(mu);
  return D;
}

// Traction operator: t = P(n) σ_voigt.
Eigen::Matrix<double, 3, 6> traction_operator(const Vec3& n) {
  Eigen::Matrix<double, 3, 6> P;
  P << n.x(), 0, 0, n.y(), 0, n.z(),
       0, n.y(), 0, n.x(), n.z(), 0,
       0, 0, n.z(), 0, n.y(), n.x();
  return P;
}

// Wilson–Taylor incompatible modes φ_m = 1 − (2ξ_m − 1)², m = x, y, z (9 internal DOFs),
// condensed statically: K ← K_uu − K_uaᵀ K_aa⁻¹ K_au. Their gradients are shifted to zero mean
// over the element's rule (Taylor's correction), so constant strain is still reproduced on
// any subvolume (patch test). Removes the bending locking of trilinear hexahedra.
struct IncompatibleModes {
  bool used = false;   ///< false on tiny pieces (K_aa near singular) or a failed factorization
  double volume = 0;   ///< Σ rule weights
  Vec3 mean{0, 0, 0};  ///< rule mean of (∂φ_x/∂x, ∂φ_y/∂y, ∂φ_z/∂z)
  Eigen::Matrix<double, 9, 24> Kau;
  Eigen::LDLT<Eigen::Matrix<double, 9, 9>> Kaa;

  /// (∂φ_x/∂x, ∂φ_y/∂y, ∂φ_z/∂z) at X, before the mean shift.
  static Vec3 gradient(const Box3& box, const Vec3& X) {
    const Vec3 h = box.size(), xi = (X - box.min).cwiseQuotient(h);
    return Vec3(-4 * (2 * xi.x() - 1) / h.x(), -4 * (2 * xi.y() - 1) / h.y(), -4 * (2 * xi.z() - 1) / h.z());
  }
  /// Strain of the modes α (column 3m + c: mode m, component c) for mean-shifted gradients γ.
  static Eigen::Matrix<double, 6, 9> strain(const Vec3& gamma) {
    Eigen::Matrix<double, 8, 3> Gm = Eigen::Matrix<double, 8, 3>::Zero();  // rows 0..2 used
    for (int m = 0; m < 3; ++m) Gm(m, m) = gamma[m];
    return strain_matrix<8>(Gm).leftCols<9>();
  }
  /// The condensed modes of nodal displacements ue: α = −K_aa⁻¹ K_au uₑ.
  Eigen::Matrix<double, 9, 1> condensed(const Eigen::VectorXd& ue) const {
    return -Kaa.solve(Kau * ue);
  }
};

// The rule's volume and mean of the mode gradients (γ̄ = Σ w γ / V).
void mode_mean(const GridElement& el, double& volume, Vec3& mean) {
  volume = 0, mean.setZero();
  for (size_t q = 0; q < el.rule.points.size(); ++q) {
    volume += el.rule.weights[q];
    mean += el.rule.weights[q] * IncompatibleModes::gradient(el.box, el.rule.points[q]);
  }
  if (volume > 0) mean /= volume;
}

// K_aa and K_au of element el's modes with their gradients shifted by `mean`.
void mode_matrices(const GridElement& el, const Eigen::Matrix<double, 6, 6>& D, const Vec3& mean,
                   Eigen::Matrix<double, 9, 9>& Kaa, Eigen::Matrix<double, 9, 24>& Kau) {
  Kaa.setZero(), Kau.setZero();
  Eigen::Matrix<double, 8, 1> N;
  Eigen::Matrix<double, 8, 3> G;
  for (size_t q = 0; q < el.rule.points.size(); ++q) {
    const Vec3& X = el.rule.points[q];
    trilinear_shape(el.box, X, N, G);
    const Mat6x24 Bu = strain_matrix<8>(G);
    const Eigen::Matrix<double, 6, 9> Ba = IncompatibleModes::strain(IncompatibleModes::gradient(el.box, X) - mean);
    Kaa.noalias() += el.rule.weights[q] * Ba.transpose() * D * Ba;
    Kau.noalias() += el.rule.weights[q] * Ba.transpose() * D * Bu;
  }
}

IncompatibleModes incompatible_modes(const GridElement& el, const Eigen::Matrix<double, 6, 6>& D, double min_fraction) {
  IncompatibleModes im;
  for (double w : el.rule.weights) im.volume += w;
  if (!(switching_fraction(el) > min_fraction)) return im;  // tiny pieces: K_aa near singular
  if (!(im.volume > 0)) return im;
  mode_mean(el, im.volume, im.mean);
  Eigen::Matrix<double, 9, 9> Kaa;
  mode_matrices(el, D, im.mean, Kaa, im.Kau);
  im.Kaa.compute(Kaa);
  im.used = im.Kaa.info() == Eigen::Success && im.Kaa.vectorD().minCoeff() > 1e-10 * im.Kaa.vectorD().maxCoeff();
  return im;
}

// Eq. 6.24 with the incompatible modes: two pieces a, b of one cell under a PieceTie (weight w,
// blend θ) condensed jointly. Their modes are the cell's (one box: the same φ_m); the energy
// gets ½w‖α_a − α_b‖² and each piece's gradient mean moves towards the pair's,
// γ̄_P = (1 − θ) M_P + θ M_ab (M: rule means). At the join (θ = 1, w at its cap) this is the
// joined piece's one mode set with its one mean; with w = θ = 0 the two pieces' own.
struct TiedModePair {
  bool used = false;
  double volume[2] = {0, 0}, pair_volume = 0;
  Vec3 own_mean[2], pair_mean, mean[2];  ///< M_a, M_b, M_ab, γ̄_a, γ̄_b
  Eigen::Matrix<double, 9, 24> Kau[2];   ///< at γ̄_P
  Eigen::LDLT<Eigen::Matrix<double, 18, 18>> Kaa;
  /// α = −K_αα⁻¹ K_αu (u_a, u_b): rows 0..8 piece a's modes, 9..17 piece b's.
  Eigen::Matrix<double, 18, 1> condensed(const Eigen::VectorXd& ua, const Eigen::VectorXd& ub) const {
    Eigen::Matrix<double, 18, 1> rhs;
    rhs << Kau[0] * ua, Kau[1] * ub;
    return -Kaa.solve(rhs);
  }
};

TiedModePair tied_mode_pair(const GridElement& a, const GridElement& b, const Eigen::Matrix<double, 6, 6>& D,
                            double weight, double blend) {
  TiedModePair pair;
  const GridElement* el[2] = {&a, &b};
  for (int i = 0; i < 2; ++i) mode_mean(*el[i], pair.volume[i], pair.own_mean[i]);
  pair.pair_volume = pair.volume[0] + pair.volume[1];
  if (!(pair.volume[0] > 0 && pair.volume[1] > 0)) return pair;
  pair.pair_mean = (pair.volume[0] * pair.own_mean[0] + pair.volume[1] * pair.own_mean[1]) / pair.pair_volume;
  Eigen::Matrix<double, 18, 18> K = Eigen::Matrix<double, 18, 18>::Zero();
  for (int i = 0; i < 2; ++i) {
    pair.mean[i] = (1 - blend) * pair.own_mean[i] + blend * pair.pair_mean;
    Eigen::Matrix<double, 9, 9> Kaa;
    mode_matrices(*el[i], D, pair.mean[i], Kaa, pair.Kau[i]);
    K.block<9, 9>(9 * i, 9 * i) = Kaa + weight * Eigen::Matrix<double, 9, 9>::Identity();
  }
  K.block<9, 9>(0, 9) = K.block<9, 9>(9, 0) = -weight * Eigen::Matrix<double, 9, 9>::Identity();
  pair.Kaa.compute(K);
  // Positive definite when both pieces' own K_aa are (mode_tied); no pivot ratio test here: the
  // weight (up to E·h·cap) sets the largest pivots, not the conditioning of the modes.
  pair.used = pair.Kaa.info() == Eigen::Success && pair.Kaa.vectorD().minCoeff() > 0;
  return pair;
}

// The pair's condensed modes (u_a, u_b) and T_P = 2 Σ_{q∈P} w_q (S_m α_P)ᵀ D ε_q (m = x, y, z;
// S_m: the mode strain of a unit gradient along x_m), the factor of the means' changes.
struct TiedModeState {
  Eigen::Matrix<double, 18, 1> alpha;
  Vec3 T[2];
};

Eigen::Matrix<double, 6, 1> tied_mode_strain(const GridElement& el, const Eigen::VectorXd& ue, const Vec3& mean,
                                             const Eigen::Matrix<double, 9, 1>& alpha, const Vec3& X) {
  Eigen::Matrix<double, 8, 1> N;
  Eigen::Matrix<double, 8, 3> G;
  trilinear_shape(el.box, X, N, G);
  return strain_matrix<8>(G) * ue + IncompatibleModes::strain(IncompatibleModes::gradient(el.box, X) - mean) * alpha;
}

TiedModeState tied_mode_state(const TiedModePair& pair, const GridElement* el[2], const Eigen::VectorXd* u[2],
                              const Eigen::Matrix<double, 6, 6>& D) {
  TiedModeState s;
  s.alpha = pair.condensed(*u[0], *u[1]);
  for (int i = 0; i < 2; ++i) {
    const Eigen::Matrix<double, 9, 1> a = s.alpha.segment<9>(9 * i);
    Eigen::Matrix<double, 6, 3> S;
    for (int m = 0; m < 3; ++m) S.col(m) = IncompatibleModes::strain(Vec3::Unit(m)) * a;
    s.T[i].setZero();
    for (size_t q = 0; q < el[i]->rule.points.size(); ++q)
      s.T[i] += 2 * el[i]->rule.weights[q] *
                (S.transpose() * (D * tied_mode_strain(*el[i], *u[i], pair.mean[i], a, el[i]->rule.points[q])));
  }
  return s;
}

void add_incompatible_modes(const GridElement& el, const Eigen::Matrix<double, 6, 6>& D,
                            double min_fraction, Eigen::MatrixXd& Ke) {
  const IncompatibleModes im = incompatible_modes(el, D, min_fraction);
  if (im.used) Ke.noalias() -= im.Kau.transpose() * im.Kaa.solve(im.Kau);
}

// The first uncut element (no subvolume), or −1.
int first_interior_element(const std::vector<GridElement>& elements) {
  for (size_t e = 0; e < elements.size(); ++e)
    if (!elements[e].subvolume) return static_cast<int>(e);
  return -1;
}

// Uncut element b has the box size and rule of uncut element a (up to a translation, to
// 1e-12 relative): then their matrices are equal to round-off.
bool same_uncut_shape(const GridElement& a, const GridElement& b) {
  if (b.subvolume || a.subvolume || a.rule.points.size() != b.rule.points.size()) return false;
  const Vec3 ha = a.box.size(), hb = b.box.size();
  if (((ha - hb).array().abs() > 1e-12 * ha.array().abs()).any()) return false;
  const double volume = a.box.volume();
  for (size_t q = 0; q < a.rule.points.size(); ++q) {
    const Vec3 xa = (a.rule.points[q] - a.box.min).cwiseQuotient(ha), xb = (b.rule.points[q] - b.box.min).cwiseQuotient(hb);
    if ((xa - xb).cwiseAbs().maxCoeff() > 1e-12 || std::abs(a.rule.weights[q] - b.rule.weights[q]) > 1e-12 * volume)
      return false;
  }
  return true;
}

// Isotropic bulk stiffness of the rule (points, weights) in `box`, by node pairs:
// K(3a+i, 3b+j) = λ C_ij + μ C_ji + μ δ_ij Σ_k C_kk at (a, b), C_ij(a, b) = Σ_q w_q ∂_i N_a ∂_j N_b
// (9 products NN × nq × NN instead of B_qᵀ D B_q).
template <int NN>
Eigen::MatrixXd bulk_stiffness(const Box3& box, const std::vector<Vec3>& points, const std::vector<double>& weights,
                               const Lame& lm) {
  const auto [lambda, mu] = lm;
  const int nq = static_cast<int>(points.size());
  Eigen::Matrix<double, NN, 1> N;
  Eigen::Matrix<double, NN, 3> G;
  std::array<Eigen::Matrix<double, NN, Eigen::Dynamic>, 3> P;  // P[i](a, q) = ∂N_a/∂x_i at point q
  for (auto& p : P) p.resize(NN, nq);
  for (int q = 0; q < nq; ++q) {
    shape<NN>(box, points[q], N, G);
    for (int i = 0; i < 3; ++i) P[i].col(q) = G.col(i);
  }
  const Eigen::Map<const Eigen::VectorXd> w(weights.data(), nq);
  std::array<std::array<Eigen::Matrix<double, NN, NN>, 3>, 3> C;
  for (int i = 0; i < 3; ++i) {  // C_ji = C_ijᵀ: six products
    const Eigen::Matrix<double, NN, Eigen::Dynamic> Pw = P[i] * w.asDiagonal();
    for (int j = i; j < 3; ++j) C[i][j].noalias() = Pw * P[j].transpose();
    for (int j = 0; j < i; ++j) C[i][j] = C[j][i].transpose();
  }
  const Eigen::Matrix<double, NN, NN> trace = C[0][0] + C[1][1] + C[2][2];
  Eigen::MatrixXd K(3 * NN, 3 * NN);
  for (int a = 0; a < NN; ++a)
    for (int b = 0; b < NN; ++b)
      for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j)
          K(3 * a + i, 3 * b + j) = lambda * C[i][j](a, b) + mu * C[j][i](a, b) + (i == j ? mu * trace(a, b) : 0.0);
  return K;
}

// The element's bulk stiffness: its rule, hex8 with incompatible modes condensed.
template <int NN>
Eigen::MatrixXd element_bulk_stiffness(const GridElement& el, const ElasticMaterial& material,
                                       const LinearXfemOptions& options) {
  Eigen::MatrixXd K = bulk_stiffness<NN>(el.box, el.rule.points, el.rule.weights, lame(material));
  if constexpr (NN == 8)
    if (options.incompatible_modes) add_incompatible_modes(el, elasticity(material), options.incompatible_min_fraction, K);
  return K;
}

// The uncut cell's stiffness (3-point Gauss rule per axis: exact for hex8 and hex27).
template <int NN>
Eigen::MatrixXd full_cell_stiffness(const Box3& box, const Lame& lm) {
  static const double x[3] = {0.5 - 0.5 * std::sqrt(0.6), 0.5, 0.5 + 0.5 * std::sqrt(0.6)};
  static const double wt[3] = {5.0 / 18, 8.0 / 18, 5.0 / 18};
  std::vector<Vec3> points;
  std::vector<double> weights;
  const Vec3 h = box.size();
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j)
      for (int k = 0; k < 3; ++k) {
        points.push_back(box.min + Vec3(x[i], x[j], x[k]).cwiseProduct(h));
        weights.push_back(wt[i] * wt[j] * wt[k] * box.volume());
      }
  return bulk_stiffness<NN>(box, points, weights, lm);
}

// Λ of the local Nitsche penalty (LinearXfemOptions::nitsche_penalty): the largest λ with
// B v = λ A v off the rigid modes, A the element's bulk stiffness plus nitsche_local_floor × the
// uncut cell's (null space: the rigid modes R), B the Nitsche flux matrix Σ_q w_q Tᵀ M T over
// its Dirichlet patches (zero on R too). A + s·R Rᵀ (R orthonormal) is positive definite with
// the same eigenpairs off R, so one Cholesky-based generalized eigensolve gives Λ; if A has
// further non-positive directions (a rule with negative weights), the pencil is restricted
// to A's positive eigenvectors instead. With `mode`: also the eigenvector v (vᵀAv = 1, v ⟂ R)
// and in `gap` (Λ − λ₂)/Λ, λ₂ the next eigenvalue.
struct FluxEigen {
  double value = 0;
  Eigen::VectorXd mode;
  double gap = 1;
};
template <int NN>
FluxEigen largest_flux_eigenvalue(const Box3& box, const Eigen::MatrixXd& A, const Eigen::MatrixXd& B,
                                  bool mode = false) {
  constexpr int n = 3 * NN;
  Eigen::Matrix<double, n, 6> R;
  const Vec3 centre = 0.5 * (box.min + box.max);
  for (int a = 0; a < NN; ++a) {
    const Vec3 x = (node_position(box, NN, a) - centre) / box.size().maxCoeff();
    R.template block<3, 3>(3 * a, 0).setIdentity();
    for (int k = 0; k < 3; ++k) R.template block<3, 1>(3 * a, 3 + k) = Vec3::Unit(k).cross(x);
  }
  const Eigen::HouseholderQR<Eigen::Matrix<double, n, 6>> qr(R);
  const Eigen::Matrix<double, n, 6> Q = qr.householderQ() * Eigen::Matrix<double, n, 6>::Identity();
  const Eigen::MatrixXd shifted = A + (A.trace() / n) * Q * Q.transpose();
  FluxEigen out;
  auto finish = [&](const Eigen::VectorXd& values, const Eigen::MatrixXd* vectors) {
    const int top = static_cast<int>(values.size()) - 1;  // ascending
    out.value = std::max(0.0, values(top));
    if (top > 0 && out.value > 0) out.gap = (values(top) - values(top - 1)) / values(top);
    if (vectors) out.mode = vectors->col(top);
  };
  const Eigen::GeneralizedSelfAdjointEigenSolver<Eigen::MatrixXd> ge(B, shifted,
                                                                     mode ? Eigen::ComputeEigenvectors : Eigen::EigenvaluesOnly);
  if (ge.info() == Eigen::Success) {
    finish(ge.eigenvalues(), mode ? &ge.eigenvectors() : nullptr);
    if (mode) out.mode /= std::sqrt(out.mode.dot(shifted * out.mode));
    return out;
  }
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> ea(A);
  PARAFAB_VERIFY(ea.info() == Eigen::Success, "local Nitsche penalty: eigen decomposition of the bulk stiffness failed");
  const Eigen::VectorXd& d = ea.eigenvalues();
  const double cut = 1e-10 * d.cwiseAbs().maxCoeff();
  int first = 0;
  while (first < d.size() && d(first) <= cut) ++first;
  if (first == d.size()) return out;
  const int r = static_cast<int>(d.size()) - first;
  const Eigen::MatrixXd W = ea.eigenvectors().rightCols(r) * d.tail(r).cwiseSqrt().cwiseInverse().asDiagonal();
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> ec(W.transpose() * B * W,
                                                          mode ? Eigen::ComputeEigenvectors : Eigen::EigenvaluesOnly);
  PARAFAB_VERIFY(ec.info() == Eigen::Success, "local Nitsche penalty: eigenvalues of the flux matrix failed");
  if (!mode) {
    finish(ec.eigenvalues(), nullptr);
    return out;
  }
  const Eigen::MatrixXd V = W * ec.eigenvectors();  // vᵀAv = 1
  finish(ec.eigenvalues(), &V);
  return out;
}

// Whether the patch's surface map is affine (a plane): the same tangents at the corners and the
// centre of its loops' uv box.
bool affine_patch(const CutPatch& patch) {
  Vec2 lo = Vec2::Constant(std::numeric_limits<double>::infinity()), hi = -lo;
  for (const BoundaryLoop& l : patch.loops)
    for (const Vec2& q : l.points) lo = lo.cwiseMin(q), hi = hi.cwiseMax(q);
  if (!(lo.allFinite() && hi.allFinite())) return false;
  Vec3 X, Xu0, Xv0, Xu, Xv;
  patch.surface->evaluate(0.5 * (lo.x() + hi.x()), 0.5 * (lo.y() + hi.y()), X, Xu0, Xv0);
  const double scale = 1e-12 * (Xu0.norm() + Xv0.norm());
  for (const Vec2& q : {lo, hi, Vec2(lo.x(), hi.y()), Vec2(hi.x(), lo.y())}) {
    patch.surface->evaluate(q.x(), q.y(), X, Xu, Xv);
    if ((Xu - Xu0).norm() > scale || (Xv - Xv0).norm() > scale) return false;
  }
  return true;
}

}  // namespace

int patch_rule_degree(const LinearXfemOptions& options, const CutPatch& patch, bool dirichlet) {
  const int degree = options.element == ElementType::Hex27 ? std::max(options.surface_degree, 8) : options.surface_degree;
  return dirichlet && options.dirichlet_surface_degree > degree && !affine_patch(patch)
             ? options.dirichlet_surface_degree
             : degree;
}

namespace {

// The Dirichlet condition on `face`, or null.
const DirichletCondition* dirichlet_on(const std::vector<DirichletCondition>& dirichlet, int face) {
  const DirichletCondition* dc = nullptr;
  for (const auto& d : dirichlet) if (d.face == face) dc = &d;
  return dc;
}

// The element's boundary patches with a Dirichlet or traction condition, and their rules
// (computed once: the local penalty and the boundary terms both integrate over them).
struct ConditionedPatch {
  const DirichletCondition* dirichlet = nullptr;
  const TractionCondition* traction = nullptr;
  SurfaceRule rule;
};

template <int NN>
std::vector<ConditionedPatch> conditioned_patches(const GridElement& el, const std::vector<DirichletCondition>& dirichlet,
                                                  const std::vector<TractionCondition>& tractions,
                                                  const LinearXfemOptions& options) {
  std::vector<ConditionedPatch> out;
  if (!el.subvolume) return out;
  for (const CutPatch& patch : el.subvolume->patches) {
    if (patch.source_face < 0) continue;
    ConditionedPatch cp;
    cp.dirichlet = dirichlet_on(dirichlet, patch.source_face);
    for (const auto& t : tractions) if (t.face == patch.source_face) cp.traction = &t;
    if (!cp.dirichlet && !cp.traction) continue;
    SurfaceRuleOptions so;
    so.area.degree = patch_rule_degree(options, patch, cp.dirichlet != nullptr);
    cp.rule = surface_rule(patch, so);
    out.push_back(std::move(cp));
  }
  return out;
}

// The local penalty's parts on an element (`patches` from conditioned_patches); with `mode`
// also Λ's eigenvector, the penalty mass P and load g (LocalPenaltyParts).
template <int NN>
LocalPenaltyParts local_penalty_parts_n(const GridElement& el, const ElasticMaterial& material,
                                        const std::vector<ConditionedPatch>& patches, const LinearXfemOptions& options,
                                        const Eigen::MatrixXd* bulk, bool mode) {
  const Eigen::Matrix<double, 6, 6> D = elasticity(material);
  constexpr int n = 3 * NN;
  LocalPenaltyParts parts;
  Eigen::MatrixXd B = Eigen::MatrixXd::Zero(n, n);
  if (mode) parts.mass = Eigen::MatrixXd::Zero(n, n), parts.load = Eigen::VectorXd::Zero(n);
  Eigen::Matrix<double, NN, 1> N;
  Eigen::Matrix<double, NN, 3> G;
  for (const ConditionedPatch& cp : patches) {
    if (!cp.dirichlet) continue;
    parts.clamped = true;
    const SurfaceRule& sr = cp.rule;
    const Eigen::Matrix3d M = cp.dirichlet->components.asDiagonal();
    for (size_t q = 0; q < sr.points.size(); ++q) {
      shape<NN>(el.box, sr.points[q], N, G);
      const Eigen::Matrix<double, 3, n> T = traction_operator(sr.normals[q]) * D * strain_matrix<NN>(G);
      B.noalias() += sr.weights[q] * T.transpose() * M * T;
      if (!mode) continue;
      const Eigen::Matrix<double, 3, n> Nm = value_matrix<NN>(N);
      const Vec3 g = cp.dirichlet->field ? cp.dirichlet->field(sr.points[q])
                                         : Vec3(cp.dirichlet->offset + cp.dirichlet->gradient * sr.points[q]);
      parts.mass.noalias() += sr.weights[q] * Nm.transpose() * M * Nm;
      parts.load.noalias() += sr.weights[q] * Nm.transpose() * (M * g);
    }
  }
  if (!parts.clamped) return parts;  // no Dirichlet patch
  Eigen::MatrixXd A = bulk ? *bulk : element_bulk_stiffness<NN>(el, material, options);
  if (options.nitsche_local_floor > 0) A += options.nitsche_local_floor * full_cell_stiffness<NN>(el.box, lame(material));
  const FluxEigen fe = largest_flux_eigenvalue<NN>(el.box, A, B, mode);
  parts.flux_eigenvalue = fe.value;
  parts.penalty = options.nitsche_local_factor * fe.value;
  parts.mode = fe.mode;
  parts.gap = fe.gap;
  return parts;
}

// The penalty on the element's Dirichlet patches (`patches` from conditioned_patches).
template <int NN>
double nitsche_penalty_n(const GridElement& el, const ElasticMaterial& material,
                         const std::vector<ConditionedPatch>& patches, const LinearXfemOptions& options,
                         const Eigen::MatrixXd* bulk) {
  if (options.nitsche_penalty == LinearXfemOptions::NitschePenalty::Fixed)
    return (options.nitsche_beta > 0 ? options.nitsche_beta : 100.0) * material.youngs_modulus / el.box.size().minCoeff();
  return local_penalty_parts_n<NN>(el, material, patches, options, bulk, false).penalty;
}

template <int NN>
ElementSystem element_system_n(const GridElement& el, const ElasticMaterial& material,
                               const std::vector<DirichletCondition>& dirichlet,
                               const std::vector<TractionCondition>& tractions, const LinearXfemOptions& options,
                               bool include_bulk) {
  const Eigen::Matrix<double, 6, 6> D = elasticity(material);
  constexpr int n = 3 * NN;
  ElementSystem s;
  s.K = Eigen::MatrixXd::Zero(n, n);
  s.f = Eigen::VectorXd::Zero(n);
  Eigen::Matrix<double, NN, 1> N;
  Eigen::Matrix<double, NN, 3> G;
  const int nq = static_cast<int>(el.rule.points.size());
  if (material.density != 0 && options.gravity.squaredNorm() > 0)
    for (int q = 0; q < nq; ++q) {
      shape<NN>(el.box, el.rule.points[q], N, G);
      for (int a = 0; a < NN; ++a) s.f.template segment<3>(3 * a) += el.rule.weights[q] * material.density * N(a) * options.gravity;
    }
  if (include_bulk && nq > 0) s.K = element_bulk_stiffness<NN>(el, material, options);
  const std::vector<ConditionedPatch> patches = conditioned_patches<NN>(el, dirichlet, tractions, options);
  bool clamped = false;  // the penalty is needed (and, when local, costs an eigensolve) only here
  for (const ConditionedPatch& cp : patches) clamped = clamped || cp.dirichlet;
  const double penalty =
      clamped ? nitsche_penalty_n<NN>(el, material, patches, options, include_bulk && nq > 0 ? &s.K : nullptr) : 0.0;
  for (const ConditionedPatch& cp : patches) {
    const DirichletCondition* dc = cp.dirichlet;
    const TractionCondition* tc = cp.traction;
    const SurfaceRule& sr = cp.rule;
    for (size_t q = 0; q < sr.points.size(); ++q) {
      shape<NN>(el.box, sr.points[q], N, G);
      const Eigen::Matrix<double, 3, n> Nm = value_matrix<NN>(N);
      const double wq = sr.weights[q];
      if (tc) s.f.noalias() += wq * Nm.transpose() * tc->traction;
      if (dc) {
        const Eigen::Matrix<double, 3, n> T = traction_operator(sr.normals[q]) * D * strain_matrix<NN>(G);
        const Vec3 g = dc->field ? dc->field(sr.points[q]) : Vec3(dc->offset + dc->gradient * sr.points[q]);
        const Eigen::Matrix3d M = dc->components.asDiagonal();  // prescribed components
        const Eigen::Matrix<double, 3, n> MNm = M * Nm, MT = M * T;
        s.K.noalias() += wq * (penalty * Nm.transpose() * MNm - Nm.transpose() * MT - T.transpose() * MNm);
        s.f.noalias() += wq * (penalty * Nm.transpose() * (M * g) - T.transpose() * (M * g));
      }
    }
  }
  return s;
}

struct UnionFind {
  std::vector<int> parent;
  explicit UnionFind(int n) : parent(n) { std::iota(parent.begin(), parent.end(), 0); }
  int find(int a) { return parent[a] == a ? a : parent[a] = find(parent[a]); }
  void unite(int a, int b) { parent[find(a)] = find(b); }
};

}  // namespace

ElementType element_type_from_name(const std::string& name, const std::string& field) {
  if (name == "hex8") return ElementType::Hex8;
  if (name == "hex27") return ElementType::Hex27;
  PARAFAB_INPUT_ERROR(field << " must be \"hex8\" (trilinear) or \"hex27\" (triquadratic), got \"" << name << "\"");
}

const char* element_type_name(ElementType type) { return type == ElementType::Hex27 ? "hex27" : "hex8"; }

int nodes_per_element(ElementType type) { return type == ElementType::Hex27 ? 27 : 8; }

SparseAccumulator::SparseAccumulator(int rows, int cols, size_t chunk) : matrix_(rows, cols), chunk_(chunk) {
  triplets_.reserve(std::min<size_t>(chunk_, size_t(1) << 16));
}

void SparseAccumulator::flush() {
  if (triplets_.empty()) return;
  Eigen::SparseMatrix<double> part(matrix_.rows(), matrix_.cols());
  part.setFromTriplets(triplets_.begin(), triplets_.end());
  triplets_.clear();
  if (matrix_.nonZeros() == 0) matrix_ = std::move(part);
  else matrix_ += part;
}

Eigen::SparseMatrix<double> SparseAccumulator::finish() {
  flush();
  return std::move(matrix_);
}

void trilinear_shape(const Box3& box, const Vec3& X, Eigen::Matrix<double, 8, 1>& N,
                     Eigen::Matrix<double, 8, 3>& G) {
  const Vec3 h = box.size();
  const Vec3 xi = (X - box.min).cwiseQuotient(h);
  for (int k = 0; k < 8; ++k) {
    const int bx = k & 1, by = (k >> 1) & 1, bz = (k >> 2) & 1;
    const double fx = bx ? xi.x() : 1 - xi.x(), fy = by ? xi.y() : 1 - xi.y(), fz = bz ? xi.z() : 1 - xi.z();
    N(k) = fx * fy * fz;
    G(k, 0) = (bx ? 1 : -1) * fy * fz / h.x();
    G(k, 1) = fx * (by ? 1 : -1) * fz / h.y();
    G(k, 2) = fx * fy * (bz ? 1 : -1) / h.z();
  }
}

namespace {
// The 1D quadratic Lagrange functions with nodes 0, ½, 1 at t (triquadratic cells are their products).
void quadratic_lagrange(double t, double L[3]) {
  L[0] = (1 - t) * (1 - 2 * t), L[1] = 4 * t * (1 - t), L[2] = t * (2 * t - 1);
}
}  // namespace

void triquadratic_shape(const Box3& box, const Vec3& X, Eigen::Matrix<double, 27, 1>& N,
                        Eigen::Matrix<double, 27, 3>& G) {
  const Vec3 h = box.size();
  const Vec3 xi = (X - box.min).cwiseQuotient(h);
  double L[3][3], dL[3][3];  // 1D quadratic Lagrange at 0, ½, 1 and their x-derivatives
  for (int d = 0; d < 3; ++d) {
    const double t = xi[d];
    quadratic_lagrange(t, L[d]);
    dL[d][0] = (4 * t - 3) / h[d], dL[d][1] = (4 - 8 * t) / h[d], dL[d][2] = (4 * t - 1) / h[d];
  }
  for (int l = 0; l < 3; ++l)
    for (int j = 0; j < 3; ++j)
      for (int i = 0; i < 3; ++i) {
        const int k = i + 3 * j + 9 * l;
        N(k) = L[0][i] * L[1][j] * L[2][l];
        G(k, 0) = dL[0][i] * L[1][j] * L[2][l];
        G(k, 1) = L[0][i] * dL[1][j] * L[2][l];
        G(k, 2) = L[0][i] * L[1][j] * dL[2][l];
      }
}

Vec3 corner(const Box3& box, int k) {
  return Vec3((k & 1) ? box.max.x() : box.min.x(), (k & 2) ? box.max.y() : box.min.y(),
              (k & 4) ? box.max.z() : box.min.z());
}

std::array<int, 3> node_offset(int nodes, int k) {
  if (nodes == 27) return {k % 3, (k / 3) % 3, k / 9};
  return {2 * (k & 1), 2 * ((k >> 1) & 1), 2 * ((k >> 2) & 1)};
}

Vec3 node_position(const Box3& box, int nodes, int k) {
  const auto o = node_offset(nodes, k);
  return box.min + 0.5 * Vec3(o[0], o[1], o[2]).cwiseProduct(box.size());
}

namespace {

// Node k's grid position in half cells (hex8 corners, hex27 nodes): the key by which elements
// share DOF nodes.
std::array<int, 3> half_cell_position(const GridElement& element, int nodes, int k) {
  const auto& c = element.cell;
  const auto o = node_offset(nodes, k);
  return {2 * c[0] + o[0], 2 * c[1] + o[1], 2 * c[2] + o[2]};
}

}  // namespace

std::vector<std::vector<int>> number_dof_nodes(const std::vector<GridElement>& elements,
                                               const std::vector<std::array<int, 2>>& adjacent,
                                               int& count, ElementType element) {
  const int n = static_cast<int>(elements.size());
  const int nn = nodes_per_element(element);
  UnionFind uf(nn * n);
  auto grid_node = [&](int e, int k) { return half_cell_position(elements[e], nn, k); };
  for (const auto& [a, b] : adjacent) {
    PARAFAB_VERIFY(a >= 0 && a < n && b >= 0 && b < n, "element pair (" << a << ", " << b << ") out of range");
    for (int ka = 0; ka < nn; ++ka) {
      const auto ga = grid_node(a, ka);
      for (int kb = 0; kb < nn; ++kb)
        if (ga == grid_node(b, kb)) uf.unite(nn * a + ka, nn * b + kb);
    }
  }
  std::vector<int> id(nn * n, -1);
  std::vector<std::vector<int>> node(n, std::vector<int>(nn));
  count = 0;
  for (int s = 0; s < nn * n; ++s) {
    const int r = uf.find(s);
    if (id[r] < 0) id[r] = count++;
    node[s / nn][s % nn] = id[r];
  }
  return node;
}

ElementSystem element_system(const GridElement& element, const ElasticMaterial& material,
                             const std::vector<DirichletCondition>& dirichlet,
                             const std::vector<TractionCondition>& tractions,
                             const LinearXfemOptions& options, bool include_bulk) {
  return options.element == ElementType::Hex27
             ? element_system_n<27>(element, material, dirichlet, tractions, options, include_bulk)
             : element_system_n<8>(element, material, dirichlet, tractions, options, include_bulk);
}

double nitsche_penalty(const GridElement& element, const ElasticMaterial& material,
                       const std::vector<DirichletCondition>& dirichlet, const LinearXfemOptions& options) {
  if (options.nitsche_penalty == LinearXfemOptions::NitschePenalty::Fixed)  // no patches needed
    return nitsche_penalty_n<8>(element, material, {}, options, nullptr);
  return options.element == ElementType::Hex27
             ? nitsche_penalty_n<27>(element, material, conditioned_patches<27>(element, dirichlet, {}, options), options, nullptr)
             : nitsche_penalty_n<8>(element, material, conditioned_patches<8>(element, dirichlet, {}, options), options, nullptr);
}

LocalPenaltyParts local_penalty_parts(const GridElement& element, const ElasticMaterial& material,
                                      const std::vector<DirichletCondition>& dirichlet, const LinearXfemOptions& options) {
  PARAFAB_VERIFY(options.nitsche_penalty == LinearXfemOptions::NitschePenalty::Local,
                 "local_penalty_parts: the options name the fixed Nitsche penalty");
  return options.element == ElementType::Hex27
             ? local_penalty_parts_n<27>(element, material, conditioned_patches<27>(element, dirichlet, {}, options), options,
                                         nullptr, true)
             : local_penalty_parts_n<8>(element, material, conditioned_patches<8>(element, dirichlet, {}, options), options,
                                        nullptr, true);
}

namespace {

// Second derivatives of the shape functions: dG[m](a, j) = ∂²N_a/∂x_j∂x_m (products of the 1D
// Lagrange functions, as trilinear_shape / triquadratic_shape).
template <int NN>
void shape_second_derivatives(const Box3& box, const Vec3& X, std::array<Eigen::Matrix<double, NN, 3>, 3>& dG) {
  constexpr int P = NN == 8 ? 2 : 3;  // nodes per direction
  const Vec3 h = box.size();
  const Vec3 xi = (X - box.min).cwiseQuotient(h);
  double L[3][3], dL[3][3], d2L[3][3];
  for (int d = 0; d < 3; ++d) {
    const double t = xi[d];
    if constexpr (P == 2) {
      L[d][0] = 1 - t, L[d][1] = t;
      dL[d][0] = -1 / h[d], dL[d][1] = 1 / h[d];
      d2L[d][0] = d2L[d][1] = 0;
    } else {
      L[d][0] = (1 - t) * (1 - 2 * t), L[d][1] = 4 * t * (1 - t), L[d][2] = t * (2 * t - 1);
      dL[d][0] = (4 * t - 3) / h[d], dL[d][1] = (4 - 8 * t) / h[d], dL[d][2] = (4 * t - 1) / h[d];
      const double h2 = h[d] * h[d];
      d2L[d][0] = 4 / h2, d2L[d][1] = -8 / h2, d2L[d][2] = 4 / h2;
    }
  }
  for (int l = 0; l < P; ++l)
    for (int j = 0; j < P; ++j)
      for (int i = 0; i < P; ++i) {
        const int a = P == 2 ? i + 2 * j + 4 * l : i + 3 * j + 9 * l;  // trilinear_shape: bit 0 x, 1 y, 2 z
        const int idx[3] = {i, j, l};
        for (int m = 0; m < 3; ++m)
          for (int c = 0; c < 3; ++c) {
            double v = 1;
            for (int d = 0; d < 3; ++d) {
              const int order = (d == m) + (d == c);
              v *= order == 0 ? L[d][idx[d]] : order == 1 ? dL[d][idx[d]] : d2L[d][idx[d]];
            }
            dG[m](a, c) = v;
          }
      }
}

// Voigt strain (engineering shears, strain_matrix's order) of a displacement gradient H_ij = ∂u_i/∂x_j.
Eigen::Matrix<double, 6, 1> voigt_strain(const Eigen::Matrix3d& H) {
  Eigen::Matrix<double, 6, 1> e;
  e << H(0, 0), H(1, 1), H(2, 2), H(0, 1) + H(1, 0), H(1, 2) + H(2, 1), H(0, 2) + H(2, 0);
  return e;
}

template <int NN>
BoundaryTermDensity boundary_term_density_n(const GridElement& el, const Eigen::VectorXd& ue,
                                            const ElasticMaterial& material, const LinearXfemOptions& options,
                                            const DirichletCondition* dc, const TractionCondition* tc, const Vec3& X,
                                            const Vec3& n, double local_penalty) {
  BoundaryTermDensity d;
  Eigen::Matrix<double, NN, 1> N;
  Eigen::Matrix<double, NN, 3> G;
  shape<NN>(el.box, X, N, G);
  const Vec3 u = value_matrix<NN>(N) * ue;
  if (tc) {
    d.load += u.dot(tc->traction);
    for (int a = 0; a < NN; ++a) d.load_gradient += G.row(a).transpose() * ue.segment<3>(3 * a).dot(tc->traction);
  }
  if (dc) {
    // The terms of element_system_n: K ∋ penalty NᵀMN − NᵀMT − TᵀMN, f ∋ penalty NᵀMg − TᵀMg.
    const Eigen::Matrix<double, 6, 6> D = elasticity(material);
    const Eigen::Matrix<double, 6, 1> stress = D * (strain_matrix<NN>(G) * ue);
    const Vec3 sigma_n = traction_operator(n) * stress;
    PARAFAB_VERIFY(options.nitsche_penalty == LinearXfemOptions::NitschePenalty::Fixed || local_penalty >= 0,
                   "boundary_term_density: the local Nitsche penalty needs the element's penalty (local_penalty_parts)");
    const double penalty = options.nitsche_penalty == LinearXfemOptions::NitschePenalty::Fixed
                               ? nitsche_penalty_n<NN>(el, material, {}, options, nullptr)  // Fixed: no patches needed
                               : local_penalty;
    const Eigen::Matrix3d M = dc->components.asDiagonal();
    d.flux = sigma_n.dot(M * sigma_n);
    const Vec3 g = dc->field ? dc->field(X) : Vec3(dc->offset + dc->gradient * X);
    d.stiffness += penalty * u.dot(M * u) - 2 * u.dot(M * sigma_n);
    d.load += penalty * u.dot(M * g) - sigma_n.dot(M * g);
    // The support's own motion: ∇_X at n held (∂_m u = H e_m, ∂_m σn from the shape functions'
    // second derivatives; ∂_m g = the prescribed gradient's column, 0 for a field) and ∂/∂n at X
    // held (a·σn = (σa)·n, σ symmetric).
    Eigen::Matrix3d H = Eigen::Matrix3d::Zero();  // ∂u_i/∂x_j
    for (int a = 0; a < NN; ++a) H += ue.segment<3>(3 * a) * G.row(a);
    std::array<Eigen::Matrix<double, NN, 3>, 3> dG;
    shape_second_derivatives<NN>(el.box, X, dG);
    const Vec3 Mu = M * u, Mg = M * g, Ms = M * sigma_n;
    for (int m = 0; m < 3; ++m) {
      Eigen::Matrix3d dH = Eigen::Matrix3d::Zero();
      for (int a = 0; a < NN; ++a) dH += ue.segment<3>(3 * a) * dG[m].row(a);
      const Vec3 dsigma_n = traction_operator(n) * (D * voigt_strain(dH));
      const Vec3 du = H.col(m);
      const Vec3 dg = dc->field ? Vec3::Zero() : Vec3(dc->gradient.col(m));
      d.stiffness_gradient[m] = 2 * penalty * du.dot(Mu) - 2 * du.dot(Ms) - 2 * Mu.dot(dsigma_n);
      d.load_gradient[m] += penalty * (du.dot(Mg) + Mu.dot(dg)) - dsigma_n.dot(Mg) - Ms.dot(dg);
      d.flux_gradient[m] = 2 * dsigma_n.dot(Ms);
    }
    d.stiffness_normal = -2 * traction_operator(Mu) * stress;
    d.load_normal = -(traction_operator(Mg) * stress);
    d.flux_normal = 2 * traction_operator(Ms) * stress;
  }
  return d;
}

}  // namespace

BoundaryTermDensity boundary_term_density(const GridElement& element, const Eigen::VectorXd& ue,
                                          const ElasticMaterial& material, const LinearXfemOptions& options,
                                          const DirichletCondition* dirichlet, const TractionCondition* traction,
                                          const Vec3& X, const Vec3& normal, double local_penalty) {
  const int nodes = nodes_per_element(options.element);
  PARAFAB_VERIFY(ue.size() == 3 * nodes, "boundary_term_density: " << ue.size() << " nodal values for a "
                                                                    << element_type_name(options.element) << " element");
  return options.element == ElementType::Hex27
             ? boundary_term_density_n<27>(element, ue, material, options, dirichlet, traction, X, normal, local_penalty)
             : boundary_term_density_n<8>(element, ue, material, options, dirichlet, traction, X, normal, local_penalty);
}

struct BulkShapeDensity::Element {
  const GridElement& el;
  Eigen::VectorXd ve, ue;
  Eigen::Matrix<double, 6, 6> D;
  LinearXfemOptions options;
  bool ready = false;  // the element's part below computed
  IncompatibleModes im;
  Eigen::Matrix<double, 9, 1> au, av;
  Vec3 tau = Vec3::Zero();
};

BulkShapeDensity::BulkShapeDensity(const GridElement& el, const Eigen::VectorXd& ve, const Eigen::VectorXd& ue,
                                   const ElasticMaterial& material, const LinearXfemOptions& options) {
  const int nodes = nodes_per_element(options.element);
  PARAFAB_VERIFY(ve.size() == 3 * nodes && ue.size() == 3 * nodes,
                 "bulk_shape_density: " << ve.size() << " and " << ue.size() << " nodal values for a "
                                        << element_type_name(options.element) << " element (" << 3 * nodes << " expected)");
  element_.reset(new Element{el, ve, ue, elasticity(material), options});
}
BulkShapeDensity::~BulkShapeDensity() = default;
BulkShapeDensity::BulkShapeDensity(BulkShapeDensity&&) noexcept = default;

std::vector<double> BulkShapeDensity::operator()(const std::vector<Vec3>& points) {
  Element& e = *element_;
  const GridElement& el = e.el;
  const Eigen::Matrix<double, 6, 6>& D = e.D;
  std::vector<double> psi(points.size(), 0.0);
  if (e.options.element == ElementType::Hex27) {
    Eigen::Matrix<double, 27, 1> N;
    Eigen::Matrix<double, 27, 3> G;
    for (size_t k = 0; k < points.size(); ++k) {
      triquadratic_shape(el.box, points[k], N, G);
      const Eigen::Matrix<double, 6, 81> B = strain_matrix<27>(G);
      psi[k] = (B * e.ve).dot(D * (B * e.ue));
    }
    return psi;
  }
  Eigen::Matrix<double, 8, 1> N;
  Eigen::Matrix<double, 8, 3> G;
  const IncompatibleModes& im = e.im;
  if (!e.ready && e.options.incompatible_modes) e.im = incompatible_modes(el, D, e.options.incompatible_min_fraction);
  if (!im.used) {
    e.ready = true;
    for (size_t k = 0; k < points.size(); ++k) {
      trilinear_shape(el.box, points[k], N, G);
      const Mat6x24 B = strain_matrix<8>(G);
      psi[k] = (B * e.ve).dot(D * (B * e.ue));
    }
    return psi;
  }
  // With condensed modes α_u, α_v (envelope: their change does not enter to first order) the
  // strains are ε = B uₑ + B_a(γ − γ̄) α, and the mean γ̄ = Σ w γ / V moves with the weights:
  // ∂γ̄/∂w_j = (γ_j − γ̄)/V, hence the term −(1/V) Σ_m (γ − γ̄)_m [τ_m(v, α_u) + τ_m(u, α_v)] with
  // τ_m(v, α_u) = Σ_q w_q ε_q(v)ᵀ D S_m α_u (S_m: mode strain of a unit gradient along x_m).
  auto strains = [&](const Vec3& X, Eigen::Matrix<double, 6, 1>& eu, Eigen::Matrix<double, 6, 1>& ev) {
    trilinear_shape(el.box, X, N, G);
    const Mat6x24 B = strain_matrix<8>(G);
    const Eigen::Matrix<double, 6, 9> Ba = IncompatibleModes::strain(IncompatibleModes::gradient(el.box, X) - im.mean);
    eu = B * e.ue + Ba * e.au;
    ev = B * e.ve + Ba * e.av;
  };
  Eigen::Matrix<double, 6, 1> eu, ev;
  if (!e.ready) {
    e.au = im.condensed(e.ue), e.av = im.condensed(e.ve);
    Eigen::Matrix<double, 6, 3> Su, Sv;  // columns m: S_m α_u, S_m α_v
    for (int m = 0; m < 3; ++m) {
      Su.col(m) = IncompatibleModes::strain(Vec3::Unit(m)) * e.au;
      Sv.col(m) = IncompatibleModes::strain(Vec3::Unit(m)) * e.av;
    }
    for (size_t q = 0; q < el.rule.points.size(); ++q) {
      strains(el.rule.points[q], eu, ev);
      e.tau += el.rule.weights[q] * (Su.transpose() * (D * ev) + Sv.transpose() * (D * eu));
    }
    e.ready = true;
  }
  for (size_t k = 0; k < points.size(); ++k) {
    strains(points[k], eu, ev);
    const Vec3 shift = IncompatibleModes::gradient(el.box, points[k]) - im.mean;
    psi[k] = ev.dot(D * eu) - shift.dot(e.tau) / im.volume;
  }
  return psi;
}

std::vector<double> bulk_shape_density(const GridElement& el, const Eigen::VectorXd& ve, const Eigen::VectorXd& ue,
                                       const ElasticMaterial& material, const LinearXfemOptions& options,
                                       const std::vector<Vec3>& points) {
  return BulkShapeDensity(el, ve, ue, material, options)(points);
}

LinearSystem assemble_linear(const std::vector<GridElement>& elements,
                             const std::vector<std::vector<int>>& node, int node_count,
                             const ElasticMaterial& material,
                             const std::vector<DirichletCondition>& dirichlet,
                             const std::vector<TractionCondition>& tractions,
                             const LinearXfemOptions& options, bool include_bulk) {
  return assemble_linear(elements, node, node_count, material, dirichlet, tractions, options, include_bulk, ElementSource{});
}

LinearSystem assemble_linear(const std::vector<GridElement>& elements,
                             const std::vector<std::vector<int>>& node, int node_count,
                             const ElasticMaterial& material,
                             const std::vector<DirichletCondition>& dirichlet,
                             const std::vector<TractionCondition>& tractions,
                             const LinearXfemOptions& options, bool include_bulk, const ElementSource& source,
                             double* integrate_seconds, double* scatter_seconds) {
  PARAFAB_VERIFY(material.youngs_modulus > 0, "material: E must be positive, got " << material.youngs_modulus);
  PARAFAB_VERIFY(material.poisson_ratio > -1 && material.poisson_ratio < 0.5,
                 "material: Poisson ratio must be in (-1, 0.5), got " << material.poisson_ratio);
  PARAFAB_VERIFY(node.size() == elements.size(), "assemble_linear: " << node.size() << " node lists for "
                                                                     << elements.size() << " elements");
  const int nn = nodes_per_element(options.element);
  const int ndof = 3 * node_count;
  SparseAccumulator K(ndof, ndof);
  Eigen::VectorXd f = Eigen::VectorXd::Zero(ndof);
  for (size_t e = 0; e < elements.size(); ++e)
    PARAFAB_VERIFY(static_cast<int>(node[e].size()) == nn,
                   "assemble_linear: element " << e << " has " << node[e].size() << " nodes, "
                                               << element_type_name(options.element) << " needs " << nn);
  // Uncut interior cells share one box size and rule, hence one matrix: integrated once (for
  // the first interior element) and copied to every element of the same shape.
  const int reference = first_interior_element(elements);
  ElementSystem reference_system;
  if (reference >= 0)
    reference_system = element_system(elements[reference], material, dirichlet, tractions, options, include_bulk);
  auto element_or_copy = [&](size_t e, ElementSystem& es) {
    if (reference >= 0 && (static_cast<int>(e) == reference || same_uncut_shape(elements[reference], elements[e]))) {
      es = reference_system;
      return static_cast<int>(e) != reference;  // counts copies, not the integrated one
    }
    if (source.known)
      if (const ElementSystem* k = source.known(e)) {
        es = *k;
        return false;
      }
    es = element_system(elements[e], material, dirichlet, tractions, options, include_bulk);
    if (source.made) source.made(e, es);
    return false;
  };
  auto scatter = [&](size_t e, const ElementSystem& es) {
    for (int a = 0; a < nn; ++a)
      for (int da = 0; da < 3; ++da) {
        const int ra = 3 * node[e][a] + da;
        f(ra) += es.f(3 * a + da);
        for (int b = 0; b < nn; ++b)
          for (int db = 0; db < 3; ++db) {
            const double v = es.K(3 * a + da, 3 * b + db);
            if (v != 0.0) K.add(ra, 3 * node[e][b] + db, v);
          }
      }
  };
  // Element matrices in parallel (TBB), a chunk at a time; the scatter runs in element order,
  // so K and f are bit-identical for every thread count.
  const size_t n = elements.size(), chunk = nn == 8 ? 4096 : 512;
  std::vector<ElementSystem> systems(std::min(n, chunk));
  std::atomic<int> copies{0};
  double t_integrate = 0, t_scatter = 0;
  for (size_t begin = 0; begin < n; begin += chunk) {
    const size_t end = std::min(n, begin + chunk);
    auto t = std::chrono::steady_clock::now();
    tbb::parallel_for(tbb::blocked_range<size_t>(begin, end, 16), [&](const tbb::blocked_range<size_t>& r) {
      int c = 0;
      for (size_t e = r.begin(); e != r.end(); ++e) c += element_or_copy(e, systems[e - begin]);
      copies += c;
    });
    t_integrate += seconds_since(t);
    t = std::chrono::steady_clock::now();
    for (size_t e = begin; e < end; ++e) scatter(e, systems[e - begin]);
    t_scatter += seconds_since(t);
  }
  LinearSystem sys;
  auto t = std::chrono::steady_clock::now();
  sys.K = K.finish();
  t_scatter += seconds_since(t);
  sys.f = std::move(f);
  sys.reused_element_matrices = copies;
  if (integrate_seconds) *integrate_seconds = t_integrate;
  if (scatter_seconds) *scatter_seconds = t_scatter;
  return sys;
}

Vec3 LinearXfemResult::displacement(const std::vector<GridElement>& elements, int e, const Vec3& X) const {
  Eigen::VectorXd N;
  Eigen::MatrixXd G;
  const int nn = static_cast<int>(node[e].size());
  shape_dynamic(elements[e].box, nn, X, N, G);
  Vec3 d = Vec3::Zero();
  for (int k = 0; k < nn; ++k) d += N(k) * u.segment<3>(3 * node[e][k]);
  return d;
}

LinearXfemResult solve_linear(const std::vector<GridElement>& elements,
                              const std::vector<std::array<int, 2>>& adjacent,
                              const ElasticMaterial& material,
                              const std::vector<DirichletCondition>& dirichlet,
                              const std::vector<TractionCondition>& tractions,
                              const LinearXfemOptions& options, const std::vector<PieceTie>& ties) {
  LinearXfemSolver solver;
  return solver.solve(elements, adjacent, material, dirichlet, tractions, options, ties);
}

std::vector<std::array<int, 2>> tied_nodes(const std::vector<GridElement>& elements,
                                           const std::vector<std::vector<int>>& node, const PieceTie& tie) {
  const int n = static_cast<int>(elements.size());
  PARAFAB_VERIFY(tie.element_a >= 0 && tie.element_a < n && tie.element_b >= 0 && tie.element_b < n,
                 "piece tie (" << tie.element_a << ", " << tie.element_b << ") out of range (" << n << " elements)");
  const int nn = static_cast<int>(node[tie.element_a].size());
  auto grid_node = [&](int e, int k) { return half_cell_position(elements[e], nn, k); };
  std::vector<std::array<int, 2>> pairs;
  for (int ka = 0; ka < nn; ++ka)
    for (int kb = 0; kb < nn; ++kb)
      if (grid_node(tie.element_a, ka) == grid_node(tie.element_b, kb) && node[tie.element_a][ka] != node[tie.element_b][kb])
        pairs.push_back({node[tie.element_a][ka], node[tie.element_b][kb]});
  return pairs;
}

std::vector<char> mode_tied(const std::vector<GridElement>& elements, const std::vector<PieceTie>& ties,
                            const ElasticMaterial& material, const LinearXfemOptions& options) {
  std::vector<char> tied(ties.size(), 0);
  if (options.element != ElementType::Hex8 || !options.incompatible_modes) return tied;
  const int n = static_cast<int>(elements.size());
  const Eigen::Matrix<double, 6, 6> D = elasticity(material);
  // As element_system decides (the pair's K_αα is then positive definite too: a mean other than
  // the rule's own only adds V (M − γ̄)(M − γ̄)ᵀ to the gradients' second moments).
  auto own_modes = [&](int e) { return incompatible_modes(elements[e], D, options.incompatible_min_fraction).used; };
  std::vector<int> uses(n, 0);
  for (size_t t = 0; t < ties.size(); ++t) {
    const PieceTie& tie = ties[t];
    PARAFAB_VERIFY(tie.element_a >= 0 && tie.element_a < n && tie.element_b >= 0 && tie.element_b < n,
                   "piece tie (" << tie.element_a << ", " << tie.element_b << ") out of range (" << n << " elements)");
    tied[t] = tie.weight > 0 && tie.element_a != tie.element_b &&
              elements[tie.element_a].cell == elements[tie.element_b].cell && own_modes(tie.element_a) &&
              own_modes(tie.element_b);
    if (tied[t]) ++uses[tie.element_a], ++uses[tie.element_b];
  }
  for (size_t t = 0; t < ties.size(); ++t)
    if (tied[t] && (uses[ties[t].element_a] > 1 || uses[ties[t].element_b] > 1)) tied[t] = 0;
  return tied;
}

Eigen::MatrixXd tied_mode_correction(const GridElement& a, const GridElement& b, const PieceTie& tie,
                                     const ElasticMaterial& material, const LinearXfemOptions& options) {
  const Eigen::Matrix<double, 6, 6> D = elasticity(material);
  const TiedModePair pair = tied_mode_pair(a, b, D, tie.weight, tie.blend);
  PARAFAB_VERIFY(pair.used, "the incompatible modes of pieces " << tie.element_a << " and " << tie.element_b
                                                                << " are singular together (tie weight " << tie.weight << ")");
  Eigen::Matrix<double, 18, 48> Kau = Eigen::Matrix<double, 18, 48>::Zero();
  Kau.block<9, 24>(0, 0) = pair.Kau[0], Kau.block<9, 24>(9, 24) = pair.Kau[1];
  Eigen::MatrixXd C = -Kau.transpose() * pair.Kaa.solve(Kau);
  const GridElement* el[2] = {&a, &b};
  for (int i = 0; i < 2; ++i) {
    const IncompatibleModes own = incompatible_modes(*el[i], D, options.incompatible_min_fraction);
    if (own.used) C.block<24, 24>(24 * i, 24 * i) += own.Kau.transpose() * own.Kaa.solve(own.Kau);
  }
  return 0.5 * (C + C.transpose());  // symmetric to round-off
}

TiedModeShapeTerms tied_mode_shape_terms(const std::vector<GridElement>& elements, const PieceTie& tie,
                                         const Eigen::VectorXd& ua, const Eigen::VectorXd& ub,
                                         const ElasticMaterial& material, const LinearXfemOptions& options, int side,
                                         const std::vector<Vec3>& points) {
  PARAFAB_VERIFY(side == 0 || side == 1, "tied_mode_shape_terms: side " << side << " (0 or 1)");
  PARAFAB_VERIFY(ua.size() == 24 && ub.size() == 24,
                 "tied_mode_shape_terms: " << ua.size() << " and " << ub.size() << " nodal values (hex8: 24)");
  PARAFAB_VERIFY(mode_tied(elements, {tie}, material, options)[0],
                 "tied_mode_shape_terms: tie (" << tie.element_a << ", " << tie.element_b << ") does not tie modes");
  const Eigen::Matrix<double, 6, 6> D = elasticity(material);
  const GridElement* el[2] = {&elements[tie.element_a], &elements[tie.element_b]};
  const Eigen::VectorXd* u[2] = {&ua, &ub};
  const TiedModePair pair = tied_mode_pair(*el[0], *el[1], D, tie.weight, tie.blend);
  PARAFAB_VERIFY(pair.used, "tied_mode_shape_terms: the modes of pieces " << tie.element_a << " and " << tie.element_b
                                                                          << " are singular together");
  const TiedModeState st = tied_mode_state(pair, el, u, D);
  TiedModeShapeTerms r;
  r.d_weight = (st.alpha.head<9>() - st.alpha.tail<9>()).squaredNorm();
  for (int i = 0; i < 2; ++i) r.d_blend -= st.T[i].dot(pair.pair_mean - pair.own_mean[i]);
  // Moving a weight w(X) of piece i moves M_i by (γ(X) − M_i)/V_i and M_ab by (γ(X) − M_ab)/V_ab.
  const int i = side, j = 1 - side;
  const double theta = tie.blend;
  r.density.resize(points.size());
  for (size_t k = 0; k < points.size(); ++k) {
    const Vec3& X = points[k];
    const Eigen::Matrix<double, 6, 1> e = tied_mode_strain(*el[i], *u[i], pair.mean[i], st.alpha.segment<9>(9 * i), X);
    const Vec3 g = IncompatibleModes::gradient(el[i]->box, X);
    const Vec3 to_own = (g - pair.own_mean[i]) / pair.volume[i], to_pair = (g - pair.pair_mean) / pair.pair_volume;
    r.density[k] = e.dot(D * e) - st.T[i].dot((1 - theta) * to_own + theta * to_pair) - st.T[j].dot(theta * to_pair);
  }
  return r;
}

namespace {

// Identity of an element across solves: its cell and two independent 64-bit hashes of every
// input of element_system but the material and options (box, rule, and for boundary terms the
// patches, their surfaces and the conditions on their faces).
struct ElementKey {
  std::array<int, 3> cell{0, 0, 0};
  uint64_t h1 = 0, h2 = 0;
  bool usable = true;  ///< false: a Dirichlet condition given by a function (not comparable)
  bool operator==(const ElementKey& o) const { return cell == o.cell && h1 == o.h1 && h2 == o.h2; }
};
struct ElementKeyHash {
  size_t operator()(const ElementKey& k) const { return static_cast<size_t>(k.h1 ^ (k.h2 << 1)); }
};

ElementKey element_key(const GridElement& el, const std::vector<DirichletCondition>& dirichlet,
                       const std::vector<TractionCondition>& tractions) {
  ElementKey k;
  k.cell = el.cell;
  BitHash h;
  h.add(el.box.min), h.add(el.box.max);
  h.add(static_cast<uint64_t>(el.rule.points.size()));
  for (const Vec3& p : el.rule.points) h.add(p);
  for (double w : el.rule.weights) h.add(w);
  h.add(static_cast<uint64_t>(el.subvolume != nullptr));
  h.add(el.switch_fraction);  // frozen switches may change the element matrix (incompatible modes)
  if (el.subvolume)
    for (const CutPatch& patch : el.subvolume->patches) {
      if (patch.source_face < 0) continue;
      // The conditions element_system applies on this patch (the last one given per face).
      const DirichletCondition* dc = nullptr;
      for (const auto& d : dirichlet) if (d.face == patch.source_face) dc = &d;
      const TractionCondition* tc = nullptr;
      for (const auto& t : tractions) if (t.face == patch.source_face) tc = &t;
      if (!dc && !tc) continue;
      h.add(static_cast<uint64_t>(patch.source_face));
      h.add(static_cast<uint64_t>(static_cast<int64_t>(patch.orientation)));
      h.add(static_cast<uint64_t>(reinterpret_cast<uintptr_t>(patch.surface.get())));
      for (const BoundaryLoop& loop : patch.loops) {
        h.add(static_cast<uint64_t>(loop.order));
        h.add(static_cast<uint64_t>(loop.points.size()));
        for (const Vec2& p : loop.points) h.add(p.x()), h.add(p.y());
      }
      if (dc) {
        if (dc->field) k.usable = false;
        for (int i = 0; i < 9; ++i) h.add(dc->gradient(i));
        h.add(dc->offset), h.add(dc->components);
      } else {
        h.add(uint64_t(0xd1));
      }
      if (tc) h.add(tc->traction);
      else h.add(uint64_t(0x7c));
    }
  k.h1 = h.h1, k.h2 = h.h2;
  return k;
}

// The inputs of element_system besides the element and its conditions.
bool same_element_inputs(const ElasticMaterial& a, const LinearXfemOptions& x, const ElasticMaterial& b,
                         const LinearXfemOptions& y) {
  return a.youngs_modulus == b.youngs_modulus && a.poisson_ratio == b.poisson_ratio && a.density == b.density &&
         x.element == y.element && x.nitsche_beta == y.nitsche_beta && x.nitsche_penalty == y.nitsche_penalty &&
         x.nitsche_local_factor == y.nitsche_local_factor && x.nitsche_local_floor == y.nitsche_local_floor &&
         x.gravity == y.gravity &&
         x.surface_degree == y.surface_degree && x.dirichlet_surface_degree == y.dirichlet_surface_degree &&
         x.incompatible_modes == y.incompatible_modes &&
         x.incompatible_min_fraction == y.incompatible_min_fraction;
}

}  // namespace

// What the last solve leaves for the next one.
struct LinearXfemSolver::Previous {
  ElasticMaterial material;
  LinearXfemOptions options;
  std::unordered_map<ElementKey, int, ElementKeyHash> element_of;  ///< key → element (unique keys only)
  std::vector<std::shared_ptr<const ElementSystem>> systems;       ///< per element; null for interior copies
  std::vector<std::shared_ptr<const SurfaceMap>> surfaces;          ///< kept alive: their addresses are in keys
  std::vector<std::vector<int>> node;  ///< DOF nodes per element
  std::vector<int> reduced;            ///< DOF node → reduced node (−1: aggregated)
  std::vector<int> factor_of;          ///< reduced DOF → DOF of the factorized system (−1: none)
  Eigen::VectorXd u_reduced;           ///< the reduced solution
  std::shared_ptr<const Eigen::SparseMatrix<double>> factored;  ///< the matrix cholesky_ factorized
};

namespace {

// LinearXfemOptions::Solver: which solver takes a reduced system of n unknowns.
bool use_petsc(const LinearXfemOptions::Solver& solver, int n) {
  using Type = LinearXfemOptions::Solver::Type;
  if (solver.type == Type::Cholmod) return false;
  if (solver.type == Type::Petsc) return true;  // PetscSystem says so when the build has none
  return (n >= solver.petsc_from || launched_ranks() > 1) && petsc_available();
}

// The reduced system by PETSc's Krylov solver: r.u (reduced), r.solved, r.iterative and the
// solve's figures in r.solve_info. `reduced`: DOF node → reduced node (−1: floating).
void solve_by_petsc(const std::vector<GridElement>& elements, LinearXfemResult& r, const std::vector<int>& reduced,
                    const Eigen::SparseMatrix<double>& K, const Eigen::VectorXd& f, const KrylovOptions& krylov) {
  const auto t0 = std::chrono::steady_clock::now();
  SolveInfo& info = r.solve_info;
  info.method = "petsc";
  info.krylov = krylov.ksp + "+" + krylov.pc;
  std::vector<Vec3> position(K.rows() / 3, Vec3::Zero());
  for (size_t e = 0; e < elements.size(); ++e) {
    const int nn = static_cast<int>(r.node[e].size());
    for (int k = 0; k < nn; ++k)
      if (const int j = reduced[r.node[e][k]]; j >= 0) position[j] = node_position(elements[e].box, nn, k);
  }
  auto system = std::make_shared<PetscSystem>(K, position, krylov);
  const KrylovResult res = system->solve(f);
  info.iterations = res.iterations;
  info.residual = res.residual;
  info.ranks = system->ranks();
  info.petsc_copy_seconds = system->create_seconds;
  info.petsc_setup_seconds = system->setup_seconds;
  info.petsc_memory_mb = system->memory_mb;
  info.petsc_seconds = seconds_since(t0);
  if (!res.converged) {
    // CG breaks down on a matrix that is not positive definite, which a sliver cut cell under the
    // fixed Nitsche penalty can make (CHOLMOD then falls back to LU and says so).
    const bool indefinite = res.reason.find("INDEFINITE") != std::string::npos || res.reason == "DIVERGED_PC_FAILED";
    r.message = "the PETSc solve (" + info.krylov + ") did not converge: " + res.reason + " after " +
                std::to_string(res.iterations) + " iterations, residual " + std::to_string(res.residual) +
                (indefinite ? "; the stiffness matrix is probably not positive definite (a sliver cut cell under the "
                              "fixed Nitsche penalty: try \"nitsche_penalty\": \"local\"), or"
                            : "; try a looser \"rtol\", or") +
                " \"solver\": {\"type\": \"cholmod\"}";
    return;
  }
  r.u = res.x;
  r.solved = r.u.allFinite();
  if (r.solved) r.iterative = std::move(system);
}

}  // namespace

LinearXfemSolver::LinearXfemSolver() : cholesky_(std::make_shared<SparseCholesky>()) {}
LinearXfemSolver::~LinearXfemSolver() = default;

void LinearXfemSolver::clear() { previous_.reset(); }

const ElementSystem* LinearXfemSolver::element_system(int e) const {
  if (!previous_ || e < 0 || e >= static_cast<int>(previous_->systems.size())) return nullptr;
  return previous_->systems[e].get();
}

LinearXfemResult LinearXfemSolver::solve(const std::vector<GridElement>& elements,
                                         const std::vector<std::array<int, 2>>& adjacent,
                                         const ElasticMaterial& material,
                                         const std::vector<DirichletCondition>& dirichlet,
                                         const std::vector<TractionCondition>& tractions,
                                         const LinearXfemOptions& options, const std::vector<PieceTie>& ties) {
  LinearXfemResult r;
  const auto t_start = std::chrono::steady_clock::now();
  auto t0 = t_start;
  int count = 0;
  r.node = number_dof_nodes(elements, adjacent, count, options.element);
  r.dofs = 3 * count;
  r.elements = static_cast<int>(elements.size());
  for (const auto& e : elements) r.cut_elements += e.subvolume != nullptr;
  const int n = static_cast<int>(elements.size());
  // Elements of the previous solve equal to these (by key).
  auto next = std::make_unique<Previous>();
  next->material = material;
  next->options = options;
  std::vector<ElementKey> keys(n);
  tbb::parallel_for(tbb::blocked_range<int>(0, n, 256), [&](const tbb::blocked_range<int>& b) {
    for (int e = b.begin(); e != b.end(); ++e) keys[e] = element_key(elements[e], dirichlet, tractions);
  });
  std::vector<int> matched(n, -1);
  if (previous_)
    for (int e = 0; e < n; ++e) {
      auto it = previous_->element_of.find(keys[e]);
      if (it != previous_->element_of.end() && previous_->node[it->second].size() == r.node[e].size()) matched[e] = it->second;
    }
  {
    std::unordered_map<ElementKey, int, ElementKeyHash> of;
    std::vector<char> duplicate(n, 0);
    for (int e = 0; e < n; ++e) {
      auto [it, fresh] = of.emplace(keys[e], e);
      if (!fresh) duplicate[e] = duplicate[it->second] = 1;
    }
    for (int e = 0; e < n; ++e)
      if (duplicate[e]) of.erase(keys[e]), matched[e] = -1;
    next->element_of = std::move(of);
  }
  r.number_seconds = seconds_since(t0);
  const bool cache = options.reuse.elements;
  const bool same_inputs = previous_ && same_element_inputs(material, options, previous_->material, previous_->options);
  next->systems.resize(n);
  // Element systems: uncut interior cells of one shape point to one integrated matrix, elements
  // equal to one of the previous solve (by key) to its system, the rest are integrated (TBB).
  t0 = std::chrono::steady_clock::now();
  const int reference = first_interior_element(elements);
  ElementSystem reference_system;
  if (reference >= 0) reference_system = xfem::element_system(elements[reference], material, dirichlet, tractions, options, true);
  std::vector<const ElementSystem*> system_of(n, nullptr);
  std::vector<std::shared_ptr<const ElementSystem>> integrated(n);
  std::atomic<int> cached{0}, copies{0};
  tbb::parallel_for(tbb::blocked_range<int>(0, n, 16), [&](const tbb::blocked_range<int>& range) {
    for (int e = range.begin(); e != range.end(); ++e) {
      if (reference >= 0 && (e == reference || same_uncut_shape(elements[reference], elements[e]))) {
        system_of[e] = &reference_system;
        if (e != reference) ++copies;
        continue;
      }
      if (cache && same_inputs && matched[e] >= 0 && keys[e].usable)
        if (const auto& s = previous_->systems[matched[e]]) {
          next->systems[e] = s;
          system_of[e] = s.get();
          ++cached;
          continue;
        }
      integrated[e] = std::make_shared<const ElementSystem>(
          xfem::element_system(elements[e], material, dirichlet, tractions, options, true));
      system_of[e] = integrated[e].get();
      if (cache && keys[e].usable) next->systems[e] = integrated[e];
    }
  });
  r.integrate_seconds = seconds_since(t0);
  r.reused_element_matrices = copies;
  r.cached_element_matrices = cached;
  if (cache)
    for (const auto& el : elements)
      if (el.subvolume)
        for (const CutPatch& p : el.subvolume->patches)
          if (p.source_face >= 0 && p.surface) next->surfaces.push_back(p.surface);
  // Aggregation (T: floating DOF nodes follow a normal neighbour), then Tᵀ K T and Tᵀ f straight
  // from the element systems (no K, no sparse triple product).
  t0 = std::chrono::steady_clock::now();
  Eigen::SparseMatrix<double> T = aggregation_map(elements, adjacent, r.node, count, options.aggregation_fraction,
                                                  &r.aggregated_nodes, &next->reduced);
  r.aggregate_seconds = seconds_since(t0);
  t0 = std::chrono::steady_clock::now();
  const int reduced_count = static_cast<int>(T.cols() / 3);
  // Ties (Eq. 6.24) on a floating node paired with an unknown one: that row of T blended towards
  // the unknown (see PieceTie).
  if (!ties.empty() && r.aggregated_nodes > 0) {
    std::map<int, std::pair<int, double>> towards;  // floating DOF node → (unknown DOF node, θ)
    for (const PieceTie& tie : ties) {
      if (!(tie.blend > 0)) continue;
      PARAFAB_VERIFY(tie.blend <= 1, "piece tie blend " << tie.blend);
      for (const auto& [ia, ib] : tied_nodes(elements, r.node, tie)) {
        const bool fa = next->reduced[ia] < 0, fb = next->reduced[ib] < 0;
        if (fa == fb) continue;
        const int floating = fa ? ia : ib, unknown = fa ? ib : ia;
        auto [it, fresh] = towards.emplace(floating, std::pair{unknown, tie.blend});
        if (!fresh && tie.blend > it->second.second) it->second = {unknown, tie.blend};  // the strongest tie
      }
    }
    if (!towards.empty()) {
      Eigen::SparseMatrix<double, Eigen::RowMajor> rows(T);
      std::vector<Eigen::Triplet<double>> trip;
      for (int i = 0; i < rows.outerSize(); ++i) {
        const auto it = towards.find(i / 3);
        const double keep = it == towards.end() ? 1.0 : 1 - it->second.second;
        for (Eigen::SparseMatrix<double, Eigen::RowMajor>::InnerIterator x(rows, i); x; ++x)
          if (keep != 0) trip.emplace_back(i, static_cast<int>(x.col()), keep * x.value());
        if (it != towards.end()) trip.emplace_back(i, 3 * next->reduced[it->second.first] + i % 3, it->second.second);
      }
      T.setFromTriplets(trip.begin(), trip.end());
      r.blended_nodes = static_cast<int>(towards.size());
    }
  }
  ReducedSystem assembled = assemble_reduced(system_of, r.node, next->reduced, reduced_count, T);
  if (!ties.empty()) {  // Eq. 6.24: + Σ w‖x_a − x_b‖², rows √w (e_a − e_b) per component, through T
    std::vector<Eigen::Triplet<double>> rows;
    int m = 0;
    for (const PieceTie& tie : ties) {
      PARAFAB_VERIFY(tie.weight >= 0 && std::isfinite(tie.weight), "piece tie weight " << tie.weight);
      if (tie.weight == 0) continue;
      const double w = std::sqrt(tie.weight);
      for (const auto& [ia, ib] : tied_nodes(elements, r.node, tie)) {
        // Floating (aggregated) nodes follow their hosts' fields: a tie on them would couple two
        // hosts' extrapolations (on the turned bracket's join of two small pieces the jump grew
        // from 3.6e-4 to 2.5e-2 relative), where the joined piece follows one host.
        if (next->reduced[ia] < 0 || next->reduced[ib] < 0) continue;
        ++r.tied_node_pairs;
        for (int d = 0; d < 3; ++d, ++m) rows.emplace_back(m, 3 * ia + d, w), rows.emplace_back(m, 3 * ib + d, -w);
      }
    }
    if (m > 0) {
      Eigen::SparseMatrix<double> D(m, 3 * count);
      D.setFromTriplets(rows.begin(), rows.end());
      const Eigen::SparseMatrix<double> DT = T.rows() > 0 ? Eigen::SparseMatrix<double>(D * T) : D;
      assembled.K += Eigen::SparseMatrix<double>(DT.transpose() * DT);
    }
    // Pieces of one cell: their modes condensed jointly (TiedModePair) in place of each piece's
    // own, i.e. + (joint − own_a − own_b) on their 16 nodes, through T.
    const std::vector<char> modes = mode_tied(elements, ties, material, options);
    std::vector<Eigen::Triplet<double>> correction;
    for (size_t t = 0; t < ties.size(); ++t) {
      if (!modes[t]) continue;
      const PieceTie& tie = ties[t];
      const Eigen::MatrixXd C = tied_mode_correction(elements[tie.element_a], elements[tie.element_b], tie, material, options);
      int dof[48];
      for (int i = 0; i < 2; ++i)
        for (int k = 0; k < 8; ++k)
          for (int d = 0; d < 3; ++d) dof[24 * i + 3 * k + d] = 3 * r.node[i == 0 ? tie.element_a : tie.element_b][k] + d;
      for (int x = 0; x < 48; ++x)
        for (int y = 0; y < 48; ++y) correction.emplace_back(dof[x], dof[y], C(x, y));
      ++r.mode_tied_pairs;
    }
    if (!correction.empty()) {
      Eigen::SparseMatrix<double> C(3 * count, 3 * count);
      C.setFromTriplets(correction.begin(), correction.end());
      assembled.K += T.rows() > 0 ? Eigen::SparseMatrix<double>(T.transpose() * C * T) : C;
    }
  }
  // K is shared by the factorization, the preconditioner and the next solve's comparison, never
  // copied (a hex27 system of 10⁴ unknowns holds ~50 MB).
  const auto K = std::make_shared<const Eigen::SparseMatrix<double>>(std::move(assembled.K));
  const Eigen::VectorXd f = std::move(assembled.f);
  if (r.aggregated_nodes > 0) {
    r.aggregation = std::move(T);
    r.floating.resize(count);
    for (int i = 0; i < count; ++i) r.floating[i] = next->reduced[i] < 0;
  }
  r.scatter_seconds = seconds_since(t0);
  r.assemble_seconds = seconds_since(t_start);
  t0 = std::chrono::steady_clock::now();
  const int nr = static_cast<int>(K->rows());
  SolveInfo& info = r.solve_info;
  bool iterative = use_petsc(options.solver, nr);
  bool after_petsc = false;
  if (iterative) {
    solve_by_petsc(elements, r, next->reduced, *K, f, options.solver.krylov);
    // Auto: where the Krylov solve fails, the factorization (with its exact memory check).
    if (!r.solved && options.solver.type == LinearXfemOptions::Solver::Type::Auto) {
      info.fallback = r.message;
      r.message.clear();
      iterative = false, after_petsc = true;
    }
  }
  // CG preconditioned by the last factorization, DOFs matched through equal elements.
  bool tried = false;
  if (!iterative && options.reuse.factorization && previous_ && previous_->factored &&
      cholesky_->status() == SparseCholesky::Status::Factorized) {
    const Previous& p = *previous_;
    std::vector<int> prev_node(count, -1);  // DOF node → DOF node of the previous solve (−2: ambiguous)
    for (int e = 0; e < n; ++e) {
      if (matched[e] < 0) continue;
      const auto& pn = p.node[matched[e]];
      for (size_t k = 0; k < pn.size(); ++k) {
        int& m = prev_node[r.node[e][k]];
        if (m == -1) m = pn[k];
        else if (m != pn[k]) m = -2;
      }
    }
    std::vector<int> old_of(nr, -1);
    std::vector<char> taken(p.factored->rows(), 0);
    Eigen::VectorXd x0 = Eigen::VectorXd::Zero(nr);
    for (int i = 0; i < count; ++i) {
      const int j = next->reduced[i], pi = prev_node[i];
      if (j < 0 || pi < 0) continue;
      const int pj = p.reduced[pi];
      if (pj < 0) continue;
      for (int d = 0; d < 3; ++d) {
        x0(3 * j + d) = p.u_reduced(3 * pj + d);
        const int f = p.factor_of[3 * pj + d];
        if (f < 0 || taken[f]) continue;
        taken[f] = 1;
        old_of[3 * j + d] = f;
      }
    }
    int mapped = 0;
    for (int f : old_of) mapped += f >= 0;
    if (mapped < options.reuse.min_mapped * nr) {
      info.fallback = std::to_string(mapped) + " of " + std::to_string(nr) +
                      " unknowns are unknowns of the factorized system (fewer than " +
                      std::to_string(options.reuse.min_mapped) + " of them)";
    } else {
      try {
        auto rf = std::make_shared<ReusedFactorization>(cholesky_, *p.factored, K, old_of, options.reuse.preconditioner);
        info.mapped_dofs = rf->mapped_dofs(), info.changed_dofs = rf->changed_dofs(), info.local_dofs = rf->local_dofs();
        info.pcg_setup_seconds = rf->setup_seconds;
        tried = true;
        PcgResult pcg = rf->solve(f, x0, options.reuse.pcg);
        info.iterations = pcg.iterations;
        info.residual = pcg.residual;
        if (pcg.converged) {
          info.method = "pcg";
          r.u = std::move(pcg.x);
          r.solved = r.u.allFinite();
          r.preconditioned = rf;
          r.pcg = options.reuse.pcg;
          next->factor_of = old_of;
          next->factored = p.factored;
        } else {
          info.fallback = "CG did not converge: " + pcg.message;
        }
      } catch (const Error& e) {
        info.fallback = std::string("no preconditioner: ") + e.what();
      }
    }
    info.pcg_seconds = seconds_since(t0);
  }
  if (!r.solved && !iterative) {
    const auto tf = std::chrono::steady_clock::now();
    if (tried) info.method = "cholesky after pcg";
    if (after_petsc) info.method = "cholesky after petsc";
    // Another pattern: a new factorization object (results and preconditioners sharing the old
    // one keep it); the same pattern: factorized again in place, reusing the analysis.
    if (cholesky_->status() != SparseCholesky::Status::Empty && !cholesky_->same_pattern(*K)) {
      auto fresh = std::make_shared<SparseCholesky>();
      fresh->analyses = cholesky_->analyses, fresh->factorizations = cholesky_->factorizations;
      fresh->analyze_seconds = cholesky_->analyze_seconds, fresh->factorize_seconds = cholesky_->factorize_seconds;
      cholesky_ = std::move(fresh);
    }
    SparseCholesky& chol = *cholesky_;
    if (options.memory_limit_mb > 0) chol.memory_limit_mb = options.memory_limit_mb;
    chol.factorize(K);
    if (chol.IsDone()) {
      // Cholesky: two steps of iterative refinement; the LU fallback solves once, as before.
      r.u = chol.solve(f, chol.status() == SparseCholesky::Status::Factorized ? 2 : 0);
      r.solved = r.u.allFinite();
      r.indefinite = chol.status() == SparseCholesky::Status::FactorizedByLU;
      if (r.indefinite)
        r.message = options.nitsche_penalty == LinearXfemOptions::NitschePenalty::Fixed
                        ? "stiffness matrix not positive definite (Nitsche β too small for some cut cell: try "
                          "\"nitsche_penalty\": \"local\"; or too few supports); solved by LU"
                        : "stiffness matrix not positive definite (the local Nitsche penalty's floor on a sliver "
                          "cut cell, or too few supports); solved by LU";
    }
    if (!r.solved) r.message = "stiffness matrix singular: is the part supported (Dirichlet faces)?";
    if (r.solved) {
      r.factorization = cholesky_;
      const double fn = f.norm();
      info.residual = fn > 0 ? (f - *K * r.u).norm() / fn : 0.0;
      next->factor_of.resize(nr);
      std::iota(next->factor_of.begin(), next->factor_of.end(), 0);
      next->factored = K;
    }
    info.factorize_seconds = seconds_since(tf);
  }
  r.solve_seconds = seconds_since(t0);
  if (r.solved) {
    r.energy = 0.5 * r.u.dot(*K * r.u) - f.dot(r.u);
    next->u_reduced = r.u;
    if (r.aggregated_nodes > 0) r.u = r.aggregation * r.u;  // back to every DOF node (aggregated ones extrapolated)
    next->node = r.node;
    previous_ = std::move(next);
  } else {
    previous_.reset();
  }
  return r;
}

Eigen::VectorXd LinearXfemResult::solve_again(const Eigen::VectorXd& f) const {
  PARAFAB_VERIFY(f.size() == dofs, "solve_again: load vector of size " << f.size() << ", expected " << dofs);
  if (iterative) {
    const Eigen::VectorXd fr = aggregation.size() == 0 ? f : Eigen::VectorXd(aggregation.transpose() * f);
    const KrylovResult res = iterative->solve(fr);
    PARAFAB_VERIFY(res.converged, "solve_again: the PETSc solve did not converge (" << res.reason << ", residual "
                                                                                 << res.residual << ")");
    return aggregation.size() == 0 ? res.x : Eigen::VectorXd(aggregation * res.x);
  }
  if (preconditioned) {
    const Eigen::VectorXd fr = aggregation.size() == 0 ? f : Eigen::VectorXd(aggregation.transpose() * f);
    const PcgResult res = preconditioned->solve(fr, Eigen::VectorXd(), pcg);
    PARAFAB_VERIFY(res.converged, "solve_again: CG with the reused factorization did not converge: " << res.message);
    return aggregation.size() == 0 ? res.x : Eigen::VectorXd(aggregation * res.x);
  }
  PARAFAB_VERIFY(factorization && factorization->IsDone(), "solve_again: the linear solve kept no factorization");
  const int refine = factorization->status() == SparseCholesky::Status::Factorized ? 2 : 0;
  if (aggregation.size() == 0) return factorization->solve(f, refine);
  return aggregation * factorization->solve(aggregation.transpose() * f, refine);
}

namespace {

// The discrete decisions of aggregation: small elements (fraction below `fraction`) and the
// host of each (its largest normal face neighbour, -1 if none), from the switching fractions
// (switches = true) or the rules' own (false).
struct AggregationSwitches {
  std::vector<char> small;
  std::vector<int> host;
};

AggregationSwitches aggregation_switches(const std::vector<GridElement>& elements,
                                         const std::vector<std::array<int, 2>>& adjacent, double fraction, bool chain,
                                         bool switches) {
  const int n = static_cast<int>(elements.size());
  AggregationSwitches sw;
  sw.small.assign(n, 0);
  std::vector<double> phi(n);
  for (int e = 0; e < n; ++e) {
    phi[e] = switches ? switching_fraction(elements[e]) : volume_fraction(elements[e]);
    sw.small[e] = fraction > 0 && phi[e] < fraction;
  }
  const std::vector<char>& small = sw.small;
  std::vector<int>& host = sw.host;  // the largest normal neighbour of every small element
  host.assign(n, -1);
  std::vector<double> host_volume(n, 0);
  for (const auto& [a, b] : adjacent)
    for (const auto& [s, o] : {std::pair<int, int>{a, b}, std::pair<int, int>{b, a}}) {
      if (!small[s] || small[o]) continue;
      const double v = phi[o] * elements[o].box.volume();
      if (v > host_volume[s]) host_volume[s] = v, host[s] = o;
    }
  // Small elements whose face neighbours are all small (corner slivers where two cut faces meet
  // a grid plane) take the host of a small neighbour that has one, level by level. Hex27 only:
  // there such floating slivers left CHOLMOD an indefinite matrix; for hex8 the chained host
  // made the Newton solve of the turned bracket stall at a residual of 3e-6 (without it: 1e-8
  // in 6 iterations, XfemParallel.NewtonIdenticalForOneAndTwoThreads), so hex8 keeps the
  // slivers' own DOFs as before.
  for (bool changed = chain; changed;) {
    changed = false;
    std::vector<int> next = host;
    for (const auto& [a, b] : adjacent)
      for (const auto& [s, o] : {std::pair<int, int>{a, b}, std::pair<int, int>{b, a}})
        if (small[s] && small[o] && host[s] < 0 && host[o] >= 0 && host_volume[o] > host_volume[s])
          next[s] = host[o], host_volume[s] = host_volume[o], changed = true;
    host = std::move(next);
  }
  return sw;
}

}  // namespace

double volume_fraction(const GridElement& element) {
  double v = 0;
  for (double w : element.rule.weights) v += w;
  return v / element.box.volume();
}

Box3 rule_frame(const GridElement& element) { return element.frame ? *element.frame : rule_box(element); }

Box3 rule_box(const GridElement& element) {
  const size_t n = element.rule.points.size();
  if (n == 0) return element.box;  // a failed rule (GridModel::rule_failures): nothing to integrate
  const int per = static_cast<int>(std::lround(std::cbrt(static_cast<double>(n))));
  PARAFAB_VERIFY(per >= 2 && static_cast<size_t>(per) * per * per == n,
                 "rule_box: a rule of " << n << " points is not a tensor Gauss rule of at least 2³ points");
  const QuadratureRule1& g = gauss_legendre(per);
  const double t0 = g.points.front(), t1 = g.points.back();
  Box3 b;
  const Vec3 size = (element.rule.points.back() - element.rule.points.front()) / (t1 - t0);
  b.min = element.rule.points.front() - t0 * size;
  b.max = b.min + size;
  return b;
}

bool switches_match_own_fractions(const std::vector<GridElement>& elements,
                                  const std::vector<std::array<int, 2>>& adjacent, const LinearXfemOptions& options) {
  bool any = false;
  for (const GridElement& el : elements) any = any || el.switch_fraction >= 0;
  if (!any) return true;
  const bool chain = options.element == ElementType::Hex27;
  const AggregationSwitches a = aggregation_switches(elements, adjacent, options.aggregation_fraction, chain, true);
  const AggregationSwitches b = aggregation_switches(elements, adjacent, options.aggregation_fraction, chain, false);
  if (a.small != b.small || a.host != b.host) return false;
  if (options.element == ElementType::Hex8 && options.incompatible_modes)
    for (const GridElement& el : elements)
      if ((switching_fraction(el) > options.incompatible_min_fraction) !=
          (volume_fraction(el) > options.incompatible_min_fraction))
        return false;
  return true;
}

Eigen::SparseMatrix<double> aggregation_map(const std::vector<GridElement>& elements,
                                            const std::vector<std::array<int, 2>>& adjacent,
                                            const std::vector<std::vector<int>>& node, int count,
                                            double fraction, int* aggregated, std::vector<int>* reduced_out) {
  // Small elements: volume fraction below `fraction`. A DOF node all of whose elements are
  // small is "floating" (barely stiff): it follows the field of a normal neighbour.
  const int n = static_cast<int>(elements.size());
  const bool chain = !node.empty() && node.front().size() == 27;
  const AggregationSwitches sw = aggregation_switches(elements, adjacent, fraction, chain, true);
  const std::vector<char>& small = sw.small;
  const std::vector<int>& host = sw.host;
  std::vector<char> supported(count, 0);
  for (int e = 0; e < n; ++e)
    if (!small[e]) for (int k : node[e]) supported[k] = 1;
  std::vector<int> reduced(count, -1);
  int m = 0;
  std::vector<std::array<int, 2>> source(count, {-1, -1});  // (small element, its node) of a floating DOF node
  for (int e = 0; e < n; ++e)
    if (small[e] && host[e] >= 0)
      for (int k = 0; k < static_cast<int>(node[e].size()); ++k)
        if (!supported[node[e][k]] && source[node[e][k]][0] < 0) source[node[e][k]] = {e, k};
  for (int i = 0; i < count; ++i)
    if (source[i][0] < 0) reduced[i] = m++;
  std::vector<Eigen::Triplet<double>> trip;
  Eigen::VectorXd N;
  Eigen::MatrixXd G;
  int agg = 0;
  for (int i = 0; i < count; ++i) {
    if (reduced[i] >= 0) {
      for (int d = 0; d < 3; ++d) trip.emplace_back(3 * i + d, 3 * reduced[i] + d, 1.0);
      continue;
    }
    ++agg;
    const auto [e, k] = source[i];
    const int h = host[e];
    const int nh = static_cast<int>(node[h].size());
    // Extrapolation of the host's field to the node's position in the small cell.
    shape_dynamic(elements[h].box, nh, node_position(elements[e].box, static_cast<int>(node[e].size()), k), N, G);
    for (int j = 0; j < nh; ++j)
      for (int d = 0; d < 3; ++d) trip.emplace_back(3 * i + d, 3 * reduced[node[h][j]] + d, N(j));
  }
  if (aggregated) *aggregated = agg;
  if (reduced_out) *reduced_out = reduced;
  Eigen::SparseMatrix<double> T(3 * count, 3 * m);
  T.setFromTriplets(trip.begin(), trip.end());
  return T;
}

}  // namespace parafab::xfem

namespace parafab::xfem {

Eigen::Matrix<double, 6, 1> stress_at(const LinearXfemResult& result, const std::vector<GridElement>& elements,
                                      const ElasticMaterial& material, int e, const Vec3& X) {
  return stress_from_gradient(material, displacement_gradient(result, elements, e, X));
}

double von_mises(const Eigen::Matrix<double, 6, 1>& s) {
  return std::sqrt(0.5 * ((s(0) - s(1)) * (s(0) - s(1)) + (s(1) - s(2)) * (s(1) - s(2)) +
                          (s(2) - s(0)) * (s(2) - s(0))) +
                   3 * (s(3) * s(3) + s(4) * s(4) + s(5) * s(5)));
}

}  // namespace parafab::xfem

namespace parafab::xfem {

Eigen::Matrix3d displacement_gradient(const LinearXfemResult& result, const std::vector<GridElement>& elements,
                                      int e, const Vec3& X) {
  Eigen::VectorXd N;
  Eigen::MatrixXd G;
  const int nn = static_cast<int>(result.node[e].size());
  shape_dynamic(elements[e].box, nn, X, N, G);
  Eigen::Matrix3d H = Eigen::Matrix3d::Zero();
  for (int k = 0; k < nn; ++k) H += result.u.segment<3>(3 * result.node[e][k]) * G.row(k);
  return H;
}

namespace {
template <int NN>
void displacement_and_gradient_n(const LinearXfemResult& result, const GridElement& el, const std::vector<int>& node,
                                 const std::vector<Vec3>& X, std::vector<Vec3>& u, std::vector<Eigen::Matrix3d>& H) {
  Eigen::Matrix<double, 3, NN> U;
  for (int k = 0; k < NN; ++k) U.col(k) = result.u.segment<3>(3 * node[k]);
  Eigen::Matrix<double, NN, 1> N;
  Eigen::Matrix<double, NN, 3> G;
  for (size_t i = 0; i < X.size(); ++i) {
    shape<NN>(el.box, X[i], N, G);
    u[i] = U * N;
    H[i] = U * G;
  }
}
}  // namespace

void displacement_at(const LinearXfemResult& result, const std::vector<GridElement>& elements, int e,
                     const std::vector<Vec3>& X, std::vector<Vec3>& u) {
  const auto& node = result.node[e];
  const int nodes = static_cast<int>(node.size());
  PARAFAB_VERIFY(nodes == 8 || nodes == 27, "element " << e << " with " << nodes << " nodes (8 or 27 expected)");
  const Box3& box = elements[e].box;
  const Vec3 h = box.size();
  u.resize(X.size());
  for (size_t p = 0; p < X.size(); ++p) {
    const Vec3 xi = (X[p] - box.min).cwiseQuotient(h);
    Vec3 sum = Vec3::Zero();
    if (nodes == 8) {  // the values of trilinear_shape
      for (int k = 0; k < 8; ++k) {
        const double fx = (k & 1) ? xi.x() : 1 - xi.x(), fy = (k & 2) ? xi.y() : 1 - xi.y(), fz = (k & 4) ? xi.z() : 1 - xi.z();
        sum += (fx * fy * fz) * result.u.segment<3>(3 * node[k]);
      }
    } else {  // the values of triquadratic_shape
      double L[3][3];
      for (int d = 0; d < 3; ++d) quadratic_lagrange(xi[d], L[d]);
      for (int l = 0; l < 3; ++l)
        for (int j = 0; j < 3; ++j)
          for (int i = 0; i < 3; ++i)
            sum += (L[0][i] * L[1][j] * L[2][l]) * result.u.segment<3>(3 * node[i + 3 * j + 9 * l]);
    }
    u[p] = sum;
  }
}

void displacement_and_gradient(const LinearXfemResult& result, const std::vector<GridElement>& elements, int e,
                               const std::vector<Vec3>& X, std::vector<Vec3>& u, std::vector<Eigen::Matrix3d>& H) {
  const auto& node = result.node[e];
  u.resize(X.size());
  H.resize(X.size());
  if (node.size() == 27) displacement_and_gradient_n<27>(result, elements[e], node, X, u, H);
  else {
    PARAFAB_VERIFY(node.size() == 8, "element " << e << " with " << node.size() << " nodes (8 or 27 expected)");
    displacement_and_gradient_n<8>(result, elements[e], node, X, u, H);
  }
}

FieldBounds field_bounds(const LinearXfemResult& result, const std::vector<GridElement>& elements, int e,
                         const ElasticMaterial* material) {
  const auto& node = result.node[e];
  const int nodes = static_cast<int>(node.size());
  PARAFAB_VERIFY(nodes == 8 || nodes == 27, "element " << e << " with " << nodes << " nodes (8 or 27 expected)");
  const int n = nodes == 8 ? 2 : 3;  // nodes per axis
  // Bernstein control points b[i][j][k] of u on the box (degree n − 1 per axis): the nodal values
  // for trilinear cells; for triquadratic ones, per axis b0 = f0, b1 = 2 f½ − (f0 + f1)/2, b2 = f1.
  Vec3 b[3][3][3];
  for (int k = 0; k < nodes; ++k) {
    const std::array<int, 3> o = node_offset(nodes, k);  // in half cells: 0, 2 (hex8) or 0, 1, 2
    const int step = nodes == 8 ? 2 : 1;
    b[o[0] / step][o[1] / step][o[2] / step] = result.u.segment<3>(3 * node[k]);
  }
  if (n == 3)
    for (int axis = 0; axis < 3; ++axis)
      for (int p = 0; p < 3; ++p)
        for (int q = 0; q < 3; ++q) {
          auto at = [&](int i) -> Vec3& {
            return axis == 0 ? b[i][p][q] : axis == 1 ? b[p][i][q] : b[p][q][i];
          };
          at(1) = 2 * at(1) - 0.5 * (at(0) + at(2));
        }
  // u is a convex combination of the b (Bernstein functions are ≥ 0 and sum to 1). Column d of
  // ∇u has the control points (n − 1)/h_d Δ_d b (degree n − 2 along d); raised to degree n − 1
  // along d, all three columns share the basis of u, so ∇u(X) is a convex combination of
  // control matrices G[i][j][k], and any convex function of ∇u (a norm, σ_vm of the linear
  // stress) is at most its largest value at them.
  const Vec3 h = elements[e].box.size();
  Eigen::Matrix3d G[3][3][3];
  auto diff = [&](int d, int i, int j, int k, int along) -> Vec3 {  // (n − 1)/h_d Δ_d at index `along` of d
    int lo[3] = {i, j, k}, hi[3] = {i, j, k};
    lo[d] = along, hi[d] = along + 1;
    return (b[hi[0]][hi[1]][hi[2]] - b[lo[0]][lo[1]][lo[2]]) * ((n - 1) / h[d]);
  };
  FieldBounds out;
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j)
      for (int k = 0; k < n; ++k) {
        out.displacement = std::max(out.displacement, b[i][j][k].norm());
        const int idx[3] = {i, j, k};
        for (int d = 0; d < 3; ++d) {
          // Degree elevation along d: from n − 1 differences to n control points.
          const int m = idx[d];
          Vec3 c;
          if (n == 2) c = diff(d, i, j, k, 0);  // a constant along d
          else if (m == 0) c = diff(d, i, j, k, 0);
          else if (m == 2) c = diff(d, i, j, k, 1);
          else c = 0.5 * (diff(d, i, j, k, 0) + diff(d, i, j, k, 1));
          G[i][j][k].col(d) = c;
        }
        out.gradient = std::max(out.gradient, G[i][j][k].norm());
        if (material) out.von_mises = std::max(out.von_mises, von_mises(stress_from_gradient(*material, G[i][j][k])));
      }
  return out;
}

Eigen::Matrix<double, 6, 1> stress_from_gradient(const ElasticMaterial& material, const Eigen::Matrix3d& H) {
  Eigen::Matrix<double, 6, 1> eps;  // Voigt, engineering shears
  eps << H(0, 0), H(1, 1), H(2, 2), H(0, 1) + H(1, 0), H(1, 2) + H(2, 1), H(0, 2) + H(2, 0);
  return elasticity(material) * eps;
}

}  // namespace parafab::xfem
