// Threads standing in for the lanes of one device group, so that the CPU runs the single-source
// kernel's lane code paths (lcpcli/solvers/kernels/src/lcp_stack.h with LCP_EMULATE_LANES):
// every lane is a thread, LCP_SYNC a barrier of the group, a shuffle or a vote an exchange
// through a slot per lane between two barriers.  Built and loaded by
// tests/solvers/test_lane_groups.py (ctypes); not part of the package.
#include <chrono>
#include <condition_variable>
#include <cstring>
#include <mutex>
#include <thread>
#include <vector>

// Thrown in every lane once the group is broken: the lanes stop where they are (a lane that
// went on with another lane's pivot row would index out of bounds) and the run reports -1.
struct emu_diverged {};

// A barrier of the group's threads that gives up after 10 s: lanes whose control flow diverged
// (a reduction that left them with different values) would wait for each other for ever on a
// device; here the barrier breaks, every lane stops at its next collective (emu_diverged), and
// the run reports the divergence instead of hanging or crashing the test.
struct emu_barrier {
    std::mutex mu;
    std::condition_variable cv;
    int count = 0, size = 1;
    unsigned long generation = 0;
    bool broken = false;
    void wait()
    {
        std::unique_lock<std::mutex> lock(mu);
        if (broken)
            throw emu_diverged();
        unsigned long gen = generation;
        if (++count == size) {
            count = 0;
            generation++;
            cv.notify_all();
            return;
        }
        if (!cv.wait_for(lock, std::chrono::seconds(10),
                         [&] { return generation != gen || broken; }))
            breaks();
        if (broken)
            throw emu_diverged();
    }
    void breaks()  // with mu held
    {
        broken = true;
        cv.notify_all();
    }
};

static thread_local int emu_lane = 0;
static int emu_lanes = 1;
static emu_barrier emu_bar;
static unsigned char emu_slot[32][8];
static unsigned emu_jitter = 1;

static void emu_start(int lanes)
{
    emu_bar.count = 0;
    emu_bar.size = lanes;
    emu_bar.broken = false;
    emu_lanes = lanes;
}

static void lcp_emu_sync()
{
    // a lane that arrives late now and then: interleavings a missing LCP_SYNC would expose
    unsigned x = __atomic_add_fetch(&emu_jitter, 2654435761u, __ATOMIC_RELAXED);
    if ((x >> 28) == 0)
        std::this_thread::yield();
    emu_bar.wait();
}

template <class T> static T lcp_emu_shfl(T x, long long o)
{
    T y;
    std::memcpy(emu_slot[emu_lane], &x, sizeof(T));
    emu_bar.wait();
    std::memcpy(&y, emu_slot[emu_lane ^ (int)o], sizeof(T));
    emu_bar.wait();
    return y;
}

// LCP_UNIFORM: every lane compares its value with every other lane's; a difference breaks the
// group (each lane sees the same slots, so all of them stop here).
static void lcp_emu_uniform(long long x)
{
    bool same = true;
    std::memcpy(emu_slot[emu_lane], &x, sizeof x);
    emu_bar.wait();
    for (int i = 0; i < emu_lanes; i++) {
        long long v;
        std::memcpy(&v, emu_slot[i], sizeof v);
        same = same && v == x;
    }
    emu_bar.wait();
    if (!same) {
        {
            std::lock_guard<std::mutex> lock(emu_bar.mu);
            emu_bar.breaks();
        }
        throw emu_diverged();
    }
}

static int lcp_emu_any(int p)
{
    int any = 0;
    std::memcpy(emu_slot[emu_lane], &p, sizeof(int));
    emu_bar.wait();
    for (int i = 0; i < emu_lanes; i++) {
        int v;
        std::memcpy(&v, emu_slot[i], sizeof(int));
        any |= v != 0;
    }
    emu_bar.wait();
    return any;
}

#define LCP_EMULATE_LANES 1
#include "lcp_stack.h"

// Lemke and the certificate on K problems of size n, one after another, each by one group of
// `lanes` threads running lcp_lemke_group (the warp kernel's body), stage as the device.
// Returns 0, or -1 when the lanes diverged (the barrier broke).
extern "C" int emu_lemke_stack(long long K, long long n, const double *M, const double *q,
                               const double *d, long long max_iter, double piv_tol,
                               double tie_tol, double tol, double polished, int balanced,
                               int q_balanced, int max_rounds, int stage, int lanes, double *z,
                               double *w, signed char *code, long long *iters, double *err,
                               double *res)
{
    long long fast = LCP_FAST_SLOTS(n), cold = LCP_COLD_SLOTS(n);
    std::vector<double> work((size_t)(fast + cold) + 1);
    emu_start(lanes);
    std::vector<std::thread> pool;
    for (int t = 0; t < lanes; t++)
        pool.emplace_back([&, t]() {
            emu_lane = t;
            double *sh = work.data();
            try {
                for (long long k = 0; k < K; k++)
                    lcp_lemke_group(n, M + k * n * n, q + k * n, d, max_iter, piv_tol, tie_tol,
                                    tol, polished, balanced, q_balanced, max_rounds, stage, sh,
                                    sh + fast, z + k * n, w + k * n, code + k, iters + k,
                                    err + k, res + k, t, lanes);
            } catch (const emu_diverged &) {
            }
        });
    for (auto &th : pool)
        th.join();
    return emu_bar.broken ? -1 : 0;
}

// The certificate alone (lcp_certify_warp) on one z, by `lanes` threads; returns the status
// (-1: the lanes diverged).
extern "C" int emu_certify(long long n, const double *M, const double *q, const double *z,
                           const double *lo, const double *up, int lanes, double *w,
                           double *error, double *residual)
{
    std::vector<double> work((size_t)LCP_CERT_DWORK(n) + 1);
    std::vector<lcp_ix> iwork((size_t)LCP_CERT_IWORK(n) + 1);
    lcp_cert out;
    int status = 0;
    emu_start(lanes);
    std::vector<std::thread> pool;
    for (int t = 0; t < lanes; t++)
        pool.emplace_back([&, t]() {
            emu_lane = t;
            try {
                int st = lcp_certify_warp(n, M, q, z, lo, up, w, work.data(), iwork.data(), &out,
                                          t, lanes);
                if (t == 0)
                    status = st;
            } catch (const emu_diverged &) {
            }
        });
    for (auto &th : pool)
        th.join();
    *error = out.error;
    *residual = out.residual;
    return emu_bar.broken ? -1 : status;
}
