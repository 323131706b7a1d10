// A peer, side by side (docs/performance.md): the project's exact ray caster against Intel Embree 3
// on the same rays in the same scene. Embree traces triangles and quads, not curves, so every
// segment of the benchmarks' 49-cubic room is tessellated into straight pieces whose chord error
// is at most 1e-4 of the scene's size, each extruded into a quad across the plane (z from -1 to
// 1), and rays travel in the plane z = 0. The rays are the shooter's: from a point of a segment
// (uniform in its parameter) in a diffuse direction about its front normal. Both casters run on
// one thread; Embree's build uses its own threads and is not timed.
//
//   build/flatland_embree_bench --benchmark_min_time=1
//
// ExactCaster is the caster as the shooter calls it (the line-space grid first), ExactTree its tree
// alone.
//
// Built only when CMake finds Embree 3 (Debian's libembree-dev); optional, never a test.
#include <cmath>
#include <cstdio>
#include <vector>

#include <benchmark/benchmark.h>
#include <embree3/rtcore.h>

#include "flatland/geometry/accelerator.hpp"
#include "flatland/geometry/bezier.hpp"
#include "flatland/scene/scene.hpp"
#include "flatland/transport/sampling.hpp"

#include "bench_scenes.hpp"

namespace {

using namespace flatland;

using bench::CastRay;
using bench::kRays;

// Appends the end points of straight pieces of c (after its start point) whose control points lie
// within `tolerance` of their chord: the curve, inside its control hull, is then too.
void tessellate(const Cubic& c, double tolerance, int depth, std::vector<Vec2>& points) {
  const Vec2 chord = c.p[3] - c.p[0];
  const double chord_length = length(chord);
  double deviation = 0.0;
  for (int i = 1; i <= 2; ++i) {
    const Vec2 d = c.p[i] - c.p[0];
    deviation = std::max(deviation, chord_length > 0.0 ? std::fabs(cross(chord, d)) / chord_length : length(d));
  }
  if (deviation <= tolerance || depth >= 24) {
    points.push_back(c.p[3]);
    return;
  }
  const auto [left, right] = split(c, 0.5);
  tessellate(left, tolerance, depth + 1, points);
  tessellate(right, tolerance, depth + 1, points);
}

struct Setup {
  Scene scene;
  SegmentAccelerator exact;
  std::vector<CastRay> rays;
  RTCDevice device = nullptr;
  RTCScene embree = nullptr;
  std::size_t quads = 0;
  double tnear = 0.0;

  Setup() {
    Result<Scene> parsed = parse_scene(bench::make_scene(bench::Layout::Cubics), "benchmark");
    if (!parsed) {
      std::fprintf(stderr, "%s\n", parsed.error().message.c_str());
      std::abort();
    }
    scene = std::move(*parsed);
    std::vector<SegmentGeometry> geometry;
    for (const SceneSegment& segment : scene.segments) geometry.push_back(segment.geometry);
    exact = SegmentAccelerator(geometry);

    // The shooter's rays: a point of a segment chosen by length, a diffuse direction.
    std::vector<double> lengths;
    for (const SceneSegment& segment : scene.segments) lengths.push_back(segment.length);
    const DiscreteDistribution choice(lengths);
    Rng rng(1, 0, 0);
    for (std::size_t i = 0; i < kRays; ++i) {
      const auto s = static_cast<std::uint32_t>(choice.sample(rng.uniform()));
      const Cubic& shape = scene.segments[s].geometry.shape;
      const double t = rng.uniform_open();
      const Vec2 normal = unit_normal(shape, t, scene.scale);
      rays.push_back({Ray{evaluate(shape, t), square_to_diffuse(rng.uniform(), normal)}, RayOrigin{s, t}});
    }

    // The tessellation, extruded into quads.
    const double tolerance = 1e-4 * scene.scale;
    tnear = 10.0 * tolerance;  // a ray leaves the exact curve, which its own pieces may miss by up to the tolerance
    std::vector<float> vertices;
    std::vector<unsigned> indices;
    for (const SceneSegment& segment : scene.segments) {
      std::vector<Vec2> points{segment.geometry.shape.p[0]};
      if (segment.geometry.kind == SegmentKind::Line)
        points.push_back(segment.geometry.shape.p[3]);
      else
        tessellate(segment.geometry.shape, tolerance, 0, points);
      for (std::size_t k = 0; k + 1 < points.size(); ++k) {
        const auto base = static_cast<unsigned>(vertices.size() / 3);
        for (const Vec2& p : {points[k], points[k + 1]})
          for (const float z : {-1.0f, 1.0f}) vertices.insert(vertices.end(), {float(p.x), float(p.y), z});
        // (a, -1), (a, 1), (b, -1), (b, 1) -> the quad a-1, b-1, b+1, a+1
        indices.insert(indices.end(), {base, base + 2, base + 3, base + 1});
      }
    }
    quads = indices.size() / 4;
    device = rtcNewDevice(nullptr);
    embree = rtcNewScene(device);
    RTCGeometry quad_geometry = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_QUAD);
    auto* v = static_cast<float*>(rtcSetNewGeometryBuffer(quad_geometry, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3,
                                                          3 * sizeof(float), vertices.size() / 3));
    std::copy(vertices.begin(), vertices.end(), v);
    auto* q = static_cast<unsigned*>(rtcSetNewGeometryBuffer(quad_geometry, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT4,
                                                             4 * sizeof(unsigned), quads));
    std::copy(indices.begin(), indices.end(), q);
    rtcCommitGeometry(quad_geometry);
    rtcAttachGeometry(embree, quad_geometry);
    rtcReleaseGeometry(quad_geometry);
    rtcSetSceneBuildQuality(embree, RTC_BUILD_QUALITY_HIGH);
    rtcCommitScene(embree);
  }

