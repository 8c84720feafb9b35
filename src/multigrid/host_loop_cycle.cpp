#include "multigrid/host_loop_cycle.hpp"

namespace hexcut::multigrid {

PetscErrorCode HostLoopCycle::create(Multigrid& mg, std::unique_ptr<HostLoopCycle>* out) {
  PetscFunctionBeginUser;
  std::unique_ptr<HostLoopCycle> c(new HostLoopCycle(mg));
  PetscCall(mg.loop_levels(&c->levels_));
  c->work_.resize(c->levels_.size());
  for (std::size_t l = 0; l < c->levels_.size(); ++l)
    for (auto& v : c->work_[l]) v.assign(3 * std::size_t(c->levels_[l].view.num_copies), 0.0);
  *out = std::move(c);
  PetscFunctionReturn(0);
}

void HostLoopCycle::solve_coarsest(const double* b, double* x) {
  // The executor interface has no error channel: the first PETSc error is kept for apply().
  if (!coarse_error_) coarse_error_ = mg_.solve_coarsest(b, x);
}

PetscErrorCode HostLoopCycle::apply(const double* b, double* x) {
  PetscFunctionBeginUser;
  auto& b0 = work_[0][0];
  std::copy(b, b + b0.size(), b0.begin());
  coarse_error_ = 0;
  loop::cycle_level(*this, 0, true);
  PetscCall(coarse_error_);
  std::copy(work_[0][1].begin(), work_[0][1].end(), x);
  PetscFunctionReturn(0);
}

}  // namespace hexcut::multigrid
