#include "flatland/transport/footprint.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numbers>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "flatland/results/result_io.hpp"
#include "flatland/transport/sampling.hpp"
#include "test_support.hpp"

namespace flatland {
namespace {

const char* kScene = R"({
  "flatland": 1,
  "materials": {"wall": {"reflectivity": 0.5, "emittance": 1}},
  "curves": [
    {"id": "line", "material": "wall", "line": [[0,0],[10,0]]},
    {"id": "collinear", "material": "wall", "line": [[0,2],[4,2],[10,2]]},
    {"id": "corner", "material": "wall", "line": [[0,4],[4,4],[4,10]]},
    {"id": "arch", "material": "wall", "bezier": [[0,1],[0,3],[4,3],[4,1],[4,0],[6,0],[6,2]]},
    {"id": "kink", "material": "wall", "bezier": [[0,-3],[1,-2],[2,-2],[3,-3],[4,-2],[5,-2],[6,-3]]},
    {"id": "cusp", "material": "wall", "bezier": [[0,-6],[2,-4],[0.05,-4],[2,-6]]}
  ]})";

constexpr double kInfinity = std::numeric_limits<double>::infinity();

// Nearly a cusp (the loader refuses a true one): the speed falls to |C'(1/2)| = 0.0375 at t = 1/2,
// a hundredth of its value elsewhere (C'(1/2) = 3 ((2,2) + 2 (-1.95,0) + (1.95,-2)) / 4).
enum CurveIndex { kLine = 0, kCollinear = 1, kCorner = 2, kArch = 3, kKink = 4, kCusp = 5 };

const Scene& scene() {
  static const Scene s = testing::scene_from_text(kScene);
  return s;
}

// Arc length from the curve's start at curve parameter u (the table's own length_at).
double arc_length_at(const Curve& curve, double u) { return flatland::arc_length_at(scene(), curve, u); }

// The weights as a dense vector over the basis, after checking the contract: coefficients in
// range and increasing, weights > 0, sum 1 to 1e-14.
std::vector<double> checked_dense(const std::vector<FootprintWeight>& weights, std::size_t size) {
  std::vector<double> dense(size, 0.0);
  double sum = 0.0;
  for (std::size_t i = 0; i < weights.size(); ++i) {
    EXPECT_LT(weights[i].coefficient, size);
    if (i > 0) {
      EXPECT_GT(weights[i].coefficient, weights[i - 1].coefficient);
    }
    EXPECT_GT(weights[i].weight, 0.0);
    sum += weights[i].weight;
    if (weights[i].coefficient < size) dense[weights[i].coefficient] = weights[i].weight;
  }
  EXPECT_NEAR(sum, 1.0, 1e-14);
  return dense;
}

std::vector<double> footprint_dense(const Curve& curve, const SplineBasis& basis, double u_hit, double a,
                                    RayProfile profile, const FootprintTable* table = nullptr) {
  std::vector<FootprintWeight> out;
  footprint_weights(scene(), curve, basis, u_hit, a, profile, out, {}, table);
  return checked_dense(out, basis.size());
}

