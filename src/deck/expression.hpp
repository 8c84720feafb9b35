// Expressions of space and time in the deck (doc/user-guide.md "Expressions"): prescribed
// displacements, tractions and pressures that vary with the reference position and time.
// A thin wrapper around muParser (https://beltoforion.de/en/muparser/), compiled once
// when the deck is parsed and evaluated from its bytecode afterwards.
#pragma once

#include <Eigen/Core>
#include <memory>
#include <string>

namespace hexcut::deck {

/// A scalar expression in muParser syntax of the variables x, y, z [m] (reference
/// position) and t [s]. Constructed once; evaluation reuses the compiled bytecode.
/// Not thread-safe: an evaluation writes the variables of the one parser it holds
/// (hexcut evaluates on one thread per rank). Not copyable; share it by pointer.
class Expression {
 public:
  /// Compiles `text` and evaluates it once at x = y = z = t = 0, so that errors that
  /// muParser finds only on evaluation show up here. Throws std::invalid_argument with
  /// muParser's message and the position (0-based) in `text`: syntax errors, unknown
  /// variables or functions, several comma-separated results, and an expression of no
  /// variable that is not finite.
  explicit Expression(const std::string& text);
  ~Expression();
  Expression(const Expression&) = delete;
  Expression& operator=(const Expression&) = delete;

  /// The value at reference position `x` [m] and time `t` [s]; may be inf or nan
  /// (1/x at x = 0): callers check.
  double operator()(const Eigen::Vector3d& x, double t) const;
  /// Whether t occurs in the expression (else the value is fixed in time).
  bool depends_on_time() const { return uses_t_; }
  const std::string& text() const { return text_; }

 private:
  struct Parser;  // muParser's parser and the variables it points to
  std::unique_ptr<Parser> parser_;
  std::string text_;
  bool uses_t_ = false;
};

}  // namespace hexcut::deck
