// Errors of one result against another (usually a reference), along arc length: relative L1, L2
// and L-infinity of B per curve and for the whole scene (docs/result-format.md for the inputs).
#pragma once

#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "flatland/result.hpp"

namespace flatland {

struct ErrorNorms {
  double l1 = 0.0;    // integral |B - R| ds / integral |R| ds
  double l2 = 0.0;    // sqrt(integral (B - R)^2 ds / integral R^2 ds)
  double linf = 0.0;  // max |B - R| / max |R|
};

struct CurveError {
  std::string id;
  ErrorNorms norms;
};

struct Comparison {
  std::vector<CurveError> curves;
  ErrorNorms scene;  // over every curve, side and channel together
};

// Both documents must describe the same scene: the same curves (ids, in order, lengths equal to
// 1e-9 relative) sampled at the same arc lengths, with the same channels; otherwise the error says
// what differs. Samples sit at the midpoints of equal arc-length cells, so sums weighted by the
// cell length are midpoint-rule integrals. Every side present in both (B, B_back) and every
// channel counts.
Result<Comparison> compare_results(const nlohmann::json& result, const nlohmann::json& reference);

}  // namespace flatland
