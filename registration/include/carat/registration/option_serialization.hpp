#pragma once

/// Option structs as bytes, to send one process's settings to the other processes of a job
/// (carat map under MPI). Every field is written except callbacks, which cannot leave their
/// process (read back, they are empty). A field added to one of these structs fails the build in
/// option_serialization.cpp until it is written there as well.

#include "carat/base/byte_stream.hpp"
#include "carat/registration/dense_graph.hpp"
#include "carat/registration/frame.hpp"
#include "carat/registration/global_registration.hpp"
#include "carat/registration/io/kitti_io.hpp"
#include "carat/registration/scan_opening.hpp"
#include "carat/solver/solver_options.hpp"

namespace carat {

/// Appends every field of `options`.
void write_options(ByteWriter& out, const ReadOptions& options);
/// Appends every field of `options`.
void write_options(ByteWriter& out, const PreprocessOptions& options);
/// Appends every field of `options` (its read and preprocess options included).
void write_options(ByteWriter& out, const OpenScansOptions& options);
/// Appends every field of `options` but iteration_callback.
void write_options(ByteWriter& out, const SolverOptions& options);
/// Appends every field of `options` (its solver options included) but the callbacks.
void write_options(ByteWriter& out, const GlobalRegistrationOptions& options);

/// Appends every field of `options`.
void write_options(ByteWriter& out, const DenseGraphOptions& options);

/// Reads what write_options() wrote for ReadOptions. Throws carat::Error (from `in`, naming its
/// input) for truncated bytes or a value no writer produces.
ReadOptions read_read_options(ByteReader& in);
/// Reads what write_options() wrote for PreprocessOptions; throws as read_read_options().
PreprocessOptions read_preprocess_options(ByteReader& in);
/// Reads what write_options() wrote for OpenScansOptions; throws as read_read_options().
OpenScansOptions read_open_scans_options(ByteReader& in);
/// Reads what write_options() wrote for SolverOptions (no callback); throws as
/// read_read_options().
SolverOptions read_solver_options(ByteReader& in);
/// Reads what write_options() wrote for GlobalRegistrationOptions (no callbacks); throws as
/// read_read_options().
GlobalRegistrationOptions read_global_registration_options(ByteReader& in);

/// Reads what write_options() wrote for DenseGraphOptions; throws as read_read_options().
DenseGraphOptions read_dense_graph_options(ByteReader& in);

}  // namespace carat
