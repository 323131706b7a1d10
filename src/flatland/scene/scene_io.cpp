// Reading scene files (format version 1, docs/scene-format.md).
//
// Two passes over the text. nlohmann::json parses it (syntax errors carry a byte offset, which we
// turn into line:column). A small scanner then walks the same text and records where every value
// and every object key starts, by field path ("curves[2].bezier[3]"), and notices what nlohmann
// silently accepts or reports without a position: duplicate keys and numbers that overflow. The
// validation works on the parsed value and asks the scanner's map where a field is, so every error
// reads "SOURCE:LINE:COLUMN: FIELD.PATH: what is wrong; what to do".
//
// Nothing here throws out of parse_scene / load_scene: validation failures are thrown internally as
// ParseFailure and caught at the top, as is anything else (allocation failure, a library exception).
#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <initializer_list>
#include <limits>
#include <numbers>
#include <optional>
#include <string>
#include <string_view>
#include <system_error>
#include <unordered_map>
#include <vector>

#include <nlohmann/json.hpp>

#include "flatland/base/files.hpp"
#include "flatland/base/sha256.hpp"
#include "flatland/base/text.hpp"
#include "flatland/scene/json_text.hpp"
#include "flatland/scene/scene.hpp"

namespace flatland {
namespace {

using namespace scene_json;

// ---------------------------------------------------------------------------------------------
// Validation

struct ParseFailure {
  std::string message;
};

enum class Quantity { Reflectivity, Emittance, Reflectance, Absorption };

// Detector bins over all detector curves (docs/scene-format.md, limits).
constexpr std::size_t kMaxDetectorBins = 65536;

// Emittance values and profile factors (docs/scene-format.md, limits).
constexpr double kMaxEmittance = 1e100;
constexpr double kMinEmittance = 1e-100;

class SceneReader {
 public:
  SceneReader(std::string_view text, std::string_view source) : text_(text), source_(source) {}

  Scene read() {
    Json root;
    try {
      root = Json::parse(text_.begin(), text_.end());
    } catch (const Json::parse_error& e) {
      throw ParseFailure{at_offset(e.byte > 0 ? e.byte - 1 : 0) + "parse error: " + strip_library_prefix(e.what())};
    } catch (const Json::out_of_range&) {
      // nlohmann refuses numbers beyond double's range (id 406) without a position: find it.
      map_ = scan_positions(text_, true);
      if (map_->overflow) {
        fail(map_->overflow->path, "the number " + map_->overflow->token +
                                       " is too large for a double (it overflows to infinity); "
                                       "use a finite value");
      }
      throw ParseFailure{source_ + ": a number is too large for a double; use finite values"};
    }
    {
      const TextMap check = scan_positions(text_, false);
      if (check.too_deep || check.duplicate) map_ = scan_positions(text_, true);
    }
    if (map_ && map_->too_deep) {
      throw ParseFailure{at_offset(*map_->too_deep) + "values nested more than " + std::to_string(kMaxDepth) +
                         " deep; a scene file needs four levels"};
    }
    if (map_ && map_->duplicate) {
      const DuplicateKey& d = *map_->duplicate;
      const TextPosition first = position_of(text_, d.first_offset);
      throw ParseFailure{at_offset(d.offset) + (d.object_path.empty() ? "" : d.object_path + ": ") + "duplicate key " +
                         quote(d.key) + " (first at line " + std::to_string(first.line) + ", column " +
                         std::to_string(first.column) + "); each key may appear once in an object, remove one of them"};
    }
    Scene scene = read_scene(root);
    scene.content_sha256 = sha256_hex(nlohmann::json(root).dump());
    return scene;
  }

  // Turns an error of finalize_scene ("FIELD: what") into a located message.
  std::string locate(const std::string& message) const {
    const std::size_t colon = message.find(": ");
    if (colon == std::string::npos) return source_ + ": " + message;
    const std::string field = message.substr(0, colon);
    return prefix(field, false) + message;
  }

 private:
  // ---- messages

  std::string at_offset(std::size_t offset) const {
    const TextPosition p = position_of(text_, offset);
    return source_ + ":" + std::to_string(p.line) + ":" + std::to_string(p.column) + ": ";
  }

