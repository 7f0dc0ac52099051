/* Single-source stacked kernels: Lemke (lexicographic ratio test) and projected SOR, each
 * followed by the project's componentwise certificate, for ONE problem of a stack.
 *
 * The same text is compiled twice:
 *   - by the C compiler, for the CPU: lcpcli/solvers/kernels/stack_c.pyx (`cdef extern`), so the
 *     test suite (which never has a GPU) checks this code against lcpcli.solve_many;
 *   - by NVRTC through CuPy (lcpcli/solvers/backends/cuda.py), for the device: the __global__
 *     kernels at the end (one thread per problem, grid-stride loop) call the same functions.
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
#define LCP_INF __longlong_as_double(0x7ff0000000000000LL)
#define LCP_NAN __longlong_as_double(0x7ff8000000000000LL)
#define LCP_ISFINITE(x) isfinite(x)
#define LCP_AXPY(y, x, a, n)                                                                 \
    do {                                                                                     \
        for (lcp_i64 j_ = 0; j_ < (n); j_++)                                                 \
            (y)[j_] += (a) * (x)[j_];                                                        \
    } while (0)
#else
#include <math.h>
#include <string.h>
/* the CPU build shares the CPU kernels' vector loop (AVX2 and baseline clones, no FMA: the
 * same rounding as the plain loop the device runs) */
#include "../simd.h"
#define LCP_AXPY(y, x, a, n) lcpcli_axpy((y), (x), (a), (n))
#define LCP_FN static inline
#define LCP_INF INFINITY
#define LCP_NAN NAN
#define LCP_ISFINITE(x) isfinite(x)
#endif

typedef long long lcp_i64;

enum { LCP_SOLVED = 0, LCP_RETRY = 1 };
enum { LCP_OK = 0, LCP_RAY = 1, LCP_MAX_ITER = 2, LCP_TRIVIAL = 3 };

/* tolerances of lemke.pyx (DEGENERATE_RTOL, LEX_RTOL) and _certificate.pyx (THETA, 2^+-960) */
#define LCP_DEGENERATE_RTOL 1e-13
#define LCP_LEX_RTOL 1e-10
#define LCP_THETA 0.0009765625

/* workspace per problem (doubles, then long longs) */
#define LCP_CERT_DWORK(n) (5 * (n))
#define LCP_CERT_IWORK(n) (3 * (n))
#define LCP_LEMKE_DWORK(n) ((n) * ((n) + 1) + 5 * (n) + 1 + LCP_CERT_DWORK(n) + (n) * (n) + 2 * (n) \
                            + 2 * (n) * (n) + 3 * (n))
#define LCP_LEMKE_IWORK(n) (5 * (n) + 2 + LCP_CERT_IWORK(n) + 4 * (n) + 3 * (n))
#define LCP_SOR_DWORK(n) (4 * (n) + 1 + LCP_CERT_DWORK(n))
#define LCP_SOR_IWORK(n) (LCP_CERT_IWORK(n))

LCP_FN double lcp_big(void) { return ldexp(1.0, 960); }
LCP_FN double lcp_small(void) { return ldexp(1.0, -960); }

/* ------------------------------------------------------------------------------ certificate */
typedef struct {
    double error, residual;
    int status; /* 0 ok, 1 non-finite z or w, 2 out of range (the CPU rescales: RETRY here) */
} lcp_cert;

LCP_FN lcp_i64 lcp_find(lcp_i64 *parent, lcp_i64 x)
{
    while (parent[x] != x) {
        parent[x] = parent[parent[x]];
        x = parent[x];
    }
    return x;
}

LCP_FN void lcp_union(lcp_i64 *parent, lcp_i64 a, lcp_i64 b)
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

