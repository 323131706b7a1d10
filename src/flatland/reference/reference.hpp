// A deterministic reference solution of the flatland radiosity equation (docs/reference.md):
//
//   B(x) = E(x) + rho(x) * integral G(x,y) B(y) ds_y,   G = cos(theta_x) cos(theta_y) / (2 r) V(x,y)
//
// 1. Every segment is flattened into chords of equal arc length (at most max_element_length; the
//    chord ends lie on the curve), cut first at contacts (find_contacts: another curve's end
//    point or corner on it, a crossing), so that no element straddles one. Each chord is a constant element with two
//    sides; the front normal is perp(chord direction). A side the scene names reflects (rho = the material's
//    reflectivity) and emits (the curve's emittance times the profile factor at the element's
//    arc-length midpoint); the other side absorbs and emits nothing.
// 2. Exact point-to-elements visibility by an angular sweep around the point (all elements are
//    occluders): F(x -> j) = (1/2) sum over the visible angular intervals of j of (sin b - sin a),
//    angles from the point's normal.
// 3. Element form factors F_ij = (1/L_i) integral over element i of F(x -> j) ds: pairs that every
//    Gauss-Legendre point of element i sees whole, and that lie wholly in front of each other,
//    take Hottel's crossed strings (exact, and it removes the log singularity of neighbours); the
//    others are integrated again with element i cut at the visibility events of the pair
//    (pair_form_factor), Gauss-Legendre on each piece.
// 4. (I - diag(rho) F) b = e per channel by restarted GMRES, until the residual r guarantees a
//    relative error of b below `tolerance`: |b - b*|_inf <= |r|_inf / (1 - q), q = max rho x row
//    sum of F (< 1 for rho < 1), so it converges, and knows its error, up to rho = 0.999 and beyond.
// 5. radiosity(curve, side, u) is a final gather at the true curve point with its true normal:
//    E(x) + rho(x) sum_j b_j F(x -> j), with the exact visibility of step 2. The point lies on
//    the curve, off its element's chord: where the curve is concave the directions between its
//    tangent and the chord ends see the arc itself, and are given to that element (so a uniform
//    enclosure gathers exactly E / (1 - rho), and the pointwise error stays O(h^2)).
//
// Emitters must be diffuse (Emission::Kind::Diffuse); other kinds are rejected with an error.
// Rows are computed independently (one thread per row at a time), so the result does not depend
// on the number of threads.
#pragma once

#include <array>
#include <atomic>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "flatland/base/status.hpp"
#include "flatland/base/vec2.hpp"
#include "flatland/results/metrics.hpp"
#include "flatland/scene/scene.hpp"

