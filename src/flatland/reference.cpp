#include "flatland/reference.hpp"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <string>
#include <thread>

#include "flatland/resources.hpp"

namespace flatland {

namespace {

constexpr double kPi = 3.14159265358979323846;

// Gauss-Legendre nodes and weights on [0, 1] (weights sum to 1): Newton on P_n from the
// Chebyshev-like first guesses cos(pi (k + 3/4) / (n + 1/2)); P_n and P_n' by the three-term
// recurrence. Accurate to rounding for n <= 64.
void gauss_legendre_unit(int n, std::vector<double>& nodes, std::vector<double>& weights) {
  nodes.assign(static_cast<std::size_t>(n), 0.0);
  weights.assign(static_cast<std::size_t>(n), 0.0);
  for (int k = 0; k < n; ++k) {
    double z = std::cos(kPi * (k + 0.75) / (n + 0.5));
    double derivative = 1.0;
    for (int iteration = 0; iteration < 100; ++iteration) {
      double p0 = 1.0;
      double p1 = z;
      for (int m = 2; m <= n; ++m) {
        const double p2 = ((2.0 * m - 1.0) * z * p1 - (m - 1.0) * p0) / m;
        p0 = p1;
        p1 = p2;
      }
      // P_n'(z) = n (z P_n - P_(n-1)) / (z^2 - 1).
      derivative = n * (z * p1 - p0) / (z * z - 1.0);
      const double step = p1 / derivative;
      z -= step;
      if (std::fabs(step) < 1e-16) break;
    }
    const double weight = 2.0 / ((1.0 - z * z) * derivative * derivative);
    // Node z in [-1, 1] maps to (1 - z) / 2 so the nodes come out increasing.
    nodes[static_cast<std::size_t>(k)] = 0.5 * (1.0 - z);
    weights[static_cast<std::size_t>(k)] = 0.5 * weight;
  }
}

std::size_t patch_index(std::uint32_t element, Side side) {
  return 2 * static_cast<std::size_t>(element) + static_cast<std::size_t>(side);
}

bool any_positive(const Spectrum& s, int channels) {
  for (int c = 0; c < channels; ++c)
    if (s[static_cast<std::size_t>(c)] > 0.0) return true;
  return false;
}

// The angular sweep of visible_elements with buffers reused across calls (one per thread).
//
// Around x, with n the normal and t = (n.y, -n.x), a point p has depth a = n.(p - x) and lateral
// offset l = t.(p - x); the direction's angle from n is theta = atan2(l, a), and on the front
// half-plane (a >= 0) sin(theta) = l / |p - x| increases with theta, so sin(theta) serves as the
// sweep key directly. Each element, clipped to a >= 0, spans one key interval. Between two
// consecutive keys no end point lies, and elements do not cross, so one element is nearest across
// the whole gap: the one nearest along the ray in the gap's middle direction. It receives
// (key_hi - key_lo) / 2 of the form factor.
//
// Elements attached to x (the one x lies on, `self`, and those with an end point at x) stand for
// the curve through x: a point on a concave arc sees the arc itself between its tangent and the
// chord to the arc's end (in the directions from that end's key to +-1), which the chords miss.
// Those directions are owned by the attached element at distance 0. A point on the chord itself
// (the quadrature points of the form factors) has its chord's ends at depth 0: no such range.
class Sweeper {
 public:
  void run(const std::vector<ReferenceElement>& elements, Vec2 x, Vec2 normal, std::uint32_t self,
           Side self_side, std::vector<VisibleElement>& out) {
    out.clear();
    events_.clear();
    pieces_.clear();
    const std::size_t count = elements.size();
    const Vec2 lateral_axis{normal.y, -normal.x};
    auto add_attached = [&](std::uint32_t j, Vec2 r, double length_r, bool own) {
      const double depth = dot(r, normal);
      if (!(depth > 1e-12 * length_r)) return;  // convex there (or on the chord): not seen
      const double key = dot(r, lateral_axis) / length_r;
      Piece piece;
      piece.element = j;
      piece.attached = true;
      piece.low = key > 0.0 ? key : -1.0;
      piece.high = key > 0.0 ? 1.0 : key;
      if (!(piece.high > piece.low)) return;
      if (own) {
        piece.side = self_side;
      } else {
        // x is on the line of j, and the arc of j bulges to the side of the chord's line these
        // directions go to; they meet the arc from its concave side, the side that faces the
        // chord: the front when they go to the chord's back half-plane (d . n_j < 0).
        const double s = 0.5 * (piece.low + piece.high);
        const Vec2 d = std::sqrt(std::max(0.0, 1.0 - s * s)) * normal + s * lateral_axis;
        piece.side = dot(d, elements[j].normal) < 0.0 ? Side::Front : Side::Back;
      }
      push(piece);
    };
    for (std::uint32_t j = 0; j < count; ++j) {
      const ReferenceElement& e = elements[j];
      const Vec2 ra = e.a - x;
      const Vec2 rb = e.b - x;
      const double la = length(ra);
      const double lb = length(rb);
      const double at_vertex = 1e-12 * std::max(la + lb, e.length);
      if (j == self) {
        if (la > at_vertex) add_attached(j, ra, la, true);
        if (lb > at_vertex) add_attached(j, rb, lb, true);
        continue;
      }
      // x at an end point of j (a neighbour in the chain).
      if (la <= at_vertex) {
        if (lb > at_vertex) add_attached(j, rb, lb, false);
        continue;
      }
      if (lb <= at_vertex) {
        add_attached(j, ra, la, false);
        continue;
      }
      // cross(ra, rb) = (x - a) . perp(b - a): positive when x is in front of j. Zero: x on the
      // line of j, which is then seen edge-on.
      const double orientation = cross(ra, rb);
      if (std::fabs(orientation) <= 1e-12 * la * lb) continue;
      Piece piece;
      piece.element = j;
      piece.a = {dot(ra, normal), dot(ra, lateral_axis)};
      piece.b = {dot(rb, normal), dot(rb, lateral_axis)};
      if (piece.a.x <= 0.0 && piece.b.x <= 0.0) continue;  // behind the half-plane
      auto key_of = [&](Vec2 p, Vec2 q, double length_p) {
        if (p.x >= 0.0) return p.y / length_p;
        // Clip at depth 0: the crossing's lateral sign gives theta = +-90 degrees.
        piece.clipped = true;
        const double s = p.x / (p.x - q.x);
        const double lateral = p.y + s * (q.y - p.y);
        return lateral > 0.0 ? 1.0 : -1.0;
      };
      const double ka = key_of(piece.a, piece.b, la);
      const double kb = key_of(piece.b, piece.a, lb);
      piece.low = std::min(ka, kb);
      piece.high = std::max(ka, kb);
      if (!(piece.high > piece.low)) continue;
      piece.side = orientation > 0.0 ? Side::Front : Side::Back;
      push(piece);
    }
    std::sort(events_.begin(), events_.end(), [](const Event& p, const Event& q) {
      if (p.key != q.key) return p.key < q.key;
      return p.piece < q.piece;
    });
    active_.clear();
    std::size_t i = 0;
    while (i < events_.size()) {
      const double key = events_[i].key;
      for (; i < events_.size() && events_[i].key == key; ++i) {
        if (events_[i].start) {
          active_.push_back(events_[i].piece);
        } else {
          const auto it = std::find(active_.begin(), active_.end(), events_[i].piece);
          *it = active_.back();
          active_.pop_back();
        }
      }
      if (i == events_.size() || active_.empty()) continue;
      const double next = events_[i].key;
      // Middle direction of the gap, in (depth, lateral) coordinates.
      const double s = 0.5 * (key + next);
      const Vec2 d{std::sqrt(std::max(0.0, 1.0 - s * s)), s};
      std::uint32_t nearest = kNoElement;
      double nearest_distance = INFINITY;
      for (const std::uint32_t k : active_) {
        const Piece& piece = pieces_[k];
        double r = 0.0;
        if (!piece.attached) {
          // x + r d = a + w (b - a): r = cross(a, b - a) / cross(d, b - a) (x is the origin).
          const Vec2 edge = piece.b - piece.a;
          r = cross(piece.a, edge) / cross(d, edge);
        }
        if (r < nearest_distance || (r == nearest_distance && k < nearest)) {
          nearest_distance = r;
          nearest = k;
        }
      }
      pieces_[nearest].seen += 0.5 * (next - key);
    }
    // Sum per (element, side); pieces come in increasing element order.
    for (const Piece& piece : pieces_) {
      if (!(piece.seen > 0.0)) continue;
      if (!out.empty() && out.back().element == piece.element && out.back().side == piece.side) {
        out.back().form_factor += piece.seen;
        out.back().whole = false;
      } else {
        const double full = 0.5 * (piece.high - piece.low);
        out.push_back({piece.element, piece.side, piece.seen,
                       !piece.attached && !piece.clipped && std::fabs(piece.seen - full) <= 1e-12});
      }
    }
  }

