// Photon throughput of the shooter (docs/performance.md). Three scenes with the same layout of
// about 50 segments: real cubics, straight lines, and the same straight lines written as cubics
// (inner control points at the thirds), so the line fast path can be compared with the cubic one.
#include <cmath>
#include <numbers>
#include <string>
#include <utility>
#include <vector>

#include <benchmark/benchmark.h>

#include "flatland/scene/scene.hpp"
#include "flatland/transport/solver.hpp"

#include "bench_scenes.hpp"

namespace {

using namespace flatland;
using namespace flatland::bench;

void solve(benchmark::State& state, Layout layout, const SolverSettings& base);

void solve(benchmark::State& state, Layout layout) {
  SolverSettings settings;
  // The random sampler, as when these three were first measured (docs/performance.md), so their
  // figures stay comparable; CubicsRays measures both samplers.
  settings.sampler = SamplerKind::Random;
  settings.sampling = state.range(1) == 0 ? PositionSampling::Uniform : PositionSampling::Reconstructed;
  solve(state, layout, settings);
}

void solve(benchmark::State& state, Layout layout, const SolverSettings& base) {
  Result<Scene> scene = parse_scene(make_scene(layout), "benchmark");
  if (!scene) {
    state.SkipWithError(scene.error().message.c_str());
    return;
  }
  SolverSettings settings = base;
  settings.photons = 2'000'000;
  settings.threads = static_cast<unsigned>(state.range(0));
  settings.tolerance = 1e-9;  // spend the whole budget
  settings.basis = BasisKind::Cubic;
  std::uint64_t photons = 0;
  for (auto _ : state) {
    Result<Solver> solver = Solver::create(*scene, settings);
    solver->run();
    photons += solver->photons_shot();
    benchmark::DoNotOptimize(solver->books());
  }
  state.counters["photons_per_second"] = benchmark::Counter(static_cast<double>(photons), benchmark::Counter::kIsRate);
  state.counters["segments"] = static_cast<double>(scene->segments.size());
}

void Cubics(benchmark::State& state) { solve(state, Layout::Cubics); }
void Lines(benchmark::State& state) { solve(state, Layout::Lines); }
void LinesAsCubics(benchmark::State& state) { solve(state, Layout::LinesAsCubics); }

// The cubic room with extended rays 0.05 wide (a hundredth of the room's radius), box profile,
// reconstructed positions, auto storage: 0 point rays, 1 footprints, 2 a band of 8 sub-rays; with
// the random (0) or Sobol' (1) sampler.
void CubicsRays(benchmark::State& state) {
  SolverSettings settings;
  settings.sampler = state.range(2) == 0 ? SamplerKind::Random : SamplerKind::Sobol;
  if (state.range(1) > 0) {
    settings.ray_width = 0.05;
    settings.ray_mode = state.range(1) == 1 ? RayMode::Footprint : RayMode::Band;
  }
  solve(state, Layout::Cubics, settings);
}

// The cubic room with a fixed storage mesh of about N elements per curve (reconstructed
// positions, point rays): the cost of the mesh's size at a fixed photon count.
void CubicsStorage(benchmark::State& state) {
  SolverSettings settings;
  settings.elements = static_cast<int>(state.range(1));
  solve(state, Layout::Cubics, settings);
}

// Times Solver::create alone on the scene `text` (parsed once, outside the timing).
void create_solvers(benchmark::State& state, const std::string& text, const SolverSettings& settings) {
  Result<Scene> scene = parse_scene(text, "benchmark");
  if (!scene) {
    state.SkipWithError(scene.error().message.c_str());
    return;
  }
  for (auto _ : state) {
    Result<Solver> solver = Solver::create(*scene, settings);
    if (!solver) {
      state.SkipWithError(solver.error().message.c_str());
      return;
    }
    benchmark::DoNotOptimize(solver->coefficient_count());
  }
}

// Solver::create alone for the same room and meshes as CubicsStorage (one thread): the part of
// that benchmark that does not depend on the photons.
void CubicsStorageSetup(benchmark::State& state) {
  SolverSettings settings;
  settings.photons = 2'000'000;
  settings.threads = 1;
  settings.basis = BasisKind::Cubic;
  settings.elements = static_cast<int>(state.range(0));
  create_solvers(state, make_scene(Layout::Cubics), settings);
}

// Scene set-up at scale: a square room with a lamp under its ceiling and a grid of wavy
// two-sided cubic curves, `segments` cubic segments in all, `per_curve` to a curve (1: as many
// curves as segments, the worst case for per-curve work; 256: long curves).
std::string make_large_scene(int segments, int per_curve) {
  const int curves = segments / per_curve;
  const int side = static_cast<int>(std::ceil(std::sqrt(static_cast<double>(curves))));
  std::string text = R"({"flatland": 2, "materials": {"wall": {"reflectivity": 0.6},
    "lamp": {"reflectivity": 0, "emittance": 1}}, "curves": [
    {"id": "walls", "material": "wall", "line": [[0,0],[10,0],[10,10],[0,10],[0,0]]},
    {"id": "lamp", "material": "lamp", "line": [[5.5,9.5],[4.5,9.5]]})";
  for (int k = 0; k < curves; ++k) {
    const double cx = 0.5 + 9.0 * ((k % side) + 0.5) / side;
    const double cy = 0.5 + 8.5 * ((k / side) + 0.5) / side;
    const double width = 9.0 / side * 0.7;
    std::vector<Point> corners;
    for (int i = 0; i <= per_curve; ++i) {
      const double t = static_cast<double>(i) / per_curve;
      corners.emplace_back(cx - width / 2 + width * t, cy + 0.1 * width * std::sin(6 * std::numbers::pi * t));
    }
    text += ",{\"id\": \"c" + std::to_string(k) + "\", \"material\": \"wall\", \"sides\": \"both\", " +
            "\"bezier\": [" + chain(Layout::Cubics, corners, 0.1) + "]}";
  }
  return text + "]}";
}

