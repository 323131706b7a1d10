#include "flatland/transport/scene_storage.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

#include "flatland/base/portable_math.hpp"

namespace flatland {

namespace {

bool is_cancelled(const std::atomic<bool>* cancel) {
  return cancel != nullptr && cancel->load(std::memory_order_relaxed);
}

// The finest level of one curve under `plan`: footprints spread every deposit over the ray's
// width, so the deposited density is smooth on that scale; elements shorter than
// kFootprintFinestElement x the width resolve only the spread, while each hit pays for every span
// it covers. A level also has at least one element a segment before it halves them, so a curve of
// many segments stops refining where its own count would pass the room (counting
// kAutoBaseElements << level built 1024 elements a curve for 3,900 photons on curves of 256
// segments).
int finest_level_of(const Scene& scene, std::uint32_t c, const SolverSettings& settings, const StoragePlan& plan,
                    bool smooth, std::span<const MeshNode> events) {
  const Curve& curve = scene.curves[c];
  int finest = plan.finest_level;
  const auto base = std::max<double>(kAutoBaseElements, curve.segment_count);
  while (plan.automatic && finest > 0 && std::ldexp(base, finest) > plan.room[c]) --finest;
  if (plan.automatic && settings.ray_width > 0.0 && settings.ray_mode == RayMode::Footprint) {
    while (finest > 0 && longest_element(scene, curve, plan.elements, smooth, events, finest) <
                             kFootprintFinestElement * settings.ray_width)
      --finest;
  }
  return finest;
}

}  // namespace

Result<SceneStorage> SceneStorage::build(const Scene& scene, const SolverSettings& settings, const StoragePlan& plan,
                                         const std::vector<std::vector<MeshNode>>& events, WorkerPool& pool,
                                         const std::atomic<bool>* cancel) {
  SceneStorage built;
  built.scene_ = &scene;
  built.basis_ = settings.basis;
  built.estimator_ = settings.estimator;
  built.channels_ = scene.channels;
  const bool hermite = settings.basis == BasisKind::Hermite;
  const bool local = settings.estimator == Estimator::Local;
  const bool smooth = settings.discontinuities == DiscontinuityMode::None;
  built.storage_.resize(scene.curves.size());
  built.levels_.resize(scene.curves.size());
  // Every curve's storage and its coarser levels, each curve's by one worker.
  pool.for_each(scene.curves.size(), [&](std::size_t c) {
    if (is_cancelled(cancel)) return;
    const Curve& curve = scene.curves[c];
    CurveStorage& finest = built.storage_[c];
    if (!scene.holds_light(curve)) {
      // Mirrors, glass and detectors hold no light: no block, no deposit, no estimate. They keep
      // the smallest storage (one element a segment, no levels) so that every curve has a basis
      // to name in results, at a cost that does not grow with the plan.
      finest = build_curve_storage(scene, curve, settings.basis, 1, smooth);
      return;
    }
    const int finest_level = finest_level_of(scene, static_cast<std::uint32_t>(c), settings, plan, smooth, events[c]);
    finest = build_curve_storage(scene, curve, settings.basis, plan.elements, smooth, events[c], finest_level);
    if (local) build_local_estimator(scene, curve, finest, hermite);
    // The coarser levels, each with its restriction from the finest.
    std::vector<Level>& levels = built.levels_[c];
    for (int level = 0; level < finest_level; ++level) {
      if (is_cancelled(cancel)) return;
      Level& coarse = levels.emplace_back();
      coarse.storage = build_curve_storage(scene, curve, settings.basis, plan.elements, smooth, events[c], level);
      if (local) build_local_estimator(scene, curve, coarse.storage, hermite);
      coarse.restriction = restriction_between(coarse.storage.basis, finest.basis);
    }
  });
  if (is_cancelled(cancel)) return Error{"cancelled"};
  built.lay_out_blocks(scene);
  return built;
}

void SceneStorage::lay_out_blocks(const Scene& scene) {
  const auto channels = static_cast<std::size_t>(channels_);
  block_offset_.assign(scene.curves.size() * 2, kNoBlock);
  block_reflectivity_.assign(scene.curves.size() * 2, Spectrum{});
  block_black_.assign(scene.curves.size() * 2, 0);
  for (std::uint32_t c = 0; c < scene.curves.size(); ++c) {
    const Curve& curve = scene.curves[c];
    chosen_level_.push_back(static_cast<int>(levels_[c].size()));
    const Material& material = scene.material_of(curve);
    for (Side side : {Side::Front, Side::Back}) {
      if (!scene.stores(curve, side)) continue;  // mirrors, glass and detectors hold no light
      const std::uint32_t block = c * 2 + static_cast<std::uint32_t>(side);
      block_offset_[block] = static_cast<std::uint32_t>(coefficient_count_);
      block_reflectivity_[block] = material.reflectivity;
      bool black = true;
      for (std::size_t ch = 0; ch < channels; ++ch) black = black && !(material.reflectivity[ch] > 0.0);
      block_black_[block] = black ? 1 : 0;
      coefficient_count_ += storage_[c].basis.size();
      coefficient_block_.resize(coefficient_count_, block);
    }
  }
  curve_chunks_.assign(1, 0);
  std::size_t in_chunk = 0;
  for (std::uint32_t c = 0; c < scene.curves.size(); ++c) {
    for (Side side : {Side::Front, Side::Back})
      if (scene.stores(scene.curves[c], side)) in_chunk += storage_[c].basis.size();
    if (in_chunk >= kChunkCoefficients || c + 1 == scene.curves.size()) {
      curve_chunks_.push_back(c + 1);
      in_chunk = 0;
    }
  }
}

const CurveStorage& SceneStorage::at_level(std::uint32_t curve, int level) const {
  const std::vector<Level>& levels = levels_[curve];
  return level < static_cast<int>(levels.size()) ? levels[static_cast<std::size_t>(level)].storage : storage_[curve];
}

int SceneStorage::elements_in_use(std::uint32_t curve) const { return level_elements(curve, chosen_level_[curve]); }

int SceneStorage::distinct_level(std::uint32_t curve, int level, int step) const {
  const double here = level_elements(curve, level);
  for (int other = level + step; other >= 0 && other < level_count(curve); other += step) {
    const double ratio = level_elements(curve, other) / here;
    if (ratio >= kDistinctLevelRatio || ratio <= 1.0 / kDistinctLevelRatio) return other;
  }
  return -1;
}

int SceneStorage::level_elements(std::uint32_t curve, int level) const {
  const CurveStorage& storage = at_level(curve, level);
  int spans = 0;
  const std::vector<double>& knots = storage.basis.knots();
  for (std::size_t span = storage.basis.first_span(); span < storage.basis.end_span(); ++span)
    spans += knots[span + 1] > knots[span];
  return spans;
}

std::size_t SceneStorage::discontinuity_nodes() const {
  std::size_t count = 0;
  for (const CurveStorage& storage : storage_)
    for (const MeshNode& node : storage.nodes) count += node.continuity != Continuity::C1;
  return count;
}

double SceneStorage::arc_length_at(std::uint32_t curve, double u) const {
  return flatland::arc_length_at(*scene_, scene_->curves[curve], u);
}

void SceneStorage::estimate_on(const CurveStorage& storage, const double* power, double* coefficients,
                               std::size_t stride) const {
  if (estimator_ == Estimator::Galerkin) {
    galerkin_estimate(storage, power, coefficients, stride);
  } else if (estimator_ == Estimator::Local) {
    local_estimate(storage, power, coefficients, stride);
  } else {
    for (std::size_t k = 0; k < storage.basis.size(); ++k)
      coefficients[k * stride] = power[k * stride] / storage.basis_length[k];
  }
}

std::vector<double> SceneStorage::estimate_in_level(std::uint32_t curve, int level, const double* power,
                                                    std::size_t stride) const {
  const std::vector<Level>& levels = levels_[curve];
  const std::size_t n = at_level(curve, level).basis.size();
  std::vector<double> deposits(n);
  std::vector<double> estimate(n);
  if (level >= static_cast<int>(levels.size())) {
    for (std::size_t k = 0; k < n; ++k) deposits[k] = power[k * stride];
    estimate_on(storage_[curve], deposits.data(), estimate.data(), 1);
    return estimate;
  }
  // Deposits of the coarse level follow from the fine ones.
  const Level& coarse = levels[static_cast<std::size_t>(level)];
  restrict_deposits(coarse.restriction, power, stride, deposits.data());
  estimate_on(coarse.storage, deposits.data(), estimate.data(), 1);
  return estimate;
}

void SceneStorage::estimate_at_level(std::uint32_t curve, int level, const double* power, double* coefficients,
                                     std::size_t stride) const {
  if (level >= static_cast<int>(levels_[curve].size())) {
    estimate_on(storage_[curve], power, coefficients, stride);
    return;
  }
  // A coarse level's estimate, prolonged, is the same function in the fine basis.
  const std::vector<double> estimate = estimate_in_level(curve, level, power, stride);
  prolong_coefficients(levels_[curve][static_cast<std::size_t>(level)].restriction, estimate.data(), coefficients,
                       stride);
}

bool SceneStorage::holds_power(const std::vector<double>& values, std::uint32_t curve, std::uint32_t offset) const {
  const auto channels = static_cast<std::size_t>(channels_);
  const double* block = &values[offset * channels];
  return std::any_of(block, block + storage_[curve].basis.size() * channels, [](double x) { return x != 0.0; });
}

void SceneStorage::estimate(const std::vector<double>& power, std::vector<double>& coefficients) const {
  coefficients.assign(power.size(), 0.0);
  for (std::uint32_t c = 0; c < scene_->curves.size(); ++c) estimate_curve(c, power, coefficients);
}

void SceneStorage::estimate(const std::vector<double>& power, std::vector<double>& coefficients,
                            const std::vector<int>& levels) const {
  const auto channels = static_cast<std::size_t>(channels_);
  coefficients.assign(power.size(), 0.0);
  for (std::uint32_t c = 0; c < scene_->curves.size(); ++c)
    for (Side side : {Side::Front, Side::Back}) {
      const std::uint32_t offset = block_offset(c, side);
      if (offset == kNoBlock || !holds_power(power, c, offset)) continue;
      for (std::size_t ch = 0; ch < channels; ++ch) {
        const std::size_t first = offset * channels + ch;
        estimate_at_level(c, levels[c], &power[first], &coefficients[first], channels);
      }
    }
}

void SceneStorage::estimate_curve(std::uint32_t c, const std::vector<double>& power,
                                  std::vector<double>& coefficients) const {
  const auto channels = static_cast<std::size_t>(channels_);
  for (Side side : {Side::Front, Side::Back}) {
    const std::uint32_t offset = block_offset(c, side);
    if (offset == kNoBlock) continue;
    // Every estimator is linear: a side that holds no power (most sides of a large scene in a
    // round of a few photons) keeps its zero coefficients without a solve.
    if (!holds_power(power, c, offset)) continue;
    for (std::size_t ch = 0; ch < channels; ++ch) {
      const std::size_t first = offset * channels + ch;
      estimate_at_level(c, chosen_level_[c], &power[first], &coefficients[first], channels);
    }
  }
}

namespace {

// The squared L2 norm along a curve of a level's function, the same for every level: a spline's
// coefficients prolonged into the fine basis, through the fine mass matrix; or a Hermite curve's
// values at two Gauss-Legendre points in arc length on every finest span (every level's Hermite
// curve is a cubic in arc length there; the rule is exact for the squared norm of differences up
// to linear, an approximation for cubic ones that chose the same levels as four points on the
// tests' scenes at half the cost). So the level is chosen by the error of what is reconstructed.
class LevelNorm {
 public:
  LevelNorm(const SceneStorage& storage, std::uint32_t curve, bool hermite, std::size_t sides)
      : storage_(storage), fine_(storage.finest(curve)), curve_(curve), hermite_(hermite), sides_(sides) {
    if (hermite_) {
      const double gauss = 1.0 / std::sqrt(3.0);
      const SplineBasis& basis = fine_.basis;
      const std::vector<double>& knots = basis.knots();
      double s1 = storage.arc_length_at(curve, knots[basis.first_span()]);  // each knot's arc length once
      for (std::size_t span = basis.first_span(); span < basis.end_span(); ++span) {
        if (!(knots[span + 1] > knots[span])) continue;
        const double s0 = s1;
        s1 = storage.arc_length_at(curve, knots[span + 1]);
        const double half_width = 0.5 * (s1 - s0);
        for (const double x : {-gauss, gauss}) {
          at_.push_back(s0 + half_width * (1.0 + x));
          weights_.push_back(half_width);
        }
      }
    }
    width_ = hermite_ ? at_.size() : fine_.basis.size();
  }

