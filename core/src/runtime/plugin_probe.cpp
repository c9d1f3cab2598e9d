#include "runtime/plugin_probe.hpp"

#include "runtime/plugin_library.hpp"

#include <qd/errors.hpp>

#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <sys/prctl.h>
#include <sys/wait.h>
#include <unistd.h>
#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <stdexcept>

namespace qd::runtime {
namespace fs = std::filesystem;

namespace {

// ---- Probing a library in a process of its own ----------------------------------------------
// The probe process writes one message on a pipe: 'K' and what the plugin declares, or 'E' and the
// rejection. Strings are a presence byte, a 32-bit length and the bytes.
constexpr int kProbeSeconds = 20;

void put_u32(std::string& out, std::uint32_t v) {
  out.append(reinterpret_cast<const char*>(&v), sizeof(v));
}
void put_text(std::string& out, const char* text) {
  out += text ? '\1' : '\0';
  const std::size_t n = text ? std::strlen(text) : 0;
  put_u32(out, static_cast<std::uint32_t>(n));
  out.append(text ? text : "", n);
}
void put_double(std::string& out, double v) {
  out.append(reinterpret_cast<const char*>(&v), sizeof(v));
}

class MessageReader {
 public:
  explicit MessageReader(const std::string& bytes) : bytes_(bytes) {}
  template <class T>
  T number() {
    T v{};
    if (at_ + sizeof(T) > bytes_.size()) throw std::runtime_error("truncated");
    std::memcpy(&v, bytes_.data() + at_, sizeof(T));
    at_ += sizeof(T);
    return v;
  }
  // nullptr for an absent string; else a pointer into `keep`, which outlives the plugin record.
  const char* text(std::deque<std::string>& keep) {
    const char present = number<char>();
    const auto n = number<std::uint32_t>();
    if (at_ + n > bytes_.size()) throw std::runtime_error("truncated");
    keep.emplace_back(bytes_.data() + at_, n);
    at_ += n;
    return present ? keep.back().c_str() : nullptr;
  }
  bool done() const noexcept { return at_ == bytes_.size(); }

 private:
  const std::string& bytes_;
  std::size_t at_ = 0;
};

std::string describe_declarations(const PluginInfo& info) {
  std::string out = "K";
  put_text(out, info.plugin_name);
  put_text(out, info.plugin_version);
  put_text(out, info.build_fingerprint);
  put_u32(out, info.component_count);
  for (std::uint32_t i = 0; i < info.component_count; ++i) {
    const ComponentInfo& c = info.components[i];
    put_u32(out, static_cast<std::uint32_t>(c.kind));
    put_u32(out, c.flags);
    put_text(out, c.name);
    put_text(out, c.summary);
    put_text(out, c.default_descriptor);
    put_u32(out, c.param_count);
    for (std::uint32_t k = 0; k < c.param_count; ++k) {
      const ParamSpec& p = c.params[k];
      put_text(out, p.key);
      put_u32(out, static_cast<std::uint32_t>(p.type));
      put_text(out, p.default_value);
      put_double(out, p.min);
      put_double(out, p.max);
      put_text(out, p.choices);
      put_text(out, p.help);
    }
  }
  return out;
}

std::shared_ptr<ProbeCopy> read_declarations(MessageReader& in) {
  auto copy = std::make_shared<ProbeCopy>();
  copy->info.abi_version = kPluginAbiVersion;
  copy->info.info_size = sizeof(PluginInfo);
  copy->info.plugin_name = in.text(copy->strings);
  copy->info.plugin_version = in.text(copy->strings);
  copy->info.build_fingerprint = in.text(copy->strings);
  const auto count = in.number<std::uint32_t>();
  if (count > 100000) throw std::runtime_error("implausible component count");
  copy->components.resize(count);
  for (ComponentInfo& c : copy->components) {
    c.kind = static_cast<Kind>(in.number<std::uint32_t>());
    c.flags = in.number<std::uint32_t>();
    c.name = in.text(copy->strings);
    c.summary = in.text(copy->strings);
    c.default_descriptor = in.text(copy->strings);
    c.param_count = in.number<std::uint32_t>();
    if (c.param_count > 100000) throw std::runtime_error("implausible parameter count");
    auto& params = copy->params.emplace_back(c.param_count);
    for (ParamSpec& p : params) {
      p.key = in.text(copy->strings);
      p.type = static_cast<ParamType>(in.number<std::uint32_t>());
      p.default_value = in.text(copy->strings);
      p.min = in.number<double>();
      p.max = in.number<double>();
      p.choices = in.text(copy->strings);
      p.help = in.text(copy->strings);
    }
    c.params = params.data();
    c.create = nullptr;  // only the loaded library's own
  }
  copy->info.component_count = count;
  copy->info.components = copy->components.data();
  return copy;
}

// In the probe process: load, check, describe, end. Never returns.
[[noreturn]] void probe_child(const fs::path& path, int out) {
  ::prctl(PR_SET_PDEATHSIG, SIGKILL);  // a probe that hangs ends with qdrun
  // What the library's code prints while it is probed is not qdrun's output.
  if (const int null = ::open("/dev/null", O_WRONLY); null >= 0) {
    ::dup2(null, STDOUT_FILENO);
    ::dup2(null, STDERR_FILENO);
  }
  std::string message;
  Rejection seen;
  try {
    message = describe_declarations(*open_checked(path, seen).info);
  } catch (const SystemError& e) {
    message = "S";  // the system refused what loading it needs: qdrun's failure, not the library's
    put_text(message, e.what());
  } catch (const std::exception& e) {
    message = "E";
    put_text(message, e.what());
    message += seen.names_known ? '\1' : '\0';
    put_u32(message, static_cast<std::uint32_t>(seen.names.size()));
    for (const auto& n : seen.names) put_text(message, n.c_str());
  } catch (...) {
    message = "E";
    put_text(message, (path.string() + ": the plugin entry function threw").c_str());
    message += '\0';
    put_u32(message, 0);
  }
  for (std::size_t at = 0; at < message.size();) {
    const ssize_t n = ::write(out, message.data() + at, message.size() - at);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) break;
    at += static_cast<std::size_t>(n);
  }
  ::_exit(0);  // no exit handlers: they are the parent's
}

}  // namespace

