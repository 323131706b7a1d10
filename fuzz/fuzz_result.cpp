// libFuzzer target: the result reader and the comparison of results (what `flatland compare` and
// `solve --reference` do with a file they are given).
//
// The bytes are a result file. When parse_result accepts them, the document is compared with
// itself, and, when it has curves, with a second copy in which one number of the curves (chosen
// by a hash of the input: a length, an arc length s, a B value, ...) is changed, in both orders,
// so the mismatch messages and the norms of a real difference are reached as well.
//
// Rejected input is fine (both functions return errors); a crash, a sanitizer report, an
// exception escaping, an assertion or a hang is a bug. docs/fuzzing.md says how to run it.
#include <cstddef>
#include <cstdint>
#include <string_view>
#include <vector>

#include <nlohmann/json.hpp>

#include "flatland/results/metrics.hpp"
#include "flatland/results/result_io.hpp"

namespace {

// The numbers under `root`, depth first, without recursion (a fuzzed document can nest thousands
// of levels deep, and this harness must not be the one that runs out of stack). At most `limit`.
std::vector<nlohmann::json*> numbers_in(nlohmann::json& root, std::size_t limit) {
  std::vector<nlohmann::json*> numbers;
  std::vector<nlohmann::json*> pending{&root};
  while (!pending.empty() && numbers.size() < limit) {
    nlohmann::json* value = pending.back();
    pending.pop_back();
    if (value->is_number())
      numbers.push_back(value);
    else if (value->is_structured())
      for (nlohmann::json& child : *value) pending.push_back(&child);
  }
  return numbers;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  flatland::Result<nlohmann::json> document = flatland::parse_result(text, "fuzz.json");
  if (!document) return 0;
  (void)flatland::compare_results(*document, *document);

  if (!document->contains("curves")) return 0;
  // The second copy is parsed again rather than copied: copying a json value recurses once per
  // level of nesting, parsing does not.
  flatland::Result<nlohmann::json> changed = flatland::parse_result(text, "fuzz.json");
  if (!changed) __builtin_trap();  // the same text parsed twice must give the same answer
  const std::vector<nlohmann::json*> numbers = numbers_in((*changed)["curves"], 4096);
  if (numbers.empty()) return 0;
  std::uint64_t hash = 1469598103934665603ull;  // FNV-1a: which number, reproducibly per input
  for (const char byte : text) hash = (hash ^ static_cast<unsigned char>(byte)) * 1099511628211ull;
  nlohmann::json& number = *numbers[hash % numbers.size()];
  // Twice plus one moves every finite value, zero included; some doubles become infinite, which
  // compare_results must handle like any other number it is given.
  number = 2.0 * number.get<double>() + 1.0;
  (void)flatland::compare_results(*changed, *document);
  (void)flatland::compare_results(*document, *changed);
  // The reflected part B - E, read from the samples' "E": the same documents.
  (void)flatland::compare_results(*changed, *document, flatland::Measure::Reflected);
  (void)flatland::compare_results(*document, *changed, flatland::Measure::Reflected);
  return 0;
}
