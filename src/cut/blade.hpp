// Blades as triangle soups and the schedule of cut events (doc/theory.md, "Cutting"). A deck cut
// becomes one event (mesh, polygon, cylinder: at its time) or, for a scalpel swept over a window,
// one event per path segment: the quad between two consecutive positions of the edge, at the time
// the edge reaches the second one.
#pragma once

#include <Eigen/Core>
#include <vector>

#include "deck/deck.hpp"

namespace hexcut::cut {

struct Triangle {
  Eigen::Vector3d a, b, c;
  /// Unit normal (b - a) x (c - a), zero for a degenerate triangle.
  Eigen::Vector3d normal() const;
  double area() const { return 0.5 * (b - a).cross(c - a).norm(); }
};

/// The whole blade of a deck cut (a scalpel: every swept quad).
std::vector<Triangle> blade_triangles(const deck::Blade& blade);

struct CutEvent {
  double time = 0.0;  // [s]
  int cut_id = 0;     // 1-based deck order
  std::vector<Triangle> triangles;
};

/// Every event of the deck's cuts, sorted by time (stable: deck order within a time).
std::vector<CutEvent> cut_schedule(const std::vector<deck::Cut>& cuts);

}  // namespace hexcut::cut
