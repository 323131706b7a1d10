// Random numbers and the samplers of the shooter, in Sample / Pdf / Invert sets.
#pragma once

#include <cmath>
#include <cstdint>
#include <numbers>
#include <span>
#include <utility>
#include <vector>

#include "flatland/base/portable_math.hpp"
#include "flatland/base/vec2.hpp"

namespace flatland {

// SplitMix64 (Steele, Lea, Flood 2014): a bijective mixer, used to seed streams.
constexpr std::uint64_t splitmix64(std::uint64_t& state) {
  std::uint64_t z = (state += 0x9e3779b97f4a7c15ull);
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
  return z ^ (z >> 31);
}

// Uniform in [0, 1) number `index` of the sequence named by `key`: SplitMix64's output number
// index + 1 from the state key, computed from the index alone (no stream to advance), so it is
// the same whichever batch, thread or step asks for it.
constexpr double indexed_uniform(std::uint64_t key, std::uint64_t index) {
  std::uint64_t state = key + index * 0x9e3779b97f4a7c15ull;
  return static_cast<double>(splitmix64(state) >> 11) * 0x1.0p-53;
}

// xoshiro256** (Blackman, Vigna 2018). A stream is named by (seed, a, b) — for the solver the
// round and the batch — so any batch of any run can be replayed on its own, on any thread.
class Rng {
 public:
  Rng(std::uint64_t seed, std::uint64_t stream_a, std::uint64_t stream_b) {
    std::uint64_t mix = seed;
    const std::uint64_t key = splitmix64(mix) ^ (stream_a * 0xd1342543de82ef95ull);
    mix = key;
    const std::uint64_t key2 = splitmix64(mix) ^ (stream_b * 0x9e3779b97f4a7c15ull);
    mix = key2;
    for (auto& word : state_) word = splitmix64(mix);
  }

  std::uint64_t next() {
    const std::uint64_t result = rotl(state_[1] * 5, 7) * 9;
    const std::uint64_t t = state_[1] << 17;
    state_[2] ^= state_[0];
    state_[3] ^= state_[1];
    state_[1] ^= state_[2];
    state_[0] ^= state_[3];
    state_[2] ^= t;
    state_[3] = rotl(state_[3], 45);
    return result;
  }

  // Uniform in [0, 1) with 53 random bits.
  double uniform() { return static_cast<double>(next() >> 11) * 0x1.0p-53; }
  // Uniform in (0, 1): never exactly 0, so a sampled curve parameter never lands on a joint.
  double uniform_open() { return (static_cast<double>(next() >> 11) + 0.5) * 0x1.0p-53; }

