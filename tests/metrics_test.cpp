#include "flatland/metrics.hpp"

#include <gtest/gtest.h>

namespace flatland {
namespace {

// A result document with one grey curve of length 2 and the given samples of B.
nlohmann::json document(const std::vector<double>& b, const std::string& id = "floor") {
  nlohmann::json samples = nlohmann::json::array();
  for (std::size_t j = 0; j < b.size(); ++j)
    samples.push_back({{"s", (static_cast<double>(j) + 0.5) * 2.0 / static_cast<double>(b.size())},
                       {"x", 0}, {"y", 0}, {"B", b[j]}});
  return {{"flatland_result", 1}, {"curves", {{{"id", id}, {"length", 2.0}, {"samples", samples}}}}};
}

TEST(Metrics, IdenticalResultsHaveZeroError) {
  const nlohmann::json a = document({1, 2, 3, 4});
  const Result<Comparison> c = compare_results(a, a);
  ASSERT_TRUE(c.ok()) << c.error().message;
  EXPECT_EQ(c->scene.l1, 0.0);
  EXPECT_EQ(c->scene.l2, 0.0);
  EXPECT_EQ(c->scene.linf, 0.0);
}

TEST(Metrics, NormsMatchHandComputedValues) {
  // B = R + (0.1, -0.1, 0, 0.2) with R = (1, 2, 3, 4): every cell 0.5 long.
  const Result<Comparison> c = compare_results(document({1.1, 1.9, 3, 4.2}), document({1, 2, 3, 4}));
  ASSERT_TRUE(c.ok());
  EXPECT_NEAR(c->scene.l1, 0.4 / 10.0, 1e-15);
  EXPECT_NEAR(c->scene.l2, std::sqrt(0.06 / 30.0), 1e-15);
  EXPECT_NEAR(c->scene.linf, 0.2 / 4.0, 1e-15);
  // A uniform 10 % excess is 10 % in every norm.
  const Result<Comparison> scaled = compare_results(document({1.1, 2.2, 3.3, 4.4}), document({1, 2, 3, 4}));
  EXPECT_NEAR(scaled->scene.l1, 0.1, 1e-14);
  EXPECT_NEAR(scaled->scene.l2, 0.1, 1e-14);
  EXPECT_NEAR(scaled->scene.linf, 0.1, 1e-14);
}

// Norms are ratios: scaling B and the reference by 1e300 (or 1e-300) changes nothing, although
// the squares of such values overflow (or underflow) a double.
TEST(Metrics, ExtremeMagnitudesGiveTheSameNorms) {
  const Result<Comparison> unit = compare_results(document({1.1, 1.9, 3, 4.2}), document({1, 2, 3, 4}));
  ASSERT_TRUE(unit.ok());
  for (const double scale : {1e300, 1e-300, -1e300}) {
    const Result<Comparison> c = compare_results(document({1.1 * scale, 1.9 * scale, 3 * scale, 4.2 * scale}),
                                                 document({scale, 2 * scale, 3 * scale, 4 * scale}));
    ASSERT_TRUE(c.ok()) << c.error().message;
    EXPECT_NEAR(c->scene.l1, unit->scene.l1, 1e-12) << scale;
    EXPECT_NEAR(c->scene.l2, unit->scene.l2, 1e-12) << scale;
    EXPECT_NEAR(c->scene.linf, unit->scene.linf, 1e-12) << scale;
  }
  // Opposite extremes: the error is finite (2 max|R| at most).
  const Result<Comparison> opposite = compare_results(document({-1e308, -1e308}), document({1e308, 1e308}));
  ASSERT_TRUE(opposite.ok());
  EXPECT_NEAR(opposite->scene.l2, 2.0, 1e-12);
  EXPECT_NEAR(opposite->scene.linf, 2.0, 1e-12);
}

TEST(Metrics, DifferentScenesAreErrors) {
  EXPECT_FALSE(compare_results(document({1, 2}), document({1, 2, 3})).ok());
  EXPECT_FALSE(compare_results(document({1, 2}, "floor"), document({1, 2}, "wall")).ok());
  nlohmann::json longer = document({1, 2});
  longer["curves"][0]["length"] = 3.0;
  EXPECT_FALSE(compare_results(document({1, 2}), longer).ok());
  EXPECT_FALSE(compare_results(nlohmann::json::object(), document({1})).ok());
}

}  // namespace
}  // namespace flatland
