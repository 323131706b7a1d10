#include "flatland/reference/coarse_answer.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "flatland/base/quadrature.hpp"

namespace flatland {

namespace {

class ReferenceAnswer final : public CoarseAnswer {
 public:
  explicit ReferenceAnswer(ReferenceSolution solution) : solution_(std::move(solution)) {}

  std::size_t elements() const override { return solution_.elements(); }
  std::vector<double> element_parameters(std::uint32_t segment) const override {
    return solution_.element_parameters(segment);
  }
  std::uint32_t first_element(std::uint32_t segment) const override { return solution_.first_element(segment); }
  Spectrum element_radiosity(std::uint32_t element, Side side) const override {
    return solution_.element_radiosity(element, side);
  }
  Spectrum irradiance(std::uint32_t curve, Side side, double u) const override {
    // The reference's final gather without E and rho: sum over what the point sees of F b.
    thread_local std::vector<std::pair<std::uint32_t, double>> seen;
    solution_.gather_weights(curve, side, u, seen);
    Spectrum gathered{};
    const auto channels = static_cast<std::size_t>(solution_.scene().channels);
    for (const auto& [patch, f] : seen) {
      const Spectrum b = solution_.element_radiosity(patch / 2, static_cast<Side>(patch % 2));
      for (std::size_t ch = 0; ch < channels; ++ch) gathered[ch] += f * b[ch];
    }
    return gathered;
  }
  std::array<double, 3> escaped() const override;
  double seconds() const override { return solution_.form_factor_seconds() + solution_.solve_seconds(); }

 private:
  ReferenceSolution solution_;
};

std::array<double, 3> ReferenceAnswer::escaped() const {
  // Per patch b L (1 - its row sum of F); a patch that reflects nothing has no row, and its row sum
  // is what its points see, by an 8-point rule along it. A row sum above 1 is the form factors'
  // quadrature error: nothing escapes there.
  const std::vector<ReferenceElement>& elements = solution_.element_list();
  const auto channels = static_cast<std::size_t>(solution_.scene().channels);
  std::array<double, 3> escaped{};
  for (std::uint32_t e = 0; e < elements.size(); ++e) {
    const ReferenceElement& element = elements[e];
    for (Side side : {Side::Front, Side::Back}) {
      const Spectrum b = solution_.element_radiosity(e, side);
      double power = 0.0;
      for (std::size_t ch = 0; ch < channels; ++ch) power += std::fabs(b[ch]);
      if (!(power > 0.0)) continue;
      double row = solution_.row_sum(e, side);
      if (row < 0.0) {
        row = 0.0;
        const Vec2 normal = side == Side::Front ? element.normal : -element.normal;
        for (std::size_t g = 0; g < gauss::kNodes8.size(); ++g) {
          const Vec2 x = element.a + (0.5 + 0.5 * gauss::kNodes8[g]) * (element.b - element.a);
          double seen = 0.0;
          for (const VisibleElement& v : visible_elements(elements, x, normal, e)) seen += v.form_factor;
          row += 0.5 * gauss::kWeights8[g] * seen;
        }
      }
      const double leaves = std::max(0.0, 1.0 - row);
      for (std::size_t ch = 0; ch < channels; ++ch) escaped[ch] += b[ch] * element.length * leaves;
    }
  }
  return escaped;
}

}  // namespace

ReferenceSettings coarse_reference_settings(const Scene& scene, unsigned threads, const std::atomic<bool>* cancel) {
  ReferenceSettings settings;
  settings.max_element_length = kControlVariateFraction * scene.scale;
  settings.threads = threads;
  settings.cancel = cancel;
  return settings;
}

Result<std::shared_ptr<const CoarseAnswer>> solve_coarse_answer(const Scene& scene, unsigned threads,
                                                                const std::atomic<bool>* cancel) {
  if (Status status = check_control_variate(scene); !status) return status.error();
  const ReferenceSettings settings = coarse_reference_settings(scene, threads, cancel);
  const double elements = reference_element_count(scene, settings);
  if (elements > static_cast<double>(kControlVariateMaxElements)) {
    char count[64];
    std::snprintf(count, sizeof count, "%.3g", elements);
    return Error{scene.source + ": control variate: coarse would solve a reference of " + count +
                 " elements (at least one a segment, none longer than a 50th of the scene's size), more than " +
                 std::to_string(kControlVariateMaxElements) +
                 ", whose form factors would take longer than the photons; solve it without the control variate"};
  }
  Result<ReferenceSolution> solution = solve_reference(scene, settings);
  if (!solution) {
    if (solution.error().message == kReferenceCancelled) return Error{kSolverCancelled};
    return Error{scene.source + ": control variate: the coarse reference solve failed: " + solution.error().message};
  }
  return std::shared_ptr<const CoarseAnswer>(std::make_shared<ReferenceAnswer>(std::move(*solution)));
}

Result<Solver> create_solver(const Scene& scene, const SolverSettings& settings, const std::atomic<bool>* cancel) {
  if (settings.control_variate == ControlVariate::None) return Solver::create(scene, settings, cancel);
  // Settings and scene first, as Solver::create checks them, before the coarse solve's work.
  if (Status status = Solver::check_settings_on(scene, settings); !status) return status.error();
  const unsigned threads = settings.threads != 0 ? settings.threads : std::max(1u, std::thread::hardware_concurrency());
  Result<std::shared_ptr<const CoarseAnswer>> coarse = solve_coarse_answer(scene, threads, cancel);
  if (!coarse) return coarse.error();
  return Solver::create(scene, settings, cancel, std::move(*coarse));
}

}  // namespace flatland