// Brute force: w_k = integral over the run [s_lo, s_hi] of the spread times phi_k(u(s)) ds,
// normalised, by the midpoint rule in arc length with u(s) from point_at_arc_length. The spread is
// k((s - s_hit)/a) plus, where it reaches past an end of the run, its mirror image about that end
// (the cut-off mass reflected back). The run is cut at the arc lengths of the knots, at the centres
// and at the edges of the spread and its images, so every cell sees a smooth integrand (error
// O(h^2)).
std::vector<double> midpoint_weights(const Curve& curve, const SplineBasis& basis, double s_lo, double s_hi,
                                     double s_hit, double a, RayProfile profile, int cells) {
  std::vector<double> centres = {s_hit};
  if (s_hit - a < s_lo) centres.push_back(2.0 * s_lo - s_hit);
  if (s_hit + a > s_hi) centres.push_back(2.0 * s_hi - s_hit);
  std::vector<double> cuts = {s_lo, s_hi};
  auto cut = [&](double s) {
    if (s > s_lo && s < s_hi) cuts.push_back(s);
  };
  for (double c : centres) {
    cut(c);
    cut(c - a);
    cut(c + a);
  }
  for (double knot : basis.knots()) cut(arc_length_at(curve, knot));
  std::sort(cuts.begin(), cuts.end());
  std::vector<double> dense(basis.size(), 0.0);
  std::array<double, SplineBasis::kMaxDegree + 1> phi{};
  for (std::size_t c = 0; c + 1 < cuts.size(); ++c) {
    const double h = (cuts[c + 1] - cuts[c]) / cells;
    for (int i = 0; i < cells; ++i) {
      const double s = cuts[c] + (i + 0.5) * h;
      double density = 0.0;
      for (double centre : centres) density += profile_density(profile, (s - centre) / a);
      const double u = point_at_arc_length(scene(), curve, s).u;
      const std::size_t first = basis.evaluate(u, phi.data());
      for (int r = 0; r <= basis.degree(); ++r) dense[basis.index(first + r)] += h * density * phi[r];
    }
  }
  double total = 0.0;
  for (double w : dense) total += w;
  for (double& w : dense) w /= total;
  return dense;
}

// The midpoint rule with 500 and 1000 cells per smooth piece, extrapolated (Richardson): the h^2
// terms cancel, leaving errors below 1e-12 here (1000 cells alone: 3e-7).
std::vector<double> brute_force(const Curve& curve, const SplineBasis& basis, double s_lo, double s_hi, double s_hit,
                                double a, RayProfile profile) {
  const std::vector<double> coarse = midpoint_weights(curve, basis, s_lo, s_hi, s_hit, a, profile, 500);
  std::vector<double> fine = midpoint_weights(curve, basis, s_lo, s_hi, s_hit, a, profile, 1000);
  for (std::size_t k = 0; k < fine.size(); ++k) fine[k] = (4.0 * fine[k] - coarse[k]) / 3.0;
  return fine;
}

void expect_close(const std::vector<double>& got, const std::vector<double>& want, double tolerance,
                  const std::string& what) {
  ASSERT_EQ(got.size(), want.size());
  for (std::size_t k = 0; k < got.size(); ++k) EXPECT_NEAR(got[k], want[k], tolerance) << what << " coefficient " << k;
}

TEST(Footprint, HalfLengthIsCappedAtGrazingIncidence) {
  EXPECT_DOUBLE_EQ(footprint_half_length(0.1, 1.0), 0.05);
  EXPECT_DOUBLE_EQ(footprint_half_length(0.1, -0.5), 0.1);
  EXPECT_DOUBLE_EQ(footprint_half_length(0.1, 0.05), 1.0);
  EXPECT_DOUBLE_EQ(footprint_half_length(0.1, 1e-9), 1.0);  // 10 W at most
  EXPECT_DOUBLE_EQ(footprint_half_length(0.1, 0.0), 1.0);
  EXPECT_DOUBLE_EQ(footprint_half_length(0.1, std::nan("")), 1.0);
}

