// Text helpers: edit distance, did-you-mean hints with a bounded cost, positions in a text, and
// numbers beyond a double's range.
#include "flatland/base/text.hpp"

#include <chrono>
#include <string>

#include <gtest/gtest.h>

namespace flatland {
namespace {

TEST(Text, EditDistanceCountsInsertionsDeletionsSubstitutionsAndTranspositions) {
  EXPECT_EQ(edit_distance("", ""), 0u);
  EXPECT_EQ(edit_distance("abc", ""), 3u);
  EXPECT_EQ(edit_distance("", "abc"), 3u);
  EXPECT_EQ(edit_distance("kitten", "sitting"), 3u);
  EXPECT_EQ(edit_distance("sitting", "kitten"), 3u);  // symmetric, whichever is longer
  EXPECT_EQ(edit_distance("emittance", "emitance"), 1u);
  EXPECT_EQ(edit_distance("ab", "ba"), 1u);      // one transposition
  EXPECT_EQ(edit_distance("Lamp", "lamp"), 0u);  // case-insensitive
  EXPECT_EQ(edit_distance("receiver", "reciever"), 1u);
}

TEST(Text, ClosestMatchSuggestsTyposOnly) {
  const std::vector<std::string> names = {"emitter", "receiver", "black"};
  EXPECT_EQ(closest_match("reciever", names).value_or(""), "receiver");
  EXPECT_EQ(closest_match("blak", names).value_or(""), "black");
  EXPECT_FALSE(closest_match("wall", names).has_value());
}

// A megabyte-long word or candidate is no typo: it is skipped at once instead of filling a
// table of 200 x 10^6 entries (the old hint took 1.6 GB for a 1 MB material name).
TEST(Text, HintsForHugeWordsAreBoundedInTimeAndMemory) {
  const std::string huge(1'000'000, 'm');
  const std::vector<std::string> names = {"mmm", huge, "lamp"};
  const auto start = std::chrono::steady_clock::now();
  EXPECT_FALSE(closest_match(huge, names).has_value());
  EXPECT_EQ(closest_match("mmmm", names).value_or(""), "mmm");
  EXPECT_FALSE(closest_match(std::string(150, 'm'), {huge}).has_value());
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  EXPECT_LT(seconds, 5.0);  // generous: a bound against quadratic blow-up, not a benchmark
}

TEST(Text, PositionOfCountsLinesAndCodePoints) {
  const std::string text = "ab\ncd\n\xC3\xA9x";  // e-acute is two bytes, one column
  EXPECT_EQ(position_of(text, 0).line, 1u);
  EXPECT_EQ(position_of(text, 0).column, 1u);
  EXPECT_EQ(position_of(text, 4).line, 2u);
  EXPECT_EQ(position_of(text, 4).column, 2u);
  EXPECT_EQ(position_of(text, 8).line, 3u);
  EXPECT_EQ(position_of(text, 8).column, 2u);
  EXPECT_EQ(position_of(text, 1000).line, 3u);  // past the end: the end
}

TEST(Text, FindsTheNumberThatOverflowsADouble) {
  EXPECT_FALSE(find_overflowing_number(R"({"a": 1e300, "b": -2.5e-400, "c": [1, 2]})").has_value());
  const std::string text = R"({"s": "1e999 in a string", "x": [1, -1e400]})";
  ASSERT_TRUE(find_overflowing_number(text).has_value());
  EXPECT_EQ(*find_overflowing_number(text), text.find("-1e400"));
  // An escaped quote does not end the string early.
  const std::string escaped = R"({"s": "a \" 1e999", "y": 2e308})";
  ASSERT_TRUE(find_overflowing_number(escaped).has_value());
  EXPECT_EQ(*find_overflowing_number(escaped), escaped.find("2e308"));
}

TEST(Text, NumbersReadBackAndWholeNumbersStayWhole) {
  EXPECT_EQ(format_number(100.0), "100");
  EXPECT_EQ(format_number(-3.0), "-3");
  EXPECT_EQ(format_number(0.1), "0.1");
  EXPECT_EQ(format_number(2.5), "2.5");
  EXPECT_EQ(format_number(1e20), "1e+20");
  EXPECT_EQ(format_number(1.0 / 3.0), "0.3333333333333333");
  EXPECT_EQ(format_number(123.456, 3), "123");
}

TEST(Text, CsvFieldsAreQuotedOnlyWhenTheyMustBe) {
  EXPECT_EQ(csv_field("probe"), "probe");
  EXPECT_EQ(csv_field("a,b"), "\"a,b\"");
  EXPECT_EQ(csv_field("say \"hi\""), "\"say \"\"hi\"\"\"");
  EXPECT_EQ(csv_field("two\nlines"), "\"two\nlines\"");
}

}  // namespace
}  // namespace flatland
