#include "runtime/run_directory.hpp"

#include <qd/errors.hpp>

#include <fcntl.h>
#include <sys/file.h>
#include <unistd.h>
#include <algorithm>
#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <fstream>

namespace qd::runtime {
namespace fs = std::filesystem;

namespace {
constexpr const char* kLockFile = "lock";
}  // namespace

RunDirectory::RunDirectory(fs::path dir)
    : dir_(std::move(dir)), metrics_(dir_ / "metrics.csv"), training_(dir_ / "training.csv") {}

RunDirectory::~RunDirectory() {
  if (lock_fd_ >= 0) ::close(lock_fd_);  // releases the lock
}

std::string RunDirectory::holder(const fs::path& dir) {
  const int fd = ::open((dir / kLockFile).c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) return "";
  std::string who;
  if (::flock(fd, LOCK_SH | LOCK_NB) != 0) {
    char buf[256] = {0};
    const ssize_t n = ::read(fd, buf, sizeof(buf) - 1);
    who = n > 0 ? std::string(buf, static_cast<std::size_t>(n)) : std::string("another process");
    while (!who.empty() && who.back() == '\n') who.pop_back();
  }
  ::close(fd);
  return who;
}

void RunDirectory::lock() {
  if (lock_fd_ >= 0) return;
  const fs::path path = dir_ / kLockFile;
  // Not inherited by the processes qdrun starts; worker processes forked by qdrun do share it,
  // which is right: they belong to this run.
  const int fd = ::open(path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
  if (fd < 0) throw InputError("cannot create " + path.string() + ": " + std::strerror(errno));
  if (::flock(fd, LOCK_EX | LOCK_NB) != 0) {
    ::close(fd);
    const std::string who = holder(dir_);
    throw InputError(dir_.string() + " is in use by qdrun " + (who.empty() ? std::string("(unknown)") : who) +
                     "; wait for it to finish or stop it first");
  }
  char host[256] = {0};
  ::gethostname(host, sizeof(host) - 1);
  const std::string me = "pid " + std::to_string(::getpid()) + " on host " + host + "\n";
  if (::ftruncate(fd, 0) != 0 || ::pwrite(fd, me.data(), me.size(), 0) != static_cast<ssize_t>(me.size())) {
    ::close(fd);
    throw SystemError("cannot write " + path.string() + ": " + std::strerror(errno));
  }
  lock_fd_ = fd;
}

void RunDirectory::open() {
  check_writable();
  lock();
}

void RunDirectory::create(const std::string& config, const std::string& metrics_header) {
  std::error_code ec;
  fs::create_directories(dir_, ec);
  if (ec) throw InputError("cannot create the run directory " + dir_.string() + ": " + ec.message());
  check_writable();
  lock();  // before looking, so two runs started together cannot both find the directory empty
  if (fs::exists(dir_ / "config.toml", ec) || CheckpointStore::exists(dir_))
    throw InputError(dir_.string() + " already holds a run; continue it with --resume " + dir_.string() +
                     ", or choose another --output, --seed or experiment.name");
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

std::filesystem::path session_provenance(const std::filesystem::path& dir, int loop) {
  std::filesystem::path found = dir / "provenance.toml";
  int found_loop = 0;
  std::error_code ec;
  const std::string prefix = "provenance-resume-loop-";
  for (const auto& e : std::filesystem::directory_iterator(dir, ec)) {
    const std::string f = e.path().filename().string();
    if (f.rfind(prefix, 0) != 0 || e.path().extension() != ".toml") continue;
    const int l = std::atoi(f.c_str() + prefix.size());
    if (l > found_loop && l <= loop) found_loop = l, found = e.path();
  }
  return found;
}

void RunDirectory::write_provenance(int first_loop, const std::string& text) const {
  const std::string name =
      first_loop == 0 ? "provenance.toml" : "provenance-resume-loop-" + std::to_string(first_loop) + ".toml";
  write_file_atomic(dir_ / name, text);
}

void RunDirectory::set_status(const std::string& status) const {
  write_file_atomic(dir_ / "status", status + "\n");
}

std::vector<LogSize> RunDirectory::log_sizes(const std::vector<std::string>& names) const {
  std::vector<LogSize> logs;
  for (const std::string& name : names) {
    std::error_code ec;
    const auto size = fs::file_size(dir_ / name, ec);
    if (!ec) logs.emplace_back(name, size);
  }
  std::sort(logs.begin(), logs.end());
  return logs;
}

void RunDirectory::cut_logs(const std::vector<LogSize>& sizes, const std::vector<std::string>& names) const {
  for (const auto& [name, size] : sizes) {
    std::error_code ec;
    const auto now = fs::file_size(dir_ / name, ec);
    if (ec)
      throw StateError((dir_ / name).string() + " is missing (the checkpoint records " + std::to_string(size) +
                       " bytes)");
    if (now < size)
      throw StateError((dir_ / name).string() + " is shorter (" + std::to_string(now) +
                       " bytes) than the checkpoint records (" + std::to_string(size) +
                       "): it was truncated or edited");
    if (now > size) fs::resize_file(dir_ / name, size);
  }
  for (const std::string& name : names) {
    const bool recorded = std::any_of(sizes.begin(), sizes.end(), [&](const LogSize& l) { return l.first == name; });
    std::error_code ec;
    if (!recorded) fs::remove(dir_ / name, ec);  // written after the checkpoint
  }
}

std::size_t RunDirectory::count_lines(const std::string& name) const {
  std::ifstream in(dir_ / name, std::ios::binary);
  std::size_t lines = 0;
  for (std::string line; std::getline(in, line);) ++lines;
  return lines;
}

}  // namespace qd::runtime
