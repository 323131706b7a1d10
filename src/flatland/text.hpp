// Small text helpers for messages a user acts on.
#pragma once

#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace flatland {

// Optimal string alignment distance (Levenshtein plus adjacent transpositions), case-insensitive.
std::size_t edit_distance(std::string_view a, std::string_view b);

// The candidate closest to `word` if it is close enough to be a likely typo (at most
// 1 + length / 4 edits), for "did you mean ...?" hints.
std::optional<std::string> closest_match(std::string_view word,
                                         const std::vector<std::string>& candidates);

}  // namespace flatland
