#include "runtime/archive_csv.hpp"

#include "runtime/number_text.hpp"
#include "runtime/run_files.hpp"

#include <qd/errors.hpp>

#include <algorithm>
#include <fstream>
#include <numeric>
#include <sstream>
#include <string>

namespace qd::runtime {
namespace fs = std::filesystem;

void write_archive_csv(const fs::path& path, const Archive& archive, bool parameters) {
  const std::size_t P = parameters ? archive.param_count() : 0;
  const std::size_t dims = archive.descriptor_dims();
  std::string text = "index,objective";
  for (std::size_t d = 0; d < dims; ++d) text += ",measures_" + std::to_string(d);
  text += ",recn_error";
  for (std::size_t k = 0; k < P; ++k) text += ",solution_" + std::to_string(k);
  text += '\n';
  // Rows in cell order, so two archives with the same content give the same file.
  std::vector<std::size_t> slots(archive.size());
  std::iota(slots.begin(), slots.end(), std::size_t{0});
  std::sort(slots.begin(), slots.end(), [&](auto a, auto b) { return archive.cell(a) < archive.cell(b); });
  AtomicFile file(path);
  for (std::size_t slot : slots) {
    append_int(text, archive.cell(slot));
    text += ',';
    append_number(text, archive.fitness(slot));
    for (std::size_t d = 0; d < dims; ++d) {
      text += ',';
      append_number(text, archive.descriptor(slot)[d]);
    }
    text += ',';
    append_number(text, archive.recn_error(slot));
    for (std::size_t k = 0; k < P; ++k) {
      text += ',';
      append_number(text, archive.params(slot)[k]);
    }
    text += '\n';
    if (text.size() > (1u << 20)) {  // written in pieces of about 1 MB
      file.write(text);
      text.clear();
    }
  }
  file.write(text);
  file.commit();
}

StoredElites read_archive_solutions(const fs::path& csv, std::size_t P) {
  if (!exists_nofollow(csv)) throw InputError(csv.string() + ": no final archive (is the run complete?)");
  std::string text;
  try {
    text = read_run_file(csv, std::uint64_t{1} << 40);  // a regular file only (a FIFO never blocks)
  } catch (const StateError& e) {
    throw InputError(e.what());
  }
  std::istringstream in(std::move(text));
  std::string header, line;
  std::getline(in, header);
  std::vector<std::string> columns;
  for (std::size_t pos = 0;;) {
    const std::size_t c = header.find(',', pos);
    columns.push_back(header.substr(pos, c == std::string::npos ? std::string::npos : c - pos));
    if (c == std::string::npos) break;
    pos = c + 1;
  }
  const auto first = std::find(columns.begin(), columns.end(), "solution_0");
  if (first == columns.end())
    throw InputError(csv.string() + ": has no solution_* columns (output.snapshot_parameters was false)");
  const auto offset = static_cast<std::size_t>(first - columns.begin());
  StoredElites out;
  std::vector<double> values;
  while (std::getline(in, line)) {
    if (line.empty()) continue;
    out.cells.push_back(std::stoll(line.substr(0, line.find(','))));
    std::size_t pos = 0;
    for (std::size_t k = 0; k < offset; ++k) pos = line.find(',', pos) + 1;
    for (std::size_t k = 0; k < P; ++k) {
      const std::size_t c = line.find(',', pos);
      values.push_back(std::stod(line.substr(pos, c - pos)));
      pos = c + 1;
    }
  }
  out.theta.resize(static_cast<Eigen::Index>(out.cells.size()), static_cast<Eigen::Index>(P));
  std::copy(values.begin(), values.end(), out.theta.data());
  return out;
}

}  // namespace qd::runtime
