// Random walks: every photon is a walk from an emitter that, at each hit, goes on with
// probability max rho (Russian roulette) in a new diffuse direction, its channels weighted by
// rho / max rho, and tallies by its score (WalkScore, settings.hpp): the power it carries at every
// hit (collision), or that power reweighted where it ends (absorption) or goes on (survival).
// Every round's tallies estimate the whole received power; the solve averages them.
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include "flatland/base/status.hpp"
#include "flatland/scene/scene.hpp"
#include "flatland/transport/light_transport.hpp"
#include "flatland/transport/settings.hpp"

namespace flatland {

class RandomWalks final : public LightTransport {
 public:
  // Walks per round: growing with the walks done (so the level choices and a viewer's picture
  // follow), at most kMaxWalksPerRound.
  static constexpr std::uint64_t kMinWalksPerRound = 16384;
  static constexpr std::uint64_t kMaxWalksPerRound = std::uint64_t{1} << 20;

  RandomWalks() = default;
  // Walks of `scene` starting from `emission` (power per coefficient and channel), tallied by
  // `score`. Refused where a side reflects more than kWalkMaxReflectivity: a walk would average
  // over 1000 rays.
  static Result<RandomWalks> create(const Scene& scene, std::vector<double> emission,
                                    WalkScore score = WalkScore::Collision);

  bool photons_go_on() const override { return true; }
  bool emitted_light(std::uint32_t) const override { return true; }
  std::uint32_t bounce(std::uint32_t) const override { return 0; }
  const std::vector<double>& pool() const override { return emission_; }
  const std::vector<double>& unshot() const override { return nothing_; }
  bool converged(double) const override { return false; }
  std::uint64_t round_photons(double pool_power, std::uint64_t shot, std::uint64_t budget,
                              std::uint32_t rounds) const override;
  int headroom_bits(std::uint64_t photons) override;
  int most_headroom_bits() const override { return most_headroom_bits_; }
  void end_round(const SceneStorage& storage, const RoundTotals& round, std::vector<double>& received,
                 std::vector<double>& parts) override;
  void add_open_round(std::vector<double>& received, std::vector<double>& parts, const std::vector<double>& open,
                      const std::vector<double>& open_parts, double before, double done, double photons) const override;
  void add_tallies(std::vector<double>& running, const std::vector<double>& round_values,
                   const RoundTotals& round) override;
  void add_books(EnergyBooks& books, int channels, std::uint32_t rounds) const override;

 private:
  std::vector<double> emission_;  // where every round's walks start, per coefficient and channel
  std::vector<double> nothing_;   // nothing waits to be shot: zeros, laid out as emission_
  double expected_rays_ = 1.0;    // an upper bound on a walk's mean number of rays
  double largest_weight_ = 1.0;   // the largest multiple of its power one tally may be (survival: 1 / q)
  int most_headroom_bits_ = 0;
  // Absorbed and escaped power per channel, averaged over rounds as the received power is.
  std::array<double, 3> absorbed_{};
  std::array<double, 3> escaped_{};
  std::array<std::array<double, 3>, kChainLosses> lost_{};  // by ChainLoss
};

}  // namespace flatland
