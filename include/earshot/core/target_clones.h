#pragma once
/** @file EARSHOT_CLONES marks a hot loop's function for an AVX2+FMA
 *  (x86-64-v3) clone, chosen at load time (ifunc) where the CPU has it, the
 *  baseline version elsewhere. GCC on x86-64 only; not under the sanitizers
 *  (their runtimes do not resolve the clones) nor clang (the fuzz build). */
#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__) && !defined(__SANITIZE_THREAD__) && \
    !defined(__SANITIZE_ADDRESS__)
#define EARSHOT_CLONES __attribute__((target_clones("arch=x86-64-v3", "default")))
#else
#define EARSHOT_CLONES
#endif
