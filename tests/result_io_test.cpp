// Result files: reading them back with errors that name the line, writing every output all or
// nothing, and the checks made before any work starts.
#include "flatland/result_io.hpp"

#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <filesystem>
#include <fstream>
#include <vector>
#include <string>

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

TEST_F(ResultIo, OutputPathsAreCheckedBeforeWork) {
  EXPECT_TRUE(check_output_file((directory_ / "r.json").string()).ok());
  const Status missing = check_output_file((directory_ / "no" / "r.json").string());
  ASSERT_FALSE(missing.ok());
  EXPECT_NE(missing.error().message.find("does not exist"), std::string::npos) << missing.error().message;
  const Status directory = check_output_file(directory_.string());
  ASSERT_FALSE(directory.ok());
  EXPECT_NE(directory.error().message.find("is a directory"), std::string::npos);
  EXPECT_FALSE(check_output_file("").ok());
  EXPECT_TRUE(files().empty());  // checking writes nothing
}

TEST_F(ResultIo, StagedFilesAppearOnlyOnCommit) {
  {
    OutputFiles outputs;
    ASSERT_TRUE(outputs.stage((directory_ / "a.json").string(), "{}\n").ok());
    ASSERT_TRUE(outputs.stage((directory_ / "b.png").string(), "png").ok());
    EXPECT_FALSE(fs::exists(directory_ / "a.json"));
    EXPECT_EQ(files().size(), 2u);  // two temporaries
  }
  // Dropped without a commit (an interrupt, an error): nothing is left, not even temporaries.
  EXPECT_TRUE(files().empty());
  OutputFiles outputs;
  ASSERT_TRUE(outputs.stage((directory_ / "a.json").string(), "{}\n").ok());
  ASSERT_TRUE(outputs.stage((directory_ / "b.png").string(), "png").ok());
  ASSERT_TRUE(outputs.commit().ok());
  EXPECT_EQ(files(), (std::vector<std::string>{"a.json", "b.png"}));
  EXPECT_EQ(testing::read_text_file(directory_ / "b.png"), "png");
}

// SIGKILL during a write leaves .NAME.tmpPID-RANDOM behind; the next write of NAME removes those
// whose process is gone, and leaves a running process's alone.
TEST_F(ResultIo, StaleTemporariesOfDeadProcessesAreRemoved) {
  const pid_t child = ::fork();
  if (child == 0) ::_exit(0);
  int status = 0;
  ::waitpid(child, &status, 0);  // `child` now names no process
  const std::string dead = ".r.json.tmp" + std::to_string(child) + "-12345";
  const std::string alive = ".r.json.tmp" + std::to_string(::getppid()) + "-777";
  const std::string other = ".s.json.tmp" + std::to_string(child) + "-1";  // another target's
  for (const std::string& name : {dead, alive, other}) std::ofstream(directory_ / name) << "partial";
  ASSERT_TRUE(write_file_atomically((directory_ / "r.json").string(), "{}\n").ok());
  EXPECT_EQ(files(), (std::vector<std::string>{alive, other, "r.json"}));
}

TEST(ResultSize, TooManySamplesAreRefusedWithTheLargestThatFits) {
  const Scene scene = testing::scene_from_text(testing::circle_enclosure(0.5, 1.0));
  EXPECT_TRUE(check_result_size(scene, 1'000'000).ok());
  const Status status = check_result_size(scene, 20'000'000);
  ASSERT_FALSE(status.ok());
  EXPECT_NE(status.error().message.find("give at most --samples 10000000"), std::string::npos)
      << status.error().message;
}

}  // namespace
}  // namespace flatland
