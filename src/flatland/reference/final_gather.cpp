#include "flatland/reference/final_gather.hpp"

#include <chrono>
#include <cstdio>
#include <thread>

#include "flatland/base/workers.hpp"

namespace flatland {

Result<FinalGather> FinalGather::create(const Scene& scene, const GatherSettings& settings) {
  const double h = settings.max_element_length > 0.0 ? settings.max_element_length : scene.scale / 400.0;
  ReferenceSettings elements;
  elements.max_element_length = h;
  elements.threads = settings.threads;
  elements.cancel = settings.cancel;
  const std::string subject = "a final gather";
  const std::string advice = settings.automatic ? "" : "use --gather none (the storage's own B)";
  Result<ReferenceSolution> fine = reference_elements(scene, elements, subject, advice);
  if (!fine) return fine.error();
  elements.max_element_length = 2.0 * h;
  Result<ReferenceSolution> coarse = reference_elements(scene, elements, subject, advice);
  if (!coarse) return coarse.error();
  return FinalGather(std::move(*fine), std::move(*coarse), settings, h);
}

void FinalGather::prepare(const Grid& grid, std::span<const FieldPoint> points) const {
  const bool same =
      points.size() == grid.points.size() &&
      std::equal(points.begin(), points.end(), grid.points.begin(), [](const FieldPoint& a, const FieldPoint& b) {
        return a.curve == b.curve && a.side == b.side && a.u == b.u;
      });
  if (same) return;
  const auto start = std::chrono::steady_clock::now();
  // Every point's sweep on its own (the weights do not depend on the thread that finds them).
  std::vector<std::vector<std::pair<std::uint32_t, double>>> seen(points.size());
  const unsigned hardware = std::max(1u, std::thread::hardware_concurrency());
  WorkerPool pool(settings_.threads == 0 ? hardware : settings_.threads);
  pool.for_each(points.size(), [&](std::size_t p) {
    if (cancelled()) return;
    grid.geometry.gather_weights(points[p].curve, points[p].side, points[p].u, seen[p]);
  });
  grid.points.assign(points.begin(), points.end());
  grid.begin.assign(1, 0);
  grid.patch.clear();
  grid.weight.clear();
  for (const auto& list : seen) {
    for (const auto& [patch, f] : list) {
      grid.patch.push_back(patch);
      grid.weight.push_back(f);
    }
    grid.begin.push_back(grid.patch.size());
  }
  if (cancelled()) grid.points.clear();  // incomplete: never reused
  sweep_seconds_ += std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

std::vector<std::vector<double>> FinalGather::gather(const Grid& grid, const Solver& solver,
                                                     std::span<const FieldPoint> points,
                                                     std::span<const ReflectedField> fields) const {
  const Scene& scene = solver.scene();
  const auto channels = static_cast<std::size_t>(scene.channels);
  prepare(grid, points);
  std::vector<std::vector<double>> values(fields.size(), std::vector<double>(points.size() * channels, 0.0));
  if (cancelled()) return values;
  const std::vector<ReferenceElement>& elements = grid.geometry.element_list();
  std::array<std::vector<double>, 3> b;
  for (std::size_t ch = 0; ch < channels; ++ch) b[ch].assign(2 * elements.size(), 0.0);
  for (std::size_t f = 0; f < fields.size(); ++f) {
    // b_j = E_j + the field's B - E at element j's arc-length midpoint, per patch 2 j + side.
    for (std::size_t j = 0; j < elements.size(); ++j) {
      const ReferenceElement& e = elements[j];
      for (const Side side : {Side::Front, Side::Back}) {
        const auto sd = static_cast<std::size_t>(side);
        Spectrum reflected{};
        if (solver.has_side(e.curve, side)) reflected = solver.reflected_at(fields[f], e.curve, side, e.u_mid);
        for (std::size_t ch = 0; ch < channels; ++ch) b[ch][2 * j + sd] = e.emittance[sd][ch] + reflected[ch];
      }
    }
    for (std::size_t p = 0; p < points.size(); ++p) {
      const Spectrum& rho = scene.material_of(scene.curves[points[p].curve]).reflectivity;
      for (std::size_t ch = 0; ch < channels; ++ch) {
        double gathered = 0.0;
        for (std::size_t k = grid.begin[p]; k < grid.begin[p + 1]; ++k)
          gathered += grid.weight[k] * b[ch][grid.patch[k]];
        values[f][p * channels + ch] = rho[ch] * gathered;
      }
    }
  }
  return values;
}

std::vector<std::vector<double>> FinalGather::evaluate(const Solver& solver, std::span<const FieldPoint> points,
                                                       std::span<const ReflectedField> fields) const {
  return gather(fine_, solver, points, fields);
}

std::vector<double> FinalGather::own_error(const Solver& solver, std::span<const FieldPoint> points,
                                           const ReflectedField& field) const {
  const std::span<const ReflectedField> one(&field, 1);
  std::vector<double> fine = gather(fine_, solver, points, one)[0];
  const std::vector<double> coarse = gather(coarse_, solver, points, one)[0];
  for (std::size_t i = 0; i < fine.size(); ++i) fine[i] -= coarse[i];
  return fine;
}

SampledResult FinalGather::gather_result(const Solver& solver, int samples_per_curve) const {
  const Scene& scene = solver.scene();
  const auto channels = static_cast<std::size_t>(scene.channels);
  ErrorEstimateOptions options;
  options.confidence = solver.settings().confidence;
  options.samples_per_curve = samples_per_curve;
  options.evaluator = this;
  const ErrorEstimate estimate = estimate_error(solver, options);
  SampledResult result = sample_solver(solver, samples_per_curve, &estimate);
  result.final_gather = max_element_length_;
  // The estimate's points, which are the result's samples (so their weights are reused).
  const std::vector<FieldPoint> points = estimate_points(solver, samples_per_curve);
  const std::vector<ReflectedField> field{solver.reflected_field(solver.received(), solver.chosen_levels())};
  const std::vector<double> gathered = evaluate(solver, points, field)[0];
  std::size_t p = 0;
  for (std::uint32_t c = 0; c < scene.curves.size(); ++c) {
    const Curve& curve = scene.curves[c];
    const Side main = curve.sides == Sides::Back ? Side::Back : Side::Front;
    for (ResultSample& sample : result.curves[c].samples) {
      for (const Side side : {Side::Front, Side::Back}) {
        if (!solver.has_side(c, side)) continue;
        Spectrum value = sample.E ? *sample.E : Spectrum{};
        for (std::size_t ch = 0; ch < channels; ++ch) value[ch] += gathered[p * channels + ch];
        ++p;
        if (side == main)
          sample.B = value;
        else if (sample.B_back)
          *sample.B_back = value;
      }
    }
  }
  return result;
}

Result<GatherChoice> choose_gather(const Scene& scene, const SolverSettings& settings, int samples,
                                   const std::atomic<bool>* cancel) {
  GatherChoice choice;
  if (settings.gather == GatherMode::None) return choice;
  const bool automatic = settings.gather == GatherMode::Auto;
  Result<FinalGather> made = FinalGather::create(scene, {0.0, settings.threads, cancel, automatic});
  if (!made) {
    if (!automatic || (cancel != nullptr && cancel->load())) return made.error();
    choice.skipped = made.error().message;
    return choice;
  }
  // The sides a sample is gathered on: those that reflect (the storage's sides).
  double sides = 0.0;
  for (const Curve& curve : scene.curves) {
    const Spectrum& rho = scene.material_of(curve).reflectivity;
    if (!(rho[0] + rho[1] + rho[2] > 0.0) || scene.material_of(curve).optics != Optics::Diffuse) continue;
    sides += curve.sides == Sides::Both ? 2.0 : 1.0;
  }
  const double work = static_cast<double>(samples) * sides * 1.5 * static_cast<double>(made->elements());
  if (automatic && work > kAutoGatherWork) {
    char text[256];
    std::snprintf(text, sizeof text,
                  "%.3g sample sides x %zu elements is more than --gather auto sweeps (%.3g pairs); --gather samples "
                  "gathers all the same",
                  static_cast<double>(samples) * sides, made->elements(), kAutoGatherWork);
    choice.skipped = text;
    return choice;
  }
  choice.gather = std::make_unique<FinalGather>(std::move(*made));
  return choice;
}

}  // namespace flatland
