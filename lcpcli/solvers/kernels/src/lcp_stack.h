/* Single-source stacked kernels: Lemke (lexicographic ratio test) and projected SOR, each
 * followed by the project's componentwise certificate, for ONE problem of a stack.
 *
 * The same text is compiled twice:
 *   - by the C compiler, for the CPU: lcpcli/solvers/kernels/stack_c.pyx (`cdef extern`), so the
 *     test suite (which never has a GPU) checks this code against lcpcli.solve_many;
 *   - by NVRTC through CuPy (lcpcli/solvers/backends/cuda.py), for the device: the __global__
 *     kernels at the end (one thread, or a group of 8-32 lanes of a warp, per problem;
 *     grid-stride loops) call the same functions.  The lane code runs on the CPU too, with one
 *     lane and (tests/solvers/test_lane_groups.py, LCP_EMULATE_LANES) with threads standing in
 *     for the lanes of a group.
 *
 * Plain C99 (and valid C++ for NVRTC); no allocation: the caller passes each problem's
 * workspace (LCP_LEMKE_DWORK / LCP_LEMKE_IWORK, LCP_SOR_DWORK / LCP_SOR_IWORK entries).
 * Arithmetic follows the CPU kernels operation by operation (lcpcli/solvers/kernels/lemke.pyx,
 * pgs.pyx, lcpcli/core/_certificate.pyx: same loops, same partial sums), so that, compiled
 * without contraction into FMA (NVRTC: --fmad=false), the device reproduces the CPU's rounding.
 *
 * Verdicts: code 0 (SOLVED) only when the certificate (docs/certificate.md) passed at `tol`;
 * else 1 (RETRY): the caller hands the problem to the CPU path.  Lemke equilibrates and
 * polishes as the CPU kernel does; it says RETRY where the CPU would take another road: a
 * certificate out of double range (the CPU rescales) or an end basis of 64 or more basic z
 * (the CPU re-solves it with LAPACK).  So every SOLVED here is an answer the CPU kernel also
 * certifies, computed the same way.
 */
#ifndef LCPCLI_LCP_STACK_H
#define LCPCLI_LCP_STACK_H

#if defined(__CUDACC_RTC__) || defined(__CUDACC__)
#define LCP_FN static __device__ __forceinline__
#define LCP_RESTRICT __restrict__
/* the serial steps lane 0 takes rarely (equilibration, polish, the lexicographic tie-break,
 * the serial certificate): called, not inlined, so they do not add to the registers of the
 * hot loops (the kernel's register count bounds how many problems run at once) */
#define LCP_COLD static __device__ __noinline__
#define LCP_INF __longlong_as_double(0x7ff0000000000000LL)
#define LCP_NAN __longlong_as_double(0x7ff8000000000000LL)
#define LCP_ISFINITE(x) isfinite(x)
#define LCP_UNROLL _Pragma("unroll")
/* a loop kept rolled (the speed variants' loops: unrolled, they raised the kernel's registers
 * and spills, ptxas -v) */
#define LCP_ROLLED _Pragma("unroll 1")
#define LCP_AXPY(y, x, a, n)                                                                 \
    do {                                                                                     \
        for (lcp_ix j_ = 0; j_ < (n); j_++)                                                 \
            (y)[j_] += (a) * (x)[j_];                                                        \
    } while (0)
#else
#include <math.h>
#include <string.h>
/* the CPU build shares the CPU kernels' vector loop (AVX2 and baseline clones, no FMA: the
 * same rounding as the plain loop the device runs) */
#include "../simd.h"
#define LCP_AXPY(y, x, a, n) lcpcli_axpy((y), (x), (a), (n))
#if defined(__GNUC__) && !defined(__clang__)
#define LCP_UNROLL _Pragma("GCC unroll 16")
#else
#define LCP_UNROLL
#endif
#define LCP_ROLLED
#define LCP_FN static inline
#define LCP_RESTRICT restrict
#define LCP_COLD static inline
#define LCP_INF INFINITY
#define LCP_NAN NAN
#define LCP_ISFINITE(x) isfinite(x)
#endif

/* lcp_i64: the 64-bit integers of the interface (sizes K and n, offsets into a stack, pivot
 * counts); lcp_ix: indices inside one problem: 32-bit on the device (fewer registers and
 * instructions than 64-bit arithmetic), 64-bit on the CPU (the stack_c.pyx declarations). */
typedef long long lcp_i64;
#if defined(__CUDACC_RTC__) || defined(__CUDACC__)
typedef int lcp_ix;
#define LCP_IX_PER_SLOT 2
#else
typedef long long lcp_ix;
#define LCP_IX_PER_SLOT 1
#endif

/* Lanes: functions that take (lane, lanes) split their loops over `lanes` lanes (on the device
 * a group of 8, 16 or 32 lanes of one warp per problem, groups aligned within the warp; 1 for
 * one thread per problem and on the CPU, where the lane code paths run with one lane) and meet
 * at LCP_SYNC(); lane 0 does the serial steps.  `lanes` is uniform in a group, and every
 * collective below names only the group's lanes (groups of one warp run independently).
 * LCP_EMULATE_LANES: the includer provides lcp_emu_sync, lcp_emu_any and lcp_emu_shfl (threads
 * standing in for lanes: tests/solvers/lanes_harness.cpp), so the CPU checks the lane paths. */
#if defined(__CUDACC_RTC__) || defined(__CUDACC__)
/* the mask of the calling lane's group of `lanes` (a power of two, at most 32) */
static __device__ __forceinline__ unsigned lcp_group_mask(int lanes)
{
    unsigned first = (threadIdx.x & 31u) & ~(unsigned)(lanes - 1);
    return lanes >= 32 ? 0xffffffffu : ((1u << lanes) - 1u) << first;
}
#define LCP_SYNC()                                                                           \
    do {                                                                                     \
        if (lanes > 1)                                                                       \
            __syncwarp(lcp_group_mask((int)lanes));                                          \
    } while (0)
#define LCP_ANY(p) (lanes > 1 ? __any_sync(lcp_group_mask((int)lanes), (p)) : (p))
#define LCP_SHFL(x, o) __shfl_xor_sync(lcp_group_mask((int)lanes), (x), (o))
#elif defined(LCP_EMULATE_LANES)
#define LCP_SYNC()                                                                           \
    do {                                                                                     \
        if (lanes > 1)                                                                       \
            lcp_emu_sync();                                                                  \
    } while (0)
#define LCP_ANY(p) (lanes > 1 ? lcp_emu_any(p) : (p))
#define LCP_SHFL(x, o) lcp_emu_shfl((x), (o))
#else
#define LCP_SYNC() ((void)lanes)
#define LCP_ANY(p) (p)
#define LCP_SHFL(x, o) (x) /* never reached: lanes == 1 on the CPU */
#endif
/* LCP_UNIFORM(x): x must be the same on every lane of the group (a pivot row every lane
 * indexes with).  A check of the lane harness only (lcp_emu_uniform: the lanes stop and the
 * run reports the divergence, instead of pivoting on different rows and writing out of
 * bounds); nothing on the device and the CPU. */
#ifdef LCP_EMULATE_LANES
#define LCP_UNIFORM(x)                                                                       \
    do {                                                                                     \
        if (lanes > 1)                                                                       \
            lcp_emu_uniform((long long)(x));                                                 \
    } while (0)
#else
#define LCP_UNIFORM(x) ((void)0)
#endif

/* Reductions over the lanes of a group (every lane gets the result; one lane: the value
 * itself).  Min and max by comparison, as the serial loops compute them: the same value
 * whatever the order (the operands are never NaN: each lane starts from a number and keeps
 * only values that compare).  The xor offsets stay below `lanes`: inside the group. */
LCP_FN double lcp_lanes_min(double x, lcp_ix lanes)
{
    double y;
    lcp_ix o;
    for (o = lanes >> 1; o > 0; o >>= 1) {
        y = LCP_SHFL(x, o);
        if (y < x)
            x = y;
    }
    return x;
}
LCP_FN lcp_ix lcp_lanes_imax(lcp_ix x, lcp_ix lanes)
{
    lcp_ix y, o;
    for (o = lanes >> 1; o > 0; o >>= 1) {
        y = LCP_SHFL(x, o);
        if (y > x)
            x = y;
    }
    return x;
}

/* Two maxima at once: their shuffles are independent, so their latencies overlap. */
LCP_FN void lcp_lanes_max2(double *x, double *y, lcp_ix lanes)
{
    double a = *x, b = *y, u, v;
    lcp_ix o;
    for (o = lanes >> 1; o > 0; o >>= 1) {
        u = LCP_SHFL(a, o);
        v = LCP_SHFL(b, o);
        if (u > a)
            a = u;
        if (v > b)
            b = v;
    }
    *x = a;
    *y = b;
}
/* An index maximum, a sum and another index maximum at once (a sum by shuffles: exact on
 * integers, so any order). */
LCP_FN void lcp_lanes_imax_isum_imax(lcp_ix *x, lcp_ix *y, lcp_ix *z, lcp_ix lanes)
{
    lcp_ix a = *x, b = *y, c = *z, u, v, o;
    for (o = lanes >> 1; o > 0; o >>= 1) {
        u = LCP_SHFL(a, o);
        b += LCP_SHFL(b, o);
        v = LCP_SHFL(c, o);
        if (u > a)
            a = u;
        if (v > c)
            c = v;
    }
    *x = a;
    *y = b;
    *z = c;
}

enum { LCP_SOLVED = 0, LCP_RETRY = 1 };
enum { LCP_OK = 0, LCP_RAY = 1, LCP_MAX_ITER = 2, LCP_TRIVIAL = 3 };

/* tolerances of lemke.pyx (DEGENERATE_RTOL, LEX_RTOL) and _certificate.pyx (THETA, 2^+-960) */
#define LCP_DEGENERATE_RTOL 1e-13
#define LCP_LEX_RTOL 1e-10
#define LCP_THETA 0.0009765625

/* workspace per problem (doubles, then long longs) */
#define LCP_CERT_DWORK(n) (5 * (n))
#define LCP_CERT_IWORK(n) (3 * (n))
/* Lemke: the tableau part (LCP_TAB_*, below) and the rest: raw z (n), the certificate's,
 * the equilibrated copy (n^2 + 2 n), polish (2 n^2 + 3 n); equilibration exponents (4 n),
 * polish indices (3 n) */
#define LCP_REST_DWORK(n) (LCP_HOT_DWORK(n) + LCP_COLD_DWORK(n))
#define LCP_REST_IWORK(n) (LCP_HOT_IWORK(n) + LCP_COLD_IWORK(n))
/* the rest in two parts: hot (every problem: raw z, the certificate's work, staged q, z, w,
 * the scaling's exponents) and cold (a scaled copy of the problem, the polish's work: rarely
 * touched) */
