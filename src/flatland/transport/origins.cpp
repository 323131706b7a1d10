#include "flatland/transport/origins.hpp"

#include <algorithm>
#include <array>
#include <cmath>

#include "flatland/geometry/bezier.hpp"

namespace flatland {
namespace {

// A parameter from what is left of kPlace, inside (0, 1) as Rng::uniform_open's.
double open(double rest) { return std::max(rest, 0x1.0p-54); }

}  // namespace

DiscreteDistribution segment_choice(const Scene& scene, const Curve& curve) {
  std::vector<double> lengths;
  for (std::uint32_t i = 0; i < curve.segment_count; ++i)
    lengths.push_back(scene.segments[curve.first_segment + i].length);
  return DiscreteDistribution(lengths);
}

std::vector<Vec2> line_tangents(const Scene& scene) {
  std::vector<Vec2> tangents;
  tangents.reserve(scene.segments.size());
  for (const SceneSegment& segment : scene.segments) {
    const Cubic& c = segment.geometry.shape;
    tangents.push_back(segment.geometry.kind == SegmentKind::Line ? normalized(c.p[3] - c.p[0]) : Vec2{});
  }
  return tangents;
}

Origin sample_uniform_origin(const Scene& scene, const Curve& curve, const DiscreteDistribution& segment_choice,
                             std::span<const Vec2> line_tangents, OriginDraws& draws) {
  // Sobol': the segment and then t from what is left of kPlace, so the origin is one stratified
  // coordinate along the whole source.
  Origin origin;
  double along = 0.0;
  origin.segment =
      curve.first_segment + static_cast<std::uint32_t>(draws.quasi() ? segment_choice.sample(draws.place, along)
                                                                     : segment_choice.sample(draws.rng.uniform()));
  const SceneSegment& segment = scene.segments[origin.segment];
  const Cubic& shape = segment.geometry.shape;
  if (segment.geometry.kind == SegmentKind::Line) {
    origin.t = draws.quasi() ? open(along) : draws.rng.uniform_open();
    origin.position = lerp(shape.p[0], shape.p[3], origin.t);
    origin.tangent = line_tangents[origin.segment];
    return origin;
  }
  for (int attempt = 0;; ++attempt) {
    const bool from_point = draws.quasi() && attempt == 0;
    origin.t = from_point ? open(along) : draws.rng.uniform_open();
    const Vec2 velocity = derivative(shape, origin.t);
    const double speed = length(velocity);
    if ((from_point ? draws.coordinate(kAcceptSpeed) : draws.rng.uniform()) * segment.speed_bound < speed) {
      origin.tangent = (1.0 / speed) * velocity;
      break;
    }
  }
  origin.position = evaluate(shape, origin.t);
  return origin;
}

double uniform_origin_pdf(const Curve& curve) { return 1.0 / curve.length; }

Origin sample_profiled_origin(const Scene& scene, const Curve& curve, const DiscreteDistribution& segment_choice,
                              OriginDraws& draws) {
  // The proposal is uniform in arc length (a segment by length, then t against the segment's
  // speed bound until accepted, on that segment); only the profile's test starts afresh. (A speed
  // rejection that chose the segment again would weight segment i by length_i^2 / bound_i: right
  // for lines, whose bound is their length, wrong for cubics of different shapes.)
  Origin origin;
  for (int attempt = 0;; ++attempt) {
    const bool from_point = draws.quasi() && attempt == 0;
    double along = 0.0;
    origin.segment =
        curve.first_segment + static_cast<std::uint32_t>(from_point ? segment_choice.sample(draws.place, along)
                                                                    : segment_choice.sample(draws.rng.uniform()));
    const SceneSegment& segment = scene.segments[origin.segment];
    const Cubic& shape = segment.geometry.shape;
    Vec2 velocity;
    double speed = 0.0;
    for (int proposal = 0;; ++proposal) {
      const bool point_proposal = from_point && proposal == 0;
      origin.t = point_proposal ? open(along) : draws.rng.uniform_open();
      velocity = derivative(shape, origin.t);
      speed = length(velocity);
      if ((point_proposal ? draws.coordinate(kAcceptSpeed) : draws.rng.uniform()) * segment.speed_bound < speed) break;
    }
    const double u = (origin.segment - curve.first_segment) + origin.t;
    if (!((from_point ? draws.coordinate(kAcceptProfile) : draws.rng.uniform()) * curve.profile_max <
          emittance_factor(curve, u)))
      continue;
    origin.tangent = (1.0 / speed) * velocity;
    origin.position = evaluate(shape, origin.t);
    return origin;
  }
}

double profiled_origin_pdf(const Curve& curve, double u) {
  return emittance_factor(curve, u) / (curve.profile_mean * curve.length);
}

Origin sample_coefficient_origin(const Scene& scene, const Curve& curve, const CurveStorage& storage, std::size_t k,
                                 std::span<const Vec2> line_tangents, OriginDraws& draws) {
  Origin origin;
  for (int attempt = 0;; ++attempt) {
    // Sobol': the place inside the piece from kPlace (for constant storage, whose basis functions
    // have one piece, the whole origin is then one stratified coordinate).
    const bool from_point = draws.quasi() && attempt == 0;
    double u = 0.0;
    if (from_point) {
      u = storage.sampler.sample(k, draws.coordinate(kPiece), draws.place);
    } else {
      // Pseudo-random numbers have no stratification to keep: the simplex draw, no inversion.
      std::array<double, 4> uniforms{};
      for (int i = 0; i <= storage.sampler.degree(); ++i) uniforms[static_cast<std::size_t>(i)] = draws.rng.uniform();
      u = storage.sampler.sample_simplex(k, uniforms);
    }
    const auto local = static_cast<std::uint32_t>(std::min<double>(std::floor(u), curve.segment_count - 1.0));
    origin.segment = curve.first_segment + local;
    origin.t = u - local;
    // A line's speed |C'| is its length (no derivative to evaluate; its tangent is tabled).
    const SceneSegment& segment = scene.segments[origin.segment];
    const bool line = segment.geometry.kind == SegmentKind::Line;
    const Vec2 velocity = line ? Vec2{} : derivative(segment.geometry.shape, origin.t);
    const double speed = line ? segment.length : length(velocity);
    if ((from_point ? draws.coordinate(kAcceptSpeed) : draws.rng.uniform()) * storage.speed_bound[k] < speed) {
      origin.tangent = line ? line_tangents[origin.segment] : (1.0 / speed) * velocity;
      break;
    }
  }
  origin.position = evaluate(scene.segments[origin.segment].geometry.shape, origin.t);
  return origin;
}

double coefficient_origin_pdf(const CurveStorage& storage, std::size_t k, double u) {
  // The sampler's density is phi_k over its integral in the curve parameter; per unit arc length
  // the integral is basis_length[k].
  return storage.sampler.pdf(k, u) * storage.sampler.mass(k) / storage.basis_length[k];
}

Origin sample_hermite_origin(const Scene& scene, const Curve& curve, const HermiteReconstruction& density,
                             OriginDraws& draws) {
  double s = 0.0;
  if (draws.quasi()) {
    s = density.sample(draws.coordinate(kPiece), draws.place);
  } else {
    const double place = draws.rng.uniform();
    const double piece = draws.rng.uniform();
    s = density.sample(piece, place);
  }
  const CurvePoint point = point_at_arc_length(scene, curve, s);
  Origin origin;
  origin.segment = curve.first_segment + point.segment_in_curve;
  origin.t = point.t;
  origin.position = point.position;
  origin.tangent = unit_tangent(scene.segments[origin.segment].geometry.shape, origin.t, scene.scale);
  return origin;
}

double hermite_origin_pdf(const HermiteReconstruction& density, double s) { return density.pdf(s); }

}  // namespace flatland
