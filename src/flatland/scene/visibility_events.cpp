// Direct-light events (D1) from the geometry: tangent points and bitangents as polynomial roots in
// Bernstein form isolated by subdivision, refined by bisection or Newton, and ray casts for
// visibility.
#include "flatland/scene/discontinuities.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <utility>

#include "flatland/base/roots.hpp"
#include "flatland/geometry/bernstein.hpp"
#include "flatland/scene/discontinuity_common.hpp"

namespace flatland {

using namespace discontinuity_detail;
using bernstein::isolate_roots;
using bernstein::split_half;

namespace {

// A line through a tangent point grazes the curve there; rounding splits the double root into two
// crossings about sqrt(2 rounding / curvature) apart. Crossings of the point's own curve closer than
// kGraze * scale to it are that graze, not a hit.
constexpr double kGraze = 1e-6;
// An event line is followed through at most this many mirror reflections.
constexpr int kMirrorBounces = 8;
// A direction whose sine with a segment's tangent is below this runs along the segment.
constexpr double kAlongSine = 1e-9;

constexpr double kBinomial[6][6] = {{1, 0, 0, 0, 0, 0}, {1, 1, 0, 0, 0, 0}, {1, 2, 1, 0, 0, 0},
                                    {1, 3, 3, 1, 0, 0}, {1, 4, 6, 4, 1, 0}, {1, 5, 10, 10, 5, 1}};

// ---------------------------------------------------------------------------------------------
// Tangent points from a point.

// g(t) = cross(C(t) - p, C'(t)) in Bernstein form of degree 5. With C(t) - p = sum_i B_i^3(t) a_i,
// a_i = P_i - p, and C'(t) = sum_j B_j^2(t) d_j, d_j = 3 (P_(j+1) - P_j), the product rule of the
// Bernstein basis gives b_k = sum_(i+j=k) C(3,i) C(2,j) / C(5,k) cross(a_i, d_j). *noise is the
// rounding of the coefficients (a few ulps of the largest product).
void tangent_coefficients(const Cubic& c, Vec2 p, double b[6], double* noise) {
  Vec2 a[4];
  Vec2 d[3];
  double a_max = 0.0;
  double d_max = 0.0;
  for (int i = 0; i < 4; ++i) {
    a[i] = c.p[i] - p;
    a_max = std::max(a_max, length(a[i]));
  }
  for (int j = 0; j < 3; ++j) {
    d[j] = 3.0 * (c.p[j + 1] - c.p[j]);
    d_max = std::max(d_max, length(d[j]));
  }
  for (int k = 0; k <= 5; ++k) {
    double sum = 0.0;
    for (int i = std::max(0, k - 2); i <= std::min(3, k); ++i) {
      sum += kBinomial[3][i] * kBinomial[2][k - i] * cross(a[i], d[k - i]);
    }
    b[k] = sum / kBinomial[5][k];
  }
  *noise = 64.0 * kEpsilon * a_max * d_max;
}

double tangent_function(const Cubic& c, Vec2 p, double t) { return cross(evaluate(c, t) - p, derivative(c, t)); }

// The interior tangent points of one curved segment from p (simple roots of g in (0,1)).
void segment_tangent_points(const Cubic& c, Vec2 p, std::vector<double>& roots) {
  double b[6];
  double noise = 0.0;
  tangent_coefficients(c, p, b, &noise);
  isolate_roots(
      b, 5, 0.0, 1.0, noise, [&](double t) { return tangent_function(c, p, t); }, 0, roots);
}

// A point of a curve where a critical line touches it.
struct Feature {
  Vec2 position;
  std::uint32_t curve = 0;
  std::uint32_t segment = kNoSegment;  // index into Scene::segments
  double t = 0.0;
  double u = 0.0;
  const Vertex* vertex = nullptr;  // null: a tangent point of a curved piece
};

// The tangent points of a curve seen from p, as features: interior roots of every curved segment,
// and tangent-continuous joints between curved segments where g changes sign across the joint
// (the tangent point is the joint itself, up to 1e-10 in t). Points within kTouch * scale of p and
// at vertices are dropped; roots within kSameParameter are one.
std::vector<Feature> curve_tangent_points(const Scene& scene, std::uint32_t c, Vec2 p,
                                          const std::vector<Vertex>& vertices) {
  const Curve& curve = scene.curves[c];
  std::vector<Feature> out;
  if (curve.kind == SegmentKind::Line) return out;
  const double touch = kTouch * scene.scale;
  std::vector<char> curved(curve.segment_count);
  std::vector<double> roots;
  for (std::uint32_t j = 0; j < curve.segment_count; ++j) {
    const SceneSegment& segment = scene.segments[curve.first_segment + j];
    curved[j] = !is_straight(segment.geometry, scene.scale);
    if (!curved[j]) continue;
    const Cubic& shape = segment.geometry.shape;
    // Cheap rejection: p inside the hull's box can still see tangents, so only the sign test of the
    // coefficients prunes (inside isolate_roots).
    roots.clear();
    segment_tangent_points(shape, p, roots);
    for (const double t : roots) out.push_back({evaluate(shape, t), c, curve.first_segment + j, t, j + t, nullptr});
  }
  constexpr double kJointStep = 1e-10;
  for (std::uint32_t j = 0; j < curve.joint_count(); ++j) {
    const std::uint32_t next = j + 1 == curve.segment_count ? 0 : j + 1;
    if (!curved[j] || !curved[next] || !is_tangent_continuous(scene, curve, j)) continue;
    const Cubic& a = scene.segments[curve.first_segment + j].geometry.shape;
    const Cubic& b = scene.segments[curve.first_segment + next].geometry.shape;
    const double left = tangent_function(a, p, 1.0 - kJointStep);
    const double right = tangent_function(b, p, kJointStep);
    if ((left < 0.0 && right > 0.0) || (left > 0.0 && right < 0.0))
      out.push_back({b.p[0], c, curve.first_segment + next, 0.0, static_cast<double>(next), nullptr});
  }
  std::erase_if(out, [&](const Feature& f) {
    if (length(f.position - p) <= touch) return true;
    for (const Vertex& v : vertices) {
      const double gap = std::fabs(f.u - v.u);
      if (gap <= kSameParameter || (curve.closed && std::fabs(gap - curve.segment_count) <= kSameParameter))
        return true;
    }
    return false;
  });
  std::sort(out.begin(), out.end(), [](const Feature& x, const Feature& y) { return x.u < y.u; });
  std::vector<Feature> unique;
  for (const Feature& f : out) {
    if (!unique.empty() && f.u - unique.back().u <= kSameParameter) continue;
    unique.push_back(f);
  }
  if (curve.closed && unique.size() >= 2 && unique.front().u + curve.segment_count - unique.back().u <= kSameParameter)
    unique.pop_back();
  return unique;
}

// ---------------------------------------------------------------------------------------------
// Bitangents of two cubic segments: G1(t,u) = cross(A'(t), B'(u)) = 0 (parallel tangents) and
// G2(t,u) = cross(B(u) - A(t), A'(t)) = 0 (B(u) on A's tangent line at t), an equivalent form of
// cross(A - B, A') = 0 = cross(A - B, B') away from A(t) = B(u). Both are tensor-product Bernstein
// polynomials: G1 of degree (2,2) with coefficients cross(a_i, b_j) (a_i, b_j the hodographs'
// control vectors), G2 of degree (5,3) with coefficients
//   sum_(i+l=k) C(3,i) C(2,l) / C(5,k) cross(Q_j - P_i, a_l)
// (B(u) - A(t) = sum_i sum_j B_i^3(t) B_j^3(u) (Q_j - P_i), times A'(t)). Boxes of (t,u) where
// either has coefficients of one strict sign hold no solution; the others are halved down to 1/32,
// where Newton on (G1, G2) from the box's centre is tried (the Jacobian is regular at a bitangent of
// two curved pieces), further halving where it fails.

struct BitangentBox {
  double t0, t1, u0, u1;
  double g1[3][3];  // [t][u]
  double g2[6][4];  // [t][u]
};

template <int T, int U>
void split_t(const double (&c)[T][U], double (&left)[T][U], double (&right)[T][U]) {
  for (int j = 0; j < U; ++j) {
    double column[6];
    double l[6];
    double r[6];
    for (int i = 0; i < T; ++i) column[i] = c[i][j];
    split_half(column, T - 1, l, r);
    for (int i = 0; i < T; ++i) {
      left[i][j] = l[i];
      right[i][j] = r[i];
    }
  }
}

template <int T, int U>
void split_u(const double (&c)[T][U], double (&left)[T][U], double (&right)[T][U]) {
  for (int i = 0; i < T; ++i) split_half(c[i], U - 1, left[i], right[i]);
}

template <int T, int U>
bool one_sign(const double (&c)[T][U]) {
  bool positive = true;
  bool negative = true;
  for (int i = 0; i < T; ++i) {
    for (int j = 0; j < U; ++j) {
      positive = positive && c[i][j] > 0.0;
      negative = negative && c[i][j] < 0.0;
    }
  }
  return positive || negative;
}

template <int T, int U>
double largest(const double (&c)[T][U]) {
  double m = 0.0;
  for (int i = 0; i < T; ++i)
    for (int j = 0; j < U; ++j) m = std::max(m, std::fabs(c[i][j]));
  return m;
}

// Newton on (G1, G2) from (t, u); true with the solution when it converges.
bool bitangent_newton(const Cubic& a, const Cubic& b, double& t, double& u) {
  for (int iteration = 0; iteration < 40; ++iteration) {
    const Vec2 pa = evaluate(a, t);
    const Vec2 pb = evaluate(b, u);
    const Vec2 da = derivative(a, t);
    const Vec2 db = derivative(b, u);
    const Vec2 dda = second_derivative(a, t);
    const Vec2 ddb = second_derivative(b, u);
    const double g1 = cross(da, db);
    const double g2 = cross(pb - pa, da);
    // d/dt G1 = cross(A'', B'), d/du G1 = cross(A', B''); d/dt G2 = cross(B - A, A''),
    // d/du G2 = cross(B', A').
    const double j11 = cross(dda, db);
    const double j12 = cross(da, ddb);
    const double j21 = cross(pb - pa, dda);
    const double j22 = cross(db, da);
    const double det = j11 * j22 - j12 * j21;
    if (!(std::fabs(det) > 0.0) || !std::isfinite(det)) return false;
    const double dt = (g1 * j22 - g2 * j12) / det;
    const double du = (j11 * g2 - j21 * g1) / det;
    t -= dt;
    u -= du;
    if (!(t > -0.5 && t < 1.5 && u > -0.5 && u < 1.5)) return false;
    if (std::fabs(dt) <= 1e-15 && std::fabs(du) <= 1e-15) return true;
  }
  return false;
}

std::vector<std::pair<double, double>> segment_bitangents(const Cubic& a, const Cubic& b, double scale) {
  BitangentBox root{0.0, 1.0, 0.0, 1.0, {}, {}};
  Vec2 da[3];
  Vec2 db[3];
  for (int i = 0; i < 3; ++i) {
    da[i] = 3.0 * (a.p[i + 1] - a.p[i]);
    db[i] = 3.0 * (b.p[i + 1] - b.p[i]);
  }
  double g1_magnitude = 0.0;
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) {
      root.g1[i][j] = cross(da[i], db[j]);
      g1_magnitude = std::max(g1_magnitude, length(da[i]) * length(db[j]));
    }
  }
  double g2_magnitude = 0.0;
  for (int k = 0; k <= 5; ++k) {
    for (int j = 0; j < 4; ++j) {
      double sum = 0.0;
      for (int i = std::max(0, k - 2); i <= std::min(3, k); ++i) {
        const Vec2 offset = b.p[j] - a.p[i];
        sum += kBinomial[3][i] * kBinomial[2][k - i] * cross(offset, da[k - i]);
        g2_magnitude = std::max(g2_magnitude, length(offset) * length(da[k - i]));
      }
      root.g2[k][j] = sum / kBinomial[5][k];
    }
  }
  const double noise1 = 64.0 * kEpsilon * g1_magnitude;
  const double noise2 = 64.0 * kEpsilon * g2_magnitude;
  std::vector<std::pair<double, double>> found;
  std::vector<BitangentBox> stack{root};
  int budget = 20000;
  while (!stack.empty() && budget-- > 0) {
    const BitangentBox box = stack.back();
    stack.pop_back();
    if (one_sign(box.g1) || one_sign(box.g2)) continue;
    if (largest(box.g1) <= noise1 && largest(box.g2) <= noise2) continue;  // collinear straight pieces
    const double wt = box.t1 - box.t0;
    const double wu = box.u1 - box.u0;
    if (wt <= 1.0 / 32 && wu <= 1.0 / 32) {
      double t = 0.5 * (box.t0 + box.t1);
      double u = 0.5 * (box.u0 + box.u1);
      if (bitangent_newton(a, b, t, u) && t >= box.t0 - 0.1 * wt && t <= box.t1 + 0.1 * wt && u >= box.u0 - 0.1 * wu &&
          u <= box.u1 + 0.1 * wu && t >= 0.0 && t <= 1.0 && u >= 0.0 && u <= 1.0) {
        if (length(evaluate(a, t) - evaluate(b, u)) > kTouch * scale) found.emplace_back(t, u);
        continue;
      }
      if (wt <= 1e-7 && wu <= 1e-7) continue;  // a degenerate point (a touching of the curves)
    }
    BitangentBox first = box;
    BitangentBox second = box;
    if (wt >= wu) {
      split_t(box.g1, first.g1, second.g1);
      split_t(box.g2, first.g2, second.g2);
      first.t1 = second.t0 = 0.5 * (box.t0 + box.t1);
    } else {
      split_u(box.g1, first.g1, second.g1);
      split_u(box.g2, first.g2, second.g2);
      first.u1 = second.u0 = 0.5 * (box.u0 + box.u1);
    }
    stack.push_back(second);
    stack.push_back(first);
  }
  std::sort(found.begin(), found.end());
  std::vector<std::pair<double, double>> unique;
  append_new_pairs(found, unique);
  return unique;
}

