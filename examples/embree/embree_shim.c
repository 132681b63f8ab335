/* Embree 3 under rayproof's audit: a shim that exposes Embree's own intersectors through the
 * plugin ABI (`rayproof header`). Copy it, build it, audit it:
 *
 *   cc -O2 -shared -fPIC embree_shim.c -o libembree_shim.so -lembree3
 *   rayproof audit --shape triangle --plugin ./libembree_shim.so:tri_f32 \
 *                                  --plugin ./libembree_shim.so:tri_robust_f32
 *   rayproof audit --shape sphere --plugin ./libembree_shim.so:sphere_f32
 *   EMBREE_SHIM_ISA=avx2 rayproof audit ...   (Embree's AVX2 path on an AVX-512 machine)
 *
 * Symbols (all f32, as Embree is):
 *   tri_f32            RTC_GEOMETRY_TYPE_TRIANGLE, default scene flags
 *   tri_robust_f32     the same with RTC_SCENE_FLAG_ROBUST (Embree's watertight mode)
 *   tri_prescaled_f32  tri_robust_f32 on the case rescaled by exact powers of two (the points by
 *                      one, the direction by another) so that their largest components are about
 *                      1, t scaled back exactly: what is left of the huge and tiny classes'
 *                      failures once Embree's range is out of the way
 *   sphere_f32         RTC_GEOMETRY_TYPE_SPHERE_POINT (a float4 x y z radius)
 *
 * Each case is one primitive in a scene of its own (built, committed, intersected, released:
 * about 5 µs per case on a 2-core machine). A ray is tnear = 0, tfar = inf, mask -1; a hit is
 * geomID set and t = tfar. Embree asserts on NaN/Inf ray components, on components beyond
 * its range (|x| > FLT_LARGE = 1.844e18) and on a zero direction (Debian's build aborts: a
 * shim that passes such a ray on is caught by rayproof as a crash), so the shim answers those
 * rays as a miss itself: right for invalid input, a false miss (Embree's range) otherwise.
 * Embree's sphere treats a negative radius as |r|; the shim leaves that to be judged.
 */
#include <embree3/rtcore.h>
#include <math.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static RTCDevice device;

/* The device: one thread, and the instruction set named by EMBREE_SHIM_ISA when it is set
 * (Embree's own names: sse2, sse4.2, avx, avx2, avx512; unset: the best this CPU has), so that
 * every path Embree has can be audited on one machine. Its answers differ between paths (a
 * finding, not noise: tests/embree.rs prints them side by side). */
static RTCDevice dev(void) {
    if (!device) {
        char config[128] = "threads=1";
        const char *isa = getenv("EMBREE_SHIM_ISA");
        if (isa && *isa) {
            /* Embree takes a name it does not know as SSE2, silently: only its own names */
            static const char *known[] = {"sse2", "sse4.2", "avx", "avx2", "avx512"};
            int ok = 0;
            for (size_t k = 0; k < sizeof known / sizeof *known; k++) ok |= strcmp(isa, known[k]) == 0;
            if (!ok) return NULL;
            snprintf(config, sizeof config, "threads=1,isa=%s", isa);
        }
        device = rtcNewDevice(config);
    }
    return device;
}

/* Whether the device exists and answers without error (an ISA this CPU lacks, or a name
 * Embree does not know, is an error: the routine fails rather than answer on another path). */
static int device_ok(void) {
    RTCDevice d = dev();
    return d != NULL && rtcGetDeviceError(d) == RTC_ERROR_NONE;
}

/* Embree's FLT_LARGE: ray components beyond it fail its ray.valid() assertion. */
#define EMBREE_LARGE 1.844e18f

static int finite_ray(const float *o, const float *d) {
    for (int k = 0; k < 3; k++)
        if (!(fabsf(o[k]) <= EMBREE_LARGE) || !(fabsf(d[k]) <= EMBREE_LARGE)) return 0;
    return d[0] != 0.0f || d[1] != 0.0f || d[2] != 0.0f;
}

/* One ray against a committed scene: 1 and t on a hit, 0 on a miss. */
static uint32_t trace(RTCScene scene, const float *o, const float *d, float *t) {
    struct RTCIntersectContext ctx;
    rtcInitIntersectContext(&ctx);
    struct RTCRayHit rh;
    rh.ray.org_x = o[0]; rh.ray.org_y = o[1]; rh.ray.org_z = o[2];
    rh.ray.dir_x = d[0]; rh.ray.dir_y = d[1]; rh.ray.dir_z = d[2];
    rh.ray.tnear = 0.0f;
    rh.ray.tfar = INFINITY;
    rh.ray.time = 0.0f;
    rh.ray.mask = 0xffffffffu;
    rh.ray.id = 0;
    rh.ray.flags = 0;
    rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
    rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
    rtcIntersect1(scene, &ctx, &rh);
    if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) return 0;
    *t = rh.ray.tfar;
    return 1;
}

