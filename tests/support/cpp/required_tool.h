// Tests that need a tool outside the build (promtool, a Python package, assimp's test
// models): on a developer's machine a missing tool skips the test, but under CI (the
// variable CI set, as .ci/run's hosts and most CI services set it) every tool is installed
// on purpose, and a skip there would pass a check that never ran.
#pragma once

#include <gtest/gtest.h>

#include <cstdlib>

namespace tcfarm::test {

inline bool RunningUnderCi() {
  const char* ci = std::getenv("CI");
  return ci != nullptr && *ci != '\0';
}

}  // namespace tcfarm::test

// TCFARM_REQUIRE_TOOL(available, message): when `available` is false, skips the test (fails
// it under CI) with `message`, which may chain values with <<. Only in a TEST body: both
// outcomes return from the enclosing function.
#define TCFARM_REQUIRE_TOOL(available, message)                                     \
  do {                                                                              \
    if (!(available)) {                                                             \
      if (::tcfarm::test::RunningUnderCi()) {                                       \
        GTEST_FAIL() << message << " (CI is set, so a missing tool is a failure)"; \
      }                                                                             \
      GTEST_SKIP() << message;                                                      \
    }                                                                               \
  } while (false)