// Bitangent features of two curves: pairs of tangent points (on a, on b).
std::vector<std::pair<Feature, Feature>> curve_bitangents(const Scene& scene, std::uint32_t ca, std::uint32_t cb,
                                                          const std::vector<Vertex>& vertices_a,
                                                          const std::vector<Vertex>& vertices_b) {
  std::vector<std::pair<Feature, Feature>> out;
  const Curve& curve_a = scene.curves[ca];
  const Curve& curve_b = scene.curves[cb];
  if (curve_a.kind == SegmentKind::Line || curve_b.kind == SegmentKind::Line) return out;
  auto at_vertex = [](const Curve& curve, const std::vector<Vertex>& vertices, double u) {
    for (const Vertex& v : vertices) {
      const double gap = std::fabs(u - v.u);
      if (gap <= kSameParameter || (curve.closed && std::fabs(gap - curve.segment_count) <= kSameParameter))
        return true;
    }
    return false;
  };
  for (std::uint32_t i = 0; i < curve_a.segment_count; ++i) {
    const std::uint32_t sa = curve_a.first_segment + i;
    const SegmentGeometry& ga = scene.segments[sa].geometry;
    if (is_straight(ga, scene.scale)) continue;
    for (std::uint32_t j = 0; j < curve_b.segment_count; ++j) {
      const std::uint32_t sb = curve_b.first_segment + j;
      if (sa == sb) continue;  // a single cubic has no bitangent with itself that matters here
      const SegmentGeometry& gb = scene.segments[sb].geometry;
      if (is_straight(gb, scene.scale)) continue;
      for (const auto& [t, u] : segment_bitangents(ga.shape, gb.shape, scene.scale)) {
        const double ua = wrap(curve_a, i + t);
        const double ub = wrap(curve_b, j + u);
        if (at_vertex(curve_a, vertices_a, ua) || at_vertex(curve_b, vertices_b, ub)) continue;
        bool seen = false;
        for (const auto& [fa, fb] : out) {
          seen = seen || (std::fabs(fa.u - ua) <= kSameParameter && std::fabs(fb.u - ub) <= kSameParameter);
        }
        if (seen) continue;
        out.push_back({Feature{evaluate(ga.shape, t), ca, sa, t, ua, nullptr},
                       Feature{evaluate(gb.shape, u), cb, sb, u, ub, nullptr}});
      }
    }
  }
  return out;
}

