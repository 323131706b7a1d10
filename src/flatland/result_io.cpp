#include "flatland/result_io.hpp"

#include "flatland/version.hpp"

#include <algorithm>
#include <cmath>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <optional>
#include <random>

#include <signal.h>
#include <unistd.h>

#include "flatland/text.hpp"

namespace flatland {

nlohmann::json scene_to_json(const Scene& scene) {
  return {{"name", scene.name}, {"file", scene.source}, {"sha256", scene.source_sha256},
          {"channels", scene.channels}};
}

nlohmann::json program_to_json() {
  return {{"name", "flatland"}, {"version", program_version()}, {"commit", program_commit()}};
}

namespace {

// The result document of `solver` with its sampled result, but for "curves" (an empty array).
nlohmann::json result_without_curves(const Solver& solver, int samples_per_curve, const SampledResult& sampled) {
  const Scene& scene = solver.scene();
  const SolverSettings& settings = solver.settings();
  nlohmann::json result;
  result["flatland_result"] = 1;
  result["program"] = program_to_json();
  result["scene"] = scene_to_json(scene);
  result["settings"] = {
      {"method", to_string(settings.transport)},
      {"transport", to_string(settings.transport)},
      {"photons", settings.photons},
      {"seed", settings.seed},
      {"threads", solver.thread_count()},
      {"processes", solver.round_sharing() != nullptr ? solver.round_sharing()->size() : 1u},
      {"basis", to_string(settings.basis)},
      {"elements", settings.elements == kAutoElements ? nlohmann::json("auto") : nlohmann::json(settings.elements)},
      {"tolerance", settings.tolerance},
      {"sampling", to_string(settings.sampling)},
      {"discontinuities", to_string(settings.discontinuities)},
      {"estimator", to_string(settings.estimator)},
      {"sampler", to_string(settings.sampler)},
      {"ray_width", settings.ray_width},
      {"ray_profile", to_string(settings.ray_profile)},
      {"ray_mode", to_string(settings.ray_mode)},
      {"band_rays", settings.band_rays},
      {"samples", samples_per_curve},
  };
  result["stats"] = stats_to_json(*sampled.stats);
  result["curves"] = nlohmann::json::array();
  return result;
}

}  // namespace

nlohmann::json result_to_json(const Solver& solver, int samples_per_curve) {
  const SampledResult sampled = sample_solver(solver, samples_per_curve);
  nlohmann::json result = result_without_curves(solver, samples_per_curve, sampled);
  result["curves"] = curves_to_json(sampled);
  return result;
}

std::string result_text(const Solver& solver, int samples_per_curve) {
  const SampledResult sampled = sample_solver(solver, samples_per_curve);
  const std::string outline = json_text(result_without_curves(solver, samples_per_curve, sampled));
  // The outline holds `"curves": []` (keys are sorted, so first); the curves go in its place as
  // dump(1) would write them at that depth: "[", each entry on its own lines two spaces in, "]"
  // one space in.
  const std::string empty = "\"curves\": []";
  const std::size_t at = outline.find(empty);
  if (at == std::string::npos || sampled.curves.empty()) return outline;
  const std::size_t open = at + empty.size() - 2;
  std::string text(outline, 0, open);
  // nlohmann's serializer (a detail of the library, the same from 3.10 to 3.12) writes an entry
  // at a given depth, as dump() does inside a document.
  nlohmann::detail::serializer<nlohmann::json> serializer(nlohmann::detail::output_adapter<char>(text), ' ',
                                                          nlohmann::json::error_handler_t::replace);
  text += "[\n";
  // Room for the whole text (growing by doubling copied it all twice): the numbers every curve
  // writes, at the bytes per number of the first kMeasured curves.
  constexpr std::size_t kMeasured = 64;
  const std::size_t curves = sampled.curves.size();
  std::size_t numbers_measured = 0;
  for (std::size_t c = 0; c < curves; ++c) {
    if (c == kMeasured) {
      std::size_t numbers_left = 0;
      for (std::size_t rest = c; rest < curves; ++rest)
        numbers_left += curve_json_numbers(sampled.curves[rest], sampled.channels);
      const double per_number = static_cast<double>(text.size() - open) / static_cast<double>(numbers_measured);
      text.reserve(text.size() + static_cast<std::size_t>(1.25 * per_number * static_cast<double>(numbers_left)) +
                   outline.size());
    }
    text += c == 0 ? "  " : ",\n  ";
    serializer.dump(curve_to_json(sampled.curves[c], sampled.channels), true, false, 1, 2);
    if (c < kMeasured) numbers_measured += curve_json_numbers(sampled.curves[c], sampled.channels);
  }
  text += "\n ]";
  text.append(outline, open + 2, std::string::npos);
  return text;
}

nlohmann::json stats_to_json(const ResultStats& stats) {
  return {
      {"photons", stats.photons},
      {"rounds", stats.rounds},
      {"rays", stats.rays},
      {"seconds", stats.seconds},
      {"stop_reason", to_string(stats.stop_reason)},
      {"emitted_power", stats.books.emitted},
      {"absorbed_power", stats.books.absorbed},
      {"escaped_power", stats.books.escaped},
      {"unshot_power", stats.books.unshot},
  };
}

nlohmann::json reference_result_to_json(const Scene& scene, const ReferenceSettings& settings,
                                        const ReferenceSolution& solution, int samples_per_curve,
                                        double seconds, const ReferenceErrorEstimate* estimate,
                                        const nlohmann::json& curves) {
  nlohmann::json result;
  result["flatland_result"] = 1;
  result["program"] = program_to_json();
  result["scene"] = scene_to_json(scene);
  result["settings"] = {{"method", "reference"},
                        {"max_element_length",
                         settings.max_element_length > 0.0 ? settings.max_element_length : scene.scale / 400.0},
                        {"quadrature", settings.quadrature},
                        {"tolerance", settings.tolerance},
                        {"samples", samples_per_curve}};
  result["stats"] = {{"elements", solution.elements()},
                     {"iterations", solution.iterations()},
                     {"residual", solution.residual()},
                     {"error_bound", solution.error_bound()},
                     {"seconds", seconds},
                     {"form_factor_seconds", solution.form_factor_seconds()},
                     {"solve_seconds", solution.solve_seconds()}};
  if (estimate != nullptr) {
    const ErrorNorms& e = estimate->error;
    result["stats"]["estimated_error"] = {{"l1", e.l1}, {"l2", e.l2}, {"linf", e.linf}};
    // null where no order could be observed (differences at round-off).
    auto number_or_null = [](double value) { return std::isnan(value) ? nlohmann::json(nullptr) : nlohmann::json(value); };
    result["stats"]["observed_order"] = number_or_null(estimate->observed_order);
    result["stats"]["estimate_order"] = number_or_null(estimate->order);
    if (!estimate->note.empty()) result["stats"]["estimate_note"] = estimate->note;
  }
  result["curves"] = curves;
  return result;
}

Result<nlohmann::json> parse_result(std::string_view text, const std::string& source) {
  auto at = [&](std::size_t offset) {
    const TextPosition p = position_of(text, offset);
    return source + ":" + std::to_string(p.line) + ":" + std::to_string(p.column) + ": ";
  };
  nlohmann::json document;
  try {
    document = nlohmann::json::parse(text.begin(), text.end());
  } catch (const nlohmann::json::parse_error& e) {
    return Error{at(e.byte > 0 ? e.byte - 1 : 0) + "not valid JSON; is this a result written by "
                 "'flatland solve --out'?"};
  } catch (const nlohmann::json::out_of_range&) {
    const std::optional<std::size_t> offset = find_overflowing_number(text);
    return Error{(offset ? at(*offset) : source + ": ") +
                 "a number is beyond the range of a double (it overflows to infinity)"};
  } catch (const std::exception& e) {
    return Error{source + ": cannot read the result: " + e.what()};
  }
  if (!document.is_object() || !document.contains("flatland_result"))
    return Error{source + ": not a flatland result (no \"flatland_result\" key); write one with "
                 "'flatland solve --out' or 'flatland reference --out'"};
  if (document["flatland_result"] != 1)
    return Error{source + ": unsupported result version " + document["flatland_result"].dump() +
                 "; this program reads version 1"};
  return document;
}

Result<nlohmann::json> read_result_file(const std::string& path) {
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec))
    return Error{path + ": is a directory, not a result file; give the path of a .json file"};
  std::ifstream in(path, std::ios::binary);
  if (!in) return Error{path + ": cannot read the result file: " + std::strerror(errno)};
  std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  if (in.bad()) return Error{path + ": cannot read the result file: " + std::strerror(errno)};
  return parse_result(text, path);
}

