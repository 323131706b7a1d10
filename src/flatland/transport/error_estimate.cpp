#include "flatland/transport/error_estimate.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>

#include "flatland/base/portable_math.hpp"
#include "flatland/base/statistics.hpp"
#include "flatland/transport/sampling.hpp"
#include "flatland/transport/solver.hpp"

namespace flatland {

namespace {

constexpr double kInfinity = std::numeric_limits<double>::infinity();
// The Gaussian combinations drawn for the noise's quantiles: enough that the 95 % quantile of 400
// draws is within a few per cent of the distribution's, fewer on a scene of many curves (the draws
// keep every curve's norms).
constexpr int kMostDraws = 400;
constexpr int kFewestDraws = 40;
constexpr double kDrawValueBudget = 2e7;

// Where B - E is evaluated: every side that has storage, at the midpoints of K equal arc-length
// cells of its curve, each channel; point p of curve c lies in [first[c], first[c + 1]).
struct EvaluationPoints {
  struct Point {
    std::uint32_t curve;
    Side side;
    double u;
    double weight;  // the cell's length
  };
  std::vector<Point> points;
  std::vector<std::size_t> first;
  int channels = 1;
  std::size_t values() const { return points.size() * static_cast<std::size_t>(channels); }
};

// Points at given curve parameters (weights: equal shares of the curve's length).
EvaluationPoints points_at(const Solver& solver, const std::vector<std::vector<double>>& parameters) {
  const Scene& scene = solver.scene();
  EvaluationPoints result;
  result.channels = scene.channels;
  for (std::uint32_t c = 0; c < scene.curves.size(); ++c) {
    result.first.push_back(result.points.size());
    const std::vector<double>& us = c < parameters.size() ? parameters[c] : std::vector<double>{};
    for (double u : us)
      for (Side side : {Side::Front, Side::Back})
        if (solver.has_side(c, side))
          result.points.push_back({c, side, u, scene.curves[c].length / static_cast<double>(us.size())});
  }
  result.first.push_back(result.points.size());
  return result;
}

EvaluationPoints evaluation_points(const Solver& solver, int samples) {
  const Scene& scene = solver.scene();
  EvaluationPoints result;
  result.channels = scene.channels;
  for (std::uint32_t c = 0; c < scene.curves.size(); ++c) {
    result.first.push_back(result.points.size());
    const Curve& curve = scene.curves[c];
    for (int j = 0; j < samples; ++j) {
      const double s = (j + 0.5) * curve.length / samples;
      const double u = point_at_arc_length(scene, curve, s).u;
      for (Side side : {Side::Front, Side::Back})
        if (solver.has_side(c, side)) result.points.push_back({c, side, u, curve.length / samples});
    }
  }
  result.first.push_back(result.points.size());
  return result;
}

// The points as an evaluator takes them.
std::vector<FieldPoint> field_points(const EvaluationPoints& at) {
  std::vector<FieldPoint> points;
  points.reserve(at.points.size());
  for (const auto& point : at.points) points.push_back({point.curve, point.side, point.u});
  return points;
}

// B - E of a field at every point and channel: [p * channels + ch].
std::vector<double> evaluate(const Solver& solver, const ReflectedField& field, const EvaluationPoints& at) {
  const auto channels = static_cast<std::size_t>(at.channels);
  std::vector<double> values(at.values());
  for (std::size_t p = 0; p < at.points.size(); ++p) {
    const auto& point = at.points[p];
    const Spectrum value = solver.reflected_at(field, point.curve, point.side, point.u);
    for (std::size_t ch = 0; ch < channels; ++ch) values[p * channels + ch] = value[ch];
  }
  return values;
}

// Norms of a function given at the points: L1 and the square of L2 (weighted by cell length) and
// L-infinity, accumulated per curve.
struct Norms {
  double l1 = 0.0;
  double l2_squared = 0.0;
  double linf = 0.0;
  void add(double value, double weight) {
    const double magnitude = std::fabs(value);
    l1 += weight * magnitude;
    l2_squared += weight * value * value;
    linf = std::max(linf, magnitude);
  }
  void add(const Norms& other) {
    l1 += other.l1;
    l2_squared += other.l2_squared;
    linf = std::max(linf, other.linf);
  }
  RelativeErrors absolute() const { return {l1, std::sqrt(l2_squared), linf}; }
};

// Per curve (and, last, over the scene) norms of `values`.
std::vector<Norms> norms_of(const std::vector<double>& values, const EvaluationPoints& at) {
  const auto channels = static_cast<std::size_t>(at.channels);
  const std::size_t curves = at.first.size() - 1;
  std::vector<Norms> norms(curves + 1);
  for (std::size_t c = 0; c < curves; ++c) {
    for (std::size_t p = at.first[c]; p < at.first[c + 1]; ++p)
      for (std::size_t ch = 0; ch < channels; ++ch) norms[c].add(values[p * channels + ch], at.points[p].weight);
    norms[curves].add(norms[c]);
  }
  return norms;
}

// The order q of the storage's discretisation error, error ~ h^q: the lumped estimator's is set by
// the ends and nodes (O(h)); Galerkin and local estimates of degree-p splines have O(h^(p+1));
// Hermite storage interpolates with slopes from three nodes (exact for quadratics, O(h^3)) its
// nodal values, which the local estimator makes exact for cubics and Galerkin's hat projection to
// O(h^2).
int storage_order(const SolverSettings& settings) {
  if (settings.estimator == Estimator::Lumped) return 1;
  if (settings.basis == BasisKind::Hermite) return settings.estimator == Estimator::Local ? 3 : 2;
  return degree_of(settings.basis) + 1;
}

std::string percent(double fraction) {
  char text[32];
  std::snprintf(text, sizeof text, "%.3g %%", 100.0 * fraction);
  return text;
}

// B - E at the points: the replicates' mean (the solver's own answer, up to rounding), each
// replicate's deviation from it, and the storage part's estimated error there (zero on a fixed
// mesh).
struct PointValues {
  std::vector<double> mean;
  std::vector<std::vector<double>> deviation;
  std::vector<double> bias;
  int unestimated = 0;  // curves with storage whose storage part could not be estimated
};

// B - E of every replicate at the points with each curve c at level levels[c], as deviations from
// their mean, and the mean.
struct LevelValues {
  std::vector<double> mean;
  std::vector<std::vector<double>> deviation;
};

LevelValues level_values(const Solver& solver, const EvaluationPoints& at, const std::vector<int>& levels,
                         const ReflectedEvaluator* evaluator, double shrink = 1.0) {
  const auto count = static_cast<std::size_t>(solver.replicates());
  LevelValues result;
  result.mean.assign(at.values(), 0.0);
  if (evaluator != nullptr) {
    std::vector<ReflectedField> fields;
    for (std::size_t r = 0; r < count; ++r)
      fields.push_back(solver.reflected_field(solver.replicate_received(static_cast<int>(r)), levels));
    const std::vector<FieldPoint> points = field_points(at);
    result.deviation = evaluator->evaluate(solver, points, fields);
  } else {
    result.deviation.resize(count);
    for (std::size_t r = 0; r < count; ++r)
      result.deviation[r] =
          evaluate(solver, solver.reflected_field(solver.replicate_received(static_cast<int>(r)), levels), at);
  }
  for (std::size_t r = 0; r < count; ++r)
    for (std::size_t i = 0; i < at.values(); ++i) result.mean[i] += result.deviation[r][i] / static_cast<double>(count);
  for (std::vector<double>& deviation : result.deviation)
    for (std::size_t i = 0; i < at.values(); ++i) deviation[i] = shrink * (deviation[i] - result.mean[i]);
  return result;
}

// Per curve, the squared L2 norm of the difference of two fields' means less its noise (the
// energy of the replicates' differences about it, over R (R - 1)): an estimate of the squared norm
// of the difference of their expectations, at least 0.
std::vector<double> difference_energy(const LevelValues& x, const LevelValues& y, const EvaluationPoints& at) {
  const std::size_t curves = at.first.size() - 1;
  const auto channels = static_cast<std::size_t>(at.channels);
  const auto count = static_cast<double>(x.deviation.size());
  std::vector<double> energy(curves, 0.0);
  for (std::size_t c = 0; c < curves; ++c) {
    double signal = 0.0;
    double noise = 0.0;
    for (std::size_t p = at.first[c]; p < at.first[c + 1]; ++p)
      for (std::size_t ch = 0; ch < channels; ++ch) {
        const std::size_t i = p * channels + ch;
        const double d = x.mean[i] - y.mean[i];
        signal += at.points[p].weight * d * d;
        for (std::size_t r = 0; r < x.deviation.size(); ++r) {
          const double e = x.deviation[r][i] - y.deviation[r][i];
          noise += at.points[p].weight * e * e / (count * (count - 1.0));
        }
      }
    energy[c] = std::max(signal - noise, 0.0);
  }
  return energy;
}

// The storage part: per point, the estimated discretisation error of B - E at each curve's chosen
// level l, with error ~ C h^q'. Against the nearest coarser level j whose mesh differs from l's
// (SceneStorage::distinct_level; k = l's elements over j's): B_l - B_j = (k^q' - 1) e_l; at the
// coarsest distinct mesh, against the nearest finer distinct level m (k = m's elements over l's):
// B_m - B_l = (k^-q' - 1) e_l. q' is the order the curve shows: the estimator's order q holds
// only where B is smooth at the scale of the elements, and a curve whose kinks the mesh has no node
// for (shadow edges of many occluders) converges at order 1 or less. From a second distinct level
// beyond the pair (j2 below j, or m2 above m), the ratio of the coarser step's difference to the
// finer step's is about k^q' (with the two steps' ratios k_c, k_f: k_f^q' (k_c^q' - 1) /
// (k_f^q' - 1)); q' is the largest whole order from 1 to q that the ratio reaches (so rounded
// down: conservative), and q where no second level exists. Each difference's noise is taken off
// its energy (difference_energy); the per-point difference is scaled by its curve's share of
// signal in it. `unestimated` counts the curves with storage but a single distinct mesh (no
// difference to measure: their part is 0).
std::vector<double> storage_bias(const Solver& solver, const EvaluationPoints& at, const LevelValues& chosen,
                                 const ReflectedEvaluator* evaluator, int& unestimated, double shrink) {
  const SceneStorage& storage = solver.scene_storage();
  const std::vector<int>& levels = solver.chosen_levels();
  const std::size_t curves = at.first.size() - 1;
  const auto channels = static_cast<std::size_t>(at.channels);
  const int order = storage_order(solver.settings());
  // Per curve, the distinct level the chosen one is compared with (`other`, element ratio k_near)
  // and, where one exists (`has_further`), a second distinct level one step further from the
  // chosen level (`further`, ratio k_far) for the observed order; `upward` where they are finer.
  std::vector<int> other(levels), further(levels);
  std::vector<char> has_further(curves, 0);
  std::vector<double> k_near(curves, 0.0), k_far(curves, 0.0);
  std::vector<char> upward(curves, 0), estimated(curves, 0);
  unestimated = 0;
  for (std::uint32_t c = 0; c < curves; ++c) {
    const int l = levels[c];
    const auto elements = [&](int level) { return static_cast<double>(storage.level_elements(c, level)); };
    if (const int j = storage.distinct_level(c, l, -1); j >= 0) {
      other[c] = j;
      k_near[c] = elements(l) / elements(j);
      if (const int j2 = storage.distinct_level(c, j, -1); j2 >= 0) {
        further[c] = j2;
        has_further[c] = 1;
        k_far[c] = elements(j) / elements(j2);
      }
      estimated[c] = 1;
    } else if (const int m = storage.distinct_level(c, l, +1); m >= 0) {
      other[c] = m;
      upward[c] = 1;
      k_near[c] = elements(m) / elements(l);
      if (const int m2 = storage.distinct_level(c, m, +1); m2 >= 0) {
        further[c] = m2;
        has_further[c] = 1;
        k_far[c] = elements(m2) / elements(m);
      }
      estimated[c] = 1;
    } else if (solver.has_side(c, Side::Front) || solver.has_side(c, Side::Back)) {
      ++unestimated;
    }
  }
  const LevelValues other_values = level_values(solver, at, other, evaluator, shrink);
  const std::vector<double> near_energy = difference_energy(chosen, other_values, at);
  std::vector<double> far_energy(curves, 0.0);
  if (std::find(has_further.begin(), has_further.end(), 1) != has_further.end())
    far_energy = difference_energy(other_values, level_values(solver, at, further, evaluator, shrink), at);
  std::vector<double> bias(at.values(), 0.0);
  for (std::uint32_t c = 0; c < curves; ++c) {
    if (!estimated[c] || !(near_energy[c] > 0.0)) continue;
    int observed = order;
    if (has_further[c]) {
      // The coarser step's difference over the finer step's.
      const double ratio = upward[c] ? std::sqrt(near_energy[c] / std::max(far_energy[c], 1e-300))
                                     : std::sqrt(far_energy[c] / near_energy[c]);
      const double k_fine = upward[c] ? k_far[c] : k_near[c];
      const double k_coarse = upward[c] ? k_near[c] : k_far[c];
      observed = 1;
      for (int q = 2; q <= order; ++q) {
        const double expected = portable::integer_power(k_fine, q) * (portable::integer_power(k_coarse, q) - 1.0) /
                                (portable::integer_power(k_fine, q) - 1.0);
        if (ratio >= expected) observed = q;
      }
    }
    const double kq = portable::integer_power(k_near[c], observed);
    const double factor = upward[c] ? kq / (kq - 1.0) : 1.0 / (kq - 1.0);
    // The mean difference holds noise too: scale it to the share of its energy that is signal.
    double energy = 0.0;
    for (std::size_t p = at.first[c]; p < at.first[c + 1]; ++p)
      for (std::size_t ch = 0; ch < channels; ++ch) {
        const double d = chosen.mean[p * channels + ch] - other_values.mean[p * channels + ch];
        energy += at.points[p].weight * d * d;
      }
    const double kept = energy > 0.0 ? std::sqrt(std::min(1.0, near_energy[c] / energy)) : 0.0;
    for (std::size_t p = at.first[c]; p < at.first[c + 1]; ++p)
      for (std::size_t ch = 0; ch < channels; ++ch) {
        const std::size_t i = p * channels + ch;
        bias[i] = factor * kept * (chosen.mean[i] - other_values.mean[i]);
      }
  }
  return bias;
}

// The factor on the replicates' deviations for the blocks' stratification (settings.hpp,
// stratification_factor): its square root, from the blocks' and the pairs' deviations pooled over
// the scene's points (arc-length weights); 1 where the replicates are not stratified.
double stratification_shrink(const Solver& solver, const LevelValues& values, const EvaluationPoints& at) {
  const std::size_t count = values.deviation.size();
  if (!replicates_stratified(solver.settings())) return 1.0;
  const auto channels = static_cast<std::size_t>(at.channels);
  double blocks = 0.0;
  double pairs = 0.0;
  for (std::size_t p = 0; p < at.points.size(); ++p)
    for (std::size_t ch = 0; ch < channels; ++ch) {
      const std::size_t i = p * channels + ch;
      const double w = at.points[p].weight;
      for (std::size_t r = 0; r < count; ++r) blocks += w * values.deviation[r][i] * values.deviation[r][i];
      for (std::size_t j = 0; j + 1 < count; j += 2) {
        const double q = 0.5 * (values.deviation[j][i] + values.deviation[j + 1][i]);
        pairs += w * q * q;
      }
    }
  return std::sqrt(stratification_factor(blocks, pairs, static_cast<int>(count)));
}

PointValues values_at(const Solver& solver, const EvaluationPoints& at, const ReflectedEvaluator* evaluator) {
  PointValues result;
  LevelValues chosen = level_values(solver, at, solver.chosen_levels(), evaluator);
  const double shrink = stratification_shrink(solver, chosen, at);
  for (std::vector<double>& deviation : chosen.deviation)
    for (double& d : deviation) d *= shrink;
  // Storage (storage_bias).
  if (solver.auto_storage())
    result.bias = storage_bias(solver, at, chosen, evaluator, result.unestimated, shrink);
  else
    result.bias.assign(at.values(), 0.0);
  // The control variate's own discretisation (the transport of b_c over chords), a bias no photon
  // corrects: its estimate's reflected radiosity (with the later bounces' share,
  // control_variate_bias) joins the storage part, in magnitude. Under a gather it is left to the
  // gather's own part, which measured covers it (docs/estimated-error.md).
  if (evaluator == nullptr && !solver.control_variate_bias().empty()) {
    const ReflectedField field = solver.reflected_field(solver.control_variate_bias(), solver.chosen_levels());
    const auto channels = static_cast<std::size_t>(at.channels);
    for (std::size_t p = 0; p < at.points.size(); ++p) {
      const EvaluationPoints::Point& point = at.points[p];
      const Spectrum variate = solver.reflected_at(field, point.curve, point.side, point.u);
      for (std::size_t ch = 0; ch < channels; ++ch) {
        double& b = result.bias[p * channels + ch];
        b = (b < 0.0 ? -1.0 : 1.0) * (std::fabs(b) + std::fabs(variate[ch]));
      }
    }
  }
  result.mean = std::move(chosen.mean);
  result.deviation = std::move(chosen.deviation);
  return result;
}

// Unshot light: a round shoots the pool U and receives at most U of it, of which rho_max
// reflects; so all later rounds add at most rho_max U / (1 - rho_max) to the integral of B - E.
// Its share of B - E's integral (`reflected`) is taken as its relative error in every norm (it is
// spread like B - E: an assumption, not a bound, for L2 and L-infinity). Walks leave nothing;
// Jacobi iterations leave their average's books' small residual (shooting.hpp), taken the same way;
// a control variate's signed pool, the sum of its magnitudes.
double unshot_share_of(const Solver& solver, double reflected) {
  if (solver.settings().transport == Transport::Walk) return 0.0;
  const Scene& scene = solver.scene();
  double rho_max = 0.0;
  for (const Curve& curve : scene.curves)
    for (int ch = 0; ch < scene.channels; ++ch)
      rho_max = std::max(rho_max, scene.material_of(curve).reflectivity[static_cast<std::size_t>(ch)]);
  // (A control variate's pool is signed: its magnitude bounds what it would bring.)
  const double unshot = solver.pool_magnitude();
  const double missing = unshot > 0.0 ? rho_max * unshot / (1.0 - rho_max) : 0.0;
  return reflected > 0.0 ? missing / reflected : (missing > 0.0 ? kInfinity : 0.0);
}

// The bound from its parts (absolute norms) and the estimate's own norm D, in each norm: the sum
// A relative to D - A (the true norm is at least D - A), none where A reaches D; and each part
// relative to D.
struct Combined {
  RelativeErrors bound, noise, storage, unshot, gather;
  bool bounded = true;
};

Combined combine(const RelativeErrors& noise, const RelativeErrors& storage, const RelativeErrors& gather,
                 const RelativeErrors& norm, double unshot_share) {
  Combined result;
  for (double RelativeErrors::*member : {&RelativeErrors::l1, &RelativeErrors::l2, &RelativeErrors::linf}) {
    const double d = norm.*member;
    const double total = noise.*member + storage.*member + gather.*member + unshot_share * d;
    result.bound.*member = total < d ? total / (d - total) : kInfinity;
    result.bounded = result.bounded && total < d;
    result.noise.*member = d > 0.0 ? noise.*member / d : kInfinity;
    result.storage.*member = d > 0.0 ? storage.*member / d : kInfinity;
    result.gather.*member = d > 0.0 ? gather.*member / d : kInfinity;
    result.unshot.*member = unshot_share;
  }
  return result;
}

}  // namespace

std::vector<FieldPoint> estimate_points(const Solver& solver, int samples_per_curve) {
  return field_points(evaluation_points(solver, std::max(1, samples_per_curve)));
}

ErrorEstimate estimate_error(const Solver& solver, const ErrorEstimateOptions& options) {
  ErrorEstimate estimate;
  estimate.confidence = options.confidence;
  estimate.replicates = solver.replicates();
  const int replicates = solver.replicates();
  if (replicates < 2) {
    estimate.unavailable = "one replicate gives no estimate of the error (give replicates 8, the default)";
    return estimate;
  }
  if (solver.photons_shot() == 0) {
    estimate.unavailable = "no photon has been shot yet";
    return estimate;
  }
  estimate.available = true;
  const auto count = static_cast<std::size_t>(replicates);
  const EvaluationPoints at = evaluation_points(solver, std::max(1, options.samples_per_curve));
  const std::size_t values = at.values();
  const std::size_t curves = at.first.size() - 1;
  PointValues point_values = values_at(solver, at, options.evaluator);
  const std::vector<double>& mean = point_values.mean;
  const std::vector<std::vector<double>>& replicate = point_values.deviation;
  const std::vector<double>& bias = point_values.bias;
  // The control variate's own part joins the storage part (values_at) without a gather.
  const bool variate_part = options.evaluator == nullptr && !solver.control_variate_bias().empty();
  estimate.storage_estimated = solver.auto_storage() || variate_part;
  if (!solver.auto_storage())
    estimate.caveat = variate_part ? "the storage mesh is fixed, so its discretisation error is not estimated (the "
                                     "bound holds for the noise, the unshot light and the control variate's own "
                                     "discretisation, the storage part here, only; --elements auto estimates it)"
                                   : "the storage mesh is fixed, so its discretisation error is not estimated (the "
                                     "bound holds for the noise and the unshot light only; --elements auto "
                                     "estimates it)";
  else if (point_values.unestimated > 0)
    estimate.caveat = "the storage's discretisation error is not estimated on " +
                      std::to_string(point_values.unestimated) +
                      " curve(s) whose photons support only one storage mesh (the bound holds for their noise and "
                      "unshot light only; more photons give them a second mesh to compare)";
  const Scene& scene = solver.scene();
  const std::vector<Norms> size = norms_of(mean, at);

  // Noise. The mean's error is about Gaussian with covariance S / R, S the replicates' sample
  // covariance; sum_r g_r (X_r - mean) / sqrt(R (R - 1)), g_r standard normal, has exactly that
  // covariance. Each norm's quantile over such draws, times t / z, bounds the norm of the error at
  // the confidence even where one pattern dominates it (then it is |t_(R-1)| times its scale).
  const double scale = 1.0 / std::sqrt(static_cast<double>(count) * static_cast<double>(count - 1));
  const int draws = static_cast<int>(std::clamp(kDrawValueBudget / (3.0 * static_cast<double>(curves + 1)),
                                                static_cast<double>(kFewestDraws), static_cast<double>(kMostDraws)));
  std::vector<std::vector<Norms>> drawn(static_cast<std::size_t>(draws));
  Rng rng(solver.settings().seed, 0x6572726f72ull, 0);  // "error"
  std::vector<double> gauss(count + 1);
  std::vector<double> error(values);
  for (auto& norms : drawn) {
    // Box and Muller's pairs of independent standard normals.
    for (std::size_t r = 0; r < count; r += 2) {
      double sine = 0.0;
      double cosine = 0.0;
      portable::sin_cos(2.0 * 3.14159265358979323846 * rng.uniform(), sine, cosine);
      const double radius = std::sqrt(-2.0 * portable::log(rng.uniform_open()));
      gauss[r] = radius * cosine;
      gauss[r + 1] = radius * sine;
    }
    std::fill(error.begin(), error.end(), 0.0);
    for (std::size_t r = 0; r < count; ++r) {
      const double g = gauss[r] * scale;
      const std::vector<double>& deviation = replicate[r];
      for (std::size_t i = 0; i < values; ++i) error[i] += g * deviation[i];
    }
    norms = norms_of(error, at);
  }
  const double t_over_z =
      student_t_quantile_two_sided(options.confidence, replicates - 1) / normal_quantile_two_sided(options.confidence);
  const auto rank = static_cast<std::size_t>(std::ceil(options.confidence * draws)) - 1;
  auto noise_of = [&](std::size_t c) {
    std::vector<double> l1, l2, linf;
    for (const auto& norms : drawn) {
      const RelativeErrors e = norms[c].absolute();
      l1.push_back(e.l1);
      l2.push_back(e.l2);
      linf.push_back(e.linf);
    }
    auto quantile = [&](std::vector<double>& v) {
      std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(rank), v.end());
      return v[rank] * t_over_z;
    };
    return RelativeErrors{quantile(l1), quantile(l2), quantile(linf)};
  };

