#include "flatland/result_io.hpp"

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <random>

#include <unistd.h>

namespace flatland {

nlohmann::json spectrum_to_json(const Spectrum& value, int channels) {
  if (channels == 1) return value[0];
  return nlohmann::json::array({value[0], value[1], value[2]});
}

namespace {

const char* sides_name(Sides sides) {
  return sides == Sides::Both ? "both" : sides == Sides::Back ? "back" : "front";
}

}  // namespace

nlohmann::json scene_to_json(const Scene& scene) {
  return {{"name", scene.name}, {"file", scene.source}, {"channels", scene.channels}};
}

nlohmann::json sampled_curves_to_json(const Scene& scene, int samples_per_curve,
                                      const RadiosityFunction& radiosity) {
  nlohmann::json curves = nlohmann::json::array();
  for (std::uint32_t c = 0; c < scene.curves.size(); ++c) {
    const Curve& curve = scene.curves[c];
    const bool two_sided = curve.sides == Sides::Both;
    const Side main_side = curve.sides == Sides::Back ? Side::Back : Side::Front;
    nlohmann::json samples = nlohmann::json::array();
    for (int j = 0; j < samples_per_curve; ++j) {
      const double s = (j + 0.5) * curve.length / samples_per_curve;
      const CurvePoint point = point_at_arc_length(scene, curve, s);
      nlohmann::json sample = {{"s", s},
                               {"x", point.position.x},
                               {"y", point.position.y},
                               {"B", spectrum_to_json(radiosity(c, main_side, point.u), scene.channels)}};
      if (two_sided)
        sample["B_back"] = spectrum_to_json(radiosity(c, Side::Back, point.u), scene.channels);
      samples.push_back(std::move(sample));
    }
    curves.push_back({{"id", curve.id},
                      {"length", curve.length},
                      {"sides", sides_name(curve.sides)},
                      {"segments", curve.segment_count},
                      {"emittance", spectrum_to_json(curve.emittance, scene.channels)},
                      {"samples", std::move(samples)}});
  }
  return curves;
}

nlohmann::json result_to_json(const Solver& solver, int samples_per_curve) {
  const Scene& scene = solver.scene();
  const SolverSettings& settings = solver.settings();
  const EnergyBooks books = solver.books();
  nlohmann::json result;
  result["flatland_result"] = 1;
  result["scene"] = scene_to_json(scene);
  result["settings"] = {
      {"method", "shooting"},
      {"photons", settings.photons},
      {"seed", settings.seed},
      {"threads", solver.thread_count()},
      {"basis", to_string(settings.basis)},
      {"elements", settings.elements},
      {"tolerance", settings.tolerance},
      {"sampling", to_string(settings.sampling)},
      {"discontinuities", to_string(settings.discontinuities)},
      {"estimator", to_string(settings.estimator)},
      {"ray_width", settings.ray_width},
      {"ray_profile", to_string(settings.ray_profile)},
      {"ray_mode", to_string(settings.ray_mode)},
      {"band_rays", settings.band_rays},
      {"samples", samples_per_curve},
  };
  result["stats"] = {
      {"photons", solver.photons_shot()},
      {"rounds", solver.rounds()},
      {"seconds", solver.seconds()},
      {"stop_reason", to_string(solver.stop_reason())},
      {"emitted_power", books.emitted},
      {"absorbed_power", books.absorbed},
      {"escaped_power", books.escaped},
      {"unshot_power", books.unshot},
  };
  nlohmann::json curves = sampled_curves_to_json(
      scene, samples_per_curve,
      [&solver](std::uint32_t c, Side side, double u) { return solver.radiosity(c, side, u); });
  // The stored spline, so a result can be re-plotted exactly: B(u) = E + sum_k b_k phi_k(u)
  // with phi_k the B-splines of `degree` on `knots`, u = segment index + t.
  for (std::uint32_t c = 0; c < scene.curves.size(); ++c) {
    const Curve& curve = scene.curves[c];
    const Side main_side = curve.sides == Sides::Back ? Side::Back : Side::Front;
    const CurveStorage& storage = solver.storage(c);
    nlohmann::json nodes = nlohmann::json::array();
    for (const MeshNode& node : storage.nodes) {
      const char* flag = node.continuity == Continuity::C1   ? "C1"
                         : node.continuity == Continuity::C0 ? "C0"
                                                             : "C-1";
      nodes.push_back({{"u", node.u}, {"continuity", flag}});
    }
    nlohmann::json& entry = curves[c];
    entry["degree"] = storage.basis.degree();
    entry["knots"] = storage.basis.knots();
    entry["continuity"] = std::move(nodes);
    const std::vector<double> main = solver.radiosity_coefficients(c, main_side);
    if (!main.empty()) entry["coefficients"] = main;
    if (curve.sides == Sides::Both)
      entry["coefficients_back"] = solver.radiosity_coefficients(c, Side::Back);
  }
  result["curves"] = std::move(curves);
  return result;
}

Status write_file_atomically(const std::string& path, const std::string& contents) {
  namespace fs = std::filesystem;
  const fs::path target(path);
  if (target.filename().empty()) return Error{path + ": not a file name"};
  std::error_code ec;
  if (fs::is_directory(target, ec)) return Error{path + ": is a directory; give a file name"};
  const fs::path directory = target.parent_path().empty() ? fs::path(".") : target.parent_path();
  if (!fs::is_directory(directory, ec))
    return Error{path + ": directory " + directory.string() + " does not exist"};

  // A unique temporary name in the same directory, so the rename is atomic.
  std::random_device device;
  // (Appended piece by piece: GCC 12 warns falsely about `"." + std::string` under -O3.)
  std::string name = ".";
  name += target.filename().string();
  name += ".tmp";
  name += std::to_string(::getpid());
  name += '-';
  name += std::to_string(device());
  const fs::path temporary = directory / name;
  {
    std::ofstream out(temporary, std::ios::binary | std::ios::trunc);
    if (!out) return Error{path + ": cannot write: " + std::strerror(errno)};
    out.write(contents.data(), static_cast<std::streamsize>(contents.size()));
    out.flush();
    if (!out) {
      const std::string reason = std::strerror(errno);
      out.close();
      fs::remove(temporary, ec);
      return Error{path + ": write failed: " + reason};
    }
  }
  fs::rename(temporary, target, ec);
  if (ec) {
    std::error_code ignored;
    fs::remove(temporary, ignored);
    return Error{path + ": cannot replace file: " + ec.message()};
  }
  return ok_status();
}

}  // namespace flatland
