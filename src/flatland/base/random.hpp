// Random numbers named by a key and an index, and streams named by (seed, a, b): every photon's
// randomness is a function of its name, so results do not depend on threads or step sizes.
#pragma once

#include <cstdint>

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

}  // namespace flatland
