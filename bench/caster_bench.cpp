// Casters side by side (docs/performance.md, "A caster made for the plane"): the BVH
// (SegmentAccelerator) against the grid over the space of lines (LineSpaceCaster), on the shooter's
// rays: from a point of a segment (chosen by length, uniform in its parameter) in a diffuse
// direction about its normal, one thread.
//
//   build/flatland_caster_bench --benchmark_min_time=1
//
// Room/A/M: the benchmarks' 49-cubic room (bench_scenes.hpp); A = 0 is the BVH, otherwise the grid
// with A angle bins and M offset cells (and the default cell limit, the BVH taking the rays of
// overfull cells, as SegmentAccelerator does). Rooms/N/A/M: a wavy closed wall of N/2 cubics around N/2
// short two-sided cubic obstacles, for the size at which one caster overtakes the other.
#include <cmath>
#include <cstdio>
#include <numbers>
#include <vector>

#include <benchmark/benchmark.h>

#include "flatland/base/discrete_distribution.hpp"
#include "flatland/base/random.hpp"
#include "flatland/geometry/accelerator.hpp"
#include "flatland/geometry/line_space.hpp"
#include "flatland/scene/scene.hpp"
#include "flatland/transport/sampling.hpp"

#include "bench_scenes.hpp"

namespace {

using namespace flatland;

using bench::CastRay;
using bench::kRays;

std::vector<CastRay> shooter_rays(const std::vector<SegmentGeometry>& segments, double scale) {
  std::vector<double> lengths;
  for (const SegmentGeometry& g : segments) lengths.push_back(arc_length(g.shape));
  const DiscreteDistribution choice(lengths);
  Rng rng(1, 0, 0);
  std::vector<CastRay> rays;
  for (std::size_t i = 0; i < kRays; ++i) {
    const auto s = static_cast<std::uint32_t>(choice.sample(rng.uniform()));
    const Cubic& shape = segments[s].shape;
    const double t = rng.uniform_open();
    Vec2 normal = unit_normal(shape, t, scale);
    if (rng.uniform() < 0.5) normal = -1.0 * normal;  // either side: the obstacles are two-sided
    rays.push_back({Ray{evaluate(shape, t), square_to_diffuse(rng.uniform(), normal)}, RayOrigin{s, t}});
  }
  return rays;
}

std::vector<SegmentGeometry> room_segments() {
  Result<Scene> parsed = parse_scene(bench::make_scene(bench::Layout::Cubics), "benchmark");
  if (!parsed) {
    std::fprintf(stderr, "%s\n", parsed.error().message.c_str());
    std::abort();
  }
  std::vector<SegmentGeometry> geometry;
  for (const SceneSegment& segment : parsed->segments) geometry.push_back(segment.geometry);
  return geometry;
}

// A wavy closed wall of n/2 cubics (radius about 5) around n/2 obstacles of length 0.4 * 10/sqrt(n).
std::vector<SegmentGeometry> rooms_segments(int n) {
  std::vector<SegmentGeometry> out;
  const int wall = std::max(n / 2, 3);
  auto ring = [](double angle) {
    const double radius = 5.0 + 0.6 * std::sin(5 * angle);
    return Vec2{radius * std::cos(angle), radius * std::sin(angle)};
  };
  for (int i = 0; i < wall; ++i) {
    const double a = 2 * std::numbers::pi * i / wall;
    const double b = 2 * std::numbers::pi * (i + 1) / wall;
    const Vec2 p = ring(a);
    const Vec2 q = ring(b);
    const Vec2 bend = 0.15 * Vec2{-(q - p).y, (q - p).x};
    out.push_back({SegmentKind::Cubic, Cubic{{p, lerp(p, q, 1.0 / 3) + bend, lerp(p, q, 2.0 / 3) + bend, q}}});
  }
  Rng rng(7, 0, 0);
  const double size = 4.0 / std::sqrt(std::max(n, 1));
  for (int i = wall; i < n; ++i) {
    const double r = 4.0 * std::sqrt(rng.uniform());
    const double a = 2 * std::numbers::pi * rng.uniform();
    const Vec2 p{r * std::cos(a), r * std::sin(a)};
    const double turn = 2 * std::numbers::pi * rng.uniform();
    const Vec2 q = p + size * Vec2{std::cos(turn), std::sin(turn)};
    const Vec2 bend = 0.3 * Vec2{-(q - p).y, (q - p).x};
    out.push_back({SegmentKind::Cubic, Cubic{{p, lerp(p, q, 1.0 / 3) + bend, lerp(p, q, 2.0 / 3) + bend, q}}});
  }
  return out;
}

void cast(benchmark::State& state, const std::vector<SegmentGeometry>& segments, int bins, int cells) {
  const std::vector<CastRay> rays = shooter_rays(segments, 10.0);
  const SegmentAccelerator tree(segments);
  const LineSpaceCaster grid = bins > 0 ? LineSpaceCaster(segments, {bins, cells}) : LineSpaceCaster();
  std::size_t i = 0;
  std::uint64_t casts = 0;
  for (auto _ : state) {
    const CastRay& r = rays[i++ % kRays];
    SceneHit hit;
    if (bins == 0 || !grid.closest_hit(r.ray, r.from, &hit)) hit = tree.closest_hit_tree(r.ray, r.from);
    benchmark::DoNotOptimize(hit);
    ++casts;
  }
  state.counters["casts_per_second"] = benchmark::Counter(static_cast<double>(casts), benchmark::Counter::kIsRate);
  state.counters["segments"] = static_cast<double>(segments.size());
  state.counters["MB"] = bins > 0 ? static_cast<double>(grid.memory_bytes()) / 1e6 : 0.0;
}

void Room(benchmark::State& state) {
  static const std::vector<SegmentGeometry> segments = room_segments();
  cast(state, segments, static_cast<int>(state.range(0)), static_cast<int>(state.range(1)));
}

void Rooms(benchmark::State& state) {
  const std::vector<SegmentGeometry> segments = rooms_segments(static_cast<int>(state.range(0)));
  cast(state, segments, static_cast<int>(state.range(1)), static_cast<int>(state.range(2)));
}

// The build: the tree alone (B = 0) or the tree and the grid (B = 1), as SegmentAccelerator makes
// them.
void Build(benchmark::State& state) {
  const std::vector<SegmentGeometry> segments = rooms_segments(static_cast<int>(state.range(0)));
  const auto queries = state.range(1) == 0 ? SegmentAccelerator::Queries::Overlaps : SegmentAccelerator::Queries::Rays;
  for (auto _ : state) benchmark::DoNotOptimize(SegmentAccelerator(segments, queries).uses_line_space());
}

}  // namespace

BENCHMARK(Build)->ArgsProduct({{16, 64, 512}, {0, 1}})->Unit(benchmark::kMillisecond);
BENCHMARK(Room)->Args({0, 0})->ArgsProduct({{32, 64, 128}, {64, 128, 256}});
BENCHMARK(Rooms)->ArgsProduct({{16, 64, 256, 512, 1024, 4096}, {0, 64}, {128}});

BENCHMARK_MAIN();
