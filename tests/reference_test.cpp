#include "flatland/reference.hpp"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "flatland/result_io.hpp"
#include "test_support.hpp"

namespace flatland {
namespace {

ReferenceSolution solve(const Scene& scene, const ReferenceSettings& settings) {
  Result<ReferenceSolution> solution = solve_reference(scene, settings);
  EXPECT_TRUE(solution.ok()) << (solution.ok() ? "" : solution.error().message);
  return std::move(solution).value();
}

// Radiosity at K points s_j = (j + 0.5) L / K along a curve, plus the curve's ends and middle.
std::vector<double> samples(const ReferenceSolution& solution, std::uint32_t curve, Side side,
                            int count) {
  const Scene& scene = solution.scene();
  const Curve& c = scene.curves[curve];
  std::vector<double> values;
  for (int j = 0; j < count; ++j) {
    const CurvePoint point = point_at_arc_length(scene, c, (j + 0.5) * c.length / count);
    values.push_back(solution.radiosity(curve, side, point.u)[0]);
  }
  return values;
}

// Closed enclosure with uniform E and rho: B = E / (1 - rho) everywhere, at element midpoints,
// element boundaries, segment joints and anywhere between; rows of F sum to 1.
TEST(Reference, UniformEnclosure) {
  const Scene scene = testing::scene_from_text(testing::circle_enclosure(0.5, 1.0));
  ReferenceSettings settings;
  settings.max_element_length = 0.05;
  const ReferenceSolution solution = solve(scene, settings);
  EXPECT_GE(solution.elements(), 4u * 32u);
  for (const double b : samples(solution, 0, Side::Front, 37)) EXPECT_NEAR(b, 2.0, 1e-9);
  for (const double u : {0.0, 0.5, 1.0, 1.25, 2.0, 3.999, 4.0})
    EXPECT_NEAR(solution.radiosity(0, Side::Front, u)[0], 2.0, 1e-9) << "u = " << u;
  // The back side is not named: it neither emits nor reflects.
  EXPECT_EQ(solution.radiosity(0, Side::Back, 0.5)[0], 0.0);
  for (std::uint32_t i = 0; i < solution.elements(); ++i) {
    EXPECT_NEAR(solution.row_sum(i, Side::Front), 1.0, 1e-12);
    EXPECT_NEAR(solution.element_radiosity(i, Side::Front)[0], 2.0, 1e-10);
  }
  EXPECT_LE(solution.error_bound(), settings.tolerance);
}

TEST(Reference, HighReflectivityEnclosure) {
  const Scene scene = testing::scene_from_text(testing::circle_enclosure(0.99, 1.0));
  ReferenceSettings settings;
  settings.max_element_length = 0.1;
  const ReferenceSolution solution = solve(scene, settings);
  for (const double b : samples(solution, 0, Side::Front, 23)) EXPECT_NEAR(b, 100.0, 1e-6);
  const Scene stiffer = testing::scene_from_text(testing::circle_enclosure(0.999, 1.0));
  const ReferenceSolution stiff = solve(stiffer, settings);
  for (const double b : samples(stiff, 0, Side::Front, 23)) EXPECT_NEAR(b, 1000.0, 1e-5);
}

// A stiff closed scene whose answer is not uniform: a circle of rho = 0.999 lit by one quarter
// of it. Chords of a circle see each other whole, so F is crossed strings (exact rows and
// reciprocity). The iterative solve must agree with a direct solve (Gaussian elimination with
// partial pivoting in long double on the dense element system, built from form_factor()) to the
// error it guarantees, and close the energy books: sum L (1 - rho) b = sum L e.
TEST(Reference, StiffEnclosureMatchesADirectSolveAndBalancesEnergy) {
  const double k = 0.5522847498307936;
  char text[1024];
  std::snprintf(text, sizeof text, R"({"flatland": 1,
    "materials": {"lamp": {"reflectivity": 0.999, "emittance": 1}, "wall": {"reflectivity": 0.999}},
    "curves": [
      {"id": "lamp", "material": "lamp", "bezier": [[1,0],[1,%.17g],[%.17g,1],[0,1]]},
      {"id": "wall", "material": "wall", "bezier": [[0,1],[%.17g,1],[-1,%.17g],[-1,0],
        [-1,%.17g],[%.17g,-1],[0,-1],[%.17g,-1],[1,%.17g],[1,0]]}]})",
                k, k, -k, k, -k, -k, k, -k);
  const Scene scene = testing::scene_from_text(text);
  ReferenceSettings settings;
  settings.max_element_length = 0.1;
  const ReferenceSolution solution = solve(scene, settings);
  const auto& elements = solution.element_list();
  const std::size_t n = elements.size();
  ASSERT_GE(n, 60u);
  EXPECT_LE(solution.error_bound(), 1e-9);
  EXPECT_LT(solution.iterations(), 200);  // Gauss-Seidel needs about 20,000 sweeps here

