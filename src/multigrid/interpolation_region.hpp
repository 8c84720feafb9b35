// The fine copies whose interpolation rows are computed rather than trilinear (today by the
// energy-minimizing interpolation, energy_interpolation.hpp): which copies they are, their
// exchange between ranks and the pattern of coarse copies each row may use, apart from how a
// row is computed. Internal to multigrid/.
#pragma once

#include <petscvec.h>

#include <array>
#include <cstdint>
#include <vector>

#include "hierarchy/hierarchy.hpp"

namespace hexcut::multigrid {

/// Coarse copies in a row's pattern, at most (the 8 corners of a parent cell).
constexpr int kPatternSlots = 8;

/// The fine copies whose rows are computed (the region), numbered like a DOF layout, and a
/// ghost exchange of `block` numbers per region copy.
struct Region {
  topology::DofLayout layout;          // over region copies: owned, then ghosts
  std::vector<std::int32_t> local_of;  // per local fine copy: local region index, or -1
  std::vector<std::int32_t> fine_of;   // per local region copy: local fine copy
  Vec global = nullptr, local = nullptr;
  VecScatter scatter = nullptr;
  Region() = default;
  Region(const Region&) = delete;
  Region& operator=(const Region&) = delete;
  ~Region();
};

/// Region = the fine copies marked in `in` (per canonical copy of `fine`, decided on the
/// replicated hierarchy so that every rank agrees); numbered like a DOF layout (owned copies
/// of each rank contiguous, rank order, canonical order within a rank), with `block` numbers
/// per copy in R->global / R->local. *global_count: region copies over all ranks. Collective.
PetscErrorCode build_region(MPI_Comm comm, const hierarchy::Level& fine,
                            const std::vector<char>& in, PetscInt block, Region* R,
                            std::int64_t* global_count);

/// Per canonical copy of `fine`: 1 where it is a corner of a cell whose parent is marked in
/// `coarse_marked` (per canonical coarse cell).
std::vector<char> corners_of_children(const hierarchy::Level& fine,
                                      const std::vector<char>& coarse_marked);

/// Owned rows (global Vec) -> every local region copy (R.local).
PetscErrorCode to_local(const Region& R, Vec global);

/// Local contributions (R.local) summed into their owners' rows of `global` (overwritten).
PetscErrorCode sum_to_owners(const Region& R, Vec global);

/// Per local region copy: the coarse copies its row may use (local copies of `coarse`'s
/// layout, ascending canonical ids, -1 after the last): those common to the parents of all
/// its incident cells (the cell pattern: every child's interpolation then involves only its
/// parent's 8 corners, so the Galerkin operator stays one 24x24 block per coarse cell).
/// Errors (PETSC_ERR_PLIB) when such a coarse copy is not on this rank.
PetscErrorCode row_patterns(const hierarchy::Level& fine, const hierarchy::Level& coarse,
                            const Region& R,
                            std::vector<std::array<std::int32_t, kPatternSlots>>* pattern);

/// A local cell of the fine level with a region copy among its corners.
struct RegionCell {
  std::int32_t e, parent;  // local cell of the fine layout, local cell of the coarse one
  int octant;              // its octant in the parent (element::parity_octant)
  // Per corner q and slot k of the corner's pattern: the parent corner that is the slot's
  // coarse copy; -1 where the slot is unused or the corner is not in the region.
  std::array<std::array<std::int8_t, kPatternSlots>, 8> parent_corner;
};

/// The local cells of `fine` with a region copy among their corners (`pattern` from
/// row_patterns). Errors (PETSC_ERR_PLIB) when a parent is not on this rank.
PetscErrorCode region_cells(const hierarchy::Level& fine, const hierarchy::Level& coarse,
                            const Region& R,
                            const std::vector<std::array<std::int32_t, kPatternSlots>>& pattern,
                            std::vector<RegionCell>* cells);

}  // namespace hexcut::multigrid