// ---------------------------------------------------------------------------------------------
// The rules of a critical line at its two touching points.

// The unit tangent at a vertex pointing into the segment s (which starts or ends there).
Vec2 outgoing_tangent(const Scene& scene, std::uint32_t s, bool starts_here) {
  const Cubic& c = scene.segments[s].geometry.shape;
  return starts_here ? unit_tangent(c, 0.0, scene.scale) : -unit_tangent(c, 1.0, scene.scale);
}

// Which side of the line through the vertex with direction d the segment s lies on near the vertex
// (+1 left, -1 right, 0 along it): by its tangent there, or by its middle when the tangent runs
// along the line (a cubic leaving a vertex along the line curves off to one side).
int side_of_line(const Scene& scene, const Vertex& v, std::uint32_t s, bool starts_here, Vec2 d) {
  const double sine = cross(d, outgoing_tangent(scene, s, starts_here));
  if (std::fabs(sine) > kAlongSine) return sine > 0.0 ? 1 : -1;
  const SegmentGeometry& g = scene.segments[s].geometry;
  if (g.kind == SegmentKind::Line) return 0;
  const Vec2 middle = evaluate(g.shape, 0.5) - v.position;
  const double off = cross(d, middle);
  if (std::fabs(off) <= kTouch * scene.scale) return 0;
  return off > 0.0 ? 1 : -1;
}

