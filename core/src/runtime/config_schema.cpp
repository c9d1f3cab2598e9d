// Configuration, stage 2: the schema (config_schema.hpp). The core tables, checking a table
// against declared parameters (the core's and every component's), and the typed core settings.
#include "runtime/config_toml.hpp"

#include "runtime/cost_model.hpp"
#include "runtime/number_text.hpp"
#include "runtime/run_files.hpp"

#include <qd/errors.hpp>

#include <algorithm>
#include <cmath>
#include <iterator>
#include <stdexcept>

namespace qd::runtime {
namespace fs = std::filesystem;

namespace {

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

// The values of the settings that select a behaviour, in their enum's order (the schema above
// lists the same words as choices; config_test checks that they agree).
constexpr const char* kInsertionNames[] = {"coin-flip", "fitness"};
constexpr const char* kDatasetOrderNames[] = {"reference", "insertion"};
constexpr const char* kBackendNames[] = {"auto", "threads", "processes", "mpi"};

// A validated choice as its enum: typed once, here.
template <class E, std::size_t N>
E choice(const Config& cfg, const char* key, const char* const (&names)[N]) {
  const std::string v = cfg.get_string(key);
  for (std::size_t i = 0; i < N; ++i)
    if (v == names[i]) return static_cast<E>(i);
  throw std::logic_error(std::string("validated setting ") + key + " = \"" + v + "\" has no enum value");
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

}  // namespace

const char* to_string(InsertionRule v) {
  return kInsertionNames[static_cast<int>(v)];
}
const char* to_string(DatasetOrder v) {
  return kDatasetOrderNames[static_cast<int>(v)];
}
const char* to_string(Backend v) {
  return kBackendNames[static_cast<int>(v)];
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

// "[0, 1]"; an infinite bound is excluded: "[0, inf)", "(-inf, inf)".
std::string range_text(const ParamSpec& s) {
  const bool integer = s.type == ParamType::kInteger || s.type == ParamType::kIntegerList;
  return (std::isinf(s.min) ? "(" : "[") + number_text(s.min, integer) + ", " + number_text(s.max, integer) +
         (std::isinf(s.max) ? ")" : "]");
}

// Validates `tbl` (may be null = all defaults) against `specs`; `skip` keys are handled by the caller.
Config validate_table(const toml::table* tbl, const std::string& table, const ParamSpec* specs, std::size_t count,
                      const std::string& owner, const std::vector<std::string>& skip) {
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

std::vector<CoreTable> core_tables() {
  return {{"experiment", kExperimentParams, std::size(kExperimentParams)},
          {"policy", kPolicyParams, std::size(kPolicyParams)},
          {"output", kOutputParams, std::size(kOutputParams)},
          {"evaluation", kEvaluationParams, std::size(kEvaluationParams)},
          cost_table()};
}

void resolve_core_tables(const toml::table& root, const fs::path& file, ExperimentSettings& s, toml::table& resolved) {
  const Config e = validate_table(sub_table(root, "experiment"), "experiment", kExperimentParams,
                                  std::size(kExperimentParams), "the core");
  const Config p =
      validate_table(sub_table(root, "policy"), "policy", kPolicyParams, std::size(kPolicyParams), "the core");
  const Config o =
      validate_table(sub_table(root, "output"), "output", kOutputParams, std::size(kOutputParams), "the core");
  const Config w = validate_table(sub_table(root, "evaluation"), "evaluation", kEvaluationParams,
                                  std::size(kEvaluationParams), "the core");
  s.name = e.get_string("name");
  if (s.name.empty()) s.name = file.empty() ? "experiment" : file.stem().string();
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
  s.insertion = choice<InsertionRule>(e, "insertion", kInsertionNames);
  s.replace_probability = e.get_float("replace_probability");
  s.fitness_lower_bound = e.get_float("fitness_lower_bound");
  s.dataset_order = choice<DatasetOrder>(e, "dataset_order", kDatasetOrderNames);
  for (auto h : p.get_int_list("hidden")) s.hidden.push_back(static_cast<int>(h));
  s.output_dir = o.get_string("dir");
  if (has_control_character(s.output_dir))
    throw InputError(o.where("dir") + ": output.dir contains a control character (" + printable(s.output_dir) + ")");
  if (s.output_dir.empty()) throw InputError(o.where("dir") + ": output.dir is empty");
  s.snapshot_every = static_cast<int>(o.get_int("snapshot_every"));
  s.snapshot_parameters = o.get_bool("snapshot_parameters");
  s.workers = static_cast<int>(w.get_int("workers"));
  s.backend = choice<Backend>(w, "backend", kBackendNames);
  s.timeout_seconds = w.get_float("timeout_seconds");
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
}

}  // namespace qd::runtime