  // Dense (I - rho F) b = e on the front sides, in long double, row-major with the right-hand
  // side as column n.
  const std::size_t width = n + 1;
  std::vector<long double> a;
  a.resize(n * width, 0.0L);
  auto at = [&a, width](std::size_t row, std::size_t col) -> long double& { return a[row * width + col]; };
  for (std::size_t i = 0; i < n; ++i) {
    const auto ii = static_cast<std::uint32_t>(i);
    at(i, i) = 1.0L;
    for (std::size_t j = 0; j < n; ++j)
      at(i, j) -= 0.999L * solution.form_factor(ii, Side::Front, static_cast<std::uint32_t>(j), Side::Front);
    at(i, n) = elements[i].emittance[0][0];
  }
  for (std::size_t col = 0; col < n; ++col) {
    std::size_t pivot = col;
    for (std::size_t r = col + 1; r < n; ++r)
      if (std::fabs(at(r, col)) > std::fabs(at(pivot, col))) pivot = r;
    for (std::size_t c = 0; c <= n; ++c) std::swap(at(col, c), at(pivot, c));
    for (std::size_t r = col + 1; r < n; ++r) {
      const long double factor = at(r, col) / at(col, col);
      for (std::size_t c = col; c <= n; ++c) at(r, c) -= factor * at(col, c);
    }
  }
  std::vector<long double> direct;
  direct.resize(n, 0.0L);
  for (std::size_t i = n; i-- > 0;) {
    long double sum = at(i, n);
    for (std::size_t j = i + 1; j < n; ++j) sum -= at(i, j) * direct[j];
    direct[i] = sum / at(i, i);
  }
  long double largest = 0.0L;
  for (const long double value : direct) largest = std::max(largest, std::fabs(value));
  double emitted = 0.0;
  double absorbed = 0.0;
  double smallest = INFINITY;
  for (std::size_t i = 0; i < n; ++i) {
    const double b = solution.element_radiosity(static_cast<std::uint32_t>(i), Side::Front)[0];
    EXPECT_NEAR(b, static_cast<double>(direct[i]), 1e-9 * static_cast<double>(largest)) << "element " << i;
    emitted += elements[i].length * elements[i].emittance[0][0];
    absorbed += elements[i].length * (1.0 - 0.999) * b;
    smallest = std::min(smallest, b);
  }
  EXPECT_NEAR(absorbed, emitted, 1e-9 * emitted);
  // Not uniform: the lamp's quarter is brighter than the far wall.
  EXPECT_GT(static_cast<double>(largest) - smallest, 1e-3 * static_cast<double>(largest));
}