#define LCP_HOT_DWORK(n) (9 * (n))
#define LCP_HOT_IWORK(n) (7 * (n))
#define LCP_COLD_DWORK(n) (3 * (n) * (n) + 5 * (n))
#define LCP_COLD_IWORK(n) (3 * (n))
/* The warp kernel's workspace per group, in 8-byte slots: the fast part (shared memory when
 * it fits: the tableau part and the hot part) and the cold part (device memory), each its
 * doubles, then its lcp_ix packed `per` to a slot (LCP_IX_PER_SLOT: two 32-bit indices to a
 * slot on the device, one on the CPU; the *_FOR forms let the host size the device's). */
#define LCP_IX_SLOTS(k, per) (((k) + (per) - 1) / (per))
#define LCP_FAST_SLOTS_FOR(n, per)                                                           \
    (LCP_TAB_DWORK(n) + LCP_IX_SLOTS(LCP_TAB_IWORK(n), per) + LCP_HOT_DWORK(n) +             \
     LCP_IX_SLOTS(LCP_HOT_IWORK(n), per))
#define LCP_COLD_SLOTS_FOR(n, per) (LCP_COLD_DWORK(n) + LCP_IX_SLOTS(LCP_COLD_IWORK(n), per))
#define LCP_FAST_SLOTS(n) LCP_FAST_SLOTS_FOR(n, LCP_IX_PER_SLOT)
#define LCP_COLD_SLOTS(n) LCP_COLD_SLOTS_FOR(n, LCP_IX_PER_SLOT)
#define LCP_LEMKE_DWORK(n) (LCP_TAB_DWORK(n) + LCP_REST_DWORK(n))
#define LCP_LEMKE_IWORK(n) (LCP_TAB_IWORK(n) + LCP_REST_IWORK(n))
#define LCP_SOR_DWORK(n) (4 * (n) + 1 + LCP_CERT_DWORK(n))
#define LCP_SOR_IWORK(n) (LCP_CERT_IWORK(n))

LCP_FN double lcp_big(void) { return ldexp(1.0, 960); }
LCP_FN double lcp_small(void) { return ldexp(1.0, -960); }

/* dst[i ld + j] = src[i n + j] for the n x n block src, split over the lanes in the order of
 * src (consecutive lanes read consecutive entries: coalesced on the device), LCP_COPY_BATCH
 * entries a lane at a time: a batch's loads are all issued before its stores (restrict), so
 * that a lane waits on device memory once a batch, not once an entry. */
#ifndef LCP_COPY_BATCH /* an NVRTC/nvcc -D option for a device sweep; speed only */
#define LCP_COPY_BATCH 4
#endif
LCP_FN void lcp_copy_block(double *LCP_RESTRICT dst, lcp_ix ld, const double *LCP_RESTRICT src,
                           lcp_ix n, lcp_ix lane, lcp_ix lanes)
{
    lcp_ix e, u, nn = n * n, i = lane / (n > 0 ? n : 1), j = lane - i * n, skip = ld - n;
    lcp_ix o[LCP_COPY_BATCH];
    double v[LCP_COPY_BATCH];
    for (e = lane; e < nn; e += LCP_COPY_BATCH * lanes) {
        LCP_UNROLL
        for (u = 0; u < LCP_COPY_BATCH; u++) {
            o[u] = e + u * lanes;
            if (o[u] < nn)
                v[u] = src[o[u]];
        }
        LCP_UNROLL
        for (u = 0; u < LCP_COPY_BATCH; u++) {
            if (o[u] < nn)
                dst[o[u] + i * skip] = v[u];
            for (j += lanes; j >= n; j -= n) /* (i, j): the row and column of the next entry */
                i += 1;
        }
    }
}

/* ------------------------------------------------------------------------------ certificate */
typedef struct {
    double error, residual;
    int status; /* 0 ok, 1 non-finite z or w, 2 out of range (the CPU rescales: RETRY here) */
} lcp_cert;

LCP_FN lcp_ix lcp_find(lcp_ix *parent, lcp_ix x)
{
    while (parent[x] != x) {
        parent[x] = parent[parent[x]];
        x = parent[x];
    }
    return x;
}

LCP_FN void lcp_union(lcp_ix *parent, lcp_ix a, lcp_ix b)
{
    a = lcp_find(parent, a);
    b = lcp_find(parent, b);
    if (a != b) {
        if (a < b)
            parent[b] = a;
        else
            parent[a] = b;
    }
}

LCP_FN double lcp_rel(double v, double s)
{
    if (v == 0.0)
        return 0.0;
    if (s == 0.0)
        return LCP_INF;
    return v / s;
}

LCP_FN double lcp_move(double x, double kappa) { return x == 0.0 ? 0.0 : x * kappa; }

LCP_FN void lcp_bounds(lcp_ix i, const double *lo, const double *up, double *l, double *u)
{
    if (lo) {
        *l = lo[i];
        *u = up[i];
    } else {
        *l = 0.0;
        *u = LCP_INF;
    }
}

/* sum_j row_j z_j and sum_j |row_j z_j| with four partial sums each (as _certificate.pyx) */
LCP_FN void lcp_row_dot(const double *row, const double *z, lcp_ix n, double *dot,
                        double *absdot)
{
    double s0 = 0.0, s1 = 0.0, s2 = 0.0, s3 = 0.0, a0 = 0.0, a1 = 0.0, a2 = 0.0, a3 = 0.0;
    double t0, t1, t2, t3;
    lcp_ix j = 0;
    while (j + 4 <= n) {
        t0 = row[j] * z[j];
        t1 = row[j + 1] * z[j + 1];
        t2 = row[j + 2] * z[j + 2];
        t3 = row[j + 3] * z[j + 3];
        s0 += t0;
        s1 += t1;
        s2 += t2;
        s3 += t3;
        a0 += fabs(t0);
        a1 += fabs(t1);
        a2 += fabs(t2);
        a3 += fabs(t3);
        j += 4;
    }
    while (j < n) {
        t0 = row[j] * z[j];
        s0 += t0;
        a0 += fabs(t0);
        j += 1;
    }
    *dot = (s0 + s1) + (s2 + s3);
    *absdot = (a0 + a1) + (a2 + a3);
}

LCP_FN int lcp_cert_fail(lcp_cert *out, int status)
{
    out->error = LCP_INF;
    out->residual = LCP_INF;
    out->status = status;
    return status;
}

/* Pass 3 of the certificate (a, s, kappa filled in work; root[i]: the least member of row
 * i's block, rows 0..n-1 and columns n..2n-1 as vertices): score the pairs, then the blocks.
 * anchor: n long longs of scratch. */
LCP_FN int lcp_cert_finish(lcp_ix n, const double *q, const double *z, const double *lo,
                           const double *up, const double *w, double *work, const lcp_ix *root,
                           lcp_ix *anchor, lcp_cert *out)
{
    double *a = work, *s = work + n, *kappa = work + 2 * n, *compmin = work + 3 * n;
    lcp_ix i, r, worst = -1;
    double l, u, zi, wi, si, best, x, g, den, e, err = 0.0, gi, cF, cL, cU, resid = 0.0, t;
    int st;
    /* (a) every pair's backward error */
    for (i = 0; i < n; i++) {
        lcp_bounds(i, lo, up, &l, &u);
        zi = z[i];
        wi = w[i];
        si = s[i];
        cF = lcp_rel(fabs(wi), si);
        x = 0.0;
        if (zi < l)
            x = l - zi;
        else if (zi > u)
            x = zi - u;
        t = lcp_move(x, kappa[i]);
        if (t > cF)
            cF = t;
        cL = LCP_INF;
        if (l > -LCP_INF) {
            cL = wi < 0.0 ? lcp_rel(-wi, si) : 0.0;
            t = lcp_move(fabs(zi - l), kappa[i]);
            if (t > cL)
                cL = t;
        }
        cU = LCP_INF;
        if (u < LCP_INF) {
            cU = wi > 0.0 ? lcp_rel(wi, si) : 0.0;
            t = lcp_move(fabs(zi - u), kappa[i]);
            if (t > cU)
                cU = t;
        }
        if (zi == l) {
            best = cL; st = 0;
            if (cF < best) { best = cF; st = 2; }
            if (cU < best) { best = cU; st = 1; }
        } else if (zi == u) {
            best = cU; st = 1;
            if (cF < best) { best = cF; st = 2; }
            if (cL < best) { best = cL; st = 0; }
        } else {
            best = cF; st = 2;
            if (cL < best) { best = cL; st = 0; }
            if (cU < best) { best = cU; st = 1; }
        }
        anchor[i] = st == 2;
        kappa[i] = best; /* eps_i */
        t = zi - l;
        if (wi < t)
            t = wi;
        if (zi - u > t)
            t = zi - u;
        if (fabs(t) > resid)
            resid = fabs(t);
    }
    /* (b) each block's growth: the smallest growth among its equations with data (q_i != 0;
     * an equation with q_i = 0 anchors nothing, as in lcpcli/core/_certificate.pyx) */
    for (i = 0; i < 2 * n; i++)
        compmin[i] = LCP_INF;
    for (i = 0; i < n; i++) {
        if (a[i] > 0.0 && anchor[i] && q[i] != 0.0) {
            den = fabs(q[i]) + fabs(w[i]);
            g = den == 0.0 ? LCP_INF : a[i] / den;
            r = root[i];
            if (g < compmin[r])
                compmin[r] = g;
        }
    }
    /* (c) the certified error: max_i eps_i max(1, G_i) */
    for (i = 0; i < n; i++) {
        best = kappa[i];
        gi = 1.0;
        if (a[i] > 0.0) {
            gi = compmin[root[i]];
            if (gi == LCP_INF) {
                den = fabs(q[i]) + fabs(w[i]);
                gi = q[i] != 0.0 ? a[i] / den : 1.0;
            }
            if (gi < 1.0)
                gi = 1.0;
        }
        e = best == 0.0 ? 0.0 : best * gi;
        if (e > err || worst < 0) {
            err = e;
            worst = i;
        }
    }
    out->error = err;
    out->residual = resid;
    out->status = 0;
    return 0;
}

/* The certificate of z for the LCP (lo == NULL: z >= 0) or box LCP [lo, up] with dense
 * row-major M (n x n): lcpcli/core/_certificate.pyx's certify_dense with n_eq = 0, field for
 * field (error and residual kept).  w (n) receives M z + q; work: LCP_CERT_DWORK(n) doubles,
 * iwork: LCP_CERT_IWORK(n).  Returns out->status. */
