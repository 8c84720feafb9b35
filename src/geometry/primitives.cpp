// Analytic primitives. Each validates its arguments up front so that a bad deck value
// fails with a message instead of voxelizing to nothing.
#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <string>

#include "geometry/shape.hpp"

namespace hexcut::geometry {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

std::string str(const Eigen::Vector3d& v) {
  std::ostringstream os;
  os.precision(17);
  os << "(" << v.x() << ", " << v.y() << ", " << v.z() << ")";
  return os.str();
}

void require_finite(const Eigen::Vector3d& v, const char* what, const char* name) {
  if (!v.allFinite()) {
    throw std::invalid_argument(std::string(what) + ": " + name + " " + str(v) + " is not finite");
  }
}

Eigen::Vector3d unit_normal(const Eigen::Vector3d& normal, const char* what) {
  require_finite(normal, what, "normal");
  const double n = normal.norm();
  if (!(n > 0.0)) throw std::invalid_argument(std::string(what) + ": normal must be nonzero");
  return normal / n;
}

class Box final : public Shape {
 public:
  Box(const Eigen::Vector3d& lo, const Eigen::Vector3d& hi) : lo_(lo), hi_(hi) {}
  bool contains(const Eigen::Vector3d& p) const override {
    return (p.array() >= lo_.array()).all() && (p.array() <= hi_.array()).all();
  }
  Aabb bounds() const override { return {lo_, hi_}; }
  // Gradient of the box's signed distance: outside, towards p from the nearest box
  // point (a face, edge or corner); inside, the normal of the nearest face.
  Eigen::Vector3d outward_normal(const Eigen::Vector3d& p) const override {
    const Eigen::Vector3d centre = 0.5 * (lo_ + hi_);
    Eigen::Vector3d excess, sign;
    for (int a = 0; a < 3; ++a) {
      excess[a] = std::max(lo_[a] - p[a], p[a] - hi_[a]);
      sign[a] = p[a] < centre[a] ? -1.0 : 1.0;
    }
    if ((excess.array() > 0.0).any()) {
      return excess.cwiseMax(0.0).cwiseProduct(sign).normalized();
    }
    int a;
    excess.maxCoeff(&a);
    return sign[a] * Eigen::Vector3d::Unit(a);
  }

 private:
  Eigen::Vector3d lo_, hi_;
};

class Sphere final : public Shape {
 public:
  Sphere(const Eigen::Vector3d& c, double r) : c_(c), r_(r) {}
  bool contains(const Eigen::Vector3d& p) const override {
    return (p - c_).squaredNorm() <= r_ * r_;
  }
  Aabb bounds() const override {
    const Eigen::Vector3d r = Eigen::Vector3d::Constant(r_);
    return {c_ - r, c_ + r};
  }
  Eigen::Vector3d outward_normal(const Eigen::Vector3d& p) const override {
    const Eigen::Vector3d d = p - c_;
    const double n = d.norm();
    return n > 0.0 ? Eigen::Vector3d(d / n) : Eigen::Vector3d::Zero();
  }

 private:
  Eigen::Vector3d c_;
  double r_;
};

class Cylinder final : public Shape {
 public:
  Cylinder(const Eigen::Vector3d& p0, const Eigen::Vector3d& p1, double r)
      : p0_(p0), p1_(p1), axis_((p1 - p0).normalized()), len_((p1 - p0).norm()), r_(r) {}
  bool contains(const Eigen::Vector3d& p) const override {
    const Eigen::Vector3d d = p - p0_;
    const double t = d.dot(axis_);
    if (t < 0.0 || t > len_) return false;
    return (d - t * axis_).squaredNorm() <= r_ * r_;
  }
  Aabb bounds() const override {
    // The caps are discs; a disc of radius r with unit normal a extends
    // r*sqrt(1 - a_i^2) along axis i.
    const Eigen::Vector3d e =
        r_ * (Eigen::Vector3d::Ones() - axis_.cwiseAbs2()).cwiseMax(0.0).cwiseSqrt();
    return {p0_.cwiseMin(p1_) - e, p0_.cwiseMax(p1_) + e};
  }
  // Gradient of the signed distance, as for the box: the mantle's radial direction or
  // the nearer cap's axis direction, blended outside the rim where both are exceeded.
  Eigen::Vector3d outward_normal(const Eigen::Vector3d& p) const override {
    const Eigen::Vector3d d = p - p0_;
    const double t = d.dot(axis_);
    const Eigen::Vector3d radial = d - t * axis_;
    const double rr = radial.norm();
    const Eigen::Vector3d cap = t < 0.5 * len_ ? Eigen::Vector3d(-axis_) : axis_;
    const double over_mantle = rr - r_, over_cap = std::max(-t, t - len_);
    if (!(rr > 0.0)) return cap;  // on the axis the radial direction is undefined
    const Eigen::Vector3d out = radial / rr;
    if (over_mantle > 0.0 && over_cap > 0.0)
      return (over_mantle * out + over_cap * cap).normalized();
    return over_mantle >= over_cap ? out : cap;
  }