/* A scene of one triangle p0 p1 p2. */
static RTCScene triangle_scene(const float *p, int robust) {
    RTCScene scene = rtcNewScene(dev());
    if (robust) rtcSetSceneFlags(scene, RTC_SCENE_FLAG_ROBUST);
    RTCGeometry g = rtcNewGeometry(dev(), RTC_GEOMETRY_TYPE_TRIANGLE);
    float *v = rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3,
                                       3 * sizeof(float), 3);
    unsigned *idx = rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3,
                                            3 * sizeof(unsigned), 1);
    for (int k = 0; k < 9; k++) v[k] = p[k];
    idx[0] = 0; idx[1] = 1; idx[2] = 2;
    rtcCommitGeometry(g);
    rtcAttachGeometry(scene, g);
    rtcReleaseGeometry(g);
    rtcCommitScene(scene);
    return scene;
}

static int triangles(size_t n, const float in[][15], uint32_t count[], float out[][1],
                     int robust, int prescale) {
    if (!device_ok()) return 1;
    for (size_t i = 0; i < n; i++) {
        float c[15];
        for (int k = 0; k < 15; k++) c[k] = in[i][k];
        count[i] = 0;
        out[i][0] = 0.0f;
        /* NaN, Inf or a zero direction: a miss (the range is checked after any rescaling) */
        int finite = c[3] != 0.0f || c[4] != 0.0f || c[5] != 0.0f;
        for (int k = 0; k < 15; k++) finite &= isfinite(c[k]) != 0;
        if (!finite) continue;
        int shift = 0; /* t = t' * 2^shift */
        if (prescale) {
            /* The points (o and the vertices) scaled by one power of two, the direction by
             * another, each to a largest component in [0.5, 1): o + t d = 2^(e) (o' + t' d')
             * with t = t' 2^(e - f), exact unless t over- or underflows */
            float mp = fabsf(c[0]), md = 0.0f;
            for (int k = 1; k < 3; k++) mp = fmaxf(mp, fabsf(c[k]));
            for (int k = 6; k < 15; k++) mp = fmaxf(mp, fabsf(c[k]));
            for (int k = 3; k < 6; k++) md = fmaxf(md, fabsf(c[k]));
            int e = 0, f = 0;
            if (mp > 0.0f) frexpf(mp, &e);
            frexpf(md, &f);
            for (int k = 0; k < 15; k++) c[k] = ldexpf(c[k], (k >= 3 && k < 6) ? -f : -e);
            shift = e - f;
        }
        if (!finite_ray(c, c + 3)) continue;
        RTCScene scene = triangle_scene(c + 6, robust);
        count[i] = trace(scene, c, c + 3, &out[i][0]);
        if (count[i]) out[i][0] = ldexpf(out[i][0], shift);
        rtcReleaseScene(scene);
    }
    return 0;
}

int tri_f32(size_t n, const float in[][15], uint32_t count[], float out[][1]) {
    return triangles(n, in, count, out, 0, 0);
}
int tri_robust_f32(size_t n, const float in[][15], uint32_t count[], float out[][1]) {
    return triangles(n, in, count, out, 1, 0);
}
int tri_prescaled_f32(size_t n, const float in[][15], uint32_t count[], float out[][1]) {
    return triangles(n, in, count, out, 1, 1);
}

int sphere_f32(size_t n, const float in[][10], uint32_t count[], float out[][1]) {
    if (!device_ok()) return 1;
    for (size_t i = 0; i < n; i++) {
        const float *c = in[i];
        count[i] = 0;
        out[i][0] = 0.0f;
        if (!finite_ray(c, c + 3)) continue;
        if (!isfinite(c[6]) || !isfinite(c[7]) || !isfinite(c[8]) || !isfinite(c[9])) continue;
        RTCScene scene = rtcNewScene(dev());
        RTCGeometry g = rtcNewGeometry(dev(), RTC_GEOMETRY_TYPE_SPHERE_POINT);
        float *v = rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT4,
                                           4 * sizeof(float), 1);
        v[0] = c[6]; v[1] = c[7]; v[2] = c[8]; v[3] = c[9];
        rtcCommitGeometry(g);
        rtcAttachGeometry(scene, g);
        rtcReleaseGeometry(g);
        rtcCommitScene(scene);
        count[i] = trace(scene, c, c + 3, &out[i][0]);
        rtcReleaseScene(scene);
    }
    return 0;
}