// Starts a probe process for `path`; throws SystemError when none can be started.
Probe start_probe(const fs::path& path) {
  Probe p;
  p.path = path;
  p.deadline = std::chrono::steady_clock::now() + std::chrono::seconds(kProbeSeconds);
  int fds[2];
  if (::pipe2(fds, O_CLOEXEC) != 0)
    throw SystemError("cannot read the plugin library " + path.string() + ": no pipe (" + std::strerror(errno) + ")");
  std::fflush(nullptr);  // nothing buffered is written twice
  p.pid = ::fork();
  if (p.pid == 0) {
    ::close(fds[0]);
    probe_child(path, fds[1]);
  }
  ::close(fds[1]);
  if (p.pid < 0) {
    const int e = errno;
    ::close(fds[0]);
    throw SystemError("cannot read the plugin library " + path.string() +
                      ": no process to load it in could be started (" + std::strerror(e) + "; a process limit?)");
  }
  p.fd = fds[0];
  return p;
}

// Collects a probe's message until it ends or its deadline passes (then it is killed).
void finish_probe(Probe& p) {
  const auto deadline = p.deadline;
  char buffer[65536];
  while (p.fd >= 0) {
    const auto left =
        std::chrono::duration_cast<std::chrono::milliseconds>(deadline - std::chrono::steady_clock::now()).count();
    pollfd pfd{p.fd, POLLIN, 0};
    // Past the deadline, what the probe has written (or its end) still counts.
    const int ready = ::poll(&pfd, 1, static_cast<int>(std::max<long long>(left, 0)));
    if (ready < 0 && errno == EINTR) continue;
    if (ready == 0) {
      p.timed_out = true;
      ::kill(p.pid, SIGKILL);
      break;
    }
    const ssize_t n = ::read(p.fd, buffer, sizeof(buffer));
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) break;
    p.message.append(buffer, static_cast<std::size_t>(n));
  }
  ::close(p.fd);
  p.fd = -1;
  while (::waitpid(p.pid, &p.status, 0) < 0 && errno == EINTR) {
  }
}

// The probe's verdict: the plugin's declarations, or PluginError (its rejection, or how the probe
// process ended: a crash, exit() or a hang in the library's constructors or entry function).
std::shared_ptr<ProbeCopy> verdict(const Probe& p, Rejection& seen) {
  const std::string where = p.path.string();
  if (p.timed_out)
    throw PluginError(where + ": did not finish loading within " + std::to_string(kProbeSeconds) +
                      " s (its static constructors or entry function hang?); qdrun left it out");
  if (WIFSIGNALED(p.status))
    throw PluginError(where + ": crashed while being loaded (signal " + std::to_string(WTERMSIG(p.status)) + ", " +
                      strsignal(WTERMSIG(p.status)) +
                      ", in its static constructors or entry function, or reading what it declares); qdrun left "
                      "it out");
  if (p.message.empty() || (WIFEXITED(p.status) && WEXITSTATUS(p.status) != 0))
    throw PluginError(where + ": ended the process while being loaded (exit(" +
                      std::to_string(WIFEXITED(p.status) ? WEXITSTATUS(p.status) : -1) +
                      ") in its static constructors or entry function); qdrun left it out");
  try {
    MessageReader in(p.message);
    const char kind = in.number<char>();
    if (kind == 'K') {
      auto copy = read_declarations(in);
      if (!in.done()) throw std::runtime_error("trailing bytes");
      return copy;
    }
    std::deque<std::string> keep;
    if (kind == 'S') throw SystemError(in.text(keep));
    if (kind != 'E') throw std::runtime_error("unknown message");
    const std::string reason = in.text(keep);
    seen.names_known = in.number<char>() != 0;
    const auto n = in.number<std::uint32_t>();
    for (std::uint32_t i = 0; i < n; ++i) seen.names.emplace_back(in.text(keep));
    throw PluginError(reason);
  } catch (const PluginError&) {
    throw;
  } catch (const SystemError&) {
    throw;
  } catch (const std::exception& e) {
    throw PluginError(where + ": its probe returned a damaged description (" + e.what() + ")");
  }
}

}  // namespace qd::runtime
