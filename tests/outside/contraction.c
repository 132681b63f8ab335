/* Two ray–triangle routines for `rayproof builds` (issue 49 item 3): the same source under
 * several compilers and flags.
 *
 * tri_mt_f32: Möller–Trumbore in float, as it is usually written. Every a*b - c*d and dot
 * product is a multiply-add the compiler may fuse (-ffp-contract=fast, GPU and ARM compilers'
 * default): the fused and the unfused routine give different edge tests near an edge.
 *
 * tri_fused_f32 (below): the same test with the fusion written in the source. */
#include <math.h>
#include <stddef.h>
#include <stdint.h>

int tri_mt_f32(size_t n, const float in[][15], uint32_t count[], float out[][1]) {
    for (size_t i = 0; i < n; i++) {
        const float *o = in[i], *d = in[i] + 3, *p0 = in[i] + 6, *p1 = in[i] + 9, *p2 = in[i] + 12;
        float e1[3] = {p1[0] - p0[0], p1[1] - p0[1], p1[2] - p0[2]};
        float e2[3] = {p2[0] - p0[0], p2[1] - p0[1], p2[2] - p0[2]};
        float h[3] = {d[1] * e2[2] - d[2] * e2[1], d[2] * e2[0] - d[0] * e2[2], d[0] * e2[1] - d[1] * e2[0]};
        float det = e1[0] * h[0] + e1[1] * h[1] + e1[2] * h[2];
        count[i] = 0;
        if (det == 0.0f) continue;
        float inv = 1.0f / det;
        float s[3] = {o[0] - p0[0], o[1] - p0[1], o[2] - p0[2]};
        float u = inv * (s[0] * h[0] + s[1] * h[1] + s[2] * h[2]);
        if (!(u >= 0.0f && u <= 1.0f)) continue;
        float q[3] = {s[1] * e1[2] - s[2] * e1[1], s[2] * e1[0] - s[0] * e1[2], s[0] * e1[1] - s[1] * e1[0]};
        float v = inv * (d[0] * q[0] + d[1] * q[1] + d[2] * q[2]);
        if (!(v >= 0.0f && u + v <= 1.0f)) continue;
        float t = inv * (e2[0] * q[0] + e2[1] * q[1] + e2[2] * q[2]);
        if (t > 0.0f && isfinite(t)) { count[i] = 1; out[i][0] = t; }
    }
    return 0;
}

/* tri_fused_f32: Möller–Trumbore with every multiply-add written as fmaf: a*b - c*d is
 * fmaf(a, b, -(c*d)), a dot product fmaf(a0, b0, fmaf(a1, b1, a2*b2)), u + v with u a product
 * fmaf(inv, su, v). No multiply feeds an add any more, so -ffp-contract has nothing to fuse and
 * every build that keeps IEEE semantics computes the same bits (-ffast-math may still reorder). */
static float dif(float a, float b, float c, float d) { return fmaf(a, b, -(c * d)); }
static float dot(const float a[3], const float b[3]) { return fmaf(a[0], b[0], fmaf(a[1], b[1], a[2] * b[2])); }

int tri_fused_f32(size_t n, const float in[][15], uint32_t count[], float out[][1]) {
    for (size_t i = 0; i < n; i++) {
        const float *o = in[i], *d = in[i] + 3, *p0 = in[i] + 6, *p1 = in[i] + 9, *p2 = in[i] + 12;
        float e1[3] = {p1[0] - p0[0], p1[1] - p0[1], p1[2] - p0[2]};
        float e2[3] = {p2[0] - p0[0], p2[1] - p0[1], p2[2] - p0[2]};
        float h[3] = {dif(d[1], e2[2], d[2], e2[1]), dif(d[2], e2[0], d[0], e2[2]), dif(d[0], e2[1], d[1], e2[0])};
        float det = dot(e1, h);
        count[i] = 0;
        if (det == 0.0f) continue;
        float inv = 1.0f / det;
        float s[3] = {o[0] - p0[0], o[1] - p0[1], o[2] - p0[2]};
        float su = dot(s, h);
        float u = inv * su;
        if (!(u >= 0.0f && u <= 1.0f)) continue;
        float q[3] = {dif(s[1], e1[2], s[2], e1[1]), dif(s[2], e1[0], s[0], e1[2]), dif(s[0], e1[1], s[1], e1[0])};
        float v = inv * dot(d, q);
        if (!(v >= 0.0f && fmaf(inv, su, v) <= 1.0f)) continue;
        float t = inv * dot(e2, q);
        if (t > 0.0f && isfinite(t)) { count[i] = 1; out[i][0] = t; }
    }
    return 0;
}
