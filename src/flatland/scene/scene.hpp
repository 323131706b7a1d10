// A flatland scene: materials and curves (chains of straight or cubic Bezier segments), validated
// and flattened into the segment list the ray caster and the solver share.
#pragma once

#include <algorithm>
#include <array>
#include <atomic>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "flatland/base/status.hpp"
#include "flatland/base/vec2.hpp"
#include "flatland/geometry/bezier.hpp"
#include "flatland/geometry/segments.hpp"
#include "flatland/scene/light_spectrum.hpp"

namespace flatland {

// Up to three colour channels; a grey scene uses channel 0 only (Scene::channels == 1).
using Spectrum = std::array<double, 3>;

// Continuity of the illumination at a node of a curve (a joint between segments or a node of the
// storage mesh). Value jump (C-1), continuous value (C0), continuous slope (C1).
enum class Continuity : std::int8_t { Jump = -1, C0 = 0, C1 = 1 };

// Which sides of a curve emit and reflect. The front is to the left of the direction of travel
// along the control points. A side that is not named absorbs everything it receives.
enum class Sides : std::uint8_t { Front, Back, Both };
enum class Side : std::uint8_t { Front = 0, Back = 1 };

// How an emitter's own light leaves it (reflected light is always diffuse). Angles theta are
// measured from the emitting side's normal.
//  - Diffuse: pdf cos(theta) / 2 on [-90, 90] degrees.
//  - Lobe: pdf proportional to cos(theta)^exponent (exponent 1 is diffuse; larger is narrower).
//  - Beam: the diffuse distribution restricted to |theta| <= half_angle (sin theta uniform in
//    [-sin a, sin a]): constant radiance inside the cone, none outside.
struct Emission {
  enum class Kind : std::uint8_t { Diffuse, Lobe, Beam };
  Kind kind = Kind::Diffuse;
  double exponent = 1.0;                   // Lobe
  double half_angle = 1.5707963267948966;  // Beam, radians, in (0, pi/2]
};

// The scene file format version this program writes; it reads this one and version 1.
inline constexpr int kSceneFormatVersion = 2;

// What a surface does with the light that reaches it (docs/scene-format.md, docs/optics.md).
//  - Diffuse: keeps reflectivity times what it receives and reflects it diffusely (storage,
//    reconstruction and origins are about these surfaces only).
//  - Mirror: perfect specular reflection of `reflectance` (per channel) on the sides that the
//    curve's `sides` names; the other side absorbs.
//  - Dielectric: an interface between the index on the front (left) side and `ior_back` on the
//    back: unpolarised Fresnel reflection, Snell refraction, total internal reflection; light
//    crossing the front side's medium is attenuated by exp(-absorption x distance).
//  - Detector: light passes untouched; the curve records the power crossing it.
// Mirrors and dielectrics may be rough: `roughness` > 0 tilts the normal of each interaction by a
// microfacet's (PhotonShooter::follow_chain).
// Only diffuse materials emit.
enum class Optics : std::uint8_t { Diffuse, Mirror, Dielectric, Detector };

// A dielectric's refractive index at a wavelength: n = a + b / lambda^2, lambda in micrometres
// (Cauchy's formula; b = 0 is a constant index).
struct RefractiveIndex {
  double a = 1.5;
  double b = 0.0;
  double at(double micrometres) const { return a + b / (micrometres * micrometres); }
};
// The wavelength at which light without a spectrum refracts: the helium d line.
inline constexpr double kGreyWavelength = 0.5876;  // micrometres

struct Material {
  std::string name;
  Spectrum reflectivity{0.0, 0.0, 0.0};  // Diffuse: each channel in [0,1)
  Spectrum emittance{0.0, 0.0, 0.0};     // power per unit length leaving each emitting side
  Emission emission;                     // directions of the emitted light
  // Spectral emitters: the spectrum its photons' wavelengths are drawn from. The emittance then is
  // its grey value E split by the spectrum's mean channel shares, 3 E x mean_shares (the same
  // total power as a grey E in a colour scene).
  std::optional<EmitterSpectrum> spectrum;
  Optics optics = Optics::Diffuse;
  Spectrum reflectance{1.0, 1.0, 1.0};  // Mirror: each channel in [0,1]
  RefractiveIndex ior;                  // Dielectric: the front side's index
  double ior_back = 1.0;                // Dielectric: the back side's index
  Spectrum absorption{0.0, 0.0, 0.0};   // Dielectric: per unit length in the front side's medium
  double roughness = 0.0;               // Mirror, Dielectric: microfacet slopes' standard deviation
  std::uint32_t detector_bins = 32;     // Detector: bins along the arc length
};

struct Curve {
  std::string id;
  std::uint32_t material = 0;
  SegmentKind kind = SegmentKind::Line;
  // The points as written: a polyline's vertices, or a Bezier chain's 3k+1 control points.
  std::vector<Vec2> points;
  // Continuity at the joints: joints[j] between segments j and j+1. An open curve has
  // segment_count - 1 joints; a closed one (its last point is its first) has segment_count, the
  // last being the closing point, between the last segment and the first.
  std::vector<Continuity> joints;
  // The chain returns to its first point (within 1e-12 of the scene's size). Its storage is
  // periodic unless the closing joint is a jump (a corner, or a version-1 scene file, where the
  // closing point was always a seam).
  bool closed = false;
  Sides sides = Sides::Front;
  Spectrum emittance{0.0, 0.0, 0.0};  // the material's, or the curve's own override
  // Optional grey factors of the emittance at the points (one per point): along a Bezier segment
  // the Bernstein polynomial of its four control points' factors, along a straight segment the
  // linear interpolation of its ends'. Empty: uniform emittance.
  std::vector<double> emittance_profile;
  double profile_mean = 1.0;        // the profile's mean over arc length (1 without a profile)
  double profile_max = 1.0;         // an upper bound of the profile (its largest factor)
  std::uint32_t first_segment = 0;  // index into Scene::segments
  std::uint32_t segment_count = 0;
  double length = 0.0;
  std::vector<double> segment_start;  // cumulative arc length at each segment start (+ total)

