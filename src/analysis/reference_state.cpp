#include "analysis/reference_state.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

#include "common/errors.hpp"
#include "output/h5_file.hpp"
#include "output/result_writer.hpp"

namespace hexcut::analysis {

ReferenceState::ReferenceState(MPI_Comm comm, const deck::Compare& cmp, const LatticeSpec& lattice)
    : comm_(comm), path_(cmp.reference), where_(cmp.where), lattice_(lattice) {
  auto fail = [&](const std::string& msg) {
    throw InputError(where_.prefix() + "compare.reference '" + path_ + "': " + msg);
  };
  try {
    auto f = output::H5File::open(path_, comm_, output::H5File::Access::kReadOnly);
    if (!f.has_attribute("/", "format") ||
        f.read_attribute_string("/", "format") != "hexcut-result")
      fail("not a hexcut result file");
    const auto origin = f.read_attribute_doubles("/mesh", "lattice_origin");
    const double h = f.read_attribute_double("/mesh", "lattice_h");
    const auto dims = f.read_attribute_int64s("/mesh", "lattice_dims");
    bool same = origin.size() == 3 && dims.size() == 3 && h == lattice.h;
    for (int d = 0; d < 3 && same; ++d)
      same = origin[d] == lattice.origin[d] && dims[d] == lattice.dims[d];
    if (!same) {
      char msg[300];
      std::snprintf(msg, sizeof msg,
                    "its lattice (h %g m, %lld x %lld x %lld cells) is not this deck's (h %g m, "
                    "%d x %d x %d cells, same origin needed): cells cannot be compared",
                    h, dims.size() == 3 ? (long long)dims[0] : 0LL,
                    dims.size() == 3 ? (long long)dims[1] : 0LL,
                    dims.size() == 3 ? (long long)dims[2] : 0LL, lattice.h, lattice.dims[0],
                    lattice.dims[1], lattice.dims[2]);
      fail(msg);
    }
    if (f.is_group("/steps"))
      for (const auto& name : f.list("/steps")) {
        const std::string g = "/steps/" + name;
        if (!f.is_group(g) || !f.has_attribute(g, "complete") ||
            f.read_attribute_int64(g, "complete") != 1)
          continue;
        for (const char* field : {"stress", "strain_energy_density"})
          if (!f.exists(g + "/" + field))
            fail("step " + name + " has no " + field +
                 " (write the reference with output.fields including stress and "
                 "strain_energy_density)");
        steps_.push_back(std::stoll(name));
      }
    if (steps_.empty()) fail("no complete output step");
  } catch (const InputError&) {
    throw;
  } catch (const std::exception& e) {
    fail(std::string("cannot read it: ") + e.what());
  }
}

const ReferenceFields& ReferenceState::fields(std::int64_t step) {
  const bool has = std::binary_search(steps_.begin(), steps_.end(), step);
  const std::int64_t use = has ? step : steps_.back();
  if (cached_.step == use) return cached_;
  auto f = output::H5File::open(path_, comm_, output::H5File::Access::kReadOnly);
  const std::string g = output::step_group(use);
  const std::string mesh =
      f.has_attribute(g, "mesh") ? f.read_attribute_string(g, "mesh") : std::string("/mesh");
  const std::int64_t n = f.dims(mesh + "/cell_lattice_index").at(0);
  std::vector<std::int32_t> ijk(3 * std::size_t(n));
  std::vector<double> stress(6 * std::size_t(n)), energy(static_cast<std::size_t>(n));
  f.read_rows(mesh + "/cell_lattice_index", n, 3, 0, n, ijk.data());
  f.read_rows(g + "/stress", n, 6, 0, n, stress.data());
  f.read_rows(g + "/strain_energy_density", n, 0, 0, n, energy.data());
  const auto& L = lattice_;
  const std::size_t cells =
      std::size_t(L.dims[0]) * std::size_t(L.dims[1]) * std::size_t(L.dims[2]);
  const double nan = std::numeric_limits<double>::quiet_NaN();
  cached_.step = use;
  cached_.stress.assign(6 * cells, nan);
  cached_.energy.assign(cells, nan);
  for (std::int64_t r = 0; r < n; ++r) {
    const std::size_t id =
        std::size_t(ijk[3 * r]) +
        std::size_t(L.dims[0]) *
            (std::size_t(ijk[3 * r + 1]) + std::size_t(L.dims[1]) * std::size_t(ijk[3 * r + 2]));
    std::copy_n(&stress[6 * r], 6, &cached_.stress[6 * id]);
    cached_.energy[id] = energy[std::size_t(r)];
  }
  return cached_;
}

}  // namespace hexcut::analysis
