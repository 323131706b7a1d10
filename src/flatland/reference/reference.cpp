#include "flatland/reference/reference.hpp"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <numbers>
#include <string>
#include <thread>

#include "flatland/base/quadrature.hpp"
#include "flatland/base/resources.hpp"
#include "flatland/base/workers.hpp"
#include "flatland/reference/form_factors.hpp"
#include "flatland/results/result_io.hpp"
#include "flatland/results/sampled_result.hpp"
#include "flatland/scene/discontinuities.hpp"

namespace flatland {

namespace {

std::size_t patch_index(std::uint32_t element, Side side) {
  return 2 * static_cast<std::size_t>(element) + static_cast<std::size_t>(side);
}

bool any_positive(const Spectrum& s, int channels) {
  for (int c = 0; c < channels; ++c)
    if (s[static_cast<std::size_t>(c)] > 0.0) return true;
  return false;
}

using reference_detail::gather_by_mirror;
using reference_detail::mirrored_point;
using reference_detail::PairQuadrature;
using reference_detail::Sweeper;

// Whether element j lies wholly in the closed half-plane in front of `side` of element i.
bool in_front_of(const ReferenceElement& i, Side side, const ReferenceElement& j) {
  const Vec2 n = side == Side::Front ? i.normal : -i.normal;
  const double tolerance = 1e-12 * (i.length + j.length);
  return dot(j.a - i.a, n) >= -tolerance && dot(j.b - i.a, n) >= -tolerance;
}

unsigned thread_count(unsigned requested) {
  if (requested != 0) return requested;
  return std::max(1u, std::thread::hardware_concurrency());
}

double seconds_since(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

// Restarted GMRES (Saad and Schultz 1986) for A x = rhs, x holding the first guess. Each cycle
// builds an orthonormal Krylov basis v_0 = r / |r|, v_(j+1) ~ A v_j - sum_i h_ij v_i (modified
// Gram-Schmidt, done twice: the radiosity matrix is close to the identity, so one pass loses
// orthogonality once the residual is small), turns the Hessenberg matrix h upper triangular with
// Givens rotations and minimises |r|_2 over x + span(v). A cycle ends after `kRestart` steps or
// when the rotated right-hand side says |r|_2 <= threshold; the true residual is then recomputed.
// Stops when |r|_inf <= threshold * |x|_inf (|r|_inf <= |r|_2), after max_iterations steps, or
// when a whole cycle fails to halve the true residual (the round-off floor).
//
// Why not Gauss-Seidel: its error shrinks by about rho per sweep in a closed scene (10^4 sweeps at
// rho = 0.999), while the spectrum of F (similar to a symmetric matrix by reciprocity) has few
// eigenvalues near 1, which Krylov methods remove in a few steps each.
struct KrylovOutcome {
  int iterations = 0;
  double relative_residual = 0.0;  // |r|_inf / |x|_inf at the end
  bool cancelled = false;
};

template <class Apply>
KrylovOutcome gmres(const Apply& apply, const std::vector<double>& rhs, std::vector<double>& x, double threshold,
                    int max_iterations, const std::atomic<bool>* cancel) {
  constexpr int kRestart = 60;
  const std::size_t n = rhs.size();
  KrylovOutcome outcome;
  auto dot_product = [n](const std::vector<double>& a, const std::vector<double>& b) {
    double sum = 0.0;
    for (std::size_t i = 0; i < n; ++i) sum += a[i] * b[i];
    return sum;
  };
  auto inf_norm = [](const std::vector<double>& a) {
    double largest = 0.0;
    for (const double value : a) largest = std::max(largest, std::fabs(value));
    return largest;
  };
  std::vector<double> r(n);
  std::vector<double> w(n);
  auto residual = [&]() {
    apply(x, w);
    for (std::size_t i = 0; i < n; ++i) r[i] = rhs[i] - w[i];
  };
  std::vector<std::vector<double>> basis(kRestart + 1, std::vector<double>(n));
  std::vector<std::vector<double>> h(kRestart + 1, std::vector<double>(kRestart, 0.0));
  std::vector<double> cosines(kRestart);
  std::vector<double> sines(kRestart);
  std::vector<double> g(kRestart + 1);
  residual();
  double previous = INFINITY;
  for (;;) {
    const double scale = inf_norm(x);
    const double r_inf = inf_norm(r);
    outcome.relative_residual = scale > 0.0 ? r_inf / scale : 0.0;
    if (r_inf <= threshold * scale || outcome.iterations >= max_iterations || !(r_inf < 0.5 * previous)) break;
    previous = r_inf;
    const double target = threshold * scale;
    const double beta = std::sqrt(dot_product(r, r));
    for (std::size_t i = 0; i < n; ++i) basis[0][i] = r[i] / beta;
    std::fill(g.begin(), g.end(), 0.0);
    g[0] = beta;
    int steps = 0;
    for (int j = 0; j < kRestart && outcome.iterations < max_iterations; ++j) {
      if (cancel != nullptr && cancel->load(std::memory_order_relaxed)) {
        outcome.cancelled = true;
        return outcome;
      }
      apply(basis[static_cast<std::size_t>(j)], w);
      ++outcome.iterations;
      const auto jj = static_cast<std::size_t>(j);
      for (std::size_t i = 0; i <= jj; ++i) h[i][jj] = 0.0;
      for (int pass = 0; pass < 2; ++pass)
        for (std::size_t i = 0; i <= jj; ++i) {
          const double projection = dot_product(w, basis[i]);
          h[i][jj] += projection;
          for (std::size_t k = 0; k < n; ++k) w[k] -= projection * basis[i][k];
        }
      const double norm = std::sqrt(dot_product(w, w));
      // Earlier rotations, then a new one that zeroes h[j+1][j].
      for (std::size_t i = 0; i < jj; ++i) {
        const double upper = cosines[i] * h[i][jj] + sines[i] * h[i + 1][jj];
        h[i + 1][jj] = -sines[i] * h[i][jj] + cosines[i] * h[i + 1][jj];
        h[i][jj] = upper;
      }
      // sqrt of the sum of squares, not std::hypot: sqrt is correctly rounded everywhere, hypot is
      // not (glibc's and the web build's differ in the last bit, and the coarse control variate
      // must give the same bits in the browser); both terms are of the order of |A v_j| <= 2.
      const double radius = std::sqrt(h[jj][jj] * h[jj][jj] + norm * norm);
      cosines[jj] = radius > 0.0 ? h[jj][jj] / radius : 1.0;
      sines[jj] = radius > 0.0 ? norm / radius : 0.0;
      h[jj][jj] = radius;
      g[jj + 1] = -sines[jj] * g[jj];
      g[jj] = cosines[jj] * g[jj];
      steps = j + 1;
      if (std::fabs(g[jj + 1]) <= target || !(norm > 0.0)) break;  // converged, or exact
      for (std::size_t k = 0; k < n; ++k) basis[jj + 1][k] = w[k] / norm;
    }
    // x += V y with h y = g (upper triangular, back substitution).
    std::vector<double> y(static_cast<std::size_t>(steps), 0.0);
    for (int i = steps - 1; i >= 0; --i) {
      const auto ii = static_cast<std::size_t>(i);
      double sum = g[ii];
      for (std::size_t k = ii + 1; k < static_cast<std::size_t>(steps); ++k) sum -= h[ii][k] * y[k];
      y[ii] = h[ii][ii] != 0.0 ? sum / h[ii][ii] : 0.0;
    }
    for (std::size_t i = 0; i < y.size(); ++i)
      for (std::size_t k = 0; k < n; ++k) x[k] += y[i] * basis[i][k];
    residual();
  }
  return outcome;
}

// Element boundaries of every segment, as arc lengths from its start: the segment is cut at the
// contacts that lie inside it (find_contacts: another curve's end point or corner on it, or a
// crossing), where light on the two sides is unrelated, and each piece between cuts is divided
// into equal arc-length chords no longer than max_length. Without the cuts a constant element
// straddling a contact averages the two sides and re-emits the lit side's light on the dark side
// (a leak of about its length times B): the reference then changes by about the same amount at
// every halving of h, as much where the contact's position inside the element moves.
std::vector<std::vector<double>> element_boundaries(const Scene& scene, double max_length) {
  std::vector<std::vector<double>> cuts(scene.segments.size());
  for (const DiscontinuityNode& node : find_contacts(scene)) {
    const Curve& curve = scene.curves[node.curve];
    const double local = std::clamp(std::floor(node.u), 0.0, static_cast<double>(curve.segment_count) - 1.0);
    const double t = node.u - local;
    if (!(t > 1e-9 && t < 1.0 - 1e-9)) continue;  // at a joint: already a boundary
    const SceneSegment& segment = scene.segments[curve.first_segment + static_cast<std::uint32_t>(local)];
    cuts[curve.first_segment + static_cast<std::uint32_t>(local)].push_back(
        segment.arc_length.length_at(segment.geometry.shape, t));
  }
  std::vector<std::vector<double>> boundaries(scene.segments.size());
  for (std::size_t si = 0; si < scene.segments.size(); ++si) {
    const double total = scene.segments[si].length;
    std::vector<double>& cut = cuts[si];
    cut.push_back(total);
    std::sort(cut.begin(), cut.end());
    std::vector<double>& b = boundaries[si];
    b.push_back(0.0);
    for (const double end : cut) {
      const double start = b.back();
      if (!(end - start > 1e-9 * total)) continue;
      const double pieces = std::max(1.0, std::ceil((end - start) / max_length));
      if (pieces > 1e8) {  // far beyond kMaxReferenceElements: marked, never built
        b.push_back(std::numeric_limits<double>::infinity());
        return boundaries;
      }
      for (double k = 1.0; k < pieces; ++k) b.push_back(start + (end - start) * k / pieces);
      b.push_back(end);
    }
    b.back() = total;
  }
  return boundaries;
}

}  // namespace

Status validate(const ReferenceSettings& settings) {
  if (!std::isfinite(settings.max_element_length) || settings.max_element_length < 0.0)
    return Error{"max element length: must be a finite length >= 0 (0: scene scale / 400)"};
  if (settings.quadrature < 1 || settings.quadrature > 64)
    return Error{"quadrature: must be between 1 and 64 points per element"};
  if (!std::isfinite(settings.tolerance) || settings.tolerance <= 0.0 || settings.tolerance >= 1.0)
    return Error{"tolerance: must be a number in (0, 1), e.g. 1e-12"};
  if (settings.max_iterations < 1) return Error{"max iterations: must be at least 1"};
  if (settings.threads > 1024) return Error{"threads: at most 1024 (0 uses every core)"};
  return ok_status();
}

Spectrum ReferenceSolution::element_radiosity(std::uint32_t element, Side side) const {
  Spectrum b{0.0, 0.0, 0.0};
  for (int c = 0; c < scene_.channels; ++c)
    b[static_cast<std::size_t>(c)] = radiosity_[static_cast<std::size_t>(c)][patch_index(element, side)];
  return b;
}

double ReferenceSolution::form_factor(std::uint32_t i, Side si, std::uint32_t j, Side sj) const {
  const std::uint32_t row = patch_row_[patch_index(i, si)];
  if (row == kNoElement) return 0.0;
  const auto target = static_cast<std::uint32_t>(patch_index(j, sj));
  const auto begin = column_.begin() + static_cast<std::ptrdiff_t>(row_begin_[row]);
  const auto end = column_.begin() + static_cast<std::ptrdiff_t>(row_begin_[row + 1]);
  const auto it = std::lower_bound(begin, end, target);
  if (it == end || *it != target) return 0.0;
  return value_[static_cast<std::size_t>(it - column_.begin())];
}

double ReferenceSolution::row_sum(std::uint32_t i, Side si) const {
  const std::uint32_t row = patch_row_[patch_index(i, si)];
  return row == kNoElement ? -1.0 : row_sums_[row];
}

void ReferenceSolution::gather_weights(std::uint32_t curve_index, Side side, double u,
                                       std::vector<std::pair<std::uint32_t, double>>& seen) const {
  seen.clear();
  const Curve& curve = scene_.curves[curve_index];
  if (!curve.has_side(side) || !any_positive(scene_.material_of(curve).reflectivity, scene_.channels)) return;
  const double clamped = std::clamp(u, 0.0, static_cast<double>(curve.segment_count));
  const auto local =
      static_cast<std::uint32_t>(std::min(std::floor(clamped), static_cast<double>(curve.segment_count) - 1.0));
  const double t = clamped - local;
  const std::uint32_t segment_index = curve.first_segment + local;
  const SceneSegment& segment = scene_.segments[segment_index];

  // The element that holds the point: the last whose start is at or before it.
  const std::uint32_t pieces = segment_count_[segment_index];
  const double s = segment.arc_length.length_at(segment.geometry.shape, t);
  const auto first = boundary_.begin() + static_cast<std::ptrdiff_t>(segment_first_[segment_index] + segment_index);
  const auto found = std::upper_bound(first, first + pieces, s);
  const auto piece = static_cast<std::uint32_t>(std::clamp<std::ptrdiff_t>(found - first - 1, 0, pieces - 1));
  const std::uint32_t self = segment_first_[segment_index] + piece;

  const Vec2 x = evaluate(segment.geometry.shape, t);
  Vec2 normal = unit_normal(segment.geometry.shape, t, scene_.scale);
  if (side == Side::Back) normal = -normal;
  Sweeper sweeper;
  std::vector<VisibleElement> visible;
  sweeper.run(elements_, x, normal, self, side, visible);
  for (const VisibleElement& v : visible)
    seen.emplace_back(static_cast<std::uint32_t>(patch_index(v.element, v.side)), v.form_factor);
  std::vector<VisibleElement> scratch;
  for (const ReferenceMirror& mirror : mirrors_)
    gather_by_mirror(sweeper, mirror, x, normal, self, side, 1e-12 * scene_.scale, scratch,
                     [&](std::uint32_t j, Side side_j, double f) {
                       seen.emplace_back(static_cast<std::uint32_t>(patch_index(j, side_j)), f);
                     });
}

std::vector<double> ReferenceSolution::element_parameters(std::uint32_t segment_index) const {
  const SceneSegment& segment = scene_.segments[segment_index];
  const std::uint32_t pieces = segment_count_[segment_index];
  const auto first = static_cast<std::size_t>(segment_first_[segment_index] + segment_index);
  std::vector<double> t(pieces + 1);
  t.front() = 0.0;
  t.back() = 1.0;
  for (std::uint32_t k = 1; k < pieces; ++k)
    t[k] = segment.arc_length.parameter_at(segment.geometry.shape, boundary_[first + k]);
  return t;
}

Spectrum ReferenceSolution::radiosity(std::uint32_t curve_index, Side side, double u) const {
  Spectrum result{0.0, 0.0, 0.0};
  const Curve& curve = scene_.curves[curve_index];
  if (!curve.has_side(side)) return result;
  const double clamped = std::clamp(u, 0.0, static_cast<double>(curve.segment_count));
  const double factor = emittance_factor(curve, clamped);
  for (int c = 0; c < scene_.channels; ++c) {
    const auto k = static_cast<std::size_t>(c);
    result[k] = curve.emittance[k] * factor;
  }
  const Material& material = scene_.material_of(curve);
  if (!any_positive(material.reflectivity, scene_.channels)) return result;
  std::vector<std::pair<std::uint32_t, double>> seen;
  gather_weights(curve_index, side, u, seen);
  for (int c = 0; c < scene_.channels; ++c) {
    const auto k = static_cast<std::size_t>(c);
    double gathered = 0.0;
    for (const auto& [p, f] : seen) gathered += f * radiosity_[k][p];
    result[k] += material.reflectivity[k] * gathered;
  }
  return result;
}

void ReferenceSolution::set_element_radiosity(std::array<std::vector<double>, 3> radiosity) {
  radiosity_ = std::move(radiosity);
}

std::vector<double> reference_element_counts(const Scene& scene, const ReferenceSettings& settings) {
  const double max_length = settings.max_element_length > 0.0 ? settings.max_element_length : scene.scale / 400.0;
  std::vector<double> counts(scene.segments.size(), 0.0);
  const std::vector<std::vector<double>> boundaries = element_boundaries(scene, max_length);
  for (std::size_t s = 0; s < boundaries.size(); ++s) {
    const std::vector<double>& b = boundaries[s];
    if (b.empty()) continue;  // after a segment marked unbounded
    counts[s] = std::isfinite(b.back()) ? static_cast<double>(b.size() - 1) : INFINITY;
  }
  return counts;
}

double reference_element_count(const Scene& scene, const ReferenceSettings& settings) {
  double count = 0.0;
  for (const double n : reference_element_counts(scene, settings)) count += n;
  return count;
}

// solve_reference's steps, each a method; a friend of ReferenceSolution, whose members it fills.
class ReferenceBuilder {
 public:
  // `subject` names the solver in refusals, `advice` says what to do instead.
  ReferenceBuilder(const Scene& scene, const ReferenceSettings& settings, ReferenceSolution& solution,
                   std::string subject = "the reference solver",
                   std::string advice =
                       "use a solve with many more photons as the reference (flatland solve --out "
                       "REF.json, then compare or converge --reference REF.json)")
      : subject_(std::move(subject)),
        advice_(std::move(advice)),
        scene_(scene),
        settings_(settings),
        solution_(solution),
        elements_(solution.elements_),
        memory_limit_(settings.memory_limit != 0 ? settings.memory_limit : default_memory_budget()) {}

