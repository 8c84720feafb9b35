// Initial (residual) stress sigma0 (doc/theory.md, "Initial stress"): its value in every local
// cell and the load it puts on the body. The uncut reference configuration is taken to be in
// equilibrium with its surroundings (tissue in vivo, a part with residual stress held in its
// assembly), so the traction sigma0 n on the body's own boundary is held there; what acts is
// the divergence of sigma0 inside the body (its jumps between cells) and, after cuts, the
// traction that the faces the cuts open no longer carry (Wu 2014, ch. 6: a cut flap gapes).
#pragma once

#include <mpi.h>

#include <string>
#include <vector>

#include "deck/deck.hpp"
#include "lattice/lattice.hpp"
#include "topology/dof_layout.hpp"
#include "topology/vertex_copies.hpp"

namespace hexcut::assembly {

/// sigma0 of the rank's local cells (index = position in DofLayout::cells), 6 per cell in
/// ParaView order xx, yy, zz, xy, yz, xz [Pa], from deck.initial_stress: the entries in
/// deck order, each over the cells of its material (all when none), a value entry at the
/// cell centre, a dataset entry where its value is not NaN; 0 where no entry gives one.
/// Empty when the deck has no initial_stress. An expression that is not finite at some
/// cell centre throws InputError naming its deck line, on every rank (collective on comm).
std::vector<double> initial_stress_of_cells(MPI_Comm comm, const deck::Deck& deck,
                                            const lattice::Lattice& lattice,
                                            const topology::DofLayout& layout);

/// "file:line: warning: ..." for every dataset entry of deck.initial_stress that has no
/// value (NaN) in some of the cells with material it selects (they keep the earlier
/// entries' sigma0, 0 if none), with the count. Every rank computes the same list.
std::vector<std::string> initial_stress_warnings(const deck::Deck& deck,
                                                 const lattice::Lattice& lattice);

/// The load of sigma0 on the local copies (3 per local copy, DofLayout's local order; sum
/// over ranks as for any local force) [N]: the consistent force -integral B^T sigma0 of
/// every local cell, with the traction sigma0 n of the uncut body's boundary faces added
/// back (held by the surroundings). For a cell-wise constant sigma0 this is, at corner q
/// of cell e (h: cell edge [m]),
///   f_q = -(h^2 / 4) sum over the faces F of e that contain q and have a face neighbour
///         cell in the lattice (linked or cut) of sigma0_e n_F,
/// n_F the outward unit normal of F. It depends on the cut state only through the vertex
/// copies: where the two cells of a face share a corner's copy, their terms are summed
/// first, -(h^2/4) (sigma0_e - sigma0_nb) n_F, by the lower cell of the pair, so that equal
/// values cancel exactly (a uniform sigma0 on an uncut body gives f = 0, bit for bit, on
/// any number of ranks); where a cut split the copies, each side gets its own -sigma0 n.
/// `sigma0`: initial_stress_of_cells (empty: returns empty); the neighbours' sigma0 is
/// evaluated here from the deck (they may be another rank's cells).
std::vector<double> initial_stress_load(const deck::Deck& deck, const lattice::Lattice& lattice,
                                        const topology::VertexCopies& copies,
                                        const topology::DofLayout& layout,
                                        const std::vector<double>& sigma0);

}  // namespace hexcut::assembly
