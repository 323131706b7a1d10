// Randomised quasi-Monte Carlo: an Owen-scrambled Sobol' sequence, point by point.
//
// The Sobol' sequence in base 2: coordinate d of point i is the XOR of the direction numbers
// v_d[j] of the bits j set in i, read as a binary fraction (the generator matrix times the digits
// of i). Dimension 0 is the van der Corput sequence (v_0[j] = 2^-(j+1), the bits of i mirrored);
// dimensions 1.. come from primitive polynomials over GF(2) and their initial direction numbers
// (Joe and Kuo's table, 2008) by Bratley and Fox's recurrence. Dimensions 0 and 1 together form a
// (0,2)-sequence: every block of 2^m points starting at a multiple of 2^m puts exactly one point
// in every elementary interval [a 2^-k, (a+1) 2^-k) x [b 2^-(m-k), (b+1) 2^-(m-k)). Further
// dimensions keep the (0,1) property in one dimension (each generator matrix is nonsingular upper
// triangular) and good, not perfect, joint strata.
//
// Owen's nested uniform scramble (1995) flips digit j of a coordinate by a random bit that
// depends on the digits above it: the points stay a (t,m,s)-net, and each point on its own is
// uniform in the cube, so an average over them is unbiased and its variance falls faster than
// 1/n for integrands of bounded variation (n^-3/2 for an integrand with a jump along a curve, in
// two dimensions). The random bits come from a hash of the digits above, after Laine and Karras
// (2011) and Burley (2020): mirror the bits so that the leading digit is bit 0, then apply steps in
// which bit j changes only by a function of bits 0..j-1 (adding a constant, multiplying by an odd
// constant, x ^= x * an even constant), then mirror back. Every dimension has its own seed.
#pragma once

#include <array>
#include <bit>
#include <cstdint>

namespace flatland {

// Dimensions of the Sobol' sequence provided.
inline constexpr int kSobolDimensions = 6;

// The bits of x in reverse order (bit 0 becomes bit 31).
constexpr std::uint32_t reverse_bits(std::uint32_t x) {
  x = ((x >> 1) & 0x55555555u) | ((x & 0x55555555u) << 1);
  x = ((x >> 2) & 0x33333333u) | ((x & 0x33333333u) << 2);
  x = ((x >> 4) & 0x0f0f0f0fu) | ((x & 0x0f0f0f0fu) << 4);
  x = ((x >> 8) & 0x00ff00ffu) | ((x & 0x00ff00ffu) << 8);
  return (x >> 16) | (x << 16);
}

// Coordinate `dimension` (0 <= dimension < kSobolDimensions) of Sobol' point `index`, as a 32-bit
// binary fraction (value = result * 2^-32), unscrambled.
std::uint32_t sobol_bits(std::uint32_t index, int dimension);

// A nested uniform scramble of a 32-bit binary fraction, named by `seed`: a bijection of the
// fractions in which digit j (from the top) is flipped by a pseudo-random function of the seed and
// of the digits above j, so that elementary intervals map onto elementary intervals of the same
// size.
std::uint32_t nested_uniform_scramble(std::uint32_t bits, std::uint32_t seed);
// The same scramble of bits given mirrored (reverse_bits(bits): the leading digit at bit 0), the
// form the scramble works in; returns the scrambled fraction the right way round.
std::uint32_t nested_uniform_scramble_mirrored(std::uint32_t mirrored, std::uint32_t seed);
// Mirrored steps between consecutive points: point i + 1 is point i XOR step[k] with k the number
// of trailing zero bits of i + 1 (the bits 0..k of the index flip, so their direction numbers
// v[0] ^ .. ^ v[k] do); step[d][k] = reverse_bits(sobol_bits(2^(k+1) - 1, d)).
const std::array<std::array<std::uint32_t, 32>, kSobolDimensions>& sobol_mirrored_steps();

// A 32-bit binary fraction as a double in (0, 1): the digits and half a unit of the last, so never
// exactly 0 or 1, and the average over a net is exactly 1/2.
inline double fraction_to_unit(std::uint32_t bits) { return (static_cast<double>(bits) + 0.5) * 0x1.0p-32; }

// One randomisation of the Sobol' sequence, named by (seed, stream): any point can be computed on
// its own, from its index, so points are the same whatever thread computes them, and different
// seeds (or streams) give independent randomisations.
class ScrambledSobol {
 public:
  ScrambledSobol(std::uint64_t seed, std::uint64_t stream);

  // Coordinate `dimension` of point `index`, in (0, 1): the 32 scrambled digits and half a unit
  // of the last (so never exactly 0 or 1, and the average over a net is exactly 1/2).
  double sample(std::uint32_t index, int dimension) const { return fraction_to_unit(scrambled_bits(index, dimension)); }
  std::uint32_t scrambled_bits(std::uint32_t index, int dimension) const {
    return nested_uniform_scramble(sobol_bits(index, dimension), seeds_[static_cast<std::size_t>(dimension)]);
  }
  std::uint32_t seed(int dimension) const { return seeds_[static_cast<std::size_t>(dimension)]; }

 private:
  std::array<std::uint32_t, kSobolDimensions> seeds_{};
};

// Walks the points of one ScrambledSobol in index order: moving to the next index costs one XOR
// per dimension (sobol_mirrored_steps), any other move recomputes the point from its index. The
// same values as ScrambledSobol::sample, bit for bit; a photon loop over consecutive indices pays
// a few operations per coordinate instead of a loop over the index's bits.
class SobolCursor {
 public:
  explicit SobolCursor(const ScrambledSobol& sobol) : sobol_(&sobol), steps_(&sobol_mirrored_steps()) {}
  SobolCursor(const ScrambledSobol&&) = delete;  // it keeps a pointer: no temporaries

  void seek(std::uint32_t index) {
    if (valid_ && index == index_ + 1u && index != 0u) {
      const auto k = static_cast<std::size_t>(std::countr_zero(index));
      for (std::size_t d = 0; d < mirrored_.size(); ++d) mirrored_[d] ^= (*steps_)[d][k];
    } else if (!valid_ || index != index_) {
      for (std::size_t d = 0; d < mirrored_.size(); ++d)
        mirrored_[d] = reverse_bits(sobol_bits(index, static_cast<int>(d)));
    }
    index_ = index;
    valid_ = true;
  }
  // Coordinate `dimension` of the current point, as ScrambledSobol::sample.
  double sample(int dimension) const {
    return fraction_to_unit(
        nested_uniform_scramble_mirrored(mirrored_[static_cast<std::size_t>(dimension)], sobol_->seed(dimension)));
  }

 private:
  const ScrambledSobol* sobol_;
  const std::array<std::array<std::uint32_t, 32>, kSobolDimensions>* steps_;
  std::uint32_t index_ = 0;
  bool valid_ = false;
  std::array<std::uint32_t, kSobolDimensions> mirrored_{};
};

}  // namespace flatland
