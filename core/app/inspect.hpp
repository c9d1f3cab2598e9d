// Looking into a finished run without changing it: qdrun --replay (one elite, or --all of them)
// and qdrun --latents. Each returns the exit code (0) or throws as qdrun's errors do.
#pragma once

#include "cli.hpp"

namespace qd::app {

// qdrun --replay RUN_DIR --cell N [--svg FILE], or --replay RUN_DIR --all [--traces FILE.csv].
int replay(const Cli& cli);
// qdrun --latents RUN_DIR [--output FILE.csv].
int latents(const Cli& cli);

}  // namespace qd::app