// Whether the line through the vertex crosses its curve there (the segments on strictly opposite
// sides).
bool line_crosses_at(const Scene& scene, const Vertex& v, Vec2 d) {
  if (v.before == kNoSegment || v.after == kNoSegment) return false;
  const int a = side_of_line(scene, v, v.before, false, d);
  const int b = side_of_line(scene, v, v.after, true, d);
  return a * b < 0;
}

// Whether some channel of the curve's material reflects (a secondary source).
bool reflects(const Scene& scene, const Curve& curve) {
  const Material& material = scene.material_of(curve);
  for (int channel = 0; channel < scene.channels; ++channel)
    if (material.reflectivity[static_cast<std::size_t>(channel)] > 0.0) return true;
  return false;
}

bool emits_toward(const Curve& curve, const Vec2 normal, Vec2 d, bool straight) {
  const double facing = dot(normal, d);
  if (facing > kAlongSine) return curve.has_side(Side::Front);
  if (facing < -kAlongSine) return curve.has_side(Side::Back);
  return straight;  // a straight piece seen edge-on along the line: its light vanishes across it
}

// The source rule at a point A of the emitter.
//  - Vertex: some adjacent segment's emitting side faces d (x = A + s d sees that side), or a
//    straight adjacent segment runs along the line. A corner the line passes through (segments on
//    both sides) is a silhouette of nothing: with diffuse emission of continuous radiance the
//    visible part's end moves smoothly across it, so it counts only for non-diffuse emission
//    (the radiance jumps with the normal there).
//  - Tangent point: the line is S's tangent there, and near the touching point x sees the branch of S
//    that runs toward x, whose visible side is the convex one (away from the centre of curvature).
//    The line bounds the visible emitting part iff that convex side emits. At an inflection (zero
//    curvature) it bounds nothing.
bool source_allows(const Scene& scene, const Feature& a, Vec2 d) {
  const Curve& curve = scene.curves[a.curve];
  if (a.vertex != nullptr) {
    const Vertex& v = *a.vertex;
    // (A reflector reflects diffusely: a secondary source is diffuse whatever its emission.)
    const bool diffuse = !scene.is_emitter(curve) || scene.material_of(curve).emission.kind == Emission::Kind::Diffuse;
    if (line_crosses_at(scene, v, d) && diffuse) return false;
    for (const std::uint32_t s : {v.before, v.after}) {
      if (s == kNoSegment) continue;
      const SegmentGeometry& g = scene.segments[s].geometry;
      const double t = s == v.after ? 0.0 : 1.0;
      const Vec2 tangent = outgoing_tangent(scene, s, s == v.after);
      const bool along = std::fabs(cross(d, tangent)) <= kAlongSine;
      const bool straight = g.kind == SegmentKind::Line || is_straight(g, scene.scale);
      if (along && !straight) continue;  // grazing a curved end: the kink is of higher order
      if (emits_toward(curve, unit_normal(g.shape, t, scene.scale), d, straight)) return true;
    }
    return false;
  }
  const Cubic& c = scene.segments[a.segment].geometry.shape;
  const Vec2 d1 = derivative(c, a.t);
  const double bend = cross(d1, second_derivative(c, a.t));
  const double speed = length(d1);
  if (std::fabs(bend) <= 1e-9 * (speed * speed * speed) / scene.scale) return false;  // inflection
  // bend > 0: turning left, the centre of curvature on the front side, the convex side is the back.
  return curve.has_side(bend > 0.0 ? Side::Back : Side::Front);
}

