// Specular chains of the photon shooter (mirrors, dielectrics, detectors) and the optics they use,
// against closed forms: Fresnel's equations at their special angles, the image method for a flat
// mirror, a slab's series of internal reflections, the critical angle, a prism's deviation, and
// a detector around a lamp; the books and the bits on any thread count.
#include <algorithm>
#include <cmath>
#include <numbers>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "flatland/transport/optics.hpp"
#include "test_support.hpp"

namespace flatland {
namespace {

constexpr double kPi = std::numbers::pi;

using testing::make_solver;

// The first round of a solve on 4 elements a curve: the light straight from the emitters, through
// every chain, and what side `side` of curve `curve` received of it, per channel.
struct FirstRound {
  Spectrum received{};
  EnergyBooks books;
  double photons = 0.0;
  std::uint64_t chains_cut = 0;
};
FirstRound first_round(const Scene& scene, std::uint32_t curve, Side side, std::uint64_t photons, std::uint64_t seed,
                       SamplerKind sampler) {
  SolverSettings settings;
  settings.photons = photons;
  settings.elements = 4;
  settings.sampler = sampler;
  settings.seed = seed;
  Solver solver = make_solver(scene, settings);
  FirstRound result;
  EXPECT_TRUE(solver.step_round());
  const auto channels = static_cast<std::size_t>(scene.channels);
  const std::uint32_t offset = solver.scene_storage().block_offset(curve, side);
  for (std::size_t k = 0; k < solver.storage(curve).basis.size(); ++k)
    for (std::size_t ch = 0; ch < channels; ++ch)
      result.received[ch] += solver.received()[(offset + k) * channels + ch];
  result.books = solver.books();
  result.photons = static_cast<double>(solver.photons_shot());
  result.chains_cut = solver.chains_cut();
  EXPECT_NEAR(result.books.imbalance(), 0.0, 1e-12 * result.books.emitted);
  return result;
}

// The paths of a first round of 4096 photons (every one recorded), with its books.
struct FirstPaths {
  std::vector<PhotonPath> paths;
  EnergyBooks books;
};
FirstPaths first_round_paths(const Scene& scene) {
  SolverSettings settings;
  settings.photons = 4096;
  settings.elements = 4;
  Solver solver = make_solver(scene, settings);
  solver.record_paths(4096);
  EXPECT_TRUE(solver.step_round());
  return {solver.paths(), solver.books()};
}

// ---- Fresnel's equations

TEST(Optics, FresnelAtNormalIncidenceIsTheSquaredContrast) {
  for (double n : {1.33, 1.5, 2.4}) {
    const double expected = (n - 1.0) * (n - 1.0) / ((n + 1.0) * (n + 1.0));
    EXPECT_NEAR(fresnel_reflectance(1.0, n, 1.0), expected, 1e-15);
    EXPECT_NEAR(fresnel_reflectance(n, 1.0, 1.0), expected, 1e-15);
  }
}

TEST(Optics, FresnelIsOneAtGrazingIncidenceAndBeyondTheCriticalAngle) {
  EXPECT_DOUBLE_EQ(fresnel_reflectance(1.0, 1.5, 0.0), 1.0);
  const double critical = std::asin(1.0 / 1.5);
  EXPECT_DOUBLE_EQ(fresnel_reflectance(1.5, 1.0, std::cos(critical + 1e-6)), 1.0);
  EXPECT_LT(fresnel_reflectance(1.5, 1.0, std::cos(critical - 1e-3)), 1.0);
  // Continuous at the critical angle: the reflectance rises to 1 there.
  EXPECT_GT(fresnel_reflectance(1.5, 1.0, std::cos(critical - 1e-9)), 0.99);
}

TEST(Optics, FresnelAtBrewstersAngleReflectsHalfTheSPolarisation) {
  // At tan(theta) = n2 / n1 the p reflectance vanishes; r_s = cos(2 theta) there
  // (r_s = -sin(theta_i - theta_t) / sin(theta_i + theta_t) with theta_i + theta_t = 90 degrees).
  const double n = 1.5;
  const double brewster = std::atan(n);
  const double r_s = std::cos(2.0 * brewster);
  EXPECT_NEAR(fresnel_reflectance(1.0, n, std::cos(brewster)), 0.5 * r_s * r_s, 1e-15);
}

TEST(Optics, FresnelIsTheSameBothWaysThroughAnInterface) {
  // Reciprocity: light arriving at theta_i from n1 reflects as light arriving at theta_t from n2.
  for (double degrees : {10.0, 35.0, 60.0, 85.0}) {
    const double in = degrees * kPi / 180.0;
    const double out = std::asin(std::sin(in) / 1.5);
    EXPECT_NEAR(fresnel_reflectance(1.0, 1.5, std::cos(in)), fresnel_reflectance(1.5, 1.0, std::cos(out)), 1e-14)
        << degrees;
  }
}

// ---- A flat mirror: the image method

// A lamp (emitting downward, black) above a floor, a vertical mirror at x = 0 standing on the
// floor's line. The floor's irradiance is the lamp's plus reflectance times its mirror image's
// (the lamp reflected to x < 0, seen through the mirror), each (sin a2 - sin a1) / 2 of its
// radiosity (the angles of the source's ends from the floor's normal). No light of the floor's
// comes back to it (its image lies on its own line), so the first round's deposits are the whole.
struct MirrorSetup {
  double lamp_left = 0.3, lamp_right = 0.8, lamp_height = 1.0;
  double floor_left = 0.05, floor_right = 2.0;
  double rho = 0.5;
  double reflectance = 0.8;

