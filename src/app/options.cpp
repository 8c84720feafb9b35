#include "app/options.hpp"

#include <petscsys.h>

#include <algorithm>
#include <array>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <sstream>
#include <vector>

#include "common/errors.hpp"
#include "common/petsc_check.hpp"

namespace hexcut::app {
namespace {

const std::vector<std::string> kKnown = {
    "-hexcut_composite_carry",  "-hexcut_composite_midpoint", "-hexcut_composite_rotate",
    "-hexcut_io_buffer",        "-hexcut_max_steps",          "-hexcut_memory_available",
    "-hexcut_output_directory", "-hexcut_partition",          "-hexcut_refine",
    "-hexcut_repartition",      "-hexcut_residual_history",   "-hexcut_superblock"};

std::string lower(std::string s) {
  for (auto& ch : s) ch = char(std::tolower(static_cast<unsigned char>(ch)));
  return s;
}

/// Levenshtein distance, for "did you mean".
std::size_t edit_distance(const std::string& a, const std::string& b) {
  std::vector<std::size_t> row(b.size() + 1);
  for (std::size_t j = 0; j <= b.size(); ++j) row[j] = j;
  for (std::size_t i = 1; i <= a.size(); ++i) {
    std::size_t diag = row[0];
    row[0] = i;
    for (std::size_t j = 1; j <= b.size(); ++j) {
      const std::size_t up = row[j];
      row[j] = std::min({row[j] + 1, row[j - 1] + 1, diag + (a[i - 1] != b[j - 1])});
      diag = up;
    }
  }
  return row[b.size()];
}

/// The option's value as given, or nullopt-like empty flag when absent.
bool option_string(const char* name, std::string* value) {
  char buf[PETSC_MAX_PATH_LEN] = "";
  PetscBool set = PETSC_FALSE;
  check_petsc(PetscOptionsGetString(nullptr, nullptr, name, buf, sizeof buf, &set), name);
  *value = buf;
  return set;
}

std::int64_t positive_integer(const char* name, const std::string& text) {
  errno = 0;
  char* end = nullptr;
  const long long v = std::strtoll(text.c_str(), &end, 10);
  if (text.empty() || *end != '\0' || errno == ERANGE || v < 1)
    throw InputError(std::string(name) + " must be an integer >= 1, got '" + text + "'");
  return v;
}

double positive_real(const char* name, const std::string& text) {
  errno = 0;
  char* end = nullptr;
  const double v = std::strtod(text.c_str(), &end);
  if (text.empty() || *end != '\0' || errno == ERANGE || !(v > 0) || !std::isfinite(v))
    throw InputError(std::string(name) + " must be a number > 0, got '" + text + "'");
  return v;
}

}  // namespace

std::set<std::string> options_in_database() {
  char* all = nullptr;
  check_petsc(PetscOptionsGetAll(nullptr, &all), "PetscOptionsGetAll");
  std::set<std::string> names;
  std::istringstream in(all ? all : "");
  std::string token;
  // Names are "-" followed by a letter; values may be negative numbers ("-3", "-.5").
  while (in >> token)
    if (token.size() > 1 && token[0] == '-' && std::isalpha(static_cast<unsigned char>(token[1])))
      names.insert(lower(token));
  PetscFree(all);
  return names;
}

HexcutOptions read_hexcut_options() {
  for (const auto& name : options_in_database()) {
    if (name.rfind("-hexcut_", 0) != 0 ||
        std::find(kKnown.begin(), kKnown.end(), name) != kKnown.end())
      continue;
    const auto best = *std::min_element(kKnown.begin(), kKnown.end(), [&](auto& a, auto& b) {
      return edit_distance(name, a) < edit_distance(name, b);
    });
    std::string known;
    for (const auto& k : kKnown) known += (known.empty() ? "" : ", ") + k;
    throw InputError("unknown option '" + name + "'" +
                     (edit_distance(name, best) <= 3 ? " (did you mean " + best + "?)" : "") +
                     "; hexcut's options are " + known);
  }
  HexcutOptions o;
  std::string value;
  if (option_string("-hexcut_max_steps", &value))
    o.max_steps = positive_integer("-hexcut_max_steps", value);
  if (option_string("-hexcut_superblock", &value)) {
    const auto n = positive_integer("-hexcut_superblock", value);
    if ((n & (n - 1)) != 0 || n > 1024)
      throw InputError("-hexcut_superblock must be a power of two between 1 and 1024, got " +
                       value);
    o.superblock = int(n);
  }
  if (option_string("-hexcut_residual_history", &value) && value.empty())
    throw InputError("-hexcut_residual_history needs a file name");
  if (option_string("-hexcut_refine", &value)) o.refine = positive_real("-hexcut_refine", value);
  if (option_string("-hexcut_partition", &value)) {
    using topology::PartitionMethod;
    bool found = false;
    for (auto m : {PartitionMethod::metis, PartitionMethod::ptscotch, PartitionMethod::sfc})
      if (lower(value) == topology::method_name(m)) o.partition = m, found = true;
    if (!found)
      throw InputError("-hexcut_partition must be metis, ptscotch or sfc, got '" + value + "'");
  }
  if (option_string("-hexcut_repartition", &value)) {
    errno = 0;
    char* end = nullptr;
    const double v = std::strtod(value.c_str(), &end);
    if (value.empty() || *end != '\0' || !std::isfinite(v) || !(v == 0 || v >= 1))
      throw InputError(
          "-hexcut_repartition must be 0 (never) or a DOF imbalance max/mean >= 1, "
          "got '" +
          value + "'");
    o.repartition = v;
  }
  if (option_string("-hexcut_io_buffer", &value)) {
    errno = 0;
    char* end = nullptr;
    const long long v = std::strtoll(value.c_str(), &end, 10);
    if (value.empty() || *end != '\0' || errno == ERANGE || v < 0 || v > 4096)
      throw InputError(
          "-hexcut_io_buffer must be an integer number of MiB from 0 (the MPI library's "
          "default) to 4096, got '" +
          value + "'");
    o.io_buffer_mib = v;
  }
  if (option_string("-hexcut_output_directory", &value)) {
    if (value.empty()) throw InputError("-hexcut_output_directory needs a directory");
    o.output_directory = value;
  }
  return o;
}

deck::Deck apply_overrides(const deck::Deck& deck, const HexcutOptions& options) {
  deck::Deck d = deck;
  if (!options.output_directory.empty()) d.output.directory = options.output_directory;
  if (options.refine != 1.0) {
    auto& s = d.lattice;
    s.h /= options.refine;
    std::array<double, 3> n{};
    for (int a = 0; a < 3; ++a)
      // The relative slack keeps 10 * 1.2 from becoming 13 cells through round-off.
      n[a] = std::max(1.0, std::ceil(double(s.dims[a]) * options.refine - 1e-9));
    if (n[0] * n[1] * n[2] > 2.0e9) {
      char what[256];
      std::snprintf(
          what, sizeof what,
          "-hexcut_refine: the refined lattice has %.15g x %.15g x %.15g cells, more than "
          "2e9; hexcut uses 32-bit cell indices",
          n[0], n[1], n[2]);
      throw InputError(what);
    }
    for (int a = 0; a < 3; ++a) s.dims[a] = int(n[a]);
  }
  return d;
}

void warn_unused_options(MPI_Comm comm, const std::set<std::string>& user_options) {
  PetscBool options_left = PETSC_FALSE, set = PETSC_FALSE;
  check_petsc(PetscOptionsGetBool(nullptr, nullptr, "-options_left", &options_left, &set),
              "-options_left");
  if (set) return;  // PETSc reports them itself at PetscFinalize
  PetscInt n = 0;
  char **names = nullptr, **values = nullptr;
  check_petsc(PetscOptionsLeftGet(nullptr, &n, &names, &values), "PetscOptionsLeftGet");
  std::vector<std::string> lines;
  for (PetscInt i = 0; i < n; ++i) {
    const std::string name = lower(std::string("-") + names[i]);
    if (!user_options.count(name)) continue;  // one of hexcut's defaults for another solver
    lines.push_back("Option left: name:" + name +
                    (values[i] ? std::string(" value: ") + values[i] : std::string(" (no value)")));
  }
  check_petsc(PetscOptionsLeftRestore(nullptr, &n, &names, &values), "PetscOptionsLeftRestore");
  if (lines.empty()) return;
  // The wording of PETSc's own PetscOptionsLeft report.
  PetscPrintf(comm,
              "WARNING! There are options you set that were not used!\n"
              "WARNING! could be spelling mistake, etc!\n");
  if (lines.size() == 1)
    PetscPrintf(comm, "There is one unused database option. It is:\n");
  else
    PetscPrintf(comm, "There are %d unused database options. They are:\n", int(lines.size()));
  for (const auto& l : lines) PetscPrintf(comm, "%s\n", l.c_str());
}

}  // namespace hexcut::app
