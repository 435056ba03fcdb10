#pragma once

// What mpirun told this process through its environment, before (or without) MPI itself: every
// subcommand needs it, since only `carat map` works over the ranks and every other one runs on
// rank 0 alone, and only rank 0 prints what went wrong (one message, not one per rank).

namespace carat::cli {

/// This process's place in an mpirun job (rank 0 of 1 when mpirun did not start it).
struct MpiLaunch {
  int rank = 0;  ///< this process's rank, from OMPI_COMM_WORLD_RANK, PMI_RANK or PMIX_RANK
  int size = 1;  ///< ranks of the job, from OMPI_COMM_WORLD_SIZE, PMI_SIZE or PMIX_SIZE
  /// Whether this is a rank other than 0 of a job of 2 or more ranks.
  bool secondary() const { return size > 1 && rank > 0; }
};

/// Reads the launcher's variables (Open MPI, MPICH / Hydra, PMIx); values that are missing or not
/// numbers count as rank 0 of 1.
MpiLaunch mpi_launch();

}  // namespace carat::cli
