// The factory of evaluator.hpp: the only file that knows every backend.
#include "runtime/evaluator.hpp"

#include "runtime/mpi_evaluator.hpp"
#include "runtime/mpi_session.hpp"
#include "runtime/process_evaluator.hpp"
#include "runtime/thread_evaluator.hpp"

namespace qd::runtime {

Backend resolve_backend(Backend requested, int persistent_worlds) {
  if (requested != Backend::kAuto) return requested;
  if (persistent_worlds > 0) return Backend::kThreads;
  return mpi_active() ? Backend::kMpi : Backend::kProcesses;
}

std::unique_ptr<Evaluator> make_evaluator(const EvaluatorSpec& spec, const Environment& env, const Descriptor& desc,
                                          const PolicyShape& shape) {
  const int worlds = spec.fresh_worlds ? 0 : env.info().persistent_worlds;
  const Backend backend = resolve_backend(spec.backend, worlds);
  if (worlds > 0 && backend != Backend::kThreads)
    throw InputError(std::string("[evaluation] backend = \"") + to_string(backend) + "\": " + spec.labels.environment +
                     " keeps " + std::to_string(worlds) +
                     " persistent worlds between episodes (one state per world, in episode order), which only "
                     "the \"threads\" backend runs; use backend = \"threads\" or \"auto\"");
  if (backend == Backend::kMpi) {
    if (!mpi_built())
      throw InputError(
          "[evaluation] backend = \"mpi\": this qdrun was built without MPI (configure with -DQD_WITH_MPI=ON)");
    if (!mpi_active())
      throw InputError("[evaluation] backend = \"mpi\" needs qdrun to be started by mpirun (mpirun -np N qdrun ...)");
    return make_mpi_evaluator(spec, env, desc, shape);
  }
  if (mpi_active() && mpi_size() > 1)
    throw InputError(std::string("[evaluation] backend = \"") + to_string(backend) + "\" under mpirun with " +
                     std::to_string(mpi_size()) +
                     " ranks: every rank would run the whole experiment; use backend = \"mpi\" (or \"auto\")");
  if (backend == Backend::kProcesses)
    return std::make_unique<ProcessEvaluator>(env, desc, shape, spec.workers, spec.capacity, spec.timeout_seconds,
                                              spec.labels);
  return std::make_unique<ThreadEvaluator>(env, desc, shape, spec.workers, spec.labels, worlds);
}

#ifndef QD_WITH_MPI
std::unique_ptr<Evaluator> make_mpi_evaluator(const EvaluatorSpec&, const Environment&, const Descriptor&,
                                              const PolicyShape&) {
  return nullptr;
}
#endif

}  // namespace qd::runtime
