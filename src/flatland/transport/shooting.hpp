// Progressive shooting, the paper's transport: each round shoots the power that the last round's
// deposits reflected (the first round the emitted power), one hop a photon, until what is left
// falls below the tolerance or the budget is spent.
//
// Averaged Jacobi iterations (Transport::Jacobi) begin the same way: the first round, the emitted
// light's, is planned for the whole budget as shooting plans it (its deposits D are shooting's bit
// for bit), the later increments for a quarter of what is left (more while they need it). Once the
// pool is below the tolerance come regular iterations: each is one round of all the light the last
// iterate reflects (deposits R_j), and iterate j's received power is r_j = D + R_j, with
// E[r_j | r_(j-1), D] = D + K rho r_(j-1), the deterministic Jacobi step from D. The shooting's
// answer r_0 and every finished iterate are averaged, each weighted by the photons that estimated
// its reflected light (r_0's: the increments after the first round): given D each
// iterate's expectation moves towards the solution for D, whose expectation is the solution, so
// the average is unbiased (up to the tolerance's share left in r_0), and the reflected light's
// noise is that of all the iterations' photons instead of the increments' frozen in. The direct
// light D is estimated once, by the one net of the first round.
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

  // Regular iterations take at least this many photons each, and each at least a quarter of the
  // photons shot on reflected light before it (so that the budget after the first round has about
  // log(4) / log(1.25), 6, of them) and a sixteenth of that budget.
  static constexpr std::uint64_t kMinPhotonsPerIteration = 4 * kMinPhotonsPerRound;

  ProgressiveShooting() = default;
  // Starts from `emission` (power per coefficient and channel), `emitted` in all; `decay` is the
  // first guess of the pool's decay per round (the reflecting sides' mean reflectivity).
  // `averaged_budget`: the photons of the solve (or pass) for averaged Jacobi iterations; 0 for
  // shooting alone.
  // `difference`: the pool is a control variate's signed difference D (control_variate.hpp), shot
  // diffusely from the storage from the first round on (no round of emitted light), its power the
  // sum of magnitudes.
  ProgressiveShooting(std::vector<double> emission, double emitted, double decay, double tolerance,
                      std::uint64_t averaged_budget = 0, bool difference = false);

  bool photons_go_on() const override { return false; }
  // The emitted light is shot once, in the first round; an iteration is one round of reflected light.
  bool emitted_light(std::uint32_t round) const override { return round == 0 && !difference_; }
  std::uint32_t bounce(std::uint32_t round) const override { return regular_ ? 1 : round; }
  const std::vector<double>& pool() const override { return unshot_; }
  // Iterations leave nothing waiting: each shoots all the light its iterate reflects.
  const std::vector<double>& unshot() const override { return regular_ ? nothing_ : unshot_; }
  // Increments stop at the tolerance (with iterations to follow, they begin instead); an iteration
  // stops only where there is nothing to shoot.
  bool converged(double pool_power) const override {
    return regular_ ? !(pool_power > 0.0) : !(pool_power > tolerance_ * emitted_);
  }
  std::uint64_t round_photons(double pool_power, std::uint64_t shot, std::uint64_t budget,
                              std::uint32_t rounds) const override;
  int headroom_bits(std::uint64_t) override { return 0; }
  // The books' rounding allowance is per photon a fraction of the emitted power; an iteration's
  // round shoots up to rho / (1 - rho) times that (all the reflected light), so it gives the bits
  // by which its largest pool exceeds the emitted power.
  int most_headroom_bits() const override { return largest_pool_bits_; }
  void end_round(const SceneStorage& storage, const RoundTotals& round, std::vector<double>& received,
                 std::vector<double>& parts) override;
  void add_open_round(std::vector<double>& received, std::vector<double>& parts, const std::vector<double>& open,
                      const std::vector<double>& open_parts, double before, double done, double photons) const override;
  void add_tallies(std::vector<double>& running, const std::vector<double>& round_values,
                   const RoundTotals& round) override;
  void add_books(EnergyBooks& books, int channels, std::uint32_t rounds) const override;

  // The iterations finished and averaged into the answer (always 0 for shooting alone).
  std::uint32_t iterations() const { return iterations_; }

 private:
  // The books of one estimate per channel: absorbed (on reflecting sides and elsewhere), escaped,
  // lost in chains, and (channels summed) unshot; for iterations, unshot is rho times the iterate's
  // received power less what its round shot (each iterate's books balance exactly).
  struct Books {
    std::array<double, 3> absorbed{}, escaped{};
    std::array<std::array<double, 3>, kChainLosses> lost{};
    double unshot = 0.0;
  };
  enum class Ended { Increment, IterationDone };
  void end_increment(const SceneStorage& storage, const RoundTotals& round, std::vector<double>& received,
                     std::vector<double>& parts);
  void end_iteration_round(const SceneStorage& storage, const RoundTotals& round, std::vector<double>& received,
                           std::vector<double>& parts);
  void begin_iterations(const SceneStorage& storage, const std::vector<double>& received);
  // Adds a round's escaped, absorbed elsewhere and lost power to `books`.
  static void add_round(Books& books, const RoundTotals& round);
  std::uint64_t incremental_photons(double pool_power, std::uint64_t shot, std::uint64_t budget,
                                    std::uint32_t rounds) const;

  std::vector<double> unshot_;                // the pool, per coefficient and channel
  std::array<CompensatedSum, 3> absorbed_{};  // over all rounds
  std::array<CompensatedSum, 3> escaped_{};
  std::array<std::array<CompensatedSum, 3>, kChainLosses> lost_{};  // by ChainLoss
  double emitted_ = 0.0;
  double initial_ratio_ = 0.5;
  double previous_unshot_ = 0.0;
  double tolerance_ = 1e-3;
  // Averaged Jacobi iterations (all unused when budget_ is 0).
  std::uint64_t budget_ = 0;  // photons of the solve or pass
  // The photons the increments may shoot in all, the first round's included (the share of the
  // rest doubled while they need more).
  std::uint64_t increment_budget_ = 0;
  std::uint64_t shot_ = 0;        // photons of the finished rounds
  std::uint32_t iterations_ = 0;  // finished iterations
  int largest_pool_bits_ = 0;     // most_headroom_bits
  std::uint32_t rounds_ = 0;      // finished rounds
  bool regular_ = false;          // the iterations have begun
  bool difference_ = false;       // the pool is a control variate's signed difference
  // A signed pool's rounds: what the pools held less what their photons carried (end_increment),
  // zero in expectation; the books count it as unshot.
  CompensatedSum sampling_residual_;
  std::vector<double> nothing_;  // unshot() during the iterations: zeros
  // The first round's deposits D (the emitted light's, per coefficient and channel), each
  // replicate's part of them, the detectors' tallies and that round's books (absorbed elsewhere,
  // escaped, lost): every iterate starts from them.
  std::vector<double> direct_;
  std::uint64_t direct_photons_ = 0;  // the first round's photons
  std::vector<double> direct_parts_;
  std::vector<double> direct_tallies_;
  Books direct_books_;
  std::vector<double> iterate_;        // the open iteration's received power, per coefficient and channel
  std::vector<double> iterate_parts_;  // and each replicate's part of it
  Books iterate_books_;                // the open iteration's books
  Books mean_books_;                   // the average's books
  double averaged_photons_ = 0.0;      // photons behind the average
  double last_weight_ = 0.0;           // the finished iteration's weight in the average
  Ended ended_ = Ended::Increment;     // what the last end_round finished
};

}  // namespace flatland
