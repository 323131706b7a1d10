// An upper bound, at a stated confidence, of the error of a solver's reflected radiosity B - E,
// from the solve itself (docs/estimated-error.md):
// - noise: every round's photons are split into R independent replicates (settings.hpp), each of
//   which estimates B - E on its own; the spread of the R estimates gives the covariance of their
//   mean, and the quantile of each norm of a Gaussian error with that covariance (drawn as Gaussian
//   combinations of the replicates' deviations, scaled from the normal to Student's t with R - 1
//   degrees of freedom) bounds the noise;
// - storage: with automatic storage, the difference between each curve's chosen level and the next
//   coarser one, scaled by Richardson's factor for the estimator's order, less its own noise;
// - unshot: the light still in the pool, which at most rho_max U / (1 - rho_max) more of B - E
//   would carry, spread like B - E;
// - with an evaluator (a final gather), its own discretisation error as it estimates it.
// The bound is their sum, relative to the estimate's norm less the bound (so that it also bounds
// the error relative to the true norm).
#pragma once

#include <array>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "flatland/scene/scene.hpp"

namespace flatland {

class Solver;
struct ReflectedField;

// A point where B - E is evaluated: curve, side and curve parameter.
struct FieldPoint {
  std::uint32_t curve = 0;
  Side side = Side::Front;
  double u = 0.0;
};

// B - E at points as something other than the storage's own spline gives it: a final gather of
// the stored solution (reference/final_gather.hpp). The error estimate evaluates every field it
// compares (each replicate's, each storage level's) through it, so that its bound is the bound of
// what the evaluator reports. It is linear in the field.
class ReflectedEvaluator {
 public:
  virtual ~ReflectedEvaluator() = default;
  // B - E of each field at the points: values[f][p * channels + ch].
  virtual std::vector<std::vector<double>> evaluate(const Solver& solver, std::span<const FieldPoint> points,
                                                    std::span<const ReflectedField> fields) const = 0;
  // An estimate of its own discretisation error at the points when it evaluates `field` (signed,
  // [p * channels + ch]), or empty where it has none.
  virtual std::vector<double> own_error(const Solver&, std::span<const FieldPoint>, const ReflectedField&) const {
    return {};
  }
};

// Relative errors of B - E along arc length, as a comparison with a reference measures them
// (results/metrics.hpp, Measure::Reflected): L1, L2 and L-infinity over every side and channel.
struct RelativeErrors {
  double l1 = 0.0;
  double l2 = 0.0;
  double linf = 0.0;
};

struct ErrorEstimateOptions {
  double confidence = 0.95;     // of the bound, in [kMinConfidence, kMaxConfidence]
  int samples_per_curve = 100;  // where B - E is evaluated: midpoints of equal arc-length cells
  // How B - E is evaluated there: null for the storage's splines.
  const ReflectedEvaluator* evaluator = nullptr;
};
inline constexpr double kMinConfidence = 0.5;
inline constexpr double kMaxConfidence = 0.999;

struct CurveErrorEstimate {
  std::string id;
  RelativeErrors bound;
  bool measured = true;  // false where the curve reflects no light: its relative error is undefined
  bool bounded = true;   // false where the estimated error is as large as the curve's B - E itself
};

struct ErrorEstimate {
  // False when the solve has no replicates to compare (one replicate) or has shot nothing;
  // `unavailable` then says why.
  bool available = false;
  std::string unavailable;
  double confidence = 0.95;
  int replicates = 0;
  // The bound over the scene; infinite (bounded false) where the error may be as large as B - E.
  RelativeErrors bound;
  bool bounded = true;
  // Its parts, each relative to the estimate's own B - E norm.
  RelativeErrors noise;
  RelativeErrors storage;
  RelativeErrors unshot;
  // The evaluator's own discretisation error (a final gather's elements); zero without one.
  RelativeErrors gather;
  // False on a fixed mesh (no coarser level to compare with): the mesh's discretisation error is
  // then not in the bound, and `caveat` says so.
  bool storage_estimated = false;
  // What the bound leaves out, in words; empty when nothing is.
  std::string caveat;
  std::vector<CurveErrorEstimate> curves;
};

// Where estimate_error evaluates B - E with `samples_per_curve`: per curve, the midpoints of equal
// arc-length cells, each side with storage (front before back), in this order.
std::vector<FieldPoint> estimate_points(const Solver& solver, int samples_per_curve);

// The solver's error estimate; the same bits on any thread and process count (it reads only the
// solver's deterministic state and draws its Gaussian combinations from a stream named by the seed).
ErrorEstimate estimate_error(const Solver& solver, const ErrorEstimateOptions& options = {});

// The bound along the curves, for a plot: at curve c's parameters `parameters[c]`, per side (empty
// for a side without storage), the half-width t_(R-1) x (standard error of the replicates' mean)
// plus the storage and unshot parts there, averaged over the channels as a plot of B shows them.
// Empty lists when the solve has no estimate (one replicate, nothing shot).
std::vector<std::array<std::vector<double>, 2>> pointwise_bound(const Solver& solver,
                                                                const std::vector<std::vector<double>>& parameters,
                                                                double confidence);

}  // namespace flatland
