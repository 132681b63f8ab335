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
 * Build and audit (the build line fixes contraction off, as the tutorial's x86 build has it):
 *   cc -O2 -ffp-contract=off -o embree_tnear_spawn scripts/embree_tnear_spawn.c -lm
 *   rayproof spawn --precision f32 --rule pbrt --exec ./embree_tnear_spawn --name embree_tutorial
 *
 * Protocol: `rayproof header --spawn`. One query per line in, `1 OX OY OZ TMIN` out, flushed. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static float maxf(float a, float b) { return a > b ? a : b; }

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
        float v[19];
        for (int i = 0; i < 19; i++) {
            char *end;
            v[i] = (float)strtod(s, &end);
            if (end == s) {
                fprintf(stderr, "embree_tnear_spawn: value %d missing\n", i + 1);
                return 2;
            }
            s = end;
        }
        const float *ng = v + 6, *wi = v + 9, *org = v + 13, *dir = v + 16;
        float tfar = v[12];
        float P[3], N[3];
        for (int i = 0; i < 3; i++) P[i] = org[i] + tfar * dir[i];
        float eps = 32.0f * 1.19209e-07f *
                    maxf(maxf(fabsf(P[0]), fabsf(P[1])), maxf(fabsf(P[2]), tfar));
        /* face_forward(dir, Ng): Ng turned against the primary ray */
        float len = sqrtf(ng[0] * ng[0] + ng[1] * ng[1] + ng[2] * ng[2]);
        float facing = dir[0] * ng[0] + dir[1] * ng[1] + dir[2] * ng[2] < 0.0f ? 1.0f : -1.0f;
        for (int i = 0; i < 3; i++) N[i] = facing * ng[i] / len;
        float sign = wi[0] * N[0] + wi[1] * N[1] + wi[2] * N[2] < 0.0f ? -1.0f : 1.0f;
        printf("1");
        for (int i = 0; i < 3; i++) printf(" %a", (double)(P[i] + sign * eps * N[i]));
        printf(" %a\n", (double)eps);
        fflush(stdout);
    }
    return 0;
}
