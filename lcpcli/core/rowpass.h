/* The certificate's loops over dense rows (pass 1, the column maxima) and over the pairs and
 * blocks (an LCP's pair scores, the blocks' growth and the error), compiled twice where the
 * toolchain allows (GCC on x86-64 glibc: AVX2 and the baseline SSE2, picked at load time by the
 * CPU), as in lcpcli/solvers/kernels/simd.h.  No FMA in either clone, a fixed summation order,
 * and selects in place of the branches of _certificate.pyx's scalar loops (the same operations
 * on the same values; only maxima and minima, exact in any order, are combined across lanes),
 * so the certificate's numbers do not depend on the CPU or on which loop scored them. */
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
typedef long long lcpcli_v4l __attribute__((vector_size(32)));
typedef signed char lcpcli_v4c __attribute__((vector_size(4)));
/* the lanes of x where m (a comparison's result: all ones or zero), else those of y */
#define LCPCLI_SEL(m, x, y) ((lcpcli_v4d)(((lcpcli_v4l)(m) & (lcpcli_v4l)(x)) \
                                          | (~(lcpcli_v4l)(m) & (lcpcli_v4l)(y))))
#define LCPCLI_VMAX(t, acc) LCPCLI_SEL((t) > (acc), (t), (acc))
#define LCPCLI_VABS(x) ((lcpcli_v4d)((lcpcli_v4l)(x) & (lcpcli_v4l)lcpcli_v4_nosign))
static const lcpcli_v4u lcpcli_v4_nosign = {0x7fffffffffffffffULL, 0x7fffffffffffffffULL,
                                            0x7fffffffffffffffULL, 0x7fffffffffffffffULL};
#endif

/* dot = sum_j row_j z_j and absdot = sum_j |row_j z_j|, four partial sums each (lane k takes
 * j = k mod 4, the tail goes to lane 0), combined as (s0 + s1) + (s2 + s3); with GCC or clang
 * the four lanes are one vector (the compiler's own vectorisation of this loop interleaved the
 * lanes badly: 3x slower), in the same order, so both give the same bits */
#if defined(__GNUC__)
#define LCPCLI_INLINE static inline __attribute__((always_inline))
#else
#define LCPCLI_INLINE static inline
#endif

LCPCLI_INLINE void lcpcli_row_dot(const double *restrict row, const double *restrict z,
                                  ptrdiff_t n, double *dot, double *absdot)
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

/* Pass 1 of the certificate over the n rows of M (row stride ldm), in one call:
 * w_i = (sum_j M_ij z_j) + q_i, a_i = sum_j |M_ij z_j|, s_i = a_i + |q_i|, rinv_i = 1 / s_i
 * (inf when s_i = 0) */