TEST(Footprint, BoxOnALineGivesTheOverlapOfConstantElements) {
  // Ten constant elements of length 1 on a line of length 10: with the box profile w_k is the
  // overlap of element k with the footprint [s - a, s + a], the parts past the line's ends folded
  // back about them ([s - a, 0] onto [0, a - s], [10, s + a] onto [20 - s - a, 10]), over 2a.
  const Curve& line = scene().curves[kLine];
  const CurveStorage storage = build_curve_storage(scene(), line, BasisKind::Constant, 10);
  ASSERT_EQ(storage.basis.size(), 10u);
  auto overlap_weights = [](double lo, double hi) {
    std::vector<double> w(10, 0.0);
    auto add = [&](double from, double to) {
      for (int k = 0; k < 10; ++k) w[k] += std::max(0.0, std::min(to, k + 1.0) - std::max(from, 1.0 * k));
    };
    add(std::max(lo, 0.0), std::min(hi, 10.0));
    if (lo < 0.0) add(0.0, -lo);
    if (hi > 10.0) add(20.0 - hi, 10.0);
    for (double& v : w) v /= hi - lo;
    return w;
  };
  struct Case {
    double s_hit, a;
  };
  for (const Case& c : {Case{3.3, 0.45}, Case{5.5, 2.2}, Case{0.3, 0.8}, Case{9.9, 0.6}, Case{6.0, 0.25},
                        Case{4.7, 1.0}, Case{0.0, 0.5}, Case{10.0, 1.5}}) {
    const std::vector<double> got = footprint_dense(line, storage.basis, c.s_hit / 10.0, c.a, RayProfile::Box);
    expect_close(got, overlap_weights(c.s_hit - c.a, c.s_hit + c.a), 1e-14, "s_hit " + std::to_string(c.s_hit));
  }
  // Grazing incidence: W = 0.3 at cos = 1e-6 is capped at a = 10 W = 3.
  const double a = footprint_half_length(0.3, 1e-6);
  EXPECT_DOUBLE_EQ(a, 3.0);
  expect_close(footprint_dense(line, storage.basis, 0.45, a, RayProfile::Box), overlap_weights(1.5, 7.5), 1e-14,
               "grazing");
  // A footprint longer than the curve, or infinite, spreads uniformly over it.
  for (double huge : {1e6, 1e300, kInfinity}) {
    for (RayProfile profile : kRayProfiles) {
      expect_close(footprint_dense(line, storage.basis, 0.37, huge, profile), std::vector<double>(10, 0.1),
                   huge > 1e100 ? 1e-14 : 1e-6, to_string(profile));
    }
  }
}

TEST(Footprint, SpillsAcrossATangentContinuousJointOnly) {
  // Polylines of segments 4 and 6 long with ten constant elements of length 1. Straight on: the
  // box over [3.1, 4.3] puts 0.9/1.2 on element 3 and 0.3/1.2 on element 4, across the joint.
  const Curve& collinear = scene().curves[kCollinear];
  const CurveStorage straight = build_curve_storage(scene(), collinear, BasisKind::Constant, 10);
  ASSERT_EQ(straight.basis.size(), 10u);
  std::vector<double> want(10, 0.0);
  want[3] = 0.75;
  want[4] = 0.25;
  expect_close(footprint_dense(collinear, straight.basis, 3.7 / 4.0, 0.6, RayProfile::Box), want, 1e-14, "collinear");
  // From the other side (u = 1 + 0.3/6, s = 4.3) over [3.7, 4.9]: 0.3/1.2 and 0.9/1.2.
  want[3] = 0.25;
  want[4] = 0.75;
  expect_close(footprint_dense(collinear, straight.basis, 1.0 + 0.3 / 6.0, 0.6, RayProfile::Box), want, 1e-14,
               "collinear, from the right");
  // Around a corner: [2.8, 4.4] is cut at 4, leaving 0.2/1.2 and 1.0/1.2 on the hit side.
  const Curve& corner = scene().curves[kCorner];
  const CurveStorage bent = build_curve_storage(scene(), corner, BasisKind::Constant, 10);
  ASSERT_EQ(bent.basis.size(), 10u);
  want.assign(10, 0.0);
  want[2] = 0.2 / 1.2;
  want[3] = 1.0 / 1.2;
  expect_close(footprint_dense(corner, bent.basis, 3.4 / 4.0, 0.6, RayProfile::Box), want, 1e-14, "corner");
  // A hit exactly on the corner belongs to the segment that starts there: [4, 4.5] only.
  want.assign(10, 0.0);
  want[4] = 1.0;
  expect_close(footprint_dense(corner, bent.basis, 1.0, 0.5, RayProfile::Box), want, 1e-14, "on the corner");
  // Infinite footprint: uniform over the run, the whole collinear curve or the corner's first leg.
  expect_close(footprint_dense(collinear, straight.basis, 0.5, kInfinity, RayProfile::Tent),
               std::vector<double>(10, 0.1), 1e-14, "collinear, infinite");
  want.assign(10, 0.0);
  for (int k = 0; k < 4; ++k) want[k] = 0.25;
  expect_close(footprint_dense(corner, bent.basis, 0.5, kInfinity, RayProfile::Tent), want, 1e-14, "corner, infinite");
}