  // "SOURCE:LINE:COLUMN: " for the value (or with at_key, the key) at path; "SOURCE: " if unknown.
  // Positions are recorded on the first message that needs one.
  std::string prefix(const std::string& path, bool at_key) const {
    if (!map_) map_ = scan_positions(text_, true);
    if (at_key) {
      if (const auto it = map_->keys.find(path); it != map_->keys.end()) return at_offset(it->second);
    }
    if (const auto it = map_->values.find(path); it != map_->values.end()) return at_offset(it->second);
    return source_ + ": ";
  }

  [[noreturn]] void fail(const std::string& path, const std::string& what) const {
    throw ParseFailure{prefix(path, false) + (path.empty() ? "" : path + ": ") + what};
  }

  static std::string strip_library_prefix(const std::string& what) {
    // "[json.exception.parse_error.101] parse error at line 2, column 10: syntax error ..."
    const std::size_t bracket = what.find("] ");
    const std::size_t colon = what.find(": ", bracket == std::string::npos ? 0 : bracket);
    if (bracket == std::string::npos || colon == std::string::npos) return what;
    return what.substr(colon + 2);
  }

  // ---- generic checks

  void check_keys(const Json& object, const std::string& path, std::initializer_list<std::string_view> allowed) const {
    const std::vector<std::string> names(allowed.begin(), allowed.end());
    for (const auto& item : object.items()) {
      const std::string& key = item.key();
      if (std::find(names.begin(), names.end(), key) != names.end()) continue;
      std::string what = "unknown key " + quote(key);
      if (const auto hint = closest(key, names)) {
        what += "; did you mean " + quote(*hint) + "?";
      } else {
        what += "; the keys here are " + quoted_list(names);
      }
      const std::string where = path.empty() ? "" : path + ": ";
      throw ParseFailure{prefix(append_key(path, key), true) + where + what};
    }
  }

  const Json& require(const Json& object, const std::string& path, const char* key,
                      const std::string& what_to_do) const {
    const auto it = object.find(key);
    if (it == object.end()) {
      fail(path, std::string("missing ") + quote(key) + "; " + what_to_do);
    }
    return *it;
  }

  double number(const Json& v, const std::string& path) const {
    if (!v.is_number()) fail(path, "expected a number, got " + type_name(v));
    const double x = v.get<double>();
    if (!std::isfinite(x)) fail(path, "the number must be finite");
    return x;
  }

  // "diffuse", {"lobe": n} or {"beam": half-angle in degrees}.
  Emission emission(const Json& v, const std::string& path) const {
    constexpr const char* kForms =
        "use \"diffuse\", {\"lobe\": n} (cos^n, n >= 0) or {\"beam\": half-angle in degrees}";
    Emission result;
    if (v.is_string()) {
      if (v.get<std::string>() != "diffuse") fail(path, std::string("unknown emission; ") + kForms);
      return result;
    }
    if (!v.is_object() || v.size() != 1) fail(path, std::string("expected one emission form; ") + kForms);
    check_keys(v, path, {"lobe", "beam"});
    if (const auto it = v.find("lobe"); it != v.end()) {
      const double n = number(*it, append_key(path, "lobe"));
      if (n < 0.0 || n > 1000.0)
        fail(append_key(path, "lobe"), "the exponent must be in [0, 1000], got " + format_number(n));
      result.kind = Emission::Kind::Lobe;
      result.exponent = n;
    } else {
      const double degrees = number(v.at("beam"), append_key(path, "beam"));
      if (!(degrees > 0.0 && degrees <= 90.0))
        fail(append_key(path, "beam"), "the half-angle must be in (0, 90] degrees, got " + format_number(degrees));
      result.kind = Emission::Kind::Beam;
      result.half_angle = degrees * std::numbers::pi / 180.0;
    }
    return result;
  }

  std::string text_value(const Json& v, const std::string& path, const char* what) const {
    if (!v.is_string()) fail(path, std::string("expected ") + what + " (a string), got " + type_name(v));
    return v.get<std::string>();
  }

  // A grey number or [r, g, b]; sets `colour` for the array form.
  Spectrum spectrum(const Json& v, const std::string& path, Quantity quantity, bool& colour) const {
    Spectrum s{};
    if (v.is_number()) {
      const double x = number(v, path);
      check_range(x, path, quantity);
      s = {x, x, x};
      return s;
    }
    if (!v.is_array()) {
      fail(path, "expected a number (grey) or [r, g, b] (colour), got " + type_name(v));
    }
    if (v.size() != 3) {
      fail(path, "expected a number (grey) or [r, g, b] (colour), got an array of " + std::to_string(v.size()) +
                     (v.size() == 1 ? " element" : " elements"));
    }
    for (std::size_t k = 0; k < 3; ++k) {
      const std::string element = append_index(path, k);
      s[k] = number(v[k], element);
      check_range(s[k], element, quantity);
    }
    colour = true;
    return s;
  }

