// The plugin call a thread is in, as qdrun's crash and exit() guards name it (app/run_guard.cpp).
#include "runtime/plugin_call.hpp"

#include <gtest/gtest.h>

#include <string>
#include <thread>

using qd::runtime::current_plugin_call;
using qd::runtime::PluginCall;
using qd::runtime::PluginCallScope;

namespace {
std::string who_of(const PluginCall& c) {
  return c.who ? c.who : "";
}
std::string call_of(const PluginCall& c) {
  return c.call ? c.call : "";
}
}  // namespace

// Runs on a fresh thread each time, so the run-thread fallback starts empty.
TEST(PluginCall, NestedScopesNameTheInnermostAndRestoreTheOuter) {
  std::thread([] {
    EXPECT_EQ(current_plugin_call().who, nullptr);
    const std::string mutator = "mutator 'poms' (/lib/qd_poms.so)", repr = "representation 'ae' (/lib/qd_ae.so)";
    {
      const PluginCallScope outer(mutator, "mutate()");
      EXPECT_EQ(who_of(current_plugin_call()), mutator);
      {
        const PluginCallScope inner(repr, "decode()");  // the mutator decodes through the representation
        EXPECT_EQ(who_of(current_plugin_call()), repr);
        EXPECT_EQ(call_of(current_plugin_call()), "decode()");
        EXPECT_TRUE(current_plugin_call().own);
      }
      EXPECT_EQ(who_of(current_plugin_call()), mutator);
      EXPECT_EQ(call_of(current_plugin_call()), "mutate()");
    }
    EXPECT_EQ(current_plugin_call().who, nullptr);
  }).join();
}

// A thread without a call of its own (one that plugin code started, e.g. for OpenMP training) sees
// the run thread's call, marked as not its own; other threads' calls never leak into it.
TEST(PluginCall, OtherThreadsSeeOnlyTheRunThreadsCall) {
  const std::string fit = "representation 'ae' (/lib/qd_ae.so)", rollout = "environment 'arm' (/lib/qd_arm.so)";
  std::thread([&] {
    const PluginCallScope not_run_thread(rollout, "rollout()");
    std::thread([] { EXPECT_EQ(current_plugin_call().who, nullptr); }).join();
  }).join();
  std::thread([&] {
    qd::runtime::mark_run_thread();
    const PluginCallScope scope(fit, "fit()");
    std::thread([&] {
      const PluginCall c = current_plugin_call();
      EXPECT_EQ(who_of(c), fit);
      EXPECT_EQ(call_of(c), "fit()");
      EXPECT_FALSE(c.own);
      {
        const PluginCallScope mine(rollout, "rollout()");
        EXPECT_EQ(who_of(current_plugin_call()), rollout);
        EXPECT_TRUE(current_plugin_call().own);
      }
    }).join();
  }).join();
}