  std::string scene_text() const {
    char text[1024];
    std::snprintf(text, sizeof text,
                  R"({"flatland": 2, "materials": {"lamp": {"emittance": 1}, "floor": {"reflectivity": %.17g},
                      "mirror": {"type": "mirror", "reflectance": %.17g}},
                      "curves": [{"id": "lamp", "material": "lamp", "line": [[%.17g,%.17g],[%.17g,%.17g]]},
                                 {"id": "floor", "material": "floor", "line": [[%.17g,0],[%.17g,0]]},
                                 {"id": "mirror", "material": "mirror", "line": [[0,1.5],[0,0]]}]})",
                  rho, reflectance, lamp_right, lamp_height, lamp_left, lamp_height, floor_left, floor_right);
    return text;
  }
  double irradiance(double x) const {
    auto sine = [&](double px) { return (px - x) / std::hypot(px - x, lamp_height); };
    const double direct = sine(lamp_right) - sine(lamp_left);
    const double image = sine(-lamp_left) - sine(-lamp_right);
    return 0.5 * (direct + reflectance * image);
  }
};

// The floor's coefficients after the first round against rho integral(phi_k H) / integral(phi_k),
// within 5 standard deviations: each photon brings at most q = emitted / n to the floor, so the
// received power's sigma is at most sqrt(q E[R_k]).
void check_mirror_floor(Transport transport) {
  const MirrorSetup setup;
  const Scene scene = testing::scene_from_text(setup.scene_text());
  SolverSettings settings;
  settings.photons = 1'000'000;
  settings.basis = BasisKind::Linear;
  settings.elements = 24;
  settings.estimator = Estimator::Lumped;
  settings.sampler = SamplerKind::Random;
  settings.seed = 5;
  settings.transport = transport;
  Solver solver = make_solver(scene, settings);
  if (transport == Transport::Walk)
    solver.run();
  else
    ASSERT_TRUE(solver.step_round());
  const double q = solver.books().emitted / static_cast<double>(solver.photons_shot());
  const CurveStorage& storage = solver.storage(1);
  const std::vector<double> b = solver.radiosity_coefficients(1, Side::Front);
  ASSERT_EQ(b.size(), storage.basis.size());
  const double length = setup.floor_right - setup.floor_left;
  std::vector<double> expected_power(b.size(), 0.0);
  std::vector<double> no_mirror_power(b.size(), 0.0);
  std::array<double, SplineBasis::kMaxDegree + 1> phi{};
  const int steps = 100'000;
  for (int i = 0; i < steps; ++i) {
    const double u = (i + 0.5) / steps;
    const double x = setup.floor_left + u * length;
    MirrorSetup without = setup;
    without.reflectance = 0.0;
    const std::size_t first = storage.basis.evaluate(u, phi.data());
    for (std::size_t j = 0; j <= static_cast<std::size_t>(storage.basis.degree()); ++j) {
      expected_power[first + j] += phi[j] * setup.irradiance(x) * length / steps;
      no_mirror_power[first + j] += phi[j] * without.irradiance(x) * length / steps;
    }
  }
  double worst = 0.0;
  double worst_without = 0.0;
  for (std::size_t k = 0; k < b.size(); ++k) {
    const double sigma = setup.rho * std::sqrt(q * expected_power[k]) / storage.basis_length[k];
    const double z = std::fabs(b[k] - setup.rho * expected_power[k] / storage.basis_length[k]) / sigma;
    worst = std::max(worst, z);
    worst_without =
        std::max(worst_without, std::fabs(b[k] - setup.rho * no_mirror_power[k] / storage.basis_length[k]) / sigma);
    EXPECT_LT(z, 5.0) << to_string(transport) << " coefficient " << k;
  }
  EXPECT_GT(worst, 0.0);
  EXPECT_GT(worst_without, 20.0);  // the mirror's light is far above the noise
  // The mirror keeps 80 % of what reaches its reflecting side: the rest is its books' line.
  EXPECT_GT(solver.books().absorbed_mirrors, 0.0);
}