  void check_range(double x, const std::string& path, Quantity quantity) const {
    if (quantity == Quantity::Reflectance) {
      if (!(x >= 0.0 && x <= 1.0)) fail(path, "must be in [0, 1] (the fraction reflected), got " + format_number(x));
    } else if (quantity == Quantity::Absorption) {
      if (!(x >= 0.0 && x <= kMaxEmittance))
        fail(path, "must be between 0 and 1e100 (attenuation per unit length inside), got " + format_number(x) +
                       "; use 0 for clear glass");
    } else if (quantity == Quantity::Reflectivity) {
      if (x < 0.0) fail(path, "must be in [0, 1), got " + format_number(x) + "; use 0 for black");
      if (x >= 1.0) {
        fail(path, "must be below 1: a surface that reflects everything never converges (got " + format_number(x) +
                       "); use at most 0.99");
      }
    } else if (x < 0.0) {
      fail(path, "must be >= 0 (power per unit length), got " + format_number(x) +
                     "; use 0 for a surface that does not emit");
    } else if (x > kMaxEmittance || (x > 0.0 && x < kMinEmittance)) {
      // Emitted power E x length must stay far inside a double's range (and its fixed-point
      // units representable) for every scene size the format allows.
      fail(path, "must be 0 or between 1e-100 and 1e100 (power per unit length), got " + format_number(x) +
                     "; choose the unit of power so that it is");
    }
  }

  // A point of a curve; its path is spelled out only for a message (most of a large scene's
  // values are points).
  Vec2 point(const Json& v, const std::string& points_path, std::size_t k) const {
    if (v.is_array() && v.size() == 2 && v[0].is_number() && v[1].is_number()) {
      const Vec2 p{v[0].get<double>(), v[1].get<double>()};
      if (std::isfinite(p.x) && std::isfinite(p.y)) return p;
    }
    return point(v, append_index(points_path, k));
  }

  Vec2 point(const Json& v, const std::string& path) const {
    if (!v.is_array()) fail(path, "expected a point [x, y], got " + type_name(v));
    if (v.size() != 2) {
      fail(path, "expected a point [x, y], got an array of " + std::to_string(v.size()) +
                     (v.size() == 1 ? " element" : " elements"));
    }
    return Vec2{number(v[0], append_index(path, 0)), number(v[1], append_index(path, 1))};
  }

  // ---- the scene

  Scene read_scene(const Json& root) {
    if (!root.is_object()) {
      fail("", "a scene file must be a JSON object {\"flatland\": 2, ...}, got " + type_name(root));
    }
    const int version = read_version(root);
    version_ = version;
    check_keys(root, "", {"flatland", "name", "description", "materials", "curves"});

    Scene scene;
    scene.source = source_;
    scene.format_version = version;
    if (const auto it = root.find("name"); it != root.end()) {
      scene.name = text_value(*it, "name", "the scene's name");
    } else {
      scene.name = std::filesystem::path(source_).stem().string();
      if (scene.name.empty()) scene.name = "scene";
    }
    if (const auto it = root.find("description"); it != root.end()) {
      scene.description = text_value(*it, "description", "a description");
    }

    bool colour = false;
    read_materials(root, scene, colour);
    read_curves(root, scene, colour);
    scene.channels = colour ? 3 : 1;
    // Every thread keeps each detector bin's tally (both sides, every channel): bounded, so that a
    // scene of many detectors cannot take the memory of its solve.
    std::size_t bins = 0;
    for (const Curve& curve : scene.curves)
      if (scene.material_of(curve).optics == Optics::Detector) bins += scene.material_of(curve).detector_bins;
    if (bins > kMaxDetectorBins)
      fail("curves", "the detector curves have " + std::to_string(bins) + " bins in all; at most " +
                         std::to_string(kMaxDetectorBins) + " (use fewer detectors or fewer \"bins\")");

    if (const Status status = finalize_scene(scene); !status) {
      throw ParseFailure{locate(status.error().message)};
    }
    const bool lit =
        std::any_of(scene.curves.begin(), scene.curves.end(), [&](const Curve& c) { return scene.is_emitter(c); });
    if (!lit) {
      fail("curves",
           "no curve emits light, so nothing would be lit; give a material (or a curve) "
           "a positive \"emittance\"");
    }
    return scene;
  }

