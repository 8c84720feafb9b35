// Which physics of a deck differs from another deck's: used by --restart to refuse a
// checkpoint written with a different model (doc/user-guide.md, "--restart").
#pragma once

#include <string>
#include <vector>

namespace hexcut::deck {

/// The keys under which two deck texts describe different physics, as dotted paths
/// with list indices ("materials.steel.E", "cuts[0].time", "analysis.dt"). Compared:
/// the sections lattice, materials, geometry, boundary, cuts and analysis, except what
/// may change between a run and its restart: analysis.steps, analysis.end_time (the
/// end), analysis.tolerance and analysis.max_iterations (convergence settings); the
/// solver and output sections are not compared. Scalars that both read as numbers are
/// compared as numbers (1e9 equals 1.0e+09); maps ignore key order; lists compare
/// element by element. A key present in one deck only differs. Texts that are not YAML
/// maps compare as one difference named "(deck)". Files named by the decks (meshes,
/// images) are compared by name only.
std::vector<std::string> physics_differences(const std::string& before, const std::string& now);

}  // namespace hexcut::deck
