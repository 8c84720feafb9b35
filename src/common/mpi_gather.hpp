// Every rank's share of a table, concatenated in rank order, on every rank: for the
// small replicated tables (cell centres at a cut, boundary Hermite data) that every rank
// of hexcut keeps whole; and one rank's string on every rank.
#pragma once

#include <mpi.h>

#include <string>
#include <type_traits>
#include <vector>

namespace hexcut {

/// The ranks' `mine` concatenated in rank order (byte counts are int: below 2 GiB).
template <class T>
std::vector<T> allgather(MPI_Comm comm, const std::vector<T>& mine) {
  static_assert(std::is_trivially_copyable_v<T>, "sent as bytes");
  int size;
  MPI_Comm_size(comm, &size);
  const int bytes = int(mine.size() * sizeof(T));
  std::vector<int> counts(size), offsets(size + 1, 0);
  MPI_Allgather(&bytes, 1, MPI_INT, counts.data(), 1, MPI_INT, comm);
  for (int r = 0; r < size; ++r) offsets[r + 1] = offsets[r] + counts[r];
  std::vector<T> all(offsets[size] / sizeof(T));
  MPI_Allgatherv(mine.data(), bytes, MPI_BYTE, all.data(), counts.data(), offsets.data(), MPI_BYTE,
                 comm);
  return all;
}

/// Rank `root`'s `text` on every rank (a deck, an error message that all ranks must act
/// on).
inline void broadcast_string(MPI_Comm comm, std::string* text, int root = 0) {
  long n = long(text->size());
  MPI_Bcast(&n, 1, MPI_LONG, root, comm);
  text->resize(std::size_t(n));
  MPI_Bcast(text->data(), int(n), MPI_CHAR, root, comm);
}

}  // namespace hexcut
