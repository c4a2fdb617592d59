// SKIP_UNDER_ASAN(): the 3-D abstraction tests run for seconds to tens of seconds in Release and
// about ten times longer under AddressSanitizer; the Release stage of CI runs them.
#pragma once

#include <gtest/gtest.h>

#if defined(__has_feature)
#if __has_feature(address_sanitizer)
#define HC_UNDER_ASAN 1
#endif
#endif
#if defined(__SANITIZE_ADDRESS__)
#define HC_UNDER_ASAN 1
#endif

#ifdef HC_UNDER_ASAN
#define SKIP_UNDER_ASAN() GTEST_SKIP() << "slow under ASan; the Release stage runs it"
#else
#define SKIP_UNDER_ASAN() (void)0
#endif
