/* A user's ray-box guard for `rayproof guard` (issue 49 item 1): the naive slab test, as a
 * command (`--exec`, the line protocol of `rayproof header --guard`) and as a library (`--plugin`,
 * its C ABI). With -DROBUST it pads the far distances and t_max by 1 + 2 gamma_3 (Ize 2013).
 *   cc -O2 -o guard_slab tests/outside/guard_slab.c
 *   cc -O2 -shared -fPIC -o libguard_slab.so tests/outside/guard_slab.c */
#include <float.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define SLAB(T, EPS)                                                            \
    static int slab_##T(const T q[13]) {                                        \
        const T *o = q, *d = q + 3, *lo = q + 6, *hi = q + 9;                   \
        T g3 = 3 * (EPS / 2) / (1 - 3 * (EPS / 2));                             \
        T pad = ROBUST ? 1 + 2 * g3 : 1;                                        \
        T t0 = 0, t1 = q[12] * pad;                                             \
        for (int i = 0; i < 3; i++) {                                           \
            T inv = 1 / d[i];                                                   \
            T a = (lo[i] - o[i]) * inv, b = (hi[i] - o[i]) * inv;               \
            T n = a < b ? a : b, f = (a < b ? b : a) * pad;                     \
            if (n > t0) t0 = n;                                                 \
            if (f < t1) t1 = f;                                                 \
        }                                                                       \
        return t0 <= t1;                                                        \
    }

#ifndef ROBUST
#define ROBUST 0
#endif
SLAB(float, FLT_EPSILON)
SLAB(double, DBL_EPSILON)

int guard_slab_f32(size_t n, const float in[][13], uint32_t count[], float out[][1]) {
    for (size_t i = 0; i < n; i++) { out[i][0] = (float)slab_float(in[i]); count[i] = 1; }
    return 0;
}
int guard_slab_f64(size_t n, const double in[][13], uint32_t count[], double out[][1]) {
    for (size_t i = 0; i < n; i++) { out[i][0] = (double)slab_double(in[i]); count[i] = 1; }
    return 0;
}

int main(void) {
    char line[4096];
    while (fgets(line, sizeof line, stdin)) {
        char *s = line;
        int f32 = strncmp(s, "f32 ", 4) == 0;
        s += 4;
        double v[13];
        for (int k = 0; k < 13; k++) v[k] = strtod(s, &s);
        int hit;
        if (f32) {
            float q[13];
            for (int k = 0; k < 13; k++) q[k] = (float)v[k];
            hit = slab_float(q);
        } else {
            hit = slab_double(v);
        }
        printf("1 %d\n", hit);
        fflush(stdout);
    }
    return 0;
}
