// flatland/light_field: the fluence of photon flights on a grid, against brute force (each cell's
// clipped length), conservation (the field's integral is the flights' power x length) and the
// record's weighting (a part of the photons stands for all of them).
#include "flatland/results/light_field.hpp"

#include <cmath>
#include <numeric>
#include <random>
#include <vector>

#include <gtest/gtest.h>

#include "flatland/transport/solver.hpp"
#include "test_support.hpp"

namespace flatland {
namespace {

Box make_box(Vec2 lower, Vec2 upper) {
  Box box;
  box.lower = lower;
  box.upper = upper;
  return box;
}

// The length of the leg a -> b inside the rectangle [lo, hi]: an independent clip.
double clipped_length(Vec2 a, Vec2 b, Vec2 lo, Vec2 hi) {
  double t0 = 0.0;
  double t1 = 1.0;
  const Vec2 d = b - a;
  auto clip = [&](double p, double q, double low, double high) {
    if (q == 0.0) return p >= low && p <= high;
    double ta = (low - p) / q;
    double tb = (high - p) / q;
    if (ta > tb) std::swap(ta, tb);
    t0 = std::max(t0, ta);
    t1 = std::min(t1, tb);
    return true;
  };
  if (!clip(a.x, d.x, lo.x, hi.x) || !clip(a.y, d.y, lo.y, hi.y) || t1 <= t0) return 0.0;
  return (t1 - t0) * length(d);
}

double integral(const LightField& field, int channel = 0) {
  double sum = 0.0;
  for (std::size_t i = static_cast<std::size_t>(channel); i < field.values().size();
       i += static_cast<std::size_t>(field.channels()))
    sum += field.values()[i];
  return sum * field.cell() * field.cell();
}

TEST(LightField, RefusesBadGrids) {
  EXPECT_FALSE(LightField::create(Box{}, 16, 1).ok());
  EXPECT_FALSE(LightField::create(make_box({0, 0}, {1, 1}), 0, 1).ok());
  EXPECT_FALSE(LightField::create(make_box({0, 0}, {1, 1}), 5000, 1).ok());
  EXPECT_FALSE(LightField::create(make_box({0, 0}, {1, 1}), 16, 2).ok());
  EXPECT_FALSE(LightField::create(make_box({0, 0}, {0, 0}), 16, 1).ok());
}

TEST(LightField, GridCoversTheBoxWithSquareCells) {
  Result<LightField> field = LightField::create(make_box({-1, 2}, {3, 3}), 40, 3);
  ASSERT_TRUE(field.ok());
  EXPECT_EQ(field->width(), 40);
  EXPECT_EQ(field->height(), 10);
  EXPECT_DOUBLE_EQ(field->cell(), 0.1);
  EXPECT_EQ(field->values().size(), 40u * 10u * 3u);
  // A flat box keeps one row.
  Result<LightField> flat = LightField::create(make_box({0, 0}, {1, 0}), 8, 1);
  ASSERT_TRUE(flat.ok());
  EXPECT_EQ(flat->height(), 1);
}

// Every cell holds power x weight x (length of the leg inside it) / cell area, for legs in every
// direction, inside, crossing and outside the box, axis-parallel ones and ones along grid lines.
TEST(LightField, EveryCellHoldsItsClippedLength) {
  const Box box = make_box({-0.5, 1.0}, {3.0, 3.5});
  Result<LightField> made = LightField::create(box, 7, 1);
  ASSERT_TRUE(made.ok());
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> x(-1.5, 4.0), y(0.0, 4.5);
  std::vector<std::array<Vec2, 2>> legs;
  for (int i = 0; i < 300; ++i) legs.push_back({Vec2{x(rng), y(rng)}, Vec2{x(rng), y(rng)}});
  const double cell = made->cell();
  legs.push_back({Vec2{-1.0, 1.0 + 2 * cell}, Vec2{4.0, 1.0 + 2 * cell}});  // along a grid line
  legs.push_back({Vec2{-0.5 + 3 * cell, 0.0}, Vec2{-0.5 + 3 * cell, 4.0}});
  legs.push_back({Vec2{0.2, 1.3}, Vec2{0.2, 3.1}});   // vertical inside
  legs.push_back({Vec2{-0.5, 1.0}, Vec2{3.0, 3.5}});  // the diagonal, corner to corner
  for (const auto& leg : legs) {
    LightField field = *made;
    field.add_leg(leg[0], leg[1], Spectrum{2.0, 0.0, 0.0}, 1.5);
    for (int row = 0; row < field.height(); ++row)
      for (int column = 0; column < field.width(); ++column) {
        const Vec2 lo = box.lower + Vec2{column * cell, row * cell};
        const double expected = 3.0 * clipped_length(leg[0], leg[1], lo, lo + Vec2{cell, cell}) / (cell * cell);
        // A leg along a grid line is booked to one of the two cells it borders: compared below by sum.
        const bool on_line = (leg[0].x == leg[1].x && std::fmod(leg[0].x - box.lower.x + 1e-12, cell) < 1e-9) ||
                             (leg[0].y == leg[1].y && std::fmod(leg[0].y - box.lower.y + 1e-12, cell) < 1e-9);
        if (!on_line) {
          EXPECT_NEAR(field.values()[static_cast<std::size_t>(row * field.width() + column)], expected,
                      1e-9 * (1.0 + expected));
        }
      }
    const double all = 3.0 * clipped_length(leg[0], leg[1], box.lower, field.box().upper);
    EXPECT_NEAR(integral(field), all, 1e-9 * (1.0 + all));
  }
}

TEST(LightField, FlightsFollowTheirChainsAndEscapeToTheEdge) {
  Result<LightField> field = LightField::create(make_box({0, 0}, {4, 2}), 64, 3);
  ASSERT_TRUE(field.ok());
  PhotonPath path;
  path.origin = {1, 1};
  path.via = {Vec2{3, 1}, Vec2{3, 0.5}};
  path.end = {2, 0.5};
  path.power = {1.0, 0.5, 0.25};
  field->add_flight(path, 2.0);
  EXPECT_NEAR(integral(*field, 0), 2.0 * (2.0 + 0.5 + 1.0), 1e-12);
  EXPECT_NEAR(integral(*field, 2), 0.25 * 2.0 * 3.5, 1e-12);
  // Escaped after the chain: from (2, 0.5) going -x (end = last point + direction) to x = 0.
  field->clear();
  path.escaped = true;
  path.end = Vec2{3, 0.5} + Vec2{-0.1, 0.0};
  field->add_flight(path, 1.0);
  EXPECT_NEAR(integral(*field, 0), 2.0 + 0.5 + 3.0, 1e-12);
}

TEST(LightField, RecordStandsForEveryPhotonShot) {
  Result<LightField> made = LightField::create(make_box({0, 0}, {1, 1}), 8, 1);
  ASSERT_TRUE(made.ok());
  auto flight = [](double y, std::uint32_t bounce, bool cut = false) {
    PhotonPath p;
    p.origin = {0.0, y};
    p.end = {1.0, y};
    p.power = {1.0, 1.0, 1.0};
    p.bounce = bounce;
    p.cut = cut;
    return p;
  };
  // Shooting: 4 photons recorded of 100, each path one photon (bounce is the round's number).
  LightField shooting = *made;
  EXPECT_EQ(
      shooting.add_record({flight(0.1, 3), flight(0.3, 3), flight(0.5, 3), flight(0.7, 3)}, 100, Transport::Shooting),
      4u);
  EXPECT_NEAR(integral(shooting), 100.0, 1e-12);
  EXPECT_EQ(shooting.photons(), 100.0);
  // Walks: two walks recorded whole, a third cut short: left out, with its photon.
  LightField walks = *made;
  EXPECT_EQ(walks.add_record({flight(0.1, 0), flight(0.2, 1), flight(0.3, 0), flight(0.4, 0), flight(0.5, 1, true)}, 10,
                             Transport::Walk),
            2u);
  EXPECT_NEAR(integral(walks), 10.0 / 2.0 * 3.0, 1e-12);
  // Built piece by piece with weight 1, then added with the record's weight: the same field.
  LightField pieces = *made;
  EXPECT_EQ(pieces.add_flights({flight(0.1, 0), flight(0.2, 1)}, 2, Transport::Walk), 1u);
  // The first three of a record whose fourth flight continues the third's walk: that walk is left
  // out, and a truncated record marks it cut.
  const std::vector<PhotonPath> longer = {flight(0.3, 0), flight(0.4, 0), flight(0.5, 1), flight(0.6, 0)};
  EXPECT_EQ(pieces.add_flights(longer, 2, Transport::Walk), 1u);
  std::vector<PhotonPath> truncated = longer;
  truncate_record(truncated, 2, Transport::Walk);
  ASSERT_EQ(truncated.size(), 2u);
  EXPECT_TRUE(truncated[1].cut);
  EXPECT_FALSE(truncated[0].cut);
  EXPECT_EQ(pieces.photons(), 0.0);
  LightField joined = *made;
  joined.add(pieces, 10.0 / 2.0, 10.0);
  EXPECT_EQ(joined.photons(), 10.0);
  for (std::size_t i = 0; i < joined.values().size(); ++i)
    EXPECT_NEAR(joined.values()[i], walks.values()[i], 1e-12 * (1.0 + walks.values()[i]));
  EXPECT_EQ(walks.add_record({}, 10, Transport::Walk), 0u);
  EXPECT_EQ(walks.add_record({flight(0.5, 0, true)}, 10, Transport::Walk), 0u);
}

TEST(LightField, QuantileOfLitCells) {
  Result<LightField> field = LightField::create(make_box({0, 0}, {10, 1}), 10, 1);
  ASSERT_TRUE(field.ok());
  EXPECT_EQ(field->quantile(0.99), 0.0);
  // Cell k (k = 0..4) crossed by k + 1 unit legs: luminance k + 1; cells 5..9 dark.
  for (int k = 0; k < 5; ++k)
    for (int n = 0; n <= k; ++n) field->add_leg({k + 0.0, 0.5}, {k + 1.0, 0.5}, {1.0, 1.0, 1.0}, 1.0);
  EXPECT_NEAR(field->quantile(1.0), 5.0, 1e-12);
  EXPECT_NEAR(field->quantile(0.5), 3.0, 1e-12);
  EXPECT_NEAR(field->quantile(0.2), 1.0, 1e-12);
  EXPECT_NEAR(field->quantile(0.0), 1.0, 1e-12);
}

// A solver's first quarter of a batch, weighted 4x, against every photon of it: the field's
// integral (power x length of flight) agrees within four standard errors of the quarter's mean
// (the spread of the per-photon integrals; Sobol' points do better than this bound of random ones).
TEST(LightField, PartOfARecordEstimatesTheWhole) {
  const Scene scene = testing::scene_from_file("scenes2d/default.json");
  SolverSettings settings;
  settings.seed = 5;
  constexpr std::uint64_t kShot = 4096;
  auto record = [&](std::size_t limit) {
    Result<Solver> solver = Solver::create(scene, settings);
    EXPECT_TRUE(solver.ok());
    std::vector<PhotonPath> paths;
    EXPECT_EQ(solver->step_photons(kShot, nullptr, &paths, limit), kShot);
    return paths;
  };
  const std::vector<PhotonPath> all = record(kShot);
  const std::vector<PhotonPath> quarter = record(kShot / 4);
  ASSERT_EQ(all.size(), kShot);
  ASSERT_EQ(quarter.size(), kShot / 4);
  Result<LightField> made = LightField::for_scene(scene, 32);
  ASSERT_TRUE(made.ok());
  LightField whole = *made;
  whole.add_record(all, kShot, Transport::Shooting);
  LightField part = *made;
  part.add_record(quarter, kShot, Transport::Shooting);
  // Per-photon integrals of the first quarter, for the standard error.
  std::vector<double> each;
  for (const PhotonPath& path : quarter) {
    LightField one = *made;
    one.add_flight(path, 1.0);
    each.push_back(integral(one, 1));
  }
  const double mean = std::accumulate(each.begin(), each.end(), 0.0) / static_cast<double>(each.size());
  double variance = 0.0;
  for (double v : each) variance += (v - mean) * (v - mean);
  variance /= static_cast<double>(each.size() - 1);
  const double standard_error = kShot * std::sqrt(variance / static_cast<double>(each.size()));
  EXPECT_NEAR(integral(part, 1), integral(whole, 1), 4.0 * standard_error);
  EXPECT_GT(integral(whole, 1), 0.0);
  EXPECT_EQ(part.photons(), whole.photons());
}

// A beam of known power crossing a known distance: a lamp of length 1 and emittance 1 (power 1)
// shines a 2-degree beam of 700 nm light straight at a black wall 2 away. The field of every
// photon's flight integrates to power x length: between 2 (straight up) and 2 / cos 2 degrees.
// Deep red lies outside sRGB on the red side, so only the red channel holds light.
TEST(LightField, ABeamsFieldIsItsPowerTimesItsLength) {
  const Scene scene = testing::scene_from_text(R"({
    "flatland": 2,
    "materials": {
      "lamp": {"emittance": 1.0, "emission": {"beam": 2}, "spectrum": {"line": 700}},
      "black": {"reflectivity": 0}
    },
    "curves": [
      {"id": "lamp", "material": "lamp", "line": [[0, 0], [1, 0]]},
      {"id": "wall", "material": "black", "line": [[2, 2], [-1, 2]]}
    ]
  })");
  ASSERT_EQ(scene.channels, 3);
  SolverSettings settings;
  settings.photons = 20'000;
  Result<Solver> solver = Solver::create(scene, settings);
  ASSERT_TRUE(solver.ok()) << solver.error().message;
  Result<LightField> field = LightField::for_scene(scene, 64);
  ASSERT_TRUE(field.ok());
  while (!solver->stopped()) {
    std::vector<PhotonPath> record;
    const std::uint64_t shot = solver->step_photons(settings.photons, nullptr, &record, settings.photons);
    if (shot == 0) break;
    EXPECT_EQ(record.size(), shot);
    field->add_record(record, shot, Transport::Shooting);
  }
  EXPECT_EQ(field->photons(), static_cast<double>(settings.photons));
  const double cos2 = std::cos(2.0 * std::acos(-1.0) / 180.0);
  // A colour scene's power is the channels' mean (grey light of power P is P in each channel).
  const double power_x_length = (integral(*field, 0) + integral(*field, 1) + integral(*field, 2)) / 3.0;
  EXPECT_GE(power_x_length, 2.0 * (1.0 - 1e-12));
  EXPECT_LE(power_x_length, 2.0 / cos2 * (1.0 + 1e-12));
  EXPECT_EQ(integral(*field, 1), 0.0);
  EXPECT_EQ(integral(*field, 2), 0.0);
}

}  // namespace
}  // namespace flatland
