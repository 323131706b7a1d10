#include "flatland/transport/solver.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <numeric>
#include <thread>

#include "flatland/base/resources.hpp"
#include "flatland/scene/discontinuities.hpp"
#include "flatland/transport/error_estimate.hpp"

namespace flatland {

namespace {

using Clock = std::chrono::steady_clock;

double seconds_since(Clock::time_point start) { return std::chrono::duration<double>(Clock::now() - start).count(); }

}  // namespace

const char* to_string(StopReason reason) {
  switch (reason) {
    case StopReason::Running: return "running";
    case StopReason::Converged: return "converged";
    case StopReason::BudgetSpent: return "photon budget spent";
    case StopReason::Cancelled: return "cancelled";
    case StopReason::BooksUnbalanced: return "energy books unbalanced";
    case StopReason::TargetReached: return "target error reached";
  }
  return "?";
}

double Solver::sum_odd_parts(const std::vector<double>& parts, std::vector<double>& half) const {
  // R is even: the odd replicates are half of every round's photons (odd photons, or odd blocks).
  const std::size_t size = received_.size();
  const auto replicates = static_cast<std::size_t>(settings_.replicates);
  half.assign(size, 0.0);
  for (std::size_t r = 1; r < replicates; r += 2)
    for (std::size_t index = 0; index < size; ++index) half[index] += parts[r * size + index];
  if (!replicates_stratified(settings_)) return 1.0;
  // Replicate r estimates the whole as R times its part, a pair as R / 2 times its two.
  const auto n = static_cast<double>(replicates);
  double blocks = 0.0;
  double pairs = 0.0;
  for (std::size_t index = 0; index < size; ++index) {
    double mean = 0.0;
    for (std::size_t r = 0; r < replicates; ++r) mean += parts[r * size + index];
    for (std::size_t r = 0; r < replicates; ++r) {
      const double d = n * parts[r * size + index] - mean;
      blocks += d * d;
    }
    for (std::size_t r = 0; r + 1 < replicates; r += 2) {
      const double d = 0.5 * n * (parts[r * size + index] + parts[(r + 1) * size + index]) - mean;
      pairs += d * d;
    }
  }
  return stratification_factor(blocks, pairs, settings_.replicates);
}

bool Solver::has_side(std::uint32_t curve, Side side) const {
  return storage_.block_offset(curve, side) != SceneStorage::kNoBlock;
}

std::size_t Solver::discontinuity_nodes() const { return storage_.discontinuity_nodes(); }

int Solver::storage_elements(std::uint32_t curve) const { return storage_.elements_in_use(curve); }

RoundView Solver::round_view() const {
  RoundView view;
  view.number = rounds_;
  view.plan = &round_;
  view.storage = &storage_;
  view.hermite_unshot = &hermite_unshot_;
  view.emitted_light = transport().emitted_light(rounds_ - pass_first_round_);
  view.photons_go_on = transport().photons_go_on();
  view.bounce = transport().bounce(rounds_ - pass_first_round_);
  return view;
}

std::size_t Solver::round_message_size() const {
  return storage_.coefficient_count() * static_cast<std::size_t>(channels_ * settings_.replicates) +
         shooter_.detector_layout().size + 22;
}

bool Solver::begin_round() {
  const auto channels = static_cast<std::size_t>(channels_);
  // The pool by block: what each curve side's photons would carry, channels summed and apart.
  std::vector<double> weights(storage_.block_count(), 0.0);
  std::vector<Spectrum> block_unshot(storage_.block_count(), Spectrum{});
  auto measure_pool = [&]() {
    const std::vector<double>& pool = transport().pool();
    std::fill(weights.begin(), weights.end(), 0.0);
    std::fill(block_unshot.begin(), block_unshot.end(), Spectrum{});
    for (std::uint32_t block = 0; block < storage_.block_count(); ++block) {
      const std::uint32_t offset = storage_.block_offset(block);
      if (offset == SceneStorage::kNoBlock) continue;
      const std::size_t count = storage_.finest(block / 2).basis.size();
      for (std::size_t k = 0; k < count; ++k)
        for (std::size_t ch = 0; ch < channels; ++ch)
          block_unshot[block][ch] +=
              signed_pool_ ? std::fabs(pool[(offset + k) * channels + ch]) : pool[(offset + k) * channels + ch];
      for (std::size_t ch = 0; ch < channels; ++ch) weights[block] += block_unshot[block][ch];
    }
    return std::accumulate(weights.begin(), weights.end(), 0.0);
  };
  double unshot = measure_pool();
  // Every round's photons are a multiple of the replicates, so that each replicate is an equal
  // share of it (R times its part estimates the whole); a budget's last R - 1 photons or fewer
  // are not shot.
  const auto replicates = static_cast<std::uint64_t>(settings_.replicates);
  if (settings_.target_error > 0.0) {
    const std::uint32_t passes_before = passes_;
    if (!next_pass_or_stop(unshot)) {
      choose_final_levels();
      return false;
    }
    if (passes_ != passes_before) unshot = measure_pool();
  } else {
    if (transport().converged(unshot)) {
      stop_reason_ = StopReason::Converged;
      choose_final_levels();
      return false;
    }
    if (settings_.photons - photons_shot_ < replicates) {
      stop_reason_ = StopReason::BudgetSpent;
      choose_final_levels();
      return false;
    }
  }
  const std::uint64_t pass_budget = pass_budget_ != 0 ? pass_budget_ : settings_.photons;
  const std::uint64_t photons =
      transport().round_photons(unshot, photons_shot_ - pass_first_photon_, pass_budget, rounds_ - pass_first_round_);
  round_.photons = std::max(replicates, photons - photons % replicates);
  round_.headroom_bits = transport().headroom_bits(round_.photons);
  // Fixed point: unshot * scale < 2^61, and scale a power of two so units convert exactly.
  round_.scale = std::ldexp(1.0, 60 - round_.headroom_bits - std::ilogb(unshot));
  plan_sources(transport().pool(), block_unshot, unshot);
  return true;
}

bool Solver::target_met() {
  const ErrorEstimate estimate = estimate_error(*this, {settings_.confidence, kTargetSamples, target_evaluator_});
  checked_error_ = estimate.available && estimate.bounded ? estimate.bound.l1 : std::numeric_limits<double>::infinity();
  return checked_error_ <= settings_.target_error;
}

bool Solver::next_pass_or_stop(double unshot) {
  const auto replicates = static_cast<std::uint64_t>(settings_.replicates);
  const bool cap_spent = settings_.photons - photons_shot_ < replicates;
  if (settings_.transport == Transport::Walk) {
    // Every round of walks estimates the whole: the target is checked after each.
    if (rounds_ > 0 && target_met()) {
      stop_reason_ = StopReason::TargetReached;
      return false;
    }
    if (cap_spent) stop_reason_ = StopReason::BudgetSpent;
    return !cap_spent;
  }
  const std::uint64_t in_pass = photons_shot_ - pass_first_photon_;
  const bool pass_over = transport().converged(unshot) || pass_budget_ - std::min(pass_budget_, in_pass) < replicates;
  if (!pass_over && !cap_spent) return true;
  // The pass joins the finished ones, weighted by its photons.
  const double n = static_cast<double>(in_pass);
  const std::size_t size = received_.size();
  if (passes_received_.empty()) {
    passes_received_.assign(size, 0.0);
    passes_parts_.assign(received_parts_.size(), 0.0);
  }
  for (std::size_t i = 0; i < size; ++i) passes_received_[i] += n * received_[i];
  for (std::size_t i = 0; i < received_parts_.size(); ++i) passes_parts_[i] += n * received_parts_[i];
  EnergyBooks pass_books;
  transport().add_books(pass_books, channels_, rounds_ - pass_first_round_);
  passes_books_.add_outcomes(pass_books, n);
  passes_detected_.resize(detected_.size(), 0.0);
  for (std::size_t i = 0; i < detected_.size(); ++i) passes_detected_[i] += n * detected_[i];
  std::fill(detected_.begin(), detected_.end(), 0.0);
  passes_photons_ += n;
  ++passes_;
  start_received();
  pass_first_photon_ = photons_shot_;
  pass_first_round_ = rounds_;
  mix_passes();
  if (auto_storage_) half_variance_factor_ = sum_odd_parts(mixed_parts_, received_half_);
  update_reflected(mixed_received_, received_half_, half_variance_factor_, LevelChoice::Final);
  if (target_met()) {
    stop_reason_ = StopReason::TargetReached;
    return false;
  }
  if (cap_spent) {
    stop_reason_ = StopReason::BudgetSpent;
    return false;
  }
  // The next pass: with error ~ N^-1/2 the photons that would reach the target, 10 % more, but at
  // least a quarter and at most all of those shot so far (so the photons spent are at most twice
  // what the target needed), and no more than the cap leaves.
  const double shot = static_cast<double>(photons_shot_);
  const double ratio = checked_error_ / settings_.target_error;
  const double wanted = std::isfinite(ratio) ? 1.1 * shot * (ratio * ratio - 1.0) : shot;
  const double budget = std::clamp(wanted, 0.25 * shot, shot);
  pass_budget_ = std::min(static_cast<std::uint64_t>(budget), settings_.photons - photons_shot_);
  transport_ = ProgressiveShooting(emission_, tolerance_power(), decay_, pass_tolerance(),
                                   averaged_budget(pass_budget_), signed_pool_);
  return true;
}

void Solver::passes_mean(const std::vector<double>& passes, const std::vector<double>& current,
                         std::vector<double>& out) const {
  // The finished passes (their values already times their photons) and the current one, each
  // weighted by its photons.
  const double n = static_cast<double>(photons_shot_ - pass_first_photon_);
  const double total = passes_photons_ + n;
  out.resize(current.size());
  for (std::size_t i = 0; i < current.size(); ++i) out[i] = (passes[i] + n * current[i]) / total;
}

void Solver::mix_passes() {
  passes_mean(passes_received_, received_, mixed_received_);
  passes_mean(passes_parts_, received_parts_, mixed_parts_);
}

void Solver::plan_sources(const std::vector<double>& pool, const std::vector<Spectrum>& block_unshot, double unshot) {
  const auto channels = static_cast<std::size_t>(channels_);
  // A photon from source j carries U_j / (n p_j) with p_j = w_j / U: its channels sum to U / n.
  // Sources are the sides of curves (uniform sampling) or single coefficients (reconstructed
  // sampling, so a photon also takes the colour of the unshot light where it starts).
  const bool reconstructed = settings_.sampling == PositionSampling::Reconstructed;
  const bool by_hermite = reconstructed && settings_.basis == BasisKind::Hermite;
  const bool by_coefficient = reconstructed && !by_hermite;
  // The unshot density of every block, channels summed, for the positions; each photon carries
  // its block's colour (its power comes from the deposits, so the books stay exact).
  if (by_hermite) update_hermite_unshot(pool);
  const std::size_t sources = by_coefficient ? storage_.coefficient_count() : storage_.block_count();
  // Scratch kept between rounds (a fresh allocation of the storage's size faulted its pages in
  // every round).
  std::vector<double>& source_weights = source_weights_;
  source_weights.assign(sources, 0.0);
  round_.photon_units.assign(sources, {});
  const double per_photon = unshot / static_cast<double>(round_.photons);
  // With the Galerkin or local estimator the reconstructed unshot density has coefficients g
  // (M^-1 U, or the local weights times U) rather than U / L, and with automatic storage it is the
  // chosen level's estimate: clamped at zero, keeping each curve side's power, coefficient k of the
  // finest basis carries the power g_k integral(phi_k ds).
  std::vector<double>& density_power = density_power_;
  density_power.clear();
  // A signed pool's later rounds (a control variate's reflections of D, noisy) leave by the lumped
  // density, the pool itself: its magnitude is at most the pool's, where the Galerkin density of
  // signed noise (M^-1 of it) can be many times larger, and reflected round after round would grow
  // without bound. Its first round, D itself, has no noise and takes the storage's estimate.
  const bool lumped_signed = signed_pool_ && rounds_ != pass_first_round_;
  if (by_coefficient && (settings_.estimator != Estimator::Lumped || auto_storage_) && !lumped_signed) {
    density_power.assign(pool.size(), 0.0);
    // A solve per curve side and channel: shared among the threads, by runs of curves.
    for_each_curve([&](std::uint32_t c) {
      storage_.estimate_curve(c, pool, density_power);
      for (Side side : {Side::Front, Side::Back}) {
        const std::uint32_t offset = storage_.block_offset(c, side);
        if (offset == SceneStorage::kNoBlock) continue;
        const CurveStorage& storage = storage_.finest(c);
        for (std::size_t ch = 0; ch < channels; ++ch) {
          // The side's deposited unshot power, exactly; where the estimate has no positive part
          // left (a local estimate on a region too short for its window can), the lumped density.
          double power = 0.0;
          for (std::size_t k = 0; k < storage.basis.size(); ++k) power += pool[(offset + k) * channels + ch];
          // A signed pool (a control variate's difference) keeps its signs: its photons carry them.
          if (!signed_pool_ && !clamp_keeping_power(storage, &density_power[offset * channels + ch], channels, power))
            for (std::size_t k = 0; k < storage.basis.size(); ++k)
              density_power[(offset + k) * channels + ch] =
                  pool[(offset + k) * channels + ch] / storage.basis_length[k];
        }
        for (std::size_t k = 0; k < storage.basis.size(); ++k)
          for (std::size_t ch = 0; ch < channels; ++ch)
            density_power[(offset + k) * channels + ch] *= storage.basis_length[k];
      }
    });
  }
  const std::vector<double>& coefficient_power = density_power.empty() ? pool : density_power;
  const auto source_power = [&](std::size_t j) {
    return by_coefficient ? &coefficient_power[j * channels] : block_unshot[j].data();
  };
  kept_.clear();
  if (!importance_.empty()) {
    if (plan_important_sources(pool, by_coefficient, source_power)) return;
    // Planned without importance after all: from nothing again.
    std::fill(source_weights.begin(), source_weights.end(), 0.0);
    std::fill(round_.photon_units.begin(), round_.photon_units.end(), std::array<std::int64_t, 3>{});
  }
  if (signed_pool_) {
    plan_signed_sources(source_power);
    return;
  }
  for (std::size_t j = 0; j < sources; ++j) {
    const double* power = source_power(j);
    for (std::size_t ch = 0; ch < channels; ++ch) source_weights[j] += power[ch];
    if (!(source_weights[j] > 0.0)) continue;
    for (std::size_t ch = 0; ch < channels; ++ch)
      round_.photon_units[j][ch] = std::llround(power[ch] / source_weights[j] * per_photon * round_.scale);
  }
  round_.sources.assign(source_weights);
}

void Solver::plan_signed_sources(const std::function<const double*(std::size_t)>& source_power) {
  // Source j (a coefficient) has signed power w_j[ch] and is chosen with probability |w_j| / T, |w_j|
  // = sum over channels of |w_j[ch]| and T the sum of |w_j|; each of the n photons carries w_j[ch]
  // T / (n |w_j|), so the source's expected power shot is w_j[ch], signs included. The fixed point's
  // scale follows T (which a Galerkin density's magnitudes can make larger than the pool's).
  const auto channels = static_cast<std::size_t>(channels_);
  std::vector<double>& source_weights = source_weights_;
  double total = 0.0;
  for (std::size_t j = 0; j < source_weights.size(); ++j) {
    const double* power = source_power(j);
    for (std::size_t ch = 0; ch < channels; ++ch) source_weights[j] += std::fabs(power[ch]);
    total += source_weights[j];
  }
  if (total > 0.0)
    round_.scale = std::min(round_.scale, std::ldexp(1.0, 60 - round_.headroom_bits - std::ilogb(total)));
  const double per_photon = total / static_cast<double>(round_.photons);
  for (std::size_t j = 0; j < source_weights.size(); ++j) {
    if (!(source_weights[j] > 0.0)) continue;
    const double* power = source_power(j);
    for (std::size_t ch = 0; ch < channels; ++ch)
      round_.photon_units[j][ch] = std::llround(power[ch] / source_weights[j] * per_photon * round_.scale);
  }
  round_.sources.assign(source_weights);
}

bool Solver::plan_important_sources(const std::vector<double>& pool, bool by_coefficient,
                                    const std::function<const double*(std::size_t)>& source_power) {
  // Source j of block b (a curve side, or one of its coefficients) has power w_j (channels summed;
  // the side's w_j sum to its unshot power P_b) and is chosen with probability proportional to
  // w_j I_b, I_b the side's weight (importance.hpp: the square root of its importance, held to a
  // floor). The round's photons are counted per side first (the same
  // choices the shooter makes), and each of side b's n_b photons carries P_b / n_b, in its
  // source's colour: given n_b, they carry exactly the side's power, so its expected deposits are
  // those of shooting it all, and the books balance photon by photon. A side that no photon chose
  // keeps its power in the pool for the next round, except in a round of emitted light: kept, the
  // power would later leave as reflected light (diffusely, from anywhere on the side, without a
  // wavelength), not as its emitter sends it. Such a round, when it would keep any power, is
  // planned without importance instead (false).
  const auto channels = static_cast<std::size_t>(channels_);
  const std::size_t sources = source_weights_.size();
  const auto block_of = [&](std::size_t j) {
    return by_coefficient ? storage_.coefficient_block(static_cast<std::uint32_t>(j)) : static_cast<std::uint32_t>(j);
  };
  std::vector<double> side_power(storage_.block_count(), 0.0);
  std::vector<double> chosen(sources, 0.0);
  for (std::size_t j = 0; j < sources; ++j) {
    const double* power = source_power(j);
    for (std::size_t ch = 0; ch < channels; ++ch) source_weights_[j] += power[ch];
    if (!(source_weights_[j] > 0.0)) continue;
    const std::uint32_t block = block_of(j);
    side_power[block] += source_weights_[j];
    chosen[j] = source_weights_[j] * importance_[block];
  }
  round_.sources.assign(chosen);
  // The count, shared among the threads by runs of photons (the sums do not depend on the split).
  const std::uint64_t photons = round_.photons;
  const RoundView view = round_view();
  const unsigned workers = threads_ > 1 && photons >= 4 * kBatchSize ? worker_pool().threads() : 1u;
  std::vector<std::vector<std::uint64_t>> counts(workers, std::vector<std::uint64_t>(storage_.block_count(), 0));
  const auto count = [&](unsigned w) {
    const std::uint64_t first = photons * w / workers;
    const std::uint64_t last = photons * (w + 1) / workers;
    shooter_.count_sources(view, first, last - first, counts[w]);
  };
  if (workers > 1)
    worker_pool().run(workers, count);
  else
    count(0);
  std::vector<std::uint64_t> block_photons(storage_.block_count(), 0);
  for (const std::vector<std::uint64_t>& part : counts)
    for (std::size_t b = 0; b < part.size(); ++b) block_photons[b] += part[b];
  for (std::size_t j = 0; j < sources; ++j) {
    if (!(source_weights_[j] > 0.0)) continue;
    const std::uint32_t block = block_of(j);
    if (block_photons[block] == 0) continue;
    const double per_photon = side_power[block] / static_cast<double>(block_photons[block]);
    const double* power = source_power(j);
    for (std::size_t ch = 0; ch < channels; ++ch)
      round_.photon_units[j][ch] = std::llround(power[ch] / source_weights_[j] * per_photon * round_.scale);
  }
  // What stays: the pool's entries of every side with power that no photon chose (kept_ stays
  // empty when nothing does).
  for (std::uint32_t block = 0; block < storage_.block_count(); ++block) {
    const std::uint32_t offset = storage_.block_offset(block);
    if (offset == SceneStorage::kNoBlock || block_photons[block] != 0 || !(side_power[block] > 0.0)) continue;
    if (view.emitted_light) return false;
    if (kept_.empty()) kept_.assign(pool.size(), 0.0);
    const std::size_t count_k = storage_.finest(block / 2).basis.size();
    for (std::size_t i = offset * channels; i < (offset + count_k) * channels; ++i) kept_[i] = pool[i];
  }
  return true;
}

void Solver::end_round(std::span<const Deposits> deposits) {
  const auto channels = static_cast<std::size_t>(channels_);
  RoundTotals totals;
  totals.deposits = deposits;
  totals.inverse_scale = 1.0 / round_.scale;
  totals.photons = round_.photons;
  totals.photons_shot = photons_shot_;
  totals.replicates = static_cast<std::size_t>(settings_.replicates);
  totals.kept = kept_;
  std::vector<std::int64_t> detected_units(shooter_.detector_layout().size, 0);
  for (const Deposits& d : deposits) {
    for (std::size_t ch = 0; ch < channels; ++ch) {
      totals.escaped[ch] += d.escaped[ch];
      totals.absorbed[ch] += d.absorbed[ch];
      totals.shot[ch] += d.shot[ch];
      for (std::size_t loss = 0; loss < kChainLosses; ++loss) totals.lost[loss][ch] += d.lost[loss][ch];
    }
    for (std::size_t i = 0; i < shooter_.detector_layout().size; ++i) detected_units[i] += d.detected[i];
    rays_traced_ += d.rays;
    chains_cut_ += d.chains_cut;
  }
  transport().end_round(storage_, totals, received_, received_parts_);
  if (shooter_.detector_layout().size > 0) {
    std::vector<double> round_detected(shooter_.detector_layout().size);
    const double unit = std::ldexp(totals.inverse_scale, kDetectorShift);
    for (std::size_t i = 0; i < shooter_.detector_layout().size; ++i)
      round_detected[i] = static_cast<double>(detected_units[i]) * unit;
    transport().add_tallies(detected_, round_detected, totals);
  }
  if (passes_photons_ > 0.0) mix_passes();
  if (auto_storage_)
    half_variance_factor_ = sum_odd_parts(passes_photons_ > 0.0 ? mixed_parts_ : received_parts_, received_half_);
  update_reflected(received(), received_half_, half_variance_factor_);
  ++rounds_;
  check_books();
}

void Solver::check_books() {
  // Always-on check of the books. Fixed-point quantisation moves at most half a unit per photon
  // and channel, 2^-61 of the round's power each (walks: 2^(H-61), H the headroom given up);
  // allow that plus double round-off.
  const EnergyBooks totals = books();
  const double allowed = emitted_total_ * (1e-12 + static_cast<double>(photons_shot_) * 3.0 *
                                                       std::ldexp(1.0, transport().most_headroom_bits() - 60));
  if (!(std::fabs(totals.imbalance()) <= allowed)) {
    char message[400];
    std::snprintf(message, sizeof message,
                  "energy books do not balance after round %u: emitted %.17g, absorbed %.17g, "
                  "escaped %.17g, unshot %.17g, absorbed by mirrors %.17g, in glass %.17g, cut %.17g",
                  rounds_, totals.emitted, totals.absorbed, totals.escaped, totals.unshot, totals.absorbed_mirrors,
                  totals.absorbed_glass, totals.cut);
    books_error_ = message;
    stop_reason_ = StopReason::BooksUnbalanced;
  }
}

void Solver::choose_final_levels() {
  if (auto_storage_ && (photons_at_choice_ != photons_shot_ || storage_.chosen_levels() != scheduled_level_))
    update_reflected(received(), received_half_, half_variance_factor_, LevelChoice::Final);
}

void Solver::update_reflected(const std::vector<double>& received, const std::vector<double>& received_half,
                              double variance_factor, LevelChoice choice) {
  if (auto_storage_) {
    const bool due = scheduled_level_.empty() ||
                     static_cast<double>(photons_shot_) >= kLevelChoiceGrowth * static_cast<double>(photons_at_choice_);
    if (choice == LevelChoice::View) {
      // A viewer asks after every piece (about 50 ms); choosing every level of every curve each
      // time cost a fifth of its solving thread's time.
      // Between choices the levels stay as the last choice left them (the solve's or the view's).
      const auto last = static_cast<double>(std::max(photons_at_view_choice_, photons_at_choice_));
      if (static_cast<double>(photons_shot_) >= kLevelChoiceGrowth * last) {
        storage_.choose_levels(received, received_half, variance_factor);
        photons_at_view_choice_ = photons_shot_;
      }
    } else if (choice == LevelChoice::Final || due) {
      storage_.choose_levels(received, received_half, variance_factor);
      scheduled_level_ = storage_.chosen_levels();
      photons_at_choice_ = photons_shot_;
    } else {
      storage_.set_chosen_levels(scheduled_level_);
    }
  }
  // Reflected radiosity coefficients, kept current for readers between rounds; run() has no
  // readers between its rounds and refreshes them once, when it returns.
  if (defer_readers_) {
    readers_stale_ = true;
    return;
  }
  refresh_readers(received);
}

void Solver::refresh_readers(const std::vector<double>& received) {
  readers_stale_ = false;
  readers_ = reflected_field(received, storage_.chosen_levels());
}

ReflectedField Solver::reflected_field(const std::vector<double>& received, const std::vector<int>& levels) const {
  const auto channels = static_cast<std::size_t>(channels_);
  ReflectedField field;
  if (settings_.basis == BasisKind::Hermite) {
    // Each channel's estimate at the curve's level, in that level's hats, times rho, interpolated.
    field.hermite.resize(storage_.block_count());
    for (std::uint32_t block = 0; block < storage_.block_count(); ++block) {
      const std::uint32_t offset = storage_.block_offset(block);
      if (offset == SceneStorage::kNoBlock) continue;
      const std::uint32_t c = block / 2;
      const Spectrum& rho = storage_.block_reflectivity(block);
      for (std::size_t ch = 0; ch < channels; ++ch) {
        std::vector<double> values =
            storage_.estimate_in_level(c, levels[c], &received[offset * channels + ch], channels);
        for (double& v : values) v *= rho[ch];
        field.hermite[block].push_back(storage_.hermite_of(c, levels[c], values.data()));
      }
    }
  }
  // The B-spline coefficients (Hermite storage keeps them too: its hats' estimate, for the
  // result's stored spline).
  storage_.estimate(received, field.coefficients, levels);
  for (std::uint32_t block = 0; block < storage_.block_count(); ++block) {
    const std::uint32_t offset = storage_.block_offset(block);
    if (offset == SceneStorage::kNoBlock) continue;
    const Spectrum& rho = storage_.block_reflectivity(block);
    for (std::size_t k = 0; k < storage_.finest(block / 2).basis.size(); ++k)
      for (std::size_t ch = 0; ch < channels; ++ch) field.coefficients[(offset + k) * channels + ch] *= rho[ch];
  }
  return field;
}

Spectrum Solver::reflected_at(const ReflectedField& field, std::uint32_t curve, Side side, double u) const {
  Spectrum result{};
  const std::uint32_t offset = storage_.block_offset(curve, side);
  if (offset == SceneStorage::kNoBlock) return result;
  const auto channels = static_cast<std::size_t>(channels_);
  if (settings_.basis == BasisKind::Hermite) {
    const std::vector<HermiteReconstruction>& per_channel = field.hermite[curve * 2 + static_cast<std::uint32_t>(side)];
    if (per_channel.empty()) return result;
    const double s = storage_.arc_length_at(curve, u);
    for (std::size_t ch = 0; ch < channels; ++ch) result[ch] = per_channel[ch].evaluate(s);
    return result;
  }
  const CurveStorage& storage = storage_.finest(curve);
  std::array<double, SplineBasis::kMaxDegree + 1> phi{};
  const std::size_t first = storage.basis.evaluate(u, phi.data());
  for (std::size_t ch = 0; ch < channels; ++ch)
    for (int j = 0; j <= storage.basis.degree(); ++j)
      result[ch] +=
          phi[static_cast<std::size_t>(j)] *
          field.coefficients[(offset + storage.basis.index(first + static_cast<std::size_t>(j))) * channels + ch];
  return result;
}

void Solver::update_hermite_unshot(const std::vector<double>& power) {
  const auto channels = static_cast<std::size_t>(channels_);
  for (std::uint32_t c = 0; c < scene_->curves.size(); ++c)
    for (Side side : {Side::Front, Side::Back}) {
      const std::uint32_t offset = storage_.block_offset(c, side);
      if (offset == SceneStorage::kNoBlock) continue;
      const std::uint32_t block = c * 2 + static_cast<std::uint32_t>(side);
      // Each channel's estimate at the chosen level, in that level's hats, summed over channels.
      std::vector<double> summed;
      for (std::size_t ch = 0; ch < channels; ++ch) {
        const std::vector<double> values =
            storage_.estimate_in_level(c, storage_.chosen_level(c), &power[offset * channels + ch], channels);
        summed.resize(values.size(), 0.0);
        for (std::size_t k = 0; k < summed.size(); ++k) summed[k] += values[k];
      }
      hermite_unshot_[block] = storage_.hermite_of(c, storage_.chosen_level(c), summed.data());
    }
}

void Solver::for_each_curve(const std::function<void(std::uint32_t)>& f) {
  // Each curve's work writes only that curve's coefficients, so the split changes no result.
  const std::vector<std::uint32_t>& chunks = storage_.curve_chunks();
  auto chunk = [&](std::size_t i) {
    for (std::uint32_t c = chunks[i]; c < chunks[i + 1]; ++c) f(c);
  };
  const std::size_t count = chunks.size() - 1;
  if (threads_ > 1 && count > 1) {
    worker_pool().for_each(count, chunk);
  } else {
    for (std::size_t i = 0; i < count; ++i) chunk(i);
  }
}

std::uint64_t Solver::step_photons(std::uint64_t max_photons, const std::atomic<bool>* cancel,
                                   std::vector<PhotonPath>* paths, std::size_t path_limit,
                                   const ProgressCallback& progress, double progress_interval) {
  if (stopped() || max_photons == 0) return 0;
  if (!round_open_) {
    if (!begin_round()) return 0;
    round_open_ = true;
    round_done_ = 0;
    round_deposits_.resize(threads_);
    for (Deposits& deposits : round_deposits_)
      deposits.reset(storage_.coefficient_count() * static_cast<std::size_t>(channels_ * settings_.replicates),
                     shooter_.detector_layout().size);
  }
  const Clock::time_point start = Clock::now();
  const std::uint64_t first = round_done_;
  // Shared rounds are shot whole: every process must reach the round's sum.
  const std::uint64_t last =
      sharing_ != nullptr ? round_.photons : first + std::min(max_photons, round_.photons - first);
  const std::uint64_t share_rank = sharing_ != nullptr ? sharing_->rank() : 0;
  const std::uint64_t share_size = sharing_ != nullptr ? sharing_->size() : 1;
  const std::uint64_t photons_before = photons_shot_;
  auto room = [&]() -> std::size_t {
    return paths != nullptr && paths->size() < path_limit ? path_limit - paths->size() : 0;
  };
  const RoundView round = round_view();
  auto shoot_here = [&](Rng& rng, std::uint64_t from, std::uint64_t count) {
    shooter_.shoot(round, rng, from, count, round_deposits_[0], room() > 0 ? paths : nullptr, path_limit);
  };
  std::uint64_t position = first;
  // The rest of a batch that an earlier step began, with the stream it left off.
  if (position % kBatchSize != 0) {
    const std::uint64_t end = std::min(last, (position / kBatchSize + 1) * kBatchSize);
    shoot_here(*partial_batch_rng_, position, end - position);
    position = end;
  }
  // Whole batches (the round's last, short one included), shared among the threads.
  const std::uint64_t whole_end = last == round_.photons ? last : last / kBatchSize * kBatchSize;
  if (whole_end > position || sharing_ != nullptr) {
    // Batch batch_begin + i * share_size + share_rank is this process's i-th.
    const std::uint64_t batch_begin = position / kBatchSize;
    const std::uint64_t all_batches = (whole_end - position + kBatchSize - 1) / kBatchSize;
    const std::uint64_t batches =
        all_batches > share_rank ? (all_batches - share_rank + share_size - 1) / share_size : 0;
    const unsigned workers = static_cast<unsigned>(std::min<std::uint64_t>(threads_, batches));
    const std::size_t path_room = room();
    const std::uint64_t path_batches = std::min<std::uint64_t>(batches, (path_room + kBatchSize - 1) / kBatchSize);
    std::vector<std::vector<PhotonPath>> batch_paths(path_batches);
    std::atomic<std::uint64_t> next_batch{0};
    std::atomic<std::uint64_t> photons_done{0};
    std::atomic<bool> aborted{false};
    auto work = [&](Deposits& acc, bool reports) {
      Clock::time_point last_report = Clock::now();
      for (;;) {
        if (cancel != nullptr && cancel->load(std::memory_order_relaxed)) {
          aborted.store(true);
          return;
        }
        const std::uint64_t i = next_batch.fetch_add(1);
        if (i >= batches) return;
        const std::uint64_t batch = batch_begin + i * share_size + share_rank;
        const std::uint64_t count = std::min(kBatchSize, round_.photons - batch * kBatchSize);
        std::vector<PhotonPath>* recorded = nullptr;
        std::size_t limit = 0;
        if (i < path_batches) {
          recorded = &batch_paths[i];
          limit = static_cast<std::size_t>(std::min<std::uint64_t>(count, path_room - i * kBatchSize));
          recorded->reserve(limit);
        }
        Rng rng(settings_.seed, rounds_, batch);
        shooter_.shoot(round, rng, batch * kBatchSize, count, acc, recorded, limit);
        photons_done.fetch_add(count, std::memory_order_relaxed);
        if (reports && progress && seconds_since(last_report) >= progress_interval) {
          last_report = Clock::now();
          SolverProgress p = this->progress();
          p.photons = photons_before + (position - first) + photons_done.load(std::memory_order_relaxed);
          p.seconds += seconds_since(start);
          progress(p);
        }
      }
    };
    worker_pool().run(workers, [&](unsigned w) { work(round_deposits_[w], w == 0); });
    if (sharing_ != nullptr) {
      const auto [all_done, any_aborted] = share_round(photons_done.load(), aborted.load());
      photons_done.store(all_done);
      aborted.store(any_aborted);
    }
    if (aborted.load()) {
      photons_cancelled_ = (position - first) + photons_done.load();
      seconds_ += seconds_since(start);
      stop_reason_ = StopReason::Cancelled;
      round_open_ = false;
      return 0;
    }
    if (paths != nullptr)
      for (std::vector<PhotonPath>& batch : batch_paths) paths->insert(paths->end(), batch.begin(), batch.end());
    position = whole_end;
  }
  // A batch begun here and finished by a later step keeps its stream.
  if (position < last) {
    partial_batch_rng_.emplace(settings_.seed, rounds_, position / kBatchSize);
    shoot_here(*partial_batch_rng_, position, last - position);
    position = last;
  }
  round_done_ = last;
  photons_shot_ += last - first;
  seconds_ += seconds_since(start);
  if (round_done_ == round_.photons) {
    round_open_ = false;
    partial_batch_rng_.reset();
    end_round(round_deposits_);
  }
  return last - first;
}

std::pair<std::uint64_t, bool> Solver::share_round(std::uint64_t photons_done, bool aborted) {
  Deposits& total = round_deposits_[0];
  for (std::size_t w = 1; w < round_deposits_.size(); ++w) {
    Deposits& acc = round_deposits_[w];
    for (std::size_t index = 0; index < total.received.size(); ++index) total.received[index] += acc.received[index];
    for (std::size_t ch = 0; ch < 3; ++ch) {
      total.escaped[ch] += acc.escaped[ch];
      total.absorbed[ch] += acc.absorbed[ch];
      total.shot[ch] += acc.shot[ch];
      for (std::size_t loss = 0; loss < kChainLosses; ++loss) total.lost[loss][ch] += acc.lost[loss][ch];
    }
    for (std::size_t i = 0; i < total.detected.size(); ++i) total.detected[i] += acc.detected[i];
    total.rays += acc.rays;
    total.chains_cut += acc.chains_cut;
    acc.reset(total.received.size(), total.detected.size());
  }
  // One message per round: the deposits and detectors' tallies, then the books' counters, chains
  // cut, rays, photons and the cancel.
  std::vector<std::int64_t> values(total.received);
  values.insert(values.end(), total.detected.begin(), total.detected.end());
  for (const std::array<std::int64_t, 3>* counters :
       {&total.escaped, &total.absorbed, &total.shot, &total.lost[0], &total.lost[1], &total.lost[2]})
    values.insert(values.end(), counters->begin(), counters->end());
  values.push_back(static_cast<std::int64_t>(total.chains_cut));
  values.push_back(static_cast<std::int64_t>(total.rays));
  values.push_back(static_cast<std::int64_t>(photons_done));
  values.push_back(aborted ? 1 : 0);
  sharing_->sum(values);
  ++rounds_shared_;
  std::size_t at = total.received.size();
  std::copy(values.begin(), values.begin() + static_cast<std::ptrdiff_t>(at), total.received.begin());
  for (std::int64_t& tally : total.detected) tally = values[at++];
  for (std::array<std::int64_t, 3>* counters :
       {&total.escaped, &total.absorbed, &total.shot, &total.lost[0], &total.lost[1], &total.lost[2]})
    for (std::int64_t& counter : *counters) counter = values[at++];
  total.chains_cut = static_cast<std::uint64_t>(values[at++]);
  total.rays = static_cast<std::uint64_t>(values[at++]);
  const auto all_done = static_cast<std::uint64_t>(values[at++]);
  return {all_done, values[at] != 0};
}

void Solver::include_open_round() {
  if (!round_open_) return;
  const double inverse_scale = 1.0 / round_.scale;
  std::vector<double> received = received_;
  std::vector<double> parts = received_parts_;
  std::vector<double> received_half = received_half_;
  const std::size_t size = received.size();
  const auto replicates = static_cast<std::size_t>(settings_.replicates);
  // The open round's power so far, all its photons and each replicate's.
  std::vector<double> open(size);
  std::vector<double> open_parts(replicates > 1 ? size * replicates : 0);
  for (std::size_t index = 0; index < size; ++index) {
    std::int64_t units = 0;
    for (std::size_t r = 0; r < replicates; ++r) {
      std::int64_t part = 0;
      for (const Deposits& deposits : round_deposits_) part += deposits.received[r * size + index];
      if (replicates > 1) open_parts[r * size + index] = static_cast<double>(part) * inverse_scale;
      units += part;
    }
    open[index] = static_cast<double>(units) * inverse_scale;
  }
  transport().add_open_round(received, parts, open, open_parts,
                             static_cast<double>(photons_shot_ - pass_first_photon_ - round_done_),
                             static_cast<double>(round_done_), static_cast<double>(round_.photons));
  if (passes_photons_ > 0.0) {
    // The current pass so far with the finished ones, each weighted by its photons.
    passes_mean(passes_received_, received, received);  // (element by element: in place is fine)
    passes_mean(passes_parts_, parts, parts);
  }
  const double variance_factor = auto_storage_ ? sum_odd_parts(parts, received_half) : 1.0;
  update_reflected(received, received_half, variance_factor, LevelChoice::View);
}

bool Solver::step_round(const std::atomic<bool>* cancel, const ProgressCallback& progress, double progress_interval) {
  if (stopped()) return false;
  std::vector<PhotonPath> paths;
  const std::uint64_t shot =
      step_photons(std::numeric_limits<std::uint64_t>::max(), cancel, &paths, path_limit_, progress, progress_interval);
  if (shot == 0) return false;
  paths_ = std::move(paths);
  if (progress) progress(this->progress());
  return true;
}

void Solver::run(const std::atomic<bool>* cancel, const ProgressCallback& progress, double progress_interval) {
  // Nobody reads the radiosity between run's rounds (its progress reports carry counts only), so
  // the reflected estimate, a solve per curve side and channel, is made once at the end instead
  // of after every round: from the same received power, so with the same result.
  defer_readers_ = true;
  while (step_round(cancel, progress, progress_interval)) {
  }
  defer_readers_ = false;
  if (readers_stale_) refresh_readers(received());
}

double Solver::pool_magnitude() const {
  if (!signed_pool_) return books().unshot;
  double magnitude = 0.0;
  for (double value : transport().unshot()) magnitude += std::fabs(value);
  return magnitude;
}

EnergyBooks Solver::books() const {
  EnergyBooks books;
  for (int ch = 0; ch < channels_; ++ch) books.emitted += emitted_[static_cast<std::size_t>(ch)];
  transport().add_books(books, channels_, rounds_ - pass_first_round_);
  if (passes_photons_ > 0.0) {
    // The finished passes and the current one, each weighted by its photons: each balances, and so
    // does their mean.
    const double n = static_cast<double>(photons_shot_ - pass_first_photon_);
    const double total = passes_photons_ + n;
    EnergyBooks mixed;
    mixed.emitted = books.emitted;
    mixed.add_outcomes(passes_books_, 1.0 / total);
    mixed.add_outcomes(books, n / total);
    books = mixed;
  }
  // The control variate's exact part (every pass's estimate holds it whole).
  for (int ch = 0; ch < channels_ && signed_pool_; ++ch) {
    books.absorbed += variate_absorbed_[static_cast<std::size_t>(ch)];
    books.escaped += variate_escaped_[static_cast<std::size_t>(ch)];
  }
  return books;
}

std::vector<double> Solver::detected() const {
  if (!(passes_photons_ > 0.0)) return detected_;
  std::vector<double> mixed;
  passes_mean(passes_detected_, detected_, mixed);
  return mixed;
}

std::vector<DetectorReading> Solver::detector_readings() const {
  const DetectorLayout& layout = shooter_.detector_layout();
  std::vector<DetectorReading> readings;
  if (layout.size == 0) return readings;
  const std::vector<double> tallies = detected();
  const auto channels = static_cast<std::size_t>(channels_);
  for (std::uint32_t c = 0; c < scene_->curves.size(); ++c) {
    if (layout.offsets[c] == kNoDetector) continue;
    DetectorReading& reading = readings.emplace_back();
    reading.curve = c;
    const std::uint32_t bins = scene_->material_of(scene_->curves[c]).detector_bins;
    for (const Side side : {Side::Front, Side::Back}) {
      std::vector<Spectrum>& out = side == Side::Front ? reading.front : reading.back;
      Spectrum& total = side == Side::Front ? reading.front_total : reading.back_total;
      const double* bin_tallies = tallies.data() + layout.offsets[c] + static_cast<std::size_t>(side) * bins * channels;
      for (std::uint32_t b = 0; b < bins; ++b) {
        Spectrum& value = out.emplace_back();
        for (std::size_t ch = 0; ch < channels; ++ch) {
          value[ch] = bin_tallies[b * channels + ch];
          total[ch] += value[ch];
        }
      }
    }
  }
  return readings;
}

SolverProgress Solver::progress() const {
  SolverProgress p;
  p.photons = photons_shot_;
  p.budget = settings_.photons;
  p.rounds = rounds_;
  p.unshot_fraction = books().unshot / emitted_total_;
  p.seconds = seconds_;
  return p;
}

std::vector<double> Solver::radiosity_coefficients(std::uint32_t curve, Side side) const {
  const std::uint32_t offset = storage_.block_offset(curve, side);
  if (offset == SceneStorage::kNoBlock) return {};
  const auto channels = static_cast<std::size_t>(channels_);
  const auto begin = readers_.coefficients.begin() + static_cast<std::ptrdiff_t>(offset * channels);
  return {begin, begin + static_cast<std::ptrdiff_t>(storage_.finest(curve).basis.size() * channels)};
}

std::vector<double> Solver::replicate_received(int replicate) const {
  if (settings_.replicates < 2) return {};
  // Replicate r's photons are a 1/R share of every round, drawn like the whole: R times its part
  // estimates the whole received power.
  const std::size_t size = received_.size();
  const std::vector<double>& parts = passes_photons_ > 0.0 ? mixed_parts_ : received_parts_;
  const auto begin = parts.begin() + static_cast<std::ptrdiff_t>(static_cast<std::size_t>(replicate) * size);
  std::vector<double> estimate(begin, begin + static_cast<std::ptrdiff_t>(size));
  for (double& value : estimate) value *= static_cast<double>(settings_.replicates);
  return estimate;
}

std::vector<double> Solver::unshot_coefficients(std::uint32_t curve, Side side) const {
  const std::uint32_t offset = storage_.block_offset(curve, side);
  if (offset == SceneStorage::kNoBlock) return {};
  const auto channels = static_cast<std::size_t>(channels_);
  std::vector<double> all;
  storage_.estimate(transport().unshot(), all);
  const auto begin = all.begin() + static_cast<std::ptrdiff_t>(offset * channels);
  return {begin, begin + static_cast<std::ptrdiff_t>(storage_.finest(curve).basis.size() * channels)};
}

Spectrum Solver::radiosity(std::uint32_t curve, Side side, double u) const {
  Spectrum result{};
  const std::uint32_t offset = storage_.block_offset(curve, side);
  if (offset == SceneStorage::kNoBlock) return result;
  const Spectrum reflected = reflected_at(readers_, curve, side, u);
  const Curve& c = scene_->curves[curve];
  for (std::size_t ch = 0; ch < static_cast<std::size_t>(channels_); ++ch)
    result[ch] = c.emittance[ch] * emittance_factor(c, u) + reflected[ch];
  return result;
}

}  // namespace flatland
