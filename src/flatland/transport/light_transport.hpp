// How light gets from the emitters to its last bounce, round by round (docs/method.md,
// "Progressive shooting" and "Random walks"): what a round's photons leave with, how many a round shoots, what its
// deposits mean for the received power, and the energy books. Every transport shoots its photons with the same
// PhotonShooter; a transport whose photons go on from where they land (random walks) says so.
//
// A new transport is a class of its own file that implements this interface and an alternative
// of the Solver's variant (solver.hpp); the two below are
//   ProgressiveShooting (shooting.hpp): rounds of one hop each, shooting what the last reflected
//   (and, for Transport::Jacobi, then averaged regular iterations);
//   RandomWalks (walks.hpp): every photon a whole walk from an emitter, ended by Russian roulette.
#pragma once

#include <array>
#include <cstdint>
#include <span>
#include <vector>

#include "flatland/transport/photon_shooter.hpp"
#include "flatland/transport/scene_storage.hpp"

namespace flatland {

// Power summed over channels. emitted = absorbed + escaped + unshot + what ended in specular
// chains (absorbed by mirrors, absorbed in glass, cut at the chain limit) after every round.
struct EnergyBooks {
  double emitted = 0.0;
  double absorbed = 0.0;
  double escaped = 0.0;
  double unshot = 0.0;
  double absorbed_mirrors = 0.0;
  double absorbed_glass = 0.0;
  double cut = 0.0;
  double imbalance() const { return emitted - (absorbed + escaped + unshot + absorbed_mirrors + absorbed_glass + cut); }
  // Adds `weight` times every outcome of `other` (all but emitted): for weighted means of books.
  void add_outcomes(const EnergyBooks& other, double weight) {
    absorbed += weight * other.absorbed;
    escaped += weight * other.escaped;
    unshot += weight * other.unshot;
    absorbed_mirrors += weight * other.absorbed_mirrors;
    absorbed_glass += weight * other.absorbed_glass;
    cut += weight * other.cut;
  }
};

// A finished round as a transport reads it: its deposits per thread (per replicate, coefficient and
// channel, in fixed-point units), its escaped and absorbed units per channel, and the power of one
// unit.
struct RoundTotals {
  std::span<const Deposits> deposits;
  std::array<std::int64_t, 3> escaped{};
  std::array<std::int64_t, 3> absorbed{};
  std::array<std::array<std::int64_t, 3>, kChainLosses> lost{};  // by ChainLoss
  std::array<std::int64_t, 3> shot{};                            // the photons' units as they left
  double inverse_scale = 0.0;
  std::uint64_t photons = 0;       // of this round
  std::uint64_t photons_shot = 0;  // of the solve, this round's included
  std::size_t replicates = 1;      // parts of the deposits, each coefficients x channels long
  // Importance: the pool's power that no photon of the round took (its curve side drew none), per
  // coefficient and channel; it stays in the pool. Empty: every side with power was shot.
  std::span<const double> kept;
};

// Entry `index` (of `size` per replicate) of the round's deposits: its units summed over the
// threads and replicates; with `parts` (more than one replicate), each replicate's power added to
// parts[r * size + index].
inline std::int64_t round_units(const RoundTotals& round, std::size_t size, std::size_t index,
                                std::vector<double>* parts) {
  std::int64_t units = 0;
  for (std::size_t r = 0; r < round.replicates; ++r) {
    std::int64_t part = 0;
    for (const Deposits& deposits : round.deposits) part += deposits.received[r * size + index];
    if (parts != nullptr) (*parts)[r * size + index] += static_cast<double>(part) * round.inverse_scale;
    units += part;
  }
  return units;
}

class LightTransport {
 public:
  virtual ~LightTransport() = default;

  // Whether a photon goes on from where it lands (a walk), whether the photons of round `round`
  // carry light straight from the emitters, and the bounce their first flights record.
  virtual bool photons_go_on() const = 0;
  virtual bool emitted_light(std::uint32_t round) const = 0;
  virtual std::uint32_t bounce(std::uint32_t round) const = 0;

  // The power per coefficient and channel that the next round's photons leave with, and the power
  // still waiting to be shot (shooting's pool; zero for walks, which start afresh every round).
  virtual const std::vector<double>& pool() const = 0;
  virtual const std::vector<double>& unshot() const = 0;
  // Whether no round is needed any more with `pool_power` in the pool.
  virtual bool converged(double pool_power) const = 0;
  // The photons of the next round, `shot` of the `budget` shot in `rounds` rounds.
  virtual std::uint64_t round_photons(double pool_power, std::uint64_t shot, std::uint64_t budget,
                                      std::uint32_t rounds) const = 0;
  // Bits of the fixed point's scale a round of `photons` gives up so that its deposits fit.
  virtual int headroom_bits(std::uint64_t photons) = 0;
  // The books' rounding allowance in bits: each photon's fixed-point power rounds by at most
  // half a unit, 2^(this - 61) of the emitted power (the most bits any round gave up, or by which a
  // round's pool exceeded the emitted power).
  virtual int most_headroom_bits() const = 0;

  // A finished round into the received power and, with more than one replicate, each replicate's
  // part of it (`parts`, replicate r's at [r * size + index]: the parts sum to `received`), and
  // into the books.
  virtual void end_round(const SceneStorage& storage, const RoundTotals& round, std::vector<double>& received,
                         std::vector<double>& parts) = 0;
  // The open round's power so far (per coefficient and channel; `open_parts` each replicate's part
  // of it, empty with one replicate) into copies of the received power and its parts, as a reader
  // sees the light arrive: `done` of the round's `photons` shot, after `before` in finished rounds.
  virtual void add_open_round(std::vector<double>& received, std::vector<double>& parts,
                              const std::vector<double>& open, const std::vector<double>& open_parts, double before,
                              double done, double photons) const = 0;
  // A finished round's tallies (power per entry, e.g. the detectors') into their running values
  // as the received power is (shooting: summed over rounds; walks and iterations: averaged),
  // called after end_round for the same round.
  virtual void add_tallies(std::vector<double>& running, const std::vector<double>& round_values,
                           const RoundTotals& round) = 0;
  // Adds the absorbed, escaped and unshot power to `books` (emitted already in it).
  virtual void add_books(EnergyBooks& books, int channels, std::uint32_t rounds) const = 0;
};

}  // namespace flatland
