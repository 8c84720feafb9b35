#include "multigrid/halo.hpp"

#include <algorithm>
#include <type_traits>

namespace hexcut::multigrid {

namespace {

template <class S>
MPI_Datatype mpi_type() {
  return std::is_same_v<S, double> ? MPI_DOUBLE : MPI_FLOAT;
}

}  // namespace

PetscErrorCode LevelHalo::create(MPI_Comm comm, const LoopLevelArrays& a,
                                 std::unique_ptr<LevelHalo>* out) {
  PetscFunctionBeginUser;
  std::unique_ptr<LevelHalo> h(new LevelHalo);
  const auto ghosts = std::int64_t(a.ghost_rank.size());
  const auto owned = a.view.num_copies;
  h->num_ghosts_ = ghosts;
  std::int64_t any = ghosts;
  PetscCallMPI(MPI_Allreduce(MPI_IN_PLACE, &any, 1, MPI_INT64_T, MPI_MAX, comm));
  if (any == 0) {
    *out = std::move(h);
    PetscFunctionReturn(0);
  }
  // 1. A star forest per copy (roots: owned copies, leaves: ghosts) finds the owned copies some
  //    rank holds as ghosts (root degree > 0): the send list, numbered in owned order.
  PetscSF copies;
  std::vector<PetscSFNode> remote(static_cast<std::size_t>(ghosts));
  for (std::int64_t g = 0; g < ghosts; ++g) {
    remote[std::size_t(g)].rank = a.ghost_rank[std::size_t(g)];
    remote[std::size_t(g)].index = a.ghost_index[std::size_t(g)];
  }
  PetscCall(PetscSFCreate(comm, &copies));
  PetscCall(PetscSFSetGraph(copies, PetscInt(owned), PetscInt(ghosts), nullptr, PETSC_COPY_VALUES,
                            remote.data(), PETSC_COPY_VALUES));
  PetscCall(PetscSFSetUp(copies));
  const PetscInt* degree;
  PetscCall(PetscSFComputeDegreeBegin(copies, &degree));
  PetscCall(PetscSFComputeDegreeEnd(copies, &degree));
  std::vector<PetscInt> slot(std::size_t(owned), -1), ghost_slot(std::size_t(ghosts), -1);
  for (std::int64_t i = 0; i < owned; ++i)
    if (degree[i] > 0) {
      slot[std::size_t(i)] = PetscInt(h->send_.size());
      h->send_.push_back(std::int32_t(i));
    }
  // 2. Each ghost learns its owner's slot in the packed buffer.
  PetscCall(PetscSFBcastBegin(copies, MPIU_INT, slot.data(), ghost_slot.data(), MPI_REPLACE));
  PetscCall(PetscSFBcastEnd(copies, MPIU_INT, slot.data(), ghost_slot.data(), MPI_REPLACE));
  PetscCall(PetscSFDestroy(&copies));
  // 3. The star forest of the values: roots the packed buffer (3 per send copy), leaves the
  //    ghost region (3 per ghost, contiguous).
  std::vector<PetscSFNode> values(std::size_t(3 * ghosts));
  for (std::int64_t g = 0; g < ghosts; ++g)
    for (int c = 0; c < 3; ++c) {
      values[std::size_t(3 * g + c)].rank = a.ghost_rank[std::size_t(g)];
      values[std::size_t(3 * g + c)].index = 3 * ghost_slot[std::size_t(g)] + c;
    }
  PetscCall(PetscSFCreate(comm, &h->sf_));
  PetscCall(PetscSFSetGraph(h->sf_, PetscInt(3 * h->send_.size()), PetscInt(3 * ghosts), nullptr,
                            PETSC_COPY_VALUES, values.data(), PETSC_COPY_VALUES));
  PetscCall(PetscSFSetUp(h->sf_));
  *out = std::move(h);
  PetscFunctionReturn(0);
}

LevelHalo::~LevelHalo() {
  PetscSFDestroy(&sf_);
}

template <class S>
PetscErrorCode LevelHalo::broadcast(const S* packed, S* ghosts) const {
  PetscFunctionBeginUser;
  if (!sf_) PetscFunctionReturn(0);
  PetscCall(PetscSFBcastBegin(sf_, mpi_type<S>(), packed, ghosts, MPI_REPLACE));
  PetscCall(PetscSFBcastEnd(sf_, mpi_type<S>(), packed, ghosts, MPI_REPLACE));
  PetscFunctionReturn(0);
}

template <class S>
PetscErrorCode LevelHalo::reduce(const S* ghosts, S* packed) const {
  PetscFunctionBeginUser;
  if (!sf_) PetscFunctionReturn(0);
  std::fill(packed, packed + 3 * send_.size(), S(0));
  PetscCall(PetscSFReduceBegin(sf_, mpi_type<S>(), ghosts, packed, MPI_SUM));
  PetscCall(PetscSFReduceEnd(sf_, mpi_type<S>(), ghosts, packed, MPI_SUM));
  PetscFunctionReturn(0);
}

template PetscErrorCode LevelHalo::broadcast(const double*, double*) const;
template PetscErrorCode LevelHalo::broadcast(const float*, float*) const;
template PetscErrorCode LevelHalo::reduce(const double*, double*) const;
template PetscErrorCode LevelHalo::reduce(const float*, float*) const;

}  // namespace hexcut::multigrid
