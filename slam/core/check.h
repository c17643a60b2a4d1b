// CERTISLAM_CHECK: an invariant check for programmer errors that stays on in Release builds.
#pragma once

#include <cstdio>
#include <cstdlib>

/// Aborts with file, line and the failed condition when `cond` is false (STYLE.md, errors rule 4).
/// Never use it on input: input errors are values or exceptions that name what was wrong.
#define CERTISLAM_CHECK(cond)                                                             \
    do {                                                                                  \
        if (!(cond)) {                                                                    \
            std::fprintf(stderr, "%s:%d: check failed: %s\n", __FILE__, __LINE__, #cond); \
            std::abort();                                                                 \
        }                                                                                 \
    } while (false)
