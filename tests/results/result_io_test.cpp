// Result files: reading them back with errors that name the line, writing every output all or
// nothing, and the checks made before any work starts.
#include "flatland/results/result_io.hpp"

#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "test_support.hpp"

namespace flatland {
namespace {

namespace fs = std::filesystem;

class ResultIo : public testing::ScratchDirectoryTest {
 protected:
  ResultIo() : ScratchDirectoryTest("flatland-result-io") {}
  std::vector<std::string> files() const {
    std::vector<std::string> names;
    for (const auto& entry : fs::directory_iterator(directory_)) names.push_back(entry.path().filename().string());
    std::sort(names.begin(), names.end());
    return names;
  }
};

TEST(ResultParse, ReadsAResult) {
  Result<nlohmann::json> doc = parse_result(R"({"flatland_result": 1, "curves": []})", "r.json");
  ASSERT_TRUE(doc.ok()) << doc.error().message;
  EXPECT_TRUE((*doc)["curves"].is_array());
}

// nlohmann::json throws out_of_range for 1e400 with no position; it used to abort compare.
TEST(ResultParse, NumbersBeyondADoubleAreErrorsWithLineAndColumn) {
  const std::string text = "{\"flatland_result\": 1,\n \"stats\": {\"emitted_power\": 1e400}}";
  Result<nlohmann::json> doc = parse_result(text, "big.json");
  ASSERT_FALSE(doc.ok());
  EXPECT_EQ(doc.error().message.rfind("big.json:2:29: ", 0), 0u) << doc.error().message;
  EXPECT_NE(doc.error().message.find("beyond the range of a double"), std::string::npos);
}

TEST(ResultParse, MalformedDocumentsAreOneLineErrors) {
  const struct {
    const char* text;
    const char* expected;
  } cases[] = {
      {"{\"flatland_result\": 1,\n  oops}", "r.json:2:3: not valid JSON"},
      {"[1, 2]", "r.json: not a flatland result"},
      {"{\"flatland\": 1}", "r.json: not a flatland result"},
      {"{\"flatland_result\": 2}", "r.json: unsupported result version 2"},
      {"", "r.json:1:1: not valid JSON"},
  };
  for (const auto& c : cases) {
    Result<nlohmann::json> doc = parse_result(c.text, "r.json");
    ASSERT_FALSE(doc.ok()) << c.text;
    EXPECT_EQ(doc.error().message.rfind(c.expected, 0), 0u) << doc.error().message;
    EXPECT_EQ(doc.error().message.find('\n'), std::string::npos) << doc.error().message;
  }
}

// A scene file's name can be any bytes; the result stores it, and dumping invalid UTF-8 threw
// (type_error 316) after the whole solve.
TEST(ResultText, InvalidUtf8IsReplacedNotFatal) {
  const nlohmann::json document = {{"file", std::string("bad\xff\xfe.json")}};
  const std::string text = json_text(document);
  EXPECT_EQ(text.back(), '\n');
  const nlohmann::json back = nlohmann::json::parse(text);
  EXPECT_EQ(back["file"].get<std::string>(), "bad\xEF\xBF\xBD\xEF\xBF\xBD.json");  // two U+FFFD
}

// result_text writes the curves one at a time; its text is json_text(result_to_json(..)) byte for
// byte, on every shipped scene (one-sided and two-sided curves, colour, closed curves, emitters
// with a profile) and with the spline of each kind of storage.
TEST(ResultText, StreamedTextIsTheDocumentsText) {
  std::vector<std::string> paths;
  for (const auto& entry : fs::directory_iterator(testing::source_path("scenes2d")))
    if (entry.path().extension() == ".json") paths.push_back(entry.path().string());
  paths.push_back(testing::source_path("scenes2d/tests/reference_ring_profile.json"));
  std::sort(paths.begin(), paths.end());
  ASSERT_GE(paths.size(), 9u);
  for (const std::string& path : paths) {
    Result<Scene> scene = load_scene(path);
    ASSERT_TRUE(scene.ok()) << scene.error().message;
    for (BasisKind basis : {BasisKind::Cubic, BasisKind::Constant, BasisKind::Hermite}) {
      SolverSettings settings;
      settings.photons = 20'000;
      settings.threads = 1;
      settings.basis = basis;
      Result<Solver> solver = Solver::create(*scene, settings);
      ASSERT_TRUE(solver.ok()) << solver.error().message;
      solver->run();
      for (int samples : {1, 7}) {
        const std::string text = result_text(*solver, samples);
        EXPECT_EQ(text, json_text(result_to_json(*solver, samples))) << path << " " << to_string(basis);
        EXPECT_EQ(text.back(), '\n');
      }
    }
  }
}

// Past 64 curves result_text reserves room for the rest from the numbers they write: on a scene
// whose first curves are long (many knots, coefficients) and the rest short, the text is still
// the document's, and the room reserved stays near what it needs.
TEST(ResultText, ManyCurvesOfMixedSizes) {
  std::string text = R"({"flatland": 2, "materials": {"wall": {"reflectivity": 0.5},
    "lamp": {"reflectivity": 0, "emittance": 1}}, "curves": [
    {"id": "room", "material": "wall", "line": [[0,0],[100,0],[100,100],[0,100],[0,0]]},
    {"id": "lamp", "material": "lamp", "line": [[60,99],[40,99]]})";
  for (int k = 0; k < 300; ++k) {
    const double x = 2.0 + 6.0 * (k % 16);
    const double y = 2.0 + 5.0 * (k / 16);
    std::string points = "[" + std::to_string(x) + "," + std::to_string(y) + "]";
    const int segments = k < 64 ? 64 : 1;
    for (int i = 1; i <= segments; ++i)
      points += ",[" + std::to_string(x + 4.0 * i / segments) + "," + std::to_string(y + (i % 2) * 0.5) + "]";
    text += ",{\"id\": \"c" + std::to_string(k) + "\", \"material\": \"wall\", \"sides\": \"both\", \"line\": [" +
            points + "]}";
  }
  const Scene scene = testing::scene_from_text(text + "]}");
  ASSERT_EQ(scene.curves.size(), 302u);
  SolverSettings settings;
  settings.photons = 50'000;
  settings.threads = 1;
  Result<Solver> solver = Solver::create(scene, settings);
  ASSERT_TRUE(solver.ok()) << solver.error().message;
  solver->run();
  const std::string streamed = result_text(*solver, 1);
  EXPECT_EQ(streamed, json_text(result_to_json(*solver, 1)));
  EXPECT_LE(streamed.capacity(), 2 * streamed.size());
}

// The bound of a result's size holds for real results (grey, colour, two-sided, emitters) and is
// not loose by more than a factor of three; a result past what flatland reads back is refused with
// the largest --samples that fits.
TEST(ResultSize, TheSampleBoundHoldsAndRefusesWhatCouldNotBeReadBack) {
  for (const char* file : {"scenes2d/penumbra.json", "scenes2d/default.json", "scenes2d/arch.json"}) {
    SCOPED_TRACE(file);
    const Scene scene = testing::scene_from_file(file);
    SolverSettings settings;
    settings.photons = 20'000;
    settings.threads = 1;
    Result<Solver> solver = Solver::create(scene, settings);
    ASSERT_TRUE(solver.ok()) << solver.error().message;
    solver->run();
    // The samples' share of the text: what 200 samples a curve add over 10.
    const double real = static_cast<double>(result_text(*solver, 200).size() - result_text(*solver, 10).size());
    const double bound = result_sample_bytes(scene, 200) - result_sample_bytes(scene, 10);
    EXPECT_LE(real, bound);
    EXPECT_GE(real, bound / 3.0);
  }
  const Scene scene = testing::scene_from_text(testing::circle_enclosure(0.5, 1.0));
  EXPECT_TRUE(check_result_size(scene, 1'000'000).ok());
  const Status status = check_result_size(scene, 20'000'000);
  ASSERT_FALSE(status.ok());
  const std::string& message = status.error().message;
  const std::size_t at = message.find("give at most ");
  ASSERT_NE(at, std::string::npos) << message;
  const int fits = std::atoi(message.c_str() + at + 12);
  EXPECT_LE(result_sample_bytes(scene, fits), static_cast<double>(kMaxInputBytes));
  EXPECT_GT(result_sample_bytes(scene, fits + 1), static_cast<double>(kMaxInputBytes));
  EXPECT_TRUE(check_result_size(scene, fits).ok());
  EXPECT_FALSE(check_result_size(scene, fits + 1).ok());
}

}  // namespace
}  // namespace flatland