  std::size_t width() const { return width_; }  // values per side

  // Level `level`'s estimate from `source` (one side's deposits), as `width()` values.
  void represent(std::size_t level, const std::vector<double>& source, double* out) const {
    if (!hermite_) {
      storage_.estimate_at_level(curve_, static_cast<int>(level), source.data(), out, 1);
      return;
    }
    const std::vector<double> nodal = storage_.estimate_in_level(curve_, static_cast<int>(level), source.data(), 1);
    storage_.hermite_of(curve_, static_cast<int>(level), nodal.data()).evaluate_increasing(at_, out);
  }

  // |x|^2 = x^T M x = |L^T x|^2 per side, with M's Cholesky factor L in envelope storage (a Hermite
  // curve: the Gauss rule on its values); value(i) gives x over all sides.
  template <typename Value>
  double operator()(Value value) const {
    double sum = 0.0;
    if (hermite_) {
      for (std::size_t i = 0; i < sides_ * width_; ++i) sum += weights_[i % width_] * value(i) * value(i);
      return sum;
    }
    const std::size_t n = fine_.basis.size();
    std::vector<double> y(n);
    for (std::size_t s = 0; s < sides_; ++s) {
      std::fill(y.begin(), y.end(), 0.0);
      for (std::size_t row = 0; row < n; ++row) {
        const double x = value(s * n + row);
        for (std::size_t col = fine_.mass_first[row]; col <= row; ++col)
          y[col] += fine_.mass_cholesky[fine_.mass_offset[row] + col - fine_.mass_first[row]] * x;
      }
      for (double v : y) sum += v * v;
    }
    return sum;
  }

