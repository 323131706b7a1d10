#include "flatland/transport/shooting.hpp"

#include <algorithm>
#include <cmath>

#include "flatland/base/portable_math.hpp"

namespace flatland {

ProgressiveShooting::ProgressiveShooting(std::vector<double> emission, double emitted, double decay, double tolerance)
    : unshot_(std::move(emission)), emitted_(emitted), initial_ratio_(decay), tolerance_(tolerance) {}

std::uint64_t ProgressiveShooting::round_photons(double unshot, std::uint64_t shot, std::uint64_t budget,
                                                 std::uint32_t rounds) const {
  // Photons of (about) equal power in every round: this round gets the share of the remaining
  // budget that its power is of all the power still to be shot. With the observed decay ratio r
  // of the unshot power, that is about U / (1 - r) (the geometric tail; ignoring where the
  // tolerance cuts it off keeps a reserve, so the budget is never spent one round too early).
  // Every round shoots at least kMinPhotonsPerRound, so the rounds still needed to reach the
  // tolerance, K = ln(tolerance E / U) / ln r, each get that much set aside first; when the budget
  // cannot pay for them all, the solve ends with its budget spent and says how much is unshot.
  const std::uint64_t remaining = budget - shot;
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
  // Power shot this round leaves the pool (all of it but what the round kept); what was received
  // comes back as rho times itself. Each
  // replicate's part adds to its own running total (the parts sum to the received power).
  const auto channels = static_cast<std::size_t>(storage.channels());
  const std::size_t size = storage.coefficient_count() * channels;
  const bool split = round.replicates > 1;
  double previous_pool = 0.0;
  for (double value : unshot_) previous_pool += value;
  for (std::uint32_t block = 0; block < storage.block_count(); ++block) {
    const std::uint32_t offset = storage.block_offset(block);
    if (offset == SceneStorage::kNoBlock) continue;
    const Spectrum& rho = storage.block_reflectivity(block);
    const std::size_t count = storage.finest(block / 2).basis.size();
    for (std::size_t k = 0; k < count; ++k) {
      for (std::size_t ch = 0; ch < channels; ++ch) {
        const std::size_t index = (offset + k) * channels + ch;
        std::int64_t units = 0;
        for (std::size_t r = 0; r < round.replicates; ++r) {
          std::int64_t part = 0;
          for (const Deposits& deposits : round.deposits) part += deposits.received[r * size + index];
          if (split) parts[r * size + index] += static_cast<double>(part) * round.inverse_scale;
          units += part;
        }
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
  for (std::size_t index = 0; index < received.size(); ++index) received[index] += open[index];
  for (std::size_t index = 0; index < open_parts.size(); ++index) parts[index] += open_parts[index];
}

void ProgressiveShooting::add_tallies(std::vector<double>& running, const std::vector<double>& round_values,
                                      const RoundTotals&) const {
  for (std::size_t i = 0; i < running.size(); ++i) running[i] += round_values[i];
}

void ProgressiveShooting::add_books(EnergyBooks& books, int channels, std::uint32_t) const {
  for (int ch = 0; ch < channels; ++ch) {
    const auto c = static_cast<std::size_t>(ch);
    books.absorbed += absorbed_[c].value();
    books.escaped += escaped_[c].value();
    books.absorbed_mirrors += lost_[static_cast<std::size_t>(ChainLoss::Mirrors)][c].value();
    books.absorbed_glass += lost_[static_cast<std::size_t>(ChainLoss::Glass)][c].value();
    books.cut += lost_[static_cast<std::size_t>(ChainLoss::Limit)][c].value();
  }
  for (double value : unshot_) books.unshot += value;
}

}  // namespace flatland
