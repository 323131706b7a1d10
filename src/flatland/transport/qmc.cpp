#include "flatland/transport/qmc.hpp"

#include "flatland/transport/sampling.hpp"

namespace flatland {

namespace {

// A dimension of the Sobol' sequence: primitive polynomial x^s + a_1 x^(s-1) + ... + a_(s-1) x + 1
// over GF(2) (the bits a_1 .. a_(s-1) of `a`, a_1 the highest) and the initial direction numbers
// m_1 .. m_s (m_j odd, m_j < 2^j). From Joe and Kuo's table (new-joe-kuo-6.21201, dimensions 2 to
// 6; their dimension 1 is the van der Corput sequence).
struct SobolPolynomial {
  int degree;
  std::uint32_t a;
  std::array<std::uint32_t, 4> m;
};
constexpr std::array<SobolPolynomial, kSobolDimensions - 1> kPolynomials{{
    {1, 0, {1, 0, 0, 0}},  // x + 1
    {2, 1, {1, 3, 0, 0}},  // x^2 + x + 1
    {3, 1, {1, 3, 1, 0}},  // x^3 + x + 1
    {3, 2, {1, 1, 1, 0}},  // x^3 + x^2 + 1
    {4, 1, {1, 1, 3, 3}},  // x^4 + x + 1
}};

using DirectionNumbers = std::array<std::array<std::uint32_t, 32>, kSobolDimensions>;

// v_j = m_j 2^(32-j) for digit j = 1..32 (stored at [j - 1]). Beyond the initial s numbers the
// polynomial's recurrence: m_j = 2 a_1 m_(j-1) ^ 4 a_2 m_(j-2) ^ ... ^ 2^s m_(j-s) ^ m_(j-s), which
// in the scaled numbers is v_j = v_(j-s) ^ (v_(j-s) >> s) ^ sum_k a_k v_(j-k).
constexpr DirectionNumbers make_direction_numbers() {
  DirectionNumbers v{};
  for (int j = 1; j <= 32; ++j) v[0][static_cast<std::size_t>(j - 1)] = std::uint32_t{1} << (32 - j);
  for (int d = 1; d < kSobolDimensions; ++d) {
    const SobolPolynomial& p = kPolynomials[static_cast<std::size_t>(d - 1)];
    auto& row = v[static_cast<std::size_t>(d)];
    const int s = p.degree;
    for (int j = 1; j <= 32; ++j) {
      const auto at = static_cast<std::size_t>(j - 1);
      if (j <= s) {
        row[at] = p.m[at] << (32 - j);
        continue;
      }
      std::uint32_t value = row[at - static_cast<std::size_t>(s)];
      value ^= value >> s;
      for (int k = 1; k < s; ++k)
        if ((p.a >> (s - 1 - k)) & 1u) value ^= row[at - static_cast<std::size_t>(k)];
      row[at] = value;
    }
  }
  return v;
}
constexpr DirectionNumbers kDirections = make_direction_numbers();

}  // namespace

std::uint32_t sobol_bits(std::uint32_t index, int dimension) {
  if (dimension == 0) return reverse_bits(index);
  const auto& v = kDirections[static_cast<std::size_t>(dimension)];
  std::uint32_t bits = 0;
  for (std::size_t j = 0; index != 0; ++j, index >>= 1)
    if (index & 1u) bits ^= v[j];
  return bits;
}

std::uint32_t nested_uniform_scramble(std::uint32_t bits, std::uint32_t seed) {
  return nested_uniform_scramble_mirrored(reverse_bits(bits), seed);
}

const std::array<std::array<std::uint32_t, 32>, kSobolDimensions>& sobol_mirrored_steps() {
  static const auto steps = [] {
    std::array<std::array<std::uint32_t, 32>, kSobolDimensions> table{};
    for (int d = 0; d < kSobolDimensions; ++d)
      for (std::uint32_t k = 0; k < 32; ++k) {
        const std::uint32_t ones = k == 31 ? 0xffffffffu : (2u << k) - 1u;  // bits 0..k
        table[static_cast<std::size_t>(d)][k] = reverse_bits(sobol_bits(ones, d));
      }
    return table;
  }();
  return steps;
}

std::uint32_t nested_uniform_scramble_mirrored(std::uint32_t mirrored, std::uint32_t seed) {
  // Mirrored, the leading digit is bit 0, and each step below changes bit j by a function of bits
  // 0..j-1 only: an addition (carries move up), a product with an odd number (bit j of x m is
  // x_j plus terms in the lower bits of x), x ^= x * c with c even (x c has bit j from bits below
  // j). So digit j of the fraction is flipped by a function of the digits above it: a nested
  // scramble. Two seed-dependent steps (the added constant and the odd factor) and three fixed
  // mixing steps spread each digit's influence over all digits below it.
  const std::uint32_t factor = (seed * 0x2c1b3c6du ^ (seed >> 13)) | 1u;
  std::uint32_t x = mirrored;
  x += seed;
  x ^= x * 0x9e3779b8u;  // even constants: the fractions of the golden ratio, sqrt 2 and sqrt 3
  x *= factor;
  x ^= x * 0x6a09e666u;
  x += (seed >> 16) | (seed << 16);
  x ^= x * 0xbb67ae84u;
  return reverse_bits(x);
}

ScrambledSobol::ScrambledSobol(std::uint64_t seed, std::uint64_t stream) {
  // A stream key apart from the photon generator's (Rng), then one seed per dimension.
  std::uint64_t mix = seed ^ 0x51ed270b27d4f3c5ull;
  mix = splitmix64(mix) ^ (stream * 0xd1342543de82ef95ull);
  for (std::uint32_t& s : seeds_) s = static_cast<std::uint32_t>(splitmix64(mix) >> 32);
}

}  // namespace flatland
