// The mid-point corotational force of composite elements computed on the composite level
// (doc/theory.md, "Composite elements", "Mid-point corotational step"): once per topology,
// each element gathers from its filled fine cells what the fine force would use, so a
// mid-point iteration costs two 24x24 products per composite element instead of two per
// fine cell. The result is I^T of the fine grouped force (assembly::assemble_midpoint_force
// with the composite elements as rotation groups) whenever both displacements are
// interpolated from the composite level, u = I u~ (tests/analysis/composite_test.cpp).
#pragma once

#include <petscdm.h>

#include <vector>

#include "assembly/operator.hpp"
#include "multigrid/gmg.hpp"

namespace hexcut::analysis {

/// Per composite element (the local cells of level mg.first_level()), summed over its
/// fine cells c with the element interpolation I_c (8 x 8 trilinear weights, a function
/// of the cell's offset in the element; applied per component):
struct CompositeElements {
  std::vector<double> stiffness;              ///< 576 each: sum_c I_c^T K_c I_c, unrotated [N/m]
  std::vector<double> gram;                   ///< 64 each: sum_c I_c^T I_c (row-major)
  std::vector<double> gradient;               ///< 24 each (8 x 3): sum_c mu_c I_c^T g_q [Pa/m]
  std::vector<double> mu_sum;                 ///< 1 each: sum_c mu_c [Pa]
  std::vector<double> corners;                ///< 24 each: reference corner positions [m]
  std::vector<multigrid::CompositeKey> keys;  ///< each: its fine cells (Multigrid::composite_keys)
  std::int64_t carried = 0;                   ///< elements copied from a previous topology's data
};
// g_q = s_q / (4h), the gradient of corner q's shape function at a fine cell's centre,
// so that sum_c mu_c F_c = mu_sum I + sum_a u~_a (x) gradient_a: the mu-weighted mean
// deformation gradient whose polar factor is the element's rotation
// (assembly::cell_rotations).

/// Builds the data of every local composite element of `mg` (composite_elements() maps
/// the fine cells) from the fine cells' Lame parameters. Requires mg.first_level() >= 1.
/// `previous` (may be null): the data of the topology before a cut; elements with the
/// same key hold the same fine cells and copy theirs instead (same material assumed).
CompositeElements build_composite_elements(const multigrid::Multigrid& mg,
                                           const assembly::CellData& cells,
                                           const CompositeElements* previous = nullptr);

/// The mean internal force over a step, f~ = I^T f_alg, from the composite displacements
/// u0c (start of the step) and u1c (iterate), global vectors of mg.dm(first_level()) [m];
/// fc (same layout) receives it [N]. Each element's rotation at the mid-point is written
/// to every one of its fine cells in cells.rotation. energy[0], energy[1] get this rank's
/// strain energies 1/2 d^T K d at u0 and u1 [J]. Collective.
PetscErrorCode composite_midpoint_force(multigrid::Multigrid& mg, const CompositeElements& E,
                                        Vec u0c, Vec u1c, Vec fc, assembly::CellData& cells,
                                        double energy[2]);

}  // namespace hexcut::analysis
