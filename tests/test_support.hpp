// Shared helpers of the test suites: scene loading, statistics with derived thresholds.
#pragma once

#include <sys/wait.h>

#include <bit>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <ostream>
#include <span>
#include <sstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "flatland/geometry/bezier.hpp"
#include "flatland/reference/coarse_answer.hpp"
#include "flatland/scene/scene.hpp"
#include "flatland/transport/solver.hpp"

namespace flatland::testing {

inline std::string source_path(const std::string& relative) {
  return std::string(FLATLAND_SOURCE_DIR) + "/" + relative;
}

// What a solve computed, as data: every side's radiosity and unshot coefficients, B at seven
// points of every segment, each curve's storage elements, the energy books, the rounds, photons and
// rays, and why it stopped. Not what may differ between runs of the same solve (its wall time, its
// threads, its processes) nor its settings. Compared bit for bit: doubles by their bits, so -0
// against +0 and NaN count as differences.
struct SolutionData {
  std::vector<std::uint64_t> coefficients;
  std::vector<std::uint64_t> unshot;
  std::vector<std::uint64_t> radiosity;
  std::vector<int> elements;
  std::vector<std::uint64_t> books;
  std::vector<std::uint64_t> detected;
  std::uint32_t rounds = 0;
  std::uint64_t photons = 0;
  std::uint64_t rays = 0;
  StopReason stop = StopReason::Running;
  bool operator==(const SolutionData&) const = default;
};

inline SolutionData solution_data(const Solver& solver) {
  SolutionData data;
  auto bits = [](std::vector<std::uint64_t>& out, double value) { out.push_back(std::bit_cast<std::uint64_t>(value)); };
  const Scene& scene = solver.scene();
  for (std::uint32_t c = 0; c < scene.curves.size(); ++c) {
    data.elements.push_back(solver.storage_elements(c));
    for (Side side : {Side::Front, Side::Back}) {
      if (!solver.has_side(c, side)) continue;
      for (double b : solver.radiosity_coefficients(c, side)) bits(data.coefficients, b);
      for (double b : solver.unshot_coefficients(c, side)) bits(data.unshot, b);
      const double segments = scene.curves[c].segment_count;
      for (int j = 0; j < 7 * static_cast<int>(segments); ++j) {
        const Spectrum b = solver.radiosity(c, side, (j + 0.5) / 7.0);
        for (int ch = 0; ch < scene.channels; ++ch) bits(data.radiosity, b[static_cast<std::size_t>(ch)]);
      }
    }
  }
  const EnergyBooks books = solver.books();
  for (double value : {books.emitted, books.absorbed, books.escaped, books.unshot, books.absorbed_mirrors,
                       books.absorbed_glass, books.cut})
    bits(data.books, value);
  for (double value : solver.detected()) bits(data.detected, value);
  data.rounds = solver.rounds();
  data.photons = solver.photons_shot();
  data.rays = solver.rays_traced();
  data.stop = solver.stop_reason();
  return data;
}

// How gtest shows a SolutionData in a failed comparison: its counts and where its parts first
// differ from nothing in particular, so a summary.
inline void PrintTo(const SolutionData& data, std::ostream* out) {
  std::uint64_t hash = 1469598103934665603ull;  // FNV-1a over the doubles' bits
  for (const auto* part : {&data.coefficients, &data.unshot, &data.radiosity, &data.books, &data.detected})
    for (std::uint64_t word : *part) hash = (hash ^ word) * 1099511628211ull;
  *out << "{" << data.rounds << " rounds, " << data.photons << " photons, " << data.rays << " rays, "
       << data.coefficients.size() << " coefficients, stop " << static_cast<int>(data.stop) << ", bits hash "
       << std::hex << hash << std::dec << "}";
}

// The solves on which rounds shared among processes are checked against one process (solver_test,
// threads standing in for processes; mpi_test, under mpirun): shooting with point rays, with
// footprints in colour, random walks, averaged Jacobi iterations, shooting through glass onto a
// detector, and shooting with importance (its rounds' sources counted by every process).
struct SharingCase {
  const char* scene;
  Transport transport;
  double ray_width;
  const char* importance = nullptr;  // a curve's id, or none
};
inline constexpr SharingCase kSharingCases[] = {{"scenes2d/mixed.json", Transport::Shooting, 0.0},
                                                {"scenes2d/syndrome.json", Transport::Shooting, 0.02},
                                                {"scenes2d/curved_room.json", Transport::Walk, 0.0},
                                                {"scenes2d/default.json", Transport::Jacobi, 0.0},
                                                {"scenes2d/prism.json", Transport::Shooting, 0.0},
                                                {"scenes2d/row_of_rooms.json", Transport::Shooting, 0.0, "desk"}};
inline SolverSettings sharing_settings(const SharingCase& c, std::uint64_t photons, std::uint64_t seed) {
  SolverSettings settings;
  settings.photons = photons;
  settings.seed = seed;
  settings.threads = 1;
  settings.transport = c.transport;
  settings.ray_width = c.ray_width;
  if (c.importance != nullptr) settings.importance = {c.importance};
  return settings;
}

// A test fixture with a fresh scratch directory of its own, named after the running test
// (PREFIX-TESTNAME under the system's temporary directory), removed after the test.
class ScratchDirectoryTest : public ::testing::Test {
 protected:
  explicit ScratchDirectoryTest(std::string prefix) : prefix_(std::move(prefix)) {}
  void SetUp() override {
    directory_ = std::filesystem::temp_directory_path() /
                 (prefix_ + "-" + ::testing::UnitTest::GetInstance()->current_test_info()->name());
    std::filesystem::remove_all(directory_);
    std::filesystem::create_directories(directory_);
  }
  void TearDown() override { std::filesystem::remove_all(directory_); }
  std::filesystem::path directory_;