TEST(SpecularChains, FlatMirrorMatchesTheImageMethod) { check_mirror_floor(Transport::Shooting); }
TEST(SpecularChains, FlatMirrorMatchesTheImageMethodWithWalks) { check_mirror_floor(Transport::Walk); }

TEST(SpecularChains, APerfectMirrorWallDoublesTheRoom) {
  // A unit box of uniform E = 1 and rho = 0.5 whose left wall is a perfect mirror is, reflected in
  // it, the closed room twice as wide: B = E / (1 - rho) = 2 on every wall. No photon escapes or is
  // absorbed by the mirror, so the power received is exact but for the unshot rest: the walls' mean
  // B is 2 to the tolerance; pointwise, within the noise of 1e6 photons (a few per cent at most).
  const Scene scene = testing::scene_from_text(R"({"flatland": 2,
      "materials": {"wall": {"emittance": 1, "reflectivity": 0.5}, "mirror": {"type": "mirror"}},
      "curves": [{"id": "walls", "material": "wall", "line": [[0, 0], [1, 0], [1, 1], [0, 1]]},
                 {"id": "mirror", "material": "mirror", "line": [[0, 1], [0, 0]]}]})");
  SolverSettings settings;
  settings.photons = 1'000'000;
  settings.tolerance = 1e-7;
  Solver solver = make_solver(scene, settings);
  solver.run();
  const EnergyBooks books = solver.books();
  EXPECT_EQ(books.escaped, 0.0);
  EXPECT_EQ(books.absorbed_mirrors, 0.0);
  double mean = 0.0, worst = 0.0;
  const int samples = 3000;
  for (int k = 0; k < samples; ++k) {
    const double b = solver.radiosity(0, Side::Front, 3.0 * (k + 0.5) / samples)[0];
    mean += b / samples;
    worst = std::max(worst, std::fabs(b - 2.0));
  }
  EXPECT_NEAR(mean, 2.0, 2e-3);  // the sampled mean of a spline, to its quadrature and the unshot rest
  EXPECT_LT(worst, 0.06);
}

TEST(SpecularChains, AMirrorsBackAbsorbs) {
  // The lamp faces the mirror's back: everything that reaches the mirror is absorbed there.
  const Scene scene = testing::scene_from_text(R"({"flatland": 2,
      "materials": {"lamp": {"emittance": 1}, "mirror": {"type": "mirror"}},
      "curves": [{"id": "lamp", "material": "lamp", "line": [[1, -1], [1, 1]]},
                 {"id": "mirror", "material": "mirror", "line": [[0, -100], [0, 100]]}]})");
  SolverSettings settings;
  settings.photons = 100'000;
  settings.elements = 4;
  Solver solver = make_solver(scene, settings);
  solver.run();
  const EnergyBooks books = solver.books();
  // Both run up (+y), so both fronts face -x: the lamp's light meets the mirror's back, all but
  // what passes its ends (100 away, a sliver).
  EXPECT_GT(books.absorbed_mirrors, 0.98 * books.emitted);
  EXPECT_NEAR(books.absorbed_mirrors + books.escaped, books.emitted, 1e-12 * books.emitted);
}

// ---- A dielectric slab: (1 - R)^2 sum R^(2k) = (1 - R) / (1 + R)

// A narrow beam at `degrees` from the normal through a slab of index 1.5 (thickness 0.1, wide),
// onto a receiver under it. With unpolarised Fresnel at each face (the same R on both faces, by
// reciprocity) the light through is (1 - R)^2 sum_k R^(2k) = (1 - R) / (1 + R), averaged over the
// beam's directions (sin(theta) uniform within the half-angle around the tilt).
double slab_transmittance(double degrees, double half_angle_degrees) {
  const int steps = 20'000;
  const double tilt = degrees * kPi / 180.0;
  const double half = std::sin(half_angle_degrees * kPi / 180.0);
  double sum = 0.0;
  for (int i = 0; i < steps; ++i) {
    const double s = (2.0 * (i + 0.5) / steps - 1.0) * half;
    const double theta = tilt + std::asin(s);
    const double r = fresnel_reflectance(1.0, 1.5, std::cos(theta));
    sum += (1.0 - r) / (1.0 + r);
  }
  return sum / steps;
}