TEST(Footprint, CubicsMatchABruteForceIntegralAcrossJointsAndEnds) {
  // The arch's joint at u = 1 is tangent-continuous (tangents (0,-2) and (0,-1)): the spread
  // continues into the second segment. The kink's joint at u = 1 is a corner ((1,-1) against
  // (1,1)): the spread stops there. Both curves end at u = 0 and u = 2.
  const Curve& arch = scene().curves[kArch];
  const Curve& kink = scene().curves[kKink];
  for (BasisKind kind : {BasisKind::Constant, BasisKind::Linear, BasisKind::Cubic}) {
    for (RayProfile profile : kRayProfiles) {
      const std::string what = std::string(to_string(kind)) + " " + to_string(profile);
      // Arch, straddling the joint from either side, and at both ends.
      const CurveStorage storage = build_curve_storage(scene(), arch, kind, 8);
      const FootprintTable table(scene(), arch, storage.basis);
      for (double u_hit : {0.93, 1.04, 0.02, 1.97, 0.5, 1.0, 0.0, 2.0}) {
        const double s_hit = arc_length_at(arch, u_hit);
        const double a = 0.9;
        const std::vector<double> got = footprint_dense(arch, storage.basis, u_hit, a, profile);
        const std::vector<double> want = brute_force(arch, storage.basis, 0.0, arch.length, s_hit, a, profile);
        expect_close(got, want, 1e-11, what + " arch u " + std::to_string(u_hit));
        // Whole spans from the table's moments (the polynomial profiles use them).
        expect_close(footprint_dense(arch, storage.basis, u_hit, a, profile, &table), want, 1e-11,
                     what + " arch, table, u " + std::to_string(u_hit));
        if (u_hit == 0.93) {  // the spill is real: weight on functions living past the joint
          double past = 0.0;
          for (std::size_t k = 0; k < storage.basis.size(); ++k)
            if (storage.basis.knots()[k] >= 1.0) past += got[k];
          EXPECT_GT(past, 1e-3) << what;
        }
      }
      // Kink, near the corner from either side: all weight on the hit side.
      const CurveStorage bent = build_curve_storage(scene(), kink, kind, 8);
      const FootprintTable bent_table(scene(), kink, bent.basis);
      const double joint = kink.segment_start[1];
      for (double u_hit : {0.93, 1.06, 1.0}) {  // 1.0: on the corner, the right side's
        const double s_hit = arc_length_at(kink, u_hit);
        const double a = 0.7;
        const std::vector<double> got = footprint_dense(kink, bent.basis, u_hit, a, profile);
        const double lo = u_hit < 1.0 ? 0.0 : joint;
        const double hi = u_hit < 1.0 ? joint : kink.length;
        const std::vector<double> want = brute_force(kink, bent.basis, lo, hi, s_hit, a, profile);
        expect_close(got, want, 1e-11, what + " kink u " + std::to_string(u_hit));
        expect_close(footprint_dense(kink, bent.basis, u_hit, a, profile, &bent_table), want, 1e-11,
                     what + " kink, table, u " + std::to_string(u_hit));
        for (std::size_t k = 0; k < bent.basis.size(); ++k) {
          const std::vector<double>& knots = bent.basis.knots();
          const bool only_right = knots[k] >= 1.0;
          const std::size_t support_end = k + static_cast<std::size_t>(bent.basis.degree()) + 1;
          const bool only_left = knots[support_end] <= 1.0;
          if ((u_hit < 1.0 && only_right) || (u_hit >= 1.0 && only_left)) {
            EXPECT_EQ(got[k], 0.0) << what << " k " << k;
          }
        }
      }
    }
  }
}

