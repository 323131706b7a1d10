// The coarse control variate's answer (transport/control_variate.hpp) from a reference solve on
// coarse elements, and the one way to create a Solver whatever its settings ask of this layer.
#pragma once

#include <atomic>
#include <cstddef>
#include <memory>

#include "flatland/base/status.hpp"
#include "flatland/reference/reference.hpp"
#include "flatland/scene/scene.hpp"
#include "flatland/transport/control_variate.hpp"
#include "flatland/transport/solver.hpp"

namespace flatland {

// The most elements the coarse reference may have: its form factors take time that grows as the
// square of their number (a few seconds for 3,000 on two cores).
inline constexpr std::size_t kControlVariateMaxElements = 3000;

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

// Solver::create, with the coarse answer solved first when the settings ask for the control
// variate: what every front end calls.
Result<Solver> create_solver(const Scene& scene, const SolverSettings& settings,
                             const std::atomic<bool>* cancel = nullptr);

}  // namespace flatland
