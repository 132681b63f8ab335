/* Routines audited through `rayproof audit --plugin` in tests/plugin.rs, with the signatures
 * of `rayproof header`. Built at test time: cc -O2 -shared -fPIC routines.c -o libroutines.so */
#include <math.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>

static float dot3f(const float a[3], const float b[3]) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
static double dot3(const double a[3], const double b[3]) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

/* The textbook ray–sphere quadratic in float: A t² + B t + C, D = B² − 4AC. */
int sphere_textbook_f32(size_t n, const float in[][10], uint32_t count[], float out[][1]) {
    for (size_t i = 0; i < n; i++) {
        const float *o = in[i], *d = in[i] + 3, *c = in[i] + 6, r = in[i][9];
        float f[3] = {o[0] - c[0], o[1] - c[1], o[2] - c[2]};
        float a = dot3f(d, d), b = 2.0f * dot3f(d, f), cc = dot3f(f, f) - r * r;
        float disc = b * b - 4.0f * a * cc;
        count[i] = 0;
        if (!(disc > 0.0f)) continue;
        float s = sqrtf(disc), t0 = (-b - s) / (2.0f * a), t1 = (-b + s) / (2.0f * a);
        float lo = fminf(t0, t1), hi = fmaxf(t0, t1);
        float t = lo > 0.0f ? lo : hi;
        if (t > 0.0f) { count[i] = 1; out[i][0] = t; }
    }
    return 0;
}

/* A careful one: the perpendicular discriminant and the stable root pair in double (every f32
 * input, product and square is exact or nearly so there), rounded once to float. */
int sphere_careful_f32(size_t n, const float in[][10], uint32_t count[], float out[][1]) {
    for (size_t i = 0; i < n; i++) {
        double o[3], d[3], c[3], r = in[i][9];
        for (int k = 0; k < 3; k++) { o[k] = in[i][k]; d[k] = in[i][3 + k]; c[k] = in[i][6 + k]; }
        count[i] = 0;
        int finite = isfinite(r) && r > 0.0;
        for (int k = 0; k < 3; k++) finite = finite && isfinite(o[k]) && isfinite(d[k]) && isfinite(c[k]);
        double f[3] = {o[0] - c[0], o[1] - c[1], o[2] - c[2]};
        double a = dot3(d, d);
        if (!finite || !(a > 0.0)) continue;
        double b = dot3(f, d), p = b / a;
        double l[3] = {f[0] - p * d[0], f[1] - p * d[1], f[2] - p * d[2]};
        double disc = (r - sqrt(dot3(l, l))) * (r + sqrt(dot3(l, l)));
        if (disc < 0.0) continue;
        double cc = (sqrt(dot3(f, f)) - r) * (sqrt(dot3(f, f)) + r);
        double q = -(b + copysign(sqrt(a * disc), b));
        double t0 = cc / q, t1 = q / a;
        double lo = fmin(t0, t1), hi = fmax(t0, t1);
        double t = lo > 0.0 ? lo : hi;
        float tf = (float)t;
        if (t > 0.0 && tf > 0.0f && isfinite(tf)) { count[i] = 1; out[i][0] = tf; }
    }
    return 0;
}