namespace flatland {

struct ReferenceSettings {
  double max_element_length = 0.0;  // 0: scene.scale / 400
  int quadrature = 8;               // Gauss-Legendre points per element for form factors, 1..64
  double tolerance = 1e-10;         // relative error (inf-norm) of the element solve
  int max_iterations = 100'000;     // Krylov steps (matrix-vector products) per channel
  unsigned threads = 0;             // 0: all hardware threads
  // Memory the form factors may take (0: default_memory_budget(), three quarters of the
  // machine's); a solve that would need more is refused with an error instead of failing to
  // allocate.
  std::size_t memory_limit = 0;
  // Set (by a signal handler, say) to stop the solve: it returns the error kReferenceCancelled
  // within a row of form factors or a Krylov step.
  const std::atomic<bool>* cancel = nullptr;
  // Called from the calling thread about every quarter second while form factors are computed
  // (the long part of a solve), with the rows done and the rows in all.
  std::function<void(std::size_t rows_done, std::size_t rows)> progress;
};

// At most this many elements: the form factors take time and memory that grow as the square of
// the element count (about 12 bytes per visible pair; 12,530 elements take 70 s and 1.7 GB on
// two cores for the default scene), so 40,000 elements would take about an hour and tens of GB.
inline constexpr std::size_t kMaxReferenceElements = 40'000;
// The message of the error a cancelled solve returns.
inline constexpr const char* kReferenceCancelled = "the reference solve was cancelled";

// Checks ranges; the message names the setting and the accepted range.
Status validate(const ReferenceSettings& settings);

inline constexpr std::uint32_t kNoElement = 0xffffffffu;

// A constant element: a chord of a segment.
struct ReferenceElement {
  Vec2 a;       // start (on the curve)
  Vec2 b;       // end (on the curve)
  Vec2 normal;  // front normal: perp(b - a) / |b - a|
  double length = 0.0;
  std::uint32_t curve = 0;
  std::uint32_t segment = 0;  // index into Scene::segments
  double u_mid = 0.0;         // curve parameter at the element's arc-length midpoint
  // The elements before and after it in its curve's chain (sharing the end point a, b exactly;
  // across joints, and across the closing point of a closed curve), or kNoElement at a chain end.
  std::uint32_t previous = kNoElement;
  std::uint32_t next = kNoElement;
  // Per side (Side::Front = 0, Side::Back = 1): reflectivity and emittance (zero on inactive sides).
  std::array<Spectrum, 2> reflectivity{};
  std::array<Spectrum, 2> emittance{};
};

// One visible piece of the scene seen from a point: element, the side of it that faces the point,
// and the point-to-element form factor (1/2) sum (sin b - sin a) over its visible intervals.
struct VisibleElement {
  std::uint32_t element = 0;
  Side side = Side::Front;
  double form_factor = 0.0;
  // The whole element lies in front of the point and no part of it is hidden.
  bool whole = false;
};

// F(x -> j) for every element j visible from x in the half-plane in front of `normal` (unit),
// with every element as an occluder. `self` (an element index, or kNoElement) is the element x
// lies on: it is not an occluder, but where x lies on the curve off the chord, at a concave place,
// the arc between x and the chord's ends is seen (directions between the tangent and the chord's
// ends); those directions go to `self`, and likewise for elements with an end point at x.
// Elements seen edge-on (x on their line) are skipped. Results are in increasing element order,
// one entry per (element, side).
std::vector<VisibleElement> visible_elements(const std::vector<ReferenceElement>& elements, Vec2 x, Vec2 normal,
                                             std::uint32_t self);

// The form factor F from (element i, side si) to (element j, side sj) of a pair that sees each
// other partly: (1/L_i) integral over i of F(x -> j), with every other element that meets the
// convex hull of i and j as an occluder. `split`: element i's parameter interval is cut at the
// visibility events (the lines through two points that bound what x sees of j: ends of j and
// occluder end points, and the line of j) and each piece takes `points` Gauss-Legendre points, as
// solve_reference does for every pair that some quadrature point does not see whole; otherwise
// one `points`-point rule over the whole element (the rule before the split, for comparison).
// `pieces`, if given, receives the number of pieces.
double pair_form_factor(const std::vector<ReferenceElement>& elements, std::uint32_t i, Side si, std::uint32_t j,
                        Side sj, int points, bool split = true, std::size_t* pieces = nullptr);

// The element with ends a and b: its length, and its front normal perp(b - a) / length.
ReferenceElement chord_element(Vec2 a, Vec2 b);

// Hottel's crossed strings for two straight segments that see each other whole:
// F_12 = (crossed - uncrossed) / (2 L_1), crossed = |a1 b2| + |b1 a2|, uncrossed = |a1 a2| + |b1 b2|
// (a's and b's chosen so that a1-a2 and b1-b2 do not cross). Returns F from segment 1 to 2.
double crossed_strings(Vec2 a1, Vec2 b1, Vec2 a2, Vec2 b2);

// One reflecting side of a flat mirror segment, as the reference sees it (reference.cpp,
// "Mirrors"): the elements in front of that side clipped to it, their mirror images (the first
// leg's occluders), and two blockers along the mirror's line outside the segment, so that a sweep
// from a point's image sees an element j exactly where light from j reaches the point by one
// reflection in the mirror.
struct ReferenceMirror {
  Vec2 origin;               // a point of the mirror's line (its first end)
  Vec2 normal;               // unit normal of the reflecting side
  double reflectance = 1.0;  // the same in every channel
  std::vector<ReferenceElement> elements;
  std::vector<std::uint32_t> real;      // per entry: the scene element it is (clipped), or kNoElement
  std::vector<std::uint32_t> image_of;  // per scene element: its image's entry, or kNoElement
};

class ReferenceSolution {
 public:
  // Radiosity leaving `side` of curve `curve` at curve parameter u (u = segment index + t): the
  // final gather E(x) + rho sum_j b_j F(x -> j) at the true curve point and normal. Zero on a
  // side that the scene does not name.
  Spectrum radiosity(std::uint32_t curve, Side side, double u) const;

