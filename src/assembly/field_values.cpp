#include "assembly/field_values.hpp"

#include <climits>
#include <cmath>
#include <cstdio>

#include "common/errors.hpp"
#include "common/mpi_gather.hpp"
#include "deck/expression.hpp"

namespace hexcut::assembly {

double evaluate(const deck::Field& f, const Eigen::Vector3d& x, double t, std::string& bad) {
  const double v = f(x, t);
  if (!std::isfinite(v) && bad.empty()) {
    char where[160];
    std::snprintf(where, sizeof where, " at x = %.9g, y = %.9g, z = %.9g m, t = %.9g s", x[0], x[1],
                  x[2], t);
    const char* what = std::isnan(v) ? "nan" : (v > 0 ? "inf" : "-inf");
    bad = f.where.prefix() + "the expression '" + (f.expression ? f.expression->text() : "") +
          "' is " + what + where;
  }
  return v;
}

void throw_if_not_finite(MPI_Comm comm, const std::string& bad) {
  int rank, first;
  MPI_Comm_rank(comm, &rank);
  const int mine = bad.empty() ? INT_MAX : rank;
  MPI_Allreduce(&mine, &first, 1, MPI_INT, MPI_MIN, comm);
  if (first == INT_MAX) return;
  std::string message = bad;
  broadcast_string(comm, &message, first);
  throw InputError(message);
}

}  // namespace hexcut::assembly