// The occluder rule at B: at a vertex, the curve stays on one side of the line (a line through a
// corner that the curve crosses is blocked on both sides: no event). A tangent point is a simple
// root of g, so the curve stays on one side there.
bool occluder_allows(const Scene& scene, const Feature& b, Vec2 d) {
  return b.vertex == nullptr || !line_crosses_at(scene, *b.vertex, d);
}

Feature vertex_feature(const Vertex& v) { return Feature{v.position, v.curve, v.segment(), v.t(), v.u, &v}; }

// ---------------------------------------------------------------------------------------------

struct EventFinder {
  const Scene& scene;
  const SegmentAccelerator& accelerator;
  std::vector<DiscontinuityNode> events;

  // The first hit of the ray from feature f along d, leaving f's segment (deflated) and skipping the
  // crossings of f's own curve within kGraze * scale of f, which a line through a tangent point (or
  // along a cubic's end tangent) makes by rounding: each is passed by restarting from it.
  SceneHit cast(const Feature& f, Vec2 d) const {
    const double graze = kGraze * scene.scale;
    SceneHit hit = accelerator.closest_hit(Ray{f.position, d}, RayOrigin{f.segment, f.t});
    double travelled = 0.0;
    for (int i = 0; i < 4 && hit.segment != kNoSegment && scene.segments[hit.segment].curve == f.curve &&
                    travelled + hit.distance <= graze;
         ++i) {
      travelled += hit.distance;
      hit = accelerator.closest_hit(Ray{f.position + travelled * d, d}, RayOrigin{hit.segment, hit.t});
    }
    if (hit.segment != kNoSegment) hit.distance += travelled;
    return hit;
  }

