#include "flatland/scene/json_text.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdlib>

#include "flatland/base/text.hpp"

namespace flatland::scene_json {

namespace {

// parsing normally): strtod returns +-HUGE_VAL (infinity) for exactly those. The program never changes the C locale, so
// '.' is the decimal point.
bool overflows(std::string_view token) {
  const std::string text(token);
  const double value = std::strtod(text.c_str(), nullptr);
  return std::isinf(value);
}

void append_utf8(std::string& out, std::uint32_t code) {
  if (code < 0x80) {
    out += static_cast<char>(code);
  } else if (code < 0x800) {
    out += static_cast<char>(0xC0 | (code >> 6));
    out += static_cast<char>(0x80 | (code & 0x3F));
  } else if (code < 0x10000) {
    out += static_cast<char>(0xE0 | (code >> 12));
    out += static_cast<char>(0x80 | ((code >> 6) & 0x3F));
    out += static_cast<char>(0x80 | (code & 0x3F));
  } else {
    out += static_cast<char>(0xF0 | (code >> 18));
    out += static_cast<char>(0x80 | ((code >> 12) & 0x3F));
    out += static_cast<char>(0x80 | ((code >> 6) & 0x3F));
    out += static_cast<char>(0x80 | (code & 0x3F));
  }
}

class TextScanner {
 public:
  TextScanner(std::string_view text, bool record) : text_(text), record_(record) {}

  TextMap scan() {
    if (text_.substr(0, 3) == "\xEF\xBB\xBF") pos_ = 3;  // a UTF-8 byte order mark
    std::string path;                                    // of the value about to be read
    bool expect_value = true;
    while (true) {
      skip_space();
      if (pos_ >= text_.size()) return std::move(map_);
      if (expect_value) {
        if (record_) map_.values.emplace(path, pos_);
        const char ch = text_[pos_];
        if (ch == '{' || ch == '[') {
          if (stack_.size() >= kMaxDepth) {
            map_.too_deep = pos_;
            return std::move(map_);
          }
          stack_.push_back(Frame{path, ch == '{', 0, {}});
          ++pos_;
          skip_space();
          if (pos_ < text_.size() && (text_[pos_] == '}' || text_[pos_] == ']')) {
            ++pos_;
            stack_.pop_back();
            expect_value = false;
          } else if (ch == '{') {
            if (!read_member_key(path)) return std::move(map_);
          } else if (record_) {
            path = append_index(stack_.back().path, 0);
          }
          continue;
        }
        if (ch == '"') {
          read_string();
        } else {
          const std::size_t start = pos_;
          while (pos_ < text_.size() && !is_space(text_[pos_]) && text_[pos_] != ',' && text_[pos_] != ']' &&
                 text_[pos_] != '}') {
            ++pos_;
          }
          const std::string_view token = text_.substr(start, pos_ - start);
          if (record_ && !map_.overflow && overflows(token)) {
            map_.overflow = NumberOverflow{path, std::string(token), start};
          }
        }
        expect_value = false;
        continue;
      }
      if (stack_.empty()) return std::move(map_);
      const char ch = text_[pos_];
      if (ch == ',') {
        ++pos_;
        Frame& frame = stack_.back();
        if (frame.object) {
          if (!read_member_key(path)) return std::move(map_);
        } else if (record_) {
          path = append_index(frame.path, ++frame.count);
        }
        expect_value = true;
      } else if (ch == '}' || ch == ']') {
        ++pos_;
        stack_.pop_back();
      } else {
        return std::move(map_);  // not JSON after all; keep what we have
      }
    }
  }

 private:
  struct Frame {
    std::string path;
    bool object = false;
    std::size_t count = 0;                              // index of the current array element
    std::unordered_map<std::string, std::size_t> seen;  // keys of an object -> offset
  };

  static bool is_space(char ch) { return ch == ' ' || ch == '\t' || ch == '\n' || ch == '\r'; }

  void skip_space() {
    while (pos_ < text_.size() && is_space(text_[pos_])) ++pos_;
  }

  // "key" : -> sets path to the member's path; false when the text is not shaped like a member.
  bool read_member_key(std::string& path) {
    skip_space();
    if (pos_ >= text_.size() || text_[pos_] != '"') return false;
    const std::size_t key_offset = pos_;
    const std::string key = read_string();
    skip_space();
    if (pos_ >= text_.size() || text_[pos_] != ':') return false;
    ++pos_;
    Frame& frame = stack_.back();
    if (record_) {
      path = append_key(frame.path, key);
      map_.keys.emplace(path, key_offset);
    }
    const auto [where, inserted] = frame.seen.emplace(key, key_offset);
    if (!inserted && !map_.duplicate) {
      map_.duplicate = DuplicateKey{frame.path, key, key_offset, where->second};
    }
    return true;
  }