TEST(SpecularChains, SlabTransmitsTheFresnelSeriesAtEveryAngle) {
  const double half_angle = 0.5;  // degrees
  for (double degrees : {0.0, 30.0, 60.0, 75.0}) {
    // The lamp (0.2 long, 1 above the slab) faces down, turned by `degrees`; the slab is a
    // counter-clockwise rectangle (its front, the glass, inside).
    const double a = degrees * kPi / 180.0;
    const double cx = -std::tan(a), cy = 1.0;
    const double dx = 0.1 * std::cos(a), dy = 0.1 * std::sin(a);
    char text[1400];
    std::snprintf(text, sizeof text, R"({"flatland": 2,
        "materials": {"lamp": {"emittance": 1, "emission": {"beam": %.17g}}, "glass": {"type": "dielectric", "ior": 1.5},
                      "screen": {"reflectivity": 0.5}},
        "curves": [{"id": "lamp", "material": "lamp", "line": [[%.17g,%.17g],[%.17g,%.17g]]},
                   {"id": "slab", "material": "glass", "line": [[-50,-0.1],[50,-0.1],[50,0],[-50,0],[-50,-0.1]]},
                   {"id": "screen", "material": "screen", "line": [[-60,-0.5],[60,-0.5]]}]})",
                  half_angle, cx + dx, cy + dy, cx - dx, cy - dy);
    // The screen's light from the lamp, through the slab.
    const FirstRound round =
        first_round(testing::scene_from_text(text), 2, Side::Front, 400'000, 11, SamplerKind::Random);
    const double expected = slab_transmittance(degrees, half_angle);
    const double sigma = std::sqrt(expected * (1.0 - expected) / round.photons);
    const double fraction = round.received[0] / round.books.emitted;
    EXPECT_NEAR(fraction, expected, 5.0 * sigma) << degrees << " degrees";
    // And not the single interface's (1 - R)^2: the internal round trips are there.
    const double r = fresnel_reflectance(1.0, 1.5, std::cos(a));
    if (degrees >= 75.0) {
      EXPECT_GT(std::fabs(fraction - (1.0 - r) * (1.0 - r)), 10.0 * sigma) << degrees;
    }
  }
}

// ---- Total internal reflection

// A beam inside a glass block (index 1.5) meets its top face at `degrees`; a screen over the
// block collects what gets out. Beyond the critical angle asin(1 / 1.5) = 41.81 degrees nothing
// does: the block's faces are square, so the beam meets every face beyond it and is trapped
// until the chain limit cuts it (or it finds the lamp again), counted in the books.
struct TrappedBeam {
  double to_screen = 0.0;
  double emitted = 0.0;
  double cut = 0.0;
  double absorbed = 0.0;
  std::uint64_t chains_cut = 0;
};
TrappedBeam beam_in_a_block(double degrees) {
  const double a = degrees * kPi / 180.0;
  const double dx = 0.02 * std::cos(a), dy = 0.02 * std::sin(a);
  char text[1400];
  std::snprintf(text, sizeof text, R"({"flatland": 2,
      "materials": {"lamp": {"emittance": 1, "emission": {"beam": 0.25}}, "glass": {"type": "dielectric", "ior": 1.5},
                    "screen": {"reflectivity": 0.5}},
      "curves": [{"id": "lamp", "material": "lamp", "line": [[%.17g,%.17g],[%.17g,%.17g]]},
                 {"id": "block", "material": "glass", "line": [[-2,0],[2,0],[2,1],[-2,1],[-2,0]]},
                 {"id": "screen", "material": "screen", "line": [[3,1.05],[-3,1.05]]}]})",
                1.5 - dx, 0.2 - dy, 1.5 + dx, 0.2 + dy);
  // The lamp runs along (cos a, sin a): its front (left) faces up, turned anticlockwise by a (the
  // beam meets the top face near x = 0.8); the screen's front faces down, to the block.
  const FirstRound round = first_round(testing::scene_from_text(text), 2, Side::Front, 20'000, 2, SamplerKind::Sobol);
  return {round.received[0], round.books.emitted, round.books.cut, round.books.absorbed, round.chains_cut};
}