  void try_line(const Feature& a, const Feature& b) {
    const Vec2 offset = b.position - a.position;
    const double distance = length(offset);
    if (distance <= kTouch * scene.scale) return;
    const Vec2 d = (1.0 / distance) * offset;
    if (!source_allows(scene, a, d) || !occluder_allows(scene, b, d)) return;
    // The touching segment A-B must be free; a hit at B itself (or a graze of B's curve next to B)
    // is B.
    const SceneHit blocker = cast(a, d);
    if (blocker.segment != kNoSegment && blocker.distance < distance - kTouch * scene.scale) {
      const Vec2 where = a.position + blocker.distance * d;
      if (scene.segments[blocker.segment].curve != b.curve || length(where - b.position) > kGraze * scene.scale) return;
    }
    land(b, d);
  }

  // The line leaves B along d: its event is where it lands on a reflecting diffuse side. A surface
  // touching B (a contact there) blocks the line at B: its node is the contact's. The line goes on
  // through detectors and is reflected by mirrors (the boundary of the light a mirror turns is the
  // mirrored boundary), up to kMirrorBounces times; glass ends it (refraction bends light into
  // caustics, which are not lines).
  void land(const Feature& b, Vec2 d) {
    SceneHit hit = cast(b, d);
    if (hit.segment == kNoSegment || hit.distance <= kTouch * scene.scale) return;
    Vec2 from = b.position;
    for (int bounce = 0;; ++bounce) {
      if (hit.segment == kNoSegment) return;
      const SceneSegment& segment = scene.segments[hit.segment];
      const Curve& receiver = scene.curves[segment.curve];
      const Material& material = scene.material_of(receiver);
      // Light arrives travelling along d: it meets the front if the front normal opposes d.
      const Vec2 normal = unit_normal(segment.geometry.shape, hit.t, scene.scale);
      const Side side = dot(normal, d) < 0.0 ? Side::Front : Side::Back;
      if (material.optics == Optics::Diffuse) {
        // Only a side that reflects stores light that could show the kink.
        if (!receiver.has_side(side) || !reflects(scene, receiver)) return;
        events.push_back({segment.curve, wrap(receiver, segment.index_in_curve + hit.t), Continuity::C0});
        return;
      }
      if (bounce == kMirrorBounces || material.optics == Optics::Dielectric) return;
      if (material.optics == Optics::Mirror) {
        if (!receiver.has_side(side)) return;
        d = d - (2.0 * dot(d, normal)) * normal;
      }
      const Vec2 at = segment.geometry.kind == SegmentKind::Line
                          ? lerp(segment.geometry.shape.p[0], segment.geometry.shape.p[3], hit.t)
                          : evaluate(segment.geometry.shape, hit.t);
      from = at;
      hit = accelerator.closest_hit(Ray{from, d}, RayOrigin{hit.segment, hit.t});
    }
  }