  std::size_t elements() const { return elements_.size(); }
  const std::vector<ReferenceElement>& element_list() const { return elements_; }
  // Element radiosity b of element j's side (zero on inactive sides).
  Spectrum element_radiosity(std::uint32_t element, Side side) const;
  // What the final gather at (curve, side, u) sums: `seen` receives (patch, F(x -> patch)) for
  // every element side that x sees, directly and by one reflection in a flat mirror (patch =
  // 2 element + side, F times the mirror's reflectance for the latter); radiosity() is then
  // E(x) + rho(x) sum F b over `seen`. Empty on a side the scene does not name or that reflects
  // nothing.
  void gather_weights(std::uint32_t curve, Side side, double u,
                      std::vector<std::pair<std::uint32_t, double>>& seen) const;
  // The parameters t in [0, 1] of segment `segment`'s element boundaries, from its start to its
  // end (its elements' count + 1 of them), and its first element: element first + i lies between
  // boundaries i and i + 1 (what a quadrature over a curve needs to integrate b exactly).
  std::vector<double> element_parameters(std::uint32_t segment) const;
  std::uint32_t first_element(std::uint32_t segment) const { return segment_first_[segment]; }
  // Replaces the element radiosities (per channel, per patch 2 element + side; channels the
  // scene does not use may be empty): a final gather of another method's solution
  // (final_gather.hpp) feeds its own.
  void set_element_radiosity(std::array<std::vector<double>, 3> radiosity);
  // Form factor F from (element i, side si) to (element j, side sj): computed for reflecting
  // patches (rho > 0 in some channel) towards patches that reflect or emit; 0 otherwise.
  double form_factor(std::uint32_t i, Side si, std::uint32_t j, Side sj) const;
  // The sum over all receivers of F from (element i, side si), including absorbing ones (1 in a
  // closed enclosure); -1 if the row was not computed (a non-reflecting patch).
  double row_sum(std::uint32_t i, Side si) const;

  int iterations() const { return iterations_; }  // GMRES steps (largest over channels)
  double residual() const { return residual_; }   // relative residual |r|_inf / |b|_inf reached
  // The guaranteed relative error of the element solve: residual / (1 - q) (largest over
  // channels). It is the linear solve's error only, not the discretisation's.
  double error_bound() const { return error_bound_; }
  double form_factor_seconds() const { return form_factor_seconds_; }
  // Empty, or why the form factors ran on fewer threads than asked (WorkerPool::shortfall).
  const std::string& thread_shortfall() const { return thread_shortfall_; }
  double solve_seconds() const { return solve_seconds_; }
  const Scene& scene() const { return scene_; }

