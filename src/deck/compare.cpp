#include "deck/compare.hpp"

#include <yaml-cpp/yaml.h>

#include <cmath>
#include <cstdlib>
#include <map>
#include <set>

namespace hexcut::deck {
namespace {

/// A scalar as a number, when all of it is one (YAML's float forms included).
bool as_number(const YAML::Node& n, double* value) {
  try {
    *value = n.as<double>();
    return true;
  } catch (const YAML::Exception&) {
    return false;
  }
}

void compare(const YAML::Node& a, const YAML::Node& b, const std::string& path,
             const std::set<std::string>& ignored, std::vector<std::string>* out) {
  if (ignored.count(path)) return;
  const bool has_a = a.IsDefined() && !a.IsNull(), has_b = b.IsDefined() && !b.IsNull();
  if (!has_a || !has_b) {
    if (has_a != has_b) out->push_back(path);
    return;
  }
  if (a.Type() != b.Type()) {
    out->push_back(path);
  } else if (a.IsScalar()) {
    double x, y;
    const bool numbers = as_number(a, &x) && as_number(b, &y);
    if (numbers ? !(x == y || (std::isnan(x) && std::isnan(y))) : a.Scalar() != b.Scalar())
      out->push_back(path);
  } else if (a.IsSequence()) {
    const std::size_t n = std::max(a.size(), b.size());
    for (std::size_t i = 0; i < n; ++i)
      compare(i < a.size() ? a[i] : YAML::Node(), i < b.size() ? b[i] : YAML::Node(),
              path + "[" + std::to_string(i) + "]", ignored, out);
  } else if (a.IsMap()) {
    std::map<std::string, std::pair<YAML::Node, YAML::Node>> keys;
    for (const auto& kv : a) keys[kv.first.Scalar()].first = kv.second;
    for (const auto& kv : b) keys[kv.first.Scalar()].second = kv.second;
    for (const auto& [key, nodes] : keys)
      compare(nodes.first, nodes.second, path.empty() ? key : path + "." + key, ignored, out);
  }
}

}  // namespace

std::vector<std::string> physics_differences(const std::string& before, const std::string& now) {
  YAML::Node a, b;
  try {
    a = YAML::Load(before);
    b = YAML::Load(now);
  } catch (const YAML::Exception&) {
    return {"(deck)"};
  }
  if (!a.IsMap() || !b.IsMap()) return {"(deck)"};
  static const std::set<std::string> ignored = {"analysis.steps", "analysis.end_time",
                                                "analysis.tolerance", "analysis.max_iterations"};
  std::vector<std::string> out;
  for (const char* section :
       {"lattice", "materials", "geometry", "boundary", "cuts", "analysis", "discretization"})
    compare(a[section], b[section], section, ignored, &out);
  return out;
}

}  // namespace hexcut::deck
