// The settings of a solve: what is stored where, how photons start and travel, how many, and
// the limits each setting must keep (checked by validate). options.hpp names them for the front
// ends.
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "flatland/base/status.hpp"
#include "flatland/scene/discontinuities.hpp"
#include "flatland/storage/spline_basis.hpp"
#include "flatland/transport/footprint.hpp"

namespace flatland {

// Where on a source photons start: uniformly in arc length (the constant radiosity assumption),
// or with density proportional to the reconstructed unshot radiosity (the paper's section 3.4).
enum class PositionSampling { Uniform, Reconstructed };
const char* to_string(PositionSampling sampling);

// How coefficients are estimated from deposits (storage/estimators.hpp): lumped
// (b_k = p_k / integral(phi_k ds), the paper's distance-weighted deposit: positive, but it puts each coefficient at its
// function's centroid, a bias of O(h^2) inside and O(h) at ends and discontinuity nodes), Galerkin (the L2 projection M
// b = p) or local (a least-variance local quasi-interpolant; Hermite: nodal values). Galerkin and local have bias
// O(h^(p+1)) up to ends and nodes and may dip below zero; the density that photon origins are drawn from is clamped at
// zero with its power kept. Auto (the default) is local for Hermite storage, whose interpolation wants nodal values
// (1.4-2x less error than Galerkin's hat projections on the five time-to-accuracy scenes, docs/method.md), and Galerkin
// for the B-splines (better than local on four of those five).
enum class Estimator { Lumped, Galerkin, Local, Auto };
const char* to_string(Estimator estimator);
// The estimator a solve with this storage uses: `estimator` itself unless it is Auto.
Estimator resolve_estimator(Estimator estimator, BasisKind basis);

enum class RayMode { Footprint, Band };
const char* to_string(RayMode mode);

// Where a photon's uniforms come from: independent pseudo-random numbers, or randomised
// quasi-Monte Carlo (an Owen-scrambled Sobol' point per photon, indexed by its number in the
// round; qmc.hpp and docs/method.md).
enum class SamplerKind { Random, Sobol };
const char* to_string(SamplerKind sampler);

// How light gets from the emitters to its last bounce (docs/method.md, "Progressive shooting" and "Random walks"):
// - Shooting: progressive rounds, each shooting the power the previous round reflected, one hop
//   per photon (the paper's method).
// - Walk: every photon is a random walk from an emitter that, at each hit, tallies the power it
//   carries as received there and goes on with probability max rho (Russian roulette) in a new
//   diffuse direction, its channels weighted by rho / max rho: the collision estimator. The same
//   storage and estimators turn its tallies into B = E + rho x received; a walk costs about
//   1 / (1 - rho) rays, and its whole journey can be shown.
// - Jacobi: shooting until the pool falls below the tolerance, then regular stochastic Jacobi
//   iterations, each shooting all the light the last iterate reflects and adding it to the first
//   round's direct light, averaged with the shooting's answer by the photons of their reflected
//   light (shooting.hpp; docs/method.md, "Averaged Jacobi iterations").
enum class Transport { Shooting, Walk, Jacobi };
const char* to_string(Transport transport);
// What a random walk tallies where it lands on a reflecting side (docs/method.md, "Random walks").
// With q the side's chance of going on (max rho), a walk arriving with power P tallies:
// - Collision: P at every landing, whatever happens next (the default).
// - Absorption: P / (1 - q) where the walk ends, nothing where it goes on: one tally per walk.
// - Survival: P / q where the walk goes on, nothing where it ends.
// Each landing's expected tally is P under all three, so they estimate the same received power;
// only the noise differs. On an element that a landing hits with a small chance p, the variance of
// its tally per walk is about p P^2 / (1 - q) by collision, 1 / (1 - q) times that by absorption
// and 1 / q times that by survival: collision is the least noisy, absorption comes near it where
// sides reflect little and survival where they reflect much. (In a closed grey room of one
// reflectivity the absorption score of the whole received power is exact: every walk ends there
// once, with weight 1 / (1 - q).)
enum class WalkScore { Collision, Absorption, Survival };
const char* to_string(WalkScore score);
// Survival's weight 1 / q is held to at most 1 / kSurvivalLeastChance: on a side whose q is
// smaller a survival-scored walk tallies as a collision-scored one (P, whatever happens next),
// which is as unbiased, and the fixed point gives up at most log2(1 / kSurvivalLeastChance) = 10
// bits for it (walks.cpp), where an unheld 1 / q of a nearly black side would take so many that a
// walk's few remaining units round its power away. (Absorption's weight 1 / (1 - q) is held to
// 1000 by the walks' refusal of rho > kWalkMaxReflectivity.)
inline constexpr double kSurvivalLeastChance = 1.0 / 1024.0;
// A walk's tally at a landing, as a multiple of the power that arrived: q the side's chance of
// going on (0 < q < 1 on a side walks deposit on), `goes_on` the roulette's outcome there.
inline double walk_score_weight(WalkScore score, double q, bool goes_on) {
  switch (score) {
    case WalkScore::Collision: return 1.0;
    case WalkScore::Absorption: return goes_on ? 0.0 : 1.0 / (1.0 - q);
    case WalkScore::Survival: return q < kSurvivalLeastChance ? 1.0 : goes_on ? 1.0 / q : 0.0;
  }
  return 1.0;
}
// What a result's samples of B are: the storage's own splines (None), or a final gather of them,
// one deterministic bounce over exactly what each sample sees (Samples; reference/final_gather.hpp,
// run by the front ends after the solve: the Solver itself does not read it), or Auto: a final
// gather wherever the scene allows one (diffuse light and flat mirrors) at a bounded cost, the
// storage's own B elsewhere.
enum class GatherMode { None, Samples, Auto };
const char* to_string(GatherMode gather);
// A control variate for progressive shooting (docs/method.md, "A coarse answer as control
// variate"): None, or Coarse: a deterministic reference solve on coarse constant elements (at most
// kControlVariateFraction of the scene's size long) gives b_c; its transport G = K b_c is added to
// the received power exactly, and the photons shoot only the signed difference D = E + rho G - b_c
// (with its reflections), which carries a few per cent of the emitted power. Auto: Coarse where the
// scene and the other settings allow it at a bounded cost, None elsewhere, saying why
// (reference/coarse_answer.hpp's create_solver decides; Solver::create alone runs Auto as Coarse
// when it is given a coarse answer and as None without one).
enum class ControlVariate { None, Coarse, Auto };
const char* to_string(ControlVariate variate);
inline constexpr double kControlVariateFraction = 1.0 / 50.0;
// Walks are refused where a side reflects more than this: a walk would average over 1000 rays,
// and a batch of 4096 walks (the unit between checks for a cancel) several seconds.
inline constexpr double kWalkMaxReflectivity = 0.999;

// SolverSettings::elements for storage that follows the photons (`--elements auto`): deposits
// land on a fine dyadic mesh, every coarser level's deposits follow exactly (the meshes nest), and
// after every round each curve takes the level with the least estimated error, bias (from the
// differences between levels) squared plus variance (from two independent halves of the photons).
// Hermite storage deposits on hats, which nest like any spline space: each level's Hermite curve
// is built on that level's nodes, and the level is chosen by those curves' error.
inline constexpr int kAutoElements = 0;
// The most storage elements a curve may be given, and the most photons one solve may shoot.
inline constexpr int kMaxElements = 1 << 16;
inline constexpr std::uint64_t kMaxPhotons = std::uint64_t{1} << 50;
// The most seeds a convergence study runs per method and budget.
inline constexpr int kMaxSeeds = 1000;
// Auto storage's levels: the coarsest has about kAutoBaseElements elements per curve (and at
// least one per segment), each next level halves every element, and each curve's finest stops
// where its share of the photon budget (by length among the reflecting curves) would put fewer than
// kAutoPhotonsPerElement photons on an element, or at kAutoMaxLevels levels.
inline constexpr int kAutoBaseElements = 4;
inline constexpr int kAutoMaxLevels = 11;
inline constexpr double kAutoPhotonsPerElement = 2048.0;
// ... but a small budget may go finer: up to kAutoSmallBudgetElements per curve while every
// element still gets kAutoSmallBudgetPhotonsPerElement photons. With 2048 photons an element alone,
// 1e4-3e5 photons left the curved room 4-32 elements a curve, and the level choice, wanting finer,
// could only take the finest (linear 9 % and Hermite 14 % at 1e5 photons, against 1.4 % and 2 %).
inline constexpr double kAutoSmallBudgetPhotonsPerElement = 128.0;
inline constexpr double kAutoSmallBudgetElements = 128.0;
// With footprint rays, auto storage refines a curve only while its longest element is at least
// this fraction of the ray's width: the footprint's spread smooths every deposit on that scale (its
// bias is O(width^2)), so finer elements would resolve nothing but cost time on every hit.
inline constexpr double kFootprintFinestElement = 0.25;
// The photons of every round are split into R replicates, each an unbiased estimate of the round
// on its own: the spread of the R estimates gives the error estimate (error_estimate.hpp) and,
// under automatic storage, the halves the levels are chosen by (the odd replicates against the
// even). How (ReplicateLayout, photon_shooter.cpp):
// - Independent: photon i is in replicate i mod R, and each replicate is a scrambled Sobol' net of
//   its own (or photons of the random sampler): the spread is an unbiased estimate of the variance,
//   but the answer is the mean of R nets of N / R points, which stratify less than one net of N.
// - Blocks: the round is one net, and replicate r is its block of consecutive photons
//   [r N / R, (r + 1) N / R): the answer keeps the whole net's stratification; the blocks are
//   stratified against each other, so their spread overstates the variance, and the estimate takes
//   off what the pairs of blocks show of it (error_estimate.cpp), conservatively.
// - Auto (the default): blocks where the coarse control variate runs, independent elsewhere
//   (Solver::create resolves it once the variate is chosen). Under the variate the photons carry
//   only a small correction, and the blocks' bound covers the true error as often as it says on
//   every scene measured while the answer keeps one net's accuracy; without it, the blocks' bound
//   fell short of its coverage on a smooth closed ring under the final gather, so independent
//   replicates stay (docs/estimated-error.md, "The default layout").
// 1 replicate (one net a round, no estimate) or an even number up to kMaxReplicates.
enum class ReplicateLayout { Independent, Blocks, Auto };
const char* to_string(ReplicateLayout layout);
// Laid out as blocks, the replicates are stratified against each other, so their spread, read as if
// they were independent, overstates the variance of their mean. With V(m) that variance read from the
// R / m groups of m neighbouring blocks as if independent, and a net's variance falling as n^-beta
// (beta = 1 for independent points, more where the net stratifies), V(2) / V(1) = 2^(1 - beta) = rho
// and the whole net's variance is V(1) rho^(log2 R). Given the summed squared deviations from their
// mean of the R blocks' estimates (`blocks`) and of the R / 2 pairs' (`pairs`), returns
// rho^(log2 R), rho held to [kFewestPairRatio, 1]; 1 where nothing is measured.
double stratification_factor(double blocks, double pairs, int replicates);
// The least rho believed: 2^(1 - beta) with beta = 3, the fastest a scrambled net's variance falls
// (as n^-3, up to logarithms, for smooth integrands).
inline constexpr double kFewestPairRatio = 0.25;
inline constexpr int kDefaultReplicates = 8;
inline constexpr int kMaxReplicates = 64;

struct SolverSettings {
  std::uint64_t photons = 1'000'000;  // total budget over all rounds
  std::uint64_t seed = 1;
  unsigned threads = 0;  // 0: all hardware threads
  BasisKind basis = BasisKind::Cubic;
  // Storage elements per curve (about; at least one per segment), or kAutoElements: each curve's
  // mesh chosen after every round from nested levels by the photons that landed there.
  int elements = kAutoElements;
  double tolerance = 1e-3;  // stop when unshot power < tolerance x emitted power
  PositionSampling sampling = PositionSampling::Reconstructed;
  DiscontinuityMode discontinuities = DiscontinuityMode::Auto;
  Estimator estimator = Estimator::Auto;  // Solver::settings() holds it resolved
  // Extended rays: width in scene units (0: point rays), energy profile across the width, and
  // how the width is realised: a footprint spread along the receiver around the centre ray's
  // hit, or a band of `band_rays` parallel sub-rays each traced on its own.
  double ray_width = 0.0;
  RayProfile ray_profile = RayProfile::Box;
  RayMode ray_mode = RayMode::Footprint;
  int band_rays = 8;
  // Replicates of every round (kDefaultReplicates above) and how they are laid out, and the
  // confidence of the estimated error's bound (error_estimate.hpp), in [0.5, 0.999].
  int replicates = kDefaultReplicates;
  ReplicateLayout replicate_layout = ReplicateLayout::Auto;
  double confidence = 0.95;
  // Solve to an accuracy (0: off): shoot until the estimated relative L1 error of B - E over the
  // scene (error_estimate.hpp) is at most this, with `photons` as the cap (Solver, "Passes").
  double target_error = 0.0;
  SamplerKind sampler = SamplerKind::Sobol;
  // With Transport::Walk, `photons` counts walks; `tolerance` is not used (a walk ends by itself),
  // and rays must be points or footprints (a band's sub-rays have no single place to go on from).
  Transport transport = Transport::Shooting;
  // What a walk tallies (Transport::Walk only; shooting refuses any score but collision).
  WalkScore walk_score = WalkScore::Collision;
  GatherMode gather = GatherMode::Auto;
  // Progressive shooting of what a coarse reference's answer leaves (ControlVariate::Coarse), of
  // all the light (None), or the first where it applies (Auto).
  ControlVariate control_variate = ControlVariate::Auto;
  // Importance (shooting only): the ids of the curves whose light matters most. Empty: none. Each
  // round's photons are shared among the curve sides by their unshot power times the side's
  // importance for those curves, found by a short solve of the adjoint scene (Solver,
  // "Importance"); the answer's expectation is the same everywhere, its noise lower on those
  // curves and higher elsewhere.
  std::vector<std::string> importance;
  // Memory the solver's storage may take (0: default_memory_budget(), three quarters of the
  // machine's); settings that would need more are refused by Solver::create before allocating.
  std::size_t memory_limit = 0;
};

// Whether the replicates are stratified against each other: blocks of one Sobol' net (the random
// sampler's blocks are independent photons).
bool replicates_stratified(const SolverSettings& settings);

// Checks ranges; the message names the setting and the accepted range.
Status validate(const SolverSettings& settings);

}  // namespace flatland