  RTCRayHit embree_ray(const CastRay& r) const {
    RTCRayHit rh{};
    rh.ray.org_x = static_cast<float>(r.ray.origin.x);
    rh.ray.org_y = static_cast<float>(r.ray.origin.y);
    rh.ray.org_z = 0.0f;
    rh.ray.dir_x = static_cast<float>(r.ray.direction.x);
    rh.ray.dir_y = static_cast<float>(r.ray.direction.y);
    rh.ray.dir_z = 0.0f;
    rh.ray.tnear = static_cast<float>(tnear);
    rh.ray.tfar = INFINITY;
    rh.ray.mask = 0xffffffffu;
    rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
    return rh;
  }
};

const Setup& setup() {
  static const Setup instance;
  return instance;
}

// The exact caster on every ray in turn: as the shooter calls it (ExactCaster: the line-space grid,
// the tree for its overfull cells) or its tree alone (ExactTree: the caster before the grid).
void cast_exact(benchmark::State& state, bool tree_only) {
  const Setup& s = setup();
  std::size_t i = 0;
  std::uint64_t casts = 0;
  for (auto _ : state) {
    const CastRay& r = s.rays[i++ % kRays];
    benchmark::DoNotOptimize(tree_only ? s.exact.closest_hit_tree(r.ray, r.from) : s.exact.closest_hit(r.ray, r.from));
    ++casts;
  }
  state.counters["casts_per_second"] = benchmark::Counter(static_cast<double>(casts), benchmark::Counter::kIsRate);
  state.counters["segments"] = static_cast<double>(s.scene.segments.size());
}

void ExactCaster(benchmark::State& state) { cast_exact(state, false); }
void ExactTree(benchmark::State& state) { cast_exact(state, true); }

void EmbreeIntersect1(benchmark::State& state) {
  const Setup& s = setup();
  RTCIntersectContext context;
  rtcInitIntersectContext(&context);
  std::size_t i = 0;
  std::uint64_t casts = 0;
  for (auto _ : state) {
    RTCRayHit rh = s.embree_ray(s.rays[i++ % kRays]);
    rtcIntersect1(s.embree, &context, &rh);
    benchmark::DoNotOptimize(rh.ray.tfar);
    ++casts;
  }
  state.counters["casts_per_second"] = benchmark::Counter(static_cast<double>(casts), benchmark::Counter::kIsRate);
  state.counters["quads"] = static_cast<double>(s.quads);
}

// Packets of 8 rays (incoherent: consecutive rays of the shooter start anywhere).
void EmbreeIntersect8(benchmark::State& state) {
  const Setup& s = setup();
  RTCIntersectContext context;
  rtcInitIntersectContext(&context);
  alignas(32) int valid[8];
  for (int& v : valid) v = -1;
  std::size_t i = 0;
  std::uint64_t casts = 0;
  for (auto _ : state) {
    alignas(32) RTCRayHit8 packet;
    for (int k = 0; k < 8; ++k) {
      const RTCRayHit rh = s.embree_ray(s.rays[i++ % kRays]);
      packet.ray.org_x[k] = rh.ray.org_x;
      packet.ray.org_y[k] = rh.ray.org_y;
      packet.ray.org_z[k] = 0.0f;
      packet.ray.dir_x[k] = rh.ray.dir_x;
      packet.ray.dir_y[k] = rh.ray.dir_y;
      packet.ray.dir_z[k] = 0.0f;
      packet.ray.tnear[k] = rh.ray.tnear;
      packet.ray.tfar[k] = INFINITY;
      packet.ray.mask[k] = 0xffffffffu;
      packet.ray.time[k] = 0.0f;
      packet.ray.flags[k] = 0;
      packet.hit.geomID[k] = RTC_INVALID_GEOMETRY_ID;
    }
    rtcIntersect8(valid, s.embree, &context, &packet);
    benchmark::DoNotOptimize(packet.ray.tfar[0]);
    casts += 8;
  }
  state.counters["casts_per_second"] = benchmark::Counter(static_cast<double>(casts), benchmark::Counter::kIsRate);
}

// Whether the two answer the same question: the share of rays on which they agree (both miss, or
// both hit within 10 tolerances of each other), printed once.
void Agreement(benchmark::State& state) {
  const Setup& s = setup();
  RTCIntersectContext context;
  rtcInitIntersectContext(&context);
  std::size_t agree = 0;
  for (auto _ : state) {
    agree = 0;
    for (const CastRay& r : s.rays) {
      const SceneHit hit = s.exact.closest_hit(r.ray, r.from);
      RTCRayHit rh = s.embree_ray(r);
      rtcIntersect1(s.embree, &context, &rh);
      const bool exact_hits = hit.segment != kNoSegment;
      const bool embree_hits = rh.hit.geomID != RTC_INVALID_GEOMETRY_ID;
      if (exact_hits == embree_hits && (!exact_hits || std::fabs(hit.distance - rh.ray.tfar) <= 10.0 * s.tnear))
        ++agree;
    }
  }
  state.counters["agreeing_share"] = static_cast<double>(agree) / kRays;
}

}  // namespace

BENCHMARK(ExactCaster);
BENCHMARK(ExactTree);
BENCHMARK(EmbreeIntersect1);
BENCHMARK(EmbreeIntersect8);
BENCHMARK(Agreement)->Iterations(1)->Unit(benchmark::kMillisecond);

BENCHMARK_MAIN();
