/* Embree's side of the BVH comparison (benches/embree/run.sh; book: "Measuring a renderer:
 * the tools"). Reads the ray-set files written by `cargo run --release --example ray_sets --
 * write DIR` (format: examples/ray_sets/format.rs), builds one Embree 3 scene of triangles
 * with RTC_BUILD_QUALITY_HIGH on one thread, and traces every set with rtcIntersect1 /
 * rtcOccluded1 ("1") and with 8-ray packets rtcIntersect8 / rtcOccluded8 ("8"), printing
 *
 *     BUILD embree SCENE TRIANGLES CPU_SECONDS
 *     RESULT embree SCENE SET KIND MODE RAYS CPU_SECONDS HITS SUM_T MRAYS_PER_S
 *
 * with the checksum of format.rs: hits and the sum of hit distances (t_max of blocked rays).
 *
 *     embree_trace DIR [--passes P] [--robust] [--verbose] SCENE...
 *
 * --verbose creates the device with verbose=2: Embree then prints, for each build, its tree's
 * surface area heuristic cost, nodes and leaf blocks (what pathspace's `SAH` lines of
 * `ray_sets trace` give in the same units).
 *
 * Embree 3.13 picks its widest compiled ISA at run time (AVX-512 or AVX2 on a recent x86-64).
 * Scene flags: none by default (Embree's fast path); --robust sets RTC_SCENE_FLAG_ROBUST. */
#include <embree3/rtcore.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#if defined(__x86_64__)
#include <pmmintrin.h>
#include <xmmintrin.h>
#endif

static const char *SETS[3] = {"camera", "bounce", "shadow"};

static double cpu_seconds(void) {
  struct timespec ts;
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return ts.tv_sec + ts.tv_nsec * 1e-9;
}

/* The whole file, checked to be `magic`, a header of `header` bytes ending in the u64 count,
 * and exactly count records of `record` bytes. Exits with a message otherwise. */
static unsigned char *read_file(const char *path, const char *magic, size_t header,
                                size_t record, uint64_t *count) {
  FILE *f = fopen(path, "rb");
  if (!f) { fprintf(stderr, "embree_trace: cannot open %s\n", path); exit(1); }
  fseek(f, 0, SEEK_END);
  long size = ftell(f);
  fseek(f, 0, SEEK_SET);
  unsigned char *bytes = malloc(size > 0 ? size : 1);
  if (!bytes || fread(bytes, 1, size, f) != (size_t)size) {
    fprintf(stderr, "embree_trace: cannot read %s\n", path); exit(1);
  }
  fclose(f);
  if ((size_t)size < header || memcmp(bytes, magic, 8) != 0) {
    fprintf(stderr, "embree_trace: %s: not a ray-set file\n", path); exit(1);
  }
  memcpy(count, bytes + header - 8, 8); /* little-endian host assumed (x86-64, aarch64) */
  if (header + *count * record != (uint64_t)size) {
    fprintf(stderr, "embree_trace: %s: records do not fill the file\n", path); exit(1);
  }
  return bytes;
}

static RTCScene build(RTCDevice dev, const char *dir, const char *name, int robust) {
  char path[4096];
  uint64_t n;
  snprintf(path, sizeof path, "%s/%s.tri", dir, name);
  unsigned char *bytes = read_file(path, "PSTRI001", 16, 36, &n);
  double start = cpu_seconds();
  RTCScene scene = rtcNewScene(dev);
  rtcSetSceneBuildQuality(scene, RTC_BUILD_QUALITY_HIGH);
  rtcSetSceneFlags(scene, robust ? RTC_SCENE_FLAG_ROBUST : RTC_SCENE_FLAG_NONE);
  RTCGeometry g = rtcNewGeometry(dev, RTC_GEOMETRY_TYPE_TRIANGLE);
  rtcSetGeometryBuildQuality(g, RTC_BUILD_QUALITY_HIGH);
  float *v = rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3,
                                     3 * sizeof(float), 3 * n);
  unsigned *idx = rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3,
                                          3 * sizeof(unsigned), n);
  memcpy(v, bytes + 16, n * 36);
  for (uint64_t i = 0; i < 3 * n; i++) idx[i] = (unsigned)i;
  rtcCommitGeometry(g);
  rtcAttachGeometry(scene, g);
  rtcReleaseGeometry(g);
  rtcCommitScene(scene);
  printf("BUILD embree %s %llu %.4f\n", name, (unsigned long long)n, cpu_seconds() - start);
  free(bytes);
  return scene;
}

/* One ray record: origin, t_min, direction, t_max. */
typedef struct { float o[3], tnear, d[3], tfar; } Record;

static void trace1(RTCScene scene, const Record *r, uint64_t n, int any, uint64_t *hits,
                   double *sum) {
  struct RTCIntersectContext ctx;
  rtcInitIntersectContext(&ctx);
  for (uint64_t i = 0; i < n; i++) {
    struct RTCRayHit rh;
    rh.ray.org_x = r[i].o[0]; rh.ray.org_y = r[i].o[1]; rh.ray.org_z = r[i].o[2];
    rh.ray.dir_x = r[i].d[0]; rh.ray.dir_y = r[i].d[1]; rh.ray.dir_z = r[i].d[2];
    rh.ray.tnear = r[i].tnear; rh.ray.tfar = r[i].tfar;
    rh.ray.time = 0.0f; rh.ray.mask = -1; rh.ray.id = 0; rh.ray.flags = 0;
    if (any) {
      rtcOccluded1(scene, &ctx, &rh.ray);
      if (rh.ray.tfar == -INFINITY) { (*hits)++; *sum += r[i].tfar; }
    } else {
      rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
      rtcIntersect1(scene, &ctx, &rh);
      if (rh.hit.geomID != RTC_INVALID_GEOMETRY_ID) { (*hits)++; *sum += rh.ray.tfar; }
    }
  }
}