TEST(Footprint, EndsKeepUniformFluxExactAndLinearFluxSecondOrder) {
  // Noise-free: photons land with density f(s) along a curve; the expected deposit on coefficient
  // k is p_k = integral f(s) w_k(s) ds with w the footprint weights of a hit at s, against the
  // point deposit's q_k = integral f(s) phi_k(s) ds (what the footprint should not change). Both
  // by the midpoint rule in s (40,000 cells: 1e-9 here). Reflecting the cut-off mass about an end
  // keeps every q_k for uniform f (renormalising it instead made the deposited density ln 2 of the
  // truth at the end and 1.19x at W/2 from it, box profile); for linear f the error is
  // O(a^2): halving the footprint quarters it. At a line's ends and at a corner (of a polyline 4
  // and 6 long), linear storage of ten elements, box and tent profiles.
  for (const std::size_t index : {kLine, kCorner}) {
    const Curve& curve = scene().curves[index];
    const CurveStorage storage = build_curve_storage(scene(), curve, BasisKind::Linear, 10);
    const std::size_t n = storage.basis.size();
    auto deposits = [&](auto flux, double a, RayProfile profile) {
      std::vector<double> p(n, 0.0);
      std::vector<double> q(n, 0.0);
      const int cells = 40'000;
      const double h = curve.length / cells;
      std::vector<FootprintWeight> out;
      std::array<double, SplineBasis::kMaxDegree + 1> phi{};
      for (int i = 0; i < cells; ++i) {
        const double s = (i + 0.5) * h;
        const double u = point_at_arc_length(scene(), curve, s).u;
        out.clear();
        footprint_weights(scene(), curve, storage.basis, u, a, profile, out);
        for (const FootprintWeight& w : out) p[w.coefficient] += flux(s) * w.weight * h;
        const std::size_t first = storage.basis.evaluate(u, phi.data());
        for (int r = 0; r <= 1; ++r) q[storage.basis.index(first + r)] += flux(s) * phi[r] * h;
      }
      double worst = 0.0;
      for (std::size_t k = 0; k < n; ++k) worst = std::max(worst, std::fabs(p[k] - q[k]) / q[k]);
      return worst;
    };
    for (RayProfile profile : {RayProfile::Box, RayProfile::Tent}) {
      const std::string what = std::string(to_string(profile)) + (index == kLine ? " line" : " corner");
      EXPECT_LT(deposits([](double) { return 1.0; }, 0.4, profile), 1e-8) << what;
      auto linear = [](double s) { return 1.0 + 0.5 * s; };
      const double wide = deposits(linear, 0.4, profile);
      const double narrow = deposits(linear, 0.2, profile);
      EXPECT_GT(wide, 1e-4) << what;  // not exact: the reflection bends a slope at the end
      EXPECT_NEAR(wide / narrow, 4.0, 0.6) << what;
    }
  }
}

TEST(Footprint, WrapsRoundTheClosingPointOfASmoothLoop) {
  // A closed circle smooth all round has no ends: a uniform flux is deposited exactly as point
  // deposits would be everywhere, the closing point included (a seam there would reflect or cut
  // the spread and so lose it only for non-uniform flux; a renormalised cut would pile it up).
  // Hits just before the closing point put weight on functions just after it.
  const Scene ring = testing::scene_from_text(testing::circle_enclosure(0.5, 1.0));
  const Curve& curve = ring.curves[0];
  const CurveStorage storage = build_curve_storage(ring, curve, BasisKind::Cubic, 16);
  ASSERT_TRUE(storage.basis.is_periodic());
  const std::size_t n = storage.basis.size();
  for (RayProfile profile : {RayProfile::Box, RayProfile::Gauss}) {
    std::vector<FootprintWeight> out;
    footprint_weights(ring, curve, storage.basis, 3.99, 0.5, profile, out);
    double sum = 0.0;
    double past = 0.0;  // on functions that live only after the closing point (u in (0, 1))
    for (const FootprintWeight& w : out) {
      ASSERT_LT(w.coefficient, n);
      sum += w.weight;
      const double begin = storage.basis.knots()[w.coefficient];
      if (begin >= 0.0 && begin < 1.0) past += w.weight;
    }
    EXPECT_NEAR(sum, 1.0, 1e-15);
    EXPECT_GT(past, 0.1) << to_string(profile);
    // Uniform flux, 16,000 cells of arc length.
    std::vector<double> p(n, 0.0);
    std::vector<double> q(n, 0.0);
    const int cells = 16'000;
    const double h = curve.length / cells;
    std::array<double, SplineBasis::kMaxDegree + 1> phi{};
    for (int i = 0; i < cells; ++i) {
      const double u = point_at_arc_length(ring, curve, (i + 0.5) * h).u;
      out.clear();
      footprint_weights(ring, curve, storage.basis, u, 0.5, profile, out);
      for (const FootprintWeight& w : out) p[w.coefficient] += w.weight * h;
      const std::size_t first = storage.basis.evaluate(u, phi.data());
      for (int r = 0; r <= 3; ++r) q[storage.basis.index(first + r)] += phi[r] * h;
    }
    for (std::size_t k = 0; k < n; ++k) EXPECT_NEAR(p[k], q[k], 1e-6 * q[k]) << to_string(profile) << " k " << k;
  }
}