LCPCLI_ROW_CLONES static void lcpcli_rows_pass(const double *restrict M, ptrdiff_t ldm,
                                               const double *restrict z,
                                               const double *restrict q, ptrdiff_t n,
                                               double *restrict w, double *restrict a,
                                               double *restrict s, double *restrict rinv)
{
    ptrdiff_t i = 0;
#if defined(__GNUC__) && !defined(__clang__)
    /* four rows at a time: each row's four lanes as lcpcli_row_dot forms them, then the four
     * rows' lanes transposed so that (s0 + s1) + (s2 + s3) is one vector sum for the four */
    const lcpcli_v4u nosign = {0x7fffffffffffffffULL, 0x7fffffffffffffffULL,
                               0x7fffffffffffffffULL, 0x7fffffffffffffffULL};
    const lcpcli_v4l lo = {0, 4, 2, 6}, hi = {1, 5, 3, 7}, first = {0, 1, 4, 5},
                     second = {2, 3, 6, 7};
    for (; i + 4 <= n; i += 4) {
        lcpcli_v4d vs[4], va[4], x, y, t, q4, c0, c1, c2, c3, d0, d1, d2, d3, dot, absdot;
        ptrdiff_t j = 0;
        for (int r = 0; r < 4; r++) {
            vs[r] = (lcpcli_v4d){0.0, 0.0, 0.0, 0.0};
            va[r] = vs[r];
        }
        for (; j + 4 <= n; j += 4) {
            __builtin_memcpy(&y, z + j, sizeof y);
            for (int r = 0; r < 4; r++) {
                __builtin_memcpy(&x, M + (i + r) * ldm + j, sizeof x);
                t = x * y;
                vs[r] += t;
                va[r] += (lcpcli_v4d)((lcpcli_v4u)t & nosign);
            }
        }
        for (; j < n; j++)  /* the tail to lane 0, in order */
            for (int r = 0; r < 4; r++) {
                double tt = M[(i + r) * ldm + j] * z[j];
                vs[r][0] += tt;
                va[r][0] += fabs(tt);
            }
        c0 = __builtin_shuffle(vs[0], vs[1], lo);    /* (s0 of row 0, of row 1, s2, s2) */
        c1 = __builtin_shuffle(vs[0], vs[1], hi);
        c2 = __builtin_shuffle(vs[2], vs[3], lo);
        c3 = __builtin_shuffle(vs[2], vs[3], hi);
        d0 = __builtin_shuffle(c0, c2, first);       /* lane 0 of the four rows */
        d2 = __builtin_shuffle(c0, c2, second);      /* lane 2 */
        d1 = __builtin_shuffle(c1, c3, first);
        d3 = __builtin_shuffle(c1, c3, second);
        dot = (d0 + d1) + (d2 + d3);
        c0 = __builtin_shuffle(va[0], va[1], lo);
        c1 = __builtin_shuffle(va[0], va[1], hi);
        c2 = __builtin_shuffle(va[2], va[3], lo);
        c3 = __builtin_shuffle(va[2], va[3], hi);
        d0 = __builtin_shuffle(c0, c2, first);
        d2 = __builtin_shuffle(c0, c2, second);
        d1 = __builtin_shuffle(c1, c3, first);
        d3 = __builtin_shuffle(c1, c3, second);
        absdot = (d0 + d1) + (d2 + d3);
        __builtin_memcpy(&q4, q + i, sizeof q4);
        t = dot + q4;
        __builtin_memcpy(w + i, &t, sizeof t);
        __builtin_memcpy(a + i, &absdot, sizeof absdot);
        t = absdot + (lcpcli_v4d)((lcpcli_v4u)q4 & nosign);
        __builtin_memcpy(s + i, &t, sizeof t);
        t = 1.0 / t;
        __builtin_memcpy(rinv + i, &t, sizeof t);
    }
#endif
    for (; i < n; i++) {
        double dot, absdot;
        lcpcli_row_dot(M + i * ldm, z, n, &dot, &absdot);
        w[i] = dot + q[i];
        a[i] = absdot;
        s[i] = absdot + fabs(q[i]);
        rinv[i] = 1.0 / s[i];
    }
}

/* kappa_j = max_i |M_ij| inv_i over the n rows (inv_i = 1 / s_i: inf when s_i = 0, so that
 * kappa_j = inf where such a row has M_ij != 0, and 0 x inf = NaN never wins a comparison), in
 * one call; four columns at a time, their maxima kept in registers down the rows (a maximum does
 * not depend on the order) */
