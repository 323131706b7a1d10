// Small text helpers for messages a user acts on.
#pragma once

#include <cstddef>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace flatland {

// Optimal string alignment distance (Levenshtein plus adjacent transpositions), case-insensitive.
// Memory is linear in the shorter word, time the product of the two lengths.
std::size_t edit_distance(std::string_view a, std::string_view b);

// The candidate closest to `word` if it is close enough to be a likely typo (at most
// 1 + length / 4 edits), for "did you mean ...?" hints. Words or candidates longer than
// kMaxHintLength are never typos of each other and are skipped, so the cost is bounded whatever
// the input holds.
inline constexpr std::size_t kMaxHintLength = 200;
std::optional<std::string> closest_match(std::string_view word, const std::vector<std::string>& candidates);

// Line and column (in UTF-8 code points, both from 1) of a byte offset in a text.
struct TextPosition {
  std::size_t line = 1;
  std::size_t column = 1;
};
TextPosition position_of(std::string_view text, std::size_t offset);

// The byte offset of the first JSON number token in `text` that overflows a double (such as
// 1e400), skipping strings; nullopt when there is none. nlohmann::json refuses such numbers
// without saying where.
std::optional<std::size_t> find_overflowing_number(std::string_view text);

// A number as text: with `significant` digits (printf's %g), or, with 0, the shortest text that
// reads back as the same double. Every message that shows a number writes it with this.
std::string format_number(double value, int significant = 0);

// A CSV field (RFC 4180): as it is, or in double quotes (inner quotes doubled) when it holds a
// comma, a quote or a line break.
std::string csv_field(std::string_view text);

// A whole number that fits an int ("16", "-3"), or nullopt ("16x", "1e3", "99999999999", "").
std::optional<int> whole_number(const std::string& text);

}  // namespace flatland
