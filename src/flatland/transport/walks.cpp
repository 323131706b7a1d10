#include "flatland/transport/walks.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace flatland {

Result<RandomWalks> RandomWalks::create(const Scene& scene, std::vector<double> emission, WalkScore score) {
  // A walk goes on with probability max rho at every hit, so its number of rays is at most
  // geometric with mean 1 / (1 - max rho) over the scene's reflecting sides.
  double most = 0.0;
  double least_reflecting = 1.0;  // the least q of a side that reflects at all
  const Curve* brightest = nullptr;
  for (const Curve& curve : scene.curves) {
    double q = 0.0;
    for (std::size_t ch = 0; ch < static_cast<std::size_t>(scene.channels); ++ch) {
      q = std::max(q, scene.material_of(curve).reflectivity[ch]);
      if (scene.material_of(curve).reflectivity[ch] > most) {
        most = scene.material_of(curve).reflectivity[ch];
        brightest = &curve;
      }
    }
    if (q > 0.0) least_reflecting = std::min(least_reflecting, q);
  }
  if (most > kWalkMaxReflectivity) {
    char message[320];
    std::snprintf(message, sizeof message,
                  "%s: curve '%s' reflects %.9g: a random walk would average %.3g rays; "
                  "walks need every reflectivity at most %g (use transport shooting)",
                  scene.source.c_str(), brightest->id.c_str(), most, 1.0 / (1.0 - most), kWalkMaxReflectivity);
    return Error{message};
  }
  RandomWalks walks;
  walks.expected_rays_ = 1.0 / (1.0 - most);
  // The tallies' bound for the headroom: collision tallies at most the arriving power at each
  // hit; absorption tallies once, P / (1 - q) <= P / (1 - max rho), within the same bound as R
  // collision tallies; survival tallies P / q at each hit it goes on from (q held to at least
  // kSurvivalLeastChance), at most 1 / q times a collision tally.
  if (score == WalkScore::Survival) walks.largest_weight_ = 1.0 / std::max(least_reflecting, kSurvivalLeastChance);
  walks.nothing_.assign(emission.size(), 0.0);
  walks.emission_ = std::move(emission);
  return walks;
}

std::uint64_t RandomWalks::round_photons(double, std::uint64_t shot, std::uint64_t budget, std::uint32_t) const {
  return std::min({std::max(kMinWalksPerRound, shot / 2), kMaxWalksPerRound, budget - shot});
}

int RandomWalks::headroom_bits(std::uint64_t photons) {
  // A walk tallies its power at every hop, so a round of n walks deposits about n R times a
  // walk's power, R the mean rays per walk (at most expected_rays_): the scale gives up H bits,
  // 2^H >= R (1 + 64 / n), so the total stays below 2^63 unless the round's rays exceed
  // 4 R n + 256 R, which for a sum of n geometric counts is rarer than e^-60. With n <= 2^20 and
  // R <= 1e6 a walk still carries at least 2^18 units. The absorption score's one tally of at
  // most P R keeps within it; the survival score's tallies of up to 1 / q times the power give
  // up log2(1 / q) bits more (largest_weight_).
  const double rays = largest_weight_ * expected_rays_ * (1.0 + 64.0 / static_cast<double>(photons));
  // ceil(log2(rays)) from the binary exponent: rays = m 2^e, m in [1/2, 1).
  int exponent = 0;
  const double mantissa = std::frexp(rays, &exponent);
  const int bits = std::max(0, mantissa == 0.5 ? exponent - 1 : exponent);
  most_headroom_bits_ = std::max(most_headroom_bits_, bits);
  return bits;
}

void RandomWalks::end_round(const SceneStorage& storage, const RoundTotals& round, std::vector<double>& received,
                            std::vector<double>& parts) {
  // Each round's tallies estimate the whole received power (its walks carry all the emitted
  // power between them): the running estimate is their average weighted by walks. Power is
  // absorbed or escapes only where a walk's units end, so the books stay exact per round.
  const auto channels = static_cast<std::size_t>(storage.channels());
  // Each replicate's part is averaged the same way, so the parts keep summing to the whole.
  const std::size_t size = storage.coefficient_count() * channels;
  const bool split = round.replicates > 1;
  const double weight = static_cast<double>(round.photons) / static_cast<double>(round.photons_shot);
  for (std::size_t index = 0; index < size; ++index) {
    std::int64_t units = 0;
    for (std::size_t r = 0; r < round.replicates; ++r) {
      std::int64_t part = 0;
      for (const Deposits& deposits : round.deposits) part += deposits.received[r * size + index];
      if (split) {
        double& running = parts[r * size + index];
        running += weight * (static_cast<double>(part) * round.inverse_scale - running);
      }
      units += part;
    }
    received[index] += weight * (static_cast<double>(units) * round.inverse_scale - received[index]);
  }
  for (std::size_t ch = 0; ch < channels; ++ch) {
    escaped_[ch] += weight * (static_cast<double>(round.escaped[ch]) * round.inverse_scale - escaped_[ch]);
    absorbed_[ch] += weight * (static_cast<double>(round.absorbed[ch]) * round.inverse_scale - absorbed_[ch]);
    for (std::size_t loss = 0; loss < kChainLosses; ++loss)
      lost_[loss][ch] += weight * (static_cast<double>(round.lost[loss][ch]) * round.inverse_scale - lost_[loss][ch]);
  }
}

void RandomWalks::add_open_round(std::vector<double>& received, std::vector<double>& parts,
                                 const std::vector<double>& open, const std::vector<double>& open_parts, double before,
                                 double done, double photons) const {
  // The round's walks so far, each carrying 1/n of the emitted power, estimate done / n of the
  // received power; averaged with the finished rounds by walks.
  if (!(done > 0.0)) return;
  for (std::size_t index = 0; index < received.size(); ++index)
    received[index] = (before * received[index] + photons * open[index]) / (before + done);
  for (std::size_t index = 0; index < open_parts.size(); ++index)
    parts[index] = (before * parts[index] + photons * open_parts[index]) / (before + done);
}

void RandomWalks::add_tallies(std::vector<double>& running, const std::vector<double>& round_values,
                              const RoundTotals& round) {
  const double weight = static_cast<double>(round.photons) / static_cast<double>(round.photons_shot);
  for (std::size_t i = 0; i < running.size(); ++i) running[i] += weight * (round_values[i] - running[i]);
}

void RandomWalks::add_books(EnergyBooks& books, int channels, std::uint32_t rounds) const {
  for (int ch = 0; ch < channels; ++ch) {
    const auto c = static_cast<std::size_t>(ch);
    books.absorbed += absorbed_[c];
    books.escaped += escaped_[c];
    books.absorbed_mirrors += lost_[static_cast<std::size_t>(ChainLoss::Mirrors)][c];
    books.absorbed_glass += lost_[static_cast<std::size_t>(ChainLoss::Glass)][c];
    books.cut += lost_[static_cast<std::size_t>(ChainLoss::Limit)][c];
  }
  // Until a round has finished nothing is accounted for: the emitted power is still to go.
  if (rounds == 0) books.unshot = books.emitted;
}

}  // namespace flatland
