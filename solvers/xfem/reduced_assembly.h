// Assembly of the aggregated system Tᵀ K T, Tᵀ f (cell aggregation, thesis §6.4.4) straight from
// the element systems, without forming K or the sparse triple product: each element's nodes are
// expanded through T (identity for ordinary nodes, extrapolation weights for floating ones), a
// pattern of 3×3 blocks over reduced nodes is built from those expansions, and every column of
// the result is summed from its elements in element order, in parallel (TBB) over columns, so the
// matrix is bit-identical for every thread count.
#pragma once

#include <Eigen/Dense>
#include <Eigen/Sparse>
#include <vector>

namespace parafab::xfem {

struct ElementSystem;

struct ReducedSystem {
  Eigen::SparseMatrix<double> K;  ///< Tᵀ K T, 3·reduced_count square, symmetric pattern (structural zeros kept)
  Eigen::VectorXd f;              ///< Tᵀ f
  int expanded_elements = 0;      ///< elements with a floating node (a local Pᵀ K P was formed)
};

/// `systems[e]`: element e's system (3n × 3n for its n = node[e].size() nodes, DOF 3k + component).
/// `reduced[i]`: reduced node of DOF node i, −1 for a floating node, whose row block of T
/// (3·node_count × 3·reduced_count, the same weight for the three components) gives its expansion.
/// T may be empty when no node floats.
ReducedSystem assemble_reduced(const std::vector<const ElementSystem*>& systems,
                               const std::vector<std::vector<int>>& node, const std::vector<int>& reduced,
                               int reduced_count, const Eigen::SparseMatrix<double>& T);

}  // namespace parafab::xfem
