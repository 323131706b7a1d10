// Closed forms the tests check against: a one-bounce penumbra (a line emitter, an occluder and a
// floor), the same past a round (Bezier) occluder, and a lit ring with an emittance profile, solved
// in Fourier series.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <string>
#include <utility>
#include <vector>

#include "flatland/geometry/bezier.hpp"
#include "flatland/scene/scene.hpp"
#include "flatland/storage/curve_storage.hpp"

namespace flatland::closed_forms {

// One bounce from a black line emitter onto a flat receiver, optionally with a black occluder.
// Irradiance at (x, 0) (normal +y): H(x) = E (1/2) * measure, in sin(theta), of the visible part of
// the emitter, theta measured from the normal; the occluder sits between them, so the visible part
// is the emitter's interval minus the occluder's.
struct PenumbraSetup {
  double emitter_left = -0.5, emitter_right = 0.5, emitter_height = 2.0;
  double occluder_left = -0.2, occluder_right = 0.6, occluder_height = 1.0;
  double floor_left = -3.0, floor_right = 3.0;
  double rho = 0.5;
  bool occluded = true;

  std::string scene_text() const {
    char curves[1024];
    std::snprintf(curves, sizeof curves,
                  R"({"id": "lamp", "material": "lamp", "line": [[%.17g,%.17g],[%.17g,%.17g]]},
                     {"id": "floor", "material": "floor", "line": [[%.17g,0],[%.17g,0]]})",
                  emitter_right, emitter_height, emitter_left, emitter_height, floor_left, floor_right);
    std::string text = R"({"flatland": 1, "materials": {"lamp": {"emittance": 1}, "black": {},
                           "floor": {"reflectivity": )" +
                       std::to_string(rho) + R"(}}, "curves": [)" + curves;
    if (occluded) {
      char occluder[256];
      std::snprintf(
          occluder, sizeof occluder,
          R"(, {"id": "occluder", "material": "black", "sides": "both", "line": [[%.17g,%.17g],[%.17g,%.17g]]})",
          occluder_left, occluder_height, occluder_right, occluder_height);
      text += occluder;
    }
    return text + "]}";
  }

  double irradiance(double x) const {
    auto sine = [x](double px, double py) { return (px - x) / std::hypot(px - x, py); };
    const double a = sine(emitter_left, emitter_height);
    const double b = sine(emitter_right, emitter_height);
    double visible = b - a;
    if (occluded) {
      const double c = std::max(a, sine(occluder_left, occluder_height));
      const double d = std::min(b, sine(occluder_right, occluder_height));
      if (d > c) visible -= d - c;
    }
    return 0.5 * visible;
  }
};

// integral(phi_k H ds) for the floor's storage functions, H the closed-form irradiance, by a fine
// midpoint rule on every knot span of the floor's basis (u runs over [0, 1], ds = L du; H kinks at
// the penumbra's edges, which need not be knots): the expected deposits. Per span, so that no step
// straddles a knot, where the functions jump or kink.
inline std::vector<double> expected_floor_power(const PenumbraSetup& setup, const CurveStorage& storage) {
  const double length = setup.floor_right - setup.floor_left;
  const SplineBasis& basis = storage.basis;
  const std::vector<double>& knots = basis.knots();
  const auto p = static_cast<std::size_t>(basis.degree());
  const int steps = 200'000;  // over the whole floor, shared among the spans by their length
  std::vector<double> expected(basis.size(), 0.0);
  std::array<double, SplineBasis::kMaxDegree + 1> phi{};
  for (std::size_t k = basis.first_span(); k < basis.end_span(); ++k) {
    const double a = knots[k];
    const double b = knots[k + 1];
    if (!(b > a)) continue;
    const int n = std::max(64, static_cast<int>(steps * (b - a)));
    for (int i = 0; i < n; ++i) {
      const double u = a + (b - a) * (i + 0.5) / n;
      const double h = setup.irradiance(setup.floor_left + u * length);
      basis.evaluate_in_span(k, u, phi.data());
      for (std::size_t j = 0; j <= p; ++j) expected[basis.index(k - p + j)] += phi[j] * h * length * (b - a) / n;
    }
  }
  return expected;
}