 private:
  Eigen::Vector3d p0_, p1_, axis_;
  double len_, r_;
};

// Unbounded in every direction except along an axis-aligned normal, where the bound
// saves visiting the whole lattice for the common "cut at x = c" case.
Aabb plane_bounds(const Eigen::Vector3d& point, const Eigen::Vector3d& n, double below,
                  double above) {
  Aabb b{Eigen::Vector3d::Constant(-kInf), Eigen::Vector3d::Constant(kInf)};
  for (int a = 0; a < 3; ++a) {
    const int o1 = (a + 1) % 3, o2 = (a + 2) % 3;
    if (n[o1] == 0.0 && n[o2] == 0.0) {
      // n = +-e_a: the shape is point[a] + sign*[-below, above].
      if (n[a] > 0.0) {
        b.lo[a] = std::isfinite(below) ? point[a] - below : -kInf;
        b.hi[a] = point[a] + above;
      } else {
        b.lo[a] = point[a] - above;
        b.hi[a] = std::isfinite(below) ? point[a] + below : kInf;
      }
    }
  }
  return b;
}

class HalfSpace final : public Shape {
 public:
  HalfSpace(const Eigen::Vector3d& point, const Eigen::Vector3d& n) : point_(point), n_(n) {}
  bool contains(const Eigen::Vector3d& p) const override { return (p - point_).dot(n_) <= 0.0; }
  Aabb bounds() const override { return plane_bounds(point_, n_, kInf, 0.0); }
  Eigen::Vector3d outward_normal(const Eigen::Vector3d&) const override { return n_; }

 private:
  Eigen::Vector3d point_, n_;
};

class Slab final : public Shape {
 public:
  Slab(const Eigen::Vector3d& point, const Eigen::Vector3d& n, double half)
      : point_(point), n_(n), half_(half) {}
  bool contains(const Eigen::Vector3d& p) const override {
    return std::abs((p - point_).dot(n_)) <= half_;
  }
  Aabb bounds() const override { return plane_bounds(point_, n_, half_, half_); }
  Eigen::Vector3d outward_normal(const Eigen::Vector3d& p) const override {
    return (p - point_).dot(n_) < 0.0 ? Eigen::Vector3d(-n_) : n_;
  }

 private:
  Eigen::Vector3d point_, n_;
  double half_;
};

}  // namespace

ShapePtr make_box(const Eigen::Vector3d& lo, const Eigen::Vector3d& hi) {
  require_finite(lo, "box", "lo");
  require_finite(hi, "box", "hi");
  if (!(lo.array() < hi.array()).all()) {
    throw std::invalid_argument("box: lo " + str(lo) + " must be < hi " + str(hi) +
                                " in every component");
  }
  return std::make_shared<Box>(lo, hi);
}

ShapePtr make_sphere(const Eigen::Vector3d& centre, double radius) {
  require_finite(centre, "sphere", "centre");
  if (!(radius > 0.0) || !std::isfinite(radius)) {
    throw std::invalid_argument("sphere: radius must be positive and finite, got " +
                                std::to_string(radius));
  }
  return std::make_shared<Sphere>(centre, radius);
}

ShapePtr make_cylinder(const Eigen::Vector3d& p0, const Eigen::Vector3d& p1, double radius) {
  require_finite(p0, "cylinder", "p0");
  require_finite(p1, "cylinder", "p1");
  if (!((p1 - p0).norm() > 0.0)) {
    throw std::invalid_argument("cylinder: end points p0 and p1 must differ, both are " + str(p0));
  }
  if (!(radius > 0.0) || !std::isfinite(radius)) {
    throw std::invalid_argument("cylinder: radius must be positive and finite, got " +
                                std::to_string(radius));
  }
  return std::make_shared<Cylinder>(p0, p1, radius);
}

ShapePtr make_half_space(const Eigen::Vector3d& point, const Eigen::Vector3d& normal) {
  require_finite(point, "half_space", "point");
  return std::make_shared<HalfSpace>(point, unit_normal(normal, "half_space"));
}

ShapePtr make_slab(const Eigen::Vector3d& point, const Eigen::Vector3d& normal,
                   double half_thickness) {
  require_finite(point, "slab", "point");
  if (!(half_thickness >= 0.0) || !std::isfinite(half_thickness)) {
    throw std::invalid_argument("slab: half_thickness must be >= 0 and finite, got " +
                                std::to_string(half_thickness));
  }
  return std::make_shared<Slab>(point, unit_normal(normal, "slab"), half_thickness);
}

}  // namespace hexcut::geometry
