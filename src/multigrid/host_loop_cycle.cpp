#include "multigrid/host_loop_cycle.hpp"

#include <type_traits>

namespace hexcut::multigrid {

namespace {

template <class S>
MPI_Datatype mpi_type() {
  return std::is_same_v<S, double> ? MPI_DOUBLE : MPI_FLOAT;
}

/// The star forest of one level's ghosts (null without ghosts on any rank): leaves the 3 DOFs
/// of each ghost copy (local entries from 3 num_copies on), roots its owner's 3 DOFs.
PetscErrorCode ghost_sf(MPI_Comm comm, const LoopLevelArrays& a, PetscSF* sf) {
  PetscFunctionBeginUser;
  *sf = nullptr;
  const auto n = std::int64_t(a.ghost_rank.size());
  std::int64_t any = n;
  PetscCallMPI(MPI_Allreduce(MPI_IN_PLACE, &any, 1, MPI_INT64_T, MPI_MAX, comm));
  if (any == 0) PetscFunctionReturn(0);
  std::vector<PetscInt> leaf(std::size_t(3 * n));
  std::vector<PetscSFNode> root(std::size_t(3 * n));
  for (std::int64_t g = 0; g < n; ++g)
    for (int c = 0; c < 3; ++c) {
      const auto k = std::size_t(3 * g + c);
      leaf[k] = PetscInt(3 * (a.view.num_copies + g) + c);
      root[k].rank = a.ghost_rank[std::size_t(g)];
      root[k].index = PetscInt(3 * std::int64_t(a.ghost_index[std::size_t(g)]) + c);
    }
  PetscCall(PetscSFCreate(comm, sf));
  PetscCall(PetscSFSetGraph(*sf, PetscInt(3 * a.view.num_copies), PetscInt(3 * n), leaf.data(),
                            PETSC_COPY_VALUES, root.data(), PETSC_COPY_VALUES));
  PetscCall(PetscSFSetUp(*sf));
  PetscFunctionReturn(0);
}

}  // namespace

template <class S>
PetscErrorCode HostLoopCycleOf<S>::create(Multigrid& mg, std::unique_ptr<HostLoopCycleOf>* out) {
  PetscFunctionBeginUser;
  std::unique_ptr<HostLoopCycleOf> c(new HostLoopCycleOf(mg));
  PetscCall(mg.loop_levels(&c->levels_));
  const auto L = c->levels_.size();
  c->work_.resize(L);
  c->ghosts_.assign(L, nullptr);
  for (std::size_t l = 0; l < L; ++l) {
    for (auto& v : c->work_[l]) v.assign(3 * std::size_t(c->levels_[l].view.num_local), S(0));
    PetscCall(ghost_sf(mg.comm(), c->levels_[l], &c->ghosts_[l]));
  }
  if constexpr (std::is_same_v<S, float>) {
    const auto n = 3 * std::size_t(c->levels_.back().view.num_copies);
    c->coarse_b_.resize(n);
    c->coarse_x_.resize(n);
    c->single_.resize(L);
    for (std::size_t l = 0; l < L; ++l) {
      auto& a = c->levels_[l];
      auto& f = c->single_[l];
      LoopLevel& v = a.view;
      const auto copies = std::size_t(v.num_copies);
      if (v.diag_inv) f[0].assign(v.diag_inv, v.diag_inv + 9 * copies);
      f[1].assign(a.mask.begin(), a.mask.end());
      f[2].assign(a.prolong_weight.begin(), a.prolong_weight.end());
      f[3].assign(a.restrict_weight.begin(), a.restrict_weight.end());
      f[4].assign(a.prolong_block.begin(), a.prolong_block.end());
      f[5].assign(a.restrict_block.begin(), a.restrict_block.end());
      const auto data = [](const std::vector<float>& u) { return u.empty() ? nullptr : u.data(); };
      v.diag_inv_single = data(f[0]);
      v.mask_single = data(f[1]);
      v.prolong_weight_single = data(f[2]);
      v.restrict_weight_single = data(f[3]);
      v.prolong_block_single = data(f[4]);
      v.restrict_block_single = data(f[5]);
      v.diag_inv = v.mask = v.prolong_weight = v.restrict_weight = nullptr;
      v.prolong_block = v.restrict_block = nullptr;
      for (auto* d :
           {&a.mask, &a.prolong_weight, &a.restrict_weight, &a.prolong_block, &a.restrict_block})
        std::vector<double>().swap(*d);
    }
  }
  *out = std::move(c);
  PetscFunctionReturn(0);
}

template <class S>
HostLoopCycleOf<S>::~HostLoopCycleOf() {
  for (auto& sf : ghosts_) PetscSFDestroy(&sf);
}

// exchange, accumulate and solve_coarsest are collective: after an error every rank still makes
// each call (keeping only the first error for apply()), so that no rank waits on one that
// stopped.
template <class S>
void HostLoopCycleOf<S>::exchange(int l, S* x) {
  PetscSF sf = ghosts_[std::size_t(l)];
  if (!sf) return;
  keep(PetscSFBcastBegin(sf, mpi_type<S>(), x, x, MPI_REPLACE));
  keep(PetscSFBcastEnd(sf, mpi_type<S>(), x, x, MPI_REPLACE));
}

template <class S>
void HostLoopCycleOf<S>::accumulate(int l, S* y) {
  PetscSF sf = ghosts_[std::size_t(l)];
  if (!sf) return;
  keep(PetscSFReduceBegin(sf, mpi_type<S>(), y, y, MPI_SUM));
  keep(PetscSFReduceEnd(sf, mpi_type<S>(), y, y, MPI_SUM));
}

template <class S>
void HostLoopCycleOf<S>::solve_coarsest(const S* b, S* x) {
  if constexpr (std::is_same_v<S, double>) {
    keep(mg_.solve_coarsest(b, x));
  } else {
    // The factorization is double's: the coarsest level's vectors (a few thousand DOFs) pass
    // through double arrays.
    std::copy(b, b + coarse_b_.size(), coarse_b_.begin());
    keep(mg_.solve_coarsest(coarse_b_.data(), coarse_x_.data()));
    std::copy(coarse_x_.begin(), coarse_x_.end(), x);
  }
}

template <class S>
PetscErrorCode HostLoopCycleOf<S>::apply(const double* b, double* x) {
  PetscFunctionBeginUser;
  const auto n = 3 * std::size_t(levels_[0].view.num_copies);  // owned DOFs
  std::copy(b, b + n, work_[0][0].begin());
  error_ = 0;
  loop::cycle_level(*this, 0, true);
  PetscCall(error_);
  std::copy_n(work_[0][1].begin(), n, x);
  PetscFunctionReturn(0);
}

template class HostLoopCycleOf<double>;
template class HostLoopCycleOf<float>;

namespace {
template <class S>
PetscErrorCode adopt(Multigrid& mg, std::unique_ptr<CycleBackend>* out) {
  PetscFunctionBeginUser;
  std::unique_ptr<HostLoopCycleOf<S>> c;
  PetscCall(HostLoopCycleOf<S>::create(mg, &c));
  *out = std::move(c);
  PetscFunctionReturn(0);
}
}  // namespace

PetscErrorCode host_loop_cycle(Multigrid& mg, Precision precision,
                               std::unique_ptr<CycleBackend>* out) {
  return precision == Precision::single ? adopt<float>(mg, out) : adopt<double>(mg, out);
}

}  // namespace hexcut::multigrid
