#include "flatland/results/sampled_result.hpp"

#include <algorithm>
#include <limits>
#include <string>

#include "flatland/results/result_io.hpp"

namespace flatland {

namespace {

const char* sides_name(Sides sides) { return sides == Sides::Both ? "both" : sides == Sides::Back ? "back" : "front"; }

const char* continuity_name(Continuity continuity) {
  return continuity == Continuity::C1 ? "C1" : continuity == Continuity::C0 ? "C0" : "C-1";
}

// The number `object[key]` of a result document, or an error naming `place`, the key and what it
// holds instead.
Result<double> number_at(const nlohmann::json& object, const char* key, const std::string& place) {
  if (!object.is_object()) return Error{"malformed result: " + place + " is not an object"};
  const auto it = object.find(key);
  if (it == object.end()) return Error{"malformed result: " + place + " has no \"" + key + "\""};
  if (!it->is_number())
    return Error{"malformed result: " + place + "." + key + ": expected a number, got " + it->dump()};
  return it->get<double>();
}

// A B, B_back, E or emittance value of a document: a number (grey) or [r, g, b].
Result<Spectrum> spectrum_of(const nlohmann::json& value, int channels, const std::string& where) {
  if (channels == 1 && value.is_number()) return Spectrum{value.get<double>(), 0.0, 0.0};
  if (channels == 3 && value.is_array() && value.size() == 3 &&
      std::all_of(value.begin(), value.end(), [](const nlohmann::json& v) { return v.is_number(); }))
    return Spectrum{value[0].get<double>(), value[1].get<double>(), value[2].get<double>()};
  if (value.is_number()) return Error{where + ": a grey value in a colour result (expected [r, g, b])"};
  if (value.is_array() && value.size() == 3)
    return Error{where + ": a colour value in a grey result (expected a number)"};
  return Error{where + ": expected a number or [r, g, b]"};
}

// The document's channels: those of its first B that is a number or an array (1 when it has
// none); a B that is neither is reported where it stands, not blamed on a value read before it.
int channels_of_document(const nlohmann::json& curves) {
  for (const nlohmann::json& curve : curves) {
    if (!curve.is_object() || !curve.contains("samples") || !curve["samples"].is_array()) continue;
    for (const nlohmann::json& sample : curve["samples"]) {
      if (!sample.is_object() || !sample.contains("B")) continue;
      if (sample["B"].is_array()) return 3;
      if (sample["B"].is_number()) return 1;
    }
  }
  return 1;
}

}  // namespace

nlohmann::json spectrum_to_json(const Spectrum& value, int channels) {
  if (channels == 1) return value[0];
  return nlohmann::json::array({value[0], value[1], value[2]});
}

SampledResult sample_radiosity(const Scene& scene, int samples_per_curve, const RadiosityFunction& radiosity) {
  SampledResult result;
  result.channels = scene.channels;
  result.scene_sha256 = scene.content_sha256;
  for (std::uint32_t c = 0; c < scene.curves.size(); ++c) {
    const Curve& curve = scene.curves[c];
    const Side main_side = curve.sides == Sides::Back ? Side::Back : Side::Front;
    const bool emits = scene.is_emitter(curve);
    ResultCurve& out = result.curves.emplace_back();
    out.id = curve.id;
    out.length = curve.length;
    out.sides = curve.sides;
    out.segments = static_cast<int>(curve.segment_count);
    out.emittance = curve.emittance;
    out.samples.reserve(static_cast<std::size_t>(samples_per_curve));
    for (int j = 0; j < samples_per_curve; ++j) {
      ResultSample& sample = out.samples.emplace_back();
      sample.s = (j + 0.5) * curve.length / samples_per_curve;
      const CurvePoint point = point_at_arc_length(scene, curve, sample.s);
      sample.x = point.position.x;
      sample.y = point.position.y;
      sample.B = radiosity(c, main_side, point.u);
      if (curve.sides == Sides::Both) sample.B_back = radiosity(c, Side::Back, point.u);
      // The emitted part of B (and of B_back: both sides of a two-sided emitter emit alike), so
      // that a comparison can measure the reflected part B - E from a document alone.
      if (emits) {
        const double factor = emittance_factor(curve, point.u);
        sample.E = Spectrum{curve.emittance[0] * factor, curve.emittance[1] * factor, curve.emittance[2] * factor};
      }
    }
  }
  return result;
}

SampledResult sample_solver(const Solver& solver, int samples_per_curve, const ErrorEstimate* estimate) {
  const Scene& scene = solver.scene();
  SampledResult result = sample_radiosity(scene, samples_per_curve, [&solver](std::uint32_t c, Side side, double u) {
    return solver.radiosity(c, side, u);
  });
  for (std::uint32_t c = 0; c < scene.curves.size(); ++c) {
    const Curve& curve = scene.curves[c];
    const CurveStorage& storage = solver.storage(c);
    StoredSpline spline;
    spline.degree = storage.basis.degree();
    spline.elements = solver.storage_elements(c);
    spline.periodic = storage.basis.is_periodic();
    if (curve.closed) spline.closing = storage.closing;
    spline.knots = storage.basis.knots();
    spline.continuity = storage.nodes;
    spline.coefficients = solver.radiosity_coefficients(c, curve.sides == Sides::Back ? Side::Back : Side::Front);
    if (curve.sides == Sides::Both) spline.coefficients_back = solver.radiosity_coefficients(c, Side::Back);
    result.curves[c].spline = std::move(spline);
  }
  ResultStats stats;
  stats.photons = solver.photons_shot();
  stats.rounds = solver.rounds();
  stats.rays = solver.rays_traced();
  stats.seconds = solver.seconds();
  stats.stop_reason = solver.stop_reason();
  stats.books = solver.books();
  stats.specular = scene.has_specular();
  stats.chains_cut = solver.chains_cut();
  stats.estimated_error =
      estimate != nullptr ? *estimate : estimate_error(solver, {solver.settings().confidence, samples_per_curve});
  result.stats = stats;
  return result;
}

nlohmann::json curve_to_json(const ResultCurve& curve, int channels) {
  nlohmann::json samples = nlohmann::json::array();
  for (const ResultSample& sample : curve.samples) {
    nlohmann::json entry = {
        {"s", sample.s}, {"x", sample.x}, {"y", sample.y}, {"B", spectrum_to_json(sample.B, channels)}};
    if (sample.B_back) entry["B_back"] = spectrum_to_json(*sample.B_back, channels);
    if (sample.E) entry["E"] = spectrum_to_json(*sample.E, channels);
    samples.push_back(std::move(entry));
  }
  nlohmann::json entry = {{"id", curve.id},
                          {"length", curve.length},
                          {"sides", sides_name(curve.sides)},
                          {"segments", curve.segments},
                          {"samples", std::move(samples)}};
  if (curve.emittance) entry["emittance"] = spectrum_to_json(*curve.emittance, channels);
  // The stored spline, so a result can be re-plotted exactly: B(u) = E + sum_k b_k phi_k(u)
  // with phi_k the B-splines of `degree` on `knots`, u = segment index + t.
  if (const std::optional<StoredSpline>& spline = curve.spline) {
    entry["degree"] = spline->degree;
    // The mesh in use: with auto storage the chosen level, held exactly by the finest basis whose
    // knots and coefficients follow (docs/result-format.md).
    entry["elements"] = spline->elements;
    // A periodic basis (a closed curve smooth at its closing point) lists one period of knots
    // extended by `degree` on each side; its functions wrap round (docs/result-format.md).
    entry["periodic"] = spline->periodic;
    if (spline->closing) entry["closing"] = continuity_name(*spline->closing);
    entry["knots"] = spline->knots;
    nlohmann::json nodes = nlohmann::json::array();
    for (const MeshNode& node : spline->continuity)
      nodes.push_back({{"u", node.u}, {"continuity", continuity_name(node.continuity)}});
    entry["continuity"] = std::move(nodes);
    if (!spline->coefficients.empty()) entry["coefficients"] = spline->coefficients;
    if (curve.sides == Sides::Both) entry["coefficients_back"] = spline->coefficients_back;
  }
  return entry;
}

std::size_t curve_json_numbers(const ResultCurve& curve, int channels) {
  const std::size_t per_sample = 3 + static_cast<std::size_t>(channels) * 3;  // s, x, y, B, B_back, E
  std::size_t count = 8 + curve.samples.size() * per_sample;
  if (curve.spline)
    count += curve.spline->knots.size() + curve.spline->coefficients.size() + curve.spline->coefficients_back.size() +
             2 * curve.spline->continuity.size();
  return count;
}

nlohmann::json curves_to_json(const SampledResult& result) {
  nlohmann::json curves = nlohmann::json::array();
  for (const ResultCurve& curve : result.curves) curves.push_back(curve_to_json(curve, result.channels));
  return curves;
}

Status check_reference_of(const SampledResult& reference, const Scene& scene, int samples) {
  if (!reference.scene_sha256.empty() && !scene.content_sha256.empty() &&
      reference.scene_sha256 != scene.content_sha256)
    return Error{"the reference was made from another scene than " + scene.source + " (content SHA-256 " +
                 reference.scene_sha256.substr(0, 12) + "... against " + scene.content_sha256.substr(0, 12) +
                 "...); solve the reference from the same scene file"};
  bool same = reference.curves.size() == scene.curves.size();
  for (std::size_t c = 0; same && c < scene.curves.size(); ++c) same = reference.curves[c].id == scene.curves[c].id;
  if (!same)
    return Error{"the reference describes another scene than " + scene.source +
                 " (its curves differ); solve the reference from the same scene file"};
  if (samples > 0 && !reference.curves.empty() &&
      reference.curves[0].samples.size() != static_cast<std::size_t>(samples))
    return Error{"the reference has " + std::to_string(reference.curves[0].samples.size()) +
                 " samples per curve, the runs " + std::to_string(samples)};
  return ok_status();
}

Result<SampledResult> sampled_from_json(const nlohmann::json& document, const std::string& what,
                                        const std::string& suffix) {
  if (!document.is_object() || !document.contains("flatland_result") || !document.contains("curves") ||
      !document["curves"].is_array())
    return Error{what + " is not a flatland result (no \"flatland_result\" and \"curves\")"};
  const nlohmann::json& curves = document["curves"];
  SampledResult result;
  result.channels = channels_of_document(curves);
  if (const auto scene = document.find("scene"); scene != document.end() && scene->is_object())
    if (const auto sha = scene->find("content_sha256"); sha != scene->end() && sha->is_string())
      result.scene_sha256 = sha->get<std::string>();
  try {
    for (std::size_t c = 0; c < curves.size(); ++c) {
      const nlohmann::json& in = curves[c];
      if (!in.is_object()) return Error{"malformed result: curves[" + std::to_string(c) + "] is not an object"};
      ResultCurve& curve = result.curves.emplace_back();
      const auto id = in.find("id");
      curve.id = id != in.end() && id->is_string() ? id->get<std::string>() : std::string();
      const std::string where = "curves[" + std::to_string(c) + "] (\"" + curve.id + "\")";
      Result<double> length = number_at(in, "length", where);
      if (!length) return length.error();
      curve.length = *length;
      const auto sides_entry = in.find("sides");
      const std::string sides =
          sides_entry != in.end() && sides_entry->is_string() ? sides_entry->get<std::string>() : "front";
      curve.sides = sides == "both" ? Sides::Both : sides == "back" ? Sides::Back : Sides::Front;
      // (A whole number that fits: a JSON number such as 1e100 would not convert to an int.)
      const nlohmann::json segments = in.value("segments", nlohmann::json(0));
      if (!segments.is_number_integer() || segments.get<std::int64_t>() < 0 ||
          segments.get<std::int64_t>() > std::numeric_limits<int>::max())
        return Error{"malformed result: " + where + ".segments: expected a whole number, got " + segments.dump()};
      curve.segments = static_cast<int>(segments.get<std::int64_t>());
      if (in.contains("emittance")) {
        Result<Spectrum> e = spectrum_of(in["emittance"], result.channels, where + " emittance");
        if (!e) return e.error();
        curve.emittance = *e;
      }
      const auto samples_entry = in.find("samples");
      if (samples_entry == in.end()) return Error{"malformed result: " + where + " has no \"samples\""};
      const nlohmann::json& samples = *samples_entry;
      if (!samples.is_array()) return Error{"malformed result: " + where + ".samples is not an array"};
      for (std::size_t j = 0; j < samples.size(); ++j) {
        const nlohmann::json& s = samples[j];
        const std::string place = where + ".samples[" + std::to_string(j) + "]";
        ResultSample& sample = curve.samples.emplace_back();
        Result<double> at = number_at(s, "s", place);
        if (!at) return at.error();
        sample.s = *at;
        for (const auto& [key, value] : {std::pair{"x", &sample.x}, std::pair{"y", &sample.y}}) {
          if (!s.contains(key)) continue;
          Result<double> coordinate = number_at(s, key, place);
          if (!coordinate) return coordinate.error();
          *value = *coordinate;
        }
        if (!s.contains("B")) return Error{"malformed result: " + place + " has no \"B\"" + suffix};
        Result<Spectrum> b = spectrum_of(s["B"], result.channels, place + ".B" + suffix);
        if (!b) return b.error();
        sample.B = *b;
        if (s.contains("B_back")) {
          Result<Spectrum> back = spectrum_of(s["B_back"], result.channels, place + ".B_back" + suffix);
          if (!back) return back.error();
          sample.B_back = *back;
        }
        if (s.contains("E")) {
          Result<Spectrum> e = spectrum_of(s["E"], result.channels, place + ".E");
          if (!e) return e.error();
          sample.E = *e;
        }
      }
    }
  } catch (const nlohmann::json::exception& e) {
    return Error{std::string("malformed result: ") + e.what()};
  }
  return result;
}

}  // namespace flatland
