#include "flatland/reference/coarse_answer.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "flatland/base/quadrature.hpp"
#include "flatland/geometry/bezier.hpp"
#include "flatland/reference/form_factors.hpp"

namespace flatland {

namespace {

// The coarse answer, and G gathered over finer chords than its own: a coarse chord stands in for its
// arc as a source and an occluder, and on a cubic segment it sits up to a sagitta (h^2 / 8r) off the
// curve, so G = K b_c would be the transport of b_c on a polygon, not on the curves the photons
// meet, and that difference is a bias no photon corrects. Each coarse element of a cubic segment is
// split into kGatherSplit chords of equal arc length (the sagitta 64 times smaller) carrying its
// b_c; a line's element is its own chord. Their ends are the coarse ends, so b_c's jumps stay where
// they are.
class ReferenceAnswer final : public CoarseAnswer {
 public:
  static constexpr int kGatherSplit = 8;

  explicit ReferenceAnswer(ReferenceSolution solution);

  std::size_t elements() const override { return solution_.elements(); }
  std::vector<double> element_parameters(std::uint32_t segment) const override {
    return solution_.element_parameters(segment);
  }
  std::uint32_t first_element(std::uint32_t segment) const override { return solution_.first_element(segment); }
  Spectrum element_radiosity(std::uint32_t element, Side side) const override {
    return solution_.element_radiosity(element, side);
  }
  Spectrum irradiance(std::uint32_t curve, Side side, double u) const override;
  Spectrum coarse_irradiance(std::uint32_t curve, Side side, double u) const override {
    // The reference's own gather over its coarse chords, without E and rho.
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
  double model_ratio() const override { return static_cast<double>(kGatherSplit * kGatherSplit); }
  double amplification() const override;
  std::array<double, 3> escaped() const override;
  double seconds() const override { return solution_.form_factor_seconds() + solution_.solve_seconds(); }

 private:
  ReferenceSolution solution_;
  std::vector<ReferenceElement> fine_;          // the gather's chords
  std::vector<std::uint32_t> parent_;           // per fine chord: its coarse element
  std::vector<std::uint32_t> fine_first_;       // per segment: its first fine chord
  std::vector<std::vector<double>> fine_ends_;  // per segment: its fine chords' ends in t
};

ReferenceAnswer::ReferenceAnswer(ReferenceSolution solution) : solution_(std::move(solution)) {
  const Scene& scene = solution_.scene();
  const std::vector<ReferenceElement>& coarse = solution_.element_list();
  fine_first_.resize(scene.segments.size());
  fine_ends_.resize(scene.segments.size());
  for (std::uint32_t si = 0; si < scene.segments.size(); ++si) {
    const SceneSegment& segment = scene.segments[si];
    const Cubic& shape = segment.geometry.shape;
    const std::vector<double> ends = solution_.element_parameters(si);
    const std::uint32_t first = solution_.first_element(si);
    const int split = segment.geometry.kind == SegmentKind::Line ? 1 : kGatherSplit;
    fine_first_[si] = static_cast<std::uint32_t>(fine_.size());
    std::vector<double>& fine_ends = fine_ends_[si];
    fine_ends.push_back(ends.front());
    for (std::size_t k = 0; k + 1 < ends.size(); ++k) {
      const std::uint32_t parent = first + static_cast<std::uint32_t>(k);
      const ReferenceElement& whole = coarse[parent];
      const double s0 = segment.arc_length.length_at(shape, ends[k]);
      const double s1 = segment.arc_length.length_at(shape, ends[k + 1]);
      Vec2 start = whole.a;  // the coarse ends exactly, so neighbours share them bit for bit
      for (int piece = 0; piece < split; ++piece) {
        const bool last = piece + 1 == split;
        const double t1 =
            last ? ends[k + 1] : segment.arc_length.parameter_at(shape, s0 + (s1 - s0) * (piece + 1) / split);
        const Vec2 end = last ? whole.b : evaluate(shape, t1);
        ReferenceElement e = whole;
        e.a = start;
        e.b = end;
        e.length = length(end - start);
        if (!(e.length > 0.0)) {
          // (A chord too short to have a direction: the coarse chord's piece is left out; it
          // hides and sends nothing measurable.)
          continue;
        }
        e.normal = (1.0 / e.length) * perp(end - start);
        e.u_mid =
            segment.index_in_curve + segment.arc_length.parameter_at(shape, s0 + (s1 - s0) * (piece + 0.5) / split);
        e.previous = kNoElement;
        e.next = kNoElement;
        fine_.push_back(e);
        parent_.push_back(parent);
        fine_ends.push_back(t1);
        start = end;
      }
    }
  }
}

Spectrum ReferenceAnswer::irradiance(std::uint32_t curve_index, Side side, double u) const {
  // The reference's final gather (reference.cpp, gather_weights) over the fine chords, without E
  // and rho: sum over what the point sees of F b_c, zero on a side that reflects nothing.
  const Scene& scene = solution_.scene();
  const Curve& curve = scene.curves[curve_index];
  Spectrum gathered{};
  if (!curve.has_side(side) || !scene.reflects_light(curve)) return gathered;
  const double clamped = std::clamp(u, 0.0, static_cast<double>(curve.segment_count));
  const auto local =
      static_cast<std::uint32_t>(std::min(std::floor(clamped), static_cast<double>(curve.segment_count) - 1.0));
  const double t = clamped - local;
  const std::uint32_t si = curve.first_segment + local;
  const std::vector<double>& ends = fine_ends_[si];
  const auto found = std::upper_bound(ends.begin(), ends.end(), t);
  const auto piece = static_cast<std::uint32_t>(
      std::clamp<std::ptrdiff_t>(found - ends.begin() - 1, 0, static_cast<std::ptrdiff_t>(ends.size()) - 2));
  const std::uint32_t self = fine_first_[si] + piece;
  const Cubic& shape = scene.segments[si].geometry.shape;
  const Vec2 x = evaluate(shape, t);
  Vec2 normal = unit_normal(shape, t, scene.scale);
  if (side == Side::Back) normal = -normal;
  thread_local reference_detail::Sweeper sweeper;
  thread_local std::vector<VisibleElement> visible;
  sweeper.run(fine_, x, normal, self, side, visible);
  const auto channels = static_cast<std::size_t>(scene.channels);
  for (const VisibleElement& v : visible) {
    const Spectrum b = solution_.element_radiosity(parent_[v.element], v.side);
    for (std::size_t ch = 0; ch < channels; ++ch) gathered[ch] += v.form_factor * b[ch];
  }
  return gathered;
}

double ReferenceAnswer::amplification() const {
  const std::vector<ReferenceElement>& elements = solution_.element_list();
  const auto channels = static_cast<std::size_t>(solution_.scene().channels);
  double answer = 0.0;
  double emitted = 0.0;
  for (std::uint32_t e = 0; e < elements.size(); ++e)
    for (Side side : {Side::Front, Side::Back}) {
      const Spectrum b = solution_.element_radiosity(e, side);
      for (std::size_t ch = 0; ch < channels; ++ch) {
        answer += std::fabs(b[ch]) * elements[e].length;
        emitted += std::fabs(elements[e].emittance[static_cast<std::size_t>(side)][ch]) * elements[e].length;
      }
    }
  return emitted > 0.0 ? std::max(1.0, answer / emitted) : 1.0;
}

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

namespace {

Status check_coarse_size(const Scene& scene, const ReferenceSettings& settings) {
  const double elements = reference_element_count(scene, settings);
  if (!(elements > static_cast<double>(kControlVariateMaxElements))) return ok_status();
  char count[64];
  std::snprintf(count, sizeof count, "%.3g", elements);
  return Error{scene.source + ": control variate: coarse would solve a reference of " + count +
               " elements (at least one a segment, none longer than a 50th of the scene's size), more than " +
               std::to_string(kControlVariateMaxElements) +
               ", whose form factors would take longer than the photons; solve it without the control variate"};
}

}  // namespace

Status check_solver_settings(const Scene& scene, const SolverSettings& settings) {
  if (Status status = Solver::check_settings_on(scene, settings); !status) return status;
  if (settings.control_variate != ControlVariate::Coarse) return ok_status();
  return check_coarse_size(scene, coarse_reference_settings(scene, 1, nullptr));
}

double control_variate_work(const Scene& scene, const SolverSettings& settings) {
  // Chords: a line's coarse elements, a cubic segment's split kGatherSplit-fold, plus the coarse
  // chords themselves where the scene has cubics (the error part's second sweep). Points: 8 on
  // every storage span, or 4 where the spans are shorter than kShortPiece of a coarse element on
  // average, their count raised by one each side by the coarse element ends (storage nodes). And
  // the coarse reference: kCoarsePairWork pairs' worth per pair of coarse elements.
  const std::vector<double> counts = reference_element_counts(scene, coarse_reference_settings(scene, 1, nullptr));
  double chords = 0.0;
  double coarse = 0.0;
  for (std::size_t s = 0; s < counts.size(); ++s) {
    chords += counts[s] * (scene.segments[s].geometry.kind == SegmentKind::Line ? 1.0 : ReferenceAnswer::kGatherSplit);
    coarse += counts[s];
  }
  if (scene.has_cubics()) chords += coarse;
  const double spans = Solver::coefficient_bound(scene, settings) + 2.0 * coarse;
  const std::size_t points = coarse < kShortPiece * spans ? gauss::kNodes4.size() : gauss::kNodes8.size();
  return spans * static_cast<double>(points) * chords + kCoarsePairWork * coarse * coarse;
}

namespace {

// A refusal of --control-variate coarse as auto's reason: without the scene's file name and the
// option's name, which the report prints beside it, and without the advice after the last "; "
// ("use ...", "solve ..."), which is to do what auto does.
std::string auto_reason(const Scene& scene, std::string message) {
  if (message.rfind(scene.source + ": ", 0) == 0) message.erase(0, scene.source.size() + 2);
  if (const std::string option = "control variate: "; message.rfind(option, 0) == 0) message.erase(0, option.size());
  if (const std::size_t advice = message.rfind("; ");
      advice != std::string::npos &&
      (message.compare(advice + 2, 4, "use ") == 0 || message.compare(advice + 2, 6, "solve ") == 0))
    message.resize(advice);
  return message;
}

}  // namespace

std::string control_variate_auto_skip(const Scene& scene, const SolverSettings& settings) {
  SolverSettings coarse = settings;
  coarse.control_variate = ControlVariate::Coarse;
  if (Status status = validate(coarse); !status) return auto_reason(scene, status.error().message);
  if (Status status = check_control_variate(scene); !status) return auto_reason(scene, status.error().message);
  const ReferenceSettings reference = coarse_reference_settings(scene, 1, nullptr);
  if (Status status = check_coarse_size(scene, reference); !status) return auto_reason(scene, status.error().message);
  const double work = control_variate_work(scene, coarse);
  const double budget =
      std::max(kAutoControlVariateWork, kAutoControlVariateWorkPerPhoton * static_cast<double>(settings.photons));
  if (work > budget) {
    char text[320];
    std::snprintf(
        text, sizeof text,
        "its projection would sweep %.3g point-chord pairs, more than auto spends (%.3g: about two "
        "seconds on two cores, or three times the photons' own); --control-variate coarse uses it all the same",
        work, budget);
    return text;
  }
  return {};
}

Result<std::shared_ptr<const CoarseAnswer>> solve_coarse_answer(const Scene& scene, unsigned threads,
                                                                const std::atomic<bool>* cancel) {
  if (Status status = check_control_variate(scene); !status) return status.error();
  const ReferenceSettings settings = coarse_reference_settings(scene, threads, cancel);
  if (Status status = check_coarse_size(scene, settings); !status) return status.error();
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
  if (settings.control_variate == ControlVariate::Auto) {
    if (std::string skipped = control_variate_auto_skip(scene, settings); !skipped.empty()) {
      Result<Solver> solver = Solver::create(scene, settings, cancel);
      if (solver) solver->set_control_variate_skipped(std::move(skipped));
      return solver;
    }
  }
  const unsigned threads = settings.threads != 0 ? settings.threads : std::max(1u, std::thread::hardware_concurrency());
  // A coarse solve that fails is an error for auto too (its memory, which depends on the machine):
  // falling back would let the processes of one MPI solve choose differently.
  Result<std::shared_ptr<const CoarseAnswer>> coarse = solve_coarse_answer(scene, threads, cancel);
  if (!coarse) return coarse.error();
  return Solver::create(scene, settings, cancel, std::move(*coarse));
}

}  // namespace flatland