// A room with an obstacle: every direction hits something, so rows sum to 1 (up to the
// quadrature of partly hidden pairs), and L_i F_ij = L_j F_ji.
TEST(Reference, ReciprocityAndRowSums) {
  const Scene scene = testing::scene_from_text(R"({"flatland": 1,
    "materials": {"wall": {"reflectivity": 0.5, "emittance": 1}, "box": {"reflectivity": 0.3}},
    "curves": [
      {"id": "room", "material": "wall", "line": [[-2,-1],[2,-1],[2,1.5],[-2,1.5],[-2,-1]]},
      {"id": "post", "material": "box", "sides": "both", "line": [[-0.3,-0.2],[0.4,0.5]]},
      {"id": "arc", "material": "box", "bezier": [[0.5,-0.6],[1.2,-0.9],[1.5,0.2],[1.0,0.6]]}]})");
  ReferenceSettings settings;
  settings.max_element_length = 0.25;
  const ReferenceSolution solution = solve(scene, settings);
  const auto& elements = solution.element_list();
  double worst_sum = 0.0;
  double worst_reciprocity = 0.0;
  for (std::uint32_t i = 0; i < elements.size(); ++i) {
    for (const Side si : {Side::Front, Side::Back}) {
      if (solution.row_sum(i, si) < 0.0) continue;
      worst_sum = std::max(worst_sum, std::fabs(solution.row_sum(i, si) - 1.0));
      for (std::uint32_t j = 0; j < elements.size(); ++j) {
        for (const Side sj : {Side::Front, Side::Back}) {
          if (solution.row_sum(j, sj) < 0.0) continue;
          const double forward = elements[i].length * solution.form_factor(i, si, j, sj);
          const double backward = elements[j].length * solution.form_factor(j, sj, i, si);
          worst_reciprocity = std::max(worst_reciprocity, std::fabs(forward - backward) /
                                                              std::min(elements[i].length, elements[j].length));
        }
      }
    }
  }
  std::printf("row sums within %.3g of 1, reciprocity within %.3g\n", worst_sum, worst_reciprocity);
  EXPECT_LT(worst_sum, 1e-3);
  EXPECT_LT(worst_reciprocity, 1e-3);
}

// Hottel's crossed strings against the point-to-segment factor integrated by brute force.
TEST(Reference, CrossedStrings) {
  const Vec2 a1{0, 0}, b1{1, 0}, a2{1.5, 2}, b2{-0.5, 1};
  const int n = 200000;
  double sum = 0.0;
  for (int k = 0; k < n; ++k) {
    const Vec2 x{(k + 0.5) / n, 0.0};
    auto sine = [&](Vec2 p) { return (p.x - x.x) / length(p - x); };
    sum += 0.5 * std::fabs(sine(a2) - sine(b2));
  }
  EXPECT_NEAR(crossed_strings(a1, b1, a2, b2), sum / n, 1e-9);
  // Two sides of a unit square corner: F = (1 + 1 - sqrt2) / 2.
  EXPECT_NEAR(crossed_strings({1, 0}, {0, 0}, {0, 0}, {0, 1}), 1.0 - 0.5 * std::sqrt(2.0), 1e-15);
}

// One bounce from a black emitter past a black occluder onto a flat receiver:
// B(x) = rho (1/2) (visible measure of the emitter in sin theta), exact penumbrae.
TEST(Reference, Penumbra) {
  const Scene scene = testing::scene_from_text(R"({"flatland": 1,
    "materials": {"lamp": {"emittance": 1}, "black": {}, "floor": {"reflectivity": 0.5}},
    "curves": [
      {"id": "lamp", "material": "lamp", "line": [[0.5,2],[-0.5,2]]},
      {"id": "floor", "material": "floor", "line": [[-3,0],[3,0]]},
      {"id": "occluder", "material": "black", "sides": "both", "line": [[-0.2,1],[0.6,1]]}]})");
  ReferenceSettings settings;
  settings.max_element_length = 0.1;
  const ReferenceSolution solution = solve(scene, settings);
  auto expected = [](double x) {
    auto sine = [x](double px, double py) { return (px - x) / std::hypot(px - x, py); };
    const double a = sine(-0.5, 2), b = sine(0.5, 2);
    const double c = std::max(a, sine(-0.2, 1)), d = std::min(b, sine(0.6, 1));
    return 0.5 * 0.5 * ((b - a) - std::max(0.0, d - c));
  };
  for (int k = 0; k <= 120; ++k) {
    const double x = -3.0 + 6.0 * k / 120.0;
    const double b = solution.radiosity(1, Side::Front, (x + 3.0) / 6.0)[0];
    EXPECT_NEAR(b, expected(x), 1e-4 * expected(x) + 1e-14) << "x = " << x;
  }
  // The occluder and the lamp's back absorb.
  EXPECT_EQ(solution.radiosity(2, Side::Front, 0.5)[0], 0.0);
  EXPECT_EQ(solution.radiosity(0, Side::Front, 0.5)[0], 1.0);
  EXPECT_EQ(solution.radiosity(0, Side::Back, 0.5)[0], 0.0);
}

