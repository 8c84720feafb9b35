// The fine cells as a CellOperator (doc/theory.md, "Elements", "Corotation", "Architecture"):
// A_e = w_K R^_e K_e R^_e^T + w_M M_e from each cell's material stiffness (shared per kind),
// rotation and density, formed on the fly, nothing 24x24 stored per cell. Optionally masked
// (Dirichlet): the rows and columns of prescribed DOFs are zeroed, the constrained operator the
// multigrid works with.
#pragma once

#include <array>
#include <vector>

#include "assembly/cell_operator.hpp"
#include "assembly/fine_cell_kernels.hpp"
#include "assembly/operator.hpp"

namespace hexcut::assembly {

class FineCells final : public CellOperator {
 public:
  /// `cells` (material data and rotations) must outlive the operator, which reads the
  /// rotations at each application. cache = false: the stiffness of a cell without a kind
  /// (per-cell E) is applied from the reference matrices at each visit, for operators
  /// applied a few times; cache = true: formed once here (4.6 KB per such cell), for
  /// operators applied
  /// many times (the multigrid's fine level), which also keeps float copies of the kinds'
  /// stiffness and the reference matrices for apply_add on float vectors (float arithmetic;
  /// without cache that apply_add computes in double). The loops are the loop layer's
  /// (backend/loop.hpp) over the kernels of fine_cell_kernels.hpp.
  FineCells(const topology::DofLayout& layout, const CellData& cells, const OperatorWeights& w,
            bool cache = false);

  /// New weights (the rotations are read at each application). Material data (lambda,
  /// mu) are read at construction when cached: after changing them, make a new operator.
  void set_weights(const OperatorWeights& w) { w_ = w; }
  /// Dirichlet mask: 1 free, 0 prescribed, 3 values per local copy (owned and ghosts).
  /// Empty: no mask.
  void set_mask(std::vector<double> mask_local);
  const OperatorWeights& weights() const { return w_; }

  void apply_add(const double* x, double* y) const override;
  void apply_add(const float* x, float* y) const override;
  void apply_add_colour(const CellPositions& position, int k, const double* x,
                        double* y) const override;
  void apply_add_colour(const CellPositions& position, int k, const float* x,
                        float* y) const override;
  void add_diagonal_blocks(double* diag) const override;
  void cell_matrix(std::size_t e, double* A) const override;

  /// The kernels' data: pointers into this operator's and the CellData's buffers, with the
  /// current rotations (or none) and weights (valid while both are unchanged).
  FineCellData data() const;

 private:

  const CellData* cells_;
  OperatorWeights w_;
  bool cache_;
  std::vector<std::int32_t> own_;           // cache: per cell, index into own_stiffness_
  std::vector<double> own_stiffness_;       // cache: 576 per cell without a kind
  std::vector<double> mask_;                // per local DOF, or empty
  std::vector<char> cell_masked_;           // per cell: has a masked DOF
  // cache: float copies of the kinds' stiffness and of the reference matrices (K_lambda,
  // K_mu, mass), what apply_add on float vectors multiplies by (FineCellOpsSingle).
  std::vector<float> kind_single_, reference_single_;
};

}  // namespace hexcut::assembly
