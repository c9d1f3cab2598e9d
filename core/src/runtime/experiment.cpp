#include "runtime/experiment.hpp"

#include "runtime/components.hpp"
#include "runtime/number_text.hpp"
#include "runtime/run_directory.hpp"

#include <qd/errors.hpp>

#include <toml++/toml.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <limits>
#include <map>
#include <optional>
#include <sstream>

namespace qd::runtime {
namespace fs = std::filesystem;

// The component type in effect where a key of a component table was set: the type in the same
// file's table or, failing that, in the layers below it. A key set under another type than the
// final one came with a component that an include or --set replaced. `known` is false for keys of
// --set (always validated) and for keys with no type anywhere below them yet.
struct KeyOrigin {
  std::string type;
  bool known = false;
};
using KeyOrigins = std::map<std::string, std::map<std::string, KeyOrigin>>;  // table -> key -> origin

struct Document::Impl {
  toml::table root;
  fs::path file;
  KeyOrigins origins;
};

Document::Document() : impl(std::make_unique<Impl>()) {}
Document::~Document() = default;
Document::Document(Document&&) noexcept = default;
Document& Document::operator=(Document&&) noexcept = default;

namespace {

// An experiment file, a run's config.toml or provenance: far beyond any real one.
constexpr std::uint64_t kMaxTomlBytes = 16 << 20;

// Text for a message: control characters (a newline in a path given on the command line) shown
// as escapes, so a message stays one line.
std::string printable(const std::string& text) {
  std::string out;
  for (const char c : text) {
    const auto u = static_cast<unsigned char>(c);
    if (u >= 0x20 && u != 0x7f) {
      out += c;
    } else {
      char esc[8];
      std::snprintf(esc, sizeof(esc), c == '\n' ? "\\n" : "\\x%02x", u);
      out += esc;
    }
  }
  return out;
}

bool has_control_character(const std::string& text) {
  return std::any_of(text.begin(), text.end(), [](char c) {
    const auto u = static_cast<unsigned char>(c);
    return u < 0x20 || u == 0x7f;
  });
}

std::string key_text(std::string_view key) {
  const bool bare = !key.empty() && std::all_of(key.begin(), key.end(), [](char c) {
    return std::isalnum(static_cast<unsigned char>(c)) || c == '_' || c == '-';
  });
  return bare ? std::string(key) : toml_string(std::string(key));
}

// TOML text of a value, numbers in their shortest exact form (toml++ writes 17 significant
// digits: 0.050000000000000003 for 0.05), for config.toml and for messages.
void put_value(std::ostream& o, const toml::node& n) {
  if (const auto* f = n.as_floating_point()) {
    std::string t = format_number(f->get());
    if (t.find_first_of(".eEn") == std::string::npos) t += ".0";  // TOML: a float has a point or exponent
    o << t;
  } else if (const auto* i = n.as_integer()) {
    o << i->get();
  } else if (const auto* b = n.as_boolean()) {
    o << (b->get() ? "true" : "false");
  } else if (const auto* str = n.as_string()) {
    // A literal string where one can hold it, as toml++ writes them.
    const std::string& v = str->get();
    if (v.find('\'') == std::string::npos && !has_control_character(v))
      o << '\'' << v << '\'';
    else
      o << toml_string(v);
  } else if (const auto* a = n.as_array()) {
    o << '[';
    for (std::size_t k = 0; k < a->size(); ++k) {
      if (k) o << ", ";
      put_value(o, *a->get(k));
    }
    o << ']';
  } else if (const auto* t = n.as_table()) {
    o << '{';
    bool first = true;
    for (auto&& [k, v] : *t) {
      o << (first ? " " : ", ") << key_text(k.str()) << " = ";
      put_value(o, v);
      first = false;
    }
    o << (first ? "}" : " }");
  } else {
    n.visit([&](const auto& v) { o << v; });  // dates and times, which no parameter takes
  }
}

std::string value_text(const toml::node& n) {
  std::ostringstream o;
  put_value(o, n);
  return o.str();
}

// A resolved configuration as TOML: each table's values, then its sub-tables under [headers].
void put_table(std::ostream& o, const toml::table& t, const std::string& prefix) {
  for (auto&& [k, v] : t) {
    if (v.is_table()) continue;
    o << key_text(k.str()) << " = ";
    put_value(o, v);
    o << '\n';
  }
  for (auto&& [k, v] : t) {
    if (!v.is_table()) continue;
    const std::string name = prefix.empty() ? key_text(k.str()) : prefix + "." + key_text(k.str());
    o << "\n[" << name << "]\n";
    put_table(o, *v.as_table(), name);
  }
}

std::string toml_text(const toml::table& t) {
  std::ostringstream o;
  put_table(o, t, "");
  std::string text = o.str();
  if (!text.empty() && text.front() == '\n') text.erase(0, 1);
  return text;
}

std::string location(const toml::source_region& src) {
  if (!src.path) return "<unknown>";
  const std::string& p = *src.path;
  // Command-line options (--set, --seed, --backend, --output) name themselves.
  if (p.rfind("--", 0) == 0) return printable(p);
  return p + ":" + std::to_string(src.begin.line) + ":" + std::to_string(src.begin.column);
}

std::string location(const toml::node& n) {
  return location(n.source());
}

[[noreturn]] void fail_at(const toml::node& n, const std::string& msg) {
  throw InputError(location(n) + ": " + msg);
}

std::size_t edit_distance(const std::string& a, const std::string& b) {
  std::vector<std::size_t> prev(b.size() + 1), cur(b.size() + 1);
  for (std::size_t j = 0; j <= b.size(); ++j) prev[j] = j;
  for (std::size_t i = 1; i <= a.size(); ++i) {
    cur[0] = i;
    for (std::size_t j = 1; j <= b.size(); ++j)
      cur[j] = std::min({prev[j] + 1, cur[j - 1] + 1, prev[j - 1] + (a[i - 1] == b[j - 1] ? 0 : 1)});
    std::swap(prev, cur);
  }
  return prev[b.size()];
}

std::string suggestion(const std::string& key, const std::vector<std::string>& known) {
  std::string best;
  std::size_t best_d = 3;
  for (const auto& k : known) {
    const std::size_t d = edit_distance(key, k);
    if (d < best_d) best_d = d, best = k;
  }
  return best.empty() ? "" : " (did you mean '" + best + "'?)";
}

std::string join(const std::vector<std::string>& v) {
  std::string s;
  for (const auto& x : v) s += (s.empty() ? "" : ", ") + x;
  return s.empty() ? "(none)" : s;
}

// Merges `over` into `base`: tables merge key by key, everything else is replaced. Nodes are
// moved, never copied: toml++ keeps a node's source location only through moves, and every error
// message needs it.
void deep_merge(toml::table& base, toml::table&& over) {
  for (auto&& [k, v] : over) {
    if (auto* sub = v.as_table()) {
      if (auto* existing = base.get(k); existing && existing->is_table()) {
        deep_merge(*existing->as_table(), std::move(*sub));
        continue;
      }
    }
    base.insert_or_assign(k, std::move(v));
  }
}

constexpr const char* kComponentTableNames[] = {"environment", "descriptor", "representation", "mutator", "initial"};

const toml::table* table_of(const toml::table& root, const char* name) {
  const toml::node* n = root.get(name);
  return n ? n->as_table() : nullptr;
}

std::optional<std::string> type_of(const toml::table& root, const char* table) {
  const toml::table* t = table_of(root, table);
  const toml::node* type = t ? t->get("type") : nullptr;
  if (type && type->is_string()) return type->as_string()->get();
  return std::nullopt;
}

// One file's own keys, tagged with the type its table names (if any).
KeyOrigins own_origins(const toml::table& root) {
  KeyOrigins out;
  for (const char* name : kComponentTableNames) {
    const toml::table* t = table_of(root, name);
    if (!t) continue;
    const auto type = type_of(root, name);
    for (const auto& [k, v] : *t)
      if (k.str() != "type") out[name][std::string(k.str())] = {type.value_or(""), type.has_value()};
  }
  return out;
}

struct Layered {
  toml::table root;
  KeyOrigins origins;
};

// Puts `over` on top of `base` (the including file over its includes, a later include over an
// earlier one). Keys of `over` without a type of their own were written for the type below them.
void layer(Layered& base, Layered&& over) {
  for (auto& [table, keys] : over.origins) {
    const auto below = type_of(base.root, table.c_str());
    for (auto& [key, origin] : keys) {
      if (!origin.known && below) origin = {*below, true};
      base.origins[table][key] = origin;
    }
  }
  deep_merge(base.root, std::move(over.root));
}

// `chain`: the files that include this one, outermost first (an include cycle is named, not
// followed).
Layered parse_file(const fs::path& file, std::vector<fs::path>& chain) {
  std::error_code ec;
  const fs::path canonical = fs::weakly_canonical(fs::absolute(file, ec), ec);
  if (const auto seen = std::find(chain.begin(), chain.end(), canonical); seen != chain.end()) {
    std::string cycle;
    for (auto it = seen; it != chain.end(); ++it) cycle += it->string() + " -> ";
    throw InputError(file.string() + ": an include cycle (" + cycle + canonical.string() + ")");
  }
  if (chain.size() > 16) throw InputError(file.string() + ": includes nest more than 16 levels");
  const fs::file_status st = fs::status(file, ec);
  if (ec && ec != std::errc::no_such_file_or_directory)
    throw InputError(file.string() + ": cannot read the experiment file: " + ec.message());
  if (!fs::exists(st)) throw InputError(file.string() + ": no such experiment file");
  // A FIFO or device would block or never end: an experiment file is a regular file (a symlink to
  // one is fine), and far smaller than this.
  if (!fs::is_regular_file(st)) throw InputError(file.string() + ": not a regular file, so not an experiment file");
  const auto size = fs::file_size(file, ec);
  if (!ec && size > kMaxTomlBytes)
    throw InputError(file.string() + ": " + std::to_string(size) + " bytes, larger than any experiment file (" +
                     std::to_string(kMaxTomlBytes >> 20) + " MB at most)");
  std::ifstream in(file);
  if (!in) throw InputError(file.string() + ": cannot open experiment file: " + std::strerror(errno));
  std::stringstream ss;
  ss << in.rdbuf();
  toml::table t;
  try {
    t = toml::parse(ss.str(), file.string());
  } catch (const toml::parse_error& e) {
    throw InputError(location(e.source()) + ": malformed TOML: " + std::string(e.description()));
  }
  const toml::node* inc = t.get("include");
  if (!inc) {
    KeyOrigins origins = own_origins(t);
    return {std::move(t), std::move(origins)};
  }
  std::vector<std::string> includes;
  if (inc->is_string()) {
    includes.push_back(inc->as_string()->get());
  } else if (inc->is_array()) {
    for (const auto& x : *inc->as_array()) {
      if (!x.is_string()) fail_at(x, "include entries must be strings (paths)");
      includes.push_back(x.as_string()->get());
    }
  } else {
    fail_at(*inc, "include must be a path or a list of paths");
  }
  Layered merged;
  chain.push_back(canonical);
  for (const auto& rel : includes) {
    fs::path p = fs::path(rel).is_absolute() ? fs::path(rel) : file.parent_path() / rel;
    try {
      layer(merged, parse_file(p, chain));
    } catch (const InputError& e) {
      throw InputError(std::string(e.what()) + " (included from " + location(*inc) + ")");
    }
  }
  chain.pop_back();
  t.erase("include");
  KeyOrigins origins = own_origins(t);
  layer(merged, Layered{std::move(t), std::move(origins)});
  return merged;
}

// ---- Core schema --------------------------------------------------------------------------
constexpr double kMaxInt = 9.0e15;
const ParamSpec kExperimentParams[] = {
    param_string("name", "\"\"", nullptr,
                 "run name; the run directory is <output.dir>/<name>/seed-<seed> (default: file name)"),
    param_int("seed", "0", 0, kMaxInt, "root seed; every random stream derives from it"),
    param_int("loops", "51", 1, 1e7, "loops including loop 0 (the initial random phase)"),
    param_int("iterations", "100", 1, 1e9, "MAP-Elites iterations per loop n >= 1"),
    param_int("batch", "200", 1, 1e7, "offspring (and selected parents) per iteration"),
    param_int("initial_samples", "2000", 1, 1e9, "policies sampled in loop 0"),
    param_string("insertion", "\"coin-flip\"", "coin-flip|fitness",
                 "occupied cell: coin-flip = replace with replace_probability (reference); fitness = replace if "
                 "strictly fitter"),
    param_float("replace_probability", "0.5", 0.0, 1.0, "replacement probability of the coin-flip rule"),
    param_float("fitness_lower_bound", "nan", -kMaxInt, kMaxInt,
                "lowest fitness of the task, for metrics.csv's qd_score = sum over elites of (fitness - bound); nan = "
                "the environment's own (if it declares one)"),
    param_string("dataset_order", "\"reference\"", "reference|insertion",
                 "order of loop-0 dataset entries: reference = descending cell index (np.unique order), insertion = "
                 "first found first"),
};
const ParamSpec kPolicyParams[] = {
    param_int_list("hidden", "[32, 32]", 1, 4096, "hidden layer sizes of the tanh MLP policy"),
};
const ParamSpec kOutputParams[] = {
    param_string("dir", "\"runs\"", nullptr, "root directory of run directories (relative to the working directory)"),
    param_int("snapshot_every", "0", 0, 1e9, "also write an archive snapshot every N loops (0 = final archive only)"),
    param_bool("snapshot_parameters", "true", "include policy parameters in archive snapshots"),
};
const ParamSpec kEvaluationParams[] = {
    param_int("workers", "0", 0, 4096, "local evaluation workers (0 = all cores); results do not depend on it"),
    param_string("backend", "\"auto\"", "auto|threads|processes|mpi",
                 "auto = mpi under mpirun, else processes (supervised worker processes, also for one worker); "
                 "threads = inside qdrun, unsupervised; results do not depend on it"),
    param_float("timeout_seconds", "300", 0.0, 1e9,
                "a worker process or MPI rank that makes no progress this long in a batch is hung: the run "
                "stops (0 = wait forever; the threads backend cannot time out)"),
};

const ParamSpec kCostParams[] = {
    param_int_list("evaluations", "[]", 0, kMaxInt,
                   "evaluations done (increasing) at which offspring_time is given; --dry-run only"),
    param_float_list("offspring_time", "[]", 0.01, 1000,
                     "time per evaluation of a mutation operator at each of `evaluations`, as a multiple of loop "
                     "0's (linear in between, end values held; [] = the dry-run pilot's offspring throughout; "
                     "qdreport measures it from finished runs); --dry-run only, no result depends on it"),
};

struct ComponentTable {
  const char* name;
  Kind kind;
  const char* default_type;  // nullptr = required
};
const ComponentTable kComponentTables[] = {
    {"environment", Kind::kEnvironment, nullptr},
    {"descriptor", Kind::kDescriptor, ""},
    {"representation", Kind::kRepresentation, "none"},
    {"mutator", Kind::kMutator, nullptr},
    {"initial", Kind::kMutator, "uniform"},
};

bool number_in_range(double v, const ParamSpec& s) {
  return v >= s.min && v <= s.max;
}

// A bound or value as the user would write it: integers in full (9000000000000000, not 9e+15),
// floats in their shortest exact form.
std::string number_text(double v, bool integer) {
  if (integer && std::isfinite(v) && std::abs(v) < 9.2e18 && v == std::floor(v))
    return std::to_string(static_cast<long long>(v));
  return format_number(v);
}

// "[0, 1]"; an infinite bound is excluded: "[0, inf)", "(-inf, inf)".
std::string range_text(const ParamSpec& s) {
  const bool integer = s.type == ParamType::kInteger || s.type == ParamType::kIntegerList;
  return (std::isinf(s.min) ? "(" : "[") + number_text(s.min, integer) + ", " + number_text(s.max, integer) +
         (std::isinf(s.max) ? ")" : "]");
}

// Checks one value node against its spec and stores it in `cfg`.
void take_value(const toml::node& n, const ParamSpec& s, const std::string& path, Config& cfg) {
  const std::string where = location(n);
  auto type_error = [&]() {
    fail_at(n, path + " must be " + std::string(s.type == ParamType::kInteger ? "an " : "a ") + to_string(s.type));
  };
  auto check_number = [&](double v, const toml::node& at) {
    const std::string text = at.is_integer() ? std::to_string(at.as_integer()->get()) : format_number(v);
    if (!std::isfinite(v)) fail_at(at, path + " = " + text + " is not a finite number (range " + range_text(s) + ")");
    if (!number_in_range(v, s)) fail_at(at, path + " = " + text + " is out of range " + range_text(s));
  };
  switch (s.type) {
    case ParamType::kBool:
      if (!n.is_boolean()) type_error();
      cfg.set_bool(s.key, n.as_boolean()->get(), where);
      break;
    case ParamType::kInteger:
      if (!n.is_integer()) type_error();
      check_number(static_cast<double>(n.as_integer()->get()), n);
      cfg.set_int(s.key, n.as_integer()->get(), where);
      break;
    case ParamType::kFloat: {
      if (!n.is_number()) type_error();
      const double v = n.value<double>().value();
      // A float whose default is nan ("not set") takes nan back from a resolved config.toml.
      if (!(std::isnan(v) && std::string(s.default_value) == "nan")) check_number(v, n);
      cfg.set_float(s.key, v, where);
      break;
    }
    case ParamType::kString: {
      if (!n.is_string()) type_error();
      const std::string v = n.as_string()->get();
      if (s.choices) {
        std::vector<std::string> options;
        std::string c = s.choices;
        for (std::size_t pos = 0;;) {
          const std::size_t bar = c.find('|', pos);
          options.push_back(c.substr(pos, bar == std::string::npos ? std::string::npos : bar - pos));
          if (bar == std::string::npos) break;
          pos = bar + 1;
        }
        if (std::find(options.begin(), options.end(), v) == options.end())
          fail_at(n, path + " = \"" + v + "\" is not one of: " + join(options) + suggestion(v, options));
      }
      cfg.set_string(s.key, v, where);
      break;
    }
    case ParamType::kIntegerList: {
      if (!n.is_array()) type_error();
      std::vector<std::int64_t> v;
      for (const auto& x : *n.as_array()) {
        if (!x.is_integer()) fail_at(x, path + " must be a list of integers");
        check_number(static_cast<double>(x.as_integer()->get()), x);
        v.push_back(x.as_integer()->get());
      }
      cfg.set_int_list(s.key, std::move(v), where);
      break;
    }
    case ParamType::kFloatList: {
      if (!n.is_array()) type_error();
      std::vector<double> v;
      for (const auto& x : *n.as_array()) {
        if (!x.is_number()) fail_at(x, path + " must be a list of numbers");
        check_number(x.value<double>().value(), x);
        v.push_back(x.value<double>().value());
      }
      cfg.set_float_list(s.key, std::move(v), where);
      break;
    }
  }
}

// Validates `tbl` (may be null = all defaults) against `specs`; `skip` keys are handled by the caller.
Config validate_table(const toml::table* tbl, const std::string& table, const ParamSpec* specs, std::size_t count,
                      const std::string& owner, const std::vector<std::string>& skip = {}) {
  Config cfg(table);
  std::vector<std::string> known;
  for (std::size_t i = 0; i < count; ++i) known.emplace_back(specs[i].key);
  if (tbl) {
    for (const auto& [k, v] : *tbl) {
      const std::string key(k.str());
      if (std::find(skip.begin(), skip.end(), key) != skip.end()) continue;
      const ParamSpec* spec = nullptr;
      for (std::size_t i = 0; i < count; ++i)
        if (key == specs[i].key) spec = &specs[i];
      if (!spec)
        fail_at(v, "unknown key '" + key + "' in [" + table + "]" + suggestion(key, known) + "; " + owner +
                       " accepts: " + join(known));
      take_value(v, *spec, table + "." + key, cfg);
    }
  }
  for (std::size_t i = 0; i < count; ++i)
    if (!cfg.has(specs[i].key)) cfg.set_from_text(specs[i], specs[i].default_value);
  return cfg;
}

const toml::table* sub_table(const toml::table& root, const char* name) {
  const toml::node* n = root.get(name);
  if (!n) return nullptr;
  if (!n->is_table()) fail_at(*n, std::string(name) + " must be a table ([" + name + "])");
  return n->as_table();
}

void put_config(toml::table& out, const Config& cfg, const ParamSpec* specs, std::size_t count) {
  for (std::size_t i = 0; i < count; ++i) {
    const ParamSpec& s = specs[i];
    switch (s.type) {
      case ParamType::kBool:
        out.insert_or_assign(s.key, cfg.get_bool(s.key));
        break;
      case ParamType::kInteger:
        out.insert_or_assign(s.key, cfg.get_int(s.key));
        break;
      case ParamType::kFloat:
        out.insert_or_assign(s.key, cfg.get_float(s.key));
        break;
      case ParamType::kString:
        out.insert_or_assign(s.key, cfg.get_string(s.key));
        break;
      case ParamType::kIntegerList: {
        toml::array a;
        for (auto x : cfg.get_int_list(s.key)) a.push_back(x);
        out.insert_or_assign(s.key, std::move(a));
        break;
      }
      case ParamType::kFloatList: {
        toml::array a;
        for (auto x : cfg.get_float_list(s.key)) a.push_back(x);
        out.insert_or_assign(s.key, std::move(a));
        break;
      }
    }
  }
}

}  // namespace

Document Document::read(const fs::path& file) {
  Document d;
  d.impl->file = fs::absolute(file);
  std::vector<fs::path> chain;
  Layered l = parse_file(d.impl->file, chain);
  d.impl->root = std::move(l.root);
  d.impl->origins = std::move(l.origins);
  return d;
}

Document Document::parse(const std::string& text, const std::string& source_name) {
  Document d;
  try {
    d.impl->root = toml::parse(text, source_name);
  } catch (const toml::parse_error& e) {
    throw InputError(location(e.source()) + ": malformed TOML: " + std::string(e.description()));
  }
  d.impl->origins = own_origins(d.impl->root);
  return d;
}

fs::path Document::file() const {
  return impl->file;
}

void Document::apply_override(const std::string& assignment, const std::string& option) {
  const std::size_t eq = assignment.find('=');
  if (eq == std::string::npos || eq == 0)
    throw InputError("--set " + assignment + ": expected KEY.PATH=VALUE, for example --set mutator.sigma=0.05");
  const std::string path = assignment.substr(0, eq);
  const std::string value = assignment.substr(eq + 1);
  const std::string source = option.empty() ? "--set " + assignment : option;
  toml::table parsed;
  bool bare = false;
  try {
    parsed = toml::parse("v = " + value, source);
    // TOML reads the words nan and inf as floats and 2024-01-01 as a date; no parameter takes
    // either, and --set mutator.mode=nan means the word.
    const toml::node& v = *parsed.get("v");
    bare = (v.is_floating_point() && !std::isfinite(v.as_floating_point()->get())) || v.is_date() || v.is_time() ||
           v.is_date_time();
  } catch (const toml::parse_error&) {
    bare = true;  // --set mutator.type=iso
  }
  if (bare) {
    try {
      parsed = toml::parse("v = " + toml_string(value), source);
    } catch (const toml::parse_error& e) {
      throw InputError(printable(source) + ": the value cannot be read: " + std::string(e.description()));
    }
  }
  std::vector<std::string> parts;
  for (std::size_t pos = 0;;) {
    const std::size_t dot = path.find('.', pos);
    parts.push_back(path.substr(pos, dot == std::string::npos ? std::string::npos : dot - pos));
    if (dot == std::string::npos) break;
    pos = dot + 1;
  }
  for (const auto& part : parts)
    if (part.empty()) throw InputError(printable(source) + ": empty key");
  toml::table* t = &impl->root;
  for (std::size_t i = 0; i + 1 < parts.size(); ++i) {
    toml::node* n = t->get(parts[i]);
    if (!n) {
      // Made by parsing, so that an error about the table (an unknown one) names this option.
      toml::table made = toml::parse("t = {}", source);
      t->insert_or_assign(parts[i], std::move(*made.get("t")));
      n = t->get(parts[i]);
    }
    if (!n->is_table()) throw InputError(printable(source) + ": '" + parts[i] + "' is not a table");
    t = n->as_table();
  }
  t->insert_or_assign(parts.back(), std::move(*parsed.get("v")));
  // A key given on the command line is always checked against the final component; a new type
  // leaves the keys already there tagged with the old one.
  if (parts.size() == 2 && parts[1] != "type") impl->origins[parts[0]][parts[1]] = KeyOrigin{};
}

namespace {
// The entries of [plugins] `key` (a path or a list of paths), made absolute against `file`'s
// directory. Checks every key of [plugins].
std::vector<std::string> plugin_dirs(const toml::table& root, const fs::path& file, const std::string& key) {
  std::vector<std::string> out;
  const toml::table* t = sub_table(root, "plugins");
  if (!t) return out;
  for (const auto& [k, v] : *t) {
    if (k.str() != "path" && k.str() != "search_path")
      fail_at(v, "unknown key '" + std::string(k.str()) + "' in [plugins]; it accepts: path, search_path");
    if (k.str() != key) continue;
    auto add = [&](const toml::node& x) {
      if (!x.is_string()) fail_at(x, "plugins." + key + " entries must be strings");
      fs::path p = x.as_string()->get();
      if (p.is_relative() && !file.empty()) p = file.parent_path() / p;
      out.push_back(p.lexically_normal().string());
    };
    if (v.is_array()) {
      for (const auto& x : *v.as_array()) add(x);
    } else {
      add(v);
    }
  }
  return out;
}
}  // namespace

std::vector<std::string> Document::plugin_paths() const {
  return plugin_dirs(impl->root, impl->file, "path");
}

std::vector<std::string> Document::recorded_search_path() const {
  return plugin_dirs(impl->root, impl->file, "search_path");
}

double CostModel::offspring_time_at(double n) const {
  if (evaluations.empty()) return 1.0;
  if (n <= evaluations.front()) return offspring_time.front();
  for (std::size_t i = 1; i < evaluations.size(); ++i)
    if (n <= evaluations[i]) {
      const double t = (n - evaluations[i - 1]) / (evaluations[i] - evaluations[i - 1]);
      return offspring_time[i - 1] + t * (offspring_time[i] - offspring_time[i - 1]);
    }
  return offspring_time.back();
}

std::vector<CoreTable> core_tables() {
  return {{"experiment", kExperimentParams, std::size(kExperimentParams)},
          {"policy", kPolicyParams, std::size(kPolicyParams)},
          {"output", kOutputParams, std::size(kOutputParams)},
          {"evaluation", kEvaluationParams, std::size(kEvaluationParams)},
          {"cost", kCostParams, std::size(kCostParams)}};
}

Experiment resolve(const Document& doc, const Registry& registry) {
  const toml::table& root = doc.impl->root;
  std::vector<std::string> allowed = {"experiment", "policy", "output", "evaluation", "cost", "plugins"};
  for (const auto& t : kComponentTables) allowed.emplace_back(t.name);
  for (const auto& [k, v] : root) {
    const std::string key(k.str());
    if (std::find(allowed.begin(), allowed.end(), key) == allowed.end())
      fail_at(v,
              "unknown table '" + key + "'" + suggestion(key, allowed) + "; experiment files have: " + join(allowed));
  }

  Experiment ex;
  ex.file = doc.impl->file;
  ex.plugin_paths = doc.plugin_paths();
  const Config e = validate_table(sub_table(root, "experiment"), "experiment", kExperimentParams,
                                  std::size(kExperimentParams), "the core");
  const Config p =
      validate_table(sub_table(root, "policy"), "policy", kPolicyParams, std::size(kPolicyParams), "the core");
  const Config o =
      validate_table(sub_table(root, "output"), "output", kOutputParams, std::size(kOutputParams), "the core");
  const Config w = validate_table(sub_table(root, "evaluation"), "evaluation", kEvaluationParams,
                                  std::size(kEvaluationParams), "the core");
  auto& s = ex.settings;
  s.name = e.get_string("name");
  if (s.name.empty()) s.name = ex.file.empty() ? "experiment" : ex.file.stem().string();
  if (s.name.find('/') != std::string::npos || s.name == "." || s.name == "..")
    throw InputError(e.where("name") + ": experiment.name must be a plain name, not a path");
  // Both name directories; a newline or other control character in one is a mistake that would
  // only surface later, in every tool that lists them.
  if (has_control_character(s.name))
    throw InputError(e.where("name") + ": experiment.name contains a control character (" + printable(s.name) +
                     "); it names the run directory");
  // A directory name has at most 255 bytes (NAME_MAX): said here, not by a failed mkdir that
  // prints the whole name.
  if (s.name.size() > 255)
    throw InputError(e.where("name") + ": experiment.name is " + std::to_string(s.name.size()) +
                     " bytes long; it names the run directory, and a directory name has at most 255");
  s.seed = static_cast<std::uint64_t>(e.get_int("seed"));
  s.loops = static_cast<int>(e.get_int("loops"));
  s.iterations = static_cast<int>(e.get_int("iterations"));
  s.batch = static_cast<int>(e.get_int("batch"));
  s.initial_samples = static_cast<int>(e.get_int("initial_samples"));
  s.insertion = e.get_string("insertion");
  s.replace_probability = e.get_float("replace_probability");
  s.fitness_lower_bound = e.get_float("fitness_lower_bound");
  s.dataset_order = e.get_string("dataset_order");
  for (auto h : p.get_int_list("hidden")) s.hidden.push_back(static_cast<int>(h));
  s.output_dir = o.get_string("dir");
  if (has_control_character(s.output_dir))
    throw InputError(o.where("dir") + ": output.dir contains a control character (" + printable(s.output_dir) + ")");
  if (s.output_dir.empty()) throw InputError(o.where("dir") + ": output.dir is empty");
  s.snapshot_every = static_cast<int>(o.get_int("snapshot_every"));
  s.snapshot_parameters = o.get_bool("snapshot_parameters");
  s.workers = static_cast<int>(w.get_int("workers"));
  s.backend = w.get_string("backend");
  s.timeout_seconds = w.get_float("timeout_seconds");
  const Config cost = validate_table(sub_table(root, "cost"), "cost", kCostParams, std::size(kCostParams), "the core");
  for (auto n : cost.get_int_list("evaluations")) s.cost.evaluations.push_back(static_cast<double>(n));
  s.cost.offspring_time = cost.get_float_list("offspring_time");
  if (s.cost.evaluations.size() != s.cost.offspring_time.size())
    throw InputError(cost.where("offspring_time") + ": cost.offspring_time has " +
                     std::to_string(s.cost.offspring_time.size()) + " values for " +
                     std::to_string(s.cost.evaluations.size()) + " cost.evaluations; give one per entry");
  for (std::size_t i = 1; i < s.cost.evaluations.size(); ++i)
    if (s.cost.evaluations[i] <= s.cost.evaluations[i - 1])
      throw InputError(cost.where("evaluations") + ": cost.evaluations must increase (entry " + std::to_string(i + 1) +
                       " is not above entry " + std::to_string(i) + ")");

  toml::table resolved;
  auto put_core = [&](const char* name, const Config& cfg, const ParamSpec* specs, std::size_t n) {
    toml::table t;
    put_config(t, cfg, specs, n);
    resolved.insert_or_assign(name, std::move(t));
  };
  put_core("experiment", e, kExperimentParams, std::size(kExperimentParams));
  resolved["experiment"].as_table()->insert_or_assign("name", s.name);
  put_core("policy", p, kPolicyParams, std::size(kPolicyParams));
  put_core("output", o, kOutputParams, std::size(kOutputParams));
  put_core("evaluation", w, kEvaluationParams, std::size(kEvaluationParams));
  // [cost] is left out: no result depends on it (CostModel).

  for (const auto& ct : kComponentTables) {
    ComponentConfig* cc = nullptr;
    const std::string table = ct.name;
    if (table == "environment") cc = &ex.environment;
    if (table == "descriptor") cc = &ex.descriptor;
    if (table == "representation") cc = &ex.representation;
    if (table == "mutator") cc = &ex.mutator;
    if (table == "initial") cc = &ex.initial;
    cc->table = table;
    const toml::table* t = sub_table(root, ct.name);
    const toml::node* type_node = t ? t->get("type") : nullptr;
    if (type_node && !type_node->is_string()) fail_at(*type_node, table + ".type must be a string (a component name)");
    if (type_node) {
      cc->type = type_node->as_string()->get();
    } else if (ct.default_type && *ct.default_type) {
      cc->type = ct.default_type;
    } else if (ct.default_type) {
      // Descriptor: the environment's default, chosen once the environment exists.
      if (t && !t->empty()) fail_at(*t, "[descriptor] sets options but no type; add type = \"<descriptor name>\"");
      continue;
    } else {
      throw InputError((ex.file.empty() ? std::string("<experiment>") : ex.file.string()) + ": [" + table +
                       "] with a type is required (see qdrun --list for the available " + to_string(ct.kind) + "s)");
    }
    try {
      cc->entry = &registry.require(cc->type, ct.kind);
    } catch (const InputError& err) {
      throw InputError((type_node ? location(*type_node) : std::string("default")) + ": " + table +
                       ".type: " + err.what());
    }
    const ComponentInfo& info = *cc->entry->info;
    // Keys written for a component that an include or --set replaced: those the new component does
    // not declare are dropped, with a note, instead of failing as unknown keys.
    std::vector<std::string> skip = {"type"};
    if (t) {
      std::string dropped, replaced;
      const auto origins = doc.impl->origins.find(table);
      for (const auto& [k, v] : *t) {
        const std::string key(k.str());
        if (key == "type" || origins == doc.impl->origins.end()) continue;
        const auto origin = origins->second.find(key);
        if (origin == origins->second.end() || !origin->second.known || origin->second.type == cc->type) continue;
        bool declared = false;
        for (std::uint32_t i = 0; i < info.param_count; ++i) declared = declared || key == info.params[i].key;
        if (declared) continue;
        skip.push_back(key);
        dropped += (dropped.empty() ? "" : ", ") + key + " (" + location(v) + ")";
        const std::string old_type = "\"" + origin->second.type + "\"";
        if (replaced.find(old_type) == std::string::npos) replaced += (replaced.empty() ? "" : ", ") + old_type;
      }
      if (!dropped.empty())
        ex.notes.push_back("[" + table + "] type = \"" + cc->type + "\" (" +
                           (type_node ? location(*type_node) : std::string("default")) + ") replaces " + replaced +
                           ": dropped " + dropped + ", which " + cc->type + " does not declare");
    }
    const bool adapter = (info.flags & kWrapsDescriptor) != 0;
    if (adapter) skip.push_back("wraps");
    cc->config = validate_table(t, table, info.params, info.param_count,
                                "component '" + cc->type + "' (" + cc->entry->plugin->path + ")", skip);
    toml::table out;
    out.insert_or_assign("type", cc->type);
    put_config(out, cc->config, info.params, info.param_count);
    // A descriptor adapter's [descriptor.wraps]: the descriptor it wraps, a component table of its
    // own (the environment's default descriptor, filled in by build_components, when absent).
    if (adapter) {
      ex.wrapped.table = table + ".wraps";
      const toml::node* wraps = t ? t->get("wraps") : nullptr;
      if (wraps && !wraps->is_table())
        fail_at(*wraps, table + ".wraps must be a table ([" + table + ".wraps] with a type)");
      const toml::table* wt = wraps ? wraps->as_table() : nullptr;
      const toml::node* wtype = wt ? wt->get("type") : nullptr;
      if (wt && (!wtype || !wtype->is_string()))
        fail_at(*wraps, "[" + ex.wrapped.table + "] needs type = \"<descriptor name>\" (the descriptor that " +
                            cc->type + " wraps), or leave it out for the environment's own");
      if (wtype) {
        ex.wrapped.type = wtype->as_string()->get();
        try {
          ex.wrapped.entry = &registry.require(ex.wrapped.type, Kind::kDescriptor);
        } catch (const InputError& err) {
          throw InputError(location(*wtype) + ": " + ex.wrapped.table + ".type: " + err.what());
        }
        const ComponentInfo& winfo = *ex.wrapped.entry->info;
        if (winfo.flags & kWrapsDescriptor)
          fail_at(*wtype, "[" + ex.wrapped.table + "] type = \"" + ex.wrapped.type +
                              "\" wraps a descriptor itself; adapters do not nest");
        ex.wrapped.config =
            validate_table(wt, ex.wrapped.table, winfo.params, winfo.param_count,
                           "component '" + ex.wrapped.type + "' (" + ex.wrapped.entry->plugin->path + ")", {"type"});
        toml::table wout;
        wout.insert_or_assign("type", ex.wrapped.type);
        put_config(wout, ex.wrapped.config, winfo.params, winfo.param_count);
        out.insert_or_assign("wraps", std::move(wout));
      }
    }
    resolved.insert_or_assign(table, std::move(out));
  }
  // The user's plugin directories this run searches, recorded so that --resume, --replay and
  // --latents find the same plugins without the command line or environment that named them.
  const std::vector<std::string> search_path = registry.user_dirs();
  if (!ex.plugin_paths.empty() || !search_path.empty()) {
    toml::table t;
    auto put = [&t](const char* key, const std::vector<std::string>& list) {
      if (list.empty()) return;
      toml::array a;
      for (const auto& x : list) a.push_back(x);
      t.insert_or_assign(key, std::move(a));
    };
    put("path", ex.plugin_paths);
    put("search_path", search_path);
    resolved.insert_or_assign("plugins", std::move(t));
  }
  ex.resolved_toml = toml_text(resolved);
  return ex;
}

void resolve_default_component(Experiment& ex, ComponentConfig& cc, const ComponentEntry& entry) {
  cc.type = entry.info->name;
  cc.entry = &entry;
  cc.config = validate_table(nullptr, cc.table, entry.info->params, entry.info->param_count, cc.type);
  toml::table out;
  out.insert_or_assign("type", cc.type);
  put_config(out, cc.config, entry.info->params, entry.info->param_count);
  // A dotted table name ("descriptor.wraps") nests: [descriptor.wraps] after [descriptor].
  const std::size_t dot = cc.table.find('.');
  toml::table wrapper;
  if (dot == std::string::npos) {
    wrapper.insert_or_assign(cc.table, std::move(out));
  } else {
    toml::table parent;
    parent.insert_or_assign(cc.table.substr(dot + 1), std::move(out));
    wrapper.insert_or_assign(cc.table.substr(0, dot), std::move(parent));
  }
  ex.resolved_toml += "\n" + toml_text(wrapper);
}

std::string describe_params(const ParamSpec* params, std::size_t count) {
  std::ostringstream o;
  if (count == 0) o << "  (no parameters)\n";
  for (std::size_t i = 0; i < count; ++i) {
    const ParamSpec& s = params[i];
    o << "  " << s.key << " (" << to_string(s.type) << ", default " << s.default_value;
    if (s.type == ParamType::kInteger || s.type == ParamType::kFloat || s.type == ParamType::kIntegerList ||
        s.type == ParamType::kFloatList) {
      if (!std::isinf(s.min) || !std::isinf(s.max)) o << ", range " << range_text(s);
    }
    if (s.choices) o << ", one of " << s.choices;
    o << ")\n      " << (s.help ? s.help : "") << "\n";
  }
  return o.str();
}

std::string describe_table(const std::string& name, const Registry& registry) {
  if (name == "plugins")
    return "[plugins] (core): where plugin libraries are searched, before qdrun's own <prefix>/lib/qd/plugins\n"
           "  path (list of strings, default [])\n"
           "      plugin directories, searched after --plugin-path and QD_PLUGIN_PATH; relative to the experiment "
           "file\n"
           "  search_path (list of strings, written by qdrun)\n"
           "      the user directories a run searched (--plugin-path, QD_PLUGIN_PATH, path), absolute; a run's "
           "config.toml records it, and --resume, --replay and --latents search it after the current ones\n";
  for (const auto& ct : kComponentTables) {
    if (name != ct.name) continue;
    std::string purpose = "the " + std::string(to_string(ct.kind)) + " component";
    if (name == "mutator") purpose = "the variation operator of loops n >= 1 (a mutator component)";
    if (name == "initial") purpose = "the loop-0 sampler (a mutator component that needs no parents)";
    if (name == "representation") purpose = "the latent model of the policy parameters (a representation component)";
    if (name == "descriptor")
      purpose =
          "the behaviour descriptor (a descriptor component); a descriptor adapter such as \"cvt\" wraps the "
          "descriptor of its sub-table [descriptor.wraps] (type and keys; default: the environment's own)";
    if (name == "environment") purpose = "the task (an environment component)";
    std::string dflt = ct.default_type == nullptr ? "required"
                       : *ct.default_type         ? "default \"" + std::string(ct.default_type) + "\""
                                                  : "default: the environment's own descriptor";
    std::string known;
    for (const auto& c : registry.components())
      if (c.info->kind == ct.kind) known += (known.empty() ? "" : ", ") + std::string(c.info->name);
    return "[" + name + "] (core): " + purpose + "\n  type (string, " + dflt +
           ")\n      the component's name; the table's other keys are that component's parameters (qdrun "
           "--describe <type>). An include or --set that changes type drops the keys the new component does not "
           "declare\n      available: " +
           (known.empty() ? std::string("(none found)") : known) + "\n";
  }
  return "";
}

namespace {
// The newest session's provenance (the plugins the run last loaded); empty when unreadable.
toml::table newest_provenance(const fs::path& run_dir) {
  const fs::path newest = session_provenance(run_dir, std::numeric_limits<int>::max());
  try {
    return toml::parse(read_run_file(newest, kMaxTomlBytes), newest.string());
  } catch (const std::exception&) {
    return {};
  }
}
}  // namespace

std::string changed_plugins(const fs::path& run_dir, const Experiment& ex, std::vector<std::string>* notes) {
  const toml::table prov = newest_provenance(run_dir);
  const toml::array* plugins = prov["plugins"].as_array();
  if (!plugins) return "";
  std::string out;
  std::error_code ec;
  for (const auto& node : *plugins) {
    const toml::table* p = node.as_table();
    if (!p) continue;
    const std::string table = (*p)["table"].value_or(std::string());
    const std::string plugin = (*p)["plugin"].value_or(std::string());
    const std::string version = (*p)["version"].value_or(std::string());
    const std::string path = (*p)["path"].value_or(std::string());
    const ComponentConfig* cc = nullptr;
    for (const ComponentConfig* c : {&ex.environment, &ex.descriptor, &ex.representation, &ex.mutator, &ex.initial})
      if (c->table == table) cc = c;
    if (!cc || !cc->entry || plugin.empty()) continue;
    const PluginInfo& now = *cc->entry->plugin->info;
    const std::string recorded =
        "[" + table + "] '" + cc->type + "' came from " + path + " (plugin " + plugin + " " + version + ")";
    if (plugin != now.plugin_name) {
      out += (out.empty() ? "" : "; ") + recorded + (fs::exists(path, ec) ? "" : ", which no longer exists") +
             ", but would now come from " + cc->entry->plugin->path + " (plugin " + now.plugin_name + " " +
             now.plugin_version + ")";
    } else if (notes && version != now.plugin_version) {
      notes->push_back(recorded + "; it is now version " + now.plugin_version + " (" + cc->entry->plugin->path +
                       "), which may compute otherwise");
    }
  }
  return out;
}

std::string missing_plugin_hint(const fs::path& run_dir, const Registry& registry) {
  std::error_code ec;
  const toml::table prov = newest_provenance(run_dir);
  const toml::array* plugins = prov["plugins"].as_array();
  if (!plugins) return "";
  std::string out;
  for (const auto& node : *plugins) {
    const toml::table* p = node.as_table();
    if (!p) continue;
    const std::string component = (*p)["component"].value_or(std::string());
    const std::string path = (*p)["path"].value_or(std::string());
    if (component.empty() || path.empty()) continue;
    if (registry.find(component)) continue;  // found (perhaps elsewhere): not why the run cannot start
    std::string what = "this run loaded [" + (*p)["table"].value_or(std::string()) + "] '" + component + "' from " +
                       path + " (plugin " + (*p)["plugin"].value_or(std::string()) + " " +
                       (*p)["version"].value_or(std::string()) + ")";
    const auto rejected = std::find_if(registry.rejected().begin(), registry.rejected().end(),
                                       [&](const Rejection& r) { return fs::equivalent(r.path, path, ec); });
    if (!fs::exists(path, ec)) {
      what += ", which no longer exists";
    } else if (rejected != registry.rejected().end()) {
      what += ", which is rejected now";
    } else {
      what += "; add its directory with --plugin-path";
    }
    out += (out.empty() ? "" : "; ") + what;
  }
  return out;
}

}  // namespace qd::runtime