// A half-circle reflector lit by a line lamp: the error at fixed points falls as h^2.
TEST(Reference, SecondOrderConvergence) {
  const double k = 0.5522847498307936;
  char text[1024];
  std::snprintf(text, sizeof text, R"({"flatland": 1,
    "materials": {"lamp": {"emittance": 1}, "mirror": {"reflectivity": 0.7}},
    "curves": [
      {"id": "lamp", "material": "lamp", "line": [[0.3,0.5],[-0.3,0.5]]},
      {"id": "bowl", "material": "mirror", "bezier":
        [[-1,0],[-1,%.17g],[%.17g,-1],[0,-1],[%.17g,-1],[1,%.17g],[1,0]]}]})",
                -k, -k, k, -k);
  const Scene scene = testing::scene_from_text(text);
  const int points = 41;
  auto run = [&](double h) {
    ReferenceSettings settings;
    settings.max_element_length = h;
    return samples(solve(scene, settings), 1, Side::Front, points);
  };
  const std::vector<double> finest = run(0.2 / 32);
  std::vector<double> errors;
  for (const double h : {0.2, 0.1, 0.05, 0.025}) {
    const std::vector<double> values = run(h);
    double error = 0.0;
    for (int j = 0; j < points; ++j) error = std::max(error, std::fabs(values[j] - finest[j]));
    errors.push_back(error);
  }
  for (std::size_t i = 0; i + 1 < errors.size(); ++i) {
    const double order = std::log2(errors[i] / errors[i + 1]);
    std::printf("h = %.4g: max error %.3e, observed order %.2f\n", 0.2 / std::pow(2.0, i), errors[i], order);
    EXPECT_GT(order, 1.5);
  }
}

// Colour channels solve independently; thread count does not change a bit.
TEST(Reference, ChannelsAndThreads) {
  const Scene scene = testing::scene_from_text(R"({"flatland": 1,
    "materials": {"lamp": {"emittance": [1, 2, 0.5]}, "wall": {"reflectivity": [0.2, 0.5, 0.8]}},
    "curves": [
      {"id": "lamp", "material": "lamp", "line": [[0.5,1],[-0.5,1]]},
      {"id": "cup", "material": "wall", "bezier": [[-1,1],[-1,-0.5],[1,-0.5],[1,1]]}]})");
  ASSERT_EQ(scene.channels, 3);
  ReferenceSettings settings;
  settings.max_element_length = 0.1;
  settings.threads = 1;
  const ReferenceSolution one = solve(scene, settings);
  settings.threads = 3;
  const ReferenceSolution three = solve(scene, settings);
  for (const double u : {0.1, 0.37, 0.5, 0.93}) {
    const Spectrum a = one.radiosity(1, Side::Front, u);
    const Spectrum b = three.radiosity(1, Side::Front, u);
    for (std::size_t c = 0; c < 3; ++c) EXPECT_EQ(a[c], b[c]);
    EXPECT_GT(a[1], 0.0);
    EXPECT_GT(a[2] / a[0], 0.5 / 1.0);  // more reflective channel, less emitted: still bright
  }
}

TEST(Reference, RejectsBadInput) {
  ReferenceSettings settings;
  settings.quadrature = 0;
  EXPECT_FALSE(validate(settings).ok());
  settings = {};
  settings.max_element_length = -1.0;
  EXPECT_FALSE(validate(settings).ok());
  const Scene scene = testing::scene_from_text(R"({"flatland": 1,
    "materials": {"lamp": {"emittance": 1, "emission": {"beam": 30}}},
    "curves": [{"id": "lamp", "material": "lamp", "line": [[0,0],[1,0]]}]})");
  EXPECT_FALSE(solve_reference(scene, ReferenceSettings{}).ok());
}