 private:
  struct Piece {
    std::uint32_t element = 0;
    Vec2 a;  // (depth, lateral) of the element's ends relative to x
    Vec2 b;
    double low = 0.0;
    double high = 0.0;
    double seen = 0.0;
    bool clipped = false;
    bool attached = false;
    Side side = Side::Front;
  };
  struct Event {
    double key;
    std::uint32_t piece;
    bool start;
  };
  void push(const Piece& piece) {
    const auto index = static_cast<std::uint32_t>(pieces_.size());
    pieces_.push_back(piece);
    events_.push_back({piece.low, index, true});
    events_.push_back({piece.high, index, false});
  }
  std::vector<Piece> pieces_;
  std::vector<Event> events_;
  std::vector<std::uint32_t> active_;
};

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
KrylovOutcome gmres(const Apply& apply, const std::vector<double>& rhs, std::vector<double>& x,
                    double threshold, int max_iterations, const std::atomic<bool>* cancel) {
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
    if (r_inf <= threshold * scale || outcome.iterations >= max_iterations ||
        !(r_inf < 0.5 * previous))
      break;
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
      const double radius = std::hypot(h[jj][jj], norm);
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

}  // namespace

Status validate(const ReferenceSettings& settings) {
  if (!std::isfinite(settings.max_element_length) || settings.max_element_length < 0.0)
    return Error{"--max-element-length: must be a finite length >= 0 (0: scene scale / 400)"};
  if (settings.quadrature < 1 || settings.quadrature > 64)
    return Error{"--quadrature: must be between 1 and 64 points per element"};
  if (!std::isfinite(settings.tolerance) || settings.tolerance <= 0.0 || settings.tolerance >= 1.0)
    return Error{"--tolerance: must be a number in (0, 1), e.g. 1e-12"};
  if (settings.max_iterations < 1) return Error{"--max-iterations: must be at least 1"};
  if (settings.threads > 1024) return Error{"--threads: at most 1024 (0 uses every core)"};
  return ok_status();
}

std::vector<VisibleElement> visible_elements(const std::vector<ReferenceElement>& elements, Vec2 x,
                                             Vec2 normal, std::uint32_t self) {
  Sweeper sweeper;
  std::vector<VisibleElement> out;
  Side side = Side::Front;
  if (self != kNoElement && dot(normal, elements[self].normal) < 0.0) side = Side::Back;
  sweeper.run(elements, x, normal, self, side, out);
  return out;
}

double crossed_strings(Vec2 a1, Vec2 b1, Vec2 a2, Vec2 b2) {
  // Of the two pairings of the ends, the crossed one (the diagonals of the convex quadrilateral
  // the two segments span) is the longer; with a shared end point it degenerates to
  // (L1 + L2 - |far ends|) / (2 L1).
  const double pairing_one = length(a1 - a2) + length(b1 - b2);
  const double pairing_two = length(a1 - b2) + length(b1 - a2);
  return std::fabs(pairing_one - pairing_two) / (2.0 * length(b1 - a1));
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

Spectrum ReferenceSolution::radiosity(std::uint32_t curve_index, Side side, double u) const {
  Spectrum result{0.0, 0.0, 0.0};
  const Curve& curve = scene_.curves[curve_index];
  if (!curve.has_side(side)) return result;
  const double clamped = std::clamp(u, 0.0, static_cast<double>(curve.segment_count));
  const auto local = static_cast<std::uint32_t>(
      std::min(std::floor(clamped), static_cast<double>(curve.segment_count) - 1.0));
  const double t = clamped - local;
  const std::uint32_t segment_index = curve.first_segment + local;
  const SceneSegment& segment = scene_.segments[segment_index];
  const Material& material = scene_.material_of(curve);
  const double factor = emittance_factor(curve, local + t);
  for (int c = 0; c < scene_.channels; ++c) {
    const auto k = static_cast<std::size_t>(c);
    result[k] = curve.emittance[k] * factor;
  }
  if (!any_positive(material.reflectivity, scene_.channels)) return result;

  // The element that holds the point: equal arc-length pieces of the segment.
  const std::uint32_t pieces = segment_count_[segment_index];
  const double s = segment.arc_length.length_at(segment.geometry.shape, t);
  const auto piece = static_cast<std::uint32_t>(
      std::clamp(std::floor(s / (segment.length / pieces)), 0.0, pieces - 1.0));
  const std::uint32_t self = segment_first_[segment_index] + piece;

  const Vec2 x = evaluate(segment.geometry.shape, t);
  Vec2 normal = unit_normal(segment.geometry.shape, t, scene_.scale);
  if (side == Side::Back) normal = -normal;
  Sweeper sweeper;
  std::vector<VisibleElement> visible;
  sweeper.run(elements_, x, normal, self, side, visible);
  for (int c = 0; c < scene_.channels; ++c) {
    const auto k = static_cast<std::size_t>(c);
    double gathered = 0.0;
    for (const VisibleElement& v : visible)
      gathered += v.form_factor * radiosity_[k][patch_index(v.element, v.side)];
    result[k] += material.reflectivity[k] * gathered;
  }
  return result;
}

double reference_element_count(const Scene& scene, const ReferenceSettings& settings) {
  const double max_length =
      settings.max_element_length > 0.0 ? settings.max_element_length : scene.scale / 400.0;
  double count = 0.0;
  for (const SceneSegment& segment : scene.segments)
    count += std::max(1.0, std::ceil(segment.length / max_length));
  return count;
}

Result<ReferenceSolution> solve_reference(const Scene& scene, const ReferenceSettings& settings) {
  if (Status status = validate(settings); !status) return status.error();
  for (const Curve& curve : scene.curves) {
    if (scene.is_emitter(curve) &&
        scene.material_of(curve).emission.kind != Emission::Kind::Diffuse)
      return Error{scene.source + ": curve '" + curve.id +
                   "': the reference solver supports diffuse emitters only"};
  }
  ReferenceSolution solution;
  solution.scene_ = scene;
  solution.settings_ = settings;
  const double max_length =
      settings.max_element_length > 0.0 ? settings.max_element_length : scene.scale / 400.0;
  const auto cancelled = [&settings] {
    return settings.cancel != nullptr && settings.cancel->load(std::memory_order_relaxed);
  };

  // The element count first, to refuse work that cannot finish before any of it is done.
  const double element_total = reference_element_count(scene, settings);
  if (element_total > static_cast<double>(kMaxReferenceElements)) {
    char message[320];
    std::snprintf(message, sizeof message,
                  "%.4g reference elements (elements of length %.3g); at most %zu: form factors "
                  "take time and memory growing as the square of the count; use fewer elements "
                  "(--elements or --max-element-length)",
                  element_total, max_length, kMaxReferenceElements);
    return Error{message};
  }
  const std::size_t memory_limit =
      settings.memory_limit != 0 ? settings.memory_limit : default_memory_budget();

  // 1. Elements: equal arc-length chords of every segment.
  std::vector<ReferenceElement>& elements = solution.elements_;
  solution.segment_first_.assign(scene.segments.size(), 0);
  solution.segment_count_.assign(scene.segments.size(), 0);
  for (std::uint32_t si = 0; si < scene.segments.size(); ++si) {
    const SceneSegment& segment = scene.segments[si];
    const Curve& curve = scene.curves[segment.curve];
    const Material& material = scene.material_of(curve);
    const Cubic& shape = segment.geometry.shape;
    const double pieces_real = std::max(1.0, std::ceil(segment.length / max_length));
    const auto pieces = static_cast<std::uint32_t>(pieces_real);
    solution.segment_first_[si] = static_cast<std::uint32_t>(elements.size());
    solution.segment_count_[si] = pieces;
    const double step = segment.length / pieces;
    auto point_at = [&](std::uint32_t k) {
      if (k == 0) return shape.p[0];
      if (k == pieces) return shape.p[3];
      return evaluate(shape, segment.arc_length.parameter_at(shape, k * step));
    };
    Vec2 start = point_at(0);
    for (std::uint32_t k = 0; k < pieces; ++k) {
      const Vec2 end = point_at(k + 1);
      ReferenceElement e;
      e.a = start;
      e.b = end;
      e.length = length(end - start);
      if (!(e.length > 0.0))
        return Error{scene.source + ": curve '" + curve.id + "': a chord of zero length"};
      e.normal = (1.0 / e.length) * perp(end - start);
      e.curve = segment.curve;
      e.segment = si;
      e.u_mid = segment.index_in_curve + segment.arc_length.parameter_at(shape, (k + 0.5) * step);
      const double factor = emittance_factor(curve, e.u_mid);
      for (const Side side : {Side::Front, Side::Back}) {
        if (!curve.has_side(side)) continue;
        const auto sd = static_cast<std::size_t>(side);
        for (int c = 0; c < scene.channels; ++c) {
          const auto ch = static_cast<std::size_t>(c);
          e.reflectivity[sd][ch] = material.reflectivity[ch];
          e.emittance[sd][ch] = curve.emittance[ch] * factor;
        }
      }
      elements.push_back(e);
      start = end;
    }
  }
  const auto element_count = static_cast<std::uint32_t>(elements.size());
  const std::size_t patch_count = 2 * static_cast<std::size_t>(element_count);
  // Patches that carry radiosity (reflect or emit) and patches that need a row (reflect).
  std::vector<char> carries(patch_count, 0);
  solution.patch_row_.assign(patch_count, kNoElement);
  for (std::uint32_t j = 0; j < element_count; ++j) {
    for (const Side side : {Side::Front, Side::Back}) {
      const auto sd = static_cast<std::size_t>(side);
      const bool reflects = any_positive(elements[j].reflectivity[sd], scene.channels);
      const bool emits = any_positive(elements[j].emittance[sd], scene.channels);
      carries[patch_index(j, side)] = reflects || emits;
      if (reflects) {
        solution.patch_row_[patch_index(j, side)] =
            static_cast<std::uint32_t>(solution.row_patch_.size());
        solution.row_patch_.push_back(static_cast<std::uint32_t>(patch_index(j, side)));
      }
    }
  }

  // 2-3. Rows of F by quadrature over the element, crossed strings where the pair sees each other
  // whole from every quadrature point and each lies in front of the other.
  const auto clock_start = std::chrono::steady_clock::now();
  const std::size_t rows = solution.row_patch_.size();
  std::vector<double> nodes;
  std::vector<double> weights;
  gauss_legendre_unit(settings.quadrature, nodes, weights);
  std::vector<std::vector<std::pair<std::uint32_t, double>>> row_entries(rows);
  std::vector<double> row_sums(rows, 0.0);
  std::atomic<std::size_t> next_row{0};
  // Bytes of the rows so far (each entry of a row and of the final CSR copy: a column index and
  // a value); past the memory limit every worker stops.
  constexpr double kBytesPerEntry = 2.0 * (sizeof(std::uint32_t) + sizeof(double)) + 4.0;
  std::atomic<std::size_t> entry_count{0};
  std::atomic<bool> out_of_memory{false};
  std::atomic<std::size_t> rows_done{0};
  auto worker = [&](bool reports) {
    auto last_report = std::chrono::steady_clock::now();
    Sweeper sweeper;
    std::vector<VisibleElement> visible;
    std::vector<double> accumulated(patch_count, 0.0);
    std::vector<int> whole_count(patch_count, 0);
    std::vector<std::uint32_t> touched;
    for (;;) {
      if (cancelled() || out_of_memory.load(std::memory_order_relaxed)) break;
      const std::size_t row = next_row.fetch_add(1);
      if (row >= rows) break;
      const std::uint32_t patch = solution.row_patch_[row];
      const std::uint32_t i = patch / 2;
      const Side side = static_cast<Side>(patch % 2);
      const ReferenceElement& ei = elements[i];
      const Vec2 normal = side == Side::Front ? ei.normal : -ei.normal;
      touched.clear();
      for (std::size_t q = 0; q < nodes.size(); ++q) {
        const Vec2 x = lerp(ei.a, ei.b, nodes[q]);
        sweeper.run(elements, x, normal, i, side, visible);
        for (const VisibleElement& v : visible) {
          const std::size_t p = patch_index(v.element, v.side);
          if (accumulated[p] == 0.0 && whole_count[p] == 0) touched.push_back(static_cast<std::uint32_t>(p));
          accumulated[p] += weights[q] * v.form_factor;
          whole_count[p] += v.whole ? 1 : 0;
        }
      }
      std::sort(touched.begin(), touched.end());
      auto& entries = row_entries[row];
      double sum = 0.0;
      for (const std::uint32_t p : touched) {
        double f = accumulated[p];
        const std::uint32_t j = p / 2;
        const Side side_j = static_cast<Side>(p % 2);
        if (whole_count[p] == settings.quadrature && in_front_of(ei, side, elements[j]) &&
            in_front_of(elements[j], side_j, ei)) {
          const ReferenceElement& ej = elements[j];
          f = crossed_strings(ei.a, ei.b, ej.a, ej.b);
        }
        accumulated[p] = 0.0;
        whole_count[p] = 0;
        sum += f;
        if (carries[p] && f > 0.0) entries.emplace_back(p, f);
      }
      row_sums[row] = sum;
      const std::size_t total = entry_count.fetch_add(entries.size()) + entries.size();
      if (static_cast<double>(total) * kBytesPerEntry > static_cast<double>(memory_limit))
        out_of_memory.store(true);
      const std::size_t done = rows_done.fetch_add(1) + 1;
      if (reports && settings.progress && seconds_since(last_report) >= 0.25) {
        last_report = std::chrono::steady_clock::now();
        settings.progress(done, rows);
      }
    }
  };
  {
    const unsigned threads =
        static_cast<unsigned>(std::min<std::size_t>(thread_count(settings.threads), std::max<std::size_t>(rows, 1)));
    std::vector<std::thread> pool;
    for (unsigned k = 1; k < threads; ++k) pool.emplace_back(worker, false);
    worker(true);
    for (std::thread& thread : pool) thread.join();
  }
  if (cancelled()) return Error{kReferenceCancelled};
  if (out_of_memory.load()) {
    const std::size_t done = std::min(next_row.load(), rows);
    const double projected = static_cast<double>(entry_count.load()) * kBytesPerEntry *
                             static_cast<double>(rows) / static_cast<double>(std::max<std::size_t>(done, 1));
    return Error{std::to_string(element_count) + " reference elements: the form factors would need about " +
                 format_bytes(projected) + ", more than the memory limit of " +
                 format_bytes(static_cast<double>(memory_limit)) +
                 "; use fewer elements (--elements or --max-element-length)"};
  }
  solution.row_begin_.assign(rows + 1, 0);
  for (std::size_t r = 0; r < rows; ++r)
    solution.row_begin_[r + 1] = solution.row_begin_[r] + row_entries[r].size();
  solution.column_.reserve(solution.row_begin_[rows]);
  solution.value_.reserve(solution.row_begin_[rows]);
  for (std::size_t r = 0; r < rows; ++r) {
    for (const auto& [p, f] : row_entries[r]) {
      solution.column_.push_back(p);
      solution.value_.push_back(f);
    }
    std::vector<std::pair<std::uint32_t, double>>().swap(row_entries[r]);
  }
  solution.row_sums_ = std::move(row_sums);
  solution.form_factor_seconds_ = seconds_since(clock_start);

  // 4. Per channel, (I - diag(rho) F) b = e by restarted GMRES (see gmres above), starting from
  // b = e. Patches without a row (non-reflecting) are identity rows: they keep b = e.
  const auto solve_start = std::chrono::steady_clock::now();
  solution.iterations_ = 0;
  solution.residual_ = 0.0;
  solution.error_bound_ = 0.0;
  for (int c = 0; c < scene.channels; ++c) {
    const auto ch = static_cast<std::size_t>(c);
    std::vector<double> rhs(patch_count, 0.0);
    std::vector<double> rho(rows, 0.0);
    // The contraction q = max_p rho_p sum_q F_pq bounds ||diag(rho) F||_inf, so
    // ||(I - diag(rho) F)^-1||_inf <= 1 / (1 - q).
    double contraction = 0.0;
    for (std::size_t p = 0; p < patch_count; ++p) rhs[p] = elements[p / 2].emittance[p % 2][ch];
    for (std::size_t r = 0; r < rows; ++r) {
      const std::uint32_t p = solution.row_patch_[r];
      rho[r] = elements[p / 2].reflectivity[p % 2][ch];
      contraction = std::max(contraction, rho[r] * solution.row_sums_[r]);
    }
    const double amplification = 1.0 / std::max(1.0 - contraction, 1e-9);
    auto apply = [&](const std::vector<double>& x, std::vector<double>& y) {
      y = x;
      for (std::size_t r = 0; r < rows; ++r) {
        double gathered = 0.0;
        for (std::size_t k = solution.row_begin_[r]; k < solution.row_begin_[r + 1]; ++k)
          gathered += solution.value_[k] * x[solution.column_[k]];
        y[solution.row_patch_[r]] -= rho[r] * gathered;
      }
    };
    std::vector<double>& b = solution.radiosity_[ch];
    b = rhs;
    const KrylovOutcome outcome =
        gmres(apply, rhs, b, settings.tolerance / amplification, settings.max_iterations, settings.cancel);
    if (outcome.cancelled) return Error{kReferenceCancelled};
    solution.iterations_ = std::max(solution.iterations_, outcome.iterations);
    solution.residual_ = std::max(solution.residual_, outcome.relative_residual);
    solution.error_bound_ = std::max(solution.error_bound_, outcome.relative_residual * amplification);
  }
  solution.solve_seconds_ = seconds_since(solve_start);
  return solution;
}

}  // namespace flatland