LCP_COLD int lcp_certify(lcp_ix n, const double *M, const double *q, const double *z,
                       const double *lo, const double *up, double *w, double *work,
                       lcp_ix *iwork, lcp_cert *out)
{
    double *a = work, *s = work + n, *kappa = work + 2 * n;
    lcp_ix *parent = iwork, *cols = iwork + 2 * n, *anchor = iwork + 2 * n;
    lcp_ix i, j, k, nc = 0;
    const double *row;
    double wi, ai, t, m, inv, BIG = lcp_big(), SMALL = lcp_small();
    for (j = 0; j < n; j++) {
        if (!LCP_ISFINITE(z[j]))
            return lcp_cert_fail(out, 1);
        if (z[j] != 0.0 && !(SMALL <= fabs(z[j]) && fabs(z[j]) <= BIG))
            return lcp_cert_fail(out, 2);
    }
    /* pass 1: w, |M||z|, s */
    for (i = 0; i < n; i++) {
        row = M + i * n;
        lcp_row_dot(row, z, n, &wi, &ai);
        wi = wi + q[i];
        w[i] = wi;
        a[i] = ai;
        s[i] = ai + fabs(q[i]);
        if (!(LCP_ISFINITE(wi) && LCP_ISFINITE(ai)) || s[i] > BIG || (0.0 < s[i] && s[i] < SMALL))
            return lcp_cert_fail(out, 2);
    }
    /* pass 2: kappa for the columns that may move, blocks through significant terms */
    for (j = 0; j < n; j++) {
        int moves = lo ? !(z[j] == lo[j] && z[j] == up[j]) : z[j] != 0.0;
        if (moves || z[j] != 0.0)
            cols[nc++] = j;
        kappa[j] = 0.0;
    }
    for (i = 0; i < 2 * n; i++)
        parent[i] = i;
    if (nc > 0) {
        for (i = 0; i < n; i++) {
            row = M + i * n;
            inv = s[i] == 0.0 ? LCP_INF : 1.0 / s[i];
            for (k = 0; k < nc; k++) {
                j = cols[k];
                m = fabs(row[j]);
                if (m != 0.0) {
                    t = m * inv;
                    if (t > kappa[j])
                        kappa[j] = t;
                }
            }
        }
        for (i = 0; i < n; i++) {
            row = M + i * n;
            inv = s[i] == 0.0 ? LCP_INF : 1.0 / s[i];
            for (k = 0; k < nc; k++) {
                j = cols[k];
                m = fabs(row[j]);
                if (m != 0.0 && z[j] != 0.0 && m * inv >= LCP_THETA * kappa[j])
                    lcp_union(parent, i, n + j);
            }
        }
    }
    for (k = 0; k < nc; k++) {
        j = cols[k];
        if (kappa[j] == 0.0)
            kappa[j] = LCP_INF;
    }
    for (i = 0; i < 2 * n; i++) /* each row's block: the root of its set (its least member) */
        parent[i] = lcp_find(parent, i);
    return lcp_cert_finish(n, q, z, lo, up, w, work, parent, anchor, out);
}

/* LCP_CERT_LINKS (an NVRTC/nvcc -D option for a device sweep; speed only, 0 (off) in the
 * shipped build: on an H200, 2026-11-28, it gained nothing at n = 12 and cost 4-6 % at
 * n = 50 beside the fused ratio test; 1 or 2: the words of 32 bits a row or column may take, so n <= 32 or
 * n <= 64): the links of the row-column graph are found once, as bit masks, by the lane of
 * each column right after its kappa_j (the same test on the same values: |M_ij| / s_i
 * against THETA kappa_j), and the label propagation reads the masks instead of M, z, kappa
 * and 1 / s_i on every pass: M is read three times (w, kappa, the links) instead of twice
 * plus twice per pass, with no more workspace: the column masks take the half of work's last
 * 2 n that lcp_cert_finish fills later, the row masks (the transpose) take 1 / s_i's n once
 * the links are found.  The same blocks, so the same error bit for bit.  Larger n: the
 * propagation below.  (2 raises the registers: ptxas -v, benchmarks/README.md.) */
#ifndef LCP_CERT_LINKS
#define LCP_CERT_LINKS 0
#endif
#if LCP_CERT_LINKS < 0 || LCP_CERT_LINKS > 2
#error "LCP_CERT_LINKS: 0, 1 or 2"
#endif
#if LCP_CERT_LINKS
#if defined(__CUDACC_RTC__) || defined(__CUDACC__)
#define LCP_CTZ(b) (__ffs((int)(b)) - 1)
#elif defined(__GNUC__)
#define LCP_CTZ(b) __builtin_ctz(b)
#else
LCP_FN int lcp_ctz(unsigned b)
{
    int k = 0;
    while (!(b & 1u)) {
        b >>= 1;
        k += 1;
    }
    return k;
}
#define LCP_CTZ(b) lcp_ctz(b)
#endif
#endif
/* lcp_certify split over the lanes (the warp kernel): the same error, bit for bit.  Rows of
 * passes 1-2 go to the lanes (each row's sums in lcp_certify's order); the blocks are found by
 * label propagation on the row-column graph instead of union-find (either gives each row its
 * block's least member); lane 0 scores the pairs (lcp_cert_finish).  Every lane returns the
 * status; only lane 0's *out is filled.  work, iwork as lcp_certify. */
LCP_FN int lcp_certify_warp(lcp_ix n, const double *M, const double *q, const double *z,
                            const double *lo, const double *up, double *w, double *work,
                            lcp_ix *iwork, lcp_cert *out, lcp_ix lane, lcp_ix lanes)
{
    /* rinv: 1 / s_i (Inf where s_i = 0), in the space lcp_cert_finish's compmin takes later */
    double *a = work, *s = work + n, *kappa = work + 2 * n, *rinv = work + 3 * n;
    lcp_ix *lab = iwork, *movable = iwork + 2 * n;
    lcp_ix i, j, best;
    int bad = 0, changed;
    double wi, ai, t, m, inv, kj, BIG = lcp_big(), SMALL = lcp_small();
#if LCP_CERT_LINKS
    /* the link masks (LCP_CERT_LINKS): nw words per column, then per row (1: a constant) */
    lcp_ix wd, nw = LCP_CERT_LINKS == 1 ? 1 : (n + 31) / 32;
    unsigned bits, *colm = n <= 32 * LCP_CERT_LINKS ? (unsigned *)(work + 4 * n) : 0;
    unsigned *rowm = (unsigned *)rinv;
#endif
    for (j = 0; j < n; j++) { /* every lane: the same answer */
        if (!LCP_ISFINITE(z[j]))
            return lcp_cert_fail(out, 1);
        if (z[j] != 0.0 && !(SMALL <= fabs(z[j]) && fabs(z[j]) <= BIG))
            return lcp_cert_fail(out, 2);
    }
    for (i = lane; i < n; i += lanes) {
        lcp_row_dot(M + i * n, z, n, &wi, &ai);
        wi = wi + q[i];
        w[i] = wi;
        a[i] = ai;
        s[i] = ai + fabs(q[i]);
        rinv[i] = s[i] == 0.0 ? LCP_INF : 1.0 / s[i];
        if (!(LCP_ISFINITE(wi) && LCP_ISFINITE(ai)) || s[i] > BIG || (0.0 < s[i] && s[i] < SMALL))
            bad = 1;
    }
    LCP_SYNC();
    if (LCP_ANY(bad))
        return lcp_cert_fail(out, 2);
    /* kappa_j = max_i |M_ij| / s_i for the columns that may move (a max: any order; kept in
     * a register: a store in the loop would order every load after it) */
    for (j = lane; j < n; j += lanes) {
        movable[j] = (lo ? !(z[j] == lo[j] && z[j] == up[j]) : z[j] != 0.0) || z[j] != 0.0;
        kj = 0.0;
        if (movable[j]) {
            for (i = 0; i < n; i++) {
                inv = rinv[i];
                m = fabs(M[i * n + j]);
                if (m != 0.0) {
                    t = m * inv;
                    if (t > kj)
                        kj = t;
                }
            }
            if (kj == 0.0) /* a zero column: no link below, moving z_j never negligible */
                kj = LCP_INF;
        }
        kappa[j] = kj;
#if LCP_CERT_LINKS
        if (colm) /* column j's links: bit i % 32 of word i / 32 */
            for (wd = 0; wd < nw; wd++) {
                bits = 0u;
                if (z[j] != 0.0)
                    LCP_ROLLED for (i = 32 * wd; i < n && i < 32 * wd + 32; i++) {
                        m = fabs(M[i * n + j]);
                        if (m != 0.0 && m * rinv[i] >= LCP_THETA * kj)
                            bits |= 1u << (i & 31);
                    }
                colm[j * nw + wd] = bits;
            }
#endif
    }
    for (i = lane; i < 2 * n; i += lanes)
        lab[i] = i;
    LCP_SYNC();
#if LCP_CERT_LINKS
    if (colm) { /* row i's links (the transpose), over 1 / s_i: every lane has read it */
        for (i = lane; i < n; i += lanes)
            for (wd = 0; wd < nw; wd++) {
                bits = 0u;
                LCP_ROLLED for (j = 32 * wd; j < n && j < 32 * wd + 32; j++)
                    bits |= ((colm[j * nw + (i >> 5)] >> (i & 31)) & 1u) << (j & 31);
                rowm[i * nw + wd] = bits;
            }
        do { /* the propagation below, on the masks (rows: their own; columns: after the SYNC) */
            changed = 0;
            for (i = lane; i < n; i += lanes) {
                best = lab[i];
                for (wd = 0; wd < nw; wd++)
                    for (bits = rowm[i * nw + wd]; bits; bits &= bits - 1u) {
                        j = 32 * wd + LCP_CTZ(bits);
                        if (lab[n + j] < best)
                            best = lab[n + j];
                    }
                if (best < lab[i]) {
                    lab[i] = best;
                    changed = 1;
                }
            }
            LCP_SYNC();
            for (j = lane; j < n; j += lanes) {
                best = lab[n + j];
                for (wd = 0; wd < nw; wd++)
                    for (bits = colm[j * nw + wd]; bits; bits &= bits - 1u) {
                        i = 32 * wd + LCP_CTZ(bits);
                        if (lab[i] < best)
                            best = lab[i];
                    }
                if (best < lab[n + j]) {
                    lab[n + j] = best;
                    changed = 1;
                }
            }
            LCP_SYNC();
        } while (LCP_ANY(changed));
    } else
#endif
    /* blocks: rows i and columns n + j linked where z_j != 0 and |M_ij| / s_i >= THETA kappa_j;
     * labels fall to the least vertex of each connected part */
    do {
        changed = 0;
        for (i = lane; i < n; i += lanes) {
            inv = rinv[i];
            best = lab[i];
            for (j = 0; j < n; j++) {
                m = fabs(M[i * n + j]);
                if (m != 0.0 && z[j] != 0.0 && m * inv >= LCP_THETA * kappa[j] && lab[n + j] < best)
                    best = lab[n + j];
            }
            if (best < lab[i]) {
                lab[i] = best;
                changed = 1;
            }
        }
        LCP_SYNC();
        for (j = lane; j < n; j += lanes) {
            if (z[j] == 0.0)
                continue;
            best = lab[n + j];
            for (i = 0; i < n; i++) {
                inv = rinv[i];
                m = fabs(M[i * n + j]);
                if (m != 0.0 && m * inv >= LCP_THETA * kappa[j] && lab[i] < best)
                    best = lab[i];
            }
            if (best < lab[n + j]) {
                lab[n + j] = best;
                changed = 1;
            }
        }
        LCP_SYNC();
    } while (LCP_ANY(changed));
    if (lane == 0)
        return lcp_cert_finish(n, q, z, lo, up, w, work, lab, movable, out);
    return 0;
}