std::string json_text(const nlohmann::json& document) {
  return document.dump(1, ' ', false, nlohmann::json::error_handler_t::replace) + "\n";
}

namespace {

namespace fs = std::filesystem;

fs::path directory_of(const fs::path& target) {
  return target.parent_path().empty() ? fs::path(".") : target.parent_path();
}

// Our temporary names: temporary_prefix(target) + PID + "-" + digits.
std::string temporary_prefix(const fs::path& target) {
  // (Appended piece by piece: GCC 12 warns falsely about `"." + std::string` under -O3.)
  std::string prefix = ".";
  prefix += target.filename().string();
  prefix += ".tmp";
  return prefix;
}

// Removes temporary files of `target` whose writing process is gone (killed mid-write).
void remove_stale_temporaries(const fs::path& target) {
  const std::string prefix = temporary_prefix(target);
  std::error_code ec;
  for (fs::directory_iterator it(directory_of(target), ec), end; !ec && it != end; it.increment(ec)) {
    const std::string name = it->path().filename().string();
    if (name.size() <= prefix.size() || name.compare(0, prefix.size(), prefix) != 0) continue;
    const std::string rest = name.substr(prefix.size());
    const std::size_t dash = rest.find('-');
    if (dash == 0 || dash == std::string::npos || dash + 1 == rest.size() ||
        rest.find_first_not_of("0123456789-") != std::string::npos || rest.find('-', dash + 1) != std::string::npos)
      continue;
    const long pid = std::strtol(rest.substr(0, dash).c_str(), nullptr, 10);
    if (pid <= 0 || pid == ::getpid()) continue;
    if (::kill(static_cast<pid_t>(pid), 0) == 0 || errno != ESRCH) continue;  // still running
    std::error_code ignored;
    fs::remove(it->path(), ignored);
  }
}

}  // namespace