  int read_version(const Json& root) const {
    const auto it = root.find("flatland");
    if (it == root.end()) {
      fail("",
           "missing \"flatland\": 2, the format version; this program reads versions 1 and 2 "
           "(docs/scene-format.md)");
    }
    if (!it->is_number()) {
      fail("flatland", "expected the format version as a number (1), got " + type_name(*it));
    }
    const double version = it->get<double>();
    if (version != 1.0 && version != 2.0) {
      fail("flatland", "unsupported format version " + format_number(version) +
                           "; this program reads versions 1 and 2 (docs/scene-format.md)");
    }
    return static_cast<int>(version);
  }

  void read_materials(const Json& root, Scene& scene, bool& colour) {
    const Json& materials =
        require(root, "", "materials", "add \"materials\": {\"name\": {\"reflectivity\": 0.5}, ...}");
    if (!materials.is_object()) {
      fail("materials", "expected an object of named materials {\"name\": {...}}, got " + type_name(materials));
    }
    if (materials.empty()) {
      fail("materials",
           "no materials defined; define at least one, e.g. "
           "{\"lamp\": {\"emittance\": 1}}");
    }
    for (const auto& item : materials.items()) {
      const std::string path = append_key("materials", item.key());
      if (item.key().empty()) fail(path, "a material name must not be empty; give it a name");
      const Json& m = item.value();
      if (!m.is_object()) {
        fail(path, "expected a material object {\"reflectivity\": ..., \"emittance\": ...}, got " + type_name(m));
      }
      Material material = read_material(m, path, colour);
      material.name = item.key();
      material_index_.emplace(material.name, static_cast<std::uint32_t>(scene.materials.size()));
      material_names_.push_back(material.name);
      scene.materials.push_back(std::move(material));
    }
  }

  Material read_material(const Json& m, const std::string& path, bool& colour) const {
    Material material;
    if (const auto it = m.find("type"); it != m.end()) {
      const std::string type = text_value(*it, append_key(path, "type"), "a material type");
      if (type == "mirror") {
        material.optics = Optics::Mirror;
      } else if (type == "dielectric") {
        material.optics = Optics::Dielectric;
      } else if (type == "detector") {
        material.optics = Optics::Detector;
      } else if (type != "diffuse") {
        fail_choice(append_key(path, "type"), "material type", type, {"diffuse", "mirror", "dielectric", "detector"});
      }
    }
    if (material.optics != Optics::Diffuse) {
      for (const char* key : {"emittance", "emission"})
        if (m.contains(key))
          fail(append_key(path, key), std::string("a ") + m.at("type").get<std::string>() +
                                          " does not emit; give the lamp a diffuse material of its own");
    }
    if (material.optics != Optics::Diffuse && m.contains("reflectivity")) {
      fail(append_key(path, "reflectivity"),
           material.optics == Optics::Mirror
               ? "a mirror reflects specularly: give its fraction as \"reflectance\" (in [0, 1]); \"reflectivity\" "
                 "is a diffuse material's"
           : material.optics == Optics::Dielectric
               ? "a dielectric reflects by Fresnel's equations from its \"ior\"; remove \"reflectivity\""
               : "a detector lets all light through; remove \"reflectivity\"");
    }
    switch (material.optics) {
      case Optics::Diffuse:
        check_keys(m, path, {"type", "reflectivity", "emittance", "emission", "spectrum"});
        if (const auto it = m.find("reflectivity"); it != m.end())
          material.reflectivity = spectrum(*it, append_key(path, "reflectivity"), Quantity::Reflectivity, colour);
        if (const auto it = m.find("emittance"); it != m.end())
          material.emittance = spectrum(*it, append_key(path, "emittance"), Quantity::Emittance, colour);
        if (const auto it = m.find("emission"); it != m.end())
          material.emission = emission(*it, append_key(path, "emission"));
        if (const auto it = m.find("spectrum"); it != m.end()) {
          const std::string spectrum_path = append_key(path, "spectrum");
          const auto emittance = m.find("emittance");
          if (emittance == m.end() || !(material.emittance[0] > 0.0))
            fail(spectrum_path, "a spectrum shapes emitted light: give the material an \"emittance\" > 0");
          if (emittance->is_array())
            fail(append_key(path, "emittance"),
                 "with a \"spectrum\" the emittance is one number (its colour comes from the spectrum)");
          material.spectrum = emitter_spectrum(*it, spectrum_path);
          // A spectral scene is a colour scene: the grey emittance E is split by the spectrum.
          colour = true;
          const double grey = material.emittance[0];
          for (std::size_t ch = 0; ch < 3; ++ch)
            material.emittance[ch] = 3.0 * grey * material.spectrum->mean_shares[ch];
        }
        break;
      case Optics::Mirror:
        check_keys(m, path, {"type", "reflectance", "roughness"});
        if (const auto it = m.find("reflectance"); it != m.end())
          material.reflectance = spectrum(*it, append_key(path, "reflectance"), Quantity::Reflectance, colour);
        material.roughness = roughness(m, path);
        break;
      case Optics::Dielectric:
        check_keys(m, path, {"type", "ior", "ior_back", "absorption", "roughness"});
        material.roughness = roughness(m, path);
        material.ior = refractive_index(require(m, path, "ior", "give the index, e.g. \"ior\": 1.5 (glass)"),
                                        append_key(path, "ior"));
        if (const auto it = m.find("ior_back"); it != m.end()) {
          material.ior_back = number(*it, append_key(path, "ior_back"));
          check_index(material.ior_back, append_key(path, "ior_back"));
        }
        if (const auto it = m.find("absorption"); it != m.end())
          material.absorption = spectrum(*it, append_key(path, "absorption"), Quantity::Absorption, colour);
        break;
      case Optics::Detector:
        check_keys(m, path, {"type", "bins"});
        if (const auto it = m.find("bins"); it != m.end()) {
          const double bins = number(*it, append_key(path, "bins"));
          if (!(bins >= 1.0 && bins <= 4096.0) || bins != std::floor(bins))
            fail(append_key(path, "bins"),
                 "expected a whole number of bins from 1 to 4096, got " + format_number(bins));
          material.detector_bins = static_cast<std::uint32_t>(bins);
        }
        break;
    }
    return material;
  }

