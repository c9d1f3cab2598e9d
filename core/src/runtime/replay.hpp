// Looking at a finished run again: replaying elites from archive.csv and exporting the latent
// codes of the dataset. Functions over a loaded run; they write only the files they are given.
#pragma once

#include "runtime/run.hpp"

#include <qd/types.hpp>

#include <filesystem>

namespace qd::runtime {

// Re-runs the elite of `cell` from the run directory's archive.csv and draws it to `svg`.
// Returns the replayed trace (its status tells whether it still evaluates as stored).
Trace replay_elite(const Run& run, std::int64_t cell, const std::filesystem::path& svg);

// Re-runs every elite of archive.csv on `workers` threads and writes their `main` trajectory rows
// to `csv`: cell,landed,status,row,main_0,... (`landed` = the cell the replay falls in).
struct ReplayAllResult {
  std::size_t elites = 0, as_stored = 0;  // elites replayed, and those landing in their stored cell
};
ReplayAllResult replay_all(const Run& run, int workers, const std::filesystem::path& csv);

// Writes the latent code of every dataset entry under the checkpoint's representation to `csv`:
// cell,loop,z_0,... (`loop` = the loop the entry joined the dataset). Needs a loaded checkpoint
// (Run::open_for_inspection) and a representation with a latent space.
void write_latents(const Run& run, const std::filesystem::path& csv);

}  // namespace qd::runtime
