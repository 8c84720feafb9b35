// Deck fields evaluated on the rank's own entities, with the collective error for a value that
// is not finite (an expression such as 1/x at x = 0): every rank throws the same InputError.
#pragma once

#include <mpi.h>

#include <Eigen/Core>
#include <string>

#include "deck/deck.hpp"

namespace hexcut::assembly {

/// f at (x [m], t [s]); when it is not finite, the first such value is described in `bad`
/// ("deck.yaml:LINE: the expression '...' is nan at x = ..."), unless `bad` holds one.
double evaluate(const deck::Field& f, const Eigen::Vector3d& x, double t, std::string& bad);

/// Throws InputError on every rank when some rank found a non-finite value (`bad` not
/// empty there), with the message of the lowest such rank. Collective.
void throw_if_not_finite(MPI_Comm comm, const std::string& bad);

}  // namespace hexcut::assembly