  // {"blackbody": kelvin}, {"line": nm} or a table [[nm, power], ...].
  EmitterSpectrum emitter_spectrum(const Json& v, const std::string& path) const {
    constexpr const char* kForms =
        "use {\"blackbody\": kelvin}, {\"line\": nanometres} or a table [[nanometres, power], ...]";
    EmitterSpectrum result;
    if (v.is_array()) {
      result.kind = EmitterSpectrum::Kind::Table;
      if (v.size() < 2) fail(path, "a spectrum table needs at least 2 points [[nanometres, power], ...]");
      for (std::size_t k = 0; k < v.size(); ++k) {
        const std::string point_path = append_index(path, k);
        if (!v[k].is_array() || v[k].size() != 2)
          fail(point_path, "expected a point [nanometres, power], got " + type_name(v[k]));
        const double nm = number(v[k][0], append_index(point_path, 0));
        const double power = number(v[k][1], append_index(point_path, 1));
        if (!(nm >= 300.0 && nm <= 900.0))
          fail(append_index(point_path, 0), "a wavelength in nanometres from 300 to 900, got " + format_number(nm));
        if (!(power >= 0.0 && power <= kMaxEmittance))
          fail(append_index(point_path, 1), "relative power must be between 0 and 1e100, got " + format_number(power));
        if (!result.points.empty() && !(nm > result.points.back().first))
          fail(append_index(point_path, 0), "wavelengths must increase along the table, got " + format_number(nm) +
                                                " after " + format_number(result.points.back().first));
        result.points.emplace_back(nm, power);
      }
    } else {
      if (!v.is_object() || v.size() != 1) fail(path, std::string("expected one spectrum form; ") + kForms);
      check_keys(v, path, {"blackbody", "line"});
      if (const auto it = v.find("blackbody"); it != v.end()) {
        result.kind = EmitterSpectrum::Kind::Blackbody;
        result.kelvin = number(*it, append_key(path, "blackbody"));
        if (!(result.kelvin >= 500.0 && result.kelvin <= 100000.0))
          fail(append_key(path, "blackbody"),
               "a temperature from 500 to 100000 kelvin, got " + format_number(result.kelvin));
      } else {
        result.kind = EmitterSpectrum::Kind::Line;
        result.line = number(v.at("line"), append_key(path, "line"));
        if (!(result.line >= kMinWavelength && result.line <= kMaxWavelength))
          fail(append_key(path, "line"),
               "a visible wavelength from 380 to 780 nanometres, got " + format_number(result.line));
      }
    }
    if (!result.prepare())
      fail(path, "the spectrum has no power between 380 and 780 nm (the visible range its photons are drawn from)");
    return result;
  }