  // The line from A's image in the flat mirror segment `mirror` through B: light from A reflected
  // at M (where the line crosses the mirror) passes B, and the line's continuation past B bounds the
  // light the mirror turns (B a vertex of an occluder, or the mirror's own end). `image` is A
  // reflected in the mirror's line; A must be on a reflecting side.
  void try_image_line(const Feature& a, Vec2 image, std::uint32_t mirror, const Feature& b) {
    const SceneSegment& m = scene.segments[mirror];
    const Vec2 p0 = m.geometry.shape.p[0], p1 = m.geometry.shape.p[3];
    const Vec2 offset = b.position - image;
    const double distance = length(offset);
    if (distance <= kTouch * scene.scale) return;
    const Vec2 d = (1.0 / distance) * offset;
    // M = image + s d on the mirror's line p0 + t (p1 - p0): s in (0, distance], t in [0, 1].
    const Vec2 edge = p1 - p0;
    const double denominator = cross(d, edge);
    if (std::fabs(denominator) <= kAlongSine * length(edge)) return;  // along the mirror
    const double s_cross = cross(p0 - image, edge) / denominator;
    const double t_cross = cross(p0 - image, d) / denominator;
    const double touch = kTouch * scene.scale / length(edge);
    if (!(s_cross > kTouch * scene.scale && s_cross <= distance + kTouch * scene.scale)) return;
    if (!(t_cross >= -touch && t_cross <= 1.0 + touch)) return;
    const Vec2 at_mirror = image + s_cross * d;
    const Vec2 to_mirror = at_mirror - a.position;
    const double reach = length(to_mirror);
    if (reach <= kTouch * scene.scale) return;
    const Vec2 d_real = (1.0 / reach) * to_mirror;
    if (!source_allows(scene, a, d_real) || !occluder_allows(scene, b, d)) return;
    // The mirror's side that A lights must reflect.
    const Vec2 normal = unit_normal(m.geometry.shape, 0.5, scene.scale);
    const Side lit = dot(normal, d_real) < 0.0 ? Side::Front : Side::Back;
    if (!scene.curves[m.curve].has_side(lit)) return;
    // A to M free (the first hit is the mirror at M, or B when B is the mirror's end there).
    const SceneHit first = cast(a, d_real);
    if (first.segment == kNoSegment || first.distance < reach - kGraze * scene.scale) return;
    // M to B free, when B lies beyond M.
    const double beyond = distance - s_cross;
    if (beyond > kGraze * scene.scale) {
      const SceneHit second =
          accelerator.closest_hit(Ray{at_mirror, d}, RayOrigin{mirror, std::clamp(t_cross, 0.0, 1.0)});
      if (second.segment != kNoSegment && second.distance < beyond - kTouch * scene.scale) {
        const Vec2 where = at_mirror + second.distance * d;
        if (scene.segments[second.segment].curve != b.curve || length(where - b.position) > kGraze * scene.scale)
          return;
      }
    }
    land(b, d);
  }
};

// Merging per EventOptions (see the header), curve by curve.
std::vector<DiscontinuityNode> merge_events(const Scene& scene, std::vector<DiscontinuityNode> events,
                                            const EventOptions& options) {
  std::sort(events.begin(), events.end(), before_node);
  std::vector<DiscontinuityNode> out;
  std::size_t begin = 0;
  while (begin < events.size()) {
    std::size_t end = begin;
    while (end < events.size() && events[end].curve == events[begin].curve) ++end;
    const Curve& curve = scene.curves[events[begin].curve];
    const double gap = options.merge_fraction * curve.length / std::max(options.elements, 1);
    // Arc lengths of the value-jump joints and open ends, where events are dropped.
    std::vector<double> jumps;
    if (!curve.closed || curve.joints.back() == Continuity::Jump) {
      jumps.push_back(0.0);
      jumps.push_back(curve.length);
    }
    for (std::uint32_t j = 0; j + 1 < curve.segment_count; ++j)
      if (curve.joints[j] == Continuity::Jump) jumps.push_back(curve.segment_start[j + 1]);
    struct Cluster {
      double s_first, s_last, u_sum;
      int count;
    };
    std::vector<Cluster> clusters;
    for (std::size_t i = begin; i < end; ++i) {
      const double s = arc_length_at(scene, curve, events[i].u);
      bool near_jump = false;
      for (const double jump : jumps) near_jump = near_jump || std::fabs(s - jump) < gap;
      if (near_jump) continue;
      if (!clusters.empty() && s - clusters.back().s_first < gap) {
        clusters.back().s_last = s;
        clusters.back().u_sum += events[i].u;
        ++clusters.back().count;
      } else {
        clusters.push_back({s, s, events[i].u, 1});
      }
    }
    // Around the closing point of a periodic curve the first and last clusters may be one.
    if (curve.closed && clusters.size() >= 2 &&
        clusters.front().s_first + curve.length - clusters.back().s_last < gap) {
      Cluster& last = clusters.back();
      Cluster& first = clusters.front();
      const double u_sum = first.u_sum + last.u_sum - last.count * static_cast<double>(curve.segment_count);
      first.u_sum = u_sum;
      first.count += last.count;
      clusters.pop_back();
    }
    for (const Cluster& cluster : clusters) {
      double u = cluster.u_sum / cluster.count;
      if (u < 0.0) u += curve.segment_count;
      out.push_back({events[begin].curve, wrap(curve, u), Continuity::C0});
    }
    begin = end;
  }
  std::sort(out.begin(), out.end(), before_node);
  return out;
}

}  // namespace

// ---------------------------------------------------------------------------------------------

std::vector<double> tangent_points(const Scene& scene, std::uint32_t curve, Vec2 p) {
  std::vector<double> out;
  for (const Feature& f : curve_tangent_points(scene, curve, p, vertices_of(scene, curve))) out.push_back(f.u);
  return out;
}

