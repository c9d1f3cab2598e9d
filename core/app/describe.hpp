// qdrun --list and --describe: what the core tables and the discovered components accept.
#pragma once

#include "runtime/registry.hpp"

#include <cstddef>
#include <string>

namespace qd::app {

// A component's (or core table's) parameters, one entry each: key, type, default, range, choices, help.
std::string describe_params(const ParamSpec* params, std::size_t count);

// `qdrun --describe` text of the tables that are no plain parameter list: [plugins] and the
// component tables ([environment], [descriptor], [representation], [mutator], [initial]). Empty
// for any other name.
std::string describe_table(const std::string& name, const runtime::Registry& registry);

// qdrun --list: every component with its plugin library, the rejected libraries, the search path.
void list_components(const runtime::Registry& registry);

// qdrun --describe NAME: a core table, a component table or a component. Throws qd::InputError
// naming what is known for anything else.
void describe(const runtime::Registry& registry, const std::string& name);

}  // namespace qd::app