LCPCLI_ROW_CLONES static void lcpcli_col_maxes(const double *restrict M, ptrdiff_t ldm,
                                               const double *restrict inv, ptrdiff_t n,
                                               double *restrict kappa)
{
    ptrdiff_t j = 0;
#if defined(__GNUC__)
    const lcpcli_v4d zero = {0.0, 0.0, 0.0, 0.0};
    for (; j + 4 <= n; j += 4) {
        lcpcli_v4d acc = zero, x;
        for (ptrdiff_t i = 0; i < n; i++) {
            __builtin_memcpy(&x, M + i * ldm + j, sizeof x);
            x = LCPCLI_VABS(x) * inv[i];
            acc = LCPCLI_VMAX(x, acc);
        }
        __builtin_memcpy(kappa + j, &acc, sizeof acc);
    }
#endif
    for (; j < n; j++) {
        double acc = 0.0;
        for (ptrdiff_t i = 0; i < n; i++) {
            double t = fabs(M[i * ldm + j]) * inv[i];
            acc = t > acc ? t : acc;
        }
        kappa[j] = acc;
    }
}

/* The pairs of an LCP (l_i = 0, u_i = inf) scored as _certificate.pyx's _finish scores any pair
 * (the same operations on the same values, so the same bits), without a branch on the data:
 * the costs of the states L (z_i = 0) and F (w_i = 0), the cheaper one (ties to the state that
 * needs no move of z_i), written to eps (over kappa), state (may be NULL) and anchor (1: F);
 * acc = {omega, residual, bound violation, w violation, complementarity}, maxima updated */
LCPCLI_ROW_CLONES static void lcpcli_lcp_pairs(ptrdiff_t n, const double *restrict z,
                                               const double *restrict w,
                                               const double *restrict s,
                                               double *restrict kappa,
                                               signed char *restrict state,
                                               ptrdiff_t *restrict anchor, double *restrict acc)
{
    double omega = acc[0], resid = acc[1], bviol = acc[2], wviol = acc[3], comp = acc[4];
    ptrdiff_t i = 0;
#if defined(__GNUC__)
    /* four pairs at a time, each lane as the scalar loop below (selects for its branches);
     * the lanes' maxima are combined exactly at the end */
    const lcpcli_v4d zero = {0.0, 0.0, 0.0, 0.0};
    lcpcli_v4d vom = zero, vre = zero, vbv = zero, vwv = zero, vco = zero;
    for (; i + 4 <= n; i += 4) {
        lcpcli_v4d zi, wi, si, k, aw, az, rel, t, cF, cL, best;
        lcpcli_v4l pickF;
        __builtin_memcpy(&zi, z + i, sizeof zi);
        __builtin_memcpy(&wi, w + i, sizeof wi);
        __builtin_memcpy(&si, s + i, sizeof si);
        __builtin_memcpy(&k, kappa + i, sizeof k);
        aw = LCPCLI_VABS(wi);
        az = LCPCLI_VABS(zi);
        rel = LCPCLI_SEL(aw == zero, zero, aw / si);
        t = LCPCLI_SEL(zi < zero, zero - zi, zero);
        t = LCPCLI_SEL(t == zero, zero, t * k);
        cF = LCPCLI_VMAX(t, rel);
        cL = LCPCLI_SEL(wi < zero, rel, zero);
        t = LCPCLI_SEL(az == zero, zero, az * k);
        cL = LCPCLI_VMAX(t, cL);
        pickF = (lcpcli_v4l)LCPCLI_SEL(zi == zero, (lcpcli_v4d)(cF < cL),
                                       (lcpcli_v4d)(~(cL < cF)));
        best = LCPCLI_SEL(pickF, cF, cL);
        __builtin_memcpy(kappa + i, &best, sizeof best);
        if (state) {
            lcpcli_v4c st = __builtin_convertvector(pickF & 2, lcpcli_v4c);
            __builtin_memcpy(state + i, &st, sizeof st);
        }
        pickF &= 1;
        __builtin_memcpy(anchor + i, &pickF, sizeof pickF);
        vom = LCPCLI_VMAX(best, vom);
        t = LCPCLI_VABS(LCPCLI_SEL(wi < zi, wi, zi));
        vre = LCPCLI_VMAX(t, vre);
        t = zero - zi;
        vbv = LCPCLI_VMAX(t, vbv);
        t = -wi;
        vwv = LCPCLI_VMAX(t, vwv);
        t = LCPCLI_VABS(zi * wi);
        vco = LCPCLI_VMAX(t, vco);
    }
    for (int l = 0; l < 4; l++) {
        omega = vom[l] > omega ? vom[l] : omega;
        resid = vre[l] > resid ? vre[l] : resid;
        bviol = vbv[l] > bviol ? vbv[l] : bviol;
        wviol = vwv[l] > wviol ? vwv[l] : wviol;
        comp = vco[l] > comp ? vco[l] : comp;
    }
#endif
    for (; i < n; i++) {
        double zi = z[i], wi = w[i], k = kappa[i], aw = fabs(wi), az = fabs(zi);
        double rel = aw == 0.0 ? 0.0 : aw / s[i];   /* _rel(|w_i|, s_i): v / 0 = inf */
        double x = zi < 0.0 ? 0.0 - zi : 0.0;       /* back into the box */
        double t = x == 0.0 ? 0.0 : x * k;          /* _move: a zero move costs 0 */
        double cF = t > rel ? t : rel;
        double cL = wi < 0.0 ? rel : 0.0;           /* _rel(-w_i, s_i) when w_i < 0 */
        t = az == 0.0 ? 0.0 : az * k;               /* the move to z_i = 0 */
        cL = t > cL ? t : cL;
        int pickF = zi == 0.0 ? cF < cL : !(cL < cF);
        double best = pickF ? cF : cL;
        if (state)
            state[i] = pickF ? 2 : 0;
        anchor[i] = pickF;
        kappa[i] = best;
        omega = best > omega ? best : omega;
        t = wi < zi ? wi : zi;                      /* mid(z - l, z - u, w) = min(z, w) */
        t = fabs(t);
        resid = t > resid ? t : resid;
        t = 0.0 - zi;
        bviol = t > bviol ? t : bviol;
        t = -wi;
        wviol = t > wviol ? t : wviol;
        t = fabs(zi * wi);
        comp = t > comp ? t : comp;
    }
    acc[0] = omega;
    acc[1] = resid;
    acc[2] = bviol;
    acc[3] = wviol;
    acc[4] = comp;
}