  const std::vector<Norms> bias_norms = norms_of(bias, at);
  // The evaluator's own error, at the solver's answer.
  std::vector<double> own;
  if (options.evaluator != nullptr) {
    const std::vector<FieldPoint> points = field_points(at);
    own =
        options.evaluator->own_error(solver, points, solver.reflected_field(solver.received(), solver.chosen_levels()));
  }
  if (own.size() != values) own.assign(values, 0.0);
  const std::vector<Norms> own_norms = norms_of(own, at);

  // Unshot light (unshot_share).
  const double unshot_share = unshot_share_of(solver, size[curves].l1);

  // The bound: the parts' sum A in each norm, relative to the estimate's norm D less A (the true
  // norm is at least D - A); none where A reaches D.
  auto combine_at = [&](std::size_t c) {
    return combine(noise_of(c), bias_norms[c].absolute(), own_norms[c].absolute(), size[c].absolute(), unshot_share);
  };
  if (!(size[curves].l1 > 0.0)) {
    estimate.available = false;
    estimate.unavailable = "no light has been reflected yet, so the relative error of B - E is undefined";
    return estimate;
  }
  const Combined scene_bound = combine_at(curves);
  estimate.bound = scene_bound.bound;
  estimate.bounded = scene_bound.bounded;
  estimate.noise = scene_bound.noise;
  estimate.storage = scene_bound.storage;
  estimate.unshot = scene_bound.unshot;
  estimate.gather = scene_bound.gather;
  if (!estimate.bounded) {
    const std::string why = "the estimated error is as large as B - E itself (noise " + percent(estimate.noise.l1) +
                            ", storage " + percent(estimate.storage.l1) + ", unshot " + percent(estimate.unshot.l1) +
                            " in L1): shoot more photons";
    estimate.caveat = estimate.caveat.empty() ? why : why + "; " + estimate.caveat;
  }
  for (std::uint32_t c = 0; c < curves; ++c) {
    CurveErrorEstimate& curve = estimate.curves.emplace_back();
    curve.id = scene.curves[c].id;
    curve.measured = size[c].l1 > 0.0;
    if (!curve.measured) {
      curve.bound = {kInfinity, kInfinity, kInfinity};
      continue;
    }
    const Combined curve_bound = combine_at(c);
    curve.bound = curve_bound.bound;
    curve.bounded = curve_bound.bounded;
  }
  return estimate;
}

