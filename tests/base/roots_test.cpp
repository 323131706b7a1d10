// The one safeguarded Newton iteration (base/roots.hpp), against roots known in closed form.
#include "flatland/base/roots.hpp"

#include <cmath>
#include <optional>

#include <gtest/gtest.h>

namespace flatland {
namespace {

std::optional<double> go_on(double, double, double, double) { return std::nullopt; }

// x^3 - 2 = 0 on [0, 2]: the cube root of 2, in a few Newton steps.
TEST(Roots, NewtonFindsASimpleRootQuickly) {
  int evaluations = 0;
  const double root = newton_bisection(
      [&](double x) {
        ++evaluations;
        return x * x * x - 2.0;
      },
      [](double x) { return 3.0 * x * x; }, 1.0, 0.0, 2.0, 100, 1e-15, go_on);
  EXPECT_NEAR(root, std::cbrt(2.0), 1e-15);
  EXPECT_LE(evaluations, 8);
}

// A slope that is zero, or a step that would leave the bracket, bisects: it still converges.
TEST(Roots, ABadSlopeFallsBackToBisection) {
  const double bisected =
      newton_bisection([](double x) { return x - 0.3; }, [](double) { return 0.0; }, 0.5, 0.0, 1.0, 200, 0.0,
                       [](double, double next, double low, double high) -> std::optional<double> {
                         if (!(next > low && next < high)) return 0.5 * (low + high);
                         return std::nullopt;
                       });
  EXPECT_NEAR(bisected, 0.3, 1e-16);
  // A wildly wrong slope (a hundred times too small) throws each step out of the bracket.
  const double guarded = newton_bisection([](double x) { return std::atan(x - 0.7); }, [](double) { return 0.01; }, 0.0,
                                          -5.0, 5.0, 200, 1e-15, go_on);
  EXPECT_NEAR(guarded, 0.7, 1e-14);
}

// The stop test decides what is returned: here the point after a step smaller than 1e-6.
TEST(Roots, TheStopTestEndsIt) {
  int points = 0;
  newton_bisection(
      [&](double x) {
        ++points;
        return x * x - 2.0;
      },
      [](double x) { return 2.0 * x; }, 1.0, 0.0, 2.0, 100, 0.0,
      [](double at, double next, double, double) -> std::optional<double> {
        if (std::fabs(next - at) < 1e-6) return next;
        return std::nullopt;
      });
  EXPECT_LE(points, 5);
}

}  // namespace
}  // namespace flatland
