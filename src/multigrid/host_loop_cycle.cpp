#include "multigrid/host_loop_cycle.hpp"

#include <type_traits>

namespace hexcut::multigrid {

template <class S>
PetscErrorCode HostLoopCycleOf<S>::create(Multigrid& mg, std::unique_ptr<HostLoopCycleOf>* out) {
  PetscFunctionBeginUser;
  std::unique_ptr<HostLoopCycleOf> c(new HostLoopCycleOf(mg));
  PetscCall(mg.loop_levels(&c->levels_));
  const auto L = c->levels_.size();
  c->work_.resize(L);
  c->halos_.resize(L);
  c->packed_.resize(L);
  for (std::size_t l = 0; l < L; ++l) {
    for (auto& v : c->work_[l]) v.assign(3 * std::size_t(c->levels_[l].view.num_local), S(0));
    PetscCall(LevelHalo::create(mg.comm(), c->levels_[l], &c->halos_[l]));
    c->packed_[l].assign(3 * c->halos_[l]->send().size(), S(0));
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
      const auto data = [](const std::vector<float>& u) { return u.empty() ? nullptr : u.data(); };
      v.diag_inv_single = data(f[0]);
      v.mask_single = data(f[1]);
      v.prolong_weight_single = data(f[2]);
      v.restrict_weight_single = data(f[3]);
      v.diag_inv = v.mask = v.prolong_weight = v.restrict_weight = nullptr;
      for (auto* d : {&a.mask, &a.prolong_weight, &a.restrict_weight})
        std::vector<double>().swap(*d);
    }
  }
  *out = std::move(c);
  PetscFunctionReturn(0);
}

// exchange, accumulate and solve_coarsest are collective: after an error every rank still makes
// each call (keeping only the first error for apply()), so that no rank waits on one that
// stopped.
template <class S>
void HostLoopCycleOf<S>::exchange(int l, S* x) {
  const LevelHalo& h = *halos_[std::size_t(l)];
  if (h.empty()) return;
  S* buf = packed_[std::size_t(l)].data();
  backend::for_each(std::int64_t(h.send().size()), PackCopies<S>{h.send().data(), x, buf});
  keep(h.broadcast(buf, x + 3 * levels_[std::size_t(l)].view.num_copies));
}

template <class S>
void HostLoopCycleOf<S>::accumulate(int l, S* y) {
  const LevelHalo& h = *halos_[std::size_t(l)];
  if (h.empty()) return;
  S* buf = packed_[std::size_t(l)].data();
  keep(h.reduce(y + 3 * levels_[std::size_t(l)].view.num_copies, buf));
  backend::for_each(std::int64_t(h.send().size()), AddCopies<S>{h.send().data(), buf, y});
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