TEST(SpecularChains, NothingLeavesGlassBeyondTheCriticalAngle) {
  const double critical = std::asin(1.0 / 1.5) * 180.0 / kPi;
  const TrappedBeam trapped = beam_in_a_block(critical + 1.0);
  EXPECT_EQ(trapped.to_screen, 0.0);
  EXPECT_GT(trapped.chains_cut, 0u);
  EXPECT_NEAR(trapped.cut + trapped.absorbed, trapped.emitted, 1e-12 * trapped.emitted);
  const TrappedBeam leaks = beam_in_a_block(critical - 1.0);
  EXPECT_GT(leaks.to_screen, 0.05 * leaks.emitted);
}

// ---- A prism's deviation

// A thin beam through a prism of apex angle A, its index from Cauchy's formula at the light's
// wavelength (a line spectrum; without a spectrum, the d line): the rays refracted at both faces
// leave deviated by delta = theta1 + theta2' - A, with sin(theta1') = sin(theta1) / n,
// theta2 = A - theta1', sin(theta2') = n sin(theta2): the textbook's angles, not the vectors the
// shooter uses.
void check_prism_deviation(double nanometres) {
  const double apex = 60.0 * kPi / 180.0;
  const double a = 1.62, b = 0.0145;  // a dense flint, for a wide spread
  const double micrometres = nanometres > 0.0 ? nanometres / 1000.0 : kGreyWavelength;
  const double n = a + b / (micrometres * micrometres);
  // An equilateral prism, counter-clockwise: base from (-1, 0) to (1, 0), apex at (0, sqrt 3).
  // Its left face's outward normal points up-left, at 150 degrees; the beam travels at theta1 from
  // the inward normal (-30 degrees), turned anticlockwise (from below the normal, towards the apex),
  // as in the textbook's figure.
  const double theta1 = 50.0 * kPi / 180.0;
  const Vec2 face_normal{std::cos(150.0 * kPi / 180.0), std::sin(150.0 * kPi / 180.0)};
  const double angle = std::atan2(-face_normal.y, -face_normal.x) + theta1;
  const Vec2 direction{std::cos(angle), std::sin(angle)};
  const Vec2 target{-0.5, 0.5 * std::sqrt(3.0)};  // the middle of the left face
  const Vec2 lamp_centre = target - 1.5 * direction;
  // The lamp's front must face `direction`: it runs along direction turned -90 degrees.
  const Vec2 along{direction.y, -direction.x};
  const Vec2 p0 = lamp_centre - 0.01 * along, p1 = lamp_centre + 0.01 * along;
  const std::string spectrum = nanometres > 0.0 ? ", \"spectrum\": {\"line\": " + std::to_string(nanometres) + "}" : "";
  char text[1400];
  std::snprintf(text, sizeof text, R"({"flatland": 2,
      "materials": {"lamp": {"emittance": 1, "emission": {"beam": 0.01}%s},
                    "glass": {"type": "dielectric", "ior": {"cauchy": [%.17g, %.17g]}}},
      "curves": [{"id": "lamp", "material": "lamp", "line": [[%.17g,%.17g],[%.17g,%.17g]]},
                 {"id": "prism", "material": "glass", "line": [[-1,0],[1,0],[0,%.17g],[-1,0]]}]})",
                spectrum.c_str(), a, b, p0.x, p0.y, p1.x, p1.y, std::sqrt(3.0));
  const FirstPaths round = first_round_paths(testing::scene_from_text(text));
  const double theta1_in = std::asin(std::sin(theta1) / n);
  const double theta2 = apex - theta1_in;
  const double theta2_out = std::asin(n * std::sin(theta2));
  const double deviation = theta1 + theta2_out - apex;
  int checked = 0;
  for (const PhotonPath& path : round.paths) {
    EXPECT_EQ(path.wavelength, nanometres);
    if (path.via.size() != 2 || !path.escaped) continue;
    const Vec2 out = normalized(path.end - path.via[1]);
    // Twice refracted paths leave through the right face (x > 0 at the second event).
    if (!(path.via[1].x > 0.0)) continue;
    const double turned = std::atan2(cross(direction, out), dot(direction, out));
    EXPECT_NEAR(-turned, deviation, 5e-4) << nanometres << " nm, path " << checked;  // clockwise, to the base
    ++checked;
  }
  EXPECT_GT(checked, 3000) << nanometres;  // most of the light goes through (about 85 %)
}

TEST(SpecularChains, PrismDeviatesAsSnellsLawSays) { check_prism_deviation(0.0); }

TEST(SpecularChains, PrismDispersesTwoWavelengthsAsCauchysIndexSays) {
  check_prism_deviation(450.0);
  check_prism_deviation(650.0);
}

