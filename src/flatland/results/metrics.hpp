// Errors of one result against another (usually a reference), along arc length: relative L1, L2
// and L-infinity of B, or of its reflected part B - E, per curve and for the whole scene
// (docs/result-format.md for the inputs); and the observed slope of a power law through errors.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "flatland/base/status.hpp"

namespace flatland {

struct SampledResult;  // sampled_result.hpp

struct ErrorNorms {
  double l1 = 0.0;    // integral |B - R| ds / integral |R| ds
  double l2 = 0.0;    // sqrt(integral (B - R)^2 ds / integral R^2 ds)
  double linf = 0.0;  // max |B - R| / max |R|
};

// What a comparison measures. Every method computes the emitted radiosity E exactly, so the error
// of B = E + reflected lies in the reflected part alone; measured against B it is divided by a norm
// that the emitters inflate (8x on the penumbra scene). Reflected measures B - E against the
// reference's B - E: the error of what the solvers actually estimate.
enum class Measure { Total, Reflected };
const char* to_string(Measure measure);  // "total", "reflected"

struct CurveError {
  std::string id;
  ErrorNorms norms;
  // False when the reference's measured quantity is zero along the whole curve (under Reflected:
  // a curve that reflects no light, such as a black lamp); its norms are then NaN.
  bool measured = true;
};

struct Comparison {
  Measure measure = Measure::Total;
  std::vector<CurveError> curves;
  ErrorNorms scene;  // over every curve, side and channel together
  // sqrt(integral R^2 ds) of the reference's measured quantity R (B, or B - E) over every curve,
  // side and channel: the denominator of scene.l2. Two comparisons of one reference under two
  // measures convert a relative L2 error from one measure to the other.
  double reference_l2 = 0.0;
};

// Both results must describe the same scene: the same curves (ids, in order, lengths equal to
// 1e-9 relative) sampled at the same arc lengths, with the same channels; otherwise the error says
// what differs. Samples sit at the midpoints of equal arc-length cells, so sums weighted by the
// cell length are midpoint-rule integrals. Every side present in both (B, B_back) and every
// channel counts.
//
// Under Measure::Total a reference that is zero along a curve (or everywhere) gives that curve's
// errors relative to the largest |B| of the comparison. Under Measure::Reflected E is read from
// the samples' "E" (the reference's, else the result's; a curve whose "emittance" is zero or absent
// needs none), a reflected part below 1e-12 of B counts as zero (the round-off of B - E), a curve
// whose reference reflects nothing is marked unmeasured, and a reference that reflects nothing
// anywhere is an error: its relative error is undefined.
// The error of a comparison under Measure::Reflected whose reference reflects no light anywhere;
// a front end adds how to ask for Measure::Total in its own words.
inline constexpr const char* kNothingReflected =
    "the reference's reflected part B - E is zero everywhere (no curve reflects light), so its relative error is "
    "undefined; measure the total B instead";

Result<Comparison> compare_sampled(const SampledResult& result, const SampledResult& reference,
                                   Measure measure = Measure::Total);
// The same for two result documents (sampled_from_json reads them; "the result" and "the
// reference" name them in errors).
Result<Comparison> compare_results(const nlohmann::json& result, const nlohmann::json& reference,
                                   Measure measure = Measure::Total);

// The exponent k of the power law error = c x^k that fits the points (x_i, error_i) best in
// the least-squares sense on log-log axes: the slope of the straight line through (ln x_i,
// ln error_i). Points with x or error not positive and finite are left out; nullopt when fewer
// than two distinct x remain (no line is determined).
std::optional<double> power_law_exponent(const std::vector<double>& x, const std::vector<double>& error);

}  // namespace flatland
