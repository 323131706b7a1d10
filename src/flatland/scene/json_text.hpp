// Reading JSON text for the scene reader (scene_io.cpp), internal to scene/: field paths, values
// quoted for one-line messages, and a scanner that finds where each value and key begins.
#pragma once

#include <cstddef>
#include <optional>
#include <string>
#include <string_view>
#include <unordered_map>
#include <vector>

#include <nlohmann/json.hpp>

namespace flatland::scene_json {

using Json = nlohmann::ordered_json;  // keeps materials and keys in file order

// Nesting deeper than this is rejected: a scene needs four levels (curves[i].bezier[j][k]).
inline constexpr std::size_t kMaxDepth = 64;
// Names shown in a "defined: ..." list before it is cut short.
inline constexpr std::size_t kMaxListedNames = 12;

// A user's string quoted for a one-line message: JSON escapes (so a newline in a key cannot break
// the line) and long strings cut short.
std::string quote(std::string_view s);

// How a value's type reads in a message: "an object", "a number", ...
std::string type_name(const Json& v);

// Field paths: keys made of [A-Za-z0-9_-] join with dots (materials.wall.reflectivity); any other
// key is written as a quoted subscript (materials["my lamp"].emittance); indices as [i].
std::string append_key(const std::string& path, std::string_view key);
std::string append_index(const std::string& path, std::size_t index);

// The candidate close enough to `word` to suggest ("did you mean ...").
std::optional<std::string> closest(std::string_view word, const std::vector<std::string>& candidates);

// The names quoted and joined by commas, cut short after kMaxListedNames.
std::string quoted_list(const std::vector<std::string>& names);

// ---------------------------------------------------------------------------------------------
// The position scanner: a walk over JSON text that records, per field path, where each value and
// each object key begins. It runs on text nlohmann has accepted (or accepted up to an overflowing
// number), keeps an explicit stack instead of recursing, and stops quietly on anything unexpected.
// Without `record` it only looks for what nlohmann lets through (duplicate keys, nesting too deep)
// and builds no paths: a scene file is scanned that way first, and positions are recorded only
// when a message needs one (a path string and two map entries per number would be most of the
// time a large scene takes to load).

struct DuplicateKey {
  std::string object_path;
  std::string key;
  std::size_t offset = 0;        // the second occurrence's opening quote
  std::size_t first_offset = 0;  // the first occurrence's
};

struct NumberOverflow {
  std::string path;
  std::string token;
  std::size_t offset = 0;
};

struct TextMap {
  std::unordered_map<std::string, std::size_t> values;  // path -> offset of the value
  std::unordered_map<std::string, std::size_t> keys;    // path -> offset of the member's key
  std::optional<DuplicateKey> duplicate;                // the first duplicate key in the text
  std::optional<NumberOverflow> overflow;               // the first number beyond double's range
  std::optional<std::size_t> too_deep;                  // offset of a container nested too deep
};

// The scan of `text`; with `record` false, only duplicate keys and nesting too deep are looked for.
TextMap scan_positions(std::string_view text, bool record);

}  // namespace flatland::scene_json
