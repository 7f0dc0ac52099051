/* The certificate's two sweeps over a dense row, compiled twice where the toolchain allows (GCC on
 * x86-64 glibc: AVX2 and the baseline SSE2, picked at load time by the CPU), as in
 * lcpcli/solvers/kernels/simd.h.  No FMA in either clone and a fixed summation order, so the
 * certificate's numbers do not depend on the CPU. */
#ifndef LCPCLI_ROWPASS_H
#define LCPCLI_ROWPASS_H

#include <math.h>
#include <stddef.h>
#include <stdlib.h> /* defines __GLIBC__ on glibc */

#if defined(__GNUC__) && !defined(__clang__) && defined(__x86_64__) && defined(__GLIBC__) \
    && !defined(LCPCLI_NO_CLONES)
#define LCPCLI_ROW_CLONES __attribute__((target_clones("avx2", "default")))
#else
#define LCPCLI_ROW_CLONES
#endif

#if defined(__GNUC__)
typedef double lcpcli_v4d __attribute__((vector_size(32)));
typedef unsigned long long lcpcli_v4u __attribute__((vector_size(32)));
#endif

/* dot = sum_j row_j z_j and absdot = sum_j |row_j z_j|, four partial sums each (lane k takes
 * j = k mod 4, the tail goes to lane 0), combined as (s0 + s1) + (s2 + s3); with GCC or clang
 * the four lanes are one vector (the compiler's own vectorisation of this loop interleaved the
 * lanes badly: 3x slower), in the same order, so both give the same bits */
LCPCLI_ROW_CLONES static void lcpcli_row_dot(const double *restrict row,
                                             const double *restrict z, ptrdiff_t n,
                                             double *dot, double *absdot)
{
    double s[4] = {0.0, 0.0, 0.0, 0.0}, a[4] = {0.0, 0.0, 0.0, 0.0};
    ptrdiff_t j = 0;
#if defined(__GNUC__)
    const lcpcli_v4u nosign = {0x7fffffffffffffffULL, 0x7fffffffffffffffULL,
                               0x7fffffffffffffffULL, 0x7fffffffffffffffULL};
    lcpcli_v4d vs = {0.0, 0.0, 0.0, 0.0}, va = {0.0, 0.0, 0.0, 0.0}, x, y, t;
    for (; j + 4 <= n; j += 4) {
        __builtin_memcpy(&x, row + j, sizeof x);
        __builtin_memcpy(&y, z + j, sizeof y);
        t = x * y;
        vs += t;
        va += (lcpcli_v4d)((lcpcli_v4u)t & nosign);
    }
    for (int k = 0; k < 4; k++) {
        s[k] = vs[k];
        a[k] = va[k];
    }
#else
    for (; j + 4 <= n; j += 4)
        for (int k = 0; k < 4; k++) {
            double t = row[j + k] * z[j + k];
            s[k] += t;
            a[k] += fabs(t);
        }
#endif
    for (; j < n; j++) {
        double t = row[j] * z[j];
        s[0] += t;
        a[0] += fabs(t);
    }
    *dot = (s[0] + s[1]) + (s[2] + s[3]);
    *absdot = (a[0] + a[1]) + (a[2] + a[3]);
}

/* kappa_j = max(kappa_j, |row_j| inv) for every j (inv finite) */
LCPCLI_ROW_CLONES static void lcpcli_col_max(double *restrict kappa, const double *restrict row,
                                             double inv, ptrdiff_t n)
{
    for (ptrdiff_t j = 0; j < n; j++) {
        double t = fabs(row[j]) * inv;
        kappa[j] = t > kappa[j] ? t : kappa[j];
    }
}

#endif