TEST(SpecularChains, SpectralPhotonsKeepTheirPowerAndShareItByWavelength) {
  // A white (6500 K) lamp over a white floor: each channel of the floor's light is the lamp's
  // mean share of it, within the noise, and the books are exact.
  const Scene scene = testing::scene_from_text(R"({"flatland": 2,
      "materials": {"sun": {"emittance": 1, "spectrum": {"blackbody": 6500}}, "floor": {"reflectivity": 0.5}},
      "curves": [{"id": "sun", "material": "sun", "line": [[1, 1], [-1, 1]]},
                 {"id": "floor", "material": "floor", "line": [[-3, 0], [3, 0]]}]})");
  const FirstRound round = first_round(scene, 1, Side::Front, 200'000, 1, SamplerKind::Random);
  const Spectrum& received = round.received;
  const double total = received[0] + received[1] + received[2];
  const Spectrum& shares = scene.materials[0].spectrum->mean_shares;
  // Each photon's share of a channel lies in [0, 1]: its variance is at most s (1 - s).
  const double n = total / (round.books.emitted / round.photons);
  for (std::size_t ch = 0; ch < 3; ++ch)
    EXPECT_NEAR(received[ch] / total, shares[ch], 5.0 * std::sqrt(shares[ch] * (1.0 - shares[ch]) / n)) << ch;
}

TEST(SpecularChains, DeepRedLightLandsInTheRedChannel) {
  // Monochromatic light from 620 nm to the end of the range is outside sRGB on the red side (its
  // green and blue are negative): a grey floor under such a lamp receives red only. A 1500 K black
  // body is mostly such light: red > green > blue.
  const auto floor_light = [](const std::string& spectrum) {
    const Scene scene = testing::scene_from_text(R"({"flatland": 2,
        "materials": {"lamp": {"emittance": 1, "spectrum": )" +
                                                 spectrum + R"(}, "floor": {"reflectivity": 0.5}},
        "curves": [{"id": "lamp", "material": "lamp", "line": [[1, 1], [-1, 1]]},
                   {"id": "floor", "material": "floor", "line": [[-3, 0], [3, 0]]}]})");
    return first_round(scene, 1, Side::Front, 20'000, 1, SamplerKind::Random).received;
  };
  for (const char* nm : {"620", "700", "750", "780"}) {
    const Spectrum received = floor_light(std::string(R"({"line": )") + nm + "}");
    EXPECT_GT(received[0], 0.0) << nm;
    EXPECT_EQ(received[1], 0.0) << nm;
    EXPECT_EQ(received[2], 0.0) << nm;
  }
  const Spectrum warm = floor_light(R"({"blackbody": 1500})");
  EXPECT_GT(warm[0], warm[1]);
  EXPECT_GT(warm[1], warm[2]);
}

// ---- Rough surfaces

// A thin beam straight down onto a rough mirror: every facet is met in proportion to its width as
// the beam sees it, which at normal incidence is 1 for every slope, so the facet's slope s is
// N(0, roughness) truncated at 5 roughness and the light leaves at 2 atan(s) from the normal. The
// spread of the leaving angles against that distribution's (by quadrature), within 6 % (5 times
// the standard error of a standard deviation from 4096 paths); roughness 0 is a perfect mirror.
TEST(SpecularChains, ARoughMirrorSpreadsABeamAsItsFacetsSay) {
  for (double roughness : {0.0, 0.05, 0.2}) {
    char text[1200];
    std::snprintf(text, sizeof text, R"({"flatland": 2,
        "materials": {"lamp": {"emittance": 1, "emission": {"beam": 0.001}},
                      "mirror": {"type": "mirror", "roughness": %.17g}},
        "curves": [{"id": "lamp", "material": "lamp", "line": [[0.001, 1], [-0.001, 1]]},
                   {"id": "mirror", "material": "mirror", "line": [[-1, 0], [1, 0]]}]})",
                  roughness);
    const FirstPaths round = first_round_paths(testing::scene_from_text(text));
    std::vector<double> angles;
    for (const PhotonPath& path : round.paths) {
      if (path.via.size() != 1) continue;  // reflected once, then out (or onto the lamp's back)
      const Vec2 out = normalized(path.end - path.via[0]);
      angles.push_back(std::atan2(out.x, out.y));
    }
    ASSERT_GT(angles.size(), 4000u);
    double mean = 0.0, squares = 0.0;
    for (double a : angles) mean += a / static_cast<double>(angles.size());
    for (double a : angles) squares += (a - mean) * (a - mean) / static_cast<double>(angles.size() - 1);
    const double spread = std::sqrt(squares);
    if (roughness == 0.0) {
      EXPECT_LT(spread, 1e-4);  // the beam's own 0.001 degrees
      continue;
    }
    double weight = 0.0, second = 0.0;
    const int steps = 20'000;
    for (int i = 0; i < steps; ++i) {
      const double s = roughness * 5.0 * (2.0 * (i + 0.5) / steps - 1.0);
      const double w = std::exp(-0.5 * s * s / (roughness * roughness));
      const double leaving = 2.0 * std::atan(s);
      weight += w;
      second += w * leaving * leaving;
    }
    const double expected = std::sqrt(second / weight);
    EXPECT_NEAR(spread, expected, 0.06 * expected) << roughness;
    EXPECT_NEAR(mean, 0.0, 5.0 * expected / std::sqrt(static_cast<double>(angles.size()))) << roughness;
    EXPECT_NEAR(round.books.imbalance(), 0.0, 1e-12 * round.books.emitted);
  }
}

