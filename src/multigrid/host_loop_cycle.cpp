#include "multigrid/host_loop_cycle.hpp"

#include <type_traits>

namespace hexcut::multigrid {

template <class S>
PetscErrorCode HostLoopCycleOf<S>::create(Multigrid& mg, std::unique_ptr<HostLoopCycleOf>* out) {
  PetscFunctionBeginUser;
  std::unique_ptr<HostLoopCycleOf> c(new HostLoopCycleOf(mg));
  PetscCall(mg.loop_levels(&c->levels_));
  c->work_.resize(c->levels_.size());
  for (std::size_t l = 0; l < c->levels_.size(); ++l)
    for (auto& v : c->work_[l]) v.assign(3 * std::size_t(c->levels_[l].view.num_copies), S(0));
  if (!std::is_same_v<S, double>) {
    const auto n = 3 * std::size_t(c->levels_.back().view.num_copies);
    c->coarse_b_.resize(n);
    c->coarse_x_.resize(n);
  }
  *out = std::move(c);
  PetscFunctionReturn(0);
}

template <class S>
void HostLoopCycleOf<S>::solve_coarsest(const S* b, S* x) {
  // The executor interface has no error channel: the first PETSc error is kept for apply().
  if (coarse_error_) return;
  if constexpr (std::is_same_v<S, double>) {
    coarse_error_ = mg_.solve_coarsest(b, x);
  } else {
    // The factorization is double's: the coarsest level's vectors (a few thousand DOFs) pass
    // through double arrays.
    std::copy(b, b + coarse_b_.size(), coarse_b_.begin());
    coarse_error_ = mg_.solve_coarsest(coarse_b_.data(), coarse_x_.data());
    std::copy(coarse_x_.begin(), coarse_x_.end(), x);
  }
}

template <class S>
PetscErrorCode HostLoopCycleOf<S>::apply(const double* b, double* x) {
  PetscFunctionBeginUser;
  auto& b0 = work_[0][0];
  std::copy(b, b + b0.size(), b0.begin());
  coarse_error_ = 0;
  loop::cycle_level(*this, 0, true);
  PetscCall(coarse_error_);
  std::copy(work_[0][1].begin(), work_[0][1].end(), x);
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