// Elements against seconds on a scene with occlusion (run with --gtest_also_run_disabled_tests).
TEST(Reference, CancelStopsTheSolve) {
  const Scene scene = testing::scene_from_text(testing::circle_enclosure(0.5, 1.0));
  ReferenceSettings settings;
  const std::atomic<bool> cancel{true};
  settings.cancel = &cancel;
  Result<ReferenceSolution> solution = solve_reference(scene, settings);
  ASSERT_FALSE(solution.ok());
  EXPECT_EQ(solution.error().message, kReferenceCancelled);
}

// Element counts that cannot finish, or whose form factors cannot fit, are refused with a message
// that names the fix, instead of running for hours or failing to allocate.
TEST(Reference, WorkBeyondItsLimitsIsRefused) {
  const Scene scene = testing::scene_from_text(testing::circle_enclosure(0.5, 1.0));
  ReferenceSettings settings;
  settings.max_element_length = scene.scale / 1'048'576;
  EXPECT_GT(reference_element_count(scene, settings), static_cast<double>(kMaxReferenceElements));
  Result<ReferenceSolution> huge = solve_reference(scene, settings);
  ASSERT_FALSE(huge.ok());
  EXPECT_NE(huge.error().message.find("use fewer elements"), std::string::npos) << huge.error().message;
  // A closed circle sees all of itself: n elements make about n^2 form factors.
  settings.max_element_length = scene.scale / 2000;
  settings.memory_limit = 1 << 20;
  Result<ReferenceSolution> tight = solve_reference(scene, settings);
  ASSERT_FALSE(tight.ok());
  EXPECT_NE(tight.error().message.find("more than the memory limit of 1.05 MB"), std::string::npos)
      << tight.error().message;
}

// Long solves report the form factors' progress from the calling thread: rows done, increasing,
// never more than the rows in all.
TEST(Reference, ReportsProgressOfTheFormFactors) {
  const Scene scene = testing::scene_from_text(testing::circle_enclosure(0.5, 1.0));
  ReferenceSettings settings;
  settings.max_element_length = scene.curves[0].length / 2000;
  std::vector<std::pair<std::size_t, std::size_t>> reports;
  settings.progress = [&](std::size_t done, std::size_t rows) { reports.emplace_back(done, rows); };
  const auto start = std::chrono::steady_clock::now();
  Result<ReferenceSolution> solution = solve_reference(scene, settings);
  ASSERT_TRUE(solution.ok()) << solution.error().message;
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  if (seconds < 0.5) GTEST_SKIP() << "solved in " << seconds << " s, before a report was due";
  ASSERT_FALSE(reports.empty());
  for (std::size_t k = 0; k < reports.size(); ++k) {
    EXPECT_EQ(reports[k].second, solution->elements());  // one reflecting side per element
    EXPECT_LE(reports[k].first, reports[k].second);
    if (k > 0) {
      EXPECT_GT(reports[k].first, reports[k - 1].first);
    }
  }
}

TEST(Reference, DISABLED_Timing) {
  const std::string path = testing::source_path("scenes2d/room_reflector.json");
  const Scene scene = testing::scene_from_file("scenes2d/room_reflector.json");
  for (const double divisor : {200.0, 400.0, 800.0}) {
    ReferenceSettings settings;
    settings.max_element_length = scene.scale / divisor;
    const auto start = std::chrono::steady_clock::now();
    const ReferenceSolution solution = solve(scene, settings);
    const double seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    std::printf("%zu elements: %.2f s (form factors %.2f s, solve %.2f s, %d sweeps)\n",
                solution.elements(), seconds, solution.form_factor_seconds(),
                solution.solve_seconds(), solution.iterations());
  }
}

}  // namespace
}  // namespace flatland
