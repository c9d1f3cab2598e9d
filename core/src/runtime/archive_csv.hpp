// archive.csv: the archive as text, one row per elite in cell order (pyribs-style columns:
// index, objective, measures_*, recn_error, solution_*), and reading its solutions back.
#pragma once

#include "runtime/grid_archive.hpp"

#include <qd/types.hpp>

#include <filesystem>
#include <vector>

namespace qd::runtime {

// Writes the archive atomically; without `parameters` the solution_* columns are left out.
void write_archive_csv(const std::filesystem::path& path, const Archive& archive, bool parameters);

// The elites of an archive.csv: their cells and parameter rows (P columns expected).
struct StoredElites {
  std::vector<std::int64_t> cells;
  Matrix theta;
};
StoredElites read_archive_solutions(const std::filesystem::path& csv, std::size_t P);

}  // namespace qd::runtime
