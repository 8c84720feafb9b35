// The reference state of a comparison (deck key compare.reference; Dick 2012, ch. 6: the
// stress of an implanted bone against the intact one): another hexcut result of the same
// lattice, read per output step as the stress and strain-energy density of each lattice
// cell (doc/user-guide.md, "compare"; doc/output-format.md).
#pragma once

#include <mpi.h>

#include <cstdint>
#include <string>
#include <vector>

#include "common/lattice_spec.hpp"
#include "deck/deck.hpp"

namespace hexcut::analysis {

/// A reference step's fields, dense over the lattice's cells (id i + nx (j + ny k)).
struct ReferenceFields {
  std::int64_t step = -1;      // the reference step they come from
  std::vector<double> stress;  // 6 per lattice cell [Pa]; NaN where it has no cell
  std::vector<double> energy;  // 1 per lattice cell: strain-energy density [Pa]; NaN: none
};

class ReferenceState {
 public:
  /// Opens cmp.reference (collective) and checks it before any work: a hexcut result file
  /// whose lattice (origin, h, dims) is `lattice`, with at least one complete output step,
  /// every one holding the datasets stress and strain_energy_density. Throws InputError at
  /// cmp.where naming what is wrong (exit 2).
  ReferenceState(MPI_Comm comm, const deck::Compare& cmp, const LatticeSpec& lattice);

  /// The reference fields for a step of this run: the reference's step of the same number
  /// when it has one, else its last step (a static reference for every step of a run).
  /// Collective (every rank reads the step whole); the last step read is kept.
  const ReferenceFields& fields(std::int64_t step);

  const std::string& path() const { return path_; }

 private:
  MPI_Comm comm_;
  std::string path_;
  deck::SourceLocation where_;
  LatticeSpec lattice_;
  std::vector<std::int64_t> steps_;  // complete steps, increasing
  ReferenceFields cached_;
};

}  // namespace hexcut::analysis
