// Where a photon leaves its source curve. The shooter has four densities of origin: uniform in
// arc length, an emitter's emittance profile, a coefficient's basis function (reconstructed
// origins on B-spline storage) and a Hermite reconstruction. Each comes as a Sample, a rejection
// loop (or an inversion) whose first proposal may come from the photon's Sobol' point and any
// later ones from the batch's stream, and a Pdf, the density per unit arc length along the curve
// that Sample follows (tests compare the two; docs/method.md derives them).
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "flatland/scene/scene.hpp"
#include "flatland/storage/curve_storage.hpp"
#include "flatland/storage/hermite.hpp"
#include "flatland/transport/qmc.hpp"
#include "flatland/transport/sampling.hpp"

namespace flatland {

// The coordinates of a photon's point of the round's scrambled Sobol' sequence: kPlace the source
// and, with what that choice leaves of it, the segment and the place on it (uniform and profiled
// origins) or inside the basis function's piece (reconstructed origins); kDirection the
// direction; kPiece the piece of the origin density; then the first proposal's acceptance tests.
enum PhotonDimension : int {
  kPlace = 0,
  kDirection = 1,
  kPiece = 2,
  kAcceptSpeed = 3,
  kAcceptProfile = 4,
  kAcceptLobe = 5,
};

// The uniforms an origin sampler draws: from the photon's Sobol' point for its first proposal
// (when there is one), from the batch's stream otherwise. Each photon's uniforms are still
// independent and uniform, so the estimate stays unbiased, and the nets stratify the proposals
// that are accepted first.
struct OriginDraws {
  Rng& rng;
  const SobolCursor* point = nullptr;  // the photon's point; null for pseudo-random numbers
  double place = 0.0;                  // what choosing the source left of kPlace, in [0, 1)

  bool quasi() const { return point != nullptr; }
  double coordinate(int dimension) const { return point->sample(dimension); }
};

struct Origin {
  std::uint32_t segment = 0;  // index into Scene::segments
  double t = 0.0;             // on that segment
  Vec2 position;
  Vec2 tangent;  // unit, in the direction of increasing t
};

// What the samplers read of a scene: a curve's segments by length, and every segment's unit
// tangent if it is a line (zero for a cubic).
DiscreteDistribution segment_choice(const Scene& scene, const Curve& curve);
std::vector<Vec2> line_tangents(const Scene& scene);

// Uniform in arc length: a segment by its length (segment_choice over the curve's segments),
// then t with density |C'(t)| / length by rejection against the segment's speed bound (a line's
// speed is constant: no rejection). line_tangents[i] is segment i's unit tangent if it is a line.
Origin sample_uniform_origin(const Scene& scene, const Curve& curve, const DiscreteDistribution& segment_choice,
                             std::span<const Vec2> line_tangents, OriginDraws& draws);
// 1 / length.
double uniform_origin_pdf(const Curve& curve);

// An emitter with an emittance profile: uniform in arc length, accepted with probability
// E(u) / max E, so the density is E(u) / integral(E ds).
Origin sample_profiled_origin(const Scene& scene, const Curve& curve, const DiscreteDistribution& segment_choice,
                              OriginDraws& draws);
// E(u) / integral(E ds) at the curve parameter u.
double profiled_origin_pdf(const Curve& curve, double u);

// Reconstructed origins: coefficient k of `storage` was chosen by its power b_k integral(phi_k ds),
// so its photons leave with density phi_k(u) |C'(u)| du / integral(phi_k ds), i.e. phi_k per unit
// arc length: u from phi_k in the curve parameter (BasisSampler), accepted with |C'(u)| over the
// speed bound of phi_k's support.
Origin sample_coefficient_origin(const Scene& scene, const Curve& curve, const CurveStorage& storage, std::size_t k,
                                 std::span<const Vec2> line_tangents, OriginDraws& draws);
// phi_k(u) / integral(phi_k ds) at the curve parameter u.
double coefficient_origin_pdf(const CurveStorage& storage, std::size_t k, double u);

// A Hermite reconstruction lives in arc length already: s by inversion, no Jacobian.
Origin sample_hermite_origin(const Scene& scene, const Curve& curve, const HermiteReconstruction& density,
                             OriginDraws& draws);
// The reconstruction's own density at arc length s.
double hermite_origin_pdf(const HermiteReconstruction& density, double s);

}  // namespace flatland