  // A mirror's or a dielectric's "roughness": 0 (smooth, the default) to 1.
  double roughness(const Json& m, const std::string& path) const {
    const auto it = m.find("roughness");
    if (it == m.end()) return 0.0;
    const double value = number(*it, append_key(path, "roughness"));
    if (!(value >= 0.0 && value <= 1.0))
      fail(append_key(path, "roughness"),
           "must be in [0, 1] (the microfacets' slope spread; 0 is smooth), got " + format_number(value));
    return value;
  }

  // A refractive index: a number, or {"cauchy": [A, B]} (n = A + B / lambda^2, lambda in um).
  RefractiveIndex refractive_index(const Json& v, const std::string& path) const {
    RefractiveIndex index;
    if (v.is_number()) {
      index.a = number(v, path);
      check_index(index.a, path);
      return index;
    }
    if (!v.is_object() || v.size() != 1 || !v.contains("cauchy"))
      fail(path,
           "expected an index (a number >= 1) or {\"cauchy\": [A, B]} (n = A + B / lambda^2, lambda in "
           "micrometres), got " +
               type_name(v));
    const Json& c = v.at("cauchy");
    const std::string cauchy_path = append_key(path, "cauchy");
    if (!c.is_array() || c.size() != 2)
      fail(cauchy_path, "expected [A, B] (n = A + B / lambda^2, lambda in micrometres), e.g. [1.5046, 0.0042] (BK7)");
    index.a = number(c[0], append_index(cauchy_path, 0));
    index.b = number(c[1], append_index(cauchy_path, 1));
    // The index must stay a physical one over the visible range (360 to 830 nm).
    for (double lambda : {0.36, 0.83}) {
      const double n = index.at(lambda);
      if (!(n >= 1.0 && n <= 10.0))
        fail(cauchy_path, "gives n = " + format_number(n) + " at " + format_number(lambda * 1000.0) +
                              " nm; the index must stay in [1, 10] from 360 to 830 nm");
    }
    return index;
  }

  void check_index(double n, const std::string& path) const {
    if (!(n >= 1.0 && n <= 10.0))
      fail(path, "a refractive index must be in [1, 10] (1 is vacuum, 1.5 glass), got " + format_number(n));
  }

  void read_curves(const Json& root, Scene& scene, bool& colour) {
    const Json& curves =
        require(root, "", "curves", "add \"curves\": [{\"id\": ..., \"material\": ..., \"line\": ...}]");
    if (!curves.is_array()) fail("curves", "expected an array of curves, got " + type_name(curves));
    if (curves.empty()) fail("curves", "the scene has no curves; add at least one");
    std::unordered_map<std::string, std::size_t> ids;
    for (std::size_t i = 0; i < curves.size(); ++i) {
      const std::string path = append_index("curves", i);
      Curve curve = read_curve(curves[i], path, scene, colour);
      const auto [where, inserted] = ids.emplace(curve.id, i);
      if (!inserted) {
        fail(path + ".id", "duplicate id " + quote(curve.id) + " (curves[" + std::to_string(where->second) +
                               "] and curves[" + std::to_string(i) + "]); give each curve its own id");
      }
      scene.curves.push_back(std::move(curve));
    }
  }

