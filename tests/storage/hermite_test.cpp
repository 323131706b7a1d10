#include "flatland/storage/hermite.hpp"

#include <algorithm>
#include <cmath>
#include <functional>
#include <numbers>
#include <vector>

#include <gtest/gtest.h>

#include "flatland/base/random.hpp"
#include "test_support.hpp"

namespace flatland {
namespace {

using Function = std::function<double(double)>;

// Nodes 0 = u_0 < ... < u_n with widths in [min_width, min_width + 1).
std::vector<double> random_nodes(Rng& rng, std::size_t pieces, double min_width = 0.05) {
  std::vector<double> u{0.0};
  for (std::size_t i = 0; i < pieces; ++i) u.push_back(u.back() + min_width + rng.uniform());
  return u;
}

std::vector<Continuity> random_continuity(Rng& rng, std::size_t nodes) {
  constexpr Continuity kinds[] = {Continuity::Jump, Continuity::C0, Continuity::C1};
  std::vector<Continuity> continuity(nodes);
  for (auto& c : continuity) c = kinds[rng.next() % 3];
  return continuity;
}

// Random data at the nodes u: the continuity drawn first, then per node a value in
// [low, low + 1) and, at a jump, a second one for its right side.
HermiteInput random_input(Rng& rng, const std::vector<double>& u, double low = 0.0) {
  HermiteInput input;
  input.u = u;
  input.continuity = random_continuity(rng, u.size());
  for (std::size_t i = 0; i < u.size(); ++i) {
    input.left.push_back(low + rng.uniform());
    input.right.push_back(input.continuity[i] == Continuity::Jump ? low + rng.uniform() : input.left.back());
  }
  return input;
}

// Samples f at the nodes: left == right everywhere (a jump node then has equal sides).
HermiteInput sampled(const std::vector<double>& u, const Function& f, std::vector<Continuity> continuity) {
  HermiteInput input;
  input.u = u;
  for (double x : u) {
    input.left.push_back(f(x));
    input.right.push_back(f(x));
  }
  input.continuity = std::move(continuity);
  return input;
}

// Largest |reconstruction - f| at `per_piece` points inside each piece (ends included).
double max_error(const HermiteReconstruction& r, const std::vector<double>& u, const Function& f, int per_piece = 50) {
  double error = 0.0;
  for (std::size_t i = 0; i + 1 < u.size(); ++i)
    for (int j = 0; j <= per_piece; ++j) {
      const double x = j == per_piece ? u[i + 1] : u[i] + (u[i + 1] - u[i]) * j / per_piece;
      error = std::max(error, std::fabs(r.evaluate(x) - f(x)));
    }
  return error;
}

// Second-order one-sided differences (error O(eps^2 f''')), left and right of x.
double slope_from_left(const HermiteReconstruction& r, double x, double eps) {
  return (3.0 * r.evaluate(x) - 4.0 * r.evaluate(x - eps) + r.evaluate(x - 2.0 * eps)) / (2.0 * eps);
}
double slope_from_right(const HermiteReconstruction& r, double x, double eps) {
  return (-3.0 * r.evaluate(x) + 4.0 * r.evaluate(x + eps) - r.evaluate(x + 2.0 * eps)) / (2.0 * eps);
}
// The value approached from the left: quadratic extrapolation from three points left of x.
double value_from_left(const HermiteReconstruction& r, double x, double eps) {
  return 3.0 * r.evaluate(x - eps) - 3.0 * r.evaluate(x - 2.0 * eps) + r.evaluate(x - 3.0 * eps);
}

TEST(Hermite, RejectsMalformedInput) {
  HermiteInput input;
  input.u = {0.0};
  input.left = input.right = {1.0};
  input.continuity = {Continuity::C1};
  EXPECT_FALSE(check_hermite_input(input).ok());
  input.u = {0.0, 1.0, 1.0};
  input.left = input.right = {1.0, 1.0, 1.0};
  input.continuity.assign(3, Continuity::C1);
  const Status repeated = check_hermite_input(input);
  ASSERT_FALSE(repeated.ok());
  EXPECT_NE(repeated.error().message.find("u[2]"), std::string::npos) << repeated.error().message;
  input.u = {0.0, 1.0, 2.0};
  input.right[1] = std::nan("");
  const Status not_finite = check_hermite_input(input);
  ASSERT_FALSE(not_finite.ok());
  EXPECT_NE(not_finite.error().message.find("right[1]"), std::string::npos);
  input.right[1] = -0.5;  // negative values are accepted (clamped); unused ends are not read
  input.left[0] = std::nan("");
  input.right[2] = INFINITY;
  EXPECT_TRUE(check_hermite_input(input).ok());
  input.left.pop_back();
  EXPECT_FALSE(check_hermite_input(input).ok());
}

TEST(Hermite, ConstantIsReproducedExactly) {
  Rng rng(1, 0, 0);
  for (int trial = 0; trial < 20; ++trial) {
    const auto u = random_nodes(rng, 1 + rng.next() % 9);
    const double c = 0.1 + 10.0 * rng.uniform();
    HermiteInput input = sampled(
        u, [c](double) { return c; }, random_continuity(rng, u.size()));
    input.monotone = trial % 2 == 1;
    const HermiteReconstruction r(input);
    ASSERT_EQ(r.pieces(), u.size() - 1);
    for (int j = 0; j <= 1000; ++j) {
      const double x = u.back() * j / 1000.0;
      EXPECT_EQ(r.evaluate(x), c);
      EXPECT_EQ(r.derivative(x), 0.0);
    }
    EXPECT_NEAR(r.integral(), c * u.back(), 1e-13 * c * u.back());
  }
}

TEST(Hermite, LinearIsReproducedWhateverTheContinuity) {
  // Every slope rule (centred, one-sided three-point, secant) is exact for linear data.
  Rng rng(2, 0, 0);
  for (int trial = 0; trial < 50; ++trial) {
    const auto u = random_nodes(rng, 1 + rng.next() % 9, 0.2);
    const double a = 1.0 + rng.uniform();
    const double b = (rng.uniform() - 0.5) * a / u.back();  // stays >= a/2 > 0 on [0, u_n]
    const Function f = [a, b](double x) { return a + b * x; };
    HermiteInput input = sampled(u, f, random_continuity(rng, u.size()));
    input.monotone = trial % 2 == 1;
    const HermiteReconstruction r(input);
    EXPECT_LT(max_error(r, u, f), 1e-13 * a);
    for (double x : {0.0, 0.3 * u.back(), u.back()}) EXPECT_NEAR(r.derivative(x), b, 1e-12 * a);
  }
  // Two different lines meeting at a jump: each side reproduces its own.
  HermiteInput input;
  input.u = {0.0, 0.5, 1.0, 1.5, 2.0, 2.5};
  const Function before = [](double x) { return 1.0 + 2.0 * x; };
  const Function after = [](double x) { return 5.0 - x; };
  for (double x : input.u) {
    input.left.push_back(x <= 1.0 ? before(x) : after(x));
    input.right.push_back(x < 1.0 ? before(x) : after(x));
  }
  input.continuity = {Continuity::C1, Continuity::C1, Continuity::Jump, Continuity::C1, Continuity::C1, Continuity::C1};
  const HermiteReconstruction r(input);
  for (int j = 0; j < 1000; ++j) {
    const double x = 2.5 * j / 1000.0;
    EXPECT_NEAR(r.evaluate(x), x < 1.0 ? before(x) : after(x), 1e-13);
  }
}

TEST(Hermite, QuadraticIsReproducedWhereSlopesUseThreeNodes) {
  // The parabola through three nodes is the quadratic itself, so the Bessel slope at a C1 node and
  // the one-sided three-point slope beside a C0 node are exact, and a cubic Hermite piece with
  // exact values and slopes reproduces a quadratic. Values >= 2 and slopes < 3 keep the positivity
  // bounds (|d| <= 3 f / h >= 12) inactive.
  const Function q = [](double x) { return 3.0 + x - 0.4 * x * x; };
  const Function dq = [](double x) { return 1.0 - 0.8 * x; };
  Rng rng(3, 0, 0);
  for (int trial = 0; trial < 20; ++trial) {
    std::vector<double> u{0.0};
    for (int i = 0; i < 8; ++i) u.push_back(u.back() + 0.1 + 0.3 * rng.uniform());
    std::vector<Continuity> continuity(u.size(), Continuity::C1);
    if (trial % 2 == 1) continuity[4] = Continuity::C0;  // two pieces on each side of it
    const HermiteReconstruction r(sampled(u, q, continuity));
    EXPECT_LT(max_error(r, u, q), 1e-13);
    for (std::size_t i = 0; i < u.size(); ++i) EXPECT_NEAR(r.derivative(u[i]), dq(u[i]), 1e-12);
  }
  // With a single piece beside an end the slope there is the secant: exact only in the interior.
  std::vector<double> u{0.0, 0.3, 0.5, 0.9, 1.2, 1.4};
  std::vector<Continuity> continuity(u.size(), Continuity::C1);
  continuity[1] = Continuity::C0;
  const HermiteReconstruction r(sampled(u, q, continuity));
  EXPECT_GT(std::fabs(r.evaluate(0.15) - q(0.15)), 1e-4);
  for (int j = 0; j <= 100; ++j) {
    const double x = 0.5 + 0.9 * j / 100.0;
    EXPECT_NEAR(r.evaluate(x), q(x), 1e-13);
  }
}

// Evaluating an increasing sequence by walking the pieces gives evaluate's bits everywhere:
// before the first node, at nodes (the right piece's value), inside pieces and past the end.
TEST(Hermite, EvaluateIncreasingEqualsEvaluate) {
  Rng rng(7, 0, 0);
  for (int trial = 0; trial < 20; ++trial) {
    const auto u = random_nodes(rng, 9, 0.2);
    const HermiteReconstruction r(random_input(rng, u));
    std::vector<double> at = {u.front() - 1.0};
    for (std::size_t i = 0; i + 1 < u.size(); ++i)
      for (int k = 0; k < 7; ++k) at.push_back(u[i] + (u[i + 1] - u[i]) * k / 7.0);
    at.push_back(u.back());
    at.push_back(u.back() + 1.0);
    std::vector<double> out(at.size());
    r.evaluate_increasing(at, out.data());
    for (std::size_t i = 0; i < at.size(); ++i) EXPECT_EQ(out[i], r.evaluate(at[i])) << at[i];
  }
}

TEST(Hermite, ContinuityAtNodesIsAsSelected) {
  Rng rng(4, 0, 0);
  int c0_nodes_with_a_kink = 0;
  int c0_nodes = 0;
  for (int trial = 0; trial < 40; ++trial) {
    const auto u = random_nodes(rng, 8, 0.2);
    HermiteInput input = random_input(rng, u, 0.2);
    input.monotone = trial % 4 == 3;
    const HermiteReconstruction r(input);
    for (std::size_t i = 0; i < u.size(); ++i) {
      // Interpolation: the node's values from each side.
      if (i + 1 < u.size()) {
        EXPECT_EQ(r.evaluate(u[i]), input.right[i]);
      }
      if (i > 0) {
        EXPECT_NEAR(value_from_left(r, u[i], 1e-5), input.left[i], 1e-9);
      }
      if (i == 0 || i + 1 == u.size()) continue;
      const double h = std::min(u[i] - u[i - 1], u[i + 1] - u[i]);
      const double eps = 1e-5 * h;
      const double left_slope = slope_from_left(r, u[i], eps);
      const double right_slope = slope_from_right(r, u[i], eps);
      // Slopes are bounded by 3 max f / h ~ 20 here; the differences are good to ~1e-8.
      if (input.continuity[i] == Continuity::C1) {
        EXPECT_NEAR(left_slope, right_slope, 1e-6) << "C1 node " << i;
      } else if (input.continuity[i] == Continuity::C0) {
        ++c0_nodes;
        if (std::fabs(left_slope - right_slope) > 1e-3) ++c0_nodes_with_a_kink;
      }
    }
  }
  EXPECT_GT(c0_nodes, 50);
  EXPECT_GT(c0_nodes_with_a_kink, c0_nodes * 9 / 10);  // one-sided slopes generally differ
}

TEST(Hermite, PieceBetweenTwoBreaksIsTheChord) {
  // Both slopes of a piece between two non-C1 nodes come from that piece alone: its secant. The
  // Hermite cubic with both end slopes equal to the secant is the straight line.
  const Function f = [](double x) { return 2.0 + std::sin(3.0 * x); };
  const std::vector<double> u{0.0, 0.4, 0.9, 1.2, 1.8};
  using enum Continuity;
  for (const auto& continuity : {std::vector{C1, C1, C0, Jump, C1}, std::vector{C1, C1, Jump, C0, C1}}) {
    const HermiteReconstruction r(sampled(u, f, continuity));
    for (int j = 0; j <= 100; ++j) {
      const double x = 0.9 + 0.3 * j / 100.0;
      EXPECT_NEAR(r.evaluate(x), f(0.9) + (f(1.2) - f(0.9)) * (x - 0.9) / 0.3, 1e-14);
    }
  }
}

TEST(Hermite, DataBeyondAC0OrJumpNodeDoNotReachAcross) {
  // C0: the slope on each side comes from that side's data alone, so changing values strictly
  // left of the node leaves the right side unchanged, bit for bit. A jump also frees the node's
  // left value.
  Rng rng(5, 0, 0);
  for (Continuity kind : {Continuity::C0, Continuity::Jump}) {
    for (int trial = 0; trial < 20; ++trial) {
      const auto u = random_nodes(rng, 8);
      HermiteInput input;
      input.u = u;
      input.continuity = random_continuity(rng, u.size());
      input.continuity[4] = kind;
      for (std::size_t i = 0; i < u.size(); ++i) {
        input.left.push_back(rng.uniform());
        input.right.push_back(input.continuity[i] == Continuity::Jump ? rng.uniform() : input.left.back());
      }
      HermiteInput changed = input;
      for (std::size_t i = 0; i < 4; ++i) changed.left[i] = changed.right[i] = 3.0 * rng.uniform();
      if (kind == Continuity::Jump) changed.left[4] = 3.0 * rng.uniform();
      const HermiteReconstruction a(input);
      const HermiteReconstruction b(changed);
      for (int j = 0; j <= 200; ++j) {
        const double x = u[4] + (u.back() - u[4]) * j / 200.0;
        EXPECT_EQ(a.evaluate(x), b.evaluate(x));
      }
    }
  }
}

TEST(Hermite, StaysNonnegativeOnSpikesAndZeros) {
  // Spikes beside zeros are where secant slopes would undershoot: the Bessel slope at a zero next
  // to a spike is positive, so without the filter the piece before it dips below zero.
  {
    HermiteInput input;
    input.u = {0.0, 1.0, 2.0, 3.0, 4.0};
    input.left = input.right = {0.0, 0.0, 1.0, 0.0, 0.0};
    input.continuity.assign(5, Continuity::C1);
    const HermiteReconstruction r(input);
    EXPECT_EQ(r.derivative(1.0), 0.0);  // clamped: 3 f / h = 0
    for (int j = 0; j <= 4000; ++j) EXPECT_GE(r.evaluate(j / 1000.0), 0.0);
  }
  Rng rng(6, 0, 0);
  for (int trial = 0; trial < 300; ++trial) {
    const std::size_t pieces = 1 + rng.next() % 12;
    std::vector<double> u{0.0};
    for (std::size_t i = 0; i < pieces; ++i)  // widths over three decades
      u.push_back(u.back() + std::pow(10.0, -3.0 * rng.uniform()));
    HermiteInput input;
    input.u = u;
    input.continuity = random_continuity(rng, u.size());
    double largest = 0.0;
    for (std::size_t i = 0; i < u.size(); ++i) {
      for (int side = 0; side < 2; ++side) {
        const double kind = rng.uniform();
        double value = kind < 0.4    ? 0.0
                       : kind < 0.55 ? 1e3 * rng.uniform()
                       : kind < 0.65 ? -rng.uniform()
                                     : rng.uniform();
        if (side == 1 && input.continuity[i] != Continuity::Jump) value = input.left.back();
        (side == 0 ? input.left : input.right).push_back(value);
        largest = std::max(largest, value);
      }
    }
    input.monotone = trial % 3 == 2;
    const HermiteReconstruction r(input);
    for (std::size_t i = 0; i < u.size(); ++i) {  // negative inputs were clamped to zero
      if (i + 1 < u.size() && input.right[i] < 0.0) {
        EXPECT_EQ(r.evaluate(u[i]), 0.0);
      }
    }
    for (std::size_t i = 0; i < r.pieces(); ++i) {
      const HermitePiece& p = r.piece(i);
      // The Bernstein coefficients are nonnegative (up to rounding of f +- h d / 3), so the cubic
      // is; evaluate() works from them by de Casteljau (convex combinations), so it returns no
      // negative value at all, not even -1 ulp.
      EXPECT_GE(p.start_value + p.width * p.start_slope / 3.0, -1e-15 * largest);
      EXPECT_GE(p.end_value - p.width * p.end_slope / 3.0, -1e-15 * largest);
      for (int j = 0; j <= 400; ++j) {
        const double x = p.u0 + p.width * j / 400.0;
        ASSERT_GE(r.evaluate(x), 0.0) << "trial " << trial << " piece " << i;
      }
    }
  }
}

TEST(Hermite, MonotoneOptionRemovesOvershoot) {
  // A step: without Fritsch-Carlson the Bessel slope at the top corner overshoots the plateau.
  HermiteInput input;
  input.u = {0.0, 1.0, 2.0, 3.0, 4.0, 5.0};
  input.left = input.right = {0.0, 0.0, 0.2, 1.0, 1.0, 1.0};
  input.continuity.assign(6, Continuity::C1);
  double overshoot = 0.0;
  {
    const HermiteReconstruction r(input);
    for (int j = 0; j <= 5000; ++j) overshoot = std::max(overshoot, r.evaluate(j / 1000.0) - 1.0);
  }
  EXPECT_GT(overshoot, 0.01);
  input.monotone = true;
  const HermiteReconstruction r(input);
  double previous = r.evaluate(0.0);
  for (int j = 1; j <= 5000; ++j) {
    const double value = r.evaluate(j / 1000.0);
    EXPECT_GE(value, previous - 1e-15);
    previous = value;
  }
  EXPECT_LE(previous, 1.0);
  // On random monotone data every piece is monotone (the derivative never changes sign).
  Rng rng(7, 0, 0);
  for (int trial = 0; trial < 50; ++trial) {
    const auto u = random_nodes(rng, 10, 0.01);
    HermiteInput data;
    data.u = u;
    double value = 0.0;
    for (std::size_t i = 0; i < u.size(); ++i) {
      value += rng.uniform() < 0.3 ? 0.0 : std::pow(10.0, 2.0 * rng.uniform());
      data.left.push_back(value);
      data.right.push_back(value);
    }
    data.continuity = random_continuity(rng, u.size());
    data.monotone = true;
    const HermiteReconstruction m(data);
    for (int j = 0; j <= 5000; ++j) {
      const double x = u.back() * j / 5000.0;
      EXPECT_GE(m.derivative(x), -1e-12 * value / (u.back() - u.front())) << "trial " << trial;
    }
  }
}

// Midpoint rule with `steps` points per piece.
double midpoint_integral(const HermiteReconstruction& r, std::size_t piece, int steps) {
  const HermitePiece& p = r.piece(piece);
  double sum = 0.0;
  for (int j = 0; j < steps; ++j) sum += r.evaluate(p.u0 + p.width * (j + 0.5) / steps);
  return sum * p.width / steps;
}

TEST(Hermite, IntegralMatchesMidpointRule) {
  Rng rng(8, 0, 0);
  for (int trial = 0; trial < 50; ++trial) {
    const auto u = random_nodes(rng, 1 + rng.next() % 10);
    HermiteInput input;
    input.u = u;
    input.continuity = random_continuity(rng, u.size());
    for (std::size_t i = 0; i < u.size(); ++i) {
      input.left.push_back(rng.uniform() < 0.3 ? 0.0 : 5.0 * rng.uniform());
      input.right.push_back(input.continuity[i] == Continuity::Jump ? 5.0 * rng.uniform() : input.left.back());
    }
    input.monotone = trial % 2 == 1;
    const HermiteReconstruction r(input);
    double total = 0.0;
    for (std::size_t i = 0; i < r.pieces(); ++i) {
      // The midpoint rule's error is width^3 max|f''| / (24 steps^2) ~ 1e-8 at most here.
      const double reference = midpoint_integral(r, i, 4000);
      EXPECT_NEAR(r.piece_integral(i), reference, 1e-7 * (1.0 + reference));
      total += reference;
    }
    EXPECT_NEAR(r.integral(), total, 1e-7 * (1.0 + total));
  }
}

TEST(Hermite, SamplesFollowTheReconstruction) {
  // Chi-square of sample() against the reconstruction: 16 equal bins per piece, expected counts
  // from the midpoint rule, bins merged until each expects at least 20 samples.
  struct Case {
    std::vector<double> u, left, right;
    std::vector<Continuity> continuity;
  };
  using enum Continuity;
  const std::vector<Case> cases = {
      {{0.0, 0.4, 1.0, 1.3, 2.0, 2.2},
       {0.0, 1.0, 0.2, 3.0, 0.5, 1.5},
       {2.0, 1.0, 0.2, 0.1, 0.5, 0.0},
       {C1, C1, C0, Jump, C1, C1}},
      {{0.0, 1.0, 1.1, 2.0, 4.0},  // spikes and zeros: filter active, pieces of zero mass
       {0.0, 0.0, 10.0, 0.0, 0.0},
       {0.0, 0.0, 10.0, 0.0, 0.0},
       {C1, C1, C1, C1, C1}},
      {{0.0, 1.0}, {0.0, 1.0}, {0.0, 0.0}, {C1, C1}},  // f = u on [0,1]: G quadratic, f(0) = 0
  };
  std::uint64_t stream = 0;
  for (const Case& c : cases) {
    const HermiteReconstruction r(HermiteInput{c.u, c.left, c.right, c.continuity, false});
    constexpr int kBins = 16;
    std::vector<double> expected;
    for (std::size_t i = 0; i < r.pieces(); ++i) {
      const HermitePiece& p = r.piece(i);
      for (int b = 0; b < kBins; ++b) {
        double sum = 0.0;
        for (int j = 0; j < 200; ++j) sum += r.evaluate(p.u0 + p.width * (b + (j + 0.5) / 200.0) / kBins);
        expected.push_back(sum * p.width / kBins / 200.0);
      }
    }
    double mass = 0.0;
    for (double e : expected) mass += e;
    EXPECT_NEAR(mass, r.integral(), 1e-6 * r.integral());
    constexpr int kSamples = 400000;
    std::vector<double> observed(expected.size(), 0.0);
    Rng rng(9, stream++, 0);
    for (int s = 0; s < kSamples; ++s) {
      const double x = r.sample(rng.uniform(), rng.uniform());
      ASSERT_GE(x, r.u_begin());
      ASSERT_LE(x, r.u_end());
      const std::size_t i = std::min<std::size_t>(
          static_cast<std::size_t>(std::upper_bound(c.u.begin(), c.u.end(), x) - c.u.begin()) - 1, r.pieces() - 1);
      const HermitePiece& p = r.piece(i);
      const int b = std::min(kBins - 1, static_cast<int>((x - p.u0) / p.width * kBins));
      observed[i * kBins + static_cast<std::size_t>(b)] += 1.0;
    }
    std::vector<double> merged_observed, merged_expected;
    double o = 0.0, e = 0.0;
    for (std::size_t k = 0; k < expected.size(); ++k) {
      if (expected[k] == 0.0) {
        EXPECT_EQ(observed[k], 0.0) << "a sample where f = 0";
      }
      o += observed[k];
      e += expected[k] / mass * kSamples;
      if (e >= 20.0) {
        merged_observed.push_back(o);
        merged_expected.push_back(e);
        o = e = 0.0;
      }
    }
    merged_observed.back() += o;
    merged_expected.back() += e;
    const int dof = static_cast<int>(merged_expected.size()) - 1;
    EXPECT_GT(dof, 10);
    EXPECT_LT(testing::chi_square(merged_observed, merged_expected), testing::chi_square_critical(dof));
    // The pdf is the normalised reconstruction.
    for (double x : {0.05, 0.5, 0.95}) {
      EXPECT_NEAR(r.pdf(x), std::max(0.0, r.evaluate(x)) / r.integral(), 1e-15);
    }
    EXPECT_EQ(r.pdf(r.u_end() + 0.1), 0.0);
  }
  // No mass: uniform.
  const HermiteReconstruction zero(HermiteInput{{0.0, 2.0}, {0.0, 0.0}, {0.0, 0.0}, {C1, C1}, false});
  EXPECT_EQ(zero.sample(0.25, 0.7), 0.5);
  EXPECT_EQ(zero.pdf(1.0), 0.5);
}

TEST(Hermite, SamplesInvertThePieceCdfToRounding) {
  // sample(u1, u2) puts x where the share of its piece's mass below x is u2. Checked against the
  // reconstruction itself, integrated by 3-point Gauss-Legendre (exact for the cubic a piece is),
  // on pieces rising, falling, humped and vanishing at an end.
  using enum Continuity;
  const HermiteReconstruction r(HermiteInput{{0.0, 0.4, 1.0, 1.3, 2.0, 2.2, 3.0},
                                             {0.0, 1.0, 0.2, 3.0, 0.5, 1.5, 0.0},
                                             {2.0, 1.0, 0.2, 0.1, 0.5, 0.0, 0.0},
                                             {C1, C1, C0, Jump, C1, C1, C1},
                                             false});
  auto integral = [&](double a, double b) {
    const double half = 0.5 * (b - a);
    const double mid = 0.5 * (a + b);
    const double node = std::sqrt(0.6);
    return half * (5.0 / 9.0 * r.evaluate(mid - half * node) + 8.0 / 9.0 * r.evaluate(mid) +
                   5.0 / 9.0 * r.evaluate(mid + half * node));
  };
  Rng rng(17, 0, 0);
  double worst = 0.0;
  for (int n = 0; n < 20000; ++n) {
    const double u1 = rng.uniform();
    const double u2 = 0.001 + 0.998 * rng.uniform();
    const double x = r.sample(u1, u2);
    std::size_t i = 0;
    while (i + 1 < r.pieces() && !(x < r.piece(i).u0 + r.piece(i).width)) ++i;
    const HermitePiece& p = r.piece(i);
    const double share = integral(p.u0, x) / integral(p.u0, p.u0 + p.width);
    worst = std::max(worst, std::fabs(share - u2));
  }
  EXPECT_LT(worst, 1e-12);
}

TEST(Hermite, ConvergesAtThirdOrder) {
  // Exact nodal values of a smooth function on nodes u_j = g(j / n), g a smooth increasing map (so
  // widths are uneven but all halve with n): the max error should fall like h^3 (slopes O(h^2)).
  const double two_pi = 2.0 * std::numbers::pi;
  const auto node = [two_pi](double s) { return two_pi * (s + 0.08 * std::sin(two_pi * s)); };
  struct Case {
    const char* name;
    Function f;
    // 0: all C1; 1: C0 and equal-valued jumps, each with at least two pieces on either side (a
    // piece between two non-C1 nodes has only its own two values to go by: it is the chord, and
    // second order).
    int pattern;
  };
  const std::vector<Case> cases = {
      {"1.5 + sin, C1", [](double x) { return 1.5 + std::sin(x); }, 0},
      {"1.5 + sin, C0 and jumps", [](double x) { return 1.5 + std::sin(x); }, 1},
      {"exp(sin), C1", [](double x) { return std::exp(std::sin(x)); }, 0},
  };
  for (const Case& c : cases) {
    std::vector<double> errors;
    for (int n : {16, 32, 64, 128, 256}) {
      std::vector<double> u;
      std::vector<Continuity> continuity;
      for (int j = 0; j <= n; ++j) {
        u.push_back(node(static_cast<double>(j) / n));
        Continuity k = Continuity::C1;
        if (c.pattern == 1 && j % 8 == 3) k = Continuity::C0;
        if (c.pattern == 1 && j % 8 == 6) k = Continuity::Jump;
        continuity.push_back(k);
      }
      errors.push_back(max_error(HermiteReconstruction(sampled(u, c.f, continuity)), u, c.f, 40));
    }
    for (std::size_t k = 1; k < errors.size(); ++k) {
      const double order = std::log2(errors[k - 1] / errors[k]);
      EXPECT_GT(order, 2.5) << c.name << ": errors " << errors[k - 1] << " -> " << errors[k];
    }
  }
}

}  // namespace
}  // namespace flatland
