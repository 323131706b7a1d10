// The coarse control variate's answer (transport/control_variate.hpp) from a reference solve on
// coarse elements, and the one way to create a Solver whatever its settings ask of this layer.
#pragma once

#include <atomic>
#include <cstddef>
#include <memory>
#include <string>

#include "flatland/base/status.hpp"
#include "flatland/reference/reference.hpp"
#include "flatland/scene/scene.hpp"
#include "flatland/transport/control_variate.hpp"
#include "flatland/transport/solver.hpp"

namespace flatland {

// The most elements the coarse reference may have: its form factors take time that grows as the
// square of their number (a few seconds for 3,000 on two cores).
inline constexpr std::size_t kControlVariateMaxElements = 3000;

// --control-variate auto's bound on the variate's set-up, in point-chord pairs: the projection
// visits 8 Gauss points on every storage span (4 on spans short against their coarse element,
// kShortPiece) and sweeps, at each, the chords G is gathered over
// and the coarse chords (its error part). Measured on the curved room (2 cores): about 2e-8 s a
// pair, so that kAutoControlVariateWork is about two seconds (the final gather's auto budget), and
// kAutoControlVariateWorkPerPhoton times the photons about three times their own time (2e-7 s a
// photon at 5 M photons/s); auto spends the larger. The variate lowers the error 20- to 4,000-fold
// (docs/family.md), so that a set-up of three times the photons' time still gains a hundredfold
// in efficiency.
inline constexpr double kAutoControlVariateWork = 1e8;
// A pair of coarse elements' form factor and its share of the GMRES, in projection pairs' time:
// 2.5e-7 s on two cores (the row of rooms at 603 elements: 0.089 s of form factors), 12 pairs.
inline constexpr double kCoarsePairWork = 15.0;
inline constexpr double kAutoControlVariateWorkPerPhoton = 30.0;

// The coarse reference's settings for `scene`: elements at most kControlVariateFraction of its size.
ReferenceSettings coarse_reference_settings(const Scene& scene, unsigned threads, const std::atomic<bool>* cancel);

// The reference solved on coarse elements, as a CoarseAnswer. Refuses what check_control_variate
// refuses, and more than kControlVariateMaxElements elements; a cancel gives kSolverCancelled's
// error.
Result<std::shared_ptr<const CoarseAnswer>> solve_coarse_answer(const Scene& scene, unsigned threads,
                                                                const std::atomic<bool>* cancel);

// What create_solver would refuse of `settings` on `scene` before any work: Solver::check_settings_on,
// and with the control variate, a coarse reference of more than kControlVariateMaxElements.
Status check_solver_settings(const Scene& scene, const SolverSettings& settings);

// The variate's set-up for `settings` on `scene`, in point-chord pairs: those its projection would
// sweep (from the storage's coefficient bound and the coarse nodes it adds) and its coarse
// reference's element pairs, weighted by kCoarsePairWork.
double control_variate_work(const Scene& scene, const SolverSettings& settings);

// Why --control-variate auto solves `scene` with `settings` without the variate: the settings or
// the scene it refuses (its refusal, by name), or a set-up above both kAutoControlVariateWork and
// kAutoControlVariateWorkPerPhoton times the photons, or above kControlVariateMaxElements. Empty where auto uses it.
std::string control_variate_auto_skip(const Scene& scene, const SolverSettings& settings);

// Solver::create, with the coarse answer solved first when the settings ask for the control
// variate (coarse, or auto where control_variate_auto_skip is empty; otherwise the solver keeps the
// reason in control_variate_skipped()): what every front end calls.
Result<Solver> create_solver(const Scene& scene, const SolverSettings& settings,
                             const std::atomic<bool>* cancel = nullptr);

}  // namespace flatland