  Curve read_curve(const Json& v, const std::string& path, const Scene& scene, bool& colour) const {
    if (!v.is_object()) {
      fail(path,
           "expected a curve object {\"id\": ..., \"material\": ..., \"line\" or \"bezier\": "
           "...}, got " +
               type_name(v));
    }
    check_keys(v, path, {"id", "material", "line", "bezier", "joints", "sides", "emittance", "emittance_profile"});
    Curve curve;
    curve.id = text_value(require(v, path, "id", "give the curve a unique \"id\""), path + ".id", "an id");
    if (curve.id.empty()) fail(path + ".id", "the id must not be empty; give the curve a name");

    const std::string material_path = path + ".material";
    const std::string material =
        text_value(require(v, path, "material", "name one of the scene's materials"), material_path, "a material name");
    const auto found = material_index_.find(material);
    if (found == material_index_.end()) {
      std::string what = "unknown material " + quote(material);
      if (const auto hint = closest(material, material_names_)) what += "; did you mean " + quote(*hint) + "?";
      what += " (defined: " + quoted_list(material_names_) + ")";
      fail(material_path, what);
    }
    curve.material = found->second;
    curve.emittance = scene.materials[found->second].emittance;
    if (const auto& spectral = scene.materials[found->second].spectrum; spectral) {
      // A curve's own emittance on a spectral material: one number, split like the material's.
      if (const auto it = v.find("emittance"); it != v.end()) {
        if (!it->is_number())
          fail(path + ".emittance", "material " + quote(material) +
                                        " has a spectrum: the curve's emittance is one number (its colour comes "
                                        "from the spectrum)");
      }
    }
    if (scene.materials[found->second].optics != Optics::Diffuse) {
      for (const char* key : {"emittance", "emittance_profile"})
        if (v.contains(key))
          fail(append_key(path, key),
               "material " + quote(material) + " is not diffuse and does not emit; give the lamp a diffuse material");
    }

    const bool has_line = v.contains("line");
    const bool has_bezier = v.contains("bezier");
    if (has_line == has_bezier) {
      fail(path, has_line ? "has both \"line\" and \"bezier\"; give exactly one"
                          : "missing geometry; give \"line\": [[x, y], ...] or "
                            "\"bezier\": [[x, y], ...] (3k+1 control points)");
    }
    const char* key = has_line ? "line" : "bezier";
    const std::string points_path = path + "." + key;
    const Json& points = v.at(key);
    if (!points.is_array()) {
      fail(points_path, "expected an array of points [[x, y], ...], got " + type_name(points));
    }
    curve.kind = has_line ? SegmentKind::Line : SegmentKind::Cubic;
    for (std::size_t k = 0; k < points.size(); ++k) {
      curve.points.push_back(point(points[k], points_path, k));
    }
    std::size_t segments = 0;
    if (has_line) {
      if (curve.points.size() < 2) {
        fail(points_path, "a line needs at least 2 points, got " + std::to_string(curve.points.size()));
      }
      for (std::size_t k = 1; k < curve.points.size(); ++k) {
        if (curve.points[k] == curve.points[k - 1]) {
          fail(append_index(points_path, k), "coincides with the previous point (" + std::string(key) + "[" +
                                                 std::to_string(k - 1) +
                                                 "]), which would make a zero-length segment; remove one of them");
        }
      }
      segments = curve.points.size() - 1;
    } else {
      const std::size_t n = curve.points.size();
      if (n < 4 || (n - 1) % 3 != 0) {
        fail(points_path, "expected 3k+1 points, got " + std::to_string(n) +
                              "; a chain of k cubic segments sharing end points has 4, 7, 10, ... "
                              "control points");
      }
      segments = (n - 1) / 3;
    }
    if (std::all_of(curve.points.begin(), curve.points.end(), [&](Vec2 p) { return p == curve.points.front(); })) {
      fail(points_path, "all points coincide, so the curve has zero length; give distinct points");
    }

    if (const auto it = v.find("joints"); it != v.end()) {
      // A closed chain (last point = first, exactly as written) may also name its closing joint;
      // finalize_scene checks the count against the closure it finds.
      // Version 1 had no closing joint (the closing point was a seam).
      const bool closed = version_ >= 2 && curve.points.size() > 1 && curve.points.back() == curve.points.front();
      curve.joints = read_joints(*it, path + ".joints", segments, closed);
    }
    if (const auto it = v.find("sides"); it != v.end()) {
      curve.sides = read_sides(*it, path + ".sides");
    }
    if (const auto it = v.find("emittance"); it != v.end()) {
      curve.emittance = spectrum(*it, path + ".emittance", Quantity::Emittance, colour);
      if (const auto& spectral = scene.materials[curve.material].spectrum; spectral) {
        const double grey = curve.emittance[0];
        for (std::size_t ch = 0; ch < 3; ++ch) curve.emittance[ch] = 3.0 * grey * spectral->mean_shares[ch];
      }
    }
    if (const auto it = v.find("emittance_profile"); it != v.end()) {
      const std::string profile_path = path + ".emittance_profile";
      if (!it->is_array()) fail(profile_path, "expected an array of factors, one per point, got " + type_name(*it));
      if (it->size() != curve.points.size())
        fail(profile_path, "expected " + std::to_string(curve.points.size()) + " factors (one per point), got " +
                               std::to_string(it->size()));
      for (std::size_t k = 0; k < it->size(); ++k) {
        const double factor = number((*it)[k], append_index(profile_path, k));
        if (factor < 0.0 || factor > kMaxEmittance)
          fail(append_index(profile_path, k), "must be between 0 and 1e100, got " + format_number(factor));
        curve.emittance_profile.push_back(factor);
      }
    }
    return curve;
  }

