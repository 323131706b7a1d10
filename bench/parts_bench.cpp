// A photon's parts one at a time, on the benchmarks' 49-cubic room (bench_scenes.hpp): the least
// work an exact photon can do, against which docs/performance.md ("The physical limit") sets
// what a photon takes in the solver.
//
//   taskset -c 1 build/flatland_parts_bench --benchmark_min_time=1 --benchmark_repetitions=3
//
// Each benchmark cycles through kRays precomputed inputs (the random numbers are drawn before
// the clock starts), one operation an iteration:
// - CubicHit: the exact ray-cubic test (`intersect_cubic`) of a shooter's ray against the cubic it
//   hits first, found beforehand; a cast by an oracle that knew the segment would take this alone.
// - CubicMiss: the same test of the ray against another cubic whose control points' box the ray
//   crosses before its hit (a candidate the caster hands to the exact test, which rejects it).
// - LineHit: the ray-line test of the same room's rays written as lines (`intersect_line`).
// - Deposit: a unit of power shared among the cubic basis functions alive at a point of a 64-element
//   curve (SplineBasis::evaluate and the integer shares, as the shooter deposits a point ray).
// - SobolPoint: the next point of a scrambled Sobol' net and four of its coordinates (the
//   shooter's place, piece, direction and speed test).
// - Origin: a place drawn from a cubic basis function by inverting its CDF (BasisSampler::sample),
//   the curve's point and tangent there, and a diffuse direction about its normal.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <utility>
#include <vector>

#include <benchmark/benchmark.h>

#include "flatland/base/random.hpp"
#include "flatland/geometry/accelerator.hpp"
#include "flatland/geometry/intersect.hpp"
#include "flatland/scene/scene.hpp"
#include "flatland/storage/curve_storage.hpp"
#include "flatland/transport/qmc.hpp"
#include "flatland/transport/sampling.hpp"

#include "bench_scenes.hpp"

