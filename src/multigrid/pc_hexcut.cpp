#include "multigrid/pc_hexcut.hpp"

// A PC implementation sets the operations table of struct _p_PC, as PETSc's own PCs do.
#include <petsc/private/pcimpl.h>

#include <cstring>

namespace hexcut::multigrid {

const char* const PCHEXCUT = "hexcut";

namespace {

struct PCData {
  Options options;
  Multigrid* mg = nullptr;
};

PetscErrorCode pc_apply(PC pc, Vec b, Vec x) {
  PetscFunctionBeginUser;
  auto* d = static_cast<PCData*>(pc->data);
  PetscCheck(d->mg, PetscObjectComm((PetscObject)pc), PETSC_ERR_ORDER,
             "PC hexcut: no multigrid attached (the analysis attaches it; a PC of this type "
             "cannot be used for other systems)");
  PetscCall(d->mg->cycle(b, x));
  PetscFunctionReturn(0);
}

PetscErrorCode pc_view(PC pc, PetscViewer viewer) {
  PetscFunctionBeginUser;
  auto* d = static_cast<PCData*>(pc->data);
  PetscBool ascii;
  PetscCall(PetscObjectTypeCompare((PetscObject)viewer, PETSCVIEWERASCII, &ascii));
  if (ascii && d->mg) PetscCall(d->mg->view(viewer));
  PetscFunctionReturn(0);
}

PetscErrorCode pc_destroy(PC pc) {
  PetscFunctionBeginUser;
  delete static_cast<PCData*>(pc->data);
  pc->data = nullptr;
  PetscFunctionReturn(0);
}

PetscErrorCode pc_set_from_options(PC pc, PetscOptionItems* PetscOptionsObject) {
  PetscFunctionBeginUser;
  auto* d = static_cast<PCData*>(pc->data);
  Options o;  // each call starts from the defaults: the database says everything
  PetscInt n;
  PetscReal w;
  PetscBool set, flag;
  const char* hierarchies[] = {"components", "naive"};
  const char* smoothers[] = {"gs", "chebyshev"};
  const char* cycles[] = {"v", "w"};
  const char* interpolations[] = {"trilinear", "energy", "smoothed"};
  PetscInt choice;
  PetscOptionsHeadBegin(PetscOptionsObject, "hexcut geometric multigrid (doc/user-guide.md)");
  PetscCall(PetscOptionsInt("-gmg_levels", "Number of levels (0: automatic, from -gmg_coarse_dofs)",
                            "", o.hierarchy.levels, &n, &set));
  if (set) {
    PetscCheck(n >= 0, PETSC_COMM_SELF, PETSC_ERR_ARG_OUTOFRANGE,
               "-gmg_levels must be >= 1, or 0 for automatic");
    o.hierarchy.levels = int(n);
  }
  PetscCall(PetscOptionsInt("-gmg_coarse_dofs",
                            "Automatic depth: the first level with at most this many DOFs is the "
                            "coarsest",
                            "", PetscInt(o.hierarchy.coarse_dofs), &n, &set));
  if (set) {
    PetscCheck(n >= 3, PETSC_COMM_SELF, PETSC_ERR_ARG_OUTOFRANGE, "-gmg_coarse_dofs must be >= 3");
    o.hierarchy.coarse_dofs = n;
  }
  PetscCall(PetscOptionsReal("-gmg_max_duplication",
                             "Automatic depth: stop before a level with more than this many "
                             "extra coarse cells per occupied position (pieces thinner than "
                             "its cells; < 0: off)",
                             "", o.hierarchy.max_duplication, &w, &set));
  if (set) o.hierarchy.max_duplication = w;
  PetscCall(PetscOptionsInt("-gmg_duplication_dofs",
                            "The -gmg_max_duplication stop applies only where the level it "
                            "stops at has at most this many DOFs (it is factored)",
                            "", PetscInt(o.hierarchy.duplication_dofs), &n, &set));
  if (set) o.hierarchy.duplication_dofs = n;
  PetscCall(PetscOptionsReal("-gmg_duplication_share",
                             "The -gmg_max_duplication stop applies only where the level it "
                             "stops at has at most this share of the fine level's DOFs (1: "
                             "any level, level 1 included)",
                             "", o.hierarchy.duplication_share, &w, &set));
  if (set) {
    PetscCheck(w > 0, PETSC_COMM_SELF, PETSC_ERR_ARG_OUTOFRANGE,
               "-gmg_duplication_share must be > 0");
    o.hierarchy.duplication_share = w;
  }
  PetscCall(PetscOptionsInt("-gmg_gather_cells",
                            "A level with fewer than this many cells per rank is gathered onto "
                            "fewer ranks (0: never)",
                            "", PetscInt(o.hierarchy.gather_cells), &n, &set));
  if (set) {
    PetscCheck(n >= 0, PETSC_COMM_SELF, PETSC_ERR_ARG_OUTOFRANGE, "-gmg_gather_cells must be >= 0");
    o.hierarchy.gather_cells = n;
  }
  choice = o.hierarchy.mode == hierarchy::Coarsening::naive ? 1 : 0;
  PetscCall(PetscOptionsEList("-gmg_hierarchy",
                              "Coarsening: components (pieces of a 2x2x2 block get their own "
                              "coarse cells) or naive (one coarse cell per block)",
                              "", hierarchies, 2, hierarchies[choice], &choice, &set));
  if (set)
    o.hierarchy.mode =
        choice == 1 ? hierarchy::Coarsening::naive : hierarchy::Coarsening::components;
  choice = o.smoother == Smoother::gauss_seidel ? 0 : 1;
  PetscCall(PetscOptionsEList("-gmg_smoother",
                              "Smoother: gs (8-colour point-block Gauss-Seidel) or chebyshev "
                              "(on point-block Jacobi)",
                              "", smoothers, 2, smoothers[choice], &choice, &set));
  if (set) o.smoother = choice == 0 ? Smoother::gauss_seidel : Smoother::chebyshev;
  PetscCall(PetscOptionsInt("-gmg_presmooth",
                            "Sweeps before the coarse correction (Chebyshev: degree)", "",
                            o.presmooth, &n, &set));
  if (set) o.presmooth = int(n);
  PetscCall(PetscOptionsInt("-gmg_postsmooth",
                            "Sweeps after the coarse correction (Chebyshev: degree)", "",
                            o.postsmooth, &n, &set));
  if (set) o.postsmooth = int(n);
  PetscCheck(o.presmooth >= 0 && o.postsmooth >= 0 && o.presmooth + o.postsmooth > 0,
             PETSC_COMM_SELF, PETSC_ERR_ARG_OUTOFRANGE,
             "-gmg_presmooth and -gmg_postsmooth must be >= 0 and not both 0");
  PetscCall(PetscOptionsReal("-gmg_omega", "Gauss-Seidel relaxation weight, in (0, 2)", "", o.omega,
                             &w, &set));
  if (set) {
    PetscCheck(w > 0 && w < 2, PETSC_COMM_SELF, PETSC_ERR_ARG_OUTOFRANGE,
               "-gmg_omega must be in (0, 2)");
    o.omega = w;
  }
  choice = o.cycle_gamma == 2 ? 1 : 0;
  PetscCall(PetscOptionsEList("-gmg_cycle",
                              "Cycle: v or w (default v; w for static analyses of cut bodies)", "",
                              cycles, 2, cycles[choice], &choice, &set));
  o.cycle_set = set;
  if (set) o.cycle_gamma = choice == 1 ? 2 : 1;
  PetscCall(PetscOptionsReal("-gmg_rebuild_tol",
                             "Rotation-only updates rebuild the Galerkin blocks above fine cells "
                             "whose rotation moved by more than this (max entry)",
                             "", o.rebuild_tolerance, &w, &set));
  if (set) {
    PetscCheck(w >= 0, PETSC_COMM_SELF, PETSC_ERR_ARG_OUTOFRANGE, "-gmg_rebuild_tol must be >= 0");
    o.rebuild_tolerance = w;
  }
  PetscCall(PetscOptionsInt("-gmg_eig_every",
                            "Chebyshev: re-estimate lambda_max on every Nth rotation-only update",
                            "", o.eig_every, &n, &set));
  if (set) {
    PetscCheck(n >= 1, PETSC_COMM_SELF, PETSC_ERR_ARG_OUTOFRANGE, "-gmg_eig_every must be >= 1");
    o.eig_every = int(n);
  }
  choice = int(o.interpolation);
  PetscCall(
      PetscOptionsEList("-gmg_interpolation",
                        "Interpolation: energy (energy-minimizing rows where coarse cells are "
                        "cut, partial or span a material jump; trilinear elsewhere), smoothed "
                        "(P <- (I - omega D^-1 A) P there; assembled sparse levels below) or "
                        "trilinear everywhere",
                        "", interpolations, 3, interpolations[choice], &choice, &set));
  if (set) o.interpolation = Interpolation(choice);
  PetscCall(PetscOptionsInt("-gmg_smoothed_layers",
                            "Smoothed interpolation: rows smoothed = corners of the children of "
                            "irregular coarse cells grown by this many cell layers (-1: all rows)",
                            "", o.smoothed_layers, &n, &set));
  if (set) {
    PetscCheck(n >= -1, PETSC_COMM_SELF, PETSC_ERR_ARG_OUTOFRANGE,
               "-gmg_smoothed_layers must be >= -1");
    o.smoothed_layers = int(n);
  }
  PetscCall(PetscOptionsInt("-gmg_smoothed_levels",
                            "Smoothed interpolation: transfers smoothed, from the first with "
                            "irregular coarse cells down (-1: all)",
                            "", o.smoothed_levels, &n, &set));
  if (set) {
    PetscCheck(n >= -1 && n != 0, PETSC_COMM_SELF, PETSC_ERR_ARG_OUTOFRANGE,
               "-gmg_smoothed_levels must be -1 or >= 1");
    o.smoothed_levels = int(n);
  }
  PetscCall(PetscOptionsInt("-gmg_energy_iterations",
                            "Energy-minimizing interpolation: conjugate-gradient iterations from "
                            "the trilinear rows",
                            "", o.energy_iterations, &n, &set));
  if (set) {
    PetscCheck(n >= 0, PETSC_COMM_SELF, PETSC_ERR_ARG_OUTOFRANGE,
               "-gmg_energy_iterations must be >= 0");
    o.energy_iterations = int(n);
  }
  PetscCall(PetscOptionsInt(
      "-gmg_energy_from", "Energy-minimizing or smoothed interpolation to levels >= this (0: all)",
      "", o.energy_from, &n, &set));
  if (set) {
    PetscCheck(n >= 0, PETSC_COMM_SELF, PETSC_ERR_ARG_OUTOFRANGE, "-gmg_energy_from must be >= 0");
    o.energy_from = int(n);
  }
  PetscCall(PetscOptionsInt("-gmg_schwarz_from",
                            "Chebyshev on additive Schwarz (patches of irregular coarse cells) on "
                            "levels >= this (-1: point-block Jacobi everywhere)",
                            "", o.schwarz_from, &n, &set));
  if (set) {
    PetscCheck(n >= -1, PETSC_COMM_SELF, PETSC_ERR_ARG_OUTOFRANGE,
               "-gmg_schwarz_from must be >= -1");
    o.schwarz_from = int(n);
  }
  PetscCall(PetscOptionsReal("-gmg_degree_growth",
                             "Chebyshev degree on level l: -gmg_presmooth x growth^l (at most 8)",
                             "", o.degree_growth, &w, &set));
  if (set) {
    PetscCheck(w >= 1.0, PETSC_COMM_SELF, PETSC_ERR_ARG_OUTOFRANGE,
               "-gmg_degree_growth must be >= 1");
    o.degree_growth = w;
  }
  const char* precisions[] = {"double", "single"};
  choice = o.precision == Precision::single ? 1 : 0;
  PetscCall(PetscOptionsEList("-gmg_precision",
                              "Precision of the cycle: double, or single (the coarse levels' "
                              "Galerkin blocks in float, products in double; with -gmg_backend "
                              "host_loop or cuda also every level's vectors, level data and the "
                              "fine cells' products in float; the outer CG in double)",
                              "", precisions, 2, precisions[choice], &choice, &set));
  if (set) o.precision = choice == 1 ? Precision::single : Precision::double_;
  PetscCheck(o.interpolation != Interpolation::smoothed || o.smoother == Smoother::chebyshev,
             PETSC_COMM_SELF, PETSC_ERR_ARG_INCOMP,
             "-gmg_interpolation smoothed needs -gmg_smoother chebyshev (its assembled levels have "
             "no colour sweeps)");
  const char* backends[] = {"host", "host_loop", "cuda"};
  choice = int(o.backend);
  PetscCall(PetscOptionsEList(
      "-gmg_backend",
      "Where the cycle runs: host (PETSc vectors, every option, any ranks), host_loop (the "
      "CUDA backend's loop-layer cycle on the host), cuda (a GPU per rank); "
      "host_loop and cuda: Chebyshev or Gauss-Seidel, trilinear or energy, no composite elements",
      "", backends, 3, backends[choice], &choice, &set));
  if (set) o.backend = Backend(choice);
  flag = o.view ? PETSC_TRUE : PETSC_FALSE;
  PetscCall(PetscOptionsBool("-gmg_view", "Print the hierarchy after each set-up", "", flag, &flag,
                             nullptr));
  o.view = flag;
  flag = o.shared_blocks ? PETSC_TRUE : PETSC_FALSE;
  PetscCall(
      PetscOptionsBool("-gmg_shared_blocks",
                       "Coarse cells with equal Galerkin blocks (children of one material in the "
                       "same octants, linear runs) store one block between them",
                       "", flag, &flag, nullptr));
  o.shared_blocks = flag;
  PetscOptionsHeadEnd();
  d->options = o;
  PetscFunctionReturn(0);
}

PetscErrorCode pc_create(PC pc) {
  PetscFunctionBeginUser;
  pc->data = new PCData();
  pc->ops->apply = pc_apply;
  pc->ops->view = pc_view;
  pc->ops->destroy = pc_destroy;
  pc->ops->setfromoptions = pc_set_from_options;
  PetscFunctionReturn(0);
}

}  // namespace

PetscErrorCode register_pc() {
  PetscFunctionBeginUser;
  static bool registered = false;
  if (!registered) PetscCall(PCRegister(PCHEXCUT, pc_create));
  registered = true;
  PetscFunctionReturn(0);
}

namespace {

/// The data of a PC that must be of type PCHEXCUT.
PetscErrorCode hexcut_data(PC pc, PCData** data) {
  PetscFunctionBeginUser;
  PetscBool match;
  PetscCall(PetscObjectTypeCompare((PetscObject)pc, PCHEXCUT, &match));
  PetscCheck(match, PETSC_COMM_SELF, PETSC_ERR_ARG_WRONG, "the PC is not of type %s", PCHEXCUT);
  *data = static_cast<PCData*>(pc->data);
  PetscFunctionReturn(0);
}

}  // namespace

PetscErrorCode pc_get_options(PC pc, Options* options) {
  PetscFunctionBeginUser;
  PCData* d = nullptr;
  PetscCall(hexcut_data(pc, &d));
  *options = d->options;
  PetscFunctionReturn(0);
}

PetscErrorCode pc_set_multigrid(PC pc, Multigrid* mg) {
  PetscFunctionBeginUser;
  PCData* d = nullptr;
  PetscCall(hexcut_data(pc, &d));
  d->mg = mg;
  PetscFunctionReturn(0);
}

}  // namespace hexcut::multigrid
