#include "flatland/transport/control_variate.hpp"

#include <algorithm>
#include <cmath>

#include "flatland/base/quadrature.hpp"
#include "flatland/geometry/bezier.hpp"

namespace flatland {

Status check_control_variate(const Scene& scene) {
  const std::string what = scene.source + ": control variate: coarse ";
  if (scene.has_spectra())
    return Error{what +
                 "follows the light of each channel, and this scene's emitters have spectra (photons of "
                 "one wavelength each); solve it without the control variate"};
  for (const Curve& curve : scene.curves) {
    const Material& material = scene.material_of(curve);
    if (material.optics != Optics::Diffuse)
      return Error{what + "needs diffuse surfaces only, and curve '" + curve.id + "' is " +
                   (material.optics == Optics::Mirror       ? "a mirror"
                    : material.optics == Optics::Dielectric ? "glass"
                                                            : "a detector") +
                   "; solve it without the control variate"};
  }
  for (const Curve& curve : scene.curves)
    if (scene.is_emitter(curve) && scene.material_of(curve).emission.kind != Emission::Kind::Diffuse)
      return Error{what + "shoots its difference diffusely, and curve '" + curve.id +
                   "' emits a lobe or a beam; solve it without the control variate"};
  return ok_status();
}

void project_control_variate(const CoarseAnswer& coarse, const Scene& scene, const SceneStorage& storage,
                             std::uint32_t curve_index, const std::vector<double>& emission,
                             std::vector<double>& received, std::vector<double>& source,
                             std::vector<double>* coarse_received, const std::atomic<bool>* cancel) {
  const Curve& curve = scene.curves[curve_index];
  const auto channels = static_cast<std::size_t>(scene.channels);
  std::array<std::uint32_t, 2> offsets{};
  bool any = false;
  for (Side side : {Side::Front, Side::Back}) {
    offsets[static_cast<std::size_t>(side)] = storage.block_offset(curve_index, side);
    any = any || offsets[static_cast<std::size_t>(side)] != SceneStorage::kNoBlock;
  }
  if (!any) return;
  const CurveStorage& finest = storage.finest(curve_index);
  const SplineBasis& basis = finest.basis;
  const std::vector<double>& knots = basis.knots();
  const auto p = static_cast<std::size_t>(basis.degree());
  const Spectrum& rho = scene.material_of(curve).reflectivity;
  // integral(phi_k b_c ds) per side, coefficient and channel of this curve.
  const std::size_t count = basis.size() * channels;
  std::array<std::vector<double>, 2> bc{std::vector<double>(count, 0.0), std::vector<double>(count, 0.0)};
  std::array<double, SplineBasis::kMaxDegree + 1> values{};
  std::uint32_t cached_segment = 0xffffffffu;
  std::vector<double> ends;  // the cached segment's element ends, in t
  for (std::size_t k = basis.first_span(); k < basis.end_span(); ++k) {
    // A span costs a few sweeps of the chords: the cancel is checked every 64.
    if (cancel != nullptr && (k & 63u) == 0 && cancel->load(std::memory_order_relaxed)) return;
    const double a = knots[k];
    const double b = knots[k + 1];
    if (!(b > a)) continue;
    const auto local = static_cast<std::uint32_t>(std::min<double>(std::floor(0.5 * (a + b)), curve.segment_count - 1));
    const std::uint32_t segment_index = curve.first_segment + local;
    if (segment_index != cached_segment) {
      ends = coarse.element_parameters(segment_index);
      cached_segment = segment_index;
    }
    const Cubic& shape = scene.segments[segment_index].geometry.shape;
    // The span in t, cut at the coarse elements' ends inside it.
    const double ta = a - local;
    const double tb = b - local;
    std::size_t piece = static_cast<std::size_t>(std::upper_bound(ends.begin(), ends.end(), ta) - ends.begin());
    piece = std::clamp<std::size_t>(piece, 1, ends.size() - 1) - 1;  // the element holding ta
    double t0 = ta;
    while (t0 < tb) {
      const double t1 = piece + 1 < ends.size() - 1 ? std::min(tb, ends[piece + 1]) : tb;
      const std::uint32_t element = coarse.first_element(segment_index) + static_cast<std::uint32_t>(piece);
      if (t1 > t0) {
        const double half = 0.5 * (t1 - t0);
        // Gauss points (kShortPiece): each costs a sweep of every chord (coarse.irradiance), most
        // of the set-up. On a piece short against its coarse element the integrand (a degree-p
        // basis function times the irradiance, smooth on the scale of the distance to its sources,
        // times the arc length's factor) is close to a polynomial of low degree, which 4 points
        // integrate (exactly to degree 7); on longer pieces the arc length's factor on a curved
        // segment needs 8 (a furnace of 16 elements on a circle is exact to 1e-9 only with 8).
        const bool short_piece = t1 - t0 < kShortPiece * (ends[piece + 1] - ends[piece]);
        const double* nodes = short_piece ? gauss::kNodes4.data() : gauss::kNodes8.data();
        const double* weights = short_piece ? gauss::kWeights4.data() : gauss::kWeights8.data();
        const std::size_t points = short_piece ? gauss::kNodes4.size() : gauss::kNodes8.size();
        for (std::size_t g = 0; g < points; ++g) {
          const double t = 0.5 * (t0 + t1) + half * nodes[g];
          const double u = local + t;
          const double weight = weights[g] * half * length(derivative(shape, t));
          basis.evaluate_in_span(k, u, values.data());
          for (Side side : {Side::Front, Side::Back}) {
            const std::uint32_t offset = offsets[static_cast<std::size_t>(side)];
            if (offset == SceneStorage::kNoBlock) continue;
            const Spectrum b_c = coarse.element_radiosity(element, side);
            const Spectrum gathered = coarse.irradiance(curve_index, side, u);
            const Spectrum modelled =
                coarse_received != nullptr ? coarse.coarse_irradiance(curve_index, side, u) : Spectrum{};
            std::vector<double>& own = bc[static_cast<std::size_t>(side)];
            for (std::size_t j = 0; j <= p; ++j) {
              const std::size_t function = basis.index(k - p + j);
              const std::size_t index = (offset + function) * channels;
              const double w = weight * values[j];
              for (std::size_t ch = 0; ch < channels; ++ch) {
                received[index + ch] += w * gathered[ch];
                own[function * channels + ch] += w * b_c[ch];
                if (coarse_received != nullptr) (*coarse_received)[index + ch] += w * modelled[ch];
              }
            }
          }
        }
      }
      t0 = t1;
      ++piece;
    }
  }
  for (Side side : {Side::Front, Side::Back}) {
    const std::uint32_t offset = offsets[static_cast<std::size_t>(side)];
    if (offset == SceneStorage::kNoBlock) continue;
    for (std::size_t k = 0; k < basis.size(); ++k)
      for (std::size_t ch = 0; ch < channels; ++ch) {
        const std::size_t index = (offset + k) * channels + ch;
        source[index] =
            emission[index] + rho[ch] * received[index] - bc[static_cast<std::size_t>(side)][k * channels + ch];
      }
  }
}

}  // namespace flatland
