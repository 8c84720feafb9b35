#include "deck/expression.hpp"

#include <muParser.h>

#include <cmath>
#include <stdexcept>

#include "deck/deck.hpp"

namespace hexcut::deck {

struct Expression::Parser {
  mu::Parser parser;
  // muParser keeps the addresses of the variables: they live next to it, in this one
  // heap object, for as long as the parser does.
  double x = 0, y = 0, z = 0, t = 0;
};

namespace {

/// muParser's message with the position, which some messages ("Missing parenthesis")
/// leave out, and the expression.
std::string describe(const mu::Parser::exception_type& e, const std::string& text) {
  std::string msg = e.GetMsg();
  while (!msg.empty() && (msg.back() == '.' || msg.back() == ' ')) msg.pop_back();
  if (msg.find("position") == std::string::npos && e.GetPos() >= 0)
    msg += " at position " + std::to_string(e.GetPos());
  return msg + " in '" + text + "'";
}

}  // namespace

Expression::Expression(const std::string& text) : parser_(std::make_unique<Parser>()), text_(text) {
  auto& p = parser_->parser;
  try {
    p.DefineVar("x", &parser_->x);
    p.DefineVar("y", &parser_->y);
    p.DefineVar("z", &parser_->z);
    p.DefineVar("t", &parser_->t);
    p.SetExpr(text);
    // GetUsedVar parses without keeping the bytecode, so it comes first; SetExpr only
    // stores the text, and the first evaluation parses it into the bytecode kept.
    const auto& used = p.GetUsedVar();
    uses_t_ = used.count("t") > 0;
    const bool constant = used.empty();
    const double sample = p.Eval();
    if (p.GetNumResults() != 1)
      throw std::invalid_argument("expression error: " + std::to_string(p.GetNumResults()) +
                                  " comma-separated values where one is expected in '" + text +
                                  "'");
    if (constant && !std::isfinite(sample))
      throw std::invalid_argument("expression error: the value is not finite in '" + text + "'");
  } catch (const mu::Parser::exception_type& e) {
    throw std::invalid_argument("expression error: " + describe(e, text));
  }
}

Expression::~Expression() = default;

double Expression::operator()(const Eigen::Vector3d& x, double t) const {
  parser_->x = x[0];
  parser_->y = x[1];
  parser_->z = x[2];
  parser_->t = t;
  return parser_->parser.Eval();
}

double Field::operator()(const Eigen::Vector3d& x, double t) const {
  return expression ? (*expression)(x, t) : function(t);
}

bool Field::depends_on_time() const {
  return expression ? expression->depends_on_time() : function.kind != TimeFunction::Kind::constant;
}

}  // namespace hexcut::deck
