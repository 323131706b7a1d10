#include "flatland/metrics.hpp"

#include <algorithm>
#include <cmath>
#include <string>
#include <utility>
#include <vector>

namespace flatland {

namespace {

// Running sums of one norm computation.
struct Sums {
  double abs_error = 0.0, abs_reference = 0.0;
  double square_error = 0.0, square_reference = 0.0;
  double max_error = 0.0, max_reference = 0.0;

  void add(double b, double r, double ds) {
    const double e = std::fabs(b - r);
    abs_error += e * ds;
    abs_reference += std::fabs(r) * ds;
    square_error += e * e * ds;
    square_reference += r * r * ds;
    max_error = std::max(max_error, e);
    max_reference = std::max(max_reference, std::fabs(r));
  }
  void add(const Sums& o) {
    abs_error += o.abs_error;
    abs_reference += o.abs_reference;
    square_error += o.square_error;
    square_reference += o.square_reference;
    max_error = std::max(max_error, o.max_error);
    max_reference = std::max(max_reference, o.max_reference);
  }
  // A reference that is zero everywhere gives errors relative to the largest |B| of the
  // comparison (the unit the sums are formed in) rather than a division by zero.
  ErrorNorms norms() const {
    auto ratio = [](double a, double b) { return b > 0.0 ? a / b : a; };
    return {ratio(abs_error, abs_reference), std::sqrt(ratio(square_error, square_reference)),
            ratio(max_error, max_reference)};
  }
};

bool is_number(const nlohmann::json& v) { return v.is_number(); }

// The channels of a B value: a number, or [r, g, b].
Result<std::vector<double>> channels_of(const nlohmann::json& v, const std::string& where) {
  if (is_number(v)) return std::vector<double>{v.get<double>()};
  if (v.is_array() && v.size() == 3 && std::all_of(v.begin(), v.end(), is_number))
    return std::vector<double>{v[0].get<double>(), v[1].get<double>(), v[2].get<double>()};
  return Error{where + ": expected a number or [r, g, b]"};
}

}  // namespace

Result<Comparison> compare_results(const nlohmann::json& result, const nlohmann::json& reference) {
  const auto curves_of = [](const nlohmann::json& doc) -> const nlohmann::json* {
    if (!doc.is_object() || !doc.contains("flatland_result") || !doc.contains("curves") ||
        !doc["curves"].is_array())
      return nullptr;
    return &doc["curves"];
  };
  const nlohmann::json* mine = curves_of(result);
  const nlohmann::json* theirs = curves_of(reference);
  if (mine == nullptr) return Error{"the result is not a flatland result (no \"flatland_result\" and \"curves\")"};
  if (theirs == nullptr) return Error{"the reference is not a flatland result (no \"flatland_result\" and \"curves\")"};
  if (mine->size() != theirs->size())
    return Error{"the results do not describe the same scene: " + std::to_string(mine->size()) +
                 " curves against " + std::to_string(theirs->size())};

  // Every (B, reference, cell length) triple, per curve; the sums are formed afterwards on values
  // divided by the largest |B| and cell lengths divided by the longest cell (the norms are ratios,
  // so they do not change), which keeps squares of B up to 1e308 finite.
  struct Term {
    double b, r, ds;
  };
  std::vector<std::pair<std::string, std::vector<Term>>> terms;
  double value_scale = 0.0;
  double length_scale = 0.0;
  try {
    for (std::size_t c = 0; c < mine->size(); ++c) {
      const nlohmann::json& a = (*mine)[c];
      const nlohmann::json& b = (*theirs)[c];
      const std::string id = a.value("id", "");
      const std::string where = "curves[" + std::to_string(c) + "] (\"" + id + "\")";
      if (id != b.value("id", ""))
        return Error{"the results do not describe the same scene: " + where + " is \"" +
                     b.value("id", "") + "\" in the reference"};
      const double length = a.at("length").get<double>();
      if (std::fabs(length - b.at("length").get<double>()) > 1e-9 * std::max(length, 1e-300))
        return Error{"the results do not describe the same scene: " + where + " has another length in the reference"};
      const nlohmann::json& sa = a.at("samples");
      const nlohmann::json& sb = b.at("samples");
      if (sa.size() != sb.size() || sa.empty())
        return Error{where + ": " + std::to_string(sa.size()) + " samples against " +
                     std::to_string(sb.size()) + " in the reference; solve both with the same --samples"};
      const double ds = length / static_cast<double>(sa.size());
      length_scale = std::max(length_scale, ds);
      std::vector<Term>& curve = terms.emplace_back(id, std::vector<Term>{}).second;
      for (std::size_t j = 0; j < sa.size(); ++j) {
        const double s = sa[j].at("s").get<double>();
        if (std::fabs(s - sb[j].at("s").get<double>()) > 1e-9 * length)
          return Error{where + ": sample " + std::to_string(j) + " sits elsewhere in the reference"};
        for (const char* key : {"B", "B_back"}) {
          if (!sa[j].contains(key) || !sb[j].contains(key)) continue;
          Result<std::vector<double>> va = channels_of(sa[j][key], where + ".samples[" + std::to_string(j) + "]." + key);
          Result<std::vector<double>> vb = channels_of(sb[j][key], where + ".samples[" + std::to_string(j) + "]." + key + " (reference)");
          if (!va) return va.error();
          if (!vb) return vb.error();
          if (va->size() != vb->size())
            return Error{"the results do not describe the same scene: grey against colour at " + where};
          for (std::size_t ch = 0; ch < va->size(); ++ch) {
            curve.push_back({(*va)[ch], (*vb)[ch], ds});
            value_scale = std::max({value_scale, std::fabs((*va)[ch]), std::fabs((*vb)[ch])});
          }
        }
      }
    }
  } catch (const nlohmann::json::exception& e) {
    return Error{std::string("malformed result: ") + e.what()};
  }
  Comparison comparison;
  Sums scene;
  if (!(value_scale > 0.0)) value_scale = 1.0;
  if (!(length_scale > 0.0)) length_scale = 1.0;
  for (const auto& [id, curve_terms] : terms) {
    Sums curve;
    for (const Term& t : curve_terms) curve.add(t.b / value_scale, t.r / value_scale, t.ds / length_scale);
    comparison.curves.push_back({id, curve.norms()});
    scene.add(curve);
  }
  comparison.scene = scene.norms();
  return comparison;
}

}  // namespace flatland
