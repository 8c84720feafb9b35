// Level 1's Galerkin blocks from the fine cells without forming their rotated matrices
// (doc/theory.md, "Geometric multigrid", "Corotation"). A fine cell's contribution to its
// parent is W^T A_e W with W = kron(w, I3) the trilinear weights of its octant and
// A_e = w_K R^ K R^T + m M. W commutes with the block rotation R^ (W^T R^ = R^ W^T), so
//   W^T A_e W = w_K R^ (W^T K W) R^T + m (W^T M W),
// and W^T K W, W^T M W depend only on the stiffness kind (or on the reference K_lambda,
// K_mu for cells with their own E and nu) and the octant: formed once, then every
// corotational rebuild rotates one 24x24 block per child (multigrid::rotated_block_add)
// instead of forming R^ K R^T and the product.
#pragma once

#include <cstdint>
#include <vector>

#include "assembly/fine_cell_kernels.hpp"
#include "assembly/operator.hpp"
#include "multigrid/stored_cells.hpp"

namespace hexcut::multigrid {

/// W_o^T X W_o for the 8 octants o (8 x 576 doubles per matrix X, octant-major, 24x24
/// row-major) of each shared stiffness kind, of the reference K_lambda and K_mu, and of the
/// lumped (I/8) and consistent reference masses (element::reference_matrices()).
struct FineGalerkinTables {
  std::vector<double> kind;  // 8 x 576 per kind of CellData::kind_stiffness
  std::vector<double> k_lambda, k_mu, lumped_mass, consistent_mass;
};

/// The tables for `cells`' kinds (unit weights; the cells' h enters through their kind
/// stiffness, or as h lambda, h mu).
FineGalerkinTables fine_galerkin_tables(const assembly::CellData& cells);

/// The fine cells' children products for StoredCells::galerkin: adds W^T A_e W of every
/// cell without a prescribed DOF from the tables; masked cells are left to galerkin().
class FineChildGalerkin final : public ChildGalerkin {
 public:
  /// `tables` (of the cells of `data`) must outlive this.
  FineChildGalerkin(const FineGalerkinTables& tables, const assembly::FineCellData& data)
      : t_(tables), d_(data) {}
  bool add(std::size_t e, int octant, double* A_parent) const override;

 private:
  const FineGalerkinTables& t_;
  assembly::FineCellData d_;
};

}  // namespace hexcut::multigrid
