/* Embree's spawn convention as a rayproof spawn rule (issue 47): the one Embree's own path
 * tracer tutorial uses (embree tutorials/pathtracer/pathtracer_device.cpp, postIntersect and
 * renderPixelFunction), in f32 as Embree is:
 *
 *   P   = ray.org + ray.tfar * ray.dir                        the hit point, not reprojected
 *   eps = 32 * 1.19209e-07f * max(|P.x|, |P.y|, |P.z|, tfar)  32 FLT_EPSILON of the scene's size
 *   Ng  = face_forward(ray.dir, normalize(Ng))                the normal turned to the viewer
 *   P'  = P + sign * eps * Ng, sign = dot(wi, Ng) < 0 ? -1 : 1
 *   new ray: org P', tnear = eps
 *
 * One file, both ways in (`rayproof header --spawn`). The build lines fix contraction off, as
 * the tutorial's x86 build has it:
 *   as a command (one query per line in, `1 OX OY OZ TMIN` out, flushed):
 *     cc -O2 -ffp-contract=off -o embree_tnear_spawn scripts/embree_tnear_spawn.c -lm
 *     rayproof spawn --precision f32 --rule pbrt --exec ./embree_tnear_spawn --name embree_tutorial
 *   as a library (its C ABI, batches in a worker process):
 *     cc -O2 -ffp-contract=off -shared -fPIC -o libembree_tnear_spawn.so scripts/embree_tnear_spawn.c -lm
 *     rayproof spawn --precision f32 --plugin ./libembree_tnear_spawn.so:embree_tutorial_spawn_f32 */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static float maxf(float a, float b) { return a > b ? a : b; }

/* q: P E Ng Wi tfar org dir (19 values); out: origin x y z, tnear */
static void spawn1(const float q[19], float out[4]) {
    const float *ng = q + 6, *wi = q + 9, *org = q + 13, *dir = q + 16;
    float tfar = q[12];
    float P[3], N[3];
    for (int i = 0; i < 3; i++) P[i] = org[i] + tfar * dir[i];
    float eps = 32.0f * 1.19209e-07f *
                maxf(maxf(fabsf(P[0]), fabsf(P[1])), maxf(fabsf(P[2]), tfar));
    /* face_forward(dir, Ng): Ng turned against the primary ray */
    float len = sqrtf(ng[0] * ng[0] + ng[1] * ng[1] + ng[2] * ng[2]);
    float facing = dir[0] * ng[0] + dir[1] * ng[1] + dir[2] * ng[2] < 0.0f ? 1.0f : -1.0f;
    for (int i = 0; i < 3; i++) N[i] = facing * ng[i] / len;
    float sign = wi[0] * N[0] + wi[1] * N[1] + wi[2] * N[2] < 0.0f ? -1.0f : 1.0f;
    for (int i = 0; i < 3; i++) out[i] = P[i] + sign * eps * N[i];
    out[3] = eps;
}

/* The C ABI: rayproof_spawn_f32 */
int embree_tutorial_spawn_f32(size_t n, const float in[][19], uint32_t count[], float out[][4]) {
    for (size_t i = 0; i < n; i++) {
        spawn1(in[i], out[i]);
        count[i] = 1;
    }
    return 0;
}

int main(void) {
    char line[4096];
    while (fgets(line, sizeof line, stdin)) {
        char *s = line;
        while (*s == ' ') s++;
        if (strncmp(s, "f32 ", 4) != 0) {
            fprintf(stderr, "embree_tnear_spawn: Embree is single precision; got: %.40s\n", s);
            return 2;
        }
        s += 4;
        float q[19], o[4];
        for (int i = 0; i < 19; i++) {
            char *end;
            q[i] = (float)strtod(s, &end);
            if (end == s) {
                fprintf(stderr, "embree_tnear_spawn: value %d missing\n", i + 1);
                return 2;
            }
            s = end;
        }
        spawn1(q, o);
        printf("1 %a %a %a %a\n", (double)o[0], (double)o[1], (double)o[2], (double)o[3]);
        fflush(stdout);
    }
    return 0;
}
