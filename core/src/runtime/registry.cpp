#include "runtime/registry.hpp"

#include <qd/errors.hpp>
#include <qd/version.hpp>

#include <vector>  // boost/dll/library_info.hpp needs it first with BOOST_DLL_USE_STD_FS (Boost 1.74)

#include <boost/dll/library_info.hpp>
#include <boost/dll/runtime_symbol_info.hpp>
#include <boost/dll/shared_library.hpp>

#include <cxxabi.h>
#include <dlfcn.h>
#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <sys/prctl.h>
#include <sys/wait.h>
#include <unistd.h>
#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <deque>
#include <fstream>
#include <set>
#include <sstream>

namespace qd::runtime {
namespace fs = std::filesystem;
namespace dll = boost::dll;

namespace {
constexpr const char* kEntrySymbol = "qd_plugin_entry_v1";

bool looks_like_plugin_file(const fs::path& p) {
  const std::string name = p.filename().string();
  return name.rfind("qd_", 0) == 0 && p.extension() == ".so";
}

// Why a directory entry named like a plugin is no file to load (`status_error`: what following it
// reported).
std::string not_a_library(const fs::path& path, const std::error_code& status_error) {
  std::error_code ec;
  const fs::file_status own = fs::symlink_status(path, ec);
  if (fs::is_symlink(own)) {
    if (status_error == std::errc::too_many_symbolic_link_levels) return "a symbolic link loop, not a shared library";
    if (status_error) return "a symbolic link to nothing (" + status_error.message() + "), not a shared library";
  }
  const fs::file_status st = fs::status(path, ec);
  if (fs::is_directory(st)) return "a directory, not a shared library";
  if (fs::is_fifo(st)) return "a FIFO, not a shared library";
  if (fs::is_character_file(st) || fs::is_block_file(st)) return "a device, not a shared library";
  if (fs::is_socket(st)) return "a socket, not a shared library";
  return "not a regular file, so not a shared library";
}

// What is wrong with a file that should be an ELF shared library, judged from its first bytes; empty
// when it looks like one. Checked here because Boost's ELF reader reports a text file as
// "basic_ios::clear: iostream error".
std::string not_elf_reason(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return "cannot be opened for reading";
  unsigned char id[5] = {0, 0, 0, 0, 0};
  in.read(reinterpret_cast<char*>(id), sizeof(id));
  const std::streamsize got = in.gcount();
  if (got == 0) return "is an empty file, not a shared library";
  if (got < 4 || id[0] != 0x7f || id[1] != 'E' || id[2] != 'L' || id[3] != 'F')
    return "is not a shared library (no ELF header: a text file or other junk named like a plugin)";
  if (got < 5 || id[4] != (sizeof(void*) == 8 ? 2 : 1))  // EI_CLASS: ELFCLASS64 = 2, ELFCLASS32 = 1
    return "is an ELF file for another word size than this qdrun's";
  return "";
}

// dlerror() text without the path it repeats, with a C++ symbol demangled.
std::string dlopen_reason(const std::string& path, std::string text) {
  if (text.rfind(path + ": ", 0) == 0) text.erase(0, path.size() + 2);
  const std::string tag = "undefined symbol: ";
  const auto at = text.find(tag);
  if (at == std::string::npos) return text;
  const std::string symbol = text.substr(at + tag.size());
  int status = 0;
  char* plain = abi::__cxa_demangle(symbol.c_str(), nullptr, nullptr, &status);
  std::string name = status == 0 && plain ? std::string(plain) + " (" + symbol + ")" : symbol;
  std::free(plain);
  return "undefined symbol " + name +
         ": the library needs code that neither it nor the libraries it links define (built against "
         "another qd, or a library missing from qd_add_plugin's LIBRARIES?)";
}

// The ';'-separated parts of two fingerprints that differ, for the mismatch message.
std::string fingerprint_difference(const std::string& plugin, const std::string& core) {
  auto parts = [](const std::string& s) {
    std::vector<std::string> out;
    std::stringstream in(s);
    for (std::string p; std::getline(in, p, ';');) out.push_back(p);
    return out;
  };
  const auto a = parts(plugin), b = parts(core);
  std::string only_plugin, only_core;
  for (const auto& p : a)
    if (std::find(b.begin(), b.end(), p) == b.end()) only_plugin += (only_plugin.empty() ? "" : ", ") + p;
  for (const auto& p : b)
    if (std::find(a.begin(), a.end(), p) == a.end()) only_core += (only_core.empty() ? "" : ", ") + p;
  return "plugin only: " + (only_plugin.empty() ? std::string("-") : only_plugin) +
         "; core only: " + (only_core.empty() ? std::string("-") : only_core);
}
}  // namespace

bool Rejection::could_provide(const std::string& name) const {
  if (!is_plugin) return false;
  return !names_known || std::find(names.begin(), names.end(), name) != names.end();
}

void Registry::add_search_dir(const fs::path& dir, DirOrigin origin) {
  if (dir.empty()) return;
  std::error_code ec;
  fs::path canon = fs::weakly_canonical(fs::absolute(dir, ec), ec);
  if (ec) canon = dir;
  if (std::find(dirs_.begin(), dirs_.end(), canon) != dirs_.end()) return;
  dirs_.push_back(canon);
  origins_.push_back(origin);
}

std::vector<std::string> Registry::user_dirs() const {
  std::vector<std::string> out;
  for (std::size_t i = 0; i < dirs_.size(); ++i)
    if (origins_[i] == DirOrigin::kUser) out.push_back(dirs_[i].string());
  return out;
}

namespace {

// A library opened in this process and checked: the plugin contract's every check passed.
struct Opened {
  std::shared_ptr<dll::shared_library> library;
  const PluginInfo* info = nullptr;
};

// What can be judged of `path` without running any of its code: a regular ELF file of this word
// size that exports the entry symbol. Reading the ELF symbol table first means a shared library
// that is not a plugin is never dlopen'ed (so its static initialisers never run).
void check_file(const fs::path& path, Rejection& seen) {
  const std::string where = path.string();
  std::error_code ec;
  if (!fs::is_regular_file(path, ec)) throw PluginError(where + ": no such plugin file");
  if (const std::string junk = not_elf_reason(path); !junk.empty()) throw PluginError(where + ": " + junk);
  try {
    dll::library_info info(path, /*throw_if_not_native=*/true);
    const auto symbols = info.symbols();
    if (std::find(symbols.begin(), symbols.end(), kEntrySymbol) == symbols.end())
      throw PluginError(where + ": not a qd plugin (no exported symbol '" + kEntrySymbol +
                        "'; was it built with QD_PLUGIN and qd_add_plugin?)");
  } catch (const PluginError&) {
    throw;
  } catch (const std::exception&) {
    // Boost's reader has nothing better to say than "iostream error" about a damaged file.
    throw PluginError(where +
                      ": not a loadable shared library (its ELF symbol table cannot be read: a truncated "
                      "or damaged file?)");
  }
  seen.is_plugin = true;
}

// Loads `path` (which check_file() accepted) into this process and checks what it declares.
Opened open_checked(const fs::path& path, Rejection& seen) {
  const std::string where = path.string();
  auto lib = std::make_shared<dll::shared_library>();
  try {
    lib->load(path, dll::load_mode::rtld_now | dll::load_mode::rtld_local);
  } catch (const std::exception& e) {
    // Boost reports every dlopen failure as "Bad file descriptor"; dlopen's own message names the
    // cause (an undefined symbol, a dependency not found). The failure repeats, so ask again.
    std::string reason = e.what();
    if (void* h = ::dlopen(path.c_str(), RTLD_NOW | RTLD_LOCAL)) {
      ::dlclose(h);
    } else if (const char* text = ::dlerror()) {
      reason = dlopen_reason(where, text);
    }
    // No descriptor or memory left to map it (ulimit -n, ulimit -v): the system's failure, not the
    // library's (exit 4), and never a silent "unknown component" for every library.
    for (const int shortage : {EMFILE, ENFILE, ENOMEM})
      if (reason.find(std::strerror(shortage)) != std::string::npos)
        throw SystemError(where + ": cannot be loaded: " + reason);
    if (reason.find("failed to map segment") != std::string::npos)
      throw SystemError(where + ": cannot be loaded: " + reason + " (too little address space: ulimit -v?)");
    throw PluginError(where + ": cannot be loaded: " + reason);
  }
  // The entry symbol is an alias: a variable holding the entry function's address. It is read as
  // that variable, so a null one is refused before it is called (get_alias would bind a reference
  // to it).
  PluginEntryFn entry = nullptr;
  try {
    const void* const address = lib->get<const void*>(kEntrySymbol);
    static_assert(sizeof(address) == sizeof(entry), "function and object pointers differ in size");
    std::memcpy(&entry, &address, sizeof(entry));
  } catch (const std::exception& e) {
    throw PluginError(where + ": cannot resolve '" + kEntrySymbol + "': " + e.what());
  }
  if (!entry) throw PluginError(where + ": its entry symbol '" + kEntrySymbol + "' is null");
  const PluginInfo* info = nullptr;
  try {
    info = entry();
  } catch (...) {
    throw PluginError(where + ": the plugin entry function threw");
  }
  if (!info) throw PluginError(where + ": the plugin entry returned no information");

  // 2-4. ABI version (read first, nothing else is trusted before it), struct size, fingerprint.
  if (info->abi_version != kPluginAbiVersion)
    throw PluginError(where + ": plugin ABI version " + std::to_string(info->abi_version) +
                      ", but this qdrun expects " + std::to_string(kPluginAbiVersion) +
                      "; rebuild the plugin against this qd installation");
  if (info->info_size != sizeof(PluginInfo))
    throw PluginError(where + ": plugin info size " + std::to_string(info->info_size) + " bytes, expected " +
                      std::to_string(sizeof(PluginInfo)) + "; the plugin was built against other qd headers");
  // From here the structs have this qdrun's layout: their plain C strings can be read even when the
  // fingerprint differs, so a rejection can say which names the library would have provided.
  if (info->components)
    for (std::uint32_t i = 0; i < info->component_count; ++i)
      if (info->components[i].name) seen.names.emplace_back(info->components[i].name);
  seen.names_known = true;
  const char* fp = info->build_fingerprint ? info->build_fingerprint : "";
  if (std::strcmp(fp, build_fingerprint()) != 0)
    throw PluginError(where + ": build fingerprint '" + fp + "' does not match the core's '" + build_fingerprint() +
                      "' (" + fingerprint_difference(fp, build_fingerprint()) +
                      "); rebuild the plugin with the same compiler, Eigen and flags");
  // 5. File name.
  const std::string plugin_name = info->plugin_name ? info->plugin_name : "";
  if (plugin_name.empty() || path.filename().string() != "qd_" + plugin_name + ".so")
    throw PluginError(where + ": plugin calls itself '" + plugin_name + "', so its file must be named qd_" +
                      plugin_name + ".so");
  // 6. Components: well-formed and unique inside the plugin.
  if (info->component_count == 0 || !info->components) throw PluginError(where + ": plugin registers no component");
  std::set<std::string> own;
  for (std::uint32_t i = 0; i < info->component_count; ++i) {
    const ComponentInfo& c = info->components[i];
    if (!c.name || !*c.name || !c.create)
      throw PluginError(where + ": component " + std::to_string(i) + " is malformed");
    if (c.kind < Kind::kEnvironment || c.kind > Kind::kMutator)
      throw PluginError(where + ": component '" + c.name + "' has an unknown kind");
    if (!own.insert(c.name).second)
      throw PluginError(where + ": component name '" + std::string(c.name) + "' is registered twice by this plugin");
    if (c.param_count > 0 && !c.params) throw PluginError(where + ": component '" + c.name + "' has no parameter list");
    if (c.default_descriptor && (c.kind != Kind::kEnvironment || !*c.default_descriptor))
      throw PluginError(where + ": component '" + c.name +
                        "' declares an empty default descriptor or is no environment");
    for (std::uint32_t k = 0; k < c.param_count; ++k)
      if (!c.params[k].key || !c.params[k].default_value)
        throw PluginError(where + ": component '" + c.name + "' declares a parameter without a name or default");
  }
  return {lib, info};
}

// An accepted plugin is never unloaded, not even at exit: its dependencies (libgomp for the
// autoencoder) keep their static state, and no destructor of a plugin-made object can outlive its
// code. Promoting the loaded library to RTLD_NODELETE does that; the extra handle is never closed.
void pin(const fs::path& path) {
  if (!::dlopen(path.c_str(), RTLD_NOW | RTLD_NOLOAD | RTLD_NODELETE))
    throw PluginError(path.string() + ": cannot pin the loaded plugin: " + ::dlerror());
}

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

// What a probe read: a plugin's declarations, owning every string and array they point to.
struct ProbeCopy {
  std::deque<std::string> strings;
  std::deque<std::vector<ParamSpec>> params;
  std::vector<ComponentInfo> components;
  PluginInfo info{};
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

struct Probe {
  fs::path path;
  pid_t pid = -1;
  int fd = -1;
  std::string message;
  bool timed_out = false;
  int status = 0;
  std::chrono::steady_clock::time_point deadline;
};

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

}  // namespace

void Registry::discover() {
  std::vector<fs::path> candidates;
  for (const auto& dir : dirs_) {
    std::error_code ec;
    if (!fs::is_directory(dir, ec)) continue;
    std::vector<fs::path> files;
    for (const auto& e : fs::directory_iterator(dir, ec)) {
      if (!looks_like_plugin_file(e.path())) continue;
      std::error_code ec2;
      if (e.is_regular_file(ec2)) {
        files.push_back(e.path());
        continue;
      }
      // Named like a plugin but no library (a dangling symlink left by a removed build, a
      // directory, a FIFO): left out, and --list says why.
      Rejection r;
      r.path = e.path().string();
      r.reason = r.path + ": " + not_a_library(e.path(), ec2);
      if (std::none_of(rejected_.begin(), rejected_.end(), [&](const Rejection& x) { return x.path == r.path; }))
        rejected_.push_back(std::move(r));
    }
    std::sort(files.begin(), files.end());
    for (const auto& f : files) {
      const auto same = [&](const fs::path& p) {
        std::error_code ec2;
        return fs::equivalent(p, f, ec2);
      };
      if (std::any_of(plugins_.begin(), plugins_.end(), [&](const auto& p) { return same(p->path); }) ||
          std::any_of(candidates.begin(), candidates.end(), same))
        continue;
      candidates.push_back(f);
    }
  }
  // Every library is probed in a process of its own, a few at once (fewer when a process limit
  // refuses more); then they are registered in search order (the first library that provides a
  // name wins).
  constexpr std::size_t kParallelProbes = 4;
  std::vector<Rejection> seen(candidates.size());
  std::vector<Probe> probes(candidates.size());
  std::vector<std::string> errors(candidates.size());
  std::deque<std::size_t> running;
  for (std::size_t next = 0; next < candidates.size() || !running.empty();) {
    while (next < candidates.size() && running.size() < kParallelProbes) {
      try {
        check_file(candidates[next], seen[next]);
      } catch (const PluginError& e) {
        errors[next++] = e.what();
        continue;
      }
      try {
        probes[next] = start_probe(candidates[next]);
      } catch (const SystemError&) {
        if (running.empty()) throw;  // not even one process: the system's failure (exit 4)
        break;                       // again once a running probe has ended
      }
      running.push_back(next++);
    }
    if (running.empty()) continue;
    finish_probe(probes[running.front()]);
    running.pop_front();
  }
  for (std::size_t i = 0; i < candidates.size(); ++i) {
    // A probe the system refused descriptors or memory may have competed with the others (each
    // holds a pipe): alone, now, it is asked once more before that is the verdict.
    if (errors[i].empty() && !probes[i].message.empty() && probes[i].message[0] == 'S') {
      probes[i] = start_probe(candidates[i]);
      finish_probe(probes[i]);
    }
    try {
      if (!errors[i].empty()) throw PluginError(errors[i]);
      std::shared_ptr<ProbeCopy> copy = verdict(probes[i], seen[i]);
      const PluginInfo* info = &copy->info;
      add(candidates[i], info, nullptr, std::move(copy));
    } catch (const PluginError& e) {
      seen[i].path = candidates[i].string();
      seen[i].reason = e.what();
      rejected_.push_back(std::move(seen[i]));
    }
  }
}

std::shared_ptr<LoadedPlugin> Registry::load(const fs::path& path) {
  Rejection seen;
  return load(path, seen);
}

std::shared_ptr<LoadedPlugin> Registry::load(const fs::path& path, Rejection& seen) {
  check_file(path, seen);
  Opened opened = open_checked(path, seen);
  pin(path);
  auto loaded = add(path, opened.info, opened.library, nullptr);
  loaded->own_info = opened.info;
  return loaded;
}

std::shared_ptr<LoadedPlugin> Registry::add(const fs::path& path, const PluginInfo* info,
                                            std::shared_ptr<const void> library,
                                            std::shared_ptr<const void> probe_copy) {
  std::error_code ec;
  auto loaded = std::make_shared<LoadedPlugin>();
  loaded->library = std::move(library);
  loaded->path = fs::weakly_canonical(path, ec).string();
  loaded->info = info;
  loaded->probe_copy = std::move(probe_copy);
  plugins_.push_back(loaded);
  // A name an earlier library already provides is shadowed: only that component is left out,
  // never the library's others.
  for (std::uint32_t i = 0; i < info->component_count; ++i) {
    const ComponentInfo& c = info->components[i];
    if (const ComponentEntry* prior = find(c.name)) {
      shadowed_.push_back({c.name, c.kind, loaded->path, prior->plugin->path});
      continue;
    }
    components_.push_back({&c, loaded});
  }
  return loaded;
}

std::vector<std::string> Registry::warnings() const {
  std::vector<std::string> out;
  std::vector<std::pair<std::string, std::string>> pairs;
  for (const auto& s : shadowed_)
    if (std::find(pairs.begin(), pairs.end(), std::pair{s.path, s.winner}) == pairs.end())
      pairs.emplace_back(s.path, s.winner);
  for (const auto& [path, winner] : pairs) {
    std::string names;
    for (const auto& s : shadowed_)
      if (s.path == path && s.winner == winner) names += (names.empty() ? "'" : ", '") + s.name + "'";
    out.push_back(path + ": " + names + " left out, already provided by " + winner +
                  " (first in the plugin search path wins; the library's other components stay available)");
  }
  return out;
}

const ComponentEntry* Registry::find(const std::string& name) const {
  for (const auto& c : components_)
    if (name == c.info->name) return &c;
  return nullptr;
}

const ComponentEntry& Registry::require(const std::string& name, Kind kind) const {
  const ComponentEntry* e = find(name);
  if (e && e->info->kind == kind) return *e;
  std::string msg;
  if (e) {
    msg =
        "'" + name + "' is a " + to_string(e->info->kind) + " (from " + e->plugin->path + "), not a " + to_string(kind);
    for (const auto& s : shadowed_)
      if (s.name == name && s.kind == kind)
        msg += "; the " + std::string(to_string(kind)) + " '" + name + "' of " + s.path + " is shadowed by it";
  } else {
    msg = "unknown " + std::string(to_string(kind)) + " '" + name + "'";
  }
  std::string known;
  for (const auto& c : components_)
    if (c.info->kind == kind) known += (known.empty() ? "" : ", ") + std::string(c.info->name);
  msg += "; known " + std::string(to_string(kind)) + "s: " + (known.empty() ? "(none)" : known);
  std::string dirs;
  for (const auto& d : dirs_) dirs += (dirs.empty() ? "" : ":") + d.string();
  msg += "; plugin search path: " + (dirs.empty() ? "(empty)" : dirs);
  // Only the libraries that might have provided the name: any other rejection is noise here
  // (qdrun --list shows them all).
  std::size_t others = 0;
  std::string candidates;
  for (const auto& r : rejected_) {
    if (r.could_provide(name))
      candidates += "\n  rejected " + r.reason;
    else
      ++others;
  }
  if (others > 0 && !e)
    msg += " (" + std::to_string(others) + " other rejected librar" + (others == 1 ? "y" : "ies") +
           " could not have provided it; qdrun --list shows why)";
  throw InputError(msg + candidates);
}

Component* Registry::construct(const ComponentEntry& entry, const Config& config, const BuildContext& ctx) const {
  LoadedPlugin& plugin = *entry.plugin;
  if (!plugin.library) {
    // Probed only: loaded now, into this process, and held to what the probe read.
    Rejection seen;
    Opened opened = open_checked(plugin.path, seen);
    const PluginInfo& now = *opened.info;
    bool same = now.component_count == plugin.info->component_count &&
                std::strcmp(now.plugin_name, plugin.info->plugin_name) == 0;
    for (std::uint32_t i = 0; same && i < now.component_count; ++i)
      same = now.components[i].kind == plugin.info->components[i].kind &&
             now.components[i].flags == plugin.info->components[i].flags &&
             std::strcmp(now.components[i].name, plugin.info->components[i].name) == 0;
    if (!same)
      throw PluginError(plugin.path + ": changed on disk since qdrun started (it declares other components now)");
    pin(plugin.path);
    plugin.own_info = opened.info;
    plugin.library = opened.library;
  }
  const ComponentInfo* own = nullptr;
  for (std::uint32_t i = 0; i < plugin.own_info->component_count; ++i)
    if (std::strcmp(plugin.own_info->components[i].name, entry.info->name) == 0) own = &plugin.own_info->components[i];
  if (!own) throw PluginError(plugin.path + ": no longer declares component '" + entry.info->name + "'");
  try {
    Component* c = own->create(config, ctx);
    if (!c)
      throw PluginError("component '" + std::string(entry.info->name) + "' from " + entry.plugin->path +
                        ": factory returned nothing");
    return c;
  } catch (const ConfigError&) {
    throw;  // the caller adds the key's location
  } catch (const PluginError&) {
    throw;
  } catch (const std::exception& e) {
    // Copy the text: the exception object lives in plugin memory.
    throw PluginError("component '" + std::string(entry.info->name) + "' from " + entry.plugin->path +
                      " failed to construct: " + e.what());
  } catch (...) {
    throw PluginError("component '" + std::string(entry.info->name) + "' from " + entry.plugin->path +
                      " failed to construct (unknown exception)");
  }
}

void Registry::destroy(Component* c, const ComponentEntry&) noexcept {
  delete c;
}

void Registry::throw_wrong_type(const ComponentEntry& entry) {
  throw PluginError("component '" + std::string(entry.info->name) + "' from " + entry.plugin->path +
                    " is registered as a " + to_string(entry.info->kind) + " but its object is not one");
}

fs::path installed_plugin_dir() {
  std::error_code ec;
  const fs::path exe = dll::program_location(ec);
  if (ec) return {};
  return exe.parent_path().parent_path() / "lib" / "qd" / "plugins";
}

fs::path build_tree_plugin_dir() {
#if defined(QD_BUILD_PLUGIN_DIR) && defined(QD_BUILD_BIN_DIR)
  // Decided at run time, by where the executable is: the same binary installed elsewhere (even into
  // a prefix inside the build tree, as tests/install does) must not see this tree's plugins.
  std::error_code ec;
  const fs::path exe = dll::program_location(ec);
  if (ec || !fs::equivalent(exe.parent_path(), fs::path(QD_BUILD_BIN_DIR), ec) || ec) return {};
  return fs::path(QD_BUILD_PLUGIN_DIR);
#else
  return {};
#endif
}

}  // namespace qd::runtime
