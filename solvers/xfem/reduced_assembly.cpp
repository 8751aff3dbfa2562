#include "xfem/reduced_assembly.h"

#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <utility>

#include "common/error.h"
#include "xfem/linear_xfem.h"

namespace parafab::xfem {

ReducedSystem assemble_reduced(const std::vector<const ElementSystem*>& systems,
                               const std::vector<std::vector<int>>& node, const std::vector<int>& reduced,
                               int reduced_count, const Eigen::SparseMatrix<double>& T) {
  const int n = static_cast<int>(systems.size());
  const int m = reduced_count;
  PARAFAB_VERIFY(static_cast<int>(node.size()) == n,
                 "assemble_reduced: " << node.size() << " node lists for " << n << " element systems");
  bool floating = false;
  for (int r : reduced) floating |= r < 0;
  PARAFAB_VERIFY(!floating || (T.rows() == 3 * static_cast<long>(reduced.size()) && T.cols() == 3 * m),
                 "assemble_reduced: T is " << T.rows() << " × " << T.cols() << ", expected "
                                           << 3 * reduced.size() << " × " << 3 * m);
  Eigen::SparseMatrix<double, Eigen::RowMajor> Tr;
  if (floating) Tr = T;

  // 1. Per element its reduced nodes (local order) and, where a node floats, Pᵀ K P and Pᵀ f with
  //    P the element's block of T (3n × 3·its reduced nodes).
  std::vector<std::vector<int>> local(n);
  std::vector<Eigen::MatrixXd> Kx(n);
  std::vector<Eigen::VectorXd> fx(n);
  std::vector<char> expanded(n, 0);
  tbb::parallel_for(tbb::blocked_range<int>(0, n, 256), [&](const tbb::blocked_range<int>& range) {
    std::vector<std::vector<std::pair<int, double>>> ex;
    for (int e = range.begin(); e != range.end(); ++e) {
      const auto& nd = node[e];
      const int nn = static_cast<int>(nd.size());
      PARAFAB_VERIFY(systems[e] && systems[e]->K.rows() == 3 * nn && systems[e]->K.cols() == 3 * nn &&
                         systems[e]->f.size() == 3 * nn,
                     "assemble_reduced: element " << e << " has " << nn << " nodes but no matching system");
      bool any = false;
      for (int k : nd) {
        PARAFAB_VERIFY(k >= 0 && k < static_cast<int>(reduced.size()), "assemble_reduced: element " << e << " node " << k);
        any |= reduced[k] < 0;
      }
      auto& R = local[e];
      if (!any) {
        R.resize(nn);
        for (int a = 0; a < nn; ++a) R[a] = reduced[nd[a]];
        continue;
      }
      expanded[e] = 1;
      ex.assign(nn, {});
      for (int a = 0; a < nn; ++a) {
        if (reduced[nd[a]] >= 0) {
          ex[a].emplace_back(reduced[nd[a]], 1.0);
          continue;
        }
        for (Eigen::SparseMatrix<double, Eigen::RowMajor>::InnerIterator it(Tr, 3 * nd[a]); it; ++it)
          if (it.col() % 3 == 0) ex[a].emplace_back(static_cast<int>(it.col() / 3), it.value());
      }
      for (const auto& list : ex)
        for (const auto& [j, w] : list)
          if (std::find(R.begin(), R.end(), j) == R.end()) R.push_back(j);
      Eigen::MatrixXd P = Eigen::MatrixXd::Zero(3 * nn, 3 * R.size());
      for (int a = 0; a < nn; ++a)
        for (const auto& [j, w] : ex[a]) {
          const int b = static_cast<int>(std::find(R.begin(), R.end(), j) - R.begin());
          for (int d = 0; d < 3; ++d) P(3 * a + d, 3 * b + d) += w;
        }
      Kx[e] = P.transpose() * systems[e]->K * P;
      fx[e] = P.transpose() * systems[e]->f;
    }
  });

  // 2. Incidence: per reduced node the (element, local index) pairs, in element order.
  std::vector<int> start(m + 1, 0);
  for (int e = 0; e < n; ++e)
    for (int j : local[e]) {
      PARAFAB_VERIFY(j >= 0 && j < m, "assemble_reduced: reduced node " << j << " of element " << e << " (of " << m << ")");
      ++start[j + 1];
    }
  for (int j = 0; j < m; ++j) start[j + 1] += start[j];
  std::vector<std::pair<int, int>> incident(start[m]);
  {
    std::vector<int> fill(start.begin(), start.end() - 1);
    for (int e = 0; e < n; ++e)
      for (int a = 0; a < static_cast<int>(local[e].size()); ++a) incident[fill[local[e][a]]++] = {e, a};
  }

  // 3. Block pattern: reduced node j couples with the reduced nodes of its elements (sorted).
  std::vector<std::vector<int>> couples(m);
  tbb::enumerable_thread_specific<std::vector<int>> marks([m] { return std::vector<int>(m, -1); });
  tbb::parallel_for(tbb::blocked_range<int>(0, m, 512), [&](const tbb::blocked_range<int>& range) {
    auto& mark = marks.local();
    for (int j = range.begin(); j != range.end(); ++j) {
      auto& c = couples[j];
      for (int k = start[j]; k < start[j + 1]; ++k)
        for (int i : local[incident[k].first])
          if (mark[i] != j) mark[i] = j, c.push_back(i);
      std::sort(c.begin(), c.end());
    }
  });

  // 4. Compressed columns: column 3j + d holds rows 3c + db for c in couples[j].
  ReducedSystem out;
  std::vector<long> base(m + 1, 0);
  for (int j = 0; j < m; ++j) base[j + 1] = base[j] + 9 * static_cast<long>(couples[j].size());
  const long nnz = base[m];
  PARAFAB_VERIFY(nnz < (1L << 31), "assemble_reduced: " << nnz << " nonzeros exceed the index range of the sparse matrix");
  Eigen::SparseMatrix<double>& K = out.K;
  K.resize(3 * m, 3 * m);
  K.resizeNonZeros(nnz);
  int* outer = K.outerIndexPtr();
  int* inner = K.innerIndexPtr();
  double* value = K.valuePtr();
  out.f = Eigen::VectorXd::Zero(3 * m);
  for (int j = 0; j < m; ++j)
    for (int d = 0; d < 3; ++d) outer[3 * j + d] = static_cast<int>(base[j] + 3L * d * couples[j].size());
  outer[3 * m] = static_cast<int>(nnz);
  tbb::parallel_for(tbb::blocked_range<int>(0, m, 256), [&](const tbb::blocked_range<int>& range) {
    std::vector<int> at;
    for (int j = range.begin(); j != range.end(); ++j) {
      const auto& c = couples[j];
      const long len = static_cast<long>(c.size());
      for (int d = 0; d < 3; ++d) {
        int* in = inner + base[j] + 3 * d * len;
        for (long i = 0; i < len; ++i)
          for (int db = 0; db < 3; ++db) in[3 * i + db] = 3 * c[i] + db;
        std::fill(value + base[j] + 3 * d * len, value + base[j] + 3 * (d + 1) * len, 0.0);
      }
      for (int k = start[j]; k < start[j + 1]; ++k) {
        const auto [e, a] = incident[k];
        const Eigen::MatrixXd& Ke = expanded[e] ? Kx[e] : systems[e]->K;
        const Eigen::VectorXd& fe = expanded[e] ? fx[e] : systems[e]->f;
        const auto& R = local[e];
        at.resize(R.size());
        for (size_t b = 0; b < R.size(); ++b) at[b] = static_cast<int>(std::lower_bound(c.begin(), c.end(), R[b]) - c.begin());
        for (int d = 0; d < 3; ++d) {
          double* col = value + base[j] + 3 * d * len;
          for (size_t b = 0; b < R.size(); ++b)
            for (int db = 0; db < 3; ++db) col[3 * at[b] + db] += Ke(3 * b + db, 3 * a + d);
          out.f(3 * j + d) += fe(3 * a + d);
        }
      }
    }
  });
  for (int e = 0; e < n; ++e) out.expanded_elements += expanded[e];
  return out;
}

}  // namespace parafab::xfem
