#include "multigrid/fine_galerkin.hpp"

#include <algorithm>

#include "element/reference.hpp"
#include "multigrid/kernels.hpp"

namespace hexcut::multigrid {
namespace {

/// W_o^T X W_o for o = 0..7, appended to `out`.
void append_octants(const double* X, std::vector<double>* out) {
  for (int o = 0; o < 8; ++o) {
    const auto at = out->size();
    out->resize(at + 576, 0.0);
    galerkin_accumulate(X, o, out->data() + at);
  }
}

}  // namespace

FineGalerkinTables fine_galerkin_tables(const assembly::CellData& cells) {
  FineGalerkinTables t;
  for (const auto& K : cells.kind_stiffness) append_octants(K.data(), &t.kind);
  const auto& ref = element::reference_matrices();
  append_octants(ref.k_lambda, &t.k_lambda);
  append_octants(ref.k_mu, &t.k_mu);
  append_octants(ref.mass, &t.consistent_mass);
  double lumped[576] = {0};
  for (int i = 0; i < 24; ++i) lumped[25 * i] = 0.125;
  append_octants(lumped, &t.lumped_mass);
  return t;
}

bool FineChildGalerkin::add(std::size_t e, int octant, double* A_parent) const {
  const auto c = std::int32_t(e);
  if (assembly::cell_is_masked(d_, c)) return false;
  const std::size_t o = 576 * std::size_t(octant);
  const double* G = nullptr;
  double formed[576];
  if (d_.kind[c] >= 0) {
    G = t_.kind.data() + 8 * 576 * std::size_t(d_.kind[c]) + o;
  } else {
    // h (lambda K_lambda + mu K_mu), as the fine cell's own stiffness.
    const double kl = d_.h * d_.lambda[c], km = d_.h * d_.mu[c];
    const double *L = t_.k_lambda.data() + o, *M = t_.k_mu.data() + o;
    for (int i = 0; i < 576; ++i) formed[i] = kl * L[i] + km * M[i];
    G = formed;
  }
  if (d_.rotation) {
    rotated_block_add(G, d_.rotation + 9 * e, d_.w_stiffness, A_parent);
  } else {
    for (int i = 0; i < 576; ++i) A_parent[i] += d_.w_stiffness * G[i];
  }
  if (d_.w_mass != 0.0) {
    const double m = d_.w_mass * d_.rho[c] * d_.h * d_.h * d_.h;
    const double* GM = (d_.lumped_mass ? t_.lumped_mass : t_.consistent_mass).data() + o;
    for (int i = 0; i < 576; ++i) A_parent[i] += m * GM[i];
  }
  return true;
}

}  // namespace hexcut::multigrid