 private:
  const SceneStorage& storage_;
  const CurveStorage& fine_;
  std::uint32_t curve_;
  bool hermite_;
  std::size_t sides_;
  std::size_t width_ = 0;
  std::vector<double> at_;       // increasing arc lengths
  std::vector<double> weights_;  // the quadrature's weight of each
};

}  // namespace

// One curve's reflected power (rho times received, summed over channels) on each of its storage
// sides: from all photons, and from the halves A and B.
struct SceneStorage::ReflectedPower {
  std::vector<std::array<std::vector<double>, 3>> sides;  // [side][all, A, B][k]
  double total = 0.0;
};

SceneStorage::ReflectedPower SceneStorage::reflected_power(std::uint32_t c, const std::vector<double>& received,
                                                           const std::vector<double>& half) const {
  const auto channels = static_cast<std::size_t>(channels_);
  const std::size_t n = storage_[c].basis.size();
  ReflectedPower reflected;
  for (Side side : {Side::Front, Side::Back}) {
    const std::uint32_t offset = block_offset(c, side);
    if (offset == kNoBlock) continue;
    const Spectrum& rho = block_reflectivity_[c * 2 + static_cast<std::uint32_t>(side)];
    auto& [all, a, b] = reflected.sides.emplace_back();
    all.assign(n, 0.0);
    a.assign(n, 0.0);
    b.assign(n, 0.0);
    for (std::size_t k = 0; k < n; ++k)
      for (std::size_t ch = 0; ch < channels; ++ch) {
        const std::size_t index = (offset + k) * channels + ch;
        all[k] += rho[ch] * received[index];
        a[k] += rho[ch] * half[index];
      }
    for (std::size_t k = 0; k < n; ++k) {
      b[k] = all[k] - a[k];
      reflected.total += all[k];
    }
  }
  return reflected;
}

// Per curve, with the reflected power on each side: the estimate f_l at every level l, and f_l^A,
// f_l^B from the two halves of the photons (the odd and even replicates, with equal means:
// independent, or, laid out as blocks of one net, stratified against each other, when the halves'
// difference overstates the variance by a factor choose_levels is given). Then, in the L2
// norm along the curve (LevelNorm),
//   variance  V_l = |f_l^A - f_l^B|^2     (its expectation is Var f_l^A + Var f_l^B = Var f_l),
//   bias^2    |f_l - f_m|^2 less its own noise |D^A - D^B|^2 (D^X = f_l^X - f_m^X), m the next
//             finer level whose mesh differs from l's (distinct_level), times
//             (k^q / (k^q - 1))^2: with the bias shrinking as h^q (q the estimator's order) and
//             k = m's elements over l's, f_l - f_m is (1 - k^-q) of level l's bias; a level with
//             no distinct finer one has the bias of the distinct level below it over k^q,
// and the level kept minimises bias^2 + V (ties: the coarser). Each level's bias comes from its
// own step to the next distinct mesh: sums of steps accumulate their noise, and differences to the
// finest level carry the finest level's large variance, both of which push choices off the best;
// a step to the same mesh (a curve cut by many nodes keeps short regions whole over several
// levels) would see no bias at all and keep the coarsest level however coarse it is.
int SceneStorage::best_level(std::uint32_t c, const ReflectedPower& reflected, double variance_factor) const {
  const int finest = static_cast<int>(levels_[c].size());
  const auto count = static_cast<std::size_t>(finest) + 1;
  const std::size_t sides = reflected.sides.size();
  const LevelNorm norm2(*this, c, basis_ == BasisKind::Hermite, sides);
  const std::size_t width = norm2.width();
  // [level][side][i]: full, A and B estimates.
  using PerLevel = std::vector<std::vector<double>>;
  PerLevel full(count, std::vector<double>(sides * width));
  PerLevel part_a = full;
  PerLevel part_b = full;
  const std::array<PerLevel*, 3> targets = {&full, &part_a, &part_b};
  for (std::size_t level = 0; level < count; ++level)
    for (std::size_t side = 0; side < sides; ++side)
      for (std::size_t set = 0; set < 3; ++set)
        norm2.represent(level, reflected.sides[side][set], (*targets[set])[level].data() + side * width);
  // The estimator's order q: its bias shrinks as h^q.
  const int degree = storage_[c].basis.degree();
  const int order = estimator_ == Estimator::Lumped ? std::min(degree + 1, 2) : degree + 1;
  double best = std::numeric_limits<double>::infinity();
  std::vector<double> biases2(count, 0.0);
  int chosen = finest;
  for (std::size_t l = 0; l < count; ++l) {
    const int level = static_cast<int>(l);
    double& bias2 = biases2[l];
    if (const int finer = distinct_level(c, level, +1); finer >= 0) {
      const auto m = static_cast<std::size_t>(finer);
      const double kq =
          portable::integer_power(static_cast<double>(level_elements(c, finer)) / level_elements(c, level), order);
      const double difference = norm2([&](std::size_t i) { return full[l][i] - full[m][i]; });
      const double noise = variance_factor * norm2([&](std::size_t i) {
                             return (part_a[l][i] - part_a[m][i]) - (part_b[l][i] - part_b[m][i]);
                           });
      bias2 = std::max(difference - noise, 0.0) * (kq / (kq - 1.0)) * (kq / (kq - 1.0));
    } else if (const int coarser = distinct_level(c, level, -1); coarser >= 0) {
      // The finest distinct mesh: the bias of the distinct level below it, shrunk by its ratio.
      const double kq =
          portable::integer_power(static_cast<double>(level_elements(c, level)) / level_elements(c, coarser), order);
      bias2 = biases2[static_cast<std::size_t>(coarser)] / (kq * kq);
    }
    const double variance = variance_factor * norm2([&](std::size_t i) { return part_a[l][i] - part_b[l][i]; });
    if (bias2 + variance < best) {
      best = bias2 + variance;
      chosen = static_cast<int>(l);
    }
  }
  return chosen;
}

void SceneStorage::choose_levels(const std::vector<double>& received, const std::vector<double>& half,
                                 double variance_factor) {
  for (std::uint32_t c = 0; c < scene_->curves.size(); ++c) {
    if (levels_[c].empty()) continue;
    // A curve that received nothing keeps its level (as one whose reflected power is zero does).
    bool received_any = false;
    for (Side side : {Side::Front, Side::Back}) {
      const std::uint32_t offset = block_offset(c, side);
      received_any = received_any || (offset != kNoBlock && holds_power(received, c, offset));
    }
    if (!received_any) continue;
    const ReflectedPower reflected = reflected_power(c, received, half);
    if (reflected.sides.empty() || !(reflected.total > 0.0)) continue;
    chosen_level_[c] = best_level(c, reflected, variance_factor);
  }
}

HermiteReconstruction SceneStorage::hermite_of(std::uint32_t curve, int level, const double* values) const {
  // Hat k of a linear B-spline peaks at knots[k + 1] (its Greville point); two hats peaking at the
  // same place are the two sides of a C-1 node.
  const CurveStorage& storage = at_level(curve, level);
  const std::vector<double>& knots = storage.basis.knots();
  HermiteInput input;
  std::size_t next_node = 0;  // storage.nodes is sorted by u, as the Greville points are
  for (std::size_t k = 0; k < storage.basis.size(); ++k) {
    const double u = knots[k + 1];
    const double value = values[k];
    if (k > 0 && u == knots[k]) {  // the right side of a jump
      input.right.back() = value;
      continue;
    }
    while (next_node < storage.nodes.size() && storage.nodes[next_node].u < u) ++next_node;
    const Continuity continuity = next_node < storage.nodes.size() && storage.nodes[next_node].u == u
                                      ? storage.nodes[next_node].continuity
                                      : Continuity::C1;
    input.u.push_back(arc_length_at(curve, u));
    input.left.push_back(value);
    input.right.push_back(value);
    input.continuity.push_back(continuity);
  }
  if (storage.basis.is_periodic()) {
    // Hat 0 peaks at the closing point: it is node 0 and, a lap later, node n.
    input.periodic = true;
    input.continuity.front() = storage.closing;
    input.u.push_back(scene_->curves[curve].length);
    input.left.push_back(values[0]);
    input.right.push_back(values[0]);
    input.continuity.push_back(storage.closing);
  }
  return HermiteReconstruction(input);
}

}  // namespace flatland
