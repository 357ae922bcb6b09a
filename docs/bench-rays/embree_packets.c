/* Native Embree 3 on the ray sets of `phr bench-rays --export-rays`: single rays
 * (rtcIntersect1) against packets of 8 consecutive rays (rtcIntersect8, the call Mitsuba 3's
 * llvm variant makes for each 8-lane chunk of its wavefront), with the default scene flags or
 * RTC_SCENE_FLAG_ROBUST, one thread. A measuring probe for docs/bench-frame/history.md, not
 * part of the build.
 *
 *   apt-get install libembree-dev      # Embree 3.13 (Debian 12)
 *   gcc -O2 -o embree_packets docs/bench-rays/embree_packets.c -lembree3
 *   phr bench-rays --scene scenes/suite/sponza.json --res 256 --threads 1 --no-embree \
 *       --export-rays --out /tmp/br
 *   ./embree_packets /tmp/br/rays/sponza diffuse [robust|high|robust-high]
 *
 * Prints the scene build time (one thread), Mrays/s of each call, best of 5 passes, and the
 * hit counts (equal for both calls).
 */
#include <embree3/rtcore.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

/* A `u32 count` then `count * width` little-endian floats (bench/embree_rays.py's format). */
static float *read_counted(const char *dir, const char *name, unsigned width, unsigned *count) {
    char path[1024];
    snprintf(path, sizeof path, "%s/%s", dir, name);
    FILE *f = fopen(path, "rb");
    if (!f || fread(count, 4, 1, f) != 1) {
        fprintf(stderr, "error: cannot read %s\n", path);
        exit(1);
    }
    float *data = malloc((size_t)*count * width * 4);
    if (!data || fread(data, 4, (size_t)*count * width, f) != (size_t)*count * width) {
        fprintf(stderr, "error: %s is shorter than its count\n", path);
        exit(1);
    }
    fclose(f);
    return data;
}

static double seconds(void) {
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return t.tv_sec + t.tv_nsec * 1e-9;
}

int main(int argc, char **argv) {
    if (argc < 3) {
        fprintf(stderr, "usage: %s DIR KIND [robust|high|robust-high]\n", argv[0]);
        return 2;
    }
    const char *dir = argv[1], *kind = argv[2];
    const char *mode = argc > 3 ? argv[3] : "default";
    int robust = strstr(mode, "robust") != NULL, high = strstr(mode, "high") != NULL;
    unsigned tris, rays, tfars;
    float *tri = read_counted(dir, "triangles.bin", 9, &tris);
    char name[256];
    snprintf(name, sizeof name, "rays_%s.bin", kind);
    float *ray = read_counted(dir, name, 6, &rays);
    snprintf(name, sizeof name, "tfar_%s.bin", kind);
    float *tfar = read_counted(dir, name, 1, &tfars);

    RTCDevice device = rtcNewDevice("threads=1");
    RTCScene scene = rtcNewScene(device);
    if (robust) rtcSetSceneFlags(scene, RTC_SCENE_FLAG_ROBUST);
    if (high) rtcSetSceneBuildQuality(scene, RTC_BUILD_QUALITY_HIGH);
    RTCGeometry mesh = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_TRIANGLE);
    if (high) rtcSetGeometryBuildQuality(mesh, RTC_BUILD_QUALITY_HIGH);
    float *vertices = rtcSetNewGeometryBuffer(mesh, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 12, tris * 3);
    unsigned *indices = rtcSetNewGeometryBuffer(mesh, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 12, tris);
    memcpy(vertices, tri, (size_t)tris * 36);
    for (unsigned i = 0; i < tris * 3; i++) indices[i] = i;
    rtcCommitGeometry(mesh);
    rtcAttachGeometry(scene, mesh);
    rtcReleaseGeometry(mesh);
    double build0 = seconds();
    rtcCommitScene(scene);
    double build_ms = (seconds() - build0) * 1e3;

    double best1 = 0, best8 = 0;
    unsigned hits1 = 0, hits8 = 0;
    struct RTCIntersectContext context;
    for (int pass = 0; pass < 5; pass++) {
        double t0 = seconds();
        hits1 = 0;
        for (unsigned i = 0; i < rays; i++) {
            struct RTCRayHit rh;
            const float *r = ray + 6 * (size_t)i;
            rh.ray.org_x = r[0], rh.ray.org_y = r[1], rh.ray.org_z = r[2];
            rh.ray.dir_x = r[3], rh.ray.dir_y = r[4], rh.ray.dir_z = r[5];
            rh.ray.tnear = 0, rh.ray.tfar = tfar[i], rh.ray.mask = -1, rh.ray.flags = 0, rh.ray.time = 0;
            rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
            rtcInitIntersectContext(&context);
            rtcIntersect1(scene, &context, &rh);
            hits1 += rh.hit.geomID != RTC_INVALID_GEOMETRY_ID;
        }
        double t1 = seconds();
        hits8 = 0;
        for (unsigned b = 0; b < rays; b += 8) {
            struct RTCRayHit8 rh __attribute__((aligned(32)));
            int valid[8] __attribute__((aligned(32)));
            for (unsigned l = 0; l < 8; l++) {
                unsigned i = b + l < rays ? b + l : rays - 1;
                const float *r = ray + 6 * (size_t)i;
                valid[l] = b + l < rays ? -1 : 0;
                rh.ray.org_x[l] = r[0], rh.ray.org_y[l] = r[1], rh.ray.org_z[l] = r[2];
                rh.ray.dir_x[l] = r[3], rh.ray.dir_y[l] = r[4], rh.ray.dir_z[l] = r[5];
                rh.ray.tnear[l] = 0, rh.ray.tfar[l] = tfar[i], rh.ray.mask[l] = -1;
                rh.ray.flags[l] = 0, rh.ray.time[l] = 0;
                rh.hit.geomID[l] = RTC_INVALID_GEOMETRY_ID;
            }
            rtcInitIntersectContext(&context);
            rtcIntersect8(valid, scene, &context, &rh);
            for (unsigned l = 0; l < 8; l++) hits8 += valid[l] && rh.hit.geomID[l] != RTC_INVALID_GEOMETRY_ID;
        }
        double t2 = seconds();
        if (rays / (t1 - t0) > best1) best1 = rays / (t1 - t0);
        if (rays / (t2 - t1) > best8) best8 = rays / (t2 - t1);
    }
    printf("%s %s %s: build %.1f ms, rtcIntersect1 %.2f Mrays/s (%u hits), rtcIntersect8 %.2f Mrays/s (%u hits)\n",
           dir, kind, mode, build_ms, best1 / 1e6, hits1, best8 / 1e6, hits8);
    rtcReleaseScene(scene);
    rtcReleaseDevice(device);
    return 0;
}