/* -------------------------------------------------------------------------- equilibration */
/* frexp's exponent of x != 0, finite, read from the IEEE-754 bits (subnormals: frexp) */
LCP_FN lcp_ix lcp_exp(double x)
{
    unsigned long long bits;
    lcp_ix field;
    int e;
#if defined(__CUDACC_RTC__) || defined(__CUDACC__)
    bits = (unsigned long long)__double_as_longlong(x);
#else
    memcpy(&bits, &x, 8);
#endif
    field = (lcp_ix)((bits >> 52) & 0x7ff);
    if (field == 0) {
        frexp(x, &e);
        return e;
    }
    return field - 1022;
}

LCP_FN lcp_ix lcp_floordiv2(lcp_ix x) { return x >= 0 ? x / 2 : -((-x + 1) / 2); }

/* below and above every exponent sum of the scaling (|e| < 2^12 per factor): fits 32 bits */
#define LCP_FLOOR (-((lcp_ix)1 << 29))
#define LCP_CEIL ((lcp_ix)1 << 29)

/* row and column maxima of the exponents of D_r M D_c over the nonzeros (_scaling.pyx) */
LCP_FN void lcp_maxima(lcp_ix n, const double *M, const lcp_ix *r, const lcp_ix *c,
                       lcp_ix *rmax, lcp_ix *cmax)
{
    lcp_ix i, j, e;
    for (i = 0; i < n; i++) {
        rmax[i] = LCP_FLOOR;
        cmax[i] = LCP_FLOOR;
    }
    for (i = 0; i < n; i++)
        for (j = 0; j < n; j++)
            if (M[i * n + j] != 0.0) {
                e = lcp_exp(M[i * n + j]) + r[i] + c[j];
                if (e > rmax[i])
                    rmax[i] = e;
                if (e > cmax[j])
                    cmax[j] = e;
            }
}

/* Ruiz's iteration on binary exponents, dense (lcpcli/analysis/_scaling.pyx's _ruiz): fill
 * r, c (n each); return 1 when a scaling is needed, 0 when the problem is balanced.
 * rmax, cmax: n each. */
LCP_FN int lcp_ruiz(lcp_ix n, const double *M, const double *q, int symmetric, int balanced,
                    int q_balanced, int max_rounds, lcp_ix *r, lcp_ix *c, lcp_ix *rmax,
                    lcp_ix *cmax)
{
    lcp_ix i, j, k, e, lo, hi, clo, chi, d, qexp;
    int rnd;
    for (i = 0; i < n; i++) {
        r[i] = 0;
        c[i] = 0;
    }
    for (rnd = 0; rnd < max_rounds; rnd++) {
        lcp_maxima(n, M, r, c, rmax, cmax);
        lo = LCP_CEIL;
        hi = LCP_FLOOR;
        clo = LCP_CEIL;
        chi = LCP_FLOOR;
        for (i = 0; i < n; i++) {
            if (rmax[i] == LCP_FLOOR)
                rmax[i] = 1;
            if (cmax[i] == LCP_FLOOR)
                cmax[i] = 1;
            if (rmax[i] < lo) lo = rmax[i];
            if (rmax[i] > hi) hi = rmax[i];
            if (cmax[i] < clo) clo = cmax[i];
            if (cmax[i] > chi) chi = cmax[i];
        }
        if (hi - lo <= balanced && chi - clo <= balanced && -balanced <= hi - 1
            && hi - 1 <= balanced)
            break;
        if (symmetric) {
            for (i = 0; i < n; i++) {
                d = rmax[i] > cmax[i] ? rmax[i] : cmax[i];
                d = lcp_floordiv2(1 - d);
                r[i] += d;
                c[i] += d;
            }
        } else {
            for (i = 0; i < n; i++)
                r[i] -= lcp_floordiv2(rmax[i] - 1);
            lcp_maxima(n, M, r, c, rmax, cmax);
            for (j = 0; j < n; j++) {
                if (cmax[j] == LCP_FLOOR)
                    cmax[j] = 1;
                c[j] -= lcp_floordiv2(cmax[j] - 1);
            }
        }
    }
    /* a common factor normalising q */
    qexp = LCP_FLOOR;
    for (i = 0; i < n; i++)
        if (q[i] != 0.0) {
            e = lcp_exp(q[i]) + r[i];
            if (e > qexp)
                qexp = e;
        }
    k = qexp == LCP_FLOOR ? 0 : -qexp + 1;
    for (i = 0; i < n; i++)
        if (r[i] != 0 || c[i] != 0)
            break;
    if (i == n && -q_balanced <= k && k <= q_balanced)
        return 0;
    for (i = 0; i < n; i++) {
        r[i] += k;
        c[i] -= k;
    }
    return 1;
}

LCP_FN int lcp_symmetric(const double *M, lcp_ix n)
{
    lcp_ix i, j;
    for (i = 0; i < n; i++)
        for (j = 0; j < i; j++)
            if (M[i * n + j] != M[j * n + i])
                return 0;
    return 1;
}

/* Equilibrate one problem as batch.pyx's _balance does (D M D for a symmetric M, two-sided
 * otherwise): fill Ms = D_r M D_c, qs = D_r q, ds = D_r d (ones when d is NULL) and return 1,
 * or return 0 when the problem is balanced already.  rc: 4 n long longs (r, c, scratch). */
LCP_COLD int lcp_balance(lcp_ix n, const double *M, const double *q, const double *d,
                       int balanced, int q_balanced, int max_rounds, double *Ms, double *qs,
                       double *ds, lcp_ix *rc)
{
    lcp_ix i, j, *r = rc, *c = rc + n;
    if (!lcp_ruiz(n, M, q, 0, balanced, q_balanced, 1, r, c, rc + 2 * n, rc + 3 * n))
        return 0;
    if (!lcp_ruiz(n, M, q, lcp_symmetric(M, n), balanced, q_balanced, max_rounds, r, c,
                  rc + 2 * n, rc + 3 * n))
        return 0;
    for (i = 0; i < n; i++) {
        for (j = 0; j < n; j++)
            Ms[i * n + j] = ldexp(M[i * n + j], (int)(r[i] + c[j]));
        qs[i] = ldexp(q[i], (int)r[i]);
        ds[i] = d ? ldexp(d[i], (int)r[i]) : 1.0;
    }
    return 1;
}

/* The first balance test of lcp_balance split over the lanes: 1 when the problem is balanced
 * at once (row and column exponent maxima, then q: lcp_ruiz's round 0 passing), 0 when
 * lcp_balance must decide.  M: rows ld apart; rmax, cmax: n each; every lane returns the
 * same value. */
LCP_FN int lcp_balanced_warp(lcp_ix n, const double *M, lcp_ix ld, const double *q,
                             int balanced, int q_balanced, lcp_ix *rmax, lcp_ix *cmax,
                             lcp_ix lane, lcp_ix lanes)
{
    lcp_ix i, j, e, best, lo = LCP_CEIL, hi = LCP_FLOOR, clo = LCP_CEIL;
    lcp_ix chi = LCP_FLOOR, qexp = LCP_FLOOR, k;
    int ok;
    for (i = lane; i < n; i += lanes) {
        best = LCP_FLOOR;
        for (j = 0; j < n; j++)
            if (M[i * ld + j] != 0.0) {
                e = lcp_exp(M[i * ld + j]);
                if (e > best)
                    best = e;
            }
        rmax[i] = best == LCP_FLOOR ? 1 : best;
    }
    for (j = lane; j < n; j += lanes) {
        best = LCP_FLOOR;
        for (i = 0; i < n; i++)
            if (M[i * ld + j] != 0.0) {
                e = lcp_exp(M[i * ld + j]);
                if (e > best)
                    best = e;
            }
        cmax[j] = best == LCP_FLOOR ? 1 : best;
    }
    LCP_SYNC();
    for (i = 0; i < n; i++) {
        if (rmax[i] < lo) lo = rmax[i];
        if (rmax[i] > hi) hi = rmax[i];
        if (cmax[i] < clo) clo = cmax[i];
        if (cmax[i] > chi) chi = cmax[i];
        if (q[i] != 0.0) {
            e = lcp_exp(q[i]);
            if (e > qexp)
                qexp = e;
        }
    }
    k = qexp == LCP_FLOOR ? 0 : -qexp + 1;
    ok = hi - lo <= balanced && chi - clo <= balanced && -balanced <= hi - 1
         && hi - 1 <= balanced && -q_balanced <= k && k <= q_balanced;
    LCP_SYNC(); /* rmax, cmax are scratch again for lane 0 */
    return ok;
}

/* ---------------------------------------------------------------------------------- Lemke */
/* Workspace of the tableau part of Lemke (shared memory in the warp kernel): doubles
 * T (n x (n + 1)), qb, keys, col (n each), rowr (n + 1); long longs basic (n), where
 * (2 n + 1), cand (n), ctl (5: the lanes' broadcast slots). */
#define LCP_TAB_DWORK(n) ((n) * ((n) + 1) + 4 * (n) + 1)
#define LCP_TAB_IWORK(n) (4 * (n) + 6)

