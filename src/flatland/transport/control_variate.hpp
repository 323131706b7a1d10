// A coarse reference's answer as a control variate for progressive shooting (docs/method.md, "A
// coarse answer as control variate").
//
// With b_c the reference's answer on coarse constant elements and G = K b_c the irradiance it sends
// to a point (the reference's final gather without E and rho), C = E + rho G is known without
// photons, and B = C + B' with
//
//   B' = rho K (D + B'),   D = C - b_c = E + rho G - b_c,
//
// since B = E + rho K B and C - E = rho K b_c, for any b_c. So the received power starts at the
// projection of G (no photons) and the photons shoot D, signed and small where b_c is close to B, as
// the first round of reflected light, whose reflections follow as in plain shooting: the noise is
// that of the few per cent of the power that D carries. What differs from plain shooting's
// expectation is on the scale of the discretisation: G is gathered over chords (a 400th of the
// scene's size on curves: coarse_answer.cpp) and by quadrature, and the storage holds D (with value
// jumps at the coarse elements' ends) and later rounds' pools (lumped) as it holds any pool.
//
// Projections onto the storage's finest basis, per coefficient k of a side: g_k = integral(phi_k G
// ds) and d_k = e_k + rho g_k - integral(phi_k b_c ds), with e_k the emitted power the basis function
// starts with. Each knot span is cut at the coarse elements' ends (b_c is constant between them) and
// integrated by 8-point Gauss-Legendre in the curve parameter with the arc-length Jacobian; G is
// gathered only on sides that reflect (elsewhere rho G is zero and G is not needed).
//
// The coarse answer comes from the reference layer above this one (reference/coarse_answer.hpp,
// whose create_solver solves it and hands it to Solver::create): here it is an interface.
#pragma once

#include <array>
#include <atomic>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "flatland/base/status.hpp"
#include "flatland/scene/scene.hpp"
#include "flatland/transport/scene_storage.hpp"

namespace flatland {

// An answer b_c constant on coarse elements (chords of the curves' segments) and its transport.
class CoarseAnswer {
 public:
  virtual ~CoarseAnswer() = default;
  virtual std::size_t elements() const = 0;
  // The parameters t in [0, 1] of a segment's element ends, from its start to its end (its
  // elements' count + 1 of them), and its first element: element first + i lies between ends i and
  // i + 1.
  virtual std::vector<double> element_parameters(std::uint32_t segment) const = 0;
  virtual std::uint32_t first_element(std::uint32_t segment) const = 0;
  // b_c of an element's side (zero on a side that neither emits nor reflects).
  virtual Spectrum element_radiosity(std::uint32_t element, Side side) const = 0;
  // G = K b_c at a curve's side at curve parameter u: the irradiance the answer sends there (zero on
  // a side that reflects nothing, where it is not needed).
  virtual Spectrum irradiance(std::uint32_t curve, Side side, double u) const = 0;
  // The same gathered over a coarser model of the curves (the coarse elements' own chords): how far
  // irradiance() is from the transport on the true curves is estimated from the two.
  virtual Spectrum coarse_irradiance(std::uint32_t curve, Side side, double u) const = 0;
  // How much closer to the true curves irradiance()'s model is than coarse_irradiance()'s, in the
  // error (its chords' sagitta over theirs, h^2: the split's square).
  virtual double model_ratio() const = 0;
  // The answer's power over the emitted power (at least 1): how much the scene's interreflection
  // multiplies light, an error's later bounces included.
  virtual double amplification() const = 0;
  // What of the answer's light leaves the scene, per channel.
  virtual std::array<double, 3> escaped() const = 0;
  // The seconds its solve took.
  virtual double seconds() const = 0;
};

// What the scene must be for the coarse control variate: diffuse light only (no mirrors, glass or
// detectors: the photons' part would follow chains the coarse transport K b_c does not have in the
// same way), no spectra, and emitters that emit diffusely (D leaves diffusely, from the storage).
// The error names the scene and the first thing it has that is refused.
Status check_control_variate(const Scene& scene);

// The projection's Gauss points on a piece of a storage span inside one coarse element: 4 where
// the piece is shorter than this share of the element (in the segment's parameter), 8 elsewhere.
// Measured at 1e7 photons with the variate: the answers of 4 and 8 points everywhere differ by
// 2.5e-10 relative L2 on the closed ring profile (the same photons), and the set-up halves.
inline constexpr double kShortPiece = 1.0 / 8.0;

// Curve `curve`'s coefficients of g (`received`) and d (`source`), finest layout (per coefficient
// and channel), from `emission` (e_k, the same layout); with `coarse_received`, also g over the
// coarser model (coarse_irradiance). Writes only that curve's coefficients, so curves may be done on
// different threads. Once `cancel` is set it returns, the coefficients unfinished (the caller
// discards them).
void project_control_variate(const CoarseAnswer& coarse, const Scene& scene, const SceneStorage& storage,
                             std::uint32_t curve, const std::vector<double>& emission, std::vector<double>& received,
                             std::vector<double>& source, std::vector<double>* coarse_received = nullptr,
                             const std::atomic<bool>* cancel = nullptr);

}  // namespace flatland