/* Möller–Trumbore in float with the usual |det| < 1e-6 test. Inputs o d p0 p1 p2. */
int triangle_mt_f32(size_t n, const float in[][15], uint32_t count[], float out[][1]) {
    for (size_t i = 0; i < n; i++) {
        const float *o = in[i], *d = in[i] + 3, *p0 = in[i] + 6, *p1 = in[i] + 9, *p2 = in[i] + 12;
        float e1[3] = {p1[0] - p0[0], p1[1] - p0[1], p1[2] - p0[2]};
        float e2[3] = {p2[0] - p0[0], p2[1] - p0[1], p2[2] - p0[2]};
        float h[3] = {d[1] * e2[2] - d[2] * e2[1], d[2] * e2[0] - d[0] * e2[2], d[0] * e2[1] - d[1] * e2[0]};
        float det = dot3f(e1, h);
        count[i] = 0;
        if (!(fabsf(det) >= 1e-6f)) continue;
        float inv = 1.0f / det;
        float s[3] = {o[0] - p0[0], o[1] - p0[1], o[2] - p0[2]};
        float u = inv * dot3f(s, h);
        if (!(u >= 0.0f && u <= 1.0f)) continue;
        float q[3] = {s[1] * e1[2] - s[2] * e1[1], s[2] * e1[0] - s[0] * e1[2], s[0] * e1[1] - s[1] * e1[0]};
        float v = inv * dot3f(d, q);
        if (!(v >= 0.0f && u + v <= 1.0f)) continue;
        float t = inv * dot3f(e2, q);
        if (t > 0.0f && isfinite(t)) { count[i] = 1; out[i][0] = t; }
    }
    return 0;
}

/* The chapter's plane-then-barycentrics test (Lengyel §6.2), operation for operation the
 * built-in `chapter` method in float: N = Q1×Q2, t = −(N·S + L_w)/(N·V), then the 2×2 system.
 * The same bits as the built-in, so its rows under the outside path (o + t·d, the rule the
 * built-in `chapter` also uses) are the built-in's (tests/plugin.rs pins them). */
static void cross3f(const float a[3], const float b[3], float c[3]) {
    c[0] = a[1] * b[2] - a[2] * b[1];
    c[1] = a[2] * b[0] - a[0] * b[2];
    c[2] = a[0] * b[1] - a[1] * b[0];
}
int triangle_chapter_f32(size_t n, const float in[][15], uint32_t count[], float out[][1]) {
    for (size_t i = 0; i < n; i++) {
        const float *o = in[i], *d = in[i] + 3, *p0 = in[i] + 6, *p1 = in[i] + 9, *p2 = in[i] + 12;
        float q1[3] = {p1[0] - p0[0], p1[1] - p0[1], p1[2] - p0[2]};
        float q2[3] = {p2[0] - p0[0], p2[1] - p0[1], p2[2] - p0[2]};
        float nn[3];
        cross3f(q1, q2, nn);
        float lw = -dot3f(nn, p0), lv = dot3f(nn, d);
        count[i] = 0;
        if (lv == 0.0f) continue;
        float t = -(dot3f(nn, o) + lw) / lv;
        if (!(t > 0.0f)) continue;
        float r[3] = {o[0] + d[0] * t - p0[0], o[1] + d[1] * t - p0[1], o[2] + d[2] * t - p0[2]};
        float q11 = dot3f(q1, q1), q22 = dot3f(q2, q2), q12 = dot3f(q1, q2);
        float inv = 1.0f / (q11 * q22 - q12 * q12);
        float rq1 = dot3f(r, q1), rq2 = dot3f(r, q2);
        float w1 = inv * (q22 * rq1 - q12 * rq2);
        float w2 = inv * (q11 * rq2 - q12 * rq1);
        if (w1 >= 0.0f && w2 >= 0.0f && w1 + w2 <= 1.0f) { count[i] = 1; out[i][0] = t; }
    }
    return 0;
}

/* Möller–Trumbore whose t is 0.1 % short: a hit point in front of the triangle by far more than
 * the o + t·d rounding bound covers, so rays spawned through it hit it again (the reintersection
 * test's teeth for outside routines). */
int triangle_short_t_f32(size_t n, const float in[][15], uint32_t count[], float out[][1]) {
    int r = triangle_mt_f32(n, in, count, out);
    for (size_t i = 0; i < n; i++)
        if (count[i]) out[i][0] *= 0.999f;
    return r;
}

/* The quadratic's §1.1 formula in float, in double: D = b² − 4ac, −b/2a when D = 0, else
 * (−b ± √D)/2a, ascending; count is the number of roots written. Inputs a b c. */