/* pivot the nrows x ncols tableau on (r, c); rowr: ncols of work (lemke.pyx's pivot) */
LCP_FN void lcp_pivot(double *T, double *qb, lcp_ix nrows, lcp_ix ncols, lcp_ix r,
                      lcp_ix c, double *rowr)
{
    lcp_ix i, j;
    double p = T[r * ncols + c], inv = 1.0 / p, f, qr;
    double *Ti;
    for (j = 0; j < ncols; j++)
        rowr[j] = -T[r * ncols + j] * inv;
    rowr[c] = inv;
    qr = -qb[r] * inv;
    for (i = 0; i < nrows; i++) {
        if (i == r)
            continue;
        Ti = T + i * ncols;
        f = Ti[c];
        if (f != 0.0) {
            qb[i] += f * qr;
            LCP_AXPY(Ti, rowr, f, ncols);
            Ti[c] = f * inv;
        }
    }
    for (j = 0; j < ncols; j++)
        T[r * ncols + j] = rowr[j];
    qb[r] = qr;
}

/* The same pivot split over the lanes, a lane per column (every entry computed as lcp_pivot
 * computes it: the same rounding).  fcol: the pivot column T[:, c] as it was before the pivot
 * (fcol[r] is the pivot element; a copy, not T's own column).  A lane reads and writes only its
 * own columns of T; the entering column c, whose new entries are fcol[i] / p, is written with
 * qb, a row per lane, after the lanes meet.  Row r is updated with the others (its value is
 * dropped: rj is stored over it), so that the rows go without a test per entry, in blocks of
 * LCP_PIVOT_ROWS rows (then 4, 2 and 1 for the rest): a block's loads are all issued before
 * its stores (the compiler cannot move a load of fcol or T above a store to T, which may alias
 * it), so each block waits on memory once, not once per row. */
#ifndef LCP_PIVOT_ROWS
#define LCP_PIVOT_ROWS 8
#endif
#if LCP_PIVOT_ROWS > 16 || (LCP_PIVOT_ROWS & (LCP_PIVOT_ROWS - 1))
#error "LCP_PIVOT_ROWS: a power of two up to 16"
#endif
/* `rows` (a constant where it is called: up to LCP_PIVOT_ROWS) rows of one column: T_ij +=
 * f_i r_j where f_i != 0; Tb: the first row's entry of the column, fb: its f */
LCP_FN void lcp_pivot_rows(double *Tb, const double *fb, lcp_ix ncols, double rj, int rows)
{
    double f[LCP_PIVOT_ROWS], t[LCP_PIVOT_ROWS];
    int b;
    LCP_UNROLL
    for (b = 0; b < LCP_PIVOT_ROWS; b++)
        if (b < rows) {
            f[b] = fb[b];
            t[b] = Tb[b * ncols];
        }
    LCP_UNROLL
    for (b = 0; b < LCP_PIVOT_ROWS; b++)
        if (b < rows && f[b] != 0.0)
            Tb[b * ncols] = t[b] + f[b] * rj;
}

/* the rows left after the whole blocks, in blocks of halving size (each size at most once) */
#define LCP_PIVOT_TAIL(B)                                                                    \
    if (LCP_PIVOT_ROWS > (B) && nrows - i0 >= (B)) {                                         \
        lcp_pivot_rows(Tj + i0 * ncols, fcol + i0, ncols, rj, (B));                          \
        i0 += (B);                                                                           \
    }

LCP_FN void lcp_pivot_warp(double *T, double *qb, lcp_ix nrows, lcp_ix ncols, lcp_ix r,
                           lcp_ix c, const double *fcol, lcp_ix lane, lcp_ix lanes)
{
    lcp_ix i, i0, j;
    double inv = 1.0 / fcol[r], qr = -qb[r] * inv, rj, fi;
    double *Tj;
    for (j = lane; j < ncols; j += lanes) {
        if (j == c)
            continue;
        Tj = T + j;
        rj = -Tj[r * ncols] * inv;
        for (i0 = 0; i0 + LCP_PIVOT_ROWS <= nrows; i0 += LCP_PIVOT_ROWS)
            lcp_pivot_rows(Tj + i0 * ncols, fcol + i0, ncols, rj, LCP_PIVOT_ROWS);
        LCP_PIVOT_TAIL(8)
        LCP_PIVOT_TAIL(4)
        LCP_PIVOT_TAIL(2)
        LCP_PIVOT_TAIL(1)
        Tj[r * ncols] = rj;
    }
    LCP_SYNC(); /* every lane has read qb[r] */
    for (i = lane; i < nrows; i += lanes) {
        fi = fcol[i];
        if (i == r) {
            qb[i] = qr;
            T[i * ncols + c] = inv;
        } else if (fi != 0.0) {
            qb[i] += fi * qr;
            T[i * ncols + c] = fi * inv;
        }
    }
    LCP_SYNC();
}

/* Row of the initial pivot (most negative q_i / d_i, ties: the largest index); -1 when
 * q >= 0 (d NULL: ones) */
LCP_FN lcp_ix lcp_initial_row(const double *q, const double *d, lcp_ix n, double tie_tol)
{
    lcp_ix i, r = -1;
    double v, best = 0.0;
    for (i = 0; i < n; i++) {
        v = q[i] / (d ? d[i] : 1.0);
        if (v < best)
            best = v;
    }
    if (best >= 0.0)
        return -1;
    for (i = 0; i < n; i++)
        if (q[i] / (d ? d[i] : 1.0) <= best + tie_tol * fabs(best))
            r = i;
    return r;
}

/* The leaving row for the entering column col (basic = qb + col t): the minimum-ratio test
 * (lemke.pyx's ratio_candidates) and, among tied rows, the lexicographic minimum over rows of
 * the basis inverse divided by the pivot element (Cottle-Pang-Stone 4.9: no cycling); z0
 * leaves when it ties.  Returns -1 when no row blocks (a ray). */
LCP_COLD lcp_ix lcp_leaving_row(lcp_ix n, lcp_ix m, const double *T, const double *qb,
                               const double *col, double *keys, const lcp_ix *basic,
                               const lcp_ix *where, lcp_ix *cand, double piv_tol,
                               double tie_tol)
{
    lcp_ix i, k, s, nc, mm, loc, z0_row = -1, nz = 2 * n;
    double a, v, t, cmax = 0.0, qmax = 0.0, ptol, ztol, tmin = LCP_INF, unit, key, kmin, kmax;
    double bound;
    for (i = 0; i < n; i++) {
        a = fabs(col[i]);
        if (a > cmax)
            cmax = a;
        if (qb[i] > qmax)
            qmax = qb[i];
    }
    ptol = piv_tol * cmax;
    ztol = LCP_DEGENERATE_RTOL * qmax;
    for (i = 0; i < n; i++) {
        a = col[i];
        if (a < -ptol) {
            v = qb[i] > ztol ? qb[i] : 0.0;
            t = v / (-a);
            if (t < tmin)
                tmin = t;
        }
    }
    if (tmin == LCP_INF)
        return -1;
    nc = 0;
    for (i = 0; i < n; i++) {
        a = col[i];
        if (a < -ptol) {
            v = qb[i] > ztol ? qb[i] : 0.0;
            t = v / (-a);
            if (t <= tmin + tie_tol * tmin) {
                cand[nc++] = i;
                if (basic[i] == nz)
                    z0_row = i;
            }
        }
    }
    if (z0_row >= 0)
        return z0_row;
    if (nc == 1)
        return cand[0];
    unit = 0.0;
    for (s = 0; s < nc; s++) {
        a = -col[cand[s]];
        if (a > unit)
            unit = a;
    }
    unit = 1.0 / unit;
    for (k = 0; k < n; k++) {
        loc = where[k];
        for (s = 0; s < nc; s++) {
            i = cand[s];
            if (loc >= 0)
                key = loc == i ? 1.0 : 0.0;
            else
                key = -T[i * m + (-loc - 1)];
            keys[s] = key / (-col[i]);
        }
        kmin = LCP_INF;
        kmax = 0.0;
        for (s = 0; s < nc; s++) {
            if (keys[s] < kmin)
                kmin = keys[s];
            if (fabs(keys[s]) > kmax)
                kmax = fabs(keys[s]);
        }
        bound = kmin + LCP_LEX_RTOL * (kmax > unit ? kmax : unit);
        mm = 0;
        for (s = 0; s < nc; s++)
            if (keys[s] <= bound)
                cand[mm++] = cand[s];
        nc = mm;
        if (nc == 1)
            break;
    }
    return cand[0];
}

/* lcp_initial_row split over the lanes (the same row: the minimum by reduction, the last
 * index within the tie band by an index maximum); every lane returns it. */
LCP_FN lcp_ix lcp_initial_row_lanes(const double *q, const double *d, lcp_ix n,
                                     double tie_tol, lcp_ix lane, lcp_ix lanes)
{
    lcp_ix i, r = -1;
    double v, best = 0.0;
    for (i = lane; i < n; i += lanes) {
        v = q[i] / (d ? d[i] : 1.0);
        if (v < best)
            best = v;
    }
    best = lcp_lanes_min(best, lanes);
    if (best >= 0.0)
        return -1;
    for (i = lane; i < n; i += lanes)
        if (q[i] / (d ? d[i] : 1.0) <= best + tie_tol * fabs(best))
            r = i;
    return lcp_lanes_imax(r, lanes);
}

/* LCP_RATIO_FUSED (speed only, on in the shipped build since the H200 sweeps of 2026-11-28:
 * 2-4 % more certified problems/s at n = 12, 5-6 % at n = 50, outputs bit for bit those of
 * LCP_RATIO_FUSED=0, the earlier form, kept as a -D option for a device sweep): the minimum ratio and its row in one reduction, the lanes' other rows in the
 * tie band by one vote; only when another row ties (a degenerate step) are the ratios
 * computed again and the tied rows counted as below.  A step with one blocking row (the
 * common case) then takes one chain of shuffles of (ratio, row) and a vote instead of a
 * minimum, a second pass over the rows (a division each) and a three-way reduction. */
#ifndef LCP_RATIO_FUSED
#define LCP_RATIO_FUSED 1
#endif
#if LCP_RATIO_FUSED
/* (x, k): the least x of the group and, among equal ones, the largest k: the same on every
 * lane whatever the order (the operands are never NaN) */
LCP_FN void lcp_lanes_argmin(double *x, lcp_ix *k, lcp_ix lanes)
{
    double a = *x, u;
    lcp_ix b = *k, v, o;
    for (o = lanes >> 1; o > 0; o >>= 1) {
        u = LCP_SHFL(a, o);
        v = LCP_SHFL(b, o);
        if (u < a || (u == a && v > b)) {
            a = u;
            b = v;
        }
    }
    *x = a;
    *k = b;
}
#endif

/* lcp_leaving_row split over the lanes: the maxima, the minimum ratio and the tied rows by
 * reductions (the values lcp_leaving_row's loops compute); when more than one row ties and
 * z0 is not among them (a degenerate step), lane 0 breaks the tie with lcp_leaving_row's
 * lexicographic rule.  Every lane returns the row (-1: a ray); ctl: the lanes' broadcast
 * slot. */
