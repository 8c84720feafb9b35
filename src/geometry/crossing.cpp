#include "geometry/crossing.hpp"

#include <cmath>
#include <stdexcept>

namespace hexcut::geometry {
namespace {

// Index of the operation that decides membership at p (the last add or subtract whose
// shape contains p), or -1 when none does (outside).
int deciding_op(const std::vector<GeometryOp>& ops, const Eigen::Vector3d& p) {
  for (int i = static_cast<int>(ops.size()) - 1; i >= 0; --i) {
    if (!ops[i].shape) throw std::invalid_argument("geometry op: null shape");
    if (ops[i].mode != OpMode::assign && ops[i].shape->contains(p)) return i;
  }
  return -1;
}

bool is_inside(const std::vector<GeometryOp>& ops, int op) {
  return op >= 0 && ops[op].mode == OpMode::add;
}

}  // namespace

bool inside_after(const std::vector<GeometryOp>& ops, const Eigen::Vector3d& p) {
  return is_inside(ops, deciding_op(ops, p));
}

std::optional<Crossing> find_crossing(const std::vector<GeometryOp>& ops,
                                      const Eigen::Vector3d& inside, const Eigen::Vector3d& outside,
                                      int iterations) {
  int op_in = deciding_op(ops, inside), op_out = deciding_op(ops, outside);
  if (!is_inside(ops, op_in) || is_inside(ops, op_out)) return std::nullopt;
  const Eigen::Vector3d d = outside - inside;
  double lo = 0.0, hi = 1.0;  // inside at lo, outside at hi
  // The segment usually holds one crossing of the surface that decides (the inside point's
  // add, or the outside point's subtract): a shape that can intersect the segment exactly
  // (a triangle mesh, whose every membership test is a winding number) gives it at once,
  // accepted when membership flips across it; otherwise, bisection.
  bool exact = false;
  if (iterations > 0) {
    const int op = op_in > op_out ? op_in : op_out;
    if (const auto t = ops[op].shape->surface_crossing(inside, outside)) {
      const double a = std::max(0.0, *t - 1e-9), b = std::min(1.0, *t + 1e-9);
      const int before = deciding_op(ops, inside + a * d), after = deciding_op(ops, inside + b * d);
      if (is_inside(ops, before) && !is_inside(ops, after)) {
        lo = a, hi = b, op_in = before, op_out = after;
        exact = true;
      }
    }
  }
  for (int it = 0; it < iterations && !exact; ++it) {
    const double mid = 0.5 * (lo + hi);
    const int op = deciding_op(ops, inside + mid * d);
    if (is_inside(ops, op)) {
      lo = mid;
      op_in = op;
    } else {
      hi = mid;
      op_out = op;
    }
  }
  Crossing c;
  c.t = 0.5 * (lo + hi);
  const Eigen::Vector3d x = inside + c.t * d;
  // Between the bracketing points either the inside point's add stops containing the
  // outside point (its surface is crossed; op_in > op_out, since a later or equal op
  // containing the outside point would decide there), or a later subtract starts to
  // contain it (op_out > op_in, and then it cannot contain the inside point).
  const Eigen::Vector3d n = op_in > op_out ? ops[op_in].shape->outward_normal(x)
                                           : Eigen::Vector3d(-ops[op_out].shape->outward_normal(x));
  const double len = n.norm();
  c.normal = len > 0.0 && std::isfinite(len) ? Eigen::Vector3d(n / len) : d.normalized();
  return c;
}

}  // namespace hexcut::geometry
