#include "runtime/run_directory.hpp"

#include "runtime/experiment.hpp"

#include <qd/errors.hpp>

#include <fcntl.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>
#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>

namespace qd::runtime {
namespace fs = std::filesystem;

namespace {
constexpr const char* kLockFile = "lock";
// Logs and the status are read whole; anything larger is not a file qdrun wrote.
constexpr std::uint64_t kMaxLogBytes = std::uint64_t{1} << 30;
constexpr std::uint64_t kMaxStatusBytes = 1 << 16;

// Whether another open file description holds a lock on `fd`'s file.
bool held_by_other(int fd) {
  if (::flock(fd, LOCK_SH | LOCK_NB) == 0) {
    ::flock(fd, LOCK_UN);
    return false;
  }
  return errno == EWOULDBLOCK;
}

// CRC-32C of `size` bytes of `fd` from `from`, extending `crc` (the CRC-32C of the bytes before).
std::uint32_t extend_crc(int fd, const fs::path& path, std::uint64_t from, std::uint64_t size, std::uint32_t crc) {
  std::string buffer(1 << 20, '\0');
  while (from < size) {
    const ssize_t n =
        ::pread(fd, buffer.data(), std::min<std::uint64_t>(buffer.size(), size - from), static_cast<off_t>(from));
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) throw SystemError("cannot read " + path.string() + ": " + (n < 0 ? std::strerror(errno) : "it shrank"));
    crc = crc32c(buffer.data(), static_cast<std::size_t>(n), crc);
    from += static_cast<std::uint64_t>(n);
  }
  return crc;
}

std::uint64_t file_size_of(int fd, const fs::path& path) {
  struct stat st;
  if (::fstat(fd, &st) != 0) throw SystemError("cannot read " + path.string() + ": " + std::strerror(errno));
  return static_cast<std::uint64_t>(st.st_size);
}

// The highest loop of a metrics.csv row, -1 when it has none (or cannot be read).
int last_metrics_loop(const fs::path& metrics) {
  std::string text;
  try {
    text = read_run_file(metrics, kMaxLogBytes);
  } catch (const std::exception&) {
    return -1;
  }
  int last = -1;
  std::size_t pos = text.find('\n');  // after the header
  while (pos != std::string::npos && pos + 1 < text.size()) {
    int loop = -1;
    if (std::sscanf(text.c_str() + pos + 1, "%d,", &loop) == 1) last = std::max(last, loop);
    pos = text.find('\n', pos + 1);
  }
  return last;
}
}  // namespace

RunDirectory::RunDirectory(fs::path dir)
    : dir_(std::move(dir)), metrics_(dir_ / "metrics.csv"), training_(dir_ / "training.csv") {}

RunDirectory::~RunDirectory() {
  if (lock_fd_ >= 0) ::close(lock_fd_);  // releases the locks
  if (dir_fd_ >= 0) ::close(dir_fd_);
}

std::string RunDirectory::holder(const fs::path& dir) {
  bool locked = false;
  const int dfd = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (dfd >= 0) {
    locked = held_by_other(dfd);
    ::close(dfd);
  }
  std::string who;
  const int fd = ::open((dir / kLockFile).c_str(), O_RDONLY | O_NOFOLLOW | O_NONBLOCK | O_CLOEXEC);
  struct stat st;
  if (fd >= 0 && ::fstat(fd, &st) == 0 && S_ISREG(st.st_mode)) {
    locked = held_by_other(fd) || locked;
    char buf[256] = {0};
    const ssize_t n = locked ? ::pread(fd, buf, sizeof(buf) - 1, 0) : 0;
    for (ssize_t i = 0; i < n; ++i) who += std::isprint(static_cast<unsigned char>(buf[i])) ? buf[i] : ' ';
    while (!who.empty() && who.back() == ' ') who.pop_back();
  }
  if (fd >= 0) ::close(fd);
  if (!locked) return "";
  return who.empty() ? std::string("another process (its lock file was removed)") : who;
}