TEST(Footprint, TinyFootprintApproachesThePointDeposit) {
  // As a -> 0 the weights tend to phi_k(u_hit), with an error of order a |phi_k'| / speed; with
  // the span table too, and on a corner (u = 1 on the corner and the kink: fraction 0.5) nothing
  // leaks across it, not even a sliver made by rounding s_hit + x.
  std::array<double, SplineBasis::kMaxDegree + 1> phi{};
  for (int index : {kLine, kCollinear, kCorner, kArch, kKink}) {
    const Curve& curve = scene().curves[index];
    for (BasisKind kind : {BasisKind::Constant, BasisKind::Linear, BasisKind::Cubic}) {
      const CurveStorage storage = build_curve_storage(scene(), curve, kind, 7);
      const FootprintTable table(scene(), curve, storage.basis);
      const bool corner = index == kCorner || index == kKink;
      for (double fraction : {0.0065, 0.21605, 0.5, 0.6234, 0.9995}) {
        // (At a smooth joint the knot at 0.5 splits a tiny footprint between its two sides.)
        if (fraction == 0.5 && !corner) continue;
        const double u_hit = fraction * curve.segment_count;
        std::vector<double> point(storage.basis.size(), 0.0);
        const std::size_t first = storage.basis.evaluate(u_hit, phi.data());
        for (int r = 0; r <= storage.basis.degree(); ++r) point[first + r] = phi[r];
        for (RayProfile profile : kRayProfiles) {
          const std::string what = curve.id + " " + to_string(kind) + " " + to_string(profile);
          for (double a : {1e-7, 1e-10}) {
            expect_close(footprint_dense(curve, storage.basis, u_hit, a * curve.length, profile), point, 1e4 * a,
                         what + " a " + std::to_string(a));
            if (is_polynomial(profile))
              expect_close(footprint_dense(curve, storage.basis, u_hit, a * curve.length, profile, &table), point,
                           1e4 * a, what + " table, a " + std::to_string(a));
          }
        }
        // No footprint at all (or a NaN one): exactly the point deposit.
        for (double a : {0.0, -1.0, std::nan("")}) {
          expect_close(footprint_dense(curve, storage.basis, u_hit, a, RayProfile::Tent), point, 1e-15,
                       curve.id + " degenerate");
        }
      }
    }
  }
}

