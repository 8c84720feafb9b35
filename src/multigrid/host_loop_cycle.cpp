#include "multigrid/host_loop_cycle.hpp"

namespace hexcut::multigrid {

PetscErrorCode HostLoopCycle::create(Multigrid& mg, std::unique_ptr<HostLoopCycle>* out) {
  PetscFunctionBeginUser;
  std::unique_ptr<HostLoopCycle> c(new HostLoopCycle(mg));
  PetscCall(mg.loop_levels(&c->levels_));
  c->work_.resize(c->levels_.size());
  for (std::size_t l = 0; l < c->levels_.size(); ++l)
    for (auto& v : c->work_[l]) v.assign(3 * std::size_t(c->levels_[l].view.num_copies), 0.0);
  const int last = mg.num_levels() - 1;
  PetscCall(mg.create_vector(last, &c->coarse_b_));
  PetscCall(mg.create_vector(last, &c->coarse_x_));
  *out = std::move(c);
  PetscFunctionReturn(0);
}

HostLoopCycle::~HostLoopCycle() {
  VecDestroy(&coarse_b_);
  VecDestroy(&coarse_x_);
}

void HostLoopCycle::solve_coarsest(const double* b, double* x) {
  // The executor interface has no error channel: the first PETSc error is kept for apply().
  auto solve = [&]() -> PetscErrorCode {
    PetscFunctionBeginUser;
    PetscCall(VecPlaceArray(coarse_b_, b));
    PetscCall(VecPlaceArray(coarse_x_, x));
    PetscCall(mg_.solve_coarsest(coarse_b_, coarse_x_));
    PetscCall(VecResetArray(coarse_b_));
    PetscCall(VecResetArray(coarse_x_));
    PetscFunctionReturn(0);
  };
  if (!coarse_error_) coarse_error_ = solve();
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