std::vector<std::pair<double, double>> bitangents(const Scene& scene, std::uint32_t curve_a, std::uint32_t curve_b) {
  std::vector<std::pair<double, double>> out;
  for (const auto& [a, b] :
       curve_bitangents(scene, curve_a, curve_b, vertices_of(scene, curve_a), vertices_of(scene, curve_b)))
    out.emplace_back(a.u, b.u);
  std::sort(out.begin(), out.end());
  return out;
}

std::vector<DiscontinuityNode> find_visibility_events(const Scene& scene, const SegmentAccelerator& accelerator,
                                                      const EventOptions& options) {
  const auto curve_count = static_cast<std::uint32_t>(scene.curves.size());
  std::vector<std::vector<Vertex>> vertices(curve_count);
  for (std::uint32_t c = 0; c < curve_count; ++c) vertices[c] = vertices_of(scene, c);
  std::vector<const Vertex*> all_vertices;
  for (const std::vector<Vertex>& list : vertices)
    for (const Vertex& v : list) all_vertices.push_back(&v);
  std::vector<std::uint32_t> curved_curves;
  for (std::uint32_t c = 0; c < curve_count; ++c)
    if (scene.curves[c].kind == SegmentKind::Cubic) curved_curves.push_back(c);

  // Straight segments of mirrors: an emitter's vertex has an image in each.
  std::vector<std::uint32_t> flat_mirrors;
  for (std::uint32_t i = 0; i < scene.segments.size(); ++i) {
    const SceneSegment& segment = scene.segments[i];
    if (scene.material_of(scene.curves[segment.curve]).optics == Optics::Mirror &&
        (segment.geometry.kind == SegmentKind::Line || is_straight(segment.geometry, scene.scale)))
      flat_mirrors.push_back(i);
  }
  EventFinder finder{scene, accelerator, {}};
  const auto cancelled = [&] { return options.cancel != nullptr && options.cancel->load(std::memory_order_relaxed); };
  for (std::uint32_t s = 0; s < curve_count; ++s) {
    const Curve& source = scene.curves[s];
    if (!scene.is_emitter(source) && !(options.secondary && reflects(scene, source))) continue;
    // VV and VT: from the emitter's vertices to every vertex and every tangent point.
    for (const Vertex& v : vertices[s]) {
      if (cancelled()) return {};
      const Feature a = vertex_feature(v);
      for (const Vertex* w : all_vertices) {
        if (w != &v) finder.try_line(a, vertex_feature(*w));
      }
      for (const std::uint32_t o : curved_curves)
        for (const Feature& b : curve_tangent_points(scene, o, v.position, vertices[o])) finder.try_line(a, b);
      // Through flat mirrors: the emitter's vertex's image in each, to every vertex.
      for (const std::uint32_t m : flat_mirrors) {
        if (cancelled()) return {};  // each mirror costs a line to every vertex
        const Cubic& shape = scene.segments[m].geometry.shape;
        const Vec2 p0 = shape.p[0];
        // Light from v meets the side of the mirror that v is on: nothing to image when that side
        // does not reflect (try_image_line would refuse every line for the same reason).
        const double facing = dot(unit_normal(shape, 0.5, scene.scale), v.position - p0);
        if (!scene.curves[scene.segments[m].curve].has_side(facing > 0.0 ? Side::Front : Side::Back)) continue;
        const Vec2 along = normalized(shape.p[3] - p0);
        const Vec2 relative = v.position - p0;
        const Vec2 image = p0 + (2.0 * dot(relative, along)) * along - relative;
        if (length(image - v.position) <= kTouch * scene.scale) continue;  // on the mirror's line
        for (const Vertex* w : all_vertices) finder.try_image_line(a, image, m, vertex_feature(*w));
      }
    }
    if (scene.curves[s].kind != SegmentKind::Cubic) continue;
    // TV: tangent points of the emitter seen from every vertex.
    for (const Vertex* w : all_vertices) {
      if (cancelled()) return {};
      const Feature b = vertex_feature(*w);
      for (const Feature& a : curve_tangent_points(scene, s, w->position, vertices[s])) finder.try_line(a, b);
    }
    // TT: bitangents of the emitter and every curved curve (itself included).
    for (const std::uint32_t o : curved_curves) {
      if (cancelled()) return {};
      for (const auto& [a, b] : curve_bitangents(scene, s, o, vertices[s], vertices[o])) finder.try_line(a, b);
    }
  }
  return merge_events(scene, std::move(finder.events), options);
}

}  // namespace flatland