std::vector<std::array<std::vector<double>, 2>> pointwise_bound(const Solver& solver,
                                                                const std::vector<std::vector<double>>& parameters,
                                                                double confidence) {
  std::vector<std::array<std::vector<double>, 2>> result(solver.scene().curves.size());
  const int replicates = solver.replicates();
  if (replicates < 2 || solver.photons_shot() == 0) return result;
  const EvaluationPoints at = points_at(solver, parameters);
  const PointValues values = values_at(solver, at, nullptr);
  const auto channels = static_cast<std::size_t>(at.channels);
  // The integral of B - E over the scene, for the unshot part's share.
  double reflected = 0.0;
  for (std::size_t p = 0; p < at.points.size(); ++p)
    for (std::size_t ch = 0; ch < channels; ++ch)
      reflected += at.points[p].weight * std::fabs(values.mean[p * channels + ch]);
  const double unshot_share = unshot_share_of(solver, reflected);
  // At one point the mean's error over its standard error is Student's t with R - 1 degrees of
  // freedom: t times the standard error bounds it at the confidence.
  const double t = student_t_quantile_two_sided(confidence, replicates - 1);
  const auto count = static_cast<double>(replicates);
  for (std::size_t p = 0; p < at.points.size(); ++p) {
    const auto& point = at.points[p];
    double half_width = 0.0;
    for (std::size_t ch = 0; ch < channels; ++ch) {
      const std::size_t i = p * channels + ch;
      double squares = 0.0;
      for (const std::vector<double>& deviation : values.deviation) squares += deviation[i] * deviation[i];
      const double standard_error = std::sqrt(squares / (count * (count - 1.0)));
      half_width += t * standard_error + std::fabs(values.bias[i]) + unshot_share * std::fabs(values.mean[i]);
    }
    result[point.curve][static_cast<std::size_t>(point.side)].push_back(half_width / static_cast<double>(channels));
  }
  return result;
}

}  // namespace flatland