void RunDirectory::lock() {
  if (lock_fd_ >= 0) return;
  auto in_use = [&]() {
    if (dir_fd_ >= 0) ::close(dir_fd_);
    dir_fd_ = -1;
    const std::string who = holder(dir_);
    throw InputError(dir_.string() + " is in use by qdrun " + (who.empty() ? std::string("(unknown)") : who) +
                     "; wait for it to finish or stop it first");
  };
  // The directory itself: not inherited by the processes qdrun starts; worker processes forked by
  // qdrun do share it, which is right: they belong to this run.
  const int dfd = ::open(dir_.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (dfd < 0) throw InputError("cannot open the run directory " + dir_.string() + ": " + std::strerror(errno));
  if (::flock(dfd, LOCK_EX | LOCK_NB) == 0) {
    dir_fd_ = dfd;
  } else {
    const int e = errno;
    ::close(dfd);
    if (e == EWOULDBLOCK) in_use();
    // No directory locks on this file system (NFS): the lock file alone.
  }
  // An older qdrun (or one on a file system without directory locks) holds the lock file.
  const fs::path path = dir_ / kLockFile;
  if (const int old = ::open(path.c_str(), O_RDONLY | O_NOFOLLOW | O_NONBLOCK | O_CLOEXEC); old >= 0) {
    struct stat st;
    const bool busy = ::fstat(old, &st) == 0 && S_ISREG(st.st_mode) && held_by_other(old);
    ::close(old);
    if (busy) in_use();
  }
  // A new lock file naming this process, never the old one written in place: a hard-linked copy
  // of this directory shares it. Whatever is in its place (a symlink, a FIFO) is replaced.
  if (std::error_code ec; fs::is_directory(fs::symlink_status(path, ec))) {
    if (dir_fd_ >= 0) ::close(dir_fd_);
    dir_fd_ = -1;
    throw InputError(path.string() + " is a directory, not qdrun's lock file; move it away");
  }
  // Locked before it takes the name, so whoever reads the name finds it held.
  char host[256] = {0};
  ::gethostname(host, sizeof(host) - 1);
  const std::string me = "pid " + std::to_string(::getpid()) + " on host " + host + "\n";
  const fs::path tmp = path.string() + ".tmp";
  ::unlink(tmp.c_str());
  const int fd = ::open(tmp.c_str(), O_RDWR | O_CREAT | O_EXCL | O_NOFOLLOW | O_CLOEXEC, 0644);
  if (fd < 0) throw SystemError("cannot create " + tmp.string() + ": " + std::strerror(errno));
  try {
    write_all(fd, me.data(), me.size(), tmp);
  } catch (...) {
    ::close(fd);
    throw;
  }
  const bool file_locked = ::flock(fd, LOCK_EX | LOCK_NB) == 0;
  const int e = errno;
  if ((!file_locked && dir_fd_ < 0) || ::rename(tmp.c_str(), path.c_str()) != 0) {
    const int why = file_locked ? errno : e;
    ::close(fd);
    ::unlink(tmp.c_str());
    throw SystemError("cannot " + std::string(file_locked ? "write " : "lock ") + path.string() + ": " +
                      std::strerror(why));
  }
  lock_fd_ = fd;
}

void RunDirectory::open() {
  check_writable();
  lock();
}

std::string RunDirectory::read_status(const fs::path& dir) {
  const fs::path path = dir / "status";
  if (!exists_nofollow(path)) return "";
  try {
    return read_run_file(path, kMaxStatusBytes);
  } catch (const StateError& e) {
    throw InputError(e.what());
  }
}

Leftover RunDirectory::leftover(const fs::path& dir, std::string* found) {
  std::string results;
  auto add = [&](const std::string& what) { results += (results.empty() ? "" : ", ") + what; };
  const bool has_config = exists_nofollow(dir / "config.toml");
  if (exists_nofollow(dir / "archive.csv")) add("archive.csv");
  const std::string status = read_status(dir);
  if (status.rfind("complete", 0) == 0 || status.rfind("stopped after loop", 0) == 0)
    add("status '" + status.substr(0, status.find('\n')) + "'");
  const int last_loop = last_metrics_loop(dir / "metrics.csv");
  if (last_loop >= 1 || (!has_config && last_loop >= 0))
    add("metrics.csv holds loops up to " + std::to_string(last_loop));
  if (!has_config && exists_nofollow(dir / "dataset.bin")) add("dataset.bin");
  if (found) *found = results;
  if (!results.empty()) return Leftover::kResults;
  return has_config ? Leftover::kUnfinishedStart : Leftover::kNone;
}

void RunDirectory::remove_unfinished_start(const fs::path& dir) {
  std::error_code ec;
  for (const char* name : {"config.toml", "provenance.toml", "status", "grid.toml", "centroids.csv", "metrics.csv",
                           "training.csv", "losses.csv", "pca.csv", "dataset.bin", "checkpoint.bin.tmp", "status.tmp"})
    fs::remove(dir / name, ec);
  for (const auto& e : fs::directory_iterator(dir, ec)) {
    const std::string name = e.path().filename().string();
    if (name.rfind("archive-state-", 0) == 0) fs::remove(e.path(), ec);
  }
}

bool RunDirectory::create(const std::string& config, const std::string& metrics_header) {
  std::error_code ec;
  fs::create_directories(dir_, ec);
  if (ec) throw InputError("cannot create the run directory " + dir_.string() + ": " + ec.message());
  check_writable();
  lock();  // before looking, so two runs started together cannot both find the directory empty
  if (CheckpointStore::exists(dir_))
    throw InputError(dir_.string() + " already holds a run; continue it with --resume " + dir_.string() +
                     ", or choose another --output, --seed or experiment.name");
  bool restarted = false;
  std::string found;
  switch (leftover(dir_, &found)) {
    case Leftover::kNone:
      break;
    case Leftover::kResults:
      throw InputError(dir_.string() + " holds results but no checkpoint (" + found +
                       "); qdrun will not touch them: restore checkpoint.bin and --resume, or choose another "
                       "--output, --seed or experiment.name");
    case Leftover::kUnfinishedStart: {
      // The start of a run that stopped before its first checkpoint: nothing to keep. The same run
      // simply starts again; another one is refused, as --resume would refuse it.
      std::string old;
      try {
        old = read_run_file(dir_ / "config.toml", kMaxLogBytes);
      } catch (const StateError& e) {
        throw InputError(e.what());
      }
      for (const ConfigDifference& d : config_differences(old, config))
        if (!may_change_on_resume(d.key))
          throw InputError(dir_.string() + " holds the start of another run (" + d.key + " is " + d.before +
                           " there, " + d.after +
                           " now), which stopped before its first checkpoint; delete the directory, or choose "
                           "another --output, --seed or experiment.name");
      remove_unfinished_start(dir_);
      restarted = true;
      break;
    }
  }
  write_config(config);
  write_file_atomic(dir_ / "metrics.csv", metrics_header + "\n");
  write_file_atomic(dir_ / "training.csv", "loop,epochs,train_loss,test_loss,stopped_early,seconds\n");
  return restarted;
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

std::vector<LogSize> RunDirectory::log_sizes(const std::vector<std::string>& names) {
  std::vector<LogSize> logs;
  for (const std::string& name : names) {
    const fs::path path = dir_ / name;
    if (!exists_nofollow(path)) continue;
    const int fd = open_for_update(path, 0, false);
    LogSize log{name, 0, 0, true};
    try {
      log.size = file_size_of(fd, path);
      const auto known =
          std::find_if(checksummed_.begin(), checksummed_.end(), [&](const LogSize& l) { return l.name == name; });
      const bool extend = known != checksummed_.end() && known->size <= log.size;
      log.crc = extend_crc(fd, path, extend ? known->size : 0, log.size, extend ? known->crc : 0);
    } catch (...) {
      ::close(fd);
      throw;
    }
    ::close(fd);
    const auto known =
        std::find_if(checksummed_.begin(), checksummed_.end(), [&](const LogSize& l) { return l.name == name; });
    if (known != checksummed_.end())
      *known = log;
    else
      checksummed_.push_back(log);
    logs.push_back(log);
  }
  std::sort(logs.begin(), logs.end());
  return logs;
}

void RunDirectory::cut_logs(const std::vector<LogSize>& sizes, const std::vector<std::string>& names) {
  // Everything is checked before anything is cut: a refused run directory is left as it was.
  for (const LogSize& log : sizes) {
    const fs::path path = dir_ / log.name;
    if (!exists_nofollow(path))
      throw StateError(path.string() + " is missing (the checkpoint records " + std::to_string(log.size) + " bytes)");
    struct stat st;
    if (::lstat(path.c_str(), &st) == 0 && S_ISREG(st.st_mode) && static_cast<std::uint64_t>(st.st_size) < log.size)
      throw StateError(path.string() + " is shorter (" + std::to_string(st.st_size) +
                       " bytes) than the checkpoint records (" + std::to_string(log.size) +
                       "): it was truncated or edited");
    const std::string bytes = read_run_file_prefix(path, log.size);
    if (log.checksummed && crc32c(bytes.data(), bytes.size()) != log.crc)
      throw StateError(path.string() + ": its first " + std::to_string(log.size) +
                       " bytes differ from what the checkpoint recorded (their checksum): it was edited");
  }
  checksummed_ = sizes;
  for (const LogSize& log : sizes) {
    const fs::path path = dir_ / log.name;
    int fd = -1;
    try {
      fd = open_for_update(path, 0, false);
    } catch (const InputError& e) {
      throw StateError(e.what());
    }
    const bool ok = file_size_of(fd, path) == log.size || ::ftruncate(fd, static_cast<off_t>(log.size)) == 0;
    const int e = errno;
    ::close(fd);
    if (!ok) throw SystemError("cannot cut " + path.string() + " back to the checkpoint: " + std::strerror(e));
    if (!log.checksummed) {
      // A checkpoint of an older qdrun: its checksum from here on.
      const int rfd = open_for_update(path, 0, false);
      const std::uint32_t crc = extend_crc(rfd, path, 0, log.size, 0);
      ::close(rfd);
      for (LogSize& l : checksummed_)
        if (l.name == log.name) l.crc = crc, l.checksummed = true;
    }
  }
  for (const std::string& name : names) {
    const bool recorded = std::any_of(sizes.begin(), sizes.end(), [&](const LogSize& l) { return l.name == name; });
    std::error_code ec;
    if (!recorded) fs::remove(dir_ / name, ec);  // written after the checkpoint
  }
}

bool is_training_log_name(const std::string& name) {
  static const char* const kOwn[] = {"metrics.csv", "training.csv", "archive.csv", "centroids.csv",
                                     "fault-offspring.csv"};
  if (name.size() < 5 || name.size() > 128 || name[0] == '.' || name.compare(name.size() - 4, 4, ".csv") != 0)
    return false;
  for (const char c : name)
    if (!std::isalnum(static_cast<unsigned char>(c)) && c != '.' && c != '_' && c != '-') return false;
  return std::none_of(std::begin(kOwn), std::end(kOwn), [&](const char* own) { return name == own; });
}

void RunDirectory::append_log(const std::string& name, const std::string& header, const std::string& rows,
                              bool restart) {
  const fs::path path = dir_ / name;
  std::error_code ec;
  if (restart) fs::remove(path, ec);
  // Opened as every file the run changes in place: a symlink, FIFO, device or directory there is
  // refused, and a file shared with another directory (cp -al) gets its own copy first. One write
  // per call.
  const int fd = open_for_update(path, O_APPEND, true);
  struct stat st;
  const bool fresh = ::fstat(fd, &st) != 0 || st.st_size == 0;
  const std::string text = fresh ? header + rows : rows;
  try {
    write_all(fd, text.data(), text.size(), path);
  } catch (...) {
    ::close(fd);
    throw;
  }
  ::close(fd);
}

std::size_t RunDirectory::count_lines(const std::string& name) const {
  if (!exists_nofollow(dir_ / name)) return 0;
  const std::string text = read_run_file(dir_ / name, kMaxLogBytes);
  std::size_t lines = static_cast<std::size_t>(std::count(text.begin(), text.end(), '\n'));
  if (!text.empty() && text.back() != '\n') ++lines;
  return lines;
}

}  // namespace qd::runtime
