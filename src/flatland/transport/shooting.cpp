#include "flatland/transport/shooting.hpp"

#include <algorithm>
#include <cmath>

#include "flatland/base/portable_math.hpp"

namespace flatland {

namespace {

// `to` = rho `from` on every reflecting side's coefficients (zero elsewhere); adds (1 - rho) `from`
// per channel to `absorbed` and returns the sum of `to`.
double reflect(const SceneStorage& storage, const std::vector<double>& from, std::vector<double>& to,
               std::array<double, 3>& absorbed) {
  const auto channels = static_cast<std::size_t>(storage.channels());
  to.assign(from.size(), 0.0);
  double reflected_sum = 0.0;
  for (std::uint32_t block = 0; block < storage.block_count(); ++block) {
    const std::uint32_t offset = storage.block_offset(block);
    if (offset == SceneStorage::kNoBlock) continue;
    const Spectrum& rho = storage.block_reflectivity(block);
    const std::size_t count = storage.finest(block / 2).basis.size();
    for (std::size_t k = 0; k < count; ++k)
      for (std::size_t ch = 0; ch < channels; ++ch) {
        const std::size_t index = (offset + k) * channels + ch;
        to[index] = rho[ch] * from[index];
        absorbed[ch] += from[index] - to[index];
        reflected_sum += to[index];
      }
  }
  return reflected_sum;
}

double sum_of(const std::vector<double>& values) {
  double sum = 0.0;
  for (double value : values) sum += value;
  return sum;
}

// The bits by which `pool` exceeds `emitted` (0 when it does not): a round's fixed point has
// units of 2^(ilogb(pool) - 60), and each photon's power rounds by at most half a unit.
int pool_bits(double pool, double emitted) {
  if (!(pool > emitted)) return 0;
  return std::ilogb(pool) - std::ilogb(emitted) + 1;
}

}  // namespace

ProgressiveShooting::ProgressiveShooting(std::vector<double> emission, double emitted, double decay, double tolerance,
                                         std::uint64_t averaged_budget, bool difference)
    : unshot_(std::move(emission)),
      emitted_(emitted),
      initial_ratio_(decay),
      tolerance_(tolerance),
      budget_(averaged_budget),
      increment_budget_(averaged_budget),
      difference_(difference) {}

std::uint64_t ProgressiveShooting::round_photons(double unshot, std::uint64_t shot, std::uint64_t budget,
                                                 std::uint32_t rounds) const {
  // The first round, the emitted light's, is planned as shooting plans it (the same photons).
  if (budget_ == 0 || rounds == 0) return incremental_photons(unshot, shot, budget, rounds);
  if (!regular_) return incremental_photons(unshot, shot, std::min(budget, increment_budget_), rounds);
  // An iteration (one round) takes a quarter of the photons shot on reflected light before it, and
  // at least a sixteenth of the budget after the first round (where the iterations begin right
  // after it, so that they are about six, not many small ones) and kMinPhotonsPerIteration; the
  // last one takes all that is left.
  const std::uint64_t reflected_budget = budget_ - std::min(budget_, direct_photons_);
  std::uint64_t photons = std::max({kMinPhotonsPerIteration, (shot - direct_photons_) / 4, reflected_budget / 16});
  const std::uint64_t left = budget - std::min(budget, shot);
  if (photons + photons / 2 > left) photons = left;
  return std::min({photons, kMaxPhotonsPerRound});
}

std::uint64_t ProgressiveShooting::incremental_photons(double unshot, std::uint64_t shot, std::uint64_t budget,
                                                       std::uint32_t rounds) const {
  // Photons of (about) equal power in every round: this round gets the share of the remaining
  // budget that its power is of all the power still to be shot. With the observed decay ratio r
  // of the unshot power, that is about U / (1 - r) (the geometric tail; ignoring where the
  // tolerance cuts it off keeps a reserve, so the budget is never spent one round too early).
  // Every round shoots at least kMinPhotonsPerRound, so the rounds still needed to reach the
  // tolerance, K = ln(tolerance E / U) / ln r, each get that much set aside first; when the budget
  // cannot pay for them all, the solve ends with its budget spent and says how much is unshot.
  const std::uint64_t remaining = budget - std::min(budget, shot);
  const double ratio = std::clamp(rounds == 0 ? initial_ratio_ : unshot / previous_unshot_, 0.0, 0.999999);
  const double target = tolerance_ * emitted_;
  double later_rounds = 0.0;
  if (ratio > 0.0 && unshot > target)
    later_rounds = std::clamp(std::ceil(portable::log(target / unshot) / portable::log(ratio)) - 1.0, 0.0, 1e15);
  const double reserve = later_rounds * static_cast<double>(kMinPhotonsPerRound);
  const double available = std::max(0.0, static_cast<double>(remaining) - reserve);
  auto photons = static_cast<std::uint64_t>(std::llround(available * (1.0 - ratio)));
  photons = std::max(photons, std::min(remaining, kMinPhotonsPerRound));
  return std::min({photons, remaining, kMaxPhotonsPerRound});
}

void ProgressiveShooting::end_round(const SceneStorage& storage, const RoundTotals& round,
                                    std::vector<double>& received, std::vector<double>& parts) {
  shot_ += round.photons;
  if (regular_) {
    end_iteration_round(storage, round, received, parts);
    ++rounds_;
    return;
  }
  end_increment(storage, round, received, parts);
  ended_ = Ended::Increment;
  ++rounds_;
  if (budget_ == 0) return;
  if (rounds_ == 1) {
    // The first round's deposits are the direct light D that every iterate starts from (received
    // was empty before it); the later increments get a quarter of the photons left.
    direct_ = received;
    direct_photons_ = shot_;
    direct_parts_ = round.replicates > 1 ? parts : std::vector<double>{};
    direct_books_ = Books{};
    add_round(direct_books_, round);
    // (Where nothing reflects there is nothing to iterate: the increments take the whole budget, as
    // shooting's do.)
    if (initial_ratio_ > 0.0)
      increment_budget_ =
          std::min(budget_, shot_ + std::max((budget_ - std::min(budget_, shot_)) / 4, kMinPhotonsPerRound));
  }
  // The iterations begin once the pool is below the tolerance, so that r_0 lacks at most the
  // tolerance's share of the light (each iteration only shrinks the shortfall by rho), and while
  // an iteration's photons are left. Until then the increments' share of the budget doubles
  // whenever they are about to spend it (before a last round of a few photons, which would shoot
  // the whole pool); with the budget spent first, the answer is shooting's.
  if (!(sum_of(unshot_) > tolerance_ * emitted_)) {
    if (budget_ - std::min(budget_, shot_) >= kMinPhotonsPerIteration) begin_iterations(storage, received);
  } else if (shot_ + kMinPhotonsPerRound > increment_budget_) {
    // (Their share, not counting the first round's photons, doubles.)
    increment_budget_ = std::min(budget_, 2 * increment_budget_ - direct_photons_);
  }
}

void ProgressiveShooting::begin_iterations(const SceneStorage& storage, const std::vector<double>& received) {
  // The shooting's answer and books are the average's first entry, weighted by the photons of its
  // reflected light (below).
  Books first;
  for (std::size_t ch = 0; ch < 3; ++ch) {
    first.absorbed[ch] = absorbed_[ch].value();
    first.escaped[ch] = escaped_[ch].value();
    for (std::size_t loss = 0; loss < kChainLosses; ++loss) first.lost[loss][ch] = lost_[loss][ch].value();
  }
  first.unshot = sum_of(unshot_);
  std::vector<double> reflected;
  std::array<double, 3> ignored{};
  if (!(reflect(storage, received, reflected, ignored) > 0.0)) return;
  mean_books_ = first;
  unshot_ = std::move(reflected);  // the first iteration reflects the shooting's answer
  largest_pool_bits_ = std::max(largest_pool_bits_, pool_bits(sum_of(unshot_), emitted_));
  nothing_.assign(unshot_.size(), 0.0);
  regular_ = true;
  // Every entry of the average holds the same D: each is weighted by the photons of its reflected
  // light (the increments after the first round, for r_0).
  averaged_photons_ = static_cast<double>(shot_ - direct_photons_);
}

void ProgressiveShooting::end_iteration_round(const SceneStorage& storage, const RoundTotals& round,
                                              std::vector<double>& received, std::vector<double>& parts) {
  // An iteration's round shoots all that iterate j - 1 reflects (its deposits R_j); the iterate is
  // r_j = D + R_j, and it joins the average.
  const auto channels = static_cast<std::size_t>(storage.channels());
  const std::size_t size = storage.coefficient_count() * channels;
  const bool split = round.replicates > 1;
  iterate_ = direct_;
  iterate_parts_ = split ? direct_parts_ : std::vector<double>{};
  iterate_books_ = direct_books_;
  iterate_books_.unshot = -sum_of(unshot_);  // what this round shot
  for (std::size_t index = 0; index < size; ++index) {
    const std::int64_t units = round_units(round, size, index, split ? &iterate_parts_ : nullptr);
    iterate_[index] += static_cast<double>(units) * round.inverse_scale;
  }
  add_round(iterate_books_, round);
  // The iterate's books: rho r_j waits (the next iteration shoots it), (1 - rho) r_j is absorbed.
  iterate_books_.unshot += reflect(storage, iterate_, unshot_, iterate_books_.absorbed);
  largest_pool_bits_ = std::max(largest_pool_bits_, pool_bits(sum_of(unshot_), emitted_));
  // It joins the average, weighted by its round's photons.
  const auto photons = static_cast<double>(round.photons);
  averaged_photons_ += photons;
  last_weight_ = photons / averaged_photons_;
  const double w = last_weight_;
  for (std::size_t index = 0; index < size; ++index) received[index] += w * (iterate_[index] - received[index]);
  if (split)
    for (std::size_t index = 0; index < parts.size(); ++index)
      parts[index] += w * (iterate_parts_[index] - parts[index]);
  for (std::size_t ch = 0; ch < 3; ++ch) {
    mean_books_.absorbed[ch] += w * (iterate_books_.absorbed[ch] - mean_books_.absorbed[ch]);
    mean_books_.escaped[ch] += w * (iterate_books_.escaped[ch] - mean_books_.escaped[ch]);
    for (std::size_t loss = 0; loss < kChainLosses; ++loss)
      mean_books_.lost[loss][ch] += w * (iterate_books_.lost[loss][ch] - mean_books_.lost[loss][ch]);
  }
  mean_books_.unshot += w * (iterate_books_.unshot - mean_books_.unshot);
  ended_ = Ended::IterationDone;
  ++iterations_;
}

void ProgressiveShooting::add_round(Books& books, const RoundTotals& round) {
  for (std::size_t ch = 0; ch < 3; ++ch) {
    books.escaped[ch] += static_cast<double>(round.escaped[ch]) * round.inverse_scale;
    books.absorbed[ch] += static_cast<double>(round.absorbed[ch]) * round.inverse_scale;
    for (std::size_t loss = 0; loss < kChainLosses; ++loss)
      books.lost[loss][ch] += static_cast<double>(round.lost[loss][ch]) * round.inverse_scale;
  }
}

void ProgressiveShooting::end_increment(const SceneStorage& storage, const RoundTotals& round,
                                        std::vector<double>& received, std::vector<double>& parts) {
  // Power shot this round leaves the pool (all of it but what the round kept); what was received
  // comes back as rho times itself. Each
  // replicate's part adds to its own running total (the parts sum to the received power).
  const auto channels = static_cast<std::size_t>(storage.channels());
  const std::size_t size = storage.coefficient_count() * channels;
  const bool split = round.replicates > 1;
  double previous_pool = 0.0;
  for (double value : unshot_) previous_pool += difference_ ? std::fabs(value) : value;
  if (difference_) {
    // A signed pool's photons each carry the same magnitude with their source's signs, so what they
    // carried, the units they left with, is the pool's power (less what the round kept) only in
    // expectation: the books hold the difference as unshot.
    double held = 0.0;
    for (double value : unshot_) held += value;
    for (double value : round.kept) held -= value;
    double carried = 0.0;
    for (std::size_t ch = 0; ch < channels; ++ch) carried += static_cast<double>(round.shot[ch]) * round.inverse_scale;
    sampling_residual_.add(held - carried);
  }
  for (std::uint32_t block = 0; block < storage.block_count(); ++block) {
    const std::uint32_t offset = storage.block_offset(block);
    if (offset == SceneStorage::kNoBlock) continue;
    const Spectrum& rho = storage.block_reflectivity(block);
    const std::size_t count = storage.finest(block / 2).basis.size();
    for (std::size_t k = 0; k < count; ++k) {
      for (std::size_t ch = 0; ch < channels; ++ch) {
        const std::size_t index = (offset + k) * channels + ch;
        const std::int64_t units = round_units(round, size, index, split ? &parts : nullptr);
        const double power = static_cast<double>(units) * round.inverse_scale;
        received[index] += power;
        const double reflected = rho[ch] * power;
        absorbed_[ch].add(power - reflected);
        unshot_[index] = round.kept.empty() ? reflected : reflected + round.kept[index];
      }
    }
  }
  for (std::size_t ch = 0; ch < channels; ++ch) {
    escaped_[ch].add(static_cast<double>(round.escaped[ch]) * round.inverse_scale);
    absorbed_[ch].add(static_cast<double>(round.absorbed[ch]) * round.inverse_scale);
    for (std::size_t loss = 0; loss < kChainLosses; ++loss)
      lost_[loss][ch].add(static_cast<double>(round.lost[loss][ch]) * round.inverse_scale);
  }
  previous_unshot_ = previous_pool;
}

void ProgressiveShooting::add_open_round(std::vector<double>& received, std::vector<double>& parts,
                                         const std::vector<double>& open, const std::vector<double>& open_parts, double,
                                         double, double) const {
  // An iteration joins the average when it is finished: until then a reader sees the average.
  if (regular_) return;
  for (std::size_t index = 0; index < received.size(); ++index) received[index] += open[index];
  for (std::size_t index = 0; index < open_parts.size(); ++index) parts[index] += open_parts[index];
}

void ProgressiveShooting::add_tallies(std::vector<double>& running, const std::vector<double>& round_values,
                                      const RoundTotals&) {
  // As the received power: summed over the increments (the first round's kept as the direct
  // light's), then averaged with each finished iterate, the direct light's and its round's.
  switch (ended_) {
    case Ended::Increment:
      for (std::size_t i = 0; i < running.size(); ++i) running[i] += round_values[i];
      if (budget_ > 0 && rounds_ == 1) direct_tallies_ = round_values;
      break;
    case Ended::IterationDone:
      for (std::size_t i = 0; i < running.size(); ++i)
        running[i] += last_weight_ * (direct_tallies_[i] + round_values[i] - running[i]);
      break;
  }
}

void ProgressiveShooting::add_books(EnergyBooks& books, int channels, std::uint32_t) const {
  if (regular_) {
    for (std::size_t ch = 0; ch < static_cast<std::size_t>(channels); ++ch) {
      books.absorbed += mean_books_.absorbed[ch];
      books.escaped += mean_books_.escaped[ch];
      books.absorbed_mirrors += mean_books_.lost[static_cast<std::size_t>(ChainLoss::Mirrors)][ch];
      books.absorbed_glass += mean_books_.lost[static_cast<std::size_t>(ChainLoss::Glass)][ch];
      books.cut += mean_books_.lost[static_cast<std::size_t>(ChainLoss::Limit)][ch];
    }
    books.unshot += mean_books_.unshot;
    return;
  }
  for (int ch = 0; ch < channels; ++ch) {
    const auto c = static_cast<std::size_t>(ch);
    books.absorbed += absorbed_[c].value();
    books.escaped += escaped_[c].value();
    books.absorbed_mirrors += lost_[static_cast<std::size_t>(ChainLoss::Mirrors)][c].value();
    books.absorbed_glass += lost_[static_cast<std::size_t>(ChainLoss::Glass)][c].value();
    books.cut += lost_[static_cast<std::size_t>(ChainLoss::Limit)][c].value();
  }
  for (double value : unshot_) books.unshot += value;
  if (difference_) books.unshot += sampling_residual_.value();
}

}  // namespace flatland
