// The multigrid hierarchy (doc/theory.md, "Geometric multigrid"; Dick 2012, sec. 4.5.1). Level 0 is
// the simulation lattice. A cell of level l+1 is a connected component (under the links) of the
// level-l cells in one 2x2x2 block, so several coarse cells may share a position: pieces separated
// by empty space or, later, by cuts get their own coarse cells and never share coarse DOFs. Two
// coarse cells are linked iff some pair of their children is. Vertex copies are rebuilt per level
// exactly as on the fine level. The "naive" variant merges by position only, for comparison.
//
// Every level is distributed like the fine one: a coarse cell lives on the rank of its
// lowest-numbered child, and a coarse vertex copy on the rank of its lowest-numbered incident
// cell. Up to log2(superblock) + 1 levels the children of a coarse cell share a partition
// super-block, so they are all on its rank; below that, and on levels gathered onto fewer
// ranks, some children are on other ranks (Level::remote_children), which send their part
// of the Galerkin product to the coarse cell's rank (multigrid/gmg.cpp). A level with fewer
// than HierarchyOptions::gather_cells cells per rank is gathered onto fewer ranks, the
// PCTELESCOPE idea: consecutive ranks of the level above merge, so coarsening goes on to a
// small coarsest level at any size (doc/theory.md, "Parallel layout").
#pragma once

#include <cstdint>
#include <memory>
#include <vector>

#include "topology/cell_graph.hpp"
#include "topology/dof_layout.hpp"
#include "topology/partition.hpp"
#include "topology/vertex_copies.hpp"

namespace hexcut::hierarchy {

enum class Coarsening { components, naive };

/// One level of the hierarchy. Its vertex copies, partition and DOF layout are shared, not
/// copied: level 0's are the simulation's own (build_hierarchy's arguments, which must
/// outlive the levels: about 30 bytes per DOF that every rank would otherwise hold twice),
/// coarse levels own theirs.
struct Level {
  topology::CellGraph graph;
  std::vector<std::int32_t> parent;  // per cell of this level: its cell on the next level
  std::shared_ptr<const topology::VertexCopies> copies_ptr;
  std::shared_ptr<const topology::Partition> partition_ptr;
  std::shared_ptr<const topology::DofLayout> layout_ptr;
  int ranks = 1;  // the level's cells are on ranks 0 .. ranks-1 (fewer once gathered)
  // Some cell of this level has a child (a cell of the level above) on another rank.
  bool remote_children = false;

  const topology::VertexCopies& copies() const { return *copies_ptr; }
  const topology::Partition& partition() const { return *partition_ptr; }
  const topology::DofLayout& layout() const { return *layout_ptr; }
};

/// The coarse graph of `fine` and the parent of every fine cell.
topology::CellGraph coarsen(const topology::CellGraph& fine, Coarsening mode,
                            std::vector<std::int32_t>* parent);

struct HierarchyOptions {
  int levels = 0;                   // 0 = automatic
  std::int64_t coarse_dofs = 3000;  // automatic: stop once a level has at most this many DOFs
  Coarsening mode = Coarsening::components;
  int min_levels = 1;  // automatic: at least this many (a composite level l needs l + 1)
  // automatic: stop before a level whose duplication (duplication()) exceeds this: its coarse
  // cells have outgrown the pieces cuts or thin walls leave (doc/theory.md, "Coarse spaces
  // after cuts"). Only where the level it stops at (the coarsest, factored) has at most
  // duplication_dofs DOFs and at most duplication_share times the fine level's: a factored
  // level of 1/8 of the fine DOFs or more (any level 1) costs more than the iterations a
  // deeper hierarchy adds (doc/benchmarks.md, "The duplication rule's share"). Never below
  // two levels. max_duplication < 0: no such stop.
  double max_duplication = 0.5;
  std::int64_t duplication_dofs = 150000;
  double duplication_share = 0.1;
  // A coarse level with fewer than this many cells per rank of the level above is gathered
  // onto max(1, cells / gather_cells) ranks: rank r of the level above sends its cells' parents
  // to rank r * ranks_coarse / ranks_fine. 0: never gathered. Levels below min_levels are
  // never gathered (a composite level must stay on its fine cells' ranks). Off by default:
  // transfers to levels with remote children are trilinear and have no Schwarz patches, so
  // gathering small levels would switch those options off on small bodies.
  std::int64_t gather_cells = 0;
};

/// Coarse cells per occupied position, less one: 0 when every block of the level holds one
/// piece, 1 when on average each holds two. Pieces thinner than the level's cells (between
/// blades, in thin walls) make it grow; smooth boundaries do not.
double duplication(const topology::CellGraph& graph);

/// Builds levels 0..L-1. Level 0 takes `fine` and refers to the simulation's copies,
/// partition and DOF layout (the layout of `rank`), which must outlive the levels.
/// The automatic depth stops at the first level with <= coarse_dofs DOFs, or when
/// coarsening no longer reduces the cell count, or before a level whose duplication
/// exceeds max_duplication (when >= 0; only from a level with <= duplication_dofs DOFs and
/// <= duplication_share times the fine level's); it builds at least min_levels. An explicit depth
/// (options.levels > 0) is built unless the lattice is a single cell before it (then fewer
/// levels are returned: the caller reports it). The depth does not depend on the number of
/// ranks or the super-block.
std::vector<Level> build_hierarchy(topology::CellGraph fine, const topology::VertexCopies& copies,
                                   const topology::Partition& partition,
                                   const topology::DofLayout& layout,
                                   const HierarchyOptions& options);

/// Interpolation weights from level l+1 to level l for the fine copies owned by `rank`
/// (indices are canonical copy ids of each level): fine copy f = sum_j w_j coarse_j.
/// A fine copy takes the weights of the coarse cell of its lowest-numbered incident cell;
/// every other incident cell gives the same weights (checked by interpolation_mismatch).
struct Interpolation {
  std::vector<std::int32_t> fine;                   // owned fine copies (canonical)
  std::vector<std::array<std::int32_t, 8>> coarse;  // coarse copies (canonical), -1 = unused
  std::vector<std::array<double, 8>> weight;
};
Interpolation interpolation(const Level& fine, const Level& coarse, int rank);

/// Largest difference, over all fine copies and all their incident cells, between the
/// interpolation weights the different incident cells give (0 when consistent).
double interpolation_mismatch(const Level& fine, const Level& coarse);

/// Trilinear weight of coarse corner j at fine corner i of the child in octant o
/// (o = a + 2b + 4c: the child's offset in its 2x2x2 block).
double transfer_weight(int octant, int fine_corner, int coarse_corner);

}  // namespace hexcut::hierarchy
