// Debug-only invariant checks: a broken invariant in the core is a bug, never
// an input error, so release builds compile the check away.
#pragma once

#ifdef NDEBUG
#define CAMSIM_DCHECK(cond) ((void)0)
#else
#define CAMSIM_DCHECK(cond)          \
  do {                               \
    if (!(cond)) __builtin_trap();   \
  } while (0)
#endif
