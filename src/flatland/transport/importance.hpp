// Importance toward a region of interest (docs/method.md, "Importance"): how much of the power
// that leaves each curve side ends up arriving, after any number of bounces, on the region's
// curves.
//
// Adjoint: with F_jk the fraction of the power leaving side j that lands on side k, the
// importance of side j for the region R is W_j = sum_k F_jk (chi_R(k) + rho_k W_k). Diffuse
// exchange is reciprocal, L_j F_jk = L_k F_kj, so w_j = L_j W_j obeys
// w_j = sum_k F_kj (L_k chi_R(k) + rho_k w_k): the power that side j receives when the region's
// sides emit with an emittance of 1, everything else dark and the reflectivities unchanged. W_j is that
// received power per unit length (the adjoint's irradiance), found by a short Monte Carlo solve
// of the adjoint scene with constant storage.
//
// How the sources share a round (Solver::plan_important_sources): a photon from side j reaches the
// region with a chance of about W_j, carrying P_j / n_j of the side's unshot power P_j between its
// n_j photons, so the region's tally has a variance of about sum_j P_j^2 W_j / n_j. For N photons
// that is least (a Lagrange multiplier) with n_j proportional to P_j sqrt(W_j), where it is
// (sum_j P_j sqrt(W_j))^2 / N; sharing by power alone gives (sum_j P_j)(sum_j P_j W_j) / N, never
// less (Cauchy-Schwarz). Sharing by P_j W_j gives that same variance back: it helps only where W_j
// is zero. So each side's weight is sqrt(W_j), relative to the largest.
//
// The weight only has to be positive where power is: any such weighting leaves the answer's
// expectation unchanged, and a poor one costs only noise. So the adjoint is solved roughly, and
// the weight held to at least kImportanceFloor, which bounds how much rarer a side's photons
// become (and how much its noise grows).
#pragma once

#include <atomic>
#include <cstdint>
#include <vector>

#include "flatland/base/status.hpp"
#include "flatland/scene/scene.hpp"
#include "flatland/transport/settings.hpp"

namespace flatland {

inline constexpr double kImportanceFloor = 1.0 / 64.0;

// The curves `settings.importance` names, as indices; the error names an unknown id (and the
// likely one meant), a curve that keeps no diffuse light (a mirror, glass or detector) or one that
// reflects nothing (a black curve or an emitter of reflectivity 0: its B is exact).
Result<std::vector<std::uint32_t>> importance_curves(const Scene& scene, const SolverSettings& settings);

// The scene whose solution gives the importance of `region`: every emitter dark, the region's
// curves emitting diffusely, with a grey emittance of 1, from the sides they store; no spectra; sides
// that reflect nothing given a reflectivity of 1e-9 so that what they receive is tallied.
Scene adjoint_scene(const Scene& scene, const std::vector<std::uint32_t>& region);

// What the adjoint solve took.
struct ImportanceSolve {
  // Per block (curve * 2 + side; 0 where no storage): W over its largest value, and the weight
  // the Solver gives the side's sources, sqrt of that held to kImportanceFloor.
  std::vector<double> side_importance;
  std::vector<double> side_weight;
  std::uint64_t photons = 0;
  double seconds = 0.0;
};

// The importance of every curve side for `region`, from a solve of the adjoint scene with
// `photons` photons (the settings' seed, threads and memory limit; constant storage, one element a
// segment). Stops with kSolverCancelled when `cancel` is set.
Result<ImportanceSolve> solve_importance(const Scene& scene, const std::vector<std::uint32_t>& region,
                                         const SolverSettings& settings, std::uint64_t photons,
                                         const std::atomic<bool>* cancel);

// The adjoint solve's photons for a solve with `settings`: a sixteenth of its photons, within
// [2^14, 2^20]; 2^14 when it solves to a target error (its photons are then only a cap).
std::uint64_t importance_photons(const SolverSettings& settings);

}  // namespace flatland