TEST(Footprint, SpanTableHoldsTheBasisIntegralsAndLengths) {
  // Independent of the footprint: summed over the spans, a function's zeroth moments are its
  // integral over the curve (build_curve_storage's basis_length, its own quadrature), and a span's
  // zeroth moments sum to its arc length (B-splines sum to one); the first moments of a line's span
  // in y = (s - s_mid) / h vanish for a function symmetric about the span's middle (a constant
  // element), and the second moments of a constant element are its length / 3.
  const Scene ring = testing::scene_from_text(testing::circle_enclosure(0.5, 1.0));
  struct Case {
    const Scene* scene;
    std::uint32_t curve;
  };
  for (const Case& c :
       {Case{&scene(), kLine}, Case{&scene(), kCorner}, Case{&scene(), kArch}, Case{&scene(), kKink}, Case{&ring, 0}}) {
    const Curve& curve = c.scene->curves[c.curve];
    for (BasisKind kind : {BasisKind::Constant, BasisKind::Linear, BasisKind::Cubic}) {
      const std::string what = curve.id + " " + to_string(kind);
      const CurveStorage storage = build_curve_storage(*c.scene, curve, kind, 11);
      const SplineBasis& basis = storage.basis;
      const FootprintTable table(*c.scene, curve, basis);
      const std::size_t p = static_cast<std::size_t>(basis.degree());
      std::vector<double> integral(basis.size(), 0.0);
      double total = 0.0;
      for (std::size_t span = basis.first_span(); span < basis.end_span(); ++span) {
        const double* m = table.moments(span);
        double sum = 0.0;
        for (std::size_t r = 0; r <= p; ++r) {
          integral[basis.index(span - p + r)] += m[r];
          sum += m[r];
        }
        EXPECT_NEAR(sum, table.length(span), 1e-13 * curve.length) << what << " span " << span;
        total += table.length(span);
        if (kind == BasisKind::Constant && curve.id == "line") {
          EXPECT_NEAR(m[1], 0.0, 1e-14 * curve.length) << what;
          EXPECT_NEAR(m[2], table.length(span) / 3.0, 1e-14 * curve.length) << what;
        }
      }
      EXPECT_NEAR(total, curve.length, 1e-12 * curve.length) << what;
      // The running moments at y = 1 (T_k(1) = 1: the sum of the coefficients) are the whole
      // span's moments, and the span starts step by the spans' lengths.
      EXPECT_EQ(table.start(basis.end_span()), curve.length) << what;
      for (std::size_t span = basis.first_span(); span < basis.end_span(); ++span) {
        EXPECT_NEAR(table.start(span + 1) - table.start(span), table.length(span), 1e-13 * curve.length)
            << what << " span " << span;
        std::size_t terms = 0;
        const double* running = table.running(span, terms);
        if (table.length(span) == 0.0) {
          EXPECT_EQ(running, nullptr) << what << " span " << span;
          continue;
        }
        ASSERT_NE(running, nullptr) << what << " span " << span;
        const std::size_t powers = static_cast<std::size_t>(table.powers());
        for (std::size_t j = 0; j < powers; ++j) {
          for (std::size_t r = 0; r <= p; ++r) {
            double at_one = 0.0;
            for (std::size_t k = 0; k < terms; ++k) at_one += running[(k * powers + j) * (p + 1) + r];
            EXPECT_NEAR(at_one, table.moments(span)[j * (p + 1) + r], 1e-12 * curve.length)
                << what << " span " << span << " j " << j << " r " << r;
          }
        }
      }
      for (std::size_t k = 0; k < basis.size(); ++k)
        EXPECT_NEAR(integral[k], storage.basis_length[k], 1e-12 * curve.length) << what << " k " << k;
    }
  }
}

TEST(Footprint, SpanTableGivesTheQuadraturesWeightsEverywhere) {
  // Whole knot spans from the table against the footprint's own Gauss points: the same weights to
  // rounding for every polynomial profile, on lines, corners, cubics with smooth and corner joints,
  // a periodic ring, with walls, and footprints from a fraction of a span to many spans and the
  // whole curve (flat).
  const Scene ring = testing::scene_from_text(testing::circle_enclosure(0.5, 1.0));
  struct Case {
    const Scene* scene;
    std::uint32_t curve;
  };
  Rng rng(7, 1, 2);
  for (const Case& c : {Case{&scene(), kLine}, Case{&scene(), kCollinear}, Case{&scene(), kCorner},
                        Case{&scene(), kArch}, Case{&scene(), kKink}, Case{&ring, 0}}) {
    const Curve& curve = c.scene->curves[c.curve];
    for (BasisKind kind : {BasisKind::Constant, BasisKind::Linear, BasisKind::Cubic}) {
      const CurveStorage storage = build_curve_storage(*c.scene, curve, kind, 40);
      const FootprintTable table(*c.scene, curve, storage.basis);
      const std::vector<double> walls = {0.37 * curve.length};
      for (int trial = 0; trial < 200; ++trial) {
        const double u_hit = curve.segment_count * rng.uniform();
        const double a = trial == 0 ? kInfinity : curve.length * std::pow(10.0, -3.0 + 3.5 * rng.uniform());
        const auto profile = static_cast<RayProfile>(trial % 3);  // box, tent, Epanechnikov
        const std::span<const double> wall =
            trial % 4 == 1 ? std::span<const double>(walls) : std::span<const double>();
        std::vector<FootprintWeight> plain;
        std::vector<FootprintWeight> tabled;
        footprint_weights(*c.scene, curve, storage.basis, u_hit, a, profile, plain, wall);
        footprint_weights(*c.scene, curve, storage.basis, u_hit, a, profile, tabled, wall, &table);
        const std::vector<double> want = checked_dense(plain, storage.basis.size());
        expect_close(checked_dense(tabled, storage.basis.size()), want, 1e-12,
                     curve.id + " " + to_string(kind) + " " + to_string(profile) + " trial " + std::to_string(trial));
      }
    }
  }
}

