// Configuration, stage 2 of 3: the schema. The core's own tables ([experiment], [policy],
// [output], [evaluation]; [cost] belongs to the planning wing, cost_model.hpp), their validation,
// and the typed settings they resolve to: a setting that selects a behaviour is an enum from here
// on, never a string compared later. Component tables are resolved in experiment.hpp.
#pragma once

#include "runtime/backend.hpp"

#include <qd/config.hpp>
#include <qd/plugin.hpp>

#include <cstddef>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

namespace qd::runtime {

// [experiment] insertion: what happens when an offspring lands in an occupied cell.
enum class InsertionRule {
  kCoinFlip,  // "coin-flip": replace with probability replace_probability (the paper's reference)
  kFitness,   // "fitness": replace if strictly fitter
};
// [experiment] dataset_order: the order of loop 0's dataset entries.
enum class DatasetOrder {
  kReference,  // "reference": descending cell index (the reference's np.unique order)
  kInsertion,  // "insertion": first found first
};
// The value as written in an experiment file ("coin-flip", "processes", ...).
const char* to_string(InsertionRule v);
const char* to_string(DatasetOrder v);

// The core's own settings, resolved.
struct ExperimentSettings {
  std::string name;
  std::uint64_t seed = 0;
  int loops = 0;            // loop 0 (initial sampling) included
  int iterations = 0;       // MAP-Elites iterations per loop n >= 1
  int batch = 0;            // offspring per iteration
  int initial_samples = 0;  // loop-0 samples
  InsertionRule insertion = InsertionRule::kCoinFlip;
  double replace_probability = 0.5;
  double fitness_lower_bound = std::numeric_limits<double>::quiet_NaN();  // NaN: the environment's
  DatasetOrder dataset_order = DatasetOrder::kReference;
  std::vector<int> hidden;
  std::string output_dir;
  int snapshot_every = 0;
  bool snapshot_parameters = true;
  int workers = 0;  // 0 = all cores
  Backend backend = Backend::kAuto;
  double timeout_seconds = 0;
};

// Parameters of a core table, for --describe and validation.
struct CoreTable {
  const char* name;
  const ParamSpec* params;
  std::size_t count;
};
// [experiment], [policy], [output], [evaluation] and [cost], in that order.
std::vector<CoreTable> core_tables();

// The component tables of an experiment file, the kind of component each names and its default
// type (nullptr: required; "": the environment's default descriptor).
struct ComponentTable {
  const char* name;
  Kind kind;
  const char* default_type;
};
inline constexpr ComponentTable kComponentTables[] = {
    {"environment", Kind::kEnvironment, nullptr},
    {"descriptor", Kind::kDescriptor, ""},
    {"representation", Kind::kRepresentation, "none"},
    {"mutator", Kind::kMutator, nullptr},
    {"initial", Kind::kMutator, "uniform"},
};

// "[0, 1]"; an infinite bound is excluded: "[0, inf)", "(-inf, inf)".
std::string range_text(const ParamSpec& s);

}  // namespace qd::runtime
