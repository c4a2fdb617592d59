// Tests that need more than ~20 s in Release skip under AddressSanitizer (~10x slower); the
// Release stage of scripts/test runs them.
#pragma once

#include <gtest/gtest.h>

#if defined(__SANITIZE_ADDRESS__)
#define HC_COMPOSITE_ASAN 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define HC_COMPOSITE_ASAN 1
#endif
#endif

#if HC_COMPOSITE_ASAN
#define HC_SKIP_UNDER_SANITIZER(what) \
  GTEST_SKIP() << what << " is too slow under AddressSanitizer; the Release stage runs it"
#else
#define HC_SKIP_UNDER_SANITIZER(what) (void)0
#endif
