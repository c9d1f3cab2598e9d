// The MPI backend (mpi_evaluator.cpp, built with QD_WITH_MPI; the session is mpi_session.hpp).
#pragma once

#include "runtime/evaluator.hpp"

#include <memory>

namespace qd::runtime {

// Only with QD_WITH_MPI (make_evaluator checks mpi_built() first; without MPI this is null).
std::unique_ptr<Evaluator> make_mpi_evaluator(const EvaluatorSpec& spec, const Environment& env, const Descriptor& desc,
                                              const PolicyShape& shape);

}  // namespace qd::runtime