/* The same in packets of 8 consecutive rays (the last one partly valid). */
static void trace8(RTCScene scene, const Record *r, uint64_t n, int any, uint64_t *hits,
                   double *sum) {
  struct RTCIntersectContext ctx;
  rtcInitIntersectContext(&ctx);
  for (uint64_t base = 0; base < n; base += 8) {
    _Alignas(32) struct RTCRayHit8 rh;
    _Alignas(32) int valid[8];
    for (int k = 0; k < 8; k++) {
      uint64_t i = base + k < n ? base + k : n - 1;
      valid[k] = base + k < n ? -1 : 0;
      rh.ray.org_x[k] = r[i].o[0]; rh.ray.org_y[k] = r[i].o[1]; rh.ray.org_z[k] = r[i].o[2];
      rh.ray.dir_x[k] = r[i].d[0]; rh.ray.dir_y[k] = r[i].d[1]; rh.ray.dir_z[k] = r[i].d[2];
      rh.ray.tnear[k] = r[i].tnear; rh.ray.tfar[k] = r[i].tfar;
      rh.ray.time[k] = 0.0f; rh.ray.mask[k] = -1; rh.ray.id[k] = 0; rh.ray.flags[k] = 0;
      rh.hit.geomID[k] = RTC_INVALID_GEOMETRY_ID;
    }
    if (any) {
      rtcOccluded8(valid, scene, &ctx, &rh.ray);
      for (int k = 0; k < 8; k++)
        if (valid[k] && rh.ray.tfar[k] == -INFINITY) { (*hits)++; *sum += r[base + k].tfar; }
    } else {
      rtcIntersect8(valid, scene, &ctx, &rh);
      for (int k = 0; k < 8; k++)
        if (valid[k] && rh.hit.geomID[k] != RTC_INVALID_GEOMETRY_ID) {
          (*hits)++; *sum += rh.ray.tfar[k];
        }
    }
  }
}

int main(int argc, char **argv) {
  if (argc < 3) {
    fprintf(stderr, "usage: embree_trace DIR [--passes P] [--robust] [--verbose] SCENE...\n");
    return 2;
  }
  const char *dir = argv[1];
  int passes = 3, robust = 0;
#if defined(__x86_64__)
  /* flush-to-zero and denormals-are-zero, as Embree asks of every thread that traces */
  _MM_SET_FLUSH_ZERO_MODE(_MM_FLUSH_ZERO_ON);
  _MM_SET_DENORMALS_ZERO_MODE(_MM_DENORMALS_ZERO_ON);
#endif
  int verbose = 0;
  for (int a = 2; a < argc; a++) verbose |= !strcmp(argv[a], "--verbose");
  /* one build and traversal thread, like pathspace's side */
  RTCDevice dev = rtcNewDevice(verbose ? "threads=1,verbose=2" : "threads=1");
  if (!dev) { fprintf(stderr, "embree_trace: no Embree device\n"); return 1; }
  printf("EMBREE %s\n", RTC_VERSION_STRING);
  for (int a = 2; a < argc; a++) {
    if (!strcmp(argv[a], "--passes") && a + 1 < argc) { passes = atoi(argv[++a]); continue; }
    if (!strcmp(argv[a], "--robust")) { robust = 1; continue; }
    if (!strcmp(argv[a], "--verbose")) continue;
    const char *name = argv[a];
    RTCScene scene = build(dev, dir, name, robust);
    for (int s = 0; s < 3; s++) {
      char path[4096];
      uint64_t n;
      snprintf(path, sizeof path, "%s/%s.%s.rays", dir, name, SETS[s]);
      unsigned char *bytes = read_file(path, "PSRAY001", 24, 32, &n);
      uint32_t kind;
      memcpy(&kind, bytes + 8, 4);
      const Record *rays = (const Record *)(bytes + 24);
      for (int mode = 1; mode <= 8; mode += 7) {
        uint64_t hits = 0;
        double sum = 0.0, start = cpu_seconds();
        for (int p = 0; p < passes; p++) {
          hits = 0; sum = 0.0;
          (mode == 1 ? trace1 : trace8)(scene, rays, n, kind == 1, &hits, &sum);
        }
        double seconds = cpu_seconds() - start;
        printf("RESULT embree %s %s %s %d %llu %.6f %llu %.6f %.3f\n", name, SETS[s],
               kind == 1 ? "any" : "closest", mode, (unsigned long long)(n * passes), seconds,
               (unsigned long long)hits, sum, n * passes / seconds * 1e-6);
      }
      free(bytes);
    }
    rtcReleaseScene(scene);
  }
  rtcReleaseDevice(dev);
  return 0;
}
