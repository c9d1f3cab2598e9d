// Box2D 2.4.1 times every world step for its b2Profile statistics: b2World::Step, b2Island::Solve and
// b2TimeOfImpact construct b2Timers and read them, about a dozen clock reads per step (more with
// time-of-impact events). No simulation result depends on them; the timings only fill b2Profile,
// which qdrun never reads. On a 2-vCPU VM the clock reads took 36 % of a Striker episode.
//
// Linked into every Box2D environment plugin (and its tests and benchmarks), these definitions
// take the place of libbox2d's own: the library calls its timer through the PLT, and the dynamic
// linker resolves those calls to the first definition in the library's lookup scope, which is the
// plugin that loaded it. As a consequence b2World::GetProfile() reads zeros in qdrun's process.
// Under another Box2D (a static build, or one that calls its timer directly) these are simply
// unused, and episodes are as before: results never depend on them.
#pragma GCC visibility push(default)
#include <box2d/b2_timer.h>
#pragma GCC visibility pop

b2Timer::b2Timer() = default;

void b2Timer::Reset() {}

float b2Timer::GetMilliseconds() const {
  return 0.0f;
}