// A ring of radius 1 (eight cubic arcs of 45 degrees, counter-clockwise from (1, 0)) with
// rho = 0.5, E = 1 and an emittance profile E(phi) = 1 + 0.8 sin(phi), steepest at the closing
// point: factors at the arcs' ends, and inner factors that give the Bernstein form the profile's
// slope (as docs/figures/seam/ring_seam.py writes it). `version` 1 makes the closing point a seam.
inline std::string ring_with_profile(int version) {
  const double pi = std::numbers::pi;
  const double handle = 4.0 / 3.0 * std::tan(pi / 16.0);
  auto profile = [](double phi) { return 1.0 + 0.8 * std::sin(phi); };
  std::string points;
  std::string factors;
  auto add = [](std::string& list, double x, double y, bool pair) {
    char text[96];
    if (pair)
      std::snprintf(text, sizeof text, "%s[%.17g,%.17g]", list.empty() ? "" : ",", x, y);
    else
      std::snprintf(text, sizeof text, "%s%.17g", list.empty() ? "" : ",", x);
    list += text;
  };
  for (int i = 0; i < 8; ++i) {
    const double a = i * pi / 4.0;
    const double b = (i + 1) * pi / 4.0;
    const double d = (b - a) / 3.0;
    if (i == 0) {
      add(points, 1.0, 0.0, true);
      add(factors, profile(a), 0, false);
    }
    add(points, std::cos(a) - handle * std::sin(a), std::sin(a) + handle * std::cos(a), true);
    add(points, std::cos(b) + handle * std::sin(b), std::sin(b) - handle * std::cos(b), true);
    if (i == 7)
      add(points, 1.0, 0.0, true);
    else
      add(points, std::cos(b), std::sin(b), true);
    add(factors, profile(a) + d * 0.8 * std::cos(a), 0, false);
    add(factors, profile(b) - d * 0.8 * std::cos(b), 0, false);
    add(factors, i == 7 ? profile(0.0) : profile(b), 0, false);
  }
  return "{\"flatland\": " + std::to_string(version) +
         R"(, "materials": {"wall": {"reflectivity": 0.5, "emittance": 1}},
    "curves": [{"id": "ring", "material": "wall", "bezier": [)" +
         points + "], \"emittance_profile\": [" + factors + "]}]}";
}

// B(phi) on a ring of uniform rho: the kernel per unit angle is k(psi) = |sin(psi/2)| / 4, so the
// equation is diagonal in Fourier series, B_n = E_n / (1 - rho lambda_n), lambda_0 = 1,
// lambda_n = -1 / (4 n^2 - 1). E_n = (1/pi) integral E(phi) (cos, sin)(n phi) dphi by the midpoint
// rule along the curve's own parameter with dphi = cross(p, p') / |p|^2 du (the cubic arcs' true
// angles, not arc length / radius).
struct RingSolution {
  std::vector<double> a, b;  // cosine and sine coefficients of B
  double operator()(double phi) const {
    double sum = 0.5 * a[0];
    for (std::size_t n = 1; n < a.size(); ++n) {
      const double angle = static_cast<double>(n) * phi;
      sum += a[n] * std::cos(angle) + b[n] * std::sin(angle);
    }
    return sum;
  }
};
inline RingSolution solve_ring(const Scene& scene, double rho, int terms = 48) {
  const Curve& ring = scene.curves[0];
  RingSolution solution{std::vector<double>(terms, 0.0), std::vector<double>(terms, 0.0)};
  const int steps = 64'000;
  for (int i = 0; i < steps; ++i) {
    const double u = ring.segment_count * (i + 0.5) / steps;
    const auto j = static_cast<std::uint32_t>(u);
    const Cubic& shape = scene.segments[ring.first_segment + j].geometry.shape;
    const Vec2 p = evaluate(shape, u - j);
    const Vec2 velocity = derivative(shape, u - j);
    const double dphi = cross(p, velocity) / dot(p, p) * ring.segment_count / steps;
    const double phi = std::atan2(p.y, p.x);
    const double e = emittance_factor(ring, u);
    for (int n = 0; n < terms; ++n) {
      solution.a[n] += e * std::cos(n * phi) * dphi / std::numbers::pi;
      solution.b[n] += e * std::sin(n * phi) * dphi / std::numbers::pi;
    }
  }
  for (int n = 0; n < terms; ++n) {
    const double lambda = n == 0 ? 1.0 : -1.0 / (4.0 * n * n - 1.0);
    solution.a[n] /= 1.0 - rho * lambda;
    solution.b[n] /= 1.0 - rho * lambda;
  }
  return solution;
}

// One bounce onto a flat floor (y = 0, normal up) from a black line lamp at height 2 (E = 1,
// x in [-0.5, 0.5]) past a black convex occluder: B(x) = rho (1/2) (measure of the lamp's sin(theta)
// interval minus the part the occluder's tangent lines cut out), sin(theta) = (p.x - x) / |p - x|.
// The occluder's extreme directions come from its Bezier segments themselves: the extremes of
// sin(theta) along C(t) are roots of g(t) = cross(C(t) - x, C'(t)) (the ray touches the curve);
// a coarse search per segment brackets them and Newton on g (g' = cross(C - x, C'')) polishes.
inline double round_occluder_floor(const Scene& scene, std::uint32_t occluder, double x, double rho) {
  const Vec2 p{x, 0.0};
  auto sine = [p](Vec2 q) { return (q.x - p.x) / length(q - p); };
  double low = INFINITY;
  double high = -INFINITY;
  const Curve& curve = scene.curves[occluder];
  for (std::uint32_t k = 0; k < curve.segment_count; ++k) {
    const Cubic& c = scene.segments[curve.first_segment + k].geometry.shape;
    for (const int sign : {-1, 1}) {
      double best_t = 0.0;
      double best = -INFINITY;
      for (int m = 0; m <= 64; ++m) {
        const double t = m / 64.0;
        const double value = sign * sine(evaluate(c, t));
        if (value > best) best = value, best_t = t;
      }
      double t = best_t;
      for (int iteration = 0; iteration < 50; ++iteration) {
        const Vec2 r = evaluate(c, t) - p;
        const double g = cross(r, derivative(c, t));
        const double slope = cross(r, second_derivative(c, t));
        if (slope == 0.0) break;
        const double next = std::clamp(t - g / slope, 0.0, 1.0);
        if (std::fabs(next - t) < 1e-15) break;
        t = next;
      }
      const double value = sine(evaluate(c, t));
      const double coarse = sine(evaluate(c, best_t));
      // Newton must not lose the bracketed extreme (it may only improve it).
      const double extreme = sign > 0 ? std::max(value, coarse) : std::min(value, coarse);
      low = std::min(low, extreme);
      high = std::max(high, extreme);
    }
  }
  const double a = sine({-0.5, 2.0});
  const double b = sine({0.5, 2.0});
  const double hidden = std::max(0.0, std::min(b, high) - std::max(a, low));
  return rho * 0.5 * ((b - a) - hidden);
}

// The Fourier coefficients a0 and b1 of B along the ring (ring_with_profile) from B at curve
// parameters: the midpoint rule over 2000 steps in the curve parameter, dphi = cross(p, p') / |p|^2
// du (as solve_ring).
template <typename Radiosity>
std::pair<double, double> ring_a0_b1(const Scene& scene, Radiosity radiosity) {
  const Curve& ring = scene.curves[0];
  double a = 0.0, b = 0.0;
  const int steps = 2000;
  for (int j = 0; j < steps; ++j) {
    const double u = ring.segment_count * (j + 0.5) / steps;
    const auto i = static_cast<std::uint32_t>(u);
    const Cubic& shape = scene.segments[ring.first_segment + i].geometry.shape;
    const Vec2 p = evaluate(shape, u - i);
    const double dphi = cross(p, derivative(shape, u - i)) / dot(p, p) * ring.segment_count / steps;
    const double phi = std::atan2(p.y, p.x);
    const double value = radiosity(u);
    a += value * dphi / std::numbers::pi;
    b += value * std::sin(phi) * dphi / std::numbers::pi;
  }
  return {a, b};
}

// The mean of independent runs' values and its standard error (the runs' spread over sqrt(n)).
inline std::pair<double, double> mean_and_standard_error(const std::vector<double>& values) {
  const auto n = static_cast<double>(values.size());
  double mean = 0.0;
  for (double v : values) mean += v / n;
  double variance = 0.0;
  for (double v : values) variance += (v - mean) * (v - mean) / (n - 1.0);
  return {mean, std::sqrt(variance / n)};
}

}  // namespace flatland::closed_forms