  // Refuses what the reference cannot solve (non-diffuse emitters) or cannot finish (too many
  // elements, by their count alone), before any work is done.
  Status check() const;
  // Refuses scenes where light can meet two flat mirrors in a row (one reflection is followed).
  Status check_single_reflections() const;
  // check(), then the elements, the mirrors and the chains: what solve_reference and
  // reference_elements both build.
  Status geometry();
  // 1. Elements: the chords of every segment, equal in arc length between contacts.
  Status build_elements();
  // Mirrors: every reflecting side of every flat mirror segment, its view of the elements.
  void build_mirrors();
  // Chain neighbours: consecutive elements of a curve that share an end point exactly (joints
  // share their control point), and the last and first of a closed curve.
  void link_neighbours();
  // Patches (element sides) that carry radiosity (reflect or emit) and those that need a row of
  // F (reflect).
  void number_patches();
  // 2-3. The rows of F, by quadrature over the element, with crossed strings where the pair sees
  // each other whole from every quadrature point and each lies in front of the other; then in
  // compressed rows.
  Status form_factors();
  // 4. Per channel, (I - diag(rho) F) b = e by restarted GMRES, starting from b = e.
  Status solve_channels();

 private:
  bool cancelled() const { return settings_.cancel != nullptr && settings_.cancel->load(std::memory_order_relaxed); }
  // A mirror the reference follows: every segment straight, no roughness, one reflectance for
  // every channel.
  bool is_flat_grey_mirror(const Curve& curve) const {
    const Material& material = scene_.material_of(curve);
    if (material.roughness > 0.0) return false;
    for (int c = 1; c < scene_.channels; ++c)
      if (material.reflectance[static_cast<std::size_t>(c)] != material.reflectance[0]) return false;
    for (std::uint32_t k = 0; k < curve.segment_count; ++k)
      if (scene_.segments[curve.first_segment + k].geometry.kind != SegmentKind::Line) return false;
    return true;
  }
  double max_length() const {
    return settings_.max_element_length > 0.0 ? settings_.max_element_length : scene_.scale / 400.0;
  }
  std::size_t patch_count() const { return 2 * elements_.size(); }
  // One worker's share of the rows; `reports` says whether it calls the progress callback.
  void compute_rows(bool reports);
  void compress_rows();