namespace qd::runtime {
namespace {
void flatten(const toml::table& t, const std::string& prefix, std::map<std::string, std::string>& out) {
  for (const auto& [key, node] : t) {
    const std::string path = prefix.empty() ? std::string(key.str()) : prefix + "." + std::string(key.str());
    if (const toml::table* sub = node.as_table()) {
      flatten(*sub, path, out);
    } else {
      out[path] = value_text(node);
    }
  }
}
}  // namespace

std::vector<ConfigDifference> config_differences(const std::string& before, const std::string& after) {
  std::map<std::string, std::string> a, b;
  try {
    flatten(toml::parse(before, std::string_view("checkpoint")), "", a);
    flatten(toml::parse(after, std::string_view("config.toml")), "", b);
  } catch (const toml::parse_error& e) {
    throw InputError(location(e.source()) + ": malformed TOML: " + std::string(e.description()));
  }
  std::vector<ConfigDifference> out;
  for (const auto& [key, value] : a) {
    const auto it = b.find(key);
    if (it == b.end())
      out.push_back({key, value, "(absent)"});
    else if (it->second != value)
      out.push_back({key, value, it->second});
  }
  for (const auto& [key, value] : b)
    if (a.count(key) == 0) out.push_back({key, "(absent)", value});
  return out;
}

bool may_change_on_resume(const std::string& key) {
  for (const char* prefix : {"evaluation.", "output.", "plugins."})
    if (key.rfind(prefix, 0) == 0) return true;
  return key == "experiment.loops";
}

}  // namespace qd::runtime