#define QUADRATIC_TEXTBOOK(NAME, T, SQRT)                                              \
    int NAME(size_t n, const T in[][3], uint32_t count[], T out[][2]) {                \
        for (size_t i = 0; i < n; i++) {                                               \
            T a = in[i][0], b = in[i][1], c = in[i][2];                                \
            T d = b * b - (T)4 * a * c, two_a = (T)2 * a;                              \
            count[i] = 0;                                                              \
            if (d < 0) continue;                                                       \
            if (d == 0) { count[i] = 1; out[i][0] = -b / two_a; continue; }            \
            T s = SQRT(d), x0 = (-b - s) / two_a, x1 = (-b + s) / two_a;               \
            if (x0 > x1) { T x = x0; x0 = x1; x1 = x; }                                \
            count[i] = 2; out[i][0] = x0; out[i][1] = x1;                              \
        }                                                                              \
        return 0;                                                                      \
    }
QUADRATIC_TEXTBOOK(quadratic_textbook_f32, float, sqrtf)
QUADRATIC_TEXTBOOK(quadratic_textbook_f64, double, sqrt)

/* Bad routines, for the refusals. */
int crashes_f32(size_t n, const float in[][10], uint32_t count[], float out[][1]) {
    volatile int *null = 0;
    (void)in; (void)out; (void)count;
    return n > 0 ? *null : 0;
}
int fails_f32(size_t n, const float in[][10], uint32_t count[], float out[][1]) {
    (void)n; (void)in; (void)count; (void)out;
    return 7;
}
int forgets_counts_f32(size_t n, const float in[][10], uint32_t count[], float out[][1]) {
    (void)in; (void)count;
    for (size_t i = 0; i < n; i++) out[i][0] = 1.0f;
    return 0;
}
/* Written for doubles but loaded as f32: counts are right, values are never written. */
int nan_values_f32(size_t n, const float in[][10], uint32_t count[], float out[][1]) {
    (void)in; (void)out;
    for (size_t i = 0; i < n; i++) count[i] = 1;
    return 0;
}

/* Routines that take their process down in every way a C routine can (tests/plugin.rs): they
 * run in rayproof's worker process, so rayproof reports them instead of dying with them. */
#include <stdlib.h>
#include <unistd.h>
int aborts_f32(size_t n, const float in[][10], uint32_t count[], float out[][1]) {
    (void)in; (void)count; (void)out;
    if (n > 0) abort();
    return 0;
}
static int deep(int k) { volatile char pad[256]; pad[0] = (char)k; return deep(k + 1) + pad[0]; }
int overflows_stack_f32(size_t n, const float in[][10], uint32_t count[], float out[][1]) {
    (void)in; (void)count; (void)out;
    return n > 0 ? deep(0) : 0;
}
int calls_exit_f32(size_t n, const float in[][10], uint32_t count[], float out[][1]) {
    (void)in; (void)count; (void)out;
    if (n > 0) exit(0);
    return 0;
}
int hangs_f32(size_t n, const float in[][10], uint32_t count[], float out[][1]) {
    (void)in; (void)count; (void)out;
    for (;;) if (n > 0) sleep(1);
    return 0;
}
/* Writes far past out[]: the heap's checks abort the process (or it crashes). */
int writes_past_out_f32(size_t n, const float in[][10], uint32_t count[], float out[][1]) {
    (void)in;
    for (size_t i = 0; i < n; i++) count[i] = 0;
    for (size_t i = 0; i < n * 4096 + (1u << 20); i++) out[0][i] = 1.0f;
    return 0;
}
/* Right everywhere (a miss) but crashes on one case: the one whose ox is exactly 0.25. */
int crashes_on_one_case_f32(size_t n, const float in[][10], uint32_t count[], float out[][1]) {
    (void)out;
    for (size_t i = 0; i < n; i++) {
        if (in[i][0] == 0.25f) { volatile int *null = 0; return *null; }
        count[i] = 0;
    }
    return 0;
}