 private:
  friend Result<ReferenceSolution> solve_reference(const Scene& scene, const ReferenceSettings& settings);
  friend Result<ReferenceSolution> reference_elements(const Scene& scene, const ReferenceSettings& settings,
                                                      const std::string& subject, const std::string& advice);
  friend class ReferenceBuilder;  // solve_reference's steps (reference.cpp)
  Scene scene_;
  ReferenceSettings settings_;
  std::vector<ReferenceElement> elements_;
  // Flat mirrors' reflecting sides (one reflection each is followed).
  std::vector<ReferenceMirror> mirrors_;
  // Per segment: first element and count (elements of a segment are consecutive).
  std::vector<std::uint32_t> segment_first_;
  std::vector<std::uint32_t> segment_count_;
  // Element boundaries as arc lengths from each segment's start (segment_count_ + 1 per segment).
  std::vector<double> boundary_;
  // Rows of F for reflecting patches (sparse: receiving patch, value); patch = 2 element + side.
  std::vector<std::uint32_t> row_patch_;          // patch of each row
  std::vector<std::uint32_t> patch_row_;          // row of each patch, or kNoElement
  std::vector<std::size_t> row_begin_;            // CSR offsets (rows + 1)
  std::vector<std::uint32_t> column_;             // receiving patch
  std::vector<double> value_;                     // F
  std::vector<double> row_sums_;                  // including absorbing receivers
  std::array<std::vector<double>, 3> radiosity_;  // per channel, per patch
  int iterations_ = 0;
  double residual_ = 0.0;
  double error_bound_ = 0.0;
  double form_factor_seconds_ = 0.0;
  std::string thread_shortfall_;
  double solve_seconds_ = 0.0;
};

// The number of elements solve_reference makes of the scene with these settings (a double: it
// may be far beyond any integer type for a tiny element length).
double reference_element_count(const Scene& scene, const ReferenceSettings& settings);
// The same per segment (INFINITY on a segment that would have too many to count; a segment after it
// counts 0).
std::vector<double> reference_element_counts(const Scene& scene, const ReferenceSettings& settings);

Result<ReferenceSolution> solve_reference(const Scene& scene, const ReferenceSettings& settings);
// The reference's elements and mirrors without form factors or a solve (element radiosity b = e,
// the emittance): what a final gather of another solution needs. Refuses what solve_reference
// refuses; its messages name `subject` ("a final gather") and end with `advice`.
Result<ReferenceSolution> reference_elements(const Scene& scene, const ReferenceSettings& settings,
                                             const std::string& subject, const std::string& advice);

// The reference's own discretisation error, from references with elements of length h, 2h and 4h
// (each one flattens the curves anew, so the chords' departure from the curves is in it as much
// as the constant elements' and the quadrature's). With d1 = |R_2h - R_h| and d2 = |R_4h - R_2h|
// (relative norms over all output samples, as compare_results forms them), the error of R_h is
// e ~ C h^p with observed order p = log2(d2 / d1), and d1 = (2^p - 1) e, so e ~ d1 / (2^p - 1).
// Guards: p is clamped to [kMinimumOrder, kMaximumOrder]; when d1 is at round-off level the
// references agree to rounding at every resolution and d1 itself is the estimate (no order);
// when only d2 is, no order is observed and the lowest order is assumed (the largest estimate).
inline constexpr double kMinimumOrder = 0.5;
inline constexpr double kMaximumOrder = 4.0;
struct ReferenceErrorEstimate {
  ErrorNorms error;              // the estimated relative error of R_h (L1, L2, L-infinity)
  ErrorNorms fine_difference;    // R_2h against R_h (d1)
  ErrorNorms coarse_difference;  // R_4h against R_2h (d2)
  double observed_order = 0.0;   // log2(d2 / d1) of the L2 differences, unclamped (NaN: none)
  double order = 0.0;            // the order the estimate uses (NaN: differences at round-off)
  double round_off = 0.0;        // relative differences at or below this are round-off
  std::string note;              // why `order` is not `observed_order` (empty when it is)
};

// The estimate from the two differences; the L2 differences decide the order, whose factor
// 1 / (2^p - 1) then scales all three norms of d1.
ReferenceErrorEstimate estimate_from_differences(const ErrorNorms& fine, const ErrorNorms& coarse, double round_off);

// Solves at 2h and 4h (h = settings' element length; the settings' progress and cancel apply to
// both), samples them like `fine` (the samples of R_h, sample_radiosity with `samples` per curve)
// and estimates R_h's error. `starting(level)` is called before the solve at 2^level h (level 1,
// 2). Returns kReferenceCancelled when cancelled.
Result<ReferenceErrorEstimate> estimate_discretisation_error(const Scene& scene, const ReferenceSettings& settings,
                                                             int samples, const SampledResult& fine,
                                                             const std::function<void(int level)>& starting = {});

}  // namespace flatland
