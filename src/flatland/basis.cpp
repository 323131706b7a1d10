#include "flatland/basis.hpp"

#include <algorithm>
#include <array>
#include <cassert>
#include <cmath>

namespace flatland {

const char* to_string(BasisKind kind) {
  switch (kind) {
    case BasisKind::Constant: return "constant";
    case BasisKind::Linear: return "linear";
    case BasisKind::Cubic: return "cubic";
  }
  return "?";
}

int SplineBasis::multiplicity(int degree, Continuity continuity) {
  // Multiplicity m at a knot leaves C^(degree - m) continuity: m = degree - c, clamped to what a
  // spline of this degree can express (a constant spline jumps at every knot).
  const int c = static_cast<int>(continuity);
  return std::clamp(degree - c, 1, degree + 1);
}

SplineBasis::SplineBasis(int degree, double u_begin, double u_end, std::span<const MeshNode> nodes)
    : degree_(degree) {
  assert(degree >= 0 && degree <= kMaxDegree && u_begin < u_end);
  knots_.assign(static_cast<std::size_t>(degree + 1), u_begin);
  for (const MeshNode& node : nodes) {
    assert(node.u > u_begin && node.u < u_end);
    knots_.insert(knots_.end(), static_cast<std::size_t>(multiplicity(degree, node.continuity)),
                  node.u);
  }
  knots_.insert(knots_.end(), static_cast<std::size_t>(degree + 1), u_end);
  size_ = knots_.size() - static_cast<std::size_t>(degree) - 1;
}

std::size_t SplineBasis::find_span(double u) const {
  // The span i with knots[i] <= u < knots[i+1], among i in [degree, size-1]; u at the very end
  // belongs to the last non-empty span.
  const std::size_t p = static_cast<std::size_t>(degree_);
  if (u >= knots_[size_]) return size_ - 1;
  if (u <= knots_[p]) return p;
  // upper_bound gives the first knot > u; the span starts one before it.
  const auto it = std::upper_bound(knots_.begin() + static_cast<std::ptrdiff_t>(p),
                                   knots_.begin() + static_cast<std::ptrdiff_t>(size_) + 1, u);
  return static_cast<std::size_t>(it - knots_.begin()) - 1;
}

std::size_t SplineBasis::evaluate(double u, double* values) const {
  // Cox-de Boor recursion in the triangular form of Piegl and Tiller (The NURBS Book, A2.2):
  // builds the nonzero functions of degree j from those of degree j-1 without division by zero,
  // since only non-empty spans are visited.
  const std::size_t span = find_span(u);
  const int p = degree_;
  std::array<double, kMaxDegree + 1> left{};
  std::array<double, kMaxDegree + 1> right{};
  values[0] = 1.0;
  for (int j = 1; j <= p; ++j) {
    left[j] = u - knots_[span + 1 - static_cast<std::size_t>(j)];
    right[j] = knots_[span + static_cast<std::size_t>(j)] - u;
    double saved = 0.0;
    for (int r = 0; r < j; ++r) {
      const double temp = values[r] / (right[r + 1] + left[j - r]);
      values[r] = saved + right[r + 1] * temp;
      saved = left[j - r] * temp;
    }
    values[j] = saved;
  }
  return span - static_cast<std::size_t>(p);
}

namespace {

// 8-point Gauss-Legendre nodes and weights on [-1, 1].
constexpr std::array<double, 8> kGaussNodes = {
    -0.9602898564975362317, -0.7966664774136267396, -0.5255324099163289858, -0.1834346424956498049,
    0.1834346424956498049,  0.5255324099163289858,  0.7966664774136267396,  0.9602898564975362317};
constexpr std::array<double, 8> kGaussWeights = {
    0.1012285362903762591, 0.2223810344533744706, 0.3137066458778872873, 0.3626837833783619830,
    0.3626837833783619830, 0.3137066458778872873, 0.2223810344533744706, 0.1012285362903762591};

}  // namespace

CurveStorage build_curve_storage(const Scene& scene, const Curve& curve, BasisKind kind,
                                 int elements) {
  CurveStorage storage;
  const std::uint32_t segment_count = curve.segment_count;
  const int wanted = std::max(elements, 1);

  for (std::uint32_t i = 0; i < segment_count; ++i) {
    const SceneSegment& segment = scene.segments[curve.first_segment + i];
    if (i > 0) storage.nodes.push_back({static_cast<double>(i), curve.joints[i - 1]});
    const double share = wanted * segment.length / curve.length;
    const int pieces = std::max(1, static_cast<int>(std::lround(share)));
    for (int j = 1; j < pieces; ++j) {
      const double s = segment.length * j / pieces;
      const double t = segment.arc_length.parameter_at(segment.geometry.shape, s);
      storage.nodes.push_back({i + t, Continuity::C1});
    }
  }
  storage.basis = SplineBasis(degree_of(kind), 0.0, static_cast<double>(segment_count),
                              storage.nodes);

  // Integrals of phi_k |C'(u)| du, span by span. Each non-empty span lies in one segment; four
  // 8-point Gauss-Legendre panels per span integrate the cubic-times-speed product to far below
  // Monte Carlo noise.
  storage.basis_length.assign(storage.basis.size(), 0.0);
  const std::vector<double>& knots = storage.basis.knots();
  std::array<double, SplineBasis::kMaxDegree + 1> values{};
  constexpr int kPanels = 4;
  for (std::size_t k = 0; k + 1 < knots.size(); ++k) {
    const double a = knots[k];
    const double b = knots[k + 1];
    if (!(b > a)) continue;
    const auto segment_index = static_cast<std::uint32_t>(
        std::min<double>(std::floor(0.5 * (a + b)), segment_count - 1));
    const SceneSegment& segment = scene.segments[curve.first_segment + segment_index];
    for (int panel = 0; panel < kPanels; ++panel) {
      const double pa = a + (b - a) * panel / kPanels;
      const double pb = a + (b - a) * (panel + 1) / kPanels;
      const double half = 0.5 * (pb - pa);
      for (std::size_t g = 0; g < kGaussNodes.size(); ++g) {
        const double u = 0.5 * (pa + pb) + half * kGaussNodes[g];
        const double t = u - segment_index;
        const double speed = length(derivative(segment.geometry.shape, t));
        const std::size_t first = storage.basis.evaluate(u, values.data());
        for (int j = 0; j <= storage.basis.degree(); ++j) {
          storage.basis_length[first + static_cast<std::size_t>(j)] +=
              kGaussWeights[g] * half * speed * values[static_cast<std::size_t>(j)];
        }
      }
    }
  }
  return storage;
}

}  // namespace flatland