TEST(SpecularChains, RoughGlassBlursTheSlabsBeamAndKeepsTheBooks) {
  // A beam straight down through the slab, its glass rough: the light through spreads over the detector (its
  // bins' spread grows with the roughness), and the books stay exact.
  auto spread_through = [](double roughness) {
    char text[1400];
    std::snprintf(text, sizeof text, R"({"flatland": 2,
        "materials": {"lamp": {"emittance": 1, "emission": {"beam": 0.01}},
                      "glass": {"type": "dielectric", "ior": 1.5, "roughness": %.17g},
                      "probe": {"type": "detector", "bins": 400}},
        "curves": [{"id": "lamp", "material": "lamp", "line": [[0.01, 1], [-0.01, 1]]},
                   {"id": "slab", "material": "glass", "line": [[-50,-0.1],[50,-0.1],[50,0],[-50,0],[-50,-0.1]]},
                   {"id": "probe", "material": "probe", "line": [[-2,-1.1],[2,-1.1]]}]})",
                  roughness);
    const Scene scene = testing::scene_from_text(text);
    SolverSettings settings;
    settings.photons = 50'000;
    settings.elements = 4;
    Solver solver = make_solver(scene, settings);
    solver.run();
    EXPECT_NEAR(solver.books().imbalance(), 0.0, 1e-12 * solver.books().emitted);
    const std::vector<double> detected = solver.detected();
    double total = 0.0, mean = 0.0, squares = 0.0;
    for (std::size_t b = 0; b < 400; ++b) {
      const double x = -2.0 + 4.0 * (static_cast<double>(b) + 0.5) / 400.0;
      total += detected[b];
      mean += detected[b] * x;
      squares += detected[b] * x * x;
    }
    mean /= total;
    return std::sqrt(squares / total - mean * mean);
  };
  const double smooth = spread_through(0.0);
  const double rough = spread_through(0.1);
  const double rougher = spread_through(0.3);
  EXPECT_LT(smooth, 0.01);
  EXPECT_GT(rough, 3.0 * smooth);
  EXPECT_GT(rougher, 2.0 * rough);
}

// ---- Detectors

TEST(SpecularChains, ADetectorAroundALampRecordsItsPower) {
  // A circle of four cubic arcs (counter-clockwise: its front inside) around a two-sided lamp:
  // every photon crosses it once, outward (arriving on its front side).
  const double k = 4.0 / 3.0 * (std::sqrt(2.0) - 1.0);
  char text[1400];
  std::snprintf(text, sizeof text, R"({"flatland": 2,
      "materials": {"lamp": {"emittance": 2}, "detector": {"type": "detector", "bins": 8}},
      "curves": [{"id": "lamp", "material": "lamp", "sides": "both", "line": [[-0.1,0.02],[0.1,-0.02]]},
                 {"id": "ring", "material": "detector", "bezier": [[1,0],[1,%.17g],[%.17g,1],[0,1],[%.17g,1],[-1,%.17g],
                   [-1,0],[-1,%.17g],[%.17g,-1],[0,-1],[%.17g,-1],[1,%.17g],[1,0]]}]})",
                k, k, -k, k, -k, -k, k, -k);
  const Scene scene = testing::scene_from_text(text);
  for (Transport transport : {Transport::Shooting, Transport::Walk}) {
    SolverSettings settings;
    settings.photons = 200'000;
    settings.elements = 4;
    settings.transport = transport;
    Solver solver = make_solver(scene, settings);
    solver.run();
    const DetectorLayout& layout = solver.detector_layout();
    ASSERT_EQ(layout.size, 2u * 8u);
    ASSERT_EQ(layout.offsets[1], 0u);
    const std::vector<double> detected = solver.detected();
    double outward = 0.0;
    double inward = 0.0;
    for (std::size_t bin = 0; bin < 8; ++bin) {
      outward += detected[bin];
      inward += detected[8 + bin];
      // Every eighth of the circle gets some (the least, near the lamp's own line, about 5 %): a
      // loose check that the bins follow arc length.
      EXPECT_GT(detected[bin], 0.03 * solver.books().emitted) << to_string(transport) << " bin " << bin;
    }
    EXPECT_EQ(inward, 0.0);
    // Each crossing's units lose at most 2^kDetectorShift - 1 of 2^60 per round's power.
    EXPECT_NEAR(outward, solver.books().emitted, 1e-9 * solver.books().emitted) << to_string(transport);
    EXPECT_NEAR(solver.books().escaped, solver.books().emitted, 1e-12 * solver.books().emitted);
  }
}