  std::uint32_t joint_count() const { return closed ? segment_count : segment_count - 1; }
  // Whether the storage wraps around the closing point (a closed curve whose closing joint is not
  // a value jump).
  bool periodic() const { return closed && joints.back() != Continuity::Jump; }

  bool has_side(Side s) const {
    return sides == Sides::Both || (s == Side::Front ? sides == Sides::Front : sides == Sides::Back);
  }
};

struct SceneSegment {
  SegmentGeometry geometry;
  std::uint32_t curve = 0;
  std::uint32_t index_in_curve = 0;
  ArcLengthTable arc_length;
  double length = 0.0;
  double speed_bound = 0.0;  // >= max |C'(t)|, for rejection sampling in arc length
};

struct Scene {
  std::string name;
  std::string description;    // free text from the file ("description"), for people; may be empty
  std::string source;         // file the scene came from, for messages
  std::string source_sha256;  // SHA-256 of the text it was parsed from (results' provenance)
  // SHA-256 of the scene's JSON in one canonical form (keys sorted, no white space, numbers as the
  // parser read them): the same for a file reformatted, or for the same scene built in Python from
  // a dict. Results of scenes whose content differs are never compared.
  std::string content_sha256;
  int channels = 1;  // 1 (grey) or 3 (colour)
  std::vector<Material> materials;
  std::vector<Curve> curves;
  std::vector<SceneSegment> segments;
  Box bounds;
  double scale = 1.0;  // bounding-box diagonal: every geometric tolerance is relative to it
  // The scene format version the scene was read from (docs/scene-format.md); it decides what the
  // closing point of a closed curve means by default (1: a seam; 2: a joint like the others).
  int format_version = kSceneFormatVersion;

  const Material& material_of(const Curve& c) const { return materials[c.material]; }
  // Whether the curve's side `s` holds diffuse illumination (a diffuse material's named side).
  bool stores(const Curve& c, Side s) const { return material_of(c).optics == Optics::Diffuse && c.has_side(s); }
  // Whether either side of the curve holds diffuse illumination (mirrors, glass and detectors do not).
  bool holds_light(const Curve& c) const { return stores(c, Side::Front) || stores(c, Side::Back); }
  // Whether it holds diffuse light that the solve estimates: it reflects in some channel (on a
  // curve that reflects nothing B is its emittance, exact).
  bool reflects_light(const Curve& c) const {
    const Spectrum& rho = material_of(c).reflectivity;
    return holds_light(c) && std::any_of(rho.begin(), rho.begin() + channels, [](double r) { return r > 0.0; });
  }
  // Whether some curve is a mirror, a dielectric or a detector (photons then follow chains).
  bool has_specular() const;
  // Whether some material has a spectrum (its photons carry wavelengths).
  bool has_spectra() const;
  bool has_cubics() const;
  bool is_emitter(const Curve& c) const;
  // Total emitted power summed over channels and emitting sides.
  double emitted_power() const;
};

// The emittance profile's factor at curve parameter u (1 without a profile).
double emittance_factor(const Curve& curve, double u);

// A point of a curve found by arc length: the segment, its parameter, the curve parameter
// u = segment index + t, and the position.
struct CurvePoint {
  std::uint32_t segment_in_curve = 0;
  double t = 0.0;
  double u = 0.0;
  Vec2 position;
};
CurvePoint point_at_arc_length(const Scene& scene, const Curve& curve, double s);
// Its inverse: the arc length from the curve's start to u = segment index + t (u clamped to the
// curve's segments).
double arc_length_at(const Scene& scene, const Curve& curve, double u);

// Whether the chain is tangent-continuous at joint j (between segments j and j+1 of the curve, the
// last segment and the first for the closing joint of a closed curve): the unit tangents agree to
// 1e-9 radians. Corners are where it is not.
bool is_tangent_continuous(const Scene& scene, const Curve& curve, std::uint32_t joint);

// Parse and validate a scene (format version 1, docs/scene-format.md). `source` names the text in
// error messages (usually the file path). Errors are one line, located at the offending value:
//   "scenes2d/room.json:14:9: curves[2].bezier: expected 3k+1 points, got 5; ..."
//   "scenes2d/room.json:14:9: parse error: ..."
// (just "SOURCE: FIELD: ..." when a problem has no single place in the text). Never throws.
Result<Scene> parse_scene(std::string_view text, std::string_view source);
// The scene file at `path`, read by read_input_file (files.hpp): at most kMaxInputBytes, and a
// wait on a pipe ends when `cancel` is set (with the error kFileWaitCancelled).
Result<Scene> load_scene(const std::string& path, const std::atomic<bool>* cancel = nullptr);

// Build the derived data (segments, lengths, bounds, scale) from curves and materials that are
// already filled in and valid; used by the parser and by code that edits a scene (the viewer).
// Empty Curve::joints are filled with the default (C1 where the chain is tangent-continuous, a jump
// at corners); a closed curve given one joint fewer than its segments gets its closing joint's
// default (by the tangent test; a jump when format_version is 1). Fails on zero-length segments and interior cusps; its
// messages start with the field path as in a scene file ("curves[1].bezier[3]: segment 1 has a cusp at t = 0.5, ...").
Status finalize_scene(Scene& scene);

}  // namespace flatland
