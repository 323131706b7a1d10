// A final gather of a Monte Carlo solution (docs/method.md, "Final gather"): its radiosity taken
// one deterministic bounce further. At a point x of a reflecting side,
//
//   B_g(x) = E(x) + rho(x) sum_j F(x -> j) b_j,
//
// the sum over every element side j that x sees: the reference's elements (chords of length at
// most h) and its exact angular sweep, and one reflection in a flat mirror, with b_j the
// solution's B at element j's arc-length midpoint (E_j where the side has no storage). It is the
// reference's own final gather (reference.hpp, step 5) fed the solution's element values instead
// of its own, so fed the reference's it returns the reference.
//
// Why it helps: the solution's noise at x becomes a weighted mean of its noise over all that x
// sees, so independent element errors average out; the direct light from emitters (E_j exact)
// carries no noise at all. What it costs: one sweep per output point, O(n log n) in the n
// elements, on every thread; the weights of the last point set are kept for the next evaluation
// of the same points (the error estimate evaluates each replicate and storage level there).
//
// Scenes the reference cannot solve (glass, curved or rough mirrors, facing mirrors, detectors,
// non-diffuse emitters) are refused with the reference's message: their light does not travel by
// one diffuse bounce and a flat mirror.
#pragma once

#include <atomic>
#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "flatland/base/status.hpp"
#include "flatland/reference/reference.hpp"
#include "flatland/results/sampled_result.hpp"
#include "flatland/transport/error_estimate.hpp"
#include "flatland/transport/solver.hpp"

namespace flatland {

struct GatherSettings {
  double max_element_length = 0.0;  // h; 0: scene.scale / 400, the reference's
  unsigned threads = 0;             // 0: every core
  // Set to stop a gather: evaluate() then returns early with what it has, and cancelled() is true.
  const std::atomic<bool>* cancel = nullptr;
  // Refusals say only why (for --gather auto, which then gathers nothing); otherwise they end
  // with what to do instead.
  bool automatic = false;
};

class FinalGather final : public ReflectedEvaluator {
 public:
  // The gather's elements at h and at 2h (for its own error); refuses what the reference refuses
  // (its messages).
  static Result<FinalGather> create(const Scene& scene, const GatherSettings& settings);

  // B - E gathered from each field at the points: values[f][p * channels + ch].
  std::vector<std::vector<double>> evaluate(const Solver& solver, std::span<const FieldPoint> points,
                                            std::span<const ReflectedField> fields) const override;
  // The gather's own discretisation error at the points: the field gathered over elements of
  // length h less the same over elements of 2h. Its error is O(h^2) (constant elements, chords),
  // so the difference is about 3 times the error at h: a conservative estimate.
  std::vector<double> own_error(const Solver& solver, std::span<const FieldPoint> points,
                                const ReflectedField& field) const override;

  // The solver's result (sample_solver) with every sample's B gathered, and the estimated error
  // of the gathered answer (estimate_error through this evaluator, at the same samples).
  SampledResult gather_result(const Solver& solver, int samples_per_curve) const;

  std::size_t elements() const { return fine_.geometry.elements(); }
  double max_element_length() const { return max_element_length_; }
  // Seconds spent finding what the points see (the sweeps), over all evaluations.
  double sweep_seconds() const { return sweep_seconds_; }
  bool cancelled() const { return settings_.cancel != nullptr && settings_.cancel->load(std::memory_order_relaxed); }

 private:
  // One set of elements and the weights of the last points gathered over it, in compressed rows:
  // point p's (patch, F) at [begin[p], begin[p + 1]) (a cache: evaluate() is not called from two
  // threads at once).
  struct Grid {
    ReferenceSolution geometry;
    mutable std::vector<FieldPoint> points;
    mutable std::vector<std::size_t> begin;
    mutable std::vector<std::uint32_t> patch;
    mutable std::vector<double> weight;
  };
  FinalGather(ReferenceSolution fine, ReferenceSolution coarse, const GatherSettings& settings, double h)
      : fine_{std::move(fine), {}, {}, {}, {}},
        coarse_{std::move(coarse), {}, {}, {}, {}},
        settings_(settings),
        max_element_length_(h) {}
  // Computes (or keeps) the weights of `points` over the grid's elements.
  void prepare(const Grid& grid, std::span<const FieldPoint> points) const;
  // B - E gathered over the grid from each field at its prepared points.
  std::vector<std::vector<double>> gather(const Grid& grid, const Solver& solver, std::span<const FieldPoint> points,
                                          std::span<const ReflectedField> fields) const;

  Grid fine_;
  Grid coarse_;
  GatherSettings settings_;
  double max_element_length_ = 0.0;
  mutable double sweep_seconds_ = 0.0;
};

// The work --gather auto allows at once: pairs of (sample side, element) the sweeps visit over the
// elements of h and of 2h. A sweep visits each element about once (and sorts them), about 40 ns a
// pair on the machine of docs/performance.md, so this is about two seconds on two cores.
inline constexpr double kAutoGatherWork = 5e7;

// What a front end gathers with under `settings.gather` at `samples` per curve: the gather, or none
// and why not (auto on a scene the gather refuses or that would cost more than kAutoGatherWork;
// empty with GatherMode::None). --gather samples on a scene the gather refuses is an error (its
// message names the curves and ends with what to do).
struct GatherChoice {
  std::unique_ptr<FinalGather> gather;
  std::string skipped;
};
Result<GatherChoice> choose_gather(const Scene& scene, const SolverSettings& settings, int samples,
                                   const std::atomic<bool>* cancel = nullptr);

}  // namespace flatland