// ---- The books and the bits

TEST(SpecularChains, GlassAbsorbsByBeerLambert) {
  // A beam straight down through a slab of absorption sigma and thickness d: apart from the
  // Fresnel series, exp(-sigma d) of each pass survives. With R(0) = 0.04 the screen gets
  // T = (1 - R)^2 t / (1 - R^2 t^2), t = exp(-sigma d).
  const double sigma = 2.0, d = 0.1;
  char text[1400];
  std::snprintf(text, sizeof text, R"({"flatland": 2,
      "materials": {"lamp": {"emittance": 1, "emission": {"beam": 0.1}},
                    "glass": {"type": "dielectric", "ior": 1.5, "absorption": %.17g}, "screen": {"reflectivity": 0.5}},
      "curves": [{"id": "lamp", "material": "lamp", "line": [[0.1,1],[-0.1,1]]},
                 {"id": "slab", "material": "glass", "line": [[-50,%.17g],[50,%.17g],[50,0],[-50,0],[-50,%.17g]]},
                 {"id": "screen", "material": "screen", "line": [[-60,-0.5],[60,-0.5]]}]})",
                sigma, -d, -d, -d);
  const FirstRound round = first_round(testing::scene_from_text(text), 2, Side::Front, 400'000, 1, SamplerKind::Random);
  const double r = fresnel_reflectance(1.0, 1.5, 1.0);
  const double t = std::exp(-sigma * d);
  const double expected = (1.0 - r) * (1.0 - r) * t / (1.0 - r * r * t * t);
  // A photon brings between 0 and 1 of its power to the screen: the variance of that share is at
  // most mu (1 - mu), mu its mean.
  EXPECT_NEAR(round.received[0] / round.books.emitted, expected,
              5.0 * std::sqrt(expected * (1.0 - expected) / round.photons));
  EXPECT_GT(round.books.absorbed_glass, 0.1 * round.books.emitted);
}

TEST(SpecularChains, TeachingScenesBalanceTheirBooksWithBothTransports) {
  for (const char* file : {"scenes2d/lens.json", "scenes2d/parabolic_mirror.json", "scenes2d/light_guide.json",
                           "scenes2d/mirror_room.json", "scenes2d/prism.json"}) {
    const Scene scene = testing::scene_from_file(file);
    ASSERT_TRUE(scene.has_specular()) << file;
    for (Transport transport : {Transport::Shooting, Transport::Walk}) {
      SolverSettings settings;
      settings.photons = 100'000;
      settings.transport = transport;
      Solver solver = make_solver(scene, settings);
      solver.run();
      EXPECT_NE(solver.stop_reason(), StopReason::BooksUnbalanced) << file << " " << to_string(transport);
      const EnergyBooks books = solver.books();
      EXPECT_NEAR(books.imbalance(), 0.0, 1e-9 * books.emitted) << file << " " << to_string(transport);
    }
  }
}

TEST(SpecularChains, SameBitsOnAnyThreadCountAndStep) {
  const Scene scene = testing::scene_from_file("scenes2d/lens.json");
  for (Transport transport : {Transport::Shooting, Transport::Walk}) {
    SolverSettings settings;
    settings.photons = 60'000;
    settings.transport = transport;
    settings.threads = 1;
    Solver one = make_solver(scene, settings);
    one.run();
    settings.threads = 2;
    Solver two = make_solver(scene, settings);
    while (two.step_photons(5000) > 0) {
    }
    EXPECT_EQ(testing::solution_data(one), testing::solution_data(two)) << to_string(transport);
    EXPECT_EQ(one.detected(), two.detected());
  }
}

}  // namespace
}  // namespace flatland
