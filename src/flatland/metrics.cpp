#include "flatland/metrics.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
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

// The emitted radiosity E at one sample, `channels` values: the reference sample's "E", else the
// result sample's, else zero on a curve that emits nothing (its "emittance" zero or absent in
// both documents). A curve that emits but whose samples carry no "E" (a result written before
// flatland wrote it) is an error: E cannot be rebuilt from the document alone, since an emittance
// profile varies it along the curve.
Result<std::vector<double>> emitted_at(const nlohmann::json& result_sample, const nlohmann::json& reference_sample,
                                       const nlohmann::json& result_curve, const nlohmann::json& reference_curve,
                                       std::size_t channels, const std::string& where) {
  for (const nlohmann::json* sample : {&reference_sample, &result_sample}) {
    if (!sample->contains("E")) continue;
    Result<std::vector<double>> e = channels_of((*sample)["E"], where + ".E");
    if (e && e->size() != channels) return Error{where + ".E: grey against colour B"};
    return e;
  }
  for (const nlohmann::json* curve : {&reference_curve, &result_curve}) {
    if (!curve->contains("emittance")) continue;
    Result<std::vector<double>> e = channels_of((*curve)["emittance"], where + " emittance");
    if (!e) return e.error();
    for (const double value : *e)
      if (value != 0.0)
        return Error{where + ": the curve emits but its samples carry no \"E\" (a result written by an "
                     "older flatland); solve it again, or measure the total B"};
  }
  return std::vector<double>(channels, 0.0);
}

// B - E, with a difference below 1e-12 of |B| counted as zero: E is computed twice (by the solver
// and for the sample's "E", or by the reference at its own point) and may differ in the last bits,
// which would otherwise make a curve that reflects nothing look like one that reflects a little.
double reflected_part(double b, double e) {
  const double d = b - e;
  return std::fabs(d) <= 1e-12 * std::fabs(b) ? 0.0 : d;
}

}  // namespace

const char* to_string(Measure measure) { return measure == Measure::Reflected ? "reflected" : "total"; }

std::optional<double> power_law_exponent(const std::vector<double>& x, const std::vector<double>& error) {
  // Least squares for ln e = ln c + k ln x: k = sum (u - mean u)(v - mean v) / sum (u - mean u)^2
  // with u = ln x, v = ln e; centred sums, so that large x lose no digits.
  std::vector<double> u, v;
  for (std::size_t i = 0; i < std::min(x.size(), error.size()); ++i) {
    if (!(x[i] > 0.0) || !(error[i] > 0.0) || !std::isfinite(x[i]) || !std::isfinite(error[i])) continue;
    u.push_back(std::log(x[i]));
    v.push_back(std::log(error[i]));
  }
  if (u.size() < 2) return std::nullopt;
  const double n = static_cast<double>(u.size());
  double mean_u = 0.0, mean_v = 0.0;
  for (std::size_t i = 0; i < u.size(); ++i) {
    mean_u += u[i] / n;
    mean_v += v[i] / n;
  }
  double suu = 0.0, suv = 0.0;
  for (std::size_t i = 0; i < u.size(); ++i) {
    suu += (u[i] - mean_u) * (u[i] - mean_u);
    suv += (u[i] - mean_u) * (v[i] - mean_v);
  }
  // Distinct x: the spread of ln x is more than round-off of its size.
  if (!(suu > 1e-24 * n * std::max(1.0, mean_u * mean_u))) return std::nullopt;
  return suv / suu;
}

Result<Comparison> compare_results(const nlohmann::json& result, const nlohmann::json& reference, Measure measure) {
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

  // Every (measured value of the result, of the reference, cell length) triple, per curve: B, or
  // B - E under Measure::Reflected; the sums are formed afterwards on values
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
          std::vector<double> emitted(va->size(), 0.0);
          if (measure == Measure::Reflected) {
            Result<std::vector<double>> e = emitted_at(sa[j], sb[j], a, b, va->size(), where + ".samples[" + std::to_string(j) + "]");
            if (!e) return e.error();
            emitted = std::move(*e);
          }
          for (std::size_t ch = 0; ch < va->size(); ++ch) {
            const double mine_value = measure == Measure::Reflected ? reflected_part((*va)[ch], emitted[ch]) : (*va)[ch];
            const double their_value = measure == Measure::Reflected ? reflected_part((*vb)[ch], emitted[ch]) : (*vb)[ch];
            curve.push_back({mine_value, their_value, ds});
            value_scale = std::max({value_scale, std::fabs(mine_value), std::fabs(their_value)});
          }
        }
      }
    }
  } catch (const nlohmann::json::exception& e) {
    return Error{std::string("malformed result: ") + e.what()};
  }
  Comparison comparison;
  comparison.measure = measure;
  Sums scene;
  if (!(value_scale > 0.0)) value_scale = 1.0;
  if (!(length_scale > 0.0)) length_scale = 1.0;
  constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
  for (const auto& [id, curve_terms] : terms) {
    Sums curve;
    for (const Term& t : curve_terms) curve.add(t.b / value_scale, t.r / value_scale, t.ds / length_scale);
    // Under Reflected a curve that reflects nothing in the reference has no relative error.
    if (measure == Measure::Reflected && curve.max_reference == 0.0)
      comparison.curves.push_back({id, {kNaN, kNaN, kNaN}, false});
    else
      comparison.curves.push_back({id, curve.norms(), true});
    scene.add(curve);
  }
  if (measure == Measure::Reflected && scene.max_reference == 0.0)
    return Error{"the reference's reflected part B - E is zero everywhere (no curve reflects light), so its "
                 "relative error is undefined; measure the total B instead"};
  comparison.scene = scene.norms();
  comparison.reference_l2 = value_scale * std::sqrt(scene.square_reference * length_scale);
  return comparison;
}

}  // namespace flatland
