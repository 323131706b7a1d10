#include "flatland/results/metrics.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include "flatland/results/sampled_result.hpp"

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

// The emitted radiosity E at one sample: the reference sample's "E", else the result sample's,
// else zero on a curve that emits nothing (its "emittance" zero or absent in both documents). A
// curve that emits but whose samples carry no "E" (a result written before flatland wrote it) is
// an error: E cannot be rebuilt from the document alone, since an emittance profile varies it
// along the curve.
Result<Spectrum> emitted_at(const ResultSample& result_sample, const ResultSample& reference_sample,
                            const ResultCurve& result_curve, const ResultCurve& reference_curve,
                            const std::string& where) {
  if (reference_sample.E) return *reference_sample.E;
  if (result_sample.E) return *result_sample.E;
  for (const ResultCurve* curve : {&reference_curve, &result_curve}) {
    if (!curve->emittance) continue;
    for (const double value : *curve->emittance)
      if (value != 0.0)
        return Error{where +
                     ": the curve emits but its samples carry no \"E\" (a result written by an "
                     "older flatland); solve it again, or measure the total B"};
  }
  return Spectrum{};
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
  Result<SampledResult> mine = sampled_from_json(result, "the result");
  if (!mine) return mine.error();
  Result<SampledResult> theirs = sampled_from_json(reference, "the reference", " (reference)");
  if (!theirs) return theirs.error();
  return compare_sampled(*mine, *theirs, measure);
}

Result<Comparison> compare_sampled(const SampledResult& result, const SampledResult& reference, Measure measure) {
  if (!result.scene_sha256.empty() && !reference.scene_sha256.empty() && result.scene_sha256 != reference.scene_sha256)
    return Error{"the results were made from different scenes (content SHA-256 " + result.scene_sha256.substr(0, 12) +
                 "... and " + reference.scene_sha256.substr(0, 12) +
                 "... in the reference); compare results of the same scene file"};
  if (result.curves.size() != reference.curves.size())
    return Error{"the results do not describe the same scene: " + std::to_string(result.curves.size()) +
                 " curves against " + std::to_string(reference.curves.size())};
  const auto channels = static_cast<std::size_t>(result.channels);

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
  for (std::size_t c = 0; c < result.curves.size(); ++c) {
    const ResultCurve& a = result.curves[c];
    const ResultCurve& b = reference.curves[c];
    const std::string where = "curves[" + std::to_string(c) + "] (\"" + a.id + "\")";
    if (a.id != b.id)
      return Error{"the results do not describe the same scene: " + where + " is \"" + b.id + "\" in the reference"};
    const double length = a.length;
    if (std::fabs(length - b.length) > 1e-9 * std::max(length, 1e-300))
      return Error{"the results do not describe the same scene: " + where + " has another length in the reference"};
    if (a.samples.size() != b.samples.size() || a.samples.empty())
      return Error{where + ": " + std::to_string(a.samples.size()) + " samples against " +
                   std::to_string(b.samples.size()) + " in the reference; solve both with the same --samples"};
    if (result.channels != reference.channels)
      return Error{"the results do not describe the same scene: grey against colour at " + where};
    const double ds = length / static_cast<double>(a.samples.size());
    length_scale = std::max(length_scale, ds);
    std::vector<Term>& curve = terms.emplace_back(a.id, std::vector<Term>{}).second;
    for (std::size_t j = 0; j < a.samples.size(); ++j) {
      const ResultSample& sa = a.samples[j];
      const ResultSample& sb = b.samples[j];
      if (std::fabs(sa.s - sb.s) > 1e-9 * length)
        return Error{where + ": sample " + std::to_string(j) + " sits elsewhere in the reference"};
      Spectrum emitted{};
      if (measure == Measure::Reflected) {
        Result<Spectrum> e = emitted_at(sa, sb, a, b, where + ".samples[" + std::to_string(j) + "]");
        if (!e) return e.error();
        emitted = *e;
      }
      // B on both, and B_back where both have it.
      const Spectrum* pairs[2][2] = {{&sa.B, &sb.B},
                                     {sa.B_back ? &*sa.B_back : nullptr, sb.B_back ? &*sb.B_back : nullptr}};
      for (const auto& pair : pairs) {
        if (pair[0] == nullptr || pair[1] == nullptr) continue;
        for (std::size_t ch = 0; ch < channels; ++ch) {
          const double mine_value =
              measure == Measure::Reflected ? reflected_part((*pair[0])[ch], emitted[ch]) : (*pair[0])[ch];
          const double their_value =
              measure == Measure::Reflected ? reflected_part((*pair[1])[ch], emitted[ch]) : (*pair[1])[ch];
          curve.push_back({mine_value, their_value, ds});
          value_scale = std::max({value_scale, std::fabs(mine_value), std::fabs(their_value)});
        }
      }
    }
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
  if (measure == Measure::Reflected && scene.max_reference == 0.0) return Error{kNothingReflected};
  comparison.scene = scene.norms();
  comparison.reference_l2 = value_scale * std::sqrt(scene.square_reference * length_scale);
  return comparison;
}

}  // namespace flatland