  std::vector<Continuity> read_joints(const Json& v, const std::string& path, std::size_t segments, bool closed) const {
    const std::size_t joints = segments - 1;
    if (v.is_string()) {
      // One value for every joint, the closing point of a closed chain included.
      return std::vector<Continuity>(closed ? segments : joints, continuity(v, path));
    }
    if (!v.is_array()) {
      fail(path,
           "expected \"C1\", \"C0\" or \"C-1\" for every joint, or an array with one of them "
           "per joint, got " +
               type_name(v));
    }
    if (v.size() != joints && !(closed && v.size() == segments)) {
      if (closed) {
        fail(path, "expected " + std::to_string(segments) + (segments == 1 ? " entry" : " entries") +
                       " (one per joint of the closed chain, the last at the closing point) or " +
                       std::to_string(joints) + " (the closing point by its tangents), got " +
                       std::to_string(v.size()));
      }
      fail(path, "expected " + std::to_string(joints) + (joints == 1 ? " entry" : " entries") +
                     " (one per joint between the " + std::to_string(segments) +
                     (segments == 1 ? " segment" : " segments") + "), got " + std::to_string(v.size()));
    }
    std::vector<Continuity> out;
    for (std::size_t k = 0; k < v.size(); ++k) out.push_back(continuity(v[k], append_index(path, k)));
    return out;
  }

  Continuity continuity(const Json& v, const std::string& path) const {
    const std::string value = text_value(v, path, "\"C1\", \"C0\" or \"C-1\"");
    if (value == "C1") return Continuity::C1;
    if (value == "C0") return Continuity::C0;
    if (value == "C-1") return Continuity::Jump;
    fail_choice(path, "continuity", value, {"C1", "C0", "C-1"});
  }

  Sides read_sides(const Json& v, const std::string& path) const {
    const std::string value = text_value(v, path, "\"front\", \"back\" or \"both\"");
    if (value == "front") return Sides::Front;
    if (value == "back") return Sides::Back;
    if (value == "both") return Sides::Both;
    fail_choice(path, "value", value, {"front", "back", "both"});
  }

  [[noreturn]] void fail_choice(const std::string& path, const char* what, const std::string& value,
                                const std::vector<std::string>& choices) const {
    std::string message = std::string("unknown ") + what + " " + quote(value);
    if (const auto hint = closest(value, choices)) message += "; did you mean " + quote(*hint) + "?";
    message += " (accepted: " + quoted_list(choices) + ")";
    fail(path, message);
  }

  std::string_view text_;
  std::string source_;
  int version_ = kSceneFormatVersion;   // of the file being read
  mutable std::optional<TextMap> map_;  // positions, recorded when a message needs one
  std::unordered_map<std::string, std::uint32_t> material_index_;
  std::vector<std::string> material_names_;
};

}  // namespace

Result<Scene> parse_scene(std::string_view text, std::string_view source) {
  try {
    SceneReader reader(text, source);
    Result<Scene> scene = reader.read();
    if (scene) scene->source_sha256 = sha256_hex(text);
    return scene;
  } catch (const ParseFailure& failure) {
    return Error{failure.message};
  } catch (const std::exception& e) {
    return Error{std::string(source) + ": cannot read the scene: " + e.what()};
  } catch (...) {
    return Error{std::string(source) + ": cannot read the scene: unknown error"};
  }
}

Result<Scene> load_scene(const std::string& path, const std::atomic<bool>* cancel) {
  Result<std::string> text = read_input_file(path, "scene file", cancel);
  if (!text) return text.error();
  return parse_scene(*text, path);
}

}  // namespace flatland