Status check_output_file(const std::string& path) {
  const fs::path target(path);
  if (path.empty() || target.filename().empty() || target.filename() == "." || target.filename() == "..")
    return Error{path + ": not a file name; give a path such as out/result.json"};
  std::error_code ec;
  if (fs::is_directory(target, ec)) return Error{path + ": is a directory; give a file name"};
  const fs::path directory = directory_of(target);
  if (!fs::is_directory(directory, ec))
    return Error{path + ": directory " + directory.string() + " does not exist; create it first"};
  if (::access(directory.c_str(), W_OK | X_OK) != 0)
    return Error{path + ": cannot write in directory " + directory.string() + ": " + std::strerror(errno)};
  return ok_status();
}

OutputFiles::~OutputFiles() { discard(); }

void OutputFiles::discard() {
  for (const Staged& file : staged_) {
    std::error_code ignored;
    fs::remove(file.temporary, ignored);
  }
  staged_.clear();
}

Status OutputFiles::stage(const std::string& path, const std::string& contents) {
  if (Status status = check_output_file(path); !status) return status;
  const fs::path target(path);
  remove_stale_temporaries(target);
  // A unique temporary name in the same directory, so the rename is atomic.
  std::random_device device;
  std::string name = temporary_prefix(target);
  name += std::to_string(::getpid());
  name += '-';
  name += std::to_string(device());
  const fs::path temporary = directory_of(target) / name;
  std::error_code ec;
  {
    std::ofstream out(temporary, std::ios::binary | std::ios::trunc);
    if (!out) return Error{path + ": cannot write: " + std::strerror(errno)};
    staged_.push_back({path, temporary.string()});
    out.write(contents.data(), static_cast<std::streamsize>(contents.size()));
    out.flush();
    if (!out) {
      const std::string reason = std::strerror(errno);
      out.close();
      fs::remove(temporary, ec);
      staged_.pop_back();
      return Error{path + ": write failed: " + reason};
    }
  }
  return ok_status();
}

Status OutputFiles::commit() {
  for (std::size_t i = 0; i < staged_.size(); ++i) {
    std::error_code ec;
    fs::rename(staged_[i].temporary, staged_[i].target, ec);
    if (ec) {
      const std::string message = staged_[i].target + ": cannot replace the file: " + ec.message();
      staged_.erase(staged_.begin(), staged_.begin() + static_cast<std::ptrdiff_t>(i));
      discard();
      return Error{message};
    }
  }
  staged_.clear();
  return ok_status();
}

Status check_result_size(const Scene& scene, int samples_per_curve) {
  double sides = 0.0;
  for (const Curve& curve : scene.curves) sides += curve.sides == Sides::Both ? 2.0 : 1.0;
  const double total = sides * samples_per_curve;
  if (total <= kMaxResultSamples) return ok_status();
  char message[320];
  std::snprintf(message, sizeof message,
                "--samples %d: %zu curves make %.3g radiosity samples in the result; at most %.3g "
                "(about 100 bytes of JSON each); give at most --samples %.0f",
                samples_per_curve, scene.curves.size(), total, kMaxResultSamples,
                std::max(1.0, std::floor(kMaxResultSamples / std::max(sides, 1.0))));
  return Error{message};
}

Status write_file_atomically(const std::string& path, const std::string& contents) {
  OutputFiles files;
  if (Status status = files.stage(path, contents); !status) return status;
  return files.commit();
}

}  // namespace flatland
