#include "assembly/initial_stress.hpp"

#include <algorithm>
#include <cmath>

#include "assembly/field_values.hpp"

namespace hexcut::assembly {

namespace {

bool selects(const deck::InitialStress& s, const lattice::Lattice& L, std::int32_t cell) {
  return s.material < 0 || L.material[cell] == s.material;
}

/// A dataset entry's row of 6 for cell c, or null where the row holds a NaN (no value there).
const double* dataset_row(const deck::InitialStress& entry, const lattice::Lattice& L,
                          std::int32_t c) {
  const auto& ijk = L.ijk[c];
  const double* v = &(*entry.cells)[6 * std::size_t(L.spec.cell_index(ijk[0], ijk[1], ijk[2]))];
  return std::any_of(v, v + 6, [](double x) { return std::isnan(x); }) ? nullptr : v;
}

/// sigma0 of cell c (6 values into s): the deck's entries in order; 0 where none applies.
void cell_initial_stress(const deck::Deck& deck, const lattice::Lattice& L, std::int32_t c,
                         std::string& bad, double* s) {
  std::fill(s, s + 6, 0.0);
  for (const auto& entry : deck.initial_stress) {
    if (!selects(entry, L, c)) continue;
    if (entry.cells) {
      if (const double* v = dataset_row(entry, L, c)) std::copy(v, v + 6, s);
      // else: no value here, the earlier entries' stands
    } else {
      const auto& ijk = L.ijk[c];
      const Eigen::Vector3d x = L.spec.cell_centre(ijk[0], ijk[1], ijk[2]);
      for (int i = 0; i < 6; ++i) s[i] = evaluate(entry.value[i], x, 0.0, bad);
    }
  }
}

}  // namespace

std::vector<double> initial_stress_of_cells(MPI_Comm comm, const deck::Deck& deck,
                                            const lattice::Lattice& L,
                                            const topology::DofLayout& D) {
  if (deck.initial_stress.empty()) return {};
  std::vector<double> sigma(6 * D.cells.size(), 0.0);
  std::string bad;
  for (std::size_t e = 0; e < D.cells.size(); ++e)
    cell_initial_stress(deck, L, D.cells[e], bad, &sigma[6 * e]);
  throw_if_not_finite(comm, bad);
  return sigma;
}

std::vector<std::string> initial_stress_warnings(const deck::Deck& deck,
                                                 const lattice::Lattice& L) {
  std::vector<std::string> out;
  for (const auto& entry : deck.initial_stress) {
    if (!entry.cells) continue;
    std::int64_t missing = 0, selected = 0;
    for (std::int32_t c = 0; c < L.num_cells(); ++c) {
      if (!selects(entry, L, c)) continue;
      ++selected;
      if (!dataset_row(entry, L, c)) ++missing;
    }
    if (missing > 0)
      out.push_back(entry.where.prefix() + "warning: the dataset has no value (NaN) in " +
                    std::to_string(missing) + " of the " + std::to_string(selected) +
                    " cells with material it applies to; they keep the initial stress of the "
                    "entries before it (0 if none)");
  }
  return out;
}

std::vector<double> initial_stress_load(const deck::Deck& deck, const lattice::Lattice& L,
                                        const topology::VertexCopies& V,
                                        const topology::DofLayout& D,
                                        const std::vector<double>& sigma0) {
  if (sigma0.empty()) return {};
  std::vector<double> f(3 * std::size_t(D.num_local()), 0.0);
  const double w = L.spec.h * L.spec.h / 4.0;
  // Column d of sigma0 (ParaView order xx yy zz xy yz xz): the traction on a face of normal e_d.
  static const int kColumn[3][3] = {{0, 3, 5}, {3, 1, 4}, {5, 4, 2}};
  std::string bad;  // other ranks' cells were found finite where their rank evaluated them
  for (std::size_t e = 0; e < D.cells.size(); ++e) {
    const std::int32_t c = D.cells[e];
    const auto& ijk = L.ijk[c];
    const double* s = &sigma0[6 * e];
    for (int d = 0; d < 3; ++d)
      for (int side = 0; side < 2; ++side) {
        int n[3] = {ijk[0], ijk[1], ijk[2]};
        n[d] += side ? 1 : -1;
        const std::int32_t nb = L.find(n[0], n[1], n[2]);
        if (nb < 0) continue;                   // the body's own boundary: held
        const double sign = side ? 1.0 : -1.0;  // n_F = sign e_d
        double s_nb[6];
        bool have_nb = false;
        for (int q = 0; q < 8; ++q) {
          if (((q >> d) & 1) != side) continue;  // corner q is not on this face
          const bool shared = V.cell_corners[c][q] == V.cell_corners[nb][q ^ (1 << d)];
          if (shared && side == 0) continue;  // the lower cell of the pair adds the jump
          double t[6];
          std::copy(s, s + 6, t);
          if (shared) {
            if (!have_nb) {
              // A local neighbour's sigma0 is at hand (D.cells is ascending); another
              // rank's is evaluated here.
              const auto it = std::lower_bound(D.cells.begin(), D.cells.end(), nb);
              if (it != D.cells.end() && *it == nb)
                std::copy_n(&sigma0[6 * std::size_t(it - D.cells.begin())], 6, s_nb);
              else
                cell_initial_stress(deck, L, nb, bad, s_nb);
              have_nb = true;
            }
            for (int i = 0; i < 6; ++i) t[i] = s[i] - s_nb[i];
          }
          double* fq = &f[3 * std::size_t(D.cell_corners[e][q])];
          for (int i = 0; i < 3; ++i) fq[i] -= w * sign * t[kColumn[i][d]];
        }
      }
  }
  return f;
}

}  // namespace hexcut::assembly
