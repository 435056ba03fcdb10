#pragma once

/// Simulated drives written as KITTI lays them out (a .bin file per frame and poses.txt).

#include <cstddef>
#include <filesystem>
#include <functional>

#include "carat/sim/circuit_options.hpp"
#include "carat/sim/sequence.hpp"
#include "carat/sim/world.hpp"

namespace carat {

/// Writes a sequence as KITTI lays it out: DIR/NNNNNN.bin (x y z intensity float32, intensity
/// 0, KittiFormat::kXyzi, what `carat map` reads by default) and
/// DIR/poses.txt (12 numbers per line, row-major 3x4 of T_world_frame, %.9g). Creates DIR;
/// every file is written atomically. Throws carat::Error when scans and poses differ in number
/// or a file cannot be written.
void write_synthetic_sequence(const std::filesystem::path& dir, const SyntheticSequence& sequence);

/// Simulates the drive along world.trajectory(options) and writes it into DIR frame by frame,
/// with the same files as make_synthetic_sequence() then write_synthetic_sequence(), holding
/// only one scan per running thread in memory (so a drive of any length fits). Scans run in
/// parallel with TBB. `progress`, if set, gets (frames written, frames). Returns the number of
/// points written. Throws carat::Error as trajectory() and write_synthetic_sequence() do.
std::size_t write_synthetic_drive(
    const std::filesystem::path& dir, const SyntheticWorld& world,
    const SyntheticTrajectoryOptions& options,
    const std::function<void(std::size_t, std::size_t)>& progress = {});

}  // namespace carat