LCP_FN lcp_ix lcp_leaving_row_lanes(lcp_ix n, lcp_ix m, const double *T, const double *qb,
                                     const double *col, double *keys, const lcp_ix *basic,
                                     const lcp_ix *where, lcp_ix *cand, double piv_tol,
                                     double tie_tol, lcp_ix *ctl, lcp_ix lane, lcp_ix lanes)
{
    lcp_ix i, nc = 0, one = -1, z0_row = -1, nz = 2 * n;
    double a, v, t, cmax = 0.0, qmax = 0.0, ptol, ztol, tmin = LCP_INF;
    for (i = lane; i < n; i += lanes) {
        a = fabs(col[i]);
        if (a > cmax)
            cmax = a;
        if (qb[i] > qmax)
            qmax = qb[i];
    }
    lcp_lanes_max2(&cmax, &qmax, lanes);
    ptol = piv_tol * cmax;
    ztol = LCP_DEGENERATE_RTOL * qmax;
#if LCP_RATIO_FUSED
    {
        /* the lane's least ratio (its row) and second least; then the group's least and its
         * row; a row other than that one in the band [tmin, tmin + tie_tol tmin] is a tie */
        double t2 = LCP_INF, gmin;
        lcp_ix grow;
        LCP_ROLLED for (i = lane; i < n; i += lanes) {
            a = col[i];
            if (a < -ptol) {
                v = qb[i] > ztol ? qb[i] : 0.0;
                t = v / (-a);
                if (t < tmin) {
                    t2 = tmin;
                    tmin = t;
                    one = i;
                } else if (t < t2) {
                    t2 = t;
                }
            }
        }
        gmin = tmin;
        grow = one;
        lcp_lanes_argmin(&gmin, &grow, lanes);
        if (gmin == LCP_INF)
            return -1;
        if (!LCP_ANY((one == grow ? t2 : tmin) <= gmin + tie_tol * gmin))
            return grow; /* the only row in the band (z0's or not: lcp_leaving_row's answer) */
        tmin = gmin;
        one = -1;
    }
#else
    for (i = lane; i < n; i += lanes) {
        a = col[i];
        if (a < -ptol) {
            v = qb[i] > ztol ? qb[i] : 0.0;
            t = v / (-a);
            if (t < tmin)
                tmin = t;
        }
    }
    tmin = lcp_lanes_min(tmin, lanes);
    if (tmin == LCP_INF)
        return -1;
#endif
    for (i = lane; i < n; i += lanes) {
        a = col[i];
        if (a < -ptol) {
            v = qb[i] > ztol ? qb[i] : 0.0;
            t = v / (-a);
            if (t <= tmin + tie_tol * tmin) {
                nc += 1;
                one = i;
                if (basic[i] == nz)
                    z0_row = i;
            }
        }
    }
    lcp_lanes_imax_isum_imax(&z0_row, &nc, &one, lanes);
    if (z0_row >= 0)
        return z0_row;
    if (nc == 1)
        return one;
    if (lane == 0)
        ctl[0] = lcp_leaving_row(n, m, T, qb, col, keys, basic, where, cand, piv_tol, tie_tol);
    LCP_SYNC();
    return ctl[0];
}

/* Lemke's method (condensed tableau, covering vector d, lexicographic minimum-ratio rule:
 * Cottle-Pang-Stone, The Linear Complementarity Problem, 4.4-4.9) on one problem, as
 * lemke.pyx's lemke_tableau, split over the lanes; warp = 0: lcp_pivot (one lane only),
 * else lcp_pivot_warp.  z (n) receives the basic solution; returns the status (LCP_OK,
 * LCP_RAY, LCP_MAX_ITER, LCP_TRIVIAL) and the pivots in *pivots_out.  ready: the tableau's
 * first n columns hold M already (rows n + 1 apart).  tw: LCP_TAB_DWORK(n)
 * doubles, ti: LCP_TAB_IWORK(n) long longs (ti's first n: the end basis). */
LCP_FN int lcp_lemke(lcp_ix n, const double *M, const double *q, const double *d,
                     lcp_i64 max_iter, double piv_tol, double tie_tol, double *z, double *tw,
                     lcp_ix *ti, lcp_i64 *pivots_out, lcp_ix lane, lcp_ix lanes, int warp,
                     int ready)
{
    lcp_ix m = n + 1, nz = 2 * n, i, j, r, c, entering, leaving;
    lcp_i64 pivots;
    int status = LCP_MAX_ITER;
    double *T = tw, *qb = T + n * m, *keys = qb + n, *col = keys + n, *rowr = col + n;
    lcp_ix *basic = ti, *where = basic + n, *cand = where + 2 * n + 1, *ctl = cand + n;
    if (!ready)
        lcp_copy_block(T, m, M, n, lane, lanes);
    for (i = lane; i < n; i += lanes) {
        T[i * m + n] = d ? d[i] : 1.0;
        col[i] = T[i * m + n];
        qb[i] = q[i];
        basic[i] = i;
        where[i] = i;
        z[i] = 0.0;
    }
    for (j = lane; j < m; j += lanes)
        where[n + j] = -(j + 1);
    if (warp) {
        r = lcp_initial_row_lanes(q, d, n, tie_tol, lane, lanes);
    } else {
        r = lcp_initial_row(q, d, n, tie_tol);
    }
    LCP_UNIFORM(r);
    LCP_SYNC();
    *pivots_out = 0;
    if (r < 0)
        return LCP_TRIVIAL;
    /* initial pivot: z0 enters, row r's w leaves */
    entering = nz;
    c = n;
    leaving = r; /* basic[r] == r before the first pivot */
    if (!warp)
        lcp_pivot(T, qb, n, m, r, c, rowr);
    else
        lcp_pivot_warp(T, qb, n, m, r, c, col, lane, lanes);
    if (lane == 0) {
        basic[r] = entering;
        where[entering] = r;
        where[leaving] = -(c + 1);
    }
    pivots = 1;
    while (pivots < max_iter) {
        entering = leaving < n ? leaving + n : leaving - n;
        LCP_SYNC();
        c = -where[entering] - 1;
        for (i = lane; i < n; i += lanes)
            col[i] = T[i * m + c];
        LCP_SYNC();
        if (warp)
            r = lcp_leaving_row_lanes(n, m, T, qb, col, keys, basic, where, cand, piv_tol,
                                      tie_tol, ctl + 1, lane, lanes);
        else
            r = lcp_leaving_row(n, m, T, qb, col, keys, basic, where, cand, piv_tol, tie_tol);
        LCP_UNIFORM(r);
        if (r < 0) {
            status = LCP_RAY;
            break;
        }
        leaving = basic[r];
        if (!warp)
            lcp_pivot(T, qb, n, m, r, c, rowr);
        else
            lcp_pivot_warp(T, qb, n, m, r, c, col, lane, lanes);
        if (lane == 0) {
            basic[r] = entering;
            where[entering] = r;
            where[leaving] = -(c + 1);
        }
        pivots += 1;
        if (leaving == nz) {
            status = LCP_OK;
            break;
        }
    }
    LCP_SYNC();
    for (i = lane; i < n; i += lanes)
        if (basic[i] >= n && basic[i] < nz)
            z[basic[i] - n] = qb[i];
    LCP_SYNC();
    *pivots_out = pivots;
    return status;
}

/* ---------------------------------------------------------------------------------- polish */
/* In-place LU with partial pivoting of the row-major m x m a (dense.pyx's own loops, used by
 * the CPU below LCP_LAPACK_MIN); returns 0 or k + 1 (a zero pivot). */
LCP_FN int lcp_lu_factor(double *a, lcp_ix m, lcp_ix *ipiv)
{
    lcp_ix i, j, k, p;
    double best, v, f, piv, *rk, *ri;
    for (k = 0; k < m; k++) {
        p = k;
        best = fabs(a[k * m + k]);
        for (i = k + 1; i < m; i++) {
            v = fabs(a[i * m + k]);
            if (v > best) {
                best = v;
                p = i;
            }
        }
        ipiv[k] = p;
        if (best == 0.0)
            return (int)(k + 1);
        if (p != k)
            for (j = 0; j < m; j++) {
                v = a[k * m + j];
                a[k * m + j] = a[p * m + j];
                a[p * m + j] = v;
            }
        rk = a + k * m;
        piv = rk[k];
        for (i = k + 1; i < m; i++) {
            ri = a + i * m;
            f = ri[k] / piv;
            ri[k] = f;
            if (f != 0.0)
                for (j = k + 1; j < m; j++)
                    ri[j] -= f * rk[j];
        }
    }
    return 0;
}

LCP_FN void lcp_lu_solve(const double *lu, lcp_ix m, const lcp_ix *ipiv, double *b)
{
    lcp_ix i, j, k;
    double s, v;
    for (k = 0; k < m; k++) {
        i = ipiv[k];
        if (i != k) {
            v = b[k];
            b[k] = b[i];
            b[i] = v;
        }
    }
    for (i = 1; i < m; i++) {
        s = b[i];
        for (j = 0; j < i; j++)
            s -= lu[i * m + j] * b[j];
        b[i] = s;
    }
    for (i = m - 1; i >= 0; i--) {
        s = b[i];
        for (j = i + 1; j < m; j++)
            s -= lu[i * m + j] * b[j];
        b[i] = s / lu[i * m + i];
    }
}

/* ||min(z, M z + q)||_inf */
LCP_FN double lcp_min_residual(const double *M, const double *q, const double *z, lcp_ix n)
{
    lcp_ix i, j;
    double w, v, worst = 0.0;
    for (i = 0; i < n; i++) {
        w = q[i];
        for (j = 0; j < n; j++)
            w += M[i * n + j] * z[j];
        v = fabs(z[i] < w ? z[i] : w);
        if (v > worst)
            worst = v;
    }
    return worst;
}

/* The CPU's LU path switches to LAPACK from this size of basis on (dense.pyx's LAPACK_MIN):
 * larger end bases are not re-solved here (RETRY: the CPU does it). */
#define LCP_LAPACK_MIN 64

/* lemke.pyx's polish: the end basis M[b, b] z_b = -q_b re-solved by LU with one refinement
 * step; out receives the better (by ||min(z, M z + q)||_inf) of max(z, 0) and the re-solve.
 * Returns 0, or -1 when the basis is too large for the loops here (out is then max(z, 0)).
 * work: 2 n^2 + 3 n doubles; iwork: 3 n. */