// Reading the scene: parse, check (overlaps included) and precompute its segments.
void SetupLoad(benchmark::State& state) {
  const std::string text = make_large_scene(static_cast<int>(state.range(0)), static_cast<int>(state.range(1)));
  for (auto _ : state) {
    Result<Scene> scene = parse_scene(text, "benchmark");
    if (!scene) {
      state.SkipWithError(scene.error().message.c_str());
      return;
    }
    benchmark::DoNotOptimize(scene->segments.data());
  }
}

// Solver::create at default settings on 2 threads (1e6 photons): the tree, contacts and
// discontinuity events, every curve's storage levels and samplers.
void SetupSolver(benchmark::State& state) {
  SolverSettings settings;
  settings.photons = 1'000'000;
  settings.threads = 2;
  create_solvers(state, make_large_scene(static_cast<int>(state.range(0)), static_cast<int>(state.range(1))), settings);
}

// Arguments: threads, then positions (0 uniform in arc length, 1 reconstructed).
BENCHMARK(Cubics)->ArgsProduct({{1, 2}, {0, 1}})->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(Lines)->ArgsProduct({{1, 2}, {0, 1}})->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(LinesAsCubics)->ArgsProduct({{1, 2}, {0, 1}})->Unit(benchmark::kMillisecond)->UseRealTime();
// Arguments: threads, the ray kind (0 point, 1 footprint, 2 band), the sampler (0 random, 1 Sobol').
BENCHMARK(CubicsRays)->ArgsProduct({{1, 2}, {0, 1, 2}, {0, 1}})->Unit(benchmark::kMillisecond)->UseRealTime();
// Arguments: threads, then elements per curve.
BENCHMARK(CubicsStorage)->ArgsProduct({{1, 2}, {4, 64, 1024, 4096}})->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace

BENCHMARK(SetupLoad)->ArgsProduct({{65536}, {1, 256}})->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(SetupSolver)->ArgsProduct({{65536}, {1, 256}})->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(CubicsStorageSetup)->Arg(4)->Arg(4096)->Unit(benchmark::kMillisecond)->UseRealTime();

BENCHMARK_MAIN();