 private:
  static constexpr std::uint64_t rotl(std::uint64_t x, int k) { return (x << k) | (x >> (64 - k)); }
  std::uint64_t state_[4];
};

// Diffuse emission in 2D: the angle theta from the normal has pdf cos(theta)/2 on [-pi/2, pi/2]
// and CDF (1 + sin theta)/2, so sin theta = 2u - 1. Without trigonometry:
// dir = s * tangent + sqrt(1 - s^2) * normal with s = 2u - 1. (The 3D rule cos theta = sqrt(u)
// would put zero density along the normal.)
inline Vec2 square_to_diffuse(double u, Vec2 normal) {
  const double s = 2.0 * u - 1.0;
  const double c = std::sqrt(std::fmax(0.0, 1.0 - s * s));
  const Vec2 tangent{normal.y, -normal.x};  // normal rotated -90 degrees
  return s * tangent + c * normal;
}
// Density per radian of a direction; zero behind the surface.
inline double square_to_diffuse_pdf(Vec2 normal, Vec2 direction) {
  return std::fmax(0.0, dot(normal, direction)) * 0.5;
}
// The u that square_to_diffuse maps to the given direction (in front of the surface).
inline double square_to_diffuse_invert(Vec2 normal, Vec2 direction) {
  const Vec2 tangent{normal.y, -normal.x};
  return 0.5 * (dot(tangent, direction) + 1.0);
}

// A cos^n lobe in 2D: pdf(theta) = cos(theta)^n / c_n on [-pi/2, pi/2]. Sampled exactly by
// rejection: theta uniform, accepted with probability cos(theta)^n (expected tries pi / c_n:
// 1.6 for n = 1, 4 for n = 10, 12.6 for n = 100).
inline Vec2 sample_lobe(Rng& rng, double exponent, Vec2 normal) {
  const Vec2 tangent{normal.y, -normal.x};
  for (;;) {
    const double theta = (rng.uniform() - 0.5) * std::numbers::pi;
    double s = 0.0;
    double c = 0.0;
    portable::sin_cos(theta, s, c);  // portable: the same directions on every platform
    if (rng.uniform() < portable::pow(c, exponent)) return s * tangent + c * normal;
  }
}
// Its density per radian: cos^n / c_n with c_n = integral of cos^n over [-pi/2, pi/2]
// = sqrt(pi) Gamma((n+1)/2) / Gamma(n/2 + 1).
inline double sample_lobe_pdf(double exponent, Vec2 normal, Vec2 direction) {
  const double c = dot(normal, direction);
  if (!(c > 0.0)) return 0.0;
  const double norm =
      std::sqrt(std::numbers::pi) * std::exp(std::lgamma(0.5 * (exponent + 1.0)) - std::lgamma(0.5 * exponent + 1.0));
  return std::pow(c, exponent) / norm;
}

// A beam: the diffuse distribution restricted to |theta| <= a, so sin(theta) is uniform in
// [-sin a, sin a] (pdf cos(theta) / (2 sin a)).
inline Vec2 square_to_beam(double u, double half_angle, Vec2 normal) {
  const double s = (2.0 * u - 1.0) * portable::sin(half_angle);
  const Vec2 tangent{normal.y, -normal.x};
  return s * tangent + std::sqrt(std::fmax(0.0, 1.0 - s * s)) * normal;
}
inline double square_to_beam_pdf(double half_angle, Vec2 normal, Vec2 direction) {
  const double c = dot(normal, direction);
  if (!(c > 0.0) || c < portable::cos(half_angle)) return 0.0;
  return c / (2.0 * portable::sin(half_angle));
}

// A discrete distribution with O(1) sampling by Walker's alias method (Vose's construction):
// u picks a column i = floor(u n) and its fractional part chooses between i and its alias.
// Weights must be finite and >= 0; an index of zero weight is never returned.
class DiscreteDistribution {
 public:
  DiscreteDistribution() = default;
  // Assigning once, it borrows the thread's scratch for assign and gives it back: the solver
  // builds one per curve (65,536 in the set-up benchmark), three allocations fewer each.
  explicit DiscreteDistribution(std::span<const double> weights) {
    thread_local Scratch scratch;
    std::swap(scratch_, scratch);
    assign(weights);
    std::swap(scratch_, scratch);
  }
  void assign(std::span<const double> weights);

  double total() const { return total_; }
  bool empty() const { return !(total_ > 0.0); }
  std::size_t size() const { return probability_.size(); }
  // Index i with probability weights[i] / total (u in [0,1)).
  std::size_t sample(double u) const {
    const double scaled = u * static_cast<double>(probability_.size());
    auto column = static_cast<std::size_t>(scaled);
    if (column >= probability_.size()) column = probability_.size() - 1;
    return scaled - static_cast<double>(column) < probability_[column] ? column : alias_[column];
  }
  // The same index for the same u, and in `rest` what is left of u: where u fell inside the part
  // of its column that chose the index, rescaled to [0,1). Given the index, rest is uniform, so a
  // stratified u (quasi-Monte Carlo) goes on stratifying the next choice instead of being spent.
  // It carries log2(size()) fewer bits than u.
  std::size_t sample(double u, double& rest) const {
    const double scaled = u * static_cast<double>(probability_.size());
    auto column = static_cast<std::size_t>(scaled);
    if (column >= probability_.size()) column = probability_.size() - 1;
    const double fraction = scaled - static_cast<double>(column);
    const double keep = probability_[column];
    if (fraction < keep) {
      rest = std::fmin(fraction / keep, 1.0 - 0x1.0p-53);
      return column;
    }
    rest = std::fmin((fraction - keep) / (1.0 - keep), 1.0 - 0x1.0p-53);
    return alias_[column];
  }
  double pmf(std::size_t i) const { return weights_[i] / total_; }

 private:
  std::vector<double> probability_;  // chance of keeping the column's own index
  std::vector<std::uint32_t> alias_;
  std::vector<double> weights_;
  double total_ = 0.0;
  // assign's scratch, kept so that a distribution assigned every round (the solver's sources)
  // reuses its memory; the constructor, assigning once, hands it back to its thread.
  struct Scratch {
    std::vector<double> scaled;
    std::vector<std::uint32_t> small;
    std::vector<std::uint32_t> large;
  };
  Scratch scratch_;
};

}  // namespace flatland