LCP_COLD int lcp_polish(const double *M, const double *q, lcp_ix n, const double *z,
                      const lcp_ix *basic, double *out, double *work, lcp_ix *iwork)
{
    lcp_ix i, j, k, m = 0, *idx = iwork, *mark = iwork + n, *ipiv = iwork + 2 * n;
    double *A, *lu, *x, *r, *zc;
    int finite = 1;
    for (i = 0; i < n; i++) {
        out[i] = z[i] > 0.0 ? z[i] : 0.0;
        if (basic[i] >= n && basic[i] < 2 * n)
            m += 1;
    }
    if (m == 0)
        return 0;
    if (m >= LCP_LAPACK_MIN)
        return -1;
    A = work;
    lu = A + m * m;
    x = lu + m * m;
    r = x + m;
    zc = r + m;
    for (j = 0; j < n; j++)
        mark[j] = 0;
    for (i = 0; i < n; i++)
        if (basic[i] >= n && basic[i] < 2 * n)
            mark[basic[i] - n] = 1;
    k = 0;
    for (j = 0; j < n; j++)
        if (mark[j])
            idx[k++] = j;
    for (i = 0; i < m; i++) {
        x[i] = -q[idx[i]];
        for (j = 0; j < m; j++)
            A[i * m + j] = M[idx[i] * n + idx[j]];
    }
    /* dense.pyx's solve_refined */
    for (i = 0; i < m * m; i++)
        lu[i] = A[i];
    for (i = 0; i < m; i++)
        r[i] = x[i];
    if (lcp_lu_factor(lu, m, ipiv) == 0) {
        double sum;
        lcp_lu_solve(lu, m, ipiv, x);
        for (i = 0; i < m; i++) {
            sum = 0.0;
            for (j = 0; j < m; j++)
                sum += A[i * m + j] * x[j];
            r[i] = r[i] - sum;
        }
        lcp_lu_solve(lu, m, ipiv, r);
        for (i = 0; i < m; i++)
            x[i] += r[i];
        for (j = 0; j < n; j++)
            zc[j] = 0.0;
        for (i = 0; i < m; i++) {
            if (!LCP_ISFINITE(x[i]))
                finite = 0;
            zc[idx[i]] = x[i] > 0.0 ? x[i] : 0.0;
        }
        if (finite && lcp_min_residual(M, q, zc, n) <= lcp_min_residual(M, q, out, n))
            for (j = 0; j < n; j++)
                out[j] = zc[j];
    }
    return 0;
}

/* Lemke and the certificate of one problem (lcpcli/solvers/kernels/batch.pyx's _lemke_one):
 * equilibrated first when it is not balanced (balanced < 0: never; the answer is mapped back
 * exactly and certified on the problem as given); the end basis is re-solved (polish) when
 * the answer is not certified at rounding level (`polished`).  Lanes: (0, 1, warp = 0) one
 * thread per problem; (lane, lanes, 1) a group of lanes per problem (lane 0 writes the
 * outputs).
 * tw, ti: LCP_TAB_DWORK(n), LCP_TAB_IWORK(n); rw, ri: LCP_HOT_DWORK(n), LCP_HOT_IWORK(n) (the
 * warp kernel keeps both in shared memory when they fit); cw, ci: LCP_COLD_DWORK(n),
 * LCP_COLD_IWORK(n).  stage: the certificate reads M, q, z and w from the fast workspace
 * (copied into the spent tableau's space and the hot part), and z, w are copied out at the
 * end. */
LCP_FN void lcp_lemke_one(lcp_ix n, const double *M, const double *q, const double *d,
                          lcp_i64 max_iter, double piv_tol, double tie_tol, double tol,
                          double polished, int balanced, int q_balanced, int max_rounds,
                          double *tw, lcp_ix *ti, double *rw, lcp_ix *ri, double *cw,
                          lcp_ix *ci, double *z, double *w, signed char *code, lcp_i64 *iters,
                          double *err, double *res, lcp_ix lane, lcp_ix lanes, int warp,
                          int stage)
{
    double *raw = rw, *cwork = raw + n, *zs = cwork + 5 * n, *ws = zs + n, *qs = ws + n;
    double *Ms = cw, *qsc = Ms + n * n, *ds = qsc + n, *pwork = ds + n;
    const double *Mc = M, *qc = q;
    double *zc = z, *wc = w;
    lcp_ix *ciwork = ri, *rc = ciwork + 3 * n, *piwork = ci, *ctl = ti + 4 * n + 1;
    lcp_i64 pivots = 0;
    lcp_ix i;
    const double *Mu = M, *qu = q, *du = d;
    int scaled = 0, prc = 0, status, ready = 0;
    lcp_cert cert;
    if (lane == 0) {
        *code = LCP_RETRY;
        *iters = 0;
        *err = LCP_INF;
        *res = LCP_NAN;
    }
    if (warp) { /* M into the tableau first (one coalesced pass): the balance test reads it there */
        lcp_copy_block(tw, n + 1, M, n, lane, lanes);
        ready = 1;
        LCP_SYNC();
    }
    if (balanced >= 0) {
        if (!warp) {
            scaled = lcp_balance(n, M, q, d, balanced, q_balanced, max_rounds, Ms, qsc, ds, rc);
        } else if (!lcp_balanced_warp(n, tw, n + 1, q, balanced, q_balanced, rc, rc + n, lane,
                                      lanes)) {
            if (lane == 0)
                ctl[4] = lcp_balance(n, M, q, d, balanced, q_balanced, max_rounds, Ms, qsc, ds,
                                     rc);
            LCP_SYNC();
            scaled = (int)ctl[4];
        }
    }
    if (scaled) {
        Mu = Ms;
        qu = qsc;
        du = ds;
        ready = 0;
    }
    status = lcp_lemke(n, Mu, qu, du, max_iter, piv_tol, tie_tol, raw, tw, ti, &pivots, lane,
                       lanes, warp, ready);
    if (status != LCP_OK && status != LCP_TRIVIAL)
        return; /* a ray or the iteration limit: the CPU pipeline classifies it */
    if (stage) {
        /* the tableau is spent (z is in raw, the end basis in ti): its space (n (n + 1) >= n^2
         * doubles) takes M, the hot part q, z and w, so that the certificate's passes read
         * the fast workspace (shared memory on the device), not device memory */
        lcp_copy_block(tw, n, M, n, lane, lanes);
        for (i = lane; i < n; i += lanes) {
            qs[i] = q[i];
            ws[i] = w[i];
        }
        Mc = tw;
        qc = qs;
        zc = zs;
        wc = ws;
    }
    for (i = lane; i < n; i += lanes) {
        if (scaled) /* z = D_c z~ (exact) */
            raw[i] = ldexp(raw[i], (int)rc[n + i]);
        zc[i] = (status == LCP_TRIVIAL || raw[i] < 0.0) ? 0.0 : raw[i];
    }
    LCP_SYNC();
    if (warp)
        lcp_certify_warp(n, Mc, qc, zc, 0, 0, wc, cwork, ciwork, &cert, lane, lanes);
    else
        lcp_certify(n, Mc, qc, zc, 0, 0, wc, cwork, ciwork, &cert);
    if (lane == 0) {
        *iters = pivots;
        if (status == LCP_OK && !(cert.status == 0 && cert.error <= polished)) {
            /* not at rounding level: the end basis (ti's first n) re-solved by LU with one
             * refinement step, then certified again (a rare path: lane 0 alone) */
            prc = lcp_polish(Mc, qc, n, raw, ti, zc, pwork, piwork);
            if (prc == 0)
                lcp_certify(n, Mc, qc, zc, 0, 0, wc, cwork, ciwork, &cert);
        }
        if (prc == 0) { /* else a basis the CPU re-solves with LAPACK: RETRY */
            if (cert.status == 0)
                *err = cert.error;
            *res = cert.residual;
            if (cert.status == 0 && cert.error <= tol)
                *code = LCP_SOLVED;
        }
    }
    LCP_SYNC();
    if (stage) {
        for (i = lane; i < n; i += lanes) {
            z[i] = zs[i];
            w[i] = ws[i];
        }
        LCP_SYNC(); /* the workspace is the next problem's */
    }
}

/* One problem on a group of lanes (the warp kernel's body): sh, the group's fast workspace
 * (LCP_FAST_SLOTS(n) slots: shared memory on the device), holds the tableau and hot parts;
 * cold, the cold part (LCP_COLD_SLOTS(n) slots); stage as lcp_lemke_one.  Outputs as
 * lcp_lemke_one. */
LCP_FN void lcp_lemke_group(lcp_ix n, const double *M, const double *q, const double *d,
                            lcp_i64 max_iter, double piv_tol, double tie_tol, double tol,
                            double polished, int balanced, int q_balanced, int max_rounds,
                            int stage, double *sh, double *cold, double *z, double *w,
                            signed char *code, lcp_i64 *iters, double *err, double *res,
                            lcp_ix lane, lcp_ix lanes)
{
    double *tw = sh;
    double *rw = sh + LCP_TAB_DWORK(n) + LCP_IX_SLOTS(LCP_TAB_IWORK(n), LCP_IX_PER_SLOT);
    lcp_ix *ti = (lcp_ix *)(sh + LCP_TAB_DWORK(n)), *ri = (lcp_ix *)(rw + LCP_HOT_DWORK(n));
    lcp_ix *ci = (lcp_ix *)(cold + LCP_COLD_DWORK(n));
    lcp_lemke_one(n, M, q, d, max_iter, piv_tol, tie_tol, tol, polished, balanced, q_balanced,
                  max_rounds, tw, ti, rw, ri, cold, ci, z, w, code, iters, err, res, lane, lanes,
                  1, stage);
}

/* ------------------------------------------------------------------------- projected SOR */
LCP_FN double lcp_scaled_error(const double *z, const double *w, const double *lo,
                               const double *up, lcp_ix n, double mu, double qnorm)
{
    lcp_ix i;
    double r, r2, num = 0.0, zmax = 0.0, den;
    for (i = 0; i < n; i++) {
        r = mu * (z[i] - lo[i]);
        if (w[i] < r)
            r = w[i];
        r2 = mu * (z[i] - up[i]);
        if (r2 > r)
            r = r2;
        if (fabs(r) > num)
            num = fabs(r);
        if (fabs(z[i]) > zmax)
            zmax = fabs(z[i]);
    }
    if (num == 0.0)
        return 0.0;
    den = mu * zmax + qnorm;
    if (den <= 0.0)
        return LCP_INF;
    return num / den;
}

LCP_FN double lcp_row(const double *M, const double *q, const double *z, lcp_ix n, lcp_ix i)
{
    double s = q[i];
    const double *Mi = M + i * n;
    lcp_ix j;
    for (j = 0; j < n; j++)
        s += Mi[j] * z[j];
    return s;
}

