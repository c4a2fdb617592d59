#!/usr/bin/env bash
# check_freestanding.sh LIB.a...: fails if the firmware core or protocol archives reference the
# heap, exceptions, RTTI, threads/OS calls or out-of-line std:: functions — the "no heap, no OS, no
# exceptions" promise of firmware_host/core, checked on the built objects rather than by review.
# Allowed: memcpy/memset/memmove (the compiler emits them), sanitizer/coverage hooks, our own code.
set -euo pipefail
status=0
for lib in "$@"; do
  undefined=$(nm -u "$lib" | awk 'NF >= 2 {print $NF}' | sort -u)
  bad=$(grep -E '^(_Znw|_Zna|_Zdl|_Zda|malloc$|calloc$|realloc$|free$|__cxa_throw|__cxa_allocate_exception|__cxa_begin_catch|__gxx_personality|_Unwind_|_ZTI|_ZTS|_ZSt|_ZNSt|_ZNKSt|pthread_|abort$|exit$|printf|puts$|fopen|fwrite|write$|read$|clock_gettime|__cxa_guard)' <<<"$undefined" || true)
  if [ -n "$bad" ]; then
    echo "$lib references forbidden symbols:"
    echo "$bad" | c++filt | sed 's/^/  /'
    status=1
  else
    echo "$lib: freestanding ($(wc -w <<<"$undefined") undefined symbols, all allowed)"
  fi
done
exit $status