  // Decodes the string starting at the opening quote at pos_ and leaves pos_ after the closing one.
  std::string read_string() {
    std::string out;
    ++pos_;
    while (pos_ < text_.size() && text_[pos_] != '"') {
      const char ch = text_[pos_++];
      if (ch != '\\') {
        out += ch;
        continue;
      }
      if (pos_ >= text_.size()) break;
      const char escape = text_[pos_++];
      switch (escape) {
        case 'b': out += '\b'; break;
        case 'f': out += '\f'; break;
        case 'n': out += '\n'; break;
        case 'r': out += '\r'; break;
        case 't': out += '\t'; break;
        case 'u': {
          std::uint32_t code = read_hex4();
          if (code >= 0xD800 && code < 0xDC00 && text_.substr(pos_, 2) == "\\u") {
            pos_ += 2;
            const std::uint32_t low = read_hex4();
            code = 0x10000 + ((code - 0xD800) << 10) + (low - 0xDC00);
          }
          append_utf8(out, code);
          break;
        }
        default: out += escape;  // \" \\ \/
      }
    }
    if (pos_ < text_.size()) ++pos_;  // the closing quote
    return out;
  }

  std::uint32_t read_hex4() {
    std::uint32_t code = 0;
    for (int k = 0; k < 4 && pos_ < text_.size(); ++k, ++pos_) {
      const char ch = text_[pos_];
      std::uint32_t digit = 0;
      if (ch >= '0' && ch <= '9')
        digit = static_cast<std::uint32_t>(ch - '0');
      else if (ch >= 'a' && ch <= 'f')
        digit = static_cast<std::uint32_t>(ch - 'a' + 10);
      else if (ch >= 'A' && ch <= 'F')
        digit = static_cast<std::uint32_t>(ch - 'A' + 10);
      code = code * 16 + digit;
    }
    return code;
  }

  std::string_view text_;
  bool record_ = true;
  std::size_t pos_ = 0;
  std::vector<Frame> stack_;
  TextMap map_;
};

}  // namespace

std::string quote(std::string_view s) {
  constexpr std::size_t kMaxShown = 60;
  std::string shown(s.substr(0, kMaxShown));
  std::string out = Json(shown).dump(-1, ' ', false, Json::error_handler_t::replace);
  if (s.size() > kMaxShown) out.insert(out.size() - 1, "...");
  return out;
}

std::string type_name(const Json& v) {
  switch (v.type()) {
    case Json::value_t::object: return "an object";
    case Json::value_t::array: return "an array";
    case Json::value_t::string: return "a string";
    case Json::value_t::boolean: return "a boolean";
    case Json::value_t::null: return "null";
    case Json::value_t::number_integer:
    case Json::value_t::number_unsigned:
    case Json::value_t::number_float: return "a number";
    default: return "an unsupported value";
  }
}

// Field paths: keys made of [A-Za-z0-9_-] join with dots (materials.wall.reflectivity); any other
// key is written as a quoted subscript (materials["my lamp"].emittance).
bool is_plain_key(std::string_view key) {
  if (key.empty()) return false;
  return std::all_of(key.begin(), key.end(), [](char ch) {
    return (ch >= 'a' && ch <= 'z') || (ch >= 'A' && ch <= 'Z') || (ch >= '0' && ch <= '9') || ch == '_' || ch == '-';
  });
}

std::string append_key(const std::string& path, std::string_view key) {
  if (is_plain_key(key)) return path.empty() ? std::string(key) : path + "." + std::string(key);
  return path + "[" + quote(key) + "]";
}

std::string append_index(const std::string& path, std::size_t index) {
  return path + "[" + std::to_string(index) + "]";
}

std::optional<std::string> closest(std::string_view word, const std::vector<std::string>& candidates) {
  return closest_match(word, candidates);
}

std::string quoted_list(const std::vector<std::string>& names) {
  std::string out;
  for (std::size_t i = 0; i < names.size() && i < kMaxListedNames; ++i) {
    if (i > 0) out += ", ";
    out += quote(names[i]);
  }
  if (names.size() > kMaxListedNames) out += ", ...";
  return out;
}

TextMap scan_positions(std::string_view text, bool record) { return TextScanner(text, record).scan(); }

}  // namespace flatland::scene_json
