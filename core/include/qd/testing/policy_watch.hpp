// Which threads load each qd::Policy object, for check_environment (conformance.hpp): a Policy
// shared between rollout() calls (a `mutable Policy` member) gives wrong traces only when two
// calls overlap, which timing decides; watching Policy::load finds it whatever the timing.
// Implemented in libqd_core; Policy::load costs one relaxed atomic load more while nobody watches.
#pragma once

#include <qd/export.hpp>

namespace qd::testing {

// Starts (forgetting what an earlier watch saw) or stops watching.
QD_EXPORT void watch_policy_loads(bool on) noexcept;
// Whether, during the current or last watch, one Policy object was loaded on two threads.
QD_EXPORT bool policy_loaded_on_two_threads() noexcept;

}  // namespace qd::testing