LCP_FN void lcp_bounds(lcp_i64 i, const double *lo, const double *up, double *l, double *u)
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
LCP_FN void lcp_row_dot(const double *row, const double *z, lcp_i64 n, double *dot,
                        double *absdot)
{
    double s0 = 0.0, s1 = 0.0, s2 = 0.0, s3 = 0.0, a0 = 0.0, a1 = 0.0, a2 = 0.0, a3 = 0.0;
    double t0, t1, t2, t3;
    lcp_i64 j = 0;
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

/* The certificate of z for the LCP (lo == NULL: z >= 0) or box LCP [lo, up] with dense
 * row-major M (n x n): lcpcli/core/_certificate.pyx's certify_dense with n_eq = 0, field for
 * field (error and residual kept).  w (n) receives M z + q; work: LCP_CERT_DWORK(n) doubles,
 * iwork: LCP_CERT_IWORK(n).  Returns out->status. */
LCP_FN int lcp_certify(lcp_i64 n, const double *M, const double *q, const double *z,
                       const double *lo, const double *up, double *w, double *work,
                       lcp_i64 *iwork, lcp_cert *out)
{
    double *a = work, *s = work + n, *kappa = work + 2 * n, *compmin = work + 3 * n;
    lcp_i64 *parent = iwork, *cols = iwork + 2 * n, *anchor = iwork + 2 * n;
    lcp_i64 i, j, k, nc = 0, r, worst = -1;
    const double *row;
    double wi, ai, t, m, inv, BIG = lcp_big(), SMALL = lcp_small();
    double l, u, zi, si, best, x, g, den, e, err = 0.0, gi, cF, cL, cU, resid = 0.0;
    int st;
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
    /* pass 3 (a): every pair's backward error (anchor reuses cols: cols is not needed now) */
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
    /* (b) each block's growth: the smallest growth among its equations */
    for (i = 0; i < 2 * n; i++)
        compmin[i] = LCP_INF;
    for (i = 0; i < n; i++) {
        if (a[i] > 0.0 && anchor[i]) {
            den = fabs(q[i]) + fabs(w[i]);
            g = den == 0.0 ? LCP_INF : a[i] / den;
            r = lcp_find(parent, i);
            if (g < compmin[r])
                compmin[r] = g;
        }
    }
    /* (c) the certified error: max_i eps_i max(1, G_i) */
    for (i = 0; i < n; i++) {
        best = kappa[i];
        gi = 1.0;
        if (a[i] > 0.0) {
            gi = compmin[lcp_find(parent, i)];
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

/* -------------------------------------------------------------------------- equilibration */
/* frexp's exponent of x != 0, finite, read from the IEEE-754 bits (subnormals: frexp) */
LCP_FN lcp_i64 lcp_exp(double x)
{
    unsigned long long bits;
    lcp_i64 field;
    int e;
#if defined(__CUDACC_RTC__) || defined(__CUDACC__)
    bits = (unsigned long long)__double_as_longlong(x);
#else
    memcpy(&bits, &x, 8);
#endif
    field = (lcp_i64)((bits >> 52) & 0x7ff);
    if (field == 0) {
        frexp(x, &e);
        return e;
    }
    return field - 1022;
}

LCP_FN lcp_i64 lcp_floordiv2(lcp_i64 x) { return x >= 0 ? x / 2 : -((-x + 1) / 2); }

#define LCP_FLOOR (-((lcp_i64)1 << 40))

/* row and column maxima of the exponents of D_r M D_c over the nonzeros (_scaling.pyx) */
LCP_FN void lcp_maxima(lcp_i64 n, const double *M, const lcp_i64 *r, const lcp_i64 *c,
                       lcp_i64 *rmax, lcp_i64 *cmax)
{
    lcp_i64 i, j, e;
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
LCP_FN int lcp_ruiz(lcp_i64 n, const double *M, const double *q, int symmetric, int balanced,
                    int q_balanced, int max_rounds, lcp_i64 *r, lcp_i64 *c, lcp_i64 *rmax,
                    lcp_i64 *cmax)
{
    lcp_i64 i, j, k, e, lo, hi, clo, chi, d, qexp;
    int rnd;
    for (i = 0; i < n; i++) {
        r[i] = 0;
        c[i] = 0;
    }
    for (rnd = 0; rnd < max_rounds; rnd++) {
        lcp_maxima(n, M, r, c, rmax, cmax);
        lo = (lcp_i64)1 << 40;
        hi = -((lcp_i64)1 << 40);
        clo = (lcp_i64)1 << 40;
        chi = -((lcp_i64)1 << 40);
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

LCP_FN int lcp_symmetric(const double *M, lcp_i64 n)
{
    lcp_i64 i, j;
    for (i = 0; i < n; i++)
        for (j = 0; j < i; j++)
            if (M[i * n + j] != M[j * n + i])
                return 0;
    return 1;
}

/* Equilibrate one problem as batch.pyx's _balance does (D M D for a symmetric M, two-sided
 * otherwise): fill Ms = D_r M D_c, qs = D_r q, ds = D_r d (ones when d is NULL) and return 1,
 * or return 0 when the problem is balanced already.  rc: 4 n long longs (r, c, scratch). */
LCP_FN int lcp_balance(lcp_i64 n, const double *M, const double *q, const double *d,
                       int balanced, int q_balanced, int max_rounds, double *Ms, double *qs,
                       double *ds, lcp_i64 *rc)
{
    lcp_i64 i, j, *r = rc, *c = rc + n;
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

/* ---------------------------------------------------------------------------------- Lemke */
/* pivot the nrows x ncols tableau on (r, c); rowr: ncols of work (lemke.pyx's pivot) */
LCP_FN void lcp_pivot(double *T, double *qb, lcp_i64 nrows, lcp_i64 ncols, lcp_i64 r,
                      lcp_i64 c, double *rowr)
{
    lcp_i64 i, j;
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

/* Lemke's method (condensed tableau, covering vector d, lexicographic minimum-ratio rule:
 * Cottle-Pang-Stone, The Linear Complementarity Problem, 4.4-4.9) on one problem, as
 * lemke.pyx's lemke_tableau.  z (n) receives the basic solution; returns the status
 * (LCP_OK, LCP_RAY, LCP_MAX_ITER, LCP_TRIVIAL) and the pivots in *pivots_out.
 * work: n (n + 1) + 4 n + 1 doubles; iwork: 5 n + 2 long longs. */
LCP_FN int lcp_lemke(lcp_i64 n, const double *M, const double *q, const double *d,
                     lcp_i64 max_iter, double piv_tol, double tie_tol, double *z,
                     double *work, lcp_i64 *iwork, lcp_i64 *pivots_out)
{
    lcp_i64 m = n + 1, nz = 2 * n;
    lcp_i64 i, j, k, s, r, c, nc, z0_row, entering, leaving, pivots, loc, mm;
    int status;
    double *T = work, *qb = T + n * m, *keys = qb + n, *col = keys + n, *rowr = col + n;
    lcp_i64 *basic = iwork, *where = basic + n, *cand = where + 2 * n + 1;
    double v, best, cmax, qmax, ptol, ztol, tmin, a, t, unit, key, kmin, kmax, bound;
    for (i = 0; i < n; i++) {
        for (j = 0; j < n; j++)
            T[i * m + j] = M[i * n + j];
        T[i * m + n] = d ? d[i] : 1.0;
        qb[i] = q[i];
        basic[i] = i;
        where[i] = i;
        z[i] = 0.0;
    }
    for (j = 0; j < m; j++)
        where[n + j] = -(j + 1);
    *pivots_out = 0;
    /* initial pivot: z0 enters, the row with the most negative q_i / d_i leaves (ties: the
     * largest index) */
    best = 0.0;
    for (i = 0; i < n; i++) {
        v = q[i] / (d ? d[i] : 1.0);
        if (v < best)
            best = v;
    }
    if (best >= 0.0)
        return LCP_TRIVIAL;
    r = -1;
    for (i = 0; i < n; i++)
        if (q[i] / (d ? d[i] : 1.0) <= best + tie_tol * fabs(best))
            r = i;
    entering = nz;
    c = n;
    leaving = basic[r];
    lcp_pivot(T, qb, n, m, r, c, rowr);
    basic[r] = entering;
    where[entering] = r;
    where[leaving] = -(c + 1);
    pivots = 1;
    status = LCP_MAX_ITER;
    while (pivots < max_iter) {
        entering = leaving < n ? leaving + n : leaving - n;
        c = -where[entering] - 1;
        for (i = 0; i < n; i++)
            col[i] = T[i * m + c];
        /* the minimum-ratio test (lemke.pyx's ratio_candidates) */
        cmax = 0.0;
        qmax = 0.0;
        for (i = 0; i < n; i++) {
            a = fabs(col[i]);
            if (a > cmax)
                cmax = a;
            if (qb[i] > qmax)
                qmax = qb[i];
        }
        z0_row = -1;
        ptol = piv_tol * cmax;
        ztol = LCP_DEGENERATE_RTOL * qmax;
        tmin = LCP_INF;
        for (i = 0; i < n; i++) {
            a = col[i];
            if (a < -ptol) {
                v = qb[i] > ztol ? qb[i] : 0.0;
                t = v / (-a);
                if (t < tmin)
                    tmin = t;
            }
        }
        if (tmin == LCP_INF) {
            status = LCP_RAY;
            break;
        }
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
        if (z0_row >= 0) {
            r = z0_row; /* z0 ties for leaving: it leaves (the method ends with a solution) */
        } else if (nc == 1) {
            r = cand[0];
        } else {
            /* lexicographic minimum over rows of the basis inverse divided by the pivot */
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
            r = cand[0];
        }
        leaving = basic[r];
        lcp_pivot(T, qb, n, m, r, c, rowr);
        basic[r] = entering;
        where[entering] = r;
        where[leaving] = -(c + 1);
        pivots += 1;
        if (leaving == nz) {
            status = LCP_OK;
            break;
        }
    }
    for (i = 0; i < n; i++)
        if (basic[i] >= n && basic[i] < nz)
            z[basic[i] - n] = qb[i];
    *pivots_out = pivots;
    return status;
}

/* ---------------------------------------------------------------------------------- polish */
/* In-place LU with partial pivoting of the row-major m x m a (dense.pyx's own loops, used by
 * the CPU below LCP_LAPACK_MIN); returns 0 or k + 1 (a zero pivot). */
LCP_FN int lcp_lu_factor(double *a, lcp_i64 m, lcp_i64 *ipiv)
{
    lcp_i64 i, j, k, p;
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

LCP_FN void lcp_lu_solve(const double *lu, lcp_i64 m, const lcp_i64 *ipiv, double *b)
{
    lcp_i64 i, j, k;
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
LCP_FN double lcp_min_residual(const double *M, const double *q, const double *z, lcp_i64 n)
{
    lcp_i64 i, j;
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
LCP_FN int lcp_polish(const double *M, const double *q, lcp_i64 n, const double *z,
                      const lcp_i64 *basic, double *out, double *work, lcp_i64 *iwork)
{
    lcp_i64 i, j, k, m = 0, *idx = iwork, *mark = iwork + n, *ipiv = iwork + 2 * n;
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
 * the answer is not certified at rounding level (`polished`).
 * work: LCP_LEMKE_DWORK(n), iwork: LCP_LEMKE_IWORK(n). */
LCP_FN void lcp_lemke_one(lcp_i64 n, const double *M, const double *q, const double *d,
                          lcp_i64 max_iter, double piv_tol, double tie_tol, double tol,
                          double polished, int balanced, int q_balanced, int max_rounds,
                          double *work, lcp_i64 *iwork, double *z, double *w, signed char *code,
                          lcp_i64 *iters, double *err, double *res)
{
    double *raw = work + n * (n + 1) + 4 * n + 1, *cwork = raw + n, *Ms = cwork + 5 * n;
    double *qs = Ms + n * n, *ds = qs + n, *pwork = ds + n;
    lcp_i64 *ciwork = iwork + 5 * n + 2, *rc = ciwork + 3 * n, *piwork = rc + 4 * n;
    lcp_i64 pivots = 0, i;
    const double *Mu = M, *qu = q, *du = d;
    int scaled = 0, prc = 0;
    lcp_cert cert;
    int status;
    *code = LCP_RETRY;
    *iters = 0;
    *err = LCP_INF;
    *res = LCP_NAN;
    if (balanced >= 0 && lcp_balance(n, M, q, d, balanced, q_balanced, max_rounds, Ms, qs, ds,
                                     rc)) {
        scaled = 1;
        Mu = Ms;
        qu = qs;
        du = ds;
    }
    status = lcp_lemke(n, Mu, qu, du, max_iter, piv_tol, tie_tol, raw, work, iwork, &pivots);
    if (status != LCP_OK && status != LCP_TRIVIAL)
        return; /* a ray or the iteration limit: the CPU pipeline classifies it */
    if (scaled) /* z = D_c z~ (exact) */
        for (i = 0; i < n; i++)
            raw[i] = ldexp(raw[i], (int)rc[n + i]);
    *iters = pivots;
    for (i = 0; i < n; i++)
        z[i] = (status == LCP_TRIVIAL || raw[i] < 0.0) ? 0.0 : raw[i];
    lcp_certify(n, M, q, z, 0, 0, w, cwork, ciwork, &cert);
    if (status == LCP_OK && !(cert.status == 0 && cert.error <= polished)) {
        /* not at rounding level: the end basis (iwork's first n: lcp_lemke's `basic`)
         * re-solved by LU with one refinement step, then certified again */
        prc = lcp_polish(M, q, n, raw, iwork, z, pwork, piwork);
        if (prc != 0)
            return; /* a basis the CPU re-solves with LAPACK */
        lcp_certify(n, M, q, z, 0, 0, w, cwork, ciwork, &cert);
    }
    if (cert.status == 0)
        *err = cert.error;
    *res = cert.residual;
    if (cert.status == 0 && cert.error <= tol)
        *code = LCP_SOLVED;
}

/* ------------------------------------------------------------------------- projected SOR */
LCP_FN double lcp_scaled_error(const double *z, const double *w, const double *lo,
                               const double *up, lcp_i64 n, double mu, double qnorm)
{
    lcp_i64 i;
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

LCP_FN double lcp_row(const double *M, const double *q, const double *z, lcp_i64 n, lcp_i64 i)
{
    double s = q[i];
    const double *Mi = M + i * n;
    lcp_i64 j;
    for (j = 0; j < n; j++)
        s += Mi[j] * z[j];
    return s;
}

/* pgs.pyx's pgs_sweeps (dense): 0 converged, 1 limit, 2 non-finite; w: n doubles */
LCP_FN int lcp_sweeps(const double *M, const double *q, const double *diag, const double *lo,
                      const double *up, double *z, lcp_i64 n, double omega, lcp_i64 max_iter,
                      double tol, double mu, double qnorm, lcp_i64 *sweeps, double *w)
{
    lcp_i64 i, it, gap = 1, next_check = 1;
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
LCP_FN void lcp_sor_one(lcp_i64 n, const double *M, const double *q, const double *lo_in,
                        const double *up_in, double omega, lcp_i64 max_iter, double tol,
                        double *work, lcp_i64 *iwork, double *z, double *w, signed char *code,
                        lcp_i64 *iters, double *err, double *res)
{
    double *diag = work, *lo = work + n, *up = work + 2 * n, *sw = work + 3 * n;
    double *cwork = work + 4 * n + 1;
    double mu = 0.0, qnorm = 0.0, rowsum, target = tol;
    lcp_i64 i, j, sweeps = 0, done = 0;
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
 * the covering vector (else ones and d is not read). */
extern "C" __global__ void lcp_lemke_stack(
    lcp_i64 K, lcp_i64 n, const double *M, const double *q, int use_d, const double *d,
    lcp_i64 max_iter, double piv_tol, double tie_tol, double tol, double polished, int balanced,
    int q_balanced, int max_rounds, double *work, lcp_i64 *iwork, double *z, double *w,
    signed char *code, lcp_i64 *iters, double *err, double *res)
{
    lcp_i64 slot = (lcp_i64)blockIdx.x * blockDim.x + threadIdx.x;
    lcp_i64 stride = (lcp_i64)gridDim.x * blockDim.x, k;
    for (k = slot; k < K; k += stride)
        lcp_lemke_one(n, M + k * n * n, q + k * n, use_d ? d : 0, max_iter, piv_tol, tie_tol,
                      tol, polished, balanced, q_balanced, max_rounds,
                      work + slot * LCP_LEMKE_DWORK(n), iwork + slot * LCP_LEMKE_IWORK(n),
                      z + k * n, w + k * n, code + k, iters + k, err + k, res + k);
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
                    work + slot * LCP_SOR_DWORK(n), iwork + slot * LCP_SOR_IWORK(n), z + k * n,
                    w + k * n, code + k, iters + k, err + k, res + k);
}
#endif

#endif /* LCPCLI_LCP_STACK_H */
