#include "xfem/linear_xfem.h"

#include <Eigen/Dense>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <atomic>
#include <chrono>
#include <numeric>

#include "common/error.h"
#include "xfem/area_rules.h"

namespace parafab::xfem {

namespace {

using Mat24 = Eigen::Matrix<double, 24, 24>;
using Vec24 = Eigen::Matrix<double, 24, 1>;
using Mat6x24 = Eigen::Matrix<double, 6, 24>;
using Mat3x24 = Eigen::Matrix<double, 3, 24>;

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

// Strain–displacement matrix, Voigt order (xx, yy, zz, xy, yz, xz) with engineering shears.
Mat6x24 strain_matrix(const Eigen::Matrix<double, 8, 3>& G) {
  Mat6x24 B = Mat6x24::Zero();
  for (int k = 0; k < 8; ++k) {
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

Mat3x24 value_matrix(const Eigen::Matrix<double, 8, 1>& N) {
  Mat3x24 M = Mat3x24::Zero();
  for (int k = 0; k < 8; ++k)
    for (int d = 0; d < 3; ++d) M(d, 3 * k + d) = N(k);
  return M;
}

Eigen::Matrix<double, 6, 6> elasticity(const ElasticMaterial& m) {
  const double E = m.youngs_modulus, nu = m.poisson_ratio;
  const double lambda = E * nu / ((1 + nu) * (1 - 2 * nu)), mu = E / (2 * (1 + nu));
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
void add_incompatible_modes(const GridElement& el, const Eigen::Matrix<double, 6, 6>& D,
                            double min_fraction, Mat24& Ke) {
  double volume = 0;
  for (double w : el.rule.weights) volume += w;
  if (!(volume > min_fraction * el.box.volume())) return;  // tiny pieces: K_aa near singular
  const Vec3 h = el.box.size();
  const size_t nq = el.rule.points.size();
  std::vector<Vec3> grad(nq);  // (∂φ_x/∂x, ∂φ_y/∂y, ∂φ_z/∂z)
  Vec3 mean = Vec3::Zero();
  for (size_t q = 0; q < nq; ++q) {
    const Vec3 xi = (el.rule.points[q] - el.box.min).cwiseQuotient(h);
    grad[q] = Vec3(-4 * (2 * xi.x() - 1) / h.x(), -4 * (2 * xi.y() - 1) / h.y(), -4 * (2 * xi.z() - 1) / h.z());
    mean += el.rule.weights[q] * grad[q];
  }
  mean /= volume;
  Eigen::Matrix<double, 9, 9> Kaa = Eigen::Matrix<double, 9, 9>::Zero();
  Eigen::Matrix<double, 9, 24> Kau = Eigen::Matrix<double, 9, 24>::Zero();
  Eigen::Matrix<double, 8, 1> N;
  Eigen::Matrix<double, 8, 3> G;
  for (size_t q = 0; q < nq; ++q) {
    trilinear_shape(el.box, el.rule.points[q], N, G);
    const Mat6x24 Bu = strain_matrix(G);
    // Mode m of component c: displacement e_c φ_m; only ∂φ_m/∂x_m ≠ 0.
    Eigen::Matrix<double, 8, 3> Gm = Eigen::Matrix<double, 8, 3>::Zero();  // rows 0..2 used
    for (int m = 0; m < 3; ++m) Gm(m, m) = grad[q][m] - mean[m];
    const Mat6x24 Bfull = strain_matrix(Gm);  // columns 3m + c: mode m, component c
    const Eigen::Matrix<double, 6, 9> Ba = Bfull.leftCols<9>();
    Kaa.noalias() += el.rule.weights[q] * Ba.transpose() * D * Ba;
    Kau.noalias() += el.rule.weights[q] * Ba.transpose() * D * Bu;
  }
  const Eigen::LDLT<Eigen::Matrix<double, 9, 9>> ldlt(Kaa);
  if (ldlt.info() != Eigen::Success || !(ldlt.vectorD().minCoeff() > 1e-10 * ldlt.vectorD().maxCoeff())) return;
  Ke.noalias() -= Kau.transpose() * ldlt.solve(Kau);
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

struct UnionFind {
  std::vector<int> parent;
  explicit UnionFind(int n) : parent(n) { std::iota(parent.begin(), parent.end(), 0); }
  int find(int a) { return parent[a] == a ? a : parent[a] = find(parent[a]); }
  void unite(int a, int b) { parent[find(a)] = find(b); }
};

}  // namespace

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

Vec3 corner(const Box3& box, int k) {
  return Vec3((k & 1) ? box.max.x() : box.min.x(), (k & 2) ? box.max.y() : box.min.y(),
              (k & 4) ? box.max.z() : box.min.z());
}

std::vector<std::array<int, 8>> number_dof_nodes(const std::vector<GridElement>& elements,
                                                 const std::vector<std::array<int, 2>>& adjacent,
                                                 int& count) {
  const int n = static_cast<int>(elements.size());
  UnionFind uf(8 * n);
  auto grid_node = [&](int e, int k) {
    const auto& c = elements[e].cell;
    return std::array<int, 3>{c[0] + (k & 1), c[1] + ((k >> 1) & 1), c[2] + ((k >> 2) & 1)};
  };
  for (const auto& [a, b] : adjacent) {
    PARAFAB_VERIFY(a >= 0 && a < n && b >= 0 && b < n, "element pair (" << a << ", " << b << ") out of range");
    for (int ka = 0; ka < 8; ++ka)
      for (int kb = 0; kb < 8; ++kb)
        if (grid_node(a, ka) == grid_node(b, kb)) uf.unite(8 * a + ka, 8 * b + kb);
  }
  std::vector<int> id(8 * n, -1);
  std::vector<std::array<int, 8>> node(n);
  count = 0;
  for (int s = 0; s < 8 * n; ++s) {
    const int r = uf.find(s);
    if (id[r] < 0) id[r] = count++;
    node[s / 8][s % 8] = id[r];
  }
  return node;
}

LinearSystem assemble_linear(const std::vector<GridElement>& elements,
                             const std::vector<std::array<int, 8>>& node, int node_count,
                             const ElasticMaterial& material,
                             const std::vector<DirichletCondition>& dirichlet,
                             const std::vector<TractionCondition>& tractions,
                             const LinearXfemOptions& options, bool include_bulk) {
  PARAFAB_VERIFY(material.youngs_modulus > 0, "material: E must be positive, got " << material.youngs_modulus);
  PARAFAB_VERIFY(material.poisson_ratio > -1 && material.poisson_ratio < 0.5,
                 "material: Poisson ratio must be in (-1, 0.5), got " << material.poisson_ratio);
  const Eigen::Matrix<double, 6, 6> D = elasticity(material);
  const double beta = options.nitsche_beta > 0 ? options.nitsche_beta : 100.0;
  const int ndof = 3 * node_count;
  std::vector<Eigen::Triplet<double>> trip;
  Eigen::VectorXd f = Eigen::VectorXd::Zero(ndof);
  SurfaceRuleOptions so;
  so.area.degree = options.surface_degree;
  // The matrix and load vector of element e (thread-safe: reads only).
  auto element_matrix = [&](size_t e, Mat24& Ke, Vec24& fe) {
    const GridElement& el = elements[e];
    Eigen::Matrix<double, 8, 1> N;
    Eigen::Matrix<double, 8, 3> G;
    Ke.setZero();
    fe.setZero();
    for (size_t q = 0; q < el.rule.points.size(); ++q) {
      trilinear_shape(el.box, el.rule.points[q], N, G);
      if (include_bulk) {
        const Mat6x24 B = strain_matrix(G);
        Ke.noalias() += el.rule.weights[q] * B.transpose() * D * B;
      }
      if (material.density != 0 && options.gravity.squaredNorm() > 0)
        fe.noalias() += el.rule.weights[q] * material.density * value_matrix(N).transpose() * options.gravity;
    }
    if (include_bulk && options.incompatible_modes)
      add_incompatible_modes(el, D, options.incompatible_min_fraction, Ke);
    if (el.subvolume) {
      const double h = el.box.size().minCoeff();
      for (const CutPatch& patch : el.subvolume->patches) {
        if (patch.source_face < 0) continue;
        const DirichletCondition* dc = nullptr;
        for (const auto& d : dirichlet) if (d.face == patch.source_face) dc = &d;
        const TractionCondition* tc = nullptr;
        for (const auto& t : tractions) if (t.face == patch.source_face) tc = &t;
        if (!dc && !tc) continue;
        const SurfaceRule sr = surface_rule(patch, so);
        for (size_t q = 0; q < sr.points.size(); ++q) {
          trilinear_shape(el.box, sr.points[q], N, G);
          const Mat3x24 Nm = value_matrix(N);
          const double w = sr.weights[q];
          if (tc) fe.noalias() += w * Nm.transpose() * tc->traction;
          if (dc) {
            const Eigen::Matrix<double, 3, 24> T = traction_operator(sr.normals[q]) * D * strain_matrix(G);
            const Vec3 g = dc->offset + dc->gradient * sr.points[q];
            const double penalty = beta * material.youngs_modulus / h;
            const Eigen::Matrix3d M = dc->components.asDiagonal();  // prescribed components
            Ke.noalias() += w * (penalty * Nm.transpose() * M * Nm - Nm.transpose() * M * T - T.transpose() * M * Nm);
            fe.noalias() += w * (penalty * Nm.transpose() * M * g - T.transpose() * M * g);
          }
        }
      }
    }
  };
  // Uncut interior cells share one box size and rule, hence one matrix: integrated once (for
  // the first interior element) and copied to every element of the same shape.
  const int reference = first_interior_element(elements);
  Mat24 K_ref;
  Vec24 f_ref;
  if (reference >= 0) element_matrix(reference, K_ref, f_ref);
  auto element_or_copy = [&](size_t e, Mat24& Ke, Vec24& fe) {
    if (reference >= 0 && (static_cast<int>(e) == reference || same_uncut_shape(elements[reference], elements[e]))) {
      Ke = K_ref, fe = f_ref;
      return static_cast<int>(e) != reference;  // counts copies, not the integrated one
    }
    element_matrix(e, Ke, fe);
    return false;
  };
  auto scatter = [&](size_t e, const Mat24& Ke, const Vec24& fe) {
    for (int a = 0; a < 8; ++a)
      for (int da = 0; da < 3; ++da) {
        const int ra = 3 * node[e][a] + da;
        f(ra) += fe(3 * a + da);
        for (int b = 0; b < 8; ++b)
          for (int db = 0; db < 3; ++db)
            if (Ke(3 * a + da, 3 * b + db) != 0.0) trip.emplace_back(ra, 3 * node[e][b] + db, Ke(3 * a + da, 3 * b + db));
      }
  };
  // Element matrices in parallel, a chunk at a time; the scatter runs in element order, so
  // the triplets, K and f are bit-identical for every thread count.
  const size_t n = elements.size(), chunk = 4096;
  if (include_bulk) trip.reserve(576 * n);
  std::vector<Mat24, Eigen::aligned_allocator<Mat24>> Kc(std::min(n, chunk));
  std::vector<Vec24, Eigen::aligned_allocator<Vec24>> fc(std::min(n, chunk));
  std::atomic<int> copies{0};
  for (size_t begin = 0; begin < n; begin += chunk) {
    const size_t end = std::min(n, begin + chunk);
    tbb::parallel_for(tbb::blocked_range<size_t>(begin, end, 16), [&](const tbb::blocked_range<size_t>& r) {
      int c = 0;
      for (size_t e = r.begin(); e != r.end(); ++e) c += element_or_copy(e, Kc[e - begin], fc[e - begin]);
      copies += c;
    });
    for (size_t e = begin; e < end; ++e) scatter(e, Kc[e - begin], fc[e - begin]);
  }
  LinearSystem sys;
  sys.K.resize(ndof, ndof);
  sys.K.setFromTriplets(trip.begin(), trip.end());
  sys.f = std::move(f);
  sys.reused_element_matrices = copies;
  return sys;
}

Vec3 LinearXfemResult::displacement(const std::vector<GridElement>& elements, int e, const Vec3& X) const {
  Eigen::Matrix<double, 8, 1> N;
  Eigen::Matrix<double, 8, 3> G;
  trilinear_shape(elements[e].box, X, N, G);
  Vec3 d = Vec3::Zero();
  for (int k = 0; k < 8; ++k) d += N(k) * u.segment<3>(3 * node[e][k]);
  return d;
}

LinearXfemResult solve_linear(const std::vector<GridElement>& elements,
                              const std::vector<std::array<int, 2>>& adjacent,
                              const ElasticMaterial& material,
                              const std::vector<DirichletCondition>& dirichlet,
                              const std::vector<TractionCondition>& tractions,
                              const LinearXfemOptions& options) {
  LinearXfemSolver solver;
  return solver.solve(elements, adjacent, material, dirichlet, tractions, options);
}

LinearXfemResult LinearXfemSolver::solve(const std::vector<GridElement>& elements,
                                         const std::vector<std::array<int, 2>>& adjacent,
                                         const ElasticMaterial& material,
                                         const std::vector<DirichletCondition>& dirichlet,
                                         const std::vector<TractionCondition>& tractions,
                                         const LinearXfemOptions& options) {
  LinearXfemResult r;
  auto t0 = std::chrono::steady_clock::now();
  int count = 0;
  r.node = number_dof_nodes(elements, adjacent, count);
  r.dofs = 3 * count;
  r.elements = static_cast<int>(elements.size());
  for (const auto& e : elements) r.cut_elements += e.subvolume != nullptr;
  LinearSystem sys = assemble_linear(elements, r.node, count, material, dirichlet, tractions, options);
  r.reused_element_matrices = sys.reused_element_matrices;
  Eigen::SparseMatrix<double> T = aggregation_map(elements, adjacent, r.node, count, options.aggregation_fraction,
                                                  &r.aggregated_nodes);
  if (r.aggregated_nodes > 0) {  // otherwise T = I: no TᵀKT
    sys.K = Eigen::SparseMatrix<double>(T.transpose() * sys.K * T);
    sys.f = T.transpose() * sys.f;
    r.aggregation = std::move(T);
  }
  r.assemble_seconds = seconds_since(t0);
  t0 = std::chrono::steady_clock::now();
  SparseCholesky& chol = *cholesky_;
  chol.factorize(sys.K);
  if (chol.IsDone()) {
    // Cholesky: two steps of iterative refinement; the LU fallback solves once, as before.
    r.u = chol.solve(sys.f, chol.status() == SparseCholesky::Status::Factorized ? 2 : 0);
    r.solved = r.u.allFinite();
    if (chol.status() == SparseCholesky::Status::FactorizedByLU)
      r.message = "stiffness matrix not positive definite (Nitsche β too small, or too few supports); solved by LU";
  }
  if (!r.solved) r.message = "stiffness matrix singular: is the part supported (Dirichlet faces)?";
  r.solve_seconds = seconds_since(t0);
  if (r.solved) {
    r.energy = 0.5 * r.u.dot(sys.K * r.u) - sys.f.dot(r.u);
    if (r.aggregated_nodes > 0) r.u = r.aggregation * r.u;  // back to every DOF node (aggregated ones extrapolated)
    r.factorization = cholesky_;
  }
  return r;
}

Eigen::VectorXd LinearXfemResult::solve_again(const Eigen::VectorXd& f) const {
  PARAFAB_VERIFY(factorization && factorization->IsDone(), "solve_again: the linear solve kept no factorization");
  PARAFAB_VERIFY(f.size() == dofs, "solve_again: load vector of size " << f.size() << ", expected " << dofs);
  const int refine = factorization->status() == SparseCholesky::Status::Factorized ? 2 : 0;
  if (aggregation.size() == 0) return factorization->solve(f, refine);
  return aggregation * factorization->solve(aggregation.transpose() * f, refine);
}

Eigen::SparseMatrix<double> aggregation_map(const std::vector<GridElement>& elements,
                                            const std::vector<std::array<int, 2>>& adjacent,
                                            const std::vector<std::array<int, 8>>& node, int count,
                                            double fraction, int* aggregated) {
  // Small elements: volume fraction below `fraction`. A DOF node all of whose elements are
  // small is "floating" (barely stiff): it follows the trilinear field of a normal neighbour.
  const int n = static_cast<int>(elements.size());
  std::vector<char> small(n, 0);
  for (int e = 0; e < n; ++e) {
    double v = 0;
    for (double w : elements[e].rule.weights) v += w;
    small[e] = fraction > 0 && v < fraction * elements[e].box.volume();
  }
  std::vector<char> supported(count, 0);
  for (int e = 0; e < n; ++e)
    if (!small[e]) for (int k : node[e]) supported[k] = 1;
  std::vector<int> host(n, -1);  // the largest normal neighbour of every small element
  std::vector<double> host_volume(n, 0);
  for (const auto& [a, b] : adjacent)
    for (const auto& [s, o] : {std::pair<int, int>{a, b}, std::pair<int, int>{b, a}}) {
      if (!small[s] || small[o]) continue;
      double v = 0;
      for (double w : elements[o].rule.weights) v += w;
      if (v > host_volume[s]) host_volume[s] = v, host[s] = o;
    }
  std::vector<int> reduced(count, -1);
  int m = 0;
  std::vector<std::pair<int, int>> floating;  // (DOF node, small element, corner) via index
  std::vector<std::array<int, 2>> source(count, {-1, -1});
  for (int e = 0; e < n; ++e)
    if (small[e] && host[e] >= 0)
      for (int k = 0; k < 8; ++k)
        if (!supported[node[e][k]] && source[node[e][k]][0] < 0) source[node[e][k]] = {e, k};
  for (int i = 0; i < count; ++i)
    if (source[i][0] < 0) reduced[i] = m++;
  std::vector<Eigen::Triplet<double>> trip;
  Eigen::Matrix<double, 8, 1> N;
  Eigen::Matrix<double, 8, 3> G;
  int agg = 0;
  for (int i = 0; i < count; ++i) {
    if (reduced[i] >= 0) {
      for (int d = 0; d < 3; ++d) trip.emplace_back(3 * i + d, 3 * reduced[i] + d, 1.0);
      continue;
    }
    ++agg;
    const auto [e, k] = source[i];
    const int h = host[e];
    trilinear_shape(elements[h].box, corner(elements[e].box, k), N, G);  // extrapolation into the small cell
    for (int j = 0; j < 8; ++j)
      for (int d = 0; d < 3; ++d) trip.emplace_back(3 * i + d, 3 * reduced[node[h][j]] + d, N(j));
  }
  if (aggregated) *aggregated = agg;
  Eigen::SparseMatrix<double> T(3 * count, 3 * m);
  T.setFromTriplets(trip.begin(), trip.end());
  return T;
}

}  // namespace parafab::xfem

namespace parafab::xfem {

Eigen::Matrix<double, 6, 1> stress_at(const LinearXfemResult& result, const std::vector<GridElement>& elements,
                                      const ElasticMaterial& material, int e, const Vec3& X) {
  Eigen::Matrix<double, 8, 1> N;
  Eigen::Matrix<double, 8, 3> G;
  trilinear_shape(elements[e].box, X, N, G);
  Vec24 ue;
  for (int k = 0; k < 8; ++k) ue.segment<3>(3 * k) = result.u.segment<3>(3 * result.node[e][k]);
  return elasticity(material) * strain_matrix(G) * ue;
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
  Eigen::Matrix<double, 8, 1> N;
  Eigen::Matrix<double, 8, 3> G;
  trilinear_shape(elements[e].box, X, N, G);
  Eigen::Matrix3d H = Eigen::Matrix3d::Zero();
  for (int k = 0; k < 8; ++k) H += result.u.segment<3>(3 * result.node[e][k]) * G.row(k);
  return H;
}

}  // namespace parafab::xfem
