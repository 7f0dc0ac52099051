/* mxs128: a 128-bit non-cryptographic hash of a byte string (four 64-bit multiply-rotate
 * lanes, the round and the final mix of xxHash64 by Yann Collet), for lcpcli's stacked result
 * files: it tells whether the input of a finished chunk changed between a run and its
 * --resume.  It is NOT a cryptographic hash: anyone who wants to can make two inputs with
 * the same value; it only has to catch accidental changes.  lcpcli/batch/digest.py holds
 * the written definition, and tests/batch/test_digest.py an independent Python reference that
 * must agree bit for bit.
 *
 * Definition (all arithmetic modulo 2^64; rotl: rotate left):
 *   P1 = 0x9E3779B185EBCA87, P2 = 0xC2B2AE3D27D4EB4F, P3 = 0x165667B19E3779F9,
 *   P4 = 0x85EBCA77C2B2AE63, P5 = 0x27D4EB2F165667C5.
 *   The input (L bytes) is padded with zero bytes to a multiple of 32 (none when L = 0) and
 *   read as stripes of four little-endian uint64 words w0..w3.
 *   Lanes: a0 = s + P1 + P2, a1 = s + P2, a2 = s, a3 = s - P1 (s: the seed);
 *   each stripe: ai = rotl(ai + wi * P2, 31) * P1.
 *   h1 = mix(rotl(a0, 1) + rotl(a1, 7) + rotl(a2, 12) + rotl(a3, 18) + L * P5)
 *   h2 = mix(rotl(a0, 18) + rotl(a1, 12) + rotl(a2, 7) + rotl(a3, 1) + L * P4 + h1)
 *   mix(v): v ^= v >> 33; v *= P2; v ^= v >> 29; v *= P3; v ^= v >> 32.
 *   The value: h1 then h2, each as 8 little-endian bytes (16 bytes).
 */
#ifndef LCPCLI_MXS128_H
#define LCPCLI_MXS128_H

#include <stdint.h>
#include <string.h>

#define MXS_P1 0x9E3779B185EBCA87ULL
#define MXS_P2 0xC2B2AE3D27D4EB4FULL
#define MXS_P3 0x165667B19E3779F9ULL
#define MXS_P4 0x85EBCA77C2B2AE63ULL
#define MXS_P5 0x27D4EB2F165667C5ULL

static inline uint64_t mxs_rotl(uint64_t x, int r) { return (x << r) | (x >> (64 - r)); }

static inline uint64_t mxs_read64(const unsigned char *p) {
    uint64_t v;
    memcpy(&v, p, 8);
#if defined(__BYTE_ORDER__) && __BYTE_ORDER__ == __ORDER_BIG_ENDIAN__
    v = __builtin_bswap64(v);
#endif
    return v;
}

static inline void mxs_write64(unsigned char *p, uint64_t v) {
    for (int i = 0; i < 8; i++) p[i] = (unsigned char)(v >> (8 * i));
}

static inline uint64_t mxs_round(uint64_t a, uint64_t w) {
    return mxs_rotl(a + w * MXS_P2, 31) * MXS_P1;
}

static inline uint64_t mxs_mix(uint64_t v) {
    v ^= v >> 33;
    v *= MXS_P2;
    v ^= v >> 29;
    v *= MXS_P3;
    v ^= v >> 32;
    return v;
}

/* The 16 bytes of mxs128(data[0 .. len-1], seed) into out. */
static void mxs128(const unsigned char *data, uint64_t len, uint64_t seed, unsigned char *out) {
    uint64_t a0 = seed + MXS_P1 + MXS_P2, a1 = seed + MXS_P2, a2 = seed, a3 = seed - MXS_P1;
    uint64_t full = len / 32, i;
    const unsigned char *p = data;
    for (i = 0; i < full; i++, p += 32) {
        a0 = mxs_round(a0, mxs_read64(p));
        a1 = mxs_round(a1, mxs_read64(p + 8));
        a2 = mxs_round(a2, mxs_read64(p + 16));
        a3 = mxs_round(a3, mxs_read64(p + 24));
    }
    if (len % 32) {  /* the last, partial stripe, padded with zeros */
        unsigned char tail[32] = {0};
        memcpy(tail, p, (size_t)(len % 32));
        a0 = mxs_round(a0, mxs_read64(tail));
        a1 = mxs_round(a1, mxs_read64(tail + 8));
        a2 = mxs_round(a2, mxs_read64(tail + 16));
        a3 = mxs_round(a3, mxs_read64(tail + 24));
    }
    uint64_t h1 = mxs_mix(mxs_rotl(a0, 1) + mxs_rotl(a1, 7) + mxs_rotl(a2, 12)
                          + mxs_rotl(a3, 18) + len * MXS_P5);
    uint64_t h2 = mxs_mix(mxs_rotl(a0, 18) + mxs_rotl(a1, 12) + mxs_rotl(a2, 7)
                          + mxs_rotl(a3, 1) + len * MXS_P4 + h1);
    mxs_write64(out, h1);
    mxs_write64(out + 8, h2);
}

#endif
