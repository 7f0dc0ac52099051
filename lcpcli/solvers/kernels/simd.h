/* Vector loops of the kernels, compiled twice where the toolchain allows (GCC on x86-64 glibc:
 * AVX2 and the baseline SSE2) and picked at load time by the CPU (ifunc), so that a portable
 * wheel runs 4-wide on CPUs that have AVX2.  The AVX2 clone does not enable FMA, so both clones
 * round identically (one multiply, one add per element, in the same order): results do not
 * depend on the CPU.  Elsewhere (clang, MSVC, musl, ARM) one baseline version is compiled. */
#ifndef LCPCLI_SIMD_H
#define LCPCLI_SIMD_H

#include <stddef.h>
#include <stdlib.h> /* defines __GLIBC__ on glibc */
#if defined(__linux__)
#include <sys/mman.h>
#endif

#if defined(__GNUC__) && !defined(__clang__) && defined(__x86_64__) && defined(__GLIBC__) \
    && !defined(LCPCLI_NO_CLONES)
#define LCPCLI_CLONES __attribute__((target_clones("avx2", "default")))
#else
#define LCPCLI_CLONES
#endif

/* y[i] += a * x[i] */
LCPCLI_CLONES static void lcpcli_axpy(double *restrict y, const double *restrict x, double a,
                                      ptrdiff_t n)
{
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC unroll 4
#endif
    for (ptrdiff_t i = 0; i < n; i++)
        y[i] += a * x[i];
}

/* y[i] += (a * x[i]) * b   (a rank-one update term with its scale applied last) */
LCPCLI_CLONES static void lcpcli_axpy_scaled(double *restrict y, const double *restrict x,
                                             double a, double b, ptrdiff_t n)
{
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC unroll 4
#endif
    for (ptrdiff_t i = 0; i < n; i++)
        y[i] += (a * x[i]) * b;
}

/* sum_i x[i] y[i] with four partial sums (lane k accumulates i = k mod 4; then
 * (s0 + s1) + (s2 + s3) and the tail into s0): the same order in both clones */
LCPCLI_CLONES static double lcpcli_dot4(const double *restrict x, const double *restrict y,
                                        ptrdiff_t n)
{
    double s[4] = {0.0, 0.0, 0.0, 0.0};
    ptrdiff_t i = 0;
    for (; i + 4 <= n; i += 4)
        for (int k = 0; k < 4; k++)
            s[k] += x[i + k] * y[i + k];
    for (; i < n; i++)
        s[0] += x[i] * y[i];
    return (s[0] + s[1]) + (s[2] + s[3]);
}

/* malloc for work arrays; from 4 MiB up (Linux) 2 MiB-aligned and advised to use transparent
 * huge pages, as numpy does for its large arrays: a tableau swept once per pivot then costs a
 * few TLB entries instead of thousands (15-20% of the pivot time at n = 1000).  Free with
 * free(). */
static void *lcpcli_alloc(size_t size)
{
#if defined(__linux__) && defined(MADV_HUGEPAGE)
    if (size >= ((size_t)4 << 20)) {
        void *p = NULL;
        if (posix_memalign(&p, (size_t)2 << 20, size) != 0)
            return NULL;
        madvise(p, size, MADV_HUGEPAGE);
        return p;
    }
#endif
    return malloc(size);
}

#endif
