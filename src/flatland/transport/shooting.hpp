// Progressive shooting, the paper's transport: each round shoots the power that the last round's
// deposits reflected (the first round the emitted power), one hop a photon, until what is left
// falls below the tolerance or the budget is spent.
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include "flatland/base/summation.hpp"
#include "flatland/transport/light_transport.hpp"

namespace flatland {

class ProgressiveShooting final : public LightTransport {
 public:
  // Every round shoots at least this many photons (or what is left of the budget): a round of a
  // few photons estimates the pool so coarsely that one photon landing on an absorber could empty
  // it and stop the solve as "converged" far from the answer (as in a room of rho = 0.9999999 with a
  // black lamp). Not a whole batch (4096): the reserve for the rounds still expected would starve
  // the first rounds of small budgets (docs/method.md, Progressive shooting).
  static constexpr std::uint64_t kMinPhotonsPerRound = 256;
  // And at most this many: the fixed-point deposits quantise each photon's power to 2^-60 of the
  // round's power (half a unit per deposit), so a round of n photons rounds each photon's power
  // by at most n 2^-61 of itself; 2^30 photons keep that below 5e-10.
  static constexpr std::uint64_t kMaxPhotonsPerRound = std::uint64_t{1} << 30;

  ProgressiveShooting() = default;
  // Starts from `emission` (power per coefficient and channel), `emitted` in all; `decay` is the
  // first guess of the pool's decay per round (the reflecting sides' mean reflectivity).
  ProgressiveShooting(std::vector<double> emission, double emitted, double decay, double tolerance);

  bool photons_go_on() const override { return false; }
  bool emitted_light(std::uint32_t round) const override { return round == 0; }
  std::uint32_t bounce(std::uint32_t round) const override { return round; }
  const std::vector<double>& pool() const override { return unshot_; }
  const std::vector<double>& unshot() const override { return unshot_; }
  bool converged(double pool_power) const override { return !(pool_power > tolerance_ * emitted_); }
  std::uint64_t round_photons(double pool_power, std::uint64_t shot, std::uint64_t budget,
                              std::uint32_t rounds) const override;
  int headroom_bits(std::uint64_t) override { return 0; }
  int most_headroom_bits() const override { return 0; }
  void end_round(const SceneStorage& storage, const RoundTotals& round, std::vector<double>& received,
                 std::vector<double>& parts) override;
  void add_open_round(std::vector<double>& received, std::vector<double>& parts, const std::vector<double>& open,
                      const std::vector<double>& open_parts, double before, double done, double photons) const override;
  void add_tallies(std::vector<double>& running, const std::vector<double>& round_values,
                   const RoundTotals& round) const override;
  void add_books(EnergyBooks& books, int channels, std::uint32_t rounds) const override;

 private:
  std::vector<double> unshot_;                // the pool, per coefficient and channel
  std::array<CompensatedSum, 3> absorbed_{};  // over all rounds
  std::array<CompensatedSum, 3> escaped_{};
  std::array<std::array<CompensatedSum, 3>, kChainLosses> lost_{};  // by ChainLoss
  double emitted_ = 0.0;
  double initial_ratio_ = 0.5;
  double previous_unshot_ = 0.0;
  double tolerance_ = 1e-3;
};

}  // namespace flatland