TEST(Footprint, SpanTableFallsBackToQuadratureNearACusp) {
  // Where the speed nearly vanishes, u(s) is nearly a square root (a singularity just off the real
  // axis) and no Chebyshev series of 33 points fits phi_r(u(s)): that span keeps none, and parts of it take the
  // footprint's own quadrature in u between the inverted ends. So the tabled weights equal the plain ones there, and
  // elsewhere on the curve the series serve.
  const Curve& cusp = scene().curves[kCusp];
  for (BasisKind kind : {BasisKind::Constant, BasisKind::Linear, BasisKind::Cubic}) {
    const CurveStorage storage = build_curve_storage(scene(), cusp, kind, 3);
    const SplineBasis& basis = storage.basis;
    const FootprintTable table(scene(), cusp, basis);
    std::size_t with = 0;
    std::size_t without = 0;
    for (std::size_t span = basis.first_span(); span < basis.end_span(); ++span) {
      if (!(basis.knots()[span + 1] > basis.knots()[span])) continue;
      std::size_t terms = 0;
      (table.running(span, terms) != nullptr ? with : without) += 1;
      const bool holds_cusp = basis.knots()[span] < 0.5 && basis.knots()[span + 1] > 0.5;
      EXPECT_EQ(table.running(span, terms) == nullptr, holds_cusp) << to_string(kind) << " span " << span;
    }
    EXPECT_GT(with, 0u) << to_string(kind);
    EXPECT_GT(without, 0u) << to_string(kind);
    for (RayProfile profile : {RayProfile::Box, RayProfile::Tent, RayProfile::Epanechnikov}) {
      for (double u_hit : {0.45, 0.5, 0.55, 0.2, 0.9}) {
        for (double a : {0.01, 0.1, 0.5}) {
          const std::string what = std::string(to_string(kind)) + " " + to_string(profile) + " u " +
                                   std::to_string(u_hit) + " a " + std::to_string(a);
          expect_close(footprint_dense(cusp, basis, u_hit, a, profile, &table),
                       footprint_dense(cusp, basis, u_hit, a, profile), 1e-12, what);
        }
      }
    }
  }
}

TEST(Footprint, AppendsToTheCallersVectorAndStaysValidEverywhere) {
  // Random hits, sizes and profiles on every curve and basis: the appended block always obeys the
  // contract, and what was in the vector before is left alone.
  Rng rng(5, 1, 2);
  std::vector<FootprintWeight> out;
  for (std::size_t index = 0; index < scene().curves.size(); ++index) {
    const Curve& curve = scene().curves[index];
    for (BasisKind kind : {BasisKind::Constant, BasisKind::Linear, BasisKind::Cubic}) {
      const CurveStorage storage = build_curve_storage(scene(), curve, kind, 9);
      for (int trial = 0; trial < 300; ++trial) {
        const double u_hit = curve.segment_count * rng.uniform();
        const double a = curve.length * std::pow(10.0, -6.0 + 6.5 * rng.uniform());
        const RayProfile profile = kRayProfiles[static_cast<std::size_t>(trial) % kRayProfiles.size()];
        out.assign(1, FootprintWeight{12345, -7.0});
        footprint_weights(scene(), curve, storage.basis, u_hit, a, profile, out);
        ASSERT_GE(out.size(), 2u);
        EXPECT_EQ(out[0].coefficient, 12345u);
        EXPECT_EQ(out[0].weight, -7.0);
        const std::vector<FootprintWeight> block(out.begin() + 1, out.end());
        checked_dense(block, storage.basis.size());
      }
    }
  }
}

}  // namespace
}  // namespace flatland