/* Steps (b) and (c) of _certificate.pyx's _finish, without a branch on the data: each block's
 * growth G (the smallest g_i = a_i / (|q_i| + |w_i|) among its equations with data: anchor_i,
 * a_i > 0, q_i != 0; inf when none), then error = max_i eps_i max(1, G_i), where a row with
 * a_i > 0 in a block without such an equation takes its own g_i when q_i != 0 (else 1), and a row
 * with a_i = 0 takes 1.  root[i] < n: the smallest row of row i's block.  Scratch: g, gi, e (n
 * doubles each; e first holds the blocks' minima by root when there are several blocks).
 * res = {error, growth}; worst: the first row that decides the error (where it is largest). */
LCPCLI_ROW_CLONES static void lcpcli_block_error(ptrdiff_t n, const double *restrict q,
                                                 const double *restrict w,
                                                 const double *restrict a,
                                                 const double *restrict eps,
                                                 const ptrdiff_t *restrict anchor,
                                                 const ptrdiff_t *restrict root,
                                                 double *restrict g, double *restrict gi,
                                                 double *restrict e, double *restrict res,
                                                 ptrdiff_t *worst)
{
    ptrdiff_t several = 0, i = 0;
    double G = INFINITY, err = 0.0;   /* G: the smallest g_i, the growth of a single block */
#if defined(__GNUC__)
    const lcpcli_v4d zero = {0.0, 0.0, 0.0, 0.0}, one = {1.0, 1.0, 1.0, 1.0},
                     inf = {INFINITY, INFINITY, INFINITY, INFINITY};
    const lcpcli_v4l none = {0, 0, 0, 0};
    lcpcli_v4d vG = inf, verr = zero;
    for (; i + 4 <= n; i += 4) {  /* four rows at a time, as the scalar loop below */
        lcpcli_v4d qi, wi, ai, r;
        lcpcli_v4l an;
        __builtin_memcpy(&qi, q + i, sizeof qi);
        __builtin_memcpy(&wi, w + i, sizeof wi);
        __builtin_memcpy(&ai, a + i, sizeof ai);
        __builtin_memcpy(&an, anchor + i, sizeof an);
        r = ai / (LCPCLI_VABS(qi) + LCPCLI_VABS(wi));
        r = LCPCLI_SEL(qi != zero, r, one);
        __builtin_memcpy(gi + i, &r, sizeof r);
        r = LCPCLI_SEL((ai > zero) & (an != none) & (qi != zero), r, inf);
        __builtin_memcpy(g + i, &r, sizeof r);
        vG = LCPCLI_SEL(r < vG, r, vG);
    }
    for (int l = 0; l < 4; l++)  /* (a minimum does not depend on the order) */
        G = vG[l] < G ? vG[l] : G;
#endif
    for (; i < n; i++) {
        double r = a[i] / (fabs(q[i]) + fabs(w[i]));   /* read only where q_i != 0 */
        gi[i] = q[i] != 0.0 ? r : 1.0;                  /* the row's own growth */
        g[i] = (a[i] > 0.0) & (anchor[i] != 0) & (q[i] != 0.0) ? r : INFINITY;
        G = g[i] < G ? g[i] : G;
    }
    for (i = 0; i < n; i++)
        several |= root[i] ^ root[0];
    if (several) {  /* each block's smallest g_i, by its root, for each of its rows */
        double *blk = e;
        for (i = 0; i < n; i++)
            blk[i] = INFINITY;
        for (i = 0; i < n; i++)
            blk[root[i]] = g[i] < blk[root[i]] ? g[i] : blk[root[i]];
        for (i = 0; i < n; i++)
            g[i] = blk[root[i]];
    }
    i = 0;
#if defined(__GNUC__)
    const lcpcli_v4d vone_block = {G, G, G, G};
    const lcpcli_v4l all = {-1, -1, -1, -1};
    const lcpcli_v4l by_block = several ? all : none;
    for (; i + 4 <= n; i += 4) {
        lcpcli_v4d gb, own, ai, ep, t;
        __builtin_memcpy(&gb, g + i, sizeof gb);
        gb = LCPCLI_SEL(by_block, gb, vone_block);
        __builtin_memcpy(&own, gi + i, sizeof own);
        __builtin_memcpy(&ai, a + i, sizeof ai);
        __builtin_memcpy(&ep, eps + i, sizeof ep);
        t = LCPCLI_SEL(gb == inf, own, gb);
        t = LCPCLI_SEL(t < one, one, t);
        t = LCPCLI_SEL(ai > zero, t, one);
        __builtin_memcpy(gi + i, &t, sizeof t);
        t = LCPCLI_SEL(ep == zero, zero, ep * t);
        __builtin_memcpy(e + i, &t, sizeof t);
        verr = LCPCLI_VMAX(t, verr);
    }
    for (int l = 0; l < 4; l++)  /* (nor does a maximum) */
        err = verr[l] > err ? verr[l] : err;
#endif
    for (; i < n; i++) {
        double t = several ? g[i] : G;
        t = t == INFINITY ? gi[i] : t;
        t = t < 1.0 ? 1.0 : t;
        t = a[i] > 0.0 ? t : 1.0;
        gi[i] = t;
        e[i] = eps[i] == 0.0 ? 0.0 : eps[i] * t;
        err = e[i] > err ? e[i] : err;
    }
    ptrdiff_t first = n;  /* the first row where the error is largest (selects, no exit test) */
    for (i = n - 1; i >= 0; i--)
        first = e[i] == err ? i : first;
    res[0] = err;
    res[1] = first < n ? gi[first] : 1.0;
    *worst = first < n ? first : -1;
}

#endif