namespace {

using namespace flatland;

using bench::kRays;

Scene room(bench::Layout layout) {
  Result<Scene> parsed = parse_scene(bench::make_scene(layout), "benchmark");
  if (!parsed) {
    std::fprintf(stderr, "%s\n", parsed.error().message.c_str());
    std::abort();
  }
  return std::move(*parsed);
}

// Whether the ray meets the box of the cubic's control points within `reach` (slab test).
bool crosses_box(const Ray& ray, const Cubic& shape, double reach) {
  double enter = 0.0;
  double leave = reach;
  for (int axis = 0; axis < 2; ++axis) {
    double low = std::numeric_limits<double>::infinity();
    double high = -low;
    for (const Vec2& p : shape.p) {
      low = std::min(low, axis == 0 ? p.x : p.y);
      high = std::max(high, axis == 0 ? p.x : p.y);
    }
    const double origin = axis == 0 ? ray.origin.x : ray.origin.y;
    const double direction = axis == 0 ? ray.direction.x : ray.direction.y;
    if (direction == 0.0) {
      if (origin < low || origin > high) return false;
      continue;
    }
    double a = (low - origin) / direction;
    double b = (high - origin) / direction;
    if (a > b) std::swap(a, b);
    enter = std::max(enter, a);
    leave = std::min(leave, b);
  }
  return enter <= leave;
}

// A ray and the segment it is tested against.
struct Test {
  Ray ray;
  std::uint32_t segment = 0;
  double reach = std::numeric_limits<double>::infinity();  // the test's max_distance
};

// Rays from points of the room's segments (chosen uniformly among segments, uniform in t) in a
// diffuse direction about either normal; `hit`: each against the segment it meets first (rays that
// meet none are left out), else against another segment whose box its line crosses.
std::vector<Test> tests(const Scene& scene, bool hit) {
  std::vector<SegmentGeometry> geometry;
  for (const SceneSegment& segment : scene.segments) geometry.push_back(segment.geometry);
  const SegmentAccelerator caster(std::move(geometry));
  Rng rng(7, 0, 0);
  std::vector<Test> out;
  const auto segments = static_cast<std::uint32_t>(scene.segments.size());
  while (out.size() < kRays) {
    const auto s = std::min(segments - 1, static_cast<std::uint32_t>(rng.uniform() * segments));
    const Cubic& shape = scene.segments[s].geometry.shape;
    const double t = rng.uniform_open();
    Vec2 normal = unit_normal(shape, t, scene.scale);
    if (rng.uniform() < 0.5) normal = -1.0 * normal;
    const Ray ray{evaluate(shape, t), square_to_diffuse(rng.uniform(), normal)};
    const SceneHit first = caster.closest_hit(ray, RayOrigin{s, t});
    if (first.segment == kNoSegment) continue;
    if (hit) {
      out.push_back({ray, first.segment, std::numeric_limits<double>::infinity()});
      continue;
    }
    // Another segment, not the ray's own nor the one it hits, whose control points' box the ray
    // crosses before it stops: a candidate a caster's tree or grid hands to the exact test, which
    // rejects it.
    const auto other = std::min(segments - 1, static_cast<std::uint32_t>(rng.uniform() * segments));
    if (other == s || other == first.segment || !crosses_box(ray, scene.segments[other].geometry.shape, first.distance))
      continue;
    out.push_back({ray, other, first.distance});
  }
  return out;
}

void CubicTest(benchmark::State& state, bool hit) {
  const Scene scene = room(bench::Layout::Cubics);
  const std::vector<Test> cases = tests(scene, hit);
  std::size_t i = 0;
  std::size_t hits = 0;
  for (auto _ : state) {
    const Test& test = cases[i];
    SegmentHit result;
    hits += intersect_cubic(scene.segments[test.segment].geometry.shape, test.ray, test.reach, &result) ? 1 : 0;
    benchmark::DoNotOptimize(result);
    i = (i + 1) % cases.size();
  }
  state.counters["hit share"] = static_cast<double>(hits) / static_cast<double>(state.iterations());
}

void CubicHit(benchmark::State& state) { CubicTest(state, true); }
void CubicMiss(benchmark::State& state) { CubicTest(state, false); }

void LineHit(benchmark::State& state) {
  const Scene scene = room(bench::Layout::Lines);
  const std::vector<Test> cases = tests(scene, true);
  std::size_t i = 0;
  for (auto _ : state) {
    const Test& test = cases[i];
    const Cubic& shape = scene.segments[test.segment].geometry.shape;
    SegmentHit result;
    benchmark::DoNotOptimize(
        intersect_line(shape.p[0], shape.p[3], test.ray, std::numeric_limits<double>::infinity(), &result));
    benchmark::DoNotOptimize(result);
    i = (i + 1) % cases.size();
  }
}

// The room's wall (its longest curve) with cubic storage of 64 elements a segment.
CurveStorage wall_storage(const Scene& scene, std::size_t& curve) {
  curve = 0;
  for (std::size_t c = 1; c < scene.curves.size(); ++c)
    if (scene.curves[c].segment_count > scene.curves[curve].segment_count) curve = c;
  return build_curve_storage(scene, scene.curves[curve], BasisKind::Cubic, 64);
}

void Deposit(benchmark::State& state) {
  const Scene scene = room(bench::Layout::Cubics);
  std::size_t curve = 0;
  const CurveStorage storage = wall_storage(scene, curve);
  const SplineBasis& basis = storage.basis;
  Rng rng(11, 0, 0);
  std::vector<double> places(kRays);
  const double span = basis.u_end() - basis.u_begin();
  for (double& u : places) u = basis.u_begin() + rng.uniform() * span;
  std::vector<std::int64_t> received(basis.size(), 0);
  const std::int64_t units = std::int64_t{1} << 40;
  const auto degree = static_cast<std::size_t>(basis.degree());
  std::size_t i = 0;
  for (auto _ : state) {
    std::array<double, SplineBasis::kMaxDegree + 1> phi{};
    const std::size_t first = basis.evaluate(places[i], phi.data());
    std::int64_t left = units;
    for (std::size_t j = 0; j < degree; ++j) {
      const auto share = static_cast<std::int64_t>(phi[j] * static_cast<double>(units) + 0.5);
      received[basis.index(first + j)] += share;
      left -= share;
    }
    received[basis.index(first + degree)] += left;
    i = (i + 1) % places.size();
  }
  benchmark::DoNotOptimize(received.data());
}

void SobolPoint(benchmark::State& state) {
  const ScrambledSobol sobol(3, 0);
  SobolCursor cursor(sobol);
  std::uint32_t index = 0;
  for (auto _ : state) {
    cursor.seek(index);
    double sum = cursor.sample(0) + cursor.sample(1) + cursor.sample(2) + cursor.sample(3);
    benchmark::DoNotOptimize(sum);
    index = (index + 1) % (1u << 20);
  }
}

void Origin(benchmark::State& state) {
  const Scene scene = room(bench::Layout::Cubics);
  std::size_t curve = 0;
  const CurveStorage storage = wall_storage(scene, curve);
  const Curve& wall = scene.curves[curve];
  struct Draw {
    std::size_t k;
    double u1, u2, direction;
  };
  Rng rng(13, 0, 0);
  std::vector<Draw> draws(kRays);
  for (Draw& d : draws) {
    const std::size_t functions = storage.basis.size();
    d.k = std::min(functions - 1, static_cast<std::size_t>(rng.uniform() * static_cast<double>(functions)));
    d.u1 = rng.uniform();
    d.u2 = rng.uniform();
    d.direction = rng.uniform();
  }
  std::size_t i = 0;
  for (auto _ : state) {
    const Draw& d = draws[i];
    const double u = storage.sampler.sample(d.k, d.u1, d.u2);
    const auto local = static_cast<std::uint32_t>(std::min<double>(std::floor(u), wall.segment_count - 1.0));
    const Cubic& shape = scene.segments[wall.first_segment + local].geometry.shape;
    const double t = u - local;
    const Vec2 velocity = derivative(shape, t);
    const Vec2 tangent = (1.0 / length(velocity)) * velocity;
    const Vec2 position = evaluate(shape, t);
    const Vec2 direction = square_to_diffuse(d.direction, perp(tangent));
    benchmark::DoNotOptimize(position);
    benchmark::DoNotOptimize(direction);
    i = (i + 1) % draws.size();
  }
}

}  // namespace

BENCHMARK(CubicHit);
BENCHMARK(CubicMiss);
BENCHMARK(LineHit);
BENCHMARK(Deposit);
BENCHMARK(SobolPoint);
BENCHMARK(Origin);

BENCHMARK_MAIN();