  // Bytes of the rows so far (each entry of a row and of the final CSR copy: a column index and
  // a value); past the memory limit every worker stops.
  static constexpr double kBytesPerEntry = 2.0 * (sizeof(std::uint32_t) + sizeof(double)) + 4.0;

  std::string subject_;
  std::string advice_;
  const Scene& scene_;
  const ReferenceSettings& settings_;
  ReferenceSolution& solution_;
  std::vector<ReferenceElement>& elements_;
  // The bytes the rows may take: fixed before any work (the budget left shrinks as threads start).
  const std::size_t memory_limit_;
  std::vector<char> carries_;  // per patch
  // The rows being computed: shared by the workers, each row written by one.
  std::vector<double> nodes_;
  std::vector<double> weights_;
  std::vector<std::vector<std::pair<std::uint32_t, double>>> row_entries_;
  std::vector<double> row_sums_;
  std::atomic<std::size_t> next_row_{0};
  std::atomic<std::size_t> entry_count_{0};
  std::atomic<bool> out_of_memory_{false};
  std::atomic<std::size_t> rows_done_{0};
};

Status ReferenceBuilder::check() const {
  if (Status status = validate(settings_); !status) return status;
  // Light through specular chains is not in its equations (form factors between diffuse elements),
  // but for one reflection in a flat, smooth, grey mirror (its images, below).
  std::string specular;
  for (const Curve& curve : scene_.curves) {
    const Material& material = scene_.material_of(curve);
    const Optics optics = material.optics;
    if (optics == Optics::Diffuse) continue;
    if (optics == Optics::Mirror && is_flat_grey_mirror(curve)) continue;
    if (!specular.empty()) specular += ", ";
    specular += "'" + curve.id + "' (" +
                (optics == Optics::Mirror       ? "a curved, rough or coloured mirror"
                 : optics == Optics::Dielectric ? "dielectric"
                                                : "detector") +
                ")";
  }
  if (!specular.empty())
    return Error{scene_.source + ": " + subject_ + " handles diffuse surfaces and flat mirrors only, and curves " +
                 specular + " are not" + (advice_.empty() ? "" : "; " + advice_)};
  if (Status status = check_single_reflections(); !status) return status;
  for (const Curve& curve : scene_.curves) {
    if (scene_.is_emitter(curve) && scene_.material_of(curve).emission.kind != Emission::Kind::Diffuse)
      return Error{scene_.source + ": curve '" + curve.id + "': " + subject_ + " supports diffuse emitters only"};
  }
  const double element_total = reference_element_count(scene_, settings_);
  if (element_total > static_cast<double>(kMaxReferenceElements)) {
    char message[320];
    if (subject_ == "the reference solver" && !std::isfinite(element_total))
      std::snprintf(message, sizeof message,
                    "more reference elements than can be counted (elements of length %.3g); at most %zu: "
                    "use fewer elements (--elements or --max-element-length)",
                    max_length(), kMaxReferenceElements);
    else if (subject_ == "the reference solver")
      std::snprintf(message, sizeof message,
                    "%.4g reference elements (elements of length %.3g); at most %zu: form factors "
                    "take time and memory growing as the square of the count; use fewer elements "
                    "(--elements or --max-element-length)",
                    element_total, max_length(), kMaxReferenceElements);
    else
      std::snprintf(message, sizeof message,
                    "%.4g elements of length %.3g for %s; at most %zu (every sample sweeps them all)", element_total,
                    max_length(), subject_.c_str(), kMaxReferenceElements);
    return Error{subject_ == "the reference solver" || advice_.empty() ? std::string(message)
                                                                       : message + ("; " + advice_)};
  }
  return ok_status();
}

// Light reaches a second mirror after the first only if the two reflecting sides face each other:
// part of B lies strictly in front of A's reflecting side and part of A strictly in front of B's.
// Where no such pair exists, every path from a diffuse point to a diffuse point meets at most one
// mirror (a path that leaves mirror A toward mirror B needs B in front of A, and to be reflected
// by B it must arrive on B's reflecting side, which needs A in front of B), so one image per
// mirror is the whole of the specular light. Where one exists, the reference refuses the scene
// rather than report an error estimate that does not bound its error. The test ignores occluders
// between the two (conservative: such a pair is refused even if walls hide them from each other).
Status ReferenceBuilder::check_single_reflections() const {
  struct MirrorSide {
    Vec2 a, b, normal;
    std::uint32_t curve;
  };
  std::vector<MirrorSide> sides;
  for (const SceneSegment& segment : scene_.segments) {
    const Curve& curve = scene_.curves[segment.curve];
    if (scene_.material_of(curve).optics != Optics::Mirror) continue;
    const Vec2 a = segment.geometry.shape.p[0], b = segment.geometry.shape.p[3];
    const Vec2 front = normalized(perp(b - a));
    for (const Side side : {Side::Front, Side::Back})
      if (curve.has_side(side)) sides.push_back({a, b, side == Side::Front ? front : -front, segment.curve});
  }
  const double touch = 1e-9 * scene_.scale;
  const auto in_front = [&](const MirrorSide& of, const MirrorSide& other) {
    return dot(other.a - of.a, of.normal) > touch || dot(other.b - of.a, of.normal) > touch;
  };
  for (std::size_t i = 0; i < sides.size(); ++i) {
    if (cancelled()) return Error{kReferenceCancelled};
    for (std::size_t j = i + 1; j < sides.size(); ++j) {
      if (!in_front(sides[i], sides[j]) || !in_front(sides[j], sides[i])) continue;
      const std::string& first = scene_.curves[sides[i].curve].id;
      const std::string& second = scene_.curves[sides[j].curve].id;
      return Error{scene_.source + ": " +
                   (first == second ? "mirror '" + first + "' faces itself (two of its segments face each other)"
                                    : "mirrors '" + first + "' and '" + second + "' face each other") +
                   ": light reflected by one reaches the other, and " + subject_ + " follows one reflection" +
                   (advice_.empty() ? "" : "; " + advice_)};
    }
  }
  return ok_status();
}

Status ReferenceBuilder::build_elements() {
  const std::vector<std::vector<double>> boundaries = element_boundaries(scene_, max_length());
  solution_.segment_first_.assign(scene_.segments.size(), 0);
  solution_.segment_count_.assign(scene_.segments.size(), 0);
  for (std::uint32_t si = 0; si < scene_.segments.size(); ++si) {
    const SceneSegment& segment = scene_.segments[si];
    const Curve& curve = scene_.curves[segment.curve];
    const Material& material = scene_.material_of(curve);
    const Cubic& shape = segment.geometry.shape;
    const std::vector<double>& boundary = boundaries[si];
    const auto pieces = static_cast<std::uint32_t>(boundary.size() - 1);
    solution_.segment_first_[si] = static_cast<std::uint32_t>(elements_.size());
    solution_.segment_count_[si] = pieces;
    // Per segment pieces + 1 boundaries; segment si's start at segment_first_[si] + si.
    solution_.boundary_.insert(solution_.boundary_.end(), boundary.begin(), boundary.end());
    auto point_at = [&](std::uint32_t k) {
      if (k == 0) return shape.p[0];
      if (k == pieces) return shape.p[3];
      return evaluate(shape, segment.arc_length.parameter_at(shape, boundary[k]));
    };
    Vec2 start = point_at(0);
    for (std::uint32_t k = 0; k < pieces; ++k) {
      const Vec2 end = point_at(k + 1);
      ReferenceElement e;
      e.a = start;
      e.b = end;
      e.length = length(end - start);
      if (!(e.length > 0.0)) return Error{scene_.source + ": curve '" + curve.id + "': a chord of zero length"};
      e.normal = (1.0 / e.length) * perp(end - start);
      e.curve = segment.curve;
      e.segment = si;
      e.u_mid = segment.index_in_curve + segment.arc_length.parameter_at(shape, 0.5 * (boundary[k] + boundary[k + 1]));
      const double factor = emittance_factor(curve, e.u_mid);
      for (const Side side : {Side::Front, Side::Back}) {
        if (!curve.has_side(side)) continue;
        const auto sd = static_cast<std::size_t>(side);
        for (int c = 0; c < scene_.channels; ++c) {
          const auto ch = static_cast<std::size_t>(c);
          e.reflectivity[sd][ch] = material.reflectivity[ch];
          e.emittance[sd][ch] = curve.emittance[ch] * factor;
        }
      }
      elements_.push_back(e);
      start = end;
    }
  }
  return ok_status();
}

void ReferenceBuilder::build_mirrors() {
  const double touch = 1e-12 * scene_.scale;
  for (std::uint32_t si = 0; si < scene_.segments.size(); ++si) {
    const SceneSegment& segment = scene_.segments[si];
    const Curve& curve = scene_.curves[segment.curve];
    const Material& material = scene_.material_of(curve);
    if (material.optics != Optics::Mirror) continue;
    const Vec2 p0 = segment.geometry.shape.p[0];
    const Vec2 p1 = segment.geometry.shape.p[3];
    const Vec2 along = normalized(p1 - p0);
    for (const Side side : {Side::Front, Side::Back}) {
      if (!curve.has_side(side)) continue;
      ReferenceMirror mirror;
      mirror.origin = p0;
      mirror.normal = side == Side::Front ? perp(along) : -perp(along);
      mirror.reflectance = material.reflectance[0];
      mirror.image_of.assign(elements_.size(), kNoElement);
      // The elements in front, clipped at the line (their chain links dropped: they index the
      // scene's elements), then their images, then the blockers.
      for (std::uint32_t j = 0; j < elements_.size(); ++j) {
        const ReferenceElement& e = elements_[j];
        if (e.segment == si) continue;
        const double da = dot(e.a - p0, mirror.normal);
        const double db = dot(e.b - p0, mirror.normal);
        if (da <= touch && db <= touch) continue;
        ReferenceElement clipped = e;
        clipped.previous = kNoElement;
        clipped.next = kNoElement;
        if (da < 0.0 || db < 0.0) {
          const Vec2 cut = e.a + (da / (da - db)) * (e.b - e.a);
          (da < 0.0 ? clipped.a : clipped.b) = cut;
          clipped.length = length(clipped.b - clipped.a);
          if (!(clipped.length > touch)) continue;
        }
        mirror.real.push_back(j);
        mirror.elements.push_back(clipped);
      }
      const std::size_t in_front = mirror.elements.size();
      for (std::size_t k = 0; k < in_front; ++k) {
        const ReferenceElement& e = mirror.elements[k];
        mirror.image_of[mirror.real[k]] = static_cast<std::uint32_t>(mirror.elements.size());
        mirror.elements.push_back(chord_element(mirrored_point(e.b, mirror), mirrored_point(e.a, mirror)));
        mirror.real.push_back(kNoElement);
      }
      const double far = 10.0 * scene_.scale + length(p1 - p0);
      mirror.elements.push_back(chord_element(p0 - far * along, p0));
      mirror.elements.push_back(chord_element(p1, p1 + far * along));
      mirror.real.push_back(kNoElement);
      mirror.real.push_back(kNoElement);
      solution_.mirrors_.push_back(std::move(mirror));
    }
  }
}

void ReferenceBuilder::link_neighbours() {
  const auto element_count = static_cast<std::uint32_t>(elements_.size());
  for (std::uint32_t k = 0; k + 1 < element_count; ++k) {
    if (elements_[k + 1].curve == elements_[k].curve && elements_[k + 1].a == elements_[k].b) {
      elements_[k].next = k + 1;
      elements_[k + 1].previous = k;
    }
  }
  for (std::uint32_t first = 0; first < element_count;) {
    std::uint32_t last = first;
    while (last + 1 < element_count && elements_[last + 1].curve == elements_[first].curve) ++last;
    if (last != first && elements_[last].b == elements_[first].a) {
      elements_[last].next = first;
      elements_[first].previous = last;
    }
    first = last + 1;
  }
}

void ReferenceBuilder::number_patches() {
  carries_.assign(patch_count(), 0);
  solution_.patch_row_.assign(patch_count(), kNoElement);
  for (std::uint32_t j = 0; j < elements_.size(); ++j) {
    for (const Side side : {Side::Front, Side::Back}) {
      const auto sd = static_cast<std::size_t>(side);
      const bool reflects = any_positive(elements_[j].reflectivity[sd], scene_.channels);
      const bool emits = any_positive(elements_[j].emittance[sd], scene_.channels);
      carries_[patch_index(j, side)] = reflects || emits;
      if (reflects) {
        solution_.patch_row_[patch_index(j, side)] = static_cast<std::uint32_t>(solution_.row_patch_.size());
        solution_.row_patch_.push_back(static_cast<std::uint32_t>(patch_index(j, side)));
      }
    }
  }
}

void ReferenceBuilder::compute_rows(bool reports) {
  const std::size_t rows = solution_.row_patch_.size();
  auto last_report = std::chrono::steady_clock::now();
  Sweeper sweeper;
  PairQuadrature pair_quadrature(elements_, nodes_, weights_);
  std::vector<VisibleElement> visible;
  std::vector<double> accumulated(patch_count(), 0.0);
  std::vector<int> whole_count(patch_count(), 0);
  // Seen directly from some quadrature point; listed in `touched`; F by the mirrors.
  std::vector<char> direct(patch_count(), 0);
  std::vector<char> listed(patch_count(), 0);
  std::vector<double> mirrored(patch_count(), 0.0);
  const double touch = 1e-12 * scene_.scale;
  std::vector<std::uint32_t> touched;
  for (;;) {
    if (cancelled() || out_of_memory_.load(std::memory_order_relaxed)) break;
    const std::size_t row = next_row_.fetch_add(1);
    if (row >= rows) break;
    const std::uint32_t patch = solution_.row_patch_[row];
    const std::uint32_t i = patch / 2;
    const Side side = static_cast<Side>(patch % 2);
    const ReferenceElement& ei = elements_[i];
    const Vec2 normal = side == Side::Front ? ei.normal : -ei.normal;
    touched.clear();
    for (std::size_t q = 0; q < nodes_.size(); ++q) {
      const Vec2 x = lerp(ei.a, ei.b, nodes_[q]);
      sweeper.run(elements_, x, normal, i, side, visible);
      for (const VisibleElement& v : visible) {
        const std::size_t p = patch_index(v.element, v.side);
        if (!listed[p]) touched.push_back(static_cast<std::uint32_t>(p));
        listed[p] = 1;
        direct[p] = 1;
        accumulated[p] += weights_[q] * v.form_factor;
        whole_count[p] += v.whole ? 1 : 0;
      }
      for (const ReferenceMirror& mirror : solution_.mirrors_)
        gather_by_mirror(sweeper, mirror, x, normal, i, side, touch, visible,
                         [&](std::uint32_t j, Side side_j, double f) {
                           const std::size_t p = patch_index(j, side_j);
                           if (!listed[p]) touched.push_back(static_cast<std::uint32_t>(p));
                           listed[p] = 1;
                           mirrored[p] += weights_[q] * f;
                         });
    }
    std::sort(touched.begin(), touched.end());
    auto& entries = row_entries_[row];
    double sum = 0.0;
    for (const std::uint32_t p : touched) {
      double f = 0.0;
      const std::uint32_t j = p / 2;
      const Side side_j = static_cast<Side>(p % 2);
      if (!direct[p]) {
        // Seen by a mirror only.
      } else if (whole_count[p] == settings_.quadrature && in_front_of(ei, side, elements_[j]) &&
                 in_front_of(elements_[j], side_j, ei)) {
        const ReferenceElement& ej = elements_[j];
        f = crossed_strings(ei.a, ei.b, ej.a, ej.b);
      } else {
        // Seen partly (or clipped by i's plane) from some quadrature point: integrate again,
        // split at the visibility events.
        f = pair_quadrature.form_factor(i, side, j, side_j);
      }
      // By the mirrors: the plain quadrature over the element (their images' visibility events are
      // not split at).
      f += mirrored[p];
      accumulated[p] = 0.0;
      whole_count[p] = 0;
      direct[p] = 0;
      listed[p] = 0;
      mirrored[p] = 0.0;
      sum += f;
      if (carries_[p] && f > 0.0) entries.emplace_back(p, f);
    }
    row_sums_[row] = sum;
    const std::size_t total = entry_count_.fetch_add(entries.size()) + entries.size();
    if (static_cast<double>(total) * kBytesPerEntry > static_cast<double>(memory_limit_)) out_of_memory_.store(true);
    const std::size_t done = rows_done_.fetch_add(1) + 1;
    if (reports && settings_.progress && seconds_since(last_report) >= 0.25) {
      last_report = std::chrono::steady_clock::now();
      settings_.progress(done, rows);
    }
  }
}

Status ReferenceBuilder::form_factors() {
  const auto clock_start = std::chrono::steady_clock::now();
  const std::size_t rows = solution_.row_patch_.size();
  gauss::legendre_unit_rule(settings_.quadrature, nodes_, weights_);
  row_entries_.assign(rows, {});
  row_sums_.assign(rows, 0.0);
  {
    const unsigned threads =
        static_cast<unsigned>(std::min<std::size_t>(thread_count(settings_.threads), std::max<std::size_t>(rows, 1)));
    WorkerPool pool(threads);
    solution_.thread_shortfall_ = pool.shortfall();
    pool.run(pool.threads(), [&](unsigned w) { compute_rows(w == 0); });
  }
  if (cancelled()) return Error{kReferenceCancelled};
  if (out_of_memory_.load()) {
    const std::size_t done = std::min(next_row_.load(), rows);
    const double projected = static_cast<double>(entry_count_.load()) * kBytesPerEntry * static_cast<double>(rows) /
                             static_cast<double>(std::max<std::size_t>(done, 1));
    return Error{std::to_string(elements_.size()) + " reference elements: the form factors would need about " +
                 format_bytes(projected) + ", more than the memory limit of " +
                 format_bytes(static_cast<double>(memory_limit_)) +
                 "; use fewer elements (--elements or --max-element-length)"};
  }
  compress_rows();
  solution_.form_factor_seconds_ = seconds_since(clock_start);
  return ok_status();
}

void ReferenceBuilder::compress_rows() {
  const std::size_t rows = row_entries_.size();
  solution_.row_begin_.assign(rows + 1, 0);
  for (std::size_t r = 0; r < rows; ++r) solution_.row_begin_[r + 1] = solution_.row_begin_[r] + row_entries_[r].size();
  solution_.column_.reserve(solution_.row_begin_[rows]);
  solution_.value_.reserve(solution_.row_begin_[rows]);
  for (std::size_t r = 0; r < rows; ++r) {
    for (const auto& [p, f] : row_entries_[r]) {
      solution_.column_.push_back(p);
      solution_.value_.push_back(f);
    }
    std::vector<std::pair<std::uint32_t, double>>().swap(row_entries_[r]);
  }
  solution_.row_sums_ = std::move(row_sums_);
}

// Patches without a row (non-reflecting) are identity rows: they keep b = e.
Status ReferenceBuilder::solve_channels() {
  const auto solve_start = std::chrono::steady_clock::now();
  const std::size_t rows = solution_.row_patch_.size();
  solution_.iterations_ = 0;
  solution_.residual_ = 0.0;
  solution_.error_bound_ = 0.0;
  for (int c = 0; c < scene_.channels; ++c) {
    const auto ch = static_cast<std::size_t>(c);
    std::vector<double> rhs(patch_count(), 0.0);
    std::vector<double> rho(rows, 0.0);
    // The contraction q = max_p rho_p sum_q F_pq bounds ||diag(rho) F||_inf, so
    // ||(I - diag(rho) F)^-1||_inf <= 1 / (1 - q).
    double contraction = 0.0;
    for (std::size_t p = 0; p < patch_count(); ++p) rhs[p] = elements_[p / 2].emittance[p % 2][ch];
    for (std::size_t r = 0; r < rows; ++r) {
      const std::uint32_t p = solution_.row_patch_[r];
      rho[r] = elements_[p / 2].reflectivity[p % 2][ch];
      contraction = std::max(contraction, rho[r] * solution_.row_sums_[r]);
    }
    const double amplification = 1.0 / std::max(1.0 - contraction, 1e-9);
    auto apply = [&](const std::vector<double>& x, std::vector<double>& y) {
      y = x;
      for (std::size_t r = 0; r < rows; ++r) {
        double gathered = 0.0;
        for (std::size_t k = solution_.row_begin_[r]; k < solution_.row_begin_[r + 1]; ++k)
          gathered += solution_.value_[k] * x[solution_.column_[k]];
        y[solution_.row_patch_[r]] -= rho[r] * gathered;
      }
    };
    std::vector<double>& b = solution_.radiosity_[ch];
    b = rhs;
    const KrylovOutcome outcome =
        gmres(apply, rhs, b, settings_.tolerance / amplification, settings_.max_iterations, settings_.cancel);
    if (outcome.cancelled) return Error{kReferenceCancelled};
    solution_.iterations_ = std::max(solution_.iterations_, outcome.iterations);
    solution_.residual_ = std::max(solution_.residual_, outcome.relative_residual);
    solution_.error_bound_ = std::max(solution_.error_bound_, outcome.relative_residual * amplification);
  }
  solution_.solve_seconds_ = seconds_since(solve_start);
  return ok_status();
}

Status ReferenceBuilder::geometry() {
  if (Status status = check(); !status) return status;
  solution_.scene_ = scene_;
  solution_.settings_ = settings_;
  if (Status status = build_elements(); !status) return status;
  build_mirrors();
  link_neighbours();
  return ok_status();
}

Result<ReferenceSolution> solve_reference(const Scene& scene, const ReferenceSettings& settings) {
  ReferenceSolution solution;
  ReferenceBuilder build(scene, settings, solution);
  if (Status status = build.geometry(); !status) return status.error();
  build.number_patches();
  if (Status status = build.form_factors(); !status) return status.error();
  if (Status status = build.solve_channels(); !status) return status.error();
  return solution;
}

Result<ReferenceSolution> reference_elements(const Scene& scene, const ReferenceSettings& settings,
                                             const std::string& subject, const std::string& advice) {
  ReferenceSolution solution;
  ReferenceBuilder build(scene, settings, solution, subject, advice);
  if (Status status = build.geometry(); !status) return status.error();
  for (int c = 0; c < scene.channels; ++c) {
    std::vector<double>& b = solution.radiosity_[static_cast<std::size_t>(c)];
    b.assign(2 * solution.elements_.size(), 0.0);
    for (std::size_t p = 0; p < b.size(); ++p)
      b[p] = solution.elements_[p / 2].emittance[p % 2][static_cast<std::size_t>(c)];
  }
  return solution;
}

ReferenceErrorEstimate estimate_from_differences(const ErrorNorms& fine, const ErrorNorms& coarse, double round_off) {
  ReferenceErrorEstimate estimate;
  estimate.fine_difference = fine;
  estimate.coarse_difference = coarse;
  estimate.round_off = round_off;
  estimate.observed_order = NAN;
  estimate.order = NAN;
  char text[240];
  if (!(fine.l2 > round_off)) {
    std::snprintf(text, sizeof text,
                  "R_h and R_2h agree to round-off (%.2g): the reference reproduces this scene at "
                  "every resolution; the estimate is that difference",
                  fine.l2);
    estimate.note = text;
    estimate.error = fine;
    return estimate;
  }
  if (!(coarse.l2 > round_off)) {
    std::snprintf(text, sizeof text,
                  "R_4h and R_2h agree to round-off but R_h differs: no order observed; assumed "
                  "the lowest, %.2g",
                  kMinimumOrder);
    estimate.note = text;
    estimate.order = kMinimumOrder;
  } else {
    estimate.observed_order = std::log2(coarse.l2 / fine.l2);
    estimate.order = std::clamp(estimate.observed_order, kMinimumOrder, kMaximumOrder);
    if (estimate.order != estimate.observed_order) {
      std::snprintf(text, sizeof text, "observed order %.2f clamped to %.2g", estimate.observed_order, estimate.order);
      estimate.note = text;
    }
  }
  const double factor = 1.0 / (std::exp2(estimate.order) - 1.0);
  estimate.error = {factor * fine.l1, factor * fine.l2, factor * fine.linf};
  return estimate;
}

Result<ReferenceErrorEstimate> estimate_discretisation_error(const Scene& scene, const ReferenceSettings& settings,
                                                             int samples, const SampledResult& fine,
                                                             const std::function<void(int level)>& starting) {
  const double length = settings.max_element_length > 0.0 ? settings.max_element_length : scene.scale / 400.0;
  SampledResult previous = fine;
  std::array<ErrorNorms, 2> differences;
  double largest_bound = 0.0;
  for (int level = 1; level <= 2; ++level) {
    if (starting) starting(level);
    ReferenceSettings coarser = settings;
    coarser.max_element_length = std::ldexp(length, level);
    Result<ReferenceSolution> solved = solve_reference(scene, coarser);
    if (!solved) return solved.error();
    const ReferenceSolution& solution = *solved;
    largest_bound = std::max(largest_bound, solution.error_bound());
    SampledResult sampled = sample_radiosity(
        scene, samples, [&solution](std::uint32_t c, Side side, double u) { return solution.radiosity(c, side, u); });
    Result<Comparison> difference = compare_sampled(sampled, previous);
    if (!difference) return difference.error();
    differences[static_cast<std::size_t>(level - 1)] = difference->scene;
    previous = std::move(sampled);
  }
  // Round-off: sums of rounded terms (about 1e-15 relative; 1e-13 leaves room for the many terms
  // of a gather), and the linear solves' own guaranteed error.
  const double round_off = std::max(1e-13, 4.0 * largest_bound);
  return estimate_from_differences(differences[0], differences[1], round_off);
}

}  // namespace flatland
