// [evaluation] backend: which evaluator runs the batches. Typed once, when the experiment is
// validated (config_schema.cpp); the evaluator factory (evaluator_factory.cpp) resolves kAuto.
#pragma once

namespace qd::runtime {

enum class Backend { kAuto, kThreads, kProcesses, kMpi };
// The value as written in an experiment file ("auto", "threads", "processes", "mpi").
const char* to_string(Backend v);

}  // namespace qd::runtime
