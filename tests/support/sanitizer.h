// Tests that run only in the Release stage of scripts/test, not in the sanitizer stage, and sweeps
// that CI runs in part.
//
// The sanitizer stage (clang, ASan + UBSan) runs every test again, 10-30x slower. A few end-to-end
// tests (a simulated capture tracked over 7 cameras, the thesis's noise study, corpus sweeps) take
// minutes each there and would push CI past its time limit, while the code they exercise is run
// under the sanitizers by the smaller tests and fuzz targets of the same part. Those tests call
// HC_SKIP_WHEN_SANITIZED with the reason; the Release stage runs them in full.
#pragma once

#include <gtest/gtest.h>

#include <cstdlib>
#include <cstring>

#if defined(__SANITIZE_ADDRESS__)
#define HC_TEST_SANITIZED 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define HC_TEST_SANITIZED 1
#endif
#endif

namespace hc::testing {
#ifdef HC_TEST_SANITIZED
inline constexpr bool kSanitized = true;
#else
inline constexpr bool kSanitized = false;
#endif

// Sweeps that take many minutes (every orientation of a generated suite, the whole mesh corpus)
// run a representative part by default, so that CI stays within its time; HARDCOPY_LONG_TESTS=1
// runs them whole (what a change to the algorithms they check should be verified with).
inline bool long_tests() {
  const char* v = std::getenv("HARDCOPY_LONG_TESTS");
  return v != nullptr && std::strcmp(v, "") != 0 && std::strcmp(v, "0") != 0;
}
}  // namespace hc::testing

#define HC_SKIP_WHEN_SANITIZED(why)                                                   \
  do {                                                                               \
    if (::hc::testing::kSanitized)                                                   \
      GTEST_SKIP() << "run in the Release stage only (sanitizers make it " << (why) \
                   << "; see tests/support/sanitizer.h)";                            \
  } while (false)

// Tests that take minutes even in Release (a whole generated suite, nine base-material fits): run
// with HARDCOPY_LONG_TESTS=1 only; the default run covers the same code with smaller cases.
#define HC_LONG_TEST_ONLY(why)                                                              \
  do {                                                                                     \
    if (!::hc::testing::long_tests())                                                      \
      GTEST_SKIP() << "run with HARDCOPY_LONG_TESTS=1 only (" << (why)                     \
                   << "; see tests/support/sanitizer.h)";                                  \
  } while (false)
