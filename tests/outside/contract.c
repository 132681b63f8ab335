/* Plugins for tests/contract.rs: each case answered with one entry of a fixed table of answers,
 * in and outside the answer contract, chosen by the case's inputs (the XOR of their f64 bits,
 * every NaN as 0x7ff8000000000000, modulo the table's length), as tests/outside/contract_table.py
 * and the test's Rust routine choose it. Only what a C routine can write is here: a count and
 * OUT values (the text-only entries, a value count that does not match the count, are not). */
#include <math.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>

static size_t entry(const double *in, size_t k, size_t len) {
    uint64_t key = 0;
    for (size_t j = 0; j < k; j++) {
        uint64_t b = 0x7ff8000000000000ull;
        if (in[j] == in[j]) memcpy(&b, &in[j], 8);
        key ^= b;
    }
    return (size_t)(key % len);
}

int contract_sphere_f64(size_t n, const double in[][10], uint32_t count[], double out[][1]) {
    const uint32_t c[10] = {0, 1, 1, 1, 1, 1, 2, 7, 1, 1};
    const double t[10] = {0, -1.0, 0.0, -0.0, INFINITY, NAN, 1.0, 1.0, 5.0, 0x1p100};
    for (size_t i = 0; i < n; i++) {
        size_t e = entry(in[i], 10, 10);
        count[i] = c[e];
        out[i][0] = t[e];
    }
    return 0;
}

int contract_quadratic_f64(size_t n, const double in[][3], uint32_t count[], double out[][2]) {
    const uint32_t c[7] = {0, 1, 2, 2, 3, 2, 1};
    const double v[7][2] = {{0, 0}, {0.5, 0}, {-1, 1}, {1, -1}, {1, 2}, {NAN, 1}, {-0.0, 0}};
    for (size_t i = 0; i < n; i++) {
        size_t e = entry(in[i], 3, 7);
        count[i] = c[e];
        out[i][0] = v[e][0];
        out[i][1] = v[e][1];
    }
    return 0;
}