/* pgs.pyx's pgs_sweeps (dense): 0 converged, 1 limit, 2 non-finite; w: n doubles */
LCP_FN int lcp_sweeps(const double *M, const double *q, const double *diag, const double *lo,
                      const double *up, double *z, lcp_ix n, double omega, lcp_i64 max_iter,
                      double tol, double mu, double qnorm, lcp_i64 *sweeps, double *w)
{
    lcp_ix i;
    lcp_i64 it, gap = 1, next_check = 1;
    double est, zmax, r, zi, znew, wi, rc, r2, err;
    for (it = 1; it <= max_iter; it++) {
        est = 0.0;
        zmax = 0.0;
        for (i = 0; i < n; i++) {
            r = lcp_row(M, q, z, n, i);
            zi = z[i];
            znew = zi - omega * r / diag[i];
            if (znew < lo[i])
                znew = lo[i];
            if (znew > up[i])
                znew = up[i];
            z[i] = znew;
            wi = r + diag[i] * (znew - zi);
            rc = mu * (znew - lo[i]);
            if (wi < rc)
                rc = wi;
            r2 = mu * (znew - up[i]);
            if (r2 > rc)
                rc = r2;
            if (fabs(rc) > est)
                est = fabs(rc);
            if (fabs(znew) > zmax)
                zmax = fabs(znew);
        }
        if (!LCP_ISFINITE(est) || !LCP_ISFINITE(zmax)) {
            *sweeps = it;
            return 2;
        }
        if (it >= next_check && est <= 0.5 * tol * (mu * zmax + qnorm)) {
            for (i = 0; i < n; i++)
                w[i] = lcp_row(M, q, z, n, i);
            err = lcp_scaled_error(z, w, lo, up, n, mu, qnorm);
            if (err <= tol) {
                *sweeps = it;
                return 0;
            }
            gap = 2 * gap < 32 ? 2 * gap : 32;
            next_check = it + gap;
        }
    }
    *sweeps = max_iter;
    return 1;
}

/* Projected SOR from z (inside the bounds) until the certificate passes, tightening the
 * sweeps' normwise target tenfold as batch.pyx's _sor_one does.  lo_in/up_in NULL: an LCP.
 * work: LCP_SOR_DWORK(n); iwork: LCP_SOR_IWORK(n). */
LCP_FN void lcp_sor_one(lcp_ix n, const double *M, const double *q, const double *lo_in,
                        const double *up_in, double omega, lcp_i64 max_iter, double tol,
                        double *work, lcp_ix *iwork, double *z, double *w, signed char *code,
                        lcp_i64 *iters, double *err, double *res)
{
    double *diag = work, *lo = work + n, *up = work + 2 * n, *sw = work + 3 * n;
    double *cwork = work + 4 * n + 1;
    double mu = 0.0, qnorm = 0.0, rowsum, target = tol;
    lcp_ix i, j;
    lcp_i64 sweeps = 0, done = 0;
    int status;
    lcp_cert cert;
    *code = LCP_RETRY;
    *iters = 0;
    *err = LCP_INF;
    *res = LCP_NAN;
    for (i = 0; i < n; i++) {
        lo[i] = lo_in ? lo_in[i] : 0.0;
        up[i] = up_in ? up_in[i] : LCP_INF;
        diag[i] = M[i * n + i];
        if (!(diag[i] > 0.0)) {
            if (lo[i] < up[i])
                return; /* the update divides by M_ii: the full pipeline says so */
            diag[i] = 1.0;
        }
        rowsum = 0.0;
        for (j = 0; j < n; j++)
            rowsum = rowsum + fabs(M[i * n + j]);
        if (rowsum > mu)
            mu = rowsum;
        if (fabs(q[i]) > qnorm)
            qnorm = fabs(q[i]);
    }
    if (mu == 0.0)
        mu = 1.0;
    for (;;) {
        status = lcp_sweeps(M, q, diag, lo, up, z, n, omega, max_iter - sweeps, target, mu,
                            qnorm, &done, sw);
        sweeps = sweeps + done;
        if (status != 0 && sweeps < max_iter)
            break;
        lcp_certify(n, M, q, z, lo_in, up_in, w, cwork, iwork, &cert);
        if (cert.status == 0) {
            *err = cert.error;
            *res = cert.residual;
        }
        if (cert.status == 0 && cert.error <= tol) {
            *code = LCP_SOLVED;
            break;
        }
        if (status != 0 || sweeps >= max_iter || target < 1e-15)
            break;
        target = target * 0.1;
    }
    *iters = sweeps;
}

/* -------------------------------------------------------------------- device entry points */
#if defined(__CUDACC_RTC__) || defined(__CUDACC__)
/* One thread per problem; grid-stride loop over the K problems; slot = the thread's global
 * index (its workspace).  Arrays: M (K, n, n), q, z, w (K, n), row-major.  use_d: d (n) is
 * the covering vector (else ones and d is not read).  iwork: LCP_LEMKE_IWORK(n) 8-byte slots
 * per thread (the device uses the first half of each as 32-bit lcp_ix). */
extern "C" __global__ void lcp_lemke_stack(
    lcp_i64 K, lcp_i64 n, const double *M, const double *q, int use_d, const double *d,
    lcp_i64 max_iter, double piv_tol, double tie_tol, double tol, double polished, int balanced,
    int q_balanced, int max_rounds, double *work, lcp_i64 *iwork, double *z, double *w,
    signed char *code, lcp_i64 *iters, double *err, double *res)
{
    lcp_i64 slot = (lcp_i64)blockIdx.x * blockDim.x + threadIdx.x;
    lcp_i64 stride = (lcp_i64)gridDim.x * blockDim.x, k;
    double *tw = work + slot * LCP_LEMKE_DWORK(n);
    lcp_ix *ti = (lcp_ix *)(iwork + slot * LCP_LEMKE_IWORK(n));
    for (k = slot; k < K; k += stride)
        lcp_lemke_one(n, M + k * n * n, q + k * n, use_d ? d : 0, max_iter, piv_tol, tie_tol,
                      tol, polished, balanced, q_balanced, max_rounds, tw, ti,
                      tw + LCP_TAB_DWORK(n), ti + LCP_TAB_IWORK(n),
                      tw + LCP_TAB_DWORK(n) + LCP_HOT_DWORK(n),
                      ti + LCP_TAB_IWORK(n) + LCP_HOT_IWORK(n), z + k * n, w + k * n, code + k,
                      iters + k, err + k, res + k, 0, 1, 0, 0);
}

/* A group of `lanes` lanes per problem (8, 16 or 32, dividing blockDim.x; every lane of a
 * group takes part; several groups share a warp when lanes < 32).  work: LCP_FAST_SLOTS(n) +
 * LCP_COLD_SLOTS(n) slots per group of the grid; use_shared: each group's fast part in
 * dynamic shared memory instead (blockDim.x / lanes * 8 * LCP_FAST_SLOTS(n) bytes); stage:
 * the certificate reads M, q, z, w from the fast part (lcp_lemke_one). */
/* LCP_WARP_MIN_BLOCKS: blocks of 256 threads the compiler must fit on one multiprocessor (its
 * register budget); an NVRTC -D option (EXTRA_OPTIONS in backends/cuda.py), speed only. */
#ifndef LCP_WARP_MIN_BLOCKS
#define LCP_WARP_MIN_BLOCKS 1
#endif
extern "C" __global__ void __launch_bounds__(256, LCP_WARP_MIN_BLOCKS) lcp_lemke_warp_stack(
    lcp_i64 K, lcp_i64 n, const double *M, const double *q, int use_d, const double *d,
    lcp_i64 max_iter, double piv_tol, double tie_tol, double tol, double polished, int balanced,
    int q_balanced, int max_rounds, int lanes, int use_shared, int stage, double *work,
    double *z, double *w, signed char *code, lcp_i64 *iters, double *err, double *res)
{
    extern __shared__ double lcp_smem[];
    lcp_ix lane = threadIdx.x & (lanes - 1), grp = threadIdx.x / lanes, gpb = blockDim.x / lanes;
    lcp_i64 slot = (lcp_i64)blockIdx.x * gpb + grp, nslots = (lcp_i64)gridDim.x * gpb, k;
    lcp_i64 fast = LCP_FAST_SLOTS(n), per = fast + LCP_COLD_SLOTS(n);
    double *gw = work + slot * per;
    /* two copies of the loop: in the first the fast workspace is known to be shared memory
     * (the compiler then reads and writes it with shared-memory instructions and 32-bit
     * addresses), in the second it is device memory; one pointer for both would be generic */
    if (use_shared) {
        double *sh = lcp_smem + grp * fast;
        for (k = slot; k < K; k += nslots)
            lcp_lemke_group(n, M + k * n * n, q + k * n, use_d ? d : 0, max_iter, piv_tol,
                            tie_tol, tol, polished, balanced, q_balanced, max_rounds, stage, sh,
                            gw + fast, z + k * n, w + k * n, code + k, iters + k, err + k,
                            res + k, lane, lanes);
    } else {
        for (k = slot; k < K; k += nslots)
            lcp_lemke_group(n, M + k * n * n, q + k * n, use_d ? d : 0, max_iter, piv_tol,
                            tie_tol, tol, polished, balanced, q_balanced, max_rounds, stage, gw,
                            gw + fast, z + k * n, w + k * n, code + k, iters + k, err + k,
                            res + k, lane, lanes);
    }
}

/* bounded: lo, up (K, n) are the box (else an LCP: they are not read); z: the start points */
extern "C" __global__ void lcp_sor_stack(
    lcp_i64 K, lcp_i64 n, const double *M, const double *q, int bounded, const double *lo,
    const double *up, double omega, lcp_i64 max_iter, double tol, double *work, lcp_i64 *iwork,
    double *z, double *w, signed char *code, lcp_i64 *iters, double *err, double *res)
{
    lcp_i64 slot = (lcp_i64)blockIdx.x * blockDim.x + threadIdx.x;
    lcp_i64 stride = (lcp_i64)gridDim.x * blockDim.x, k;
    for (k = slot; k < K; k += stride)
        lcp_sor_one(n, M + k * n * n, q + k * n, bounded ? lo + k * n : 0,
                    bounded ? up + k * n : 0, omega, max_iter, tol,
                    work + slot * LCP_SOR_DWORK(n), (lcp_ix *)(iwork + slot * LCP_SOR_IWORK(n)),
                    z + k * n, w + k * n, code + k, iters + k, err + k, res + k);
}
#endif

#endif /* LCPCLI_LCP_STACK_H */
