#include "runtime/run_directory.hpp"

#include <qd/errors.hpp>

#include <unistd.h>
#include <algorithm>

namespace qd::runtime {
namespace fs = std::filesystem;

namespace {
bool is_appended_log(const fs::path& p) {
  return p.extension() == ".csv" && p.filename() != "archive.csv";
}
}  // namespace

RunDirectory::RunDirectory(fs::path dir)
    : dir_(std::move(dir)), metrics_(dir_ / "metrics.csv"), training_(dir_ / "training.csv") {}

void RunDirectory::create(const std::string& config, const std::string& metrics_header) {
  std::error_code ec;
  if (fs::exists(dir_ / "config.toml", ec) || CheckpointStore::exists(dir_))
    throw InputError(dir_.string() + " already holds a run; continue it with --resume " + dir_.string() +
                     ", or choose another --output, --seed or experiment.name");
  fs::create_directories(dir_, ec);
  if (ec) throw InputError("cannot create the run directory " + dir_.string() + ": " + ec.message());
  check_writable();
  set_status("running");
  write_config(config);
  write_file_atomic(dir_ / "metrics.csv", metrics_header + "\n");
  write_file_atomic(dir_ / "training.csv", "loop,epochs,train_loss,test_loss,stopped_early,seconds\n");
}

void RunDirectory::check_writable() const {
  if (::access(dir_.c_str(), W_OK) != 0) throw InputError("the run directory " + dir_.string() + " is not writable");
}

void RunDirectory::write_config(const std::string& config) const {
  write_file_atomic(dir_ / "config.toml", config);
}

void RunDirectory::write(const std::string& name, const std::string& text) const {
  write_file_atomic(dir_ / name, text);
}

void RunDirectory::write_provenance(int first_loop, const std::string& text) const {
  const std::string name =
      first_loop == 0 ? "provenance.toml" : "provenance-resume-loop-" + std::to_string(first_loop) + ".toml";
  write_file_atomic(dir_ / name, text);
}

void RunDirectory::set_status(const std::string& status) const {
  write_file_atomic(dir_ / "status", status + "\n");
}

std::vector<LogSize> RunDirectory::log_sizes() const {
  std::vector<LogSize> logs;
  for (const auto& e : fs::directory_iterator(dir_))
    if (e.is_regular_file() && is_appended_log(e.path()))
      logs.emplace_back(e.path().filename().string(), e.file_size());
  std::sort(logs.begin(), logs.end());
  return logs;
}

void RunDirectory::cut_logs(const std::vector<LogSize>& sizes) const {
  for (const auto& e : fs::directory_iterator(dir_)) {
    if (!e.is_regular_file() || !is_appended_log(e.path())) continue;
    const std::string name = e.path().filename().string();
    const auto it = std::find_if(sizes.begin(), sizes.end(), [&](const auto& l) { return l.first == name; });
    if (it == sizes.end())
      fs::remove(e.path());
    else if (e.file_size() > it->second)
      fs::resize_file(e.path(), it->second);
  }
}

}  // namespace qd::runtime