 private:
  std::string prefix_;
};

inline std::string read_text_file(const std::filesystem::path& path) {
  std::ifstream in(path);
  std::stringstream buffer;
  buffer << in.rdbuf();
  return buffer.str();
}

// A run of the flatland executable: exit code, standard output and standard error.
struct CommandRun {
  int exit_code = -1;
  std::string out;
  std::string err;
};

// Runs `flatland ARGUMENTS` with no input, its output captured in files in `directory`;
// `environment` prefixes the command (e.g. "env -u DISPLAY").
inline CommandRun run_flatland(const std::string& arguments, const std::filesystem::path& directory,
                               const std::string& environment = "") {
  const std::filesystem::path out = directory / "stdout.txt";
  const std::filesystem::path err = directory / "stderr.txt";
  const std::string command = environment + " " + std::string(FLATLAND_BINARY) + " " + arguments + " >" + out.string() +
                              " 2>" + err.string() + " </dev/null";
  const int status = std::system(command.c_str());
  CommandRun result;
  result.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  result.out = read_text_file(out);
  result.err = read_text_file(err);
  return result;
}

// A solver of `scene` with `settings`; a test failure with Solver::create's message when it
// refuses them. The default control variate, auto, runs as none here: these tests check the
// transport's own mechanics and expectations, and those that test the variate ask for coarse (or
// call create_solver for auto's choice).
inline Solver make_solver(const Scene& scene, SolverSettings settings) {
  if (settings.control_variate == ControlVariate::Auto) settings.control_variate = ControlVariate::None;
  Result<Solver> solver = create_solver(scene, settings);
  EXPECT_TRUE(solver.ok()) << (solver.ok() ? "" : solver.error().message);
  return std::move(solver).value();
}

inline Scene scene_from_text(const std::string& text) {
  Result<Scene> scene = parse_scene(text, "test-scene");
  if (!scene) {
    ADD_FAILURE() << scene.error().message;
    return Scene{};
  }
  return std::move(scene).value();
}

inline Scene scene_from_file(const std::string& relative) {
  Result<Scene> scene = load_scene(source_path(relative));
  if (!scene) {
    ADD_FAILURE() << scene.error().message;
    return Scene{};
  }
  return std::move(scene).value();
}

// A unit circle of four cubic arcs (k = 4/3 (sqrt 2 - 1)), counter-clockwise so its front faces
// inward, with one uniform material: the closed form is B = E / (1 - rho) everywhere. Format
// version 2: the closing point is a smooth joint and the storage periodic.
inline std::string circle_enclosure(double reflectivity, double emittance) {
  const double k = 0.5522847498307936;
  char text[1024];
  std::snprintf(text, sizeof text, R"({
    "flatland": 2,
    "materials": {"glow": {"reflectivity": %.17g, "emittance": %.17g}},
    "curves": [{"id": "circle", "material": "glow", "bezier": [
      [1,0],[1,%.17g],[%.17g,1],[0,1],[%.17g,1],[-1,%.17g],[-1,0],
      [-1,%.17g],[%.17g,-1],[0,-1],[%.17g,-1],[1,%.17g],[1,0]]}]})",
                reflectivity, emittance, k, k, -k, k, -k, -k, k, -k);
  return text;
}

// Independent evaluation of a cubic: the explicit Bernstein polynomial in long double.
struct LongVec {
  long double x, y;
};
inline LongVec bernstein_point(const Cubic& c, long double t) {
  const long double s = 1.0L - t;
  const long double w[4] = {s * s * s, 3.0L * s * s * t, 3.0L * s * t * t, t * t * t};
  LongVec r{0.0L, 0.0L};
  for (int i = 0; i < 4; ++i) {
    r.x += w[i] * c.p[i].x;
    r.y += w[i] * c.p[i].y;
  }
  return r;
}

// Upper quantile of the chi-square distribution with k degrees of freedom at significance alpha
// = 1e-4 (Wilson-Hilferty approximation; z = 3.719 is the normal 1 - 1e-4 quantile). A correct
// sampler fails such a test with probability 1e-4; with fixed seeds the outcome is fixed.
inline double chi_square_critical(int k) {
  const double z = 3.719;
  const double a = 2.0 / (9.0 * k);
  return k * std::pow(1.0 - a + z * std::sqrt(a), 3.0);
}

// Pearson's statistic of observed counts against expected counts (bins with tiny expectations
// should be merged by the caller).
inline double chi_square(std::span<const double> observed, std::span<const double> expected) {
  double sum = 0.0;
  for (std::size_t i = 0; i < observed.size(); ++i) {
    const double d = observed[i] - expected[i];
    sum += d * d / expected[i];
  }
  return sum;
}

}  // namespace flatland::testing
