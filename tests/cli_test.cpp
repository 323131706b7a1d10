// The command-line contract: exit codes, one-line errors naming what is wrong, no partial files.
#include <sys/wait.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "test_support.hpp"

namespace flatland {
namespace {

namespace fs = std::filesystem;

using testing::CommandRun;

std::string read_file(const fs::path& path) { return testing::read_text_file(path); }

class Cli : public ::testing::Test {
 protected:
  void SetUp() override {
    directory_ = fs::temp_directory_path() /
                 ("flatland-cli-" + std::string(::testing::UnitTest::GetInstance()->current_test_info()->name()));
    fs::remove_all(directory_);
    fs::create_directories(directory_);
  }
  void TearDown() override { fs::remove_all(directory_); }

  CommandRun run(const std::string& arguments) { return testing::run_flatland(arguments, directory_); }

  std::string scene(const std::string& name) { return testing::source_path("scenes2d/" + name); }
  fs::path directory_;
};

int lines(const std::string& text) {
  int count = 0;
  for (char c : text) count += c == '\n';
  return count;
}

TEST_F(Cli, HelpListsCommandsAndOptions) {
  const CommandRun top = run("--help");
  EXPECT_EQ(top.exit_code, 0);
  for (const char* command : {"solve", "reference", "compare", "converge"})
    EXPECT_NE(top.out.find(command), std::string::npos) << command;
#ifdef FLATLAND_HAVE_VIEWER
  for (const char* command : {"view", "render"}) EXPECT_NE(top.out.find(command), std::string::npos) << command;
  const CommandRun view = run("view --help");
  EXPECT_EQ(view.exit_code, 0);
  for (const char* option : {"--frames", "--screenshot", "--step", "--reference", "--photons", "--basis",
                             "--ray-width", "--keep-paths", "--shaders"})
    EXPECT_NE(view.out.find(option), std::string::npos) << option;
#endif
  const CommandRun solve = run("solve --help");
  EXPECT_EQ(solve.exit_code, 0);
  for (const char* option : {"--photons", "--seed", "--threads", "--basis", "--elements",
                             "--tolerance", "--samples", "--out", "--picture", "--sampling",
                             "--discontinuities", "--estimator"})
    EXPECT_NE(solve.out.find(option), std::string::npos) << option;
}

TEST_F(Cli, BadInputGetsOneLineAndExitCodeTwo) {
  const std::string good = scene("penumbra.json");
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"", "subcommand"},
      {"frobnicate", "frobnicate"},
      {"solve", "scene"},
      {"solve " + good + " --bogus", "--bogus"},
      {"solve " + good + " --photons abc", "--photons"},
      {"solve " + good + " --photons 0", "--photons"},
      {"solve " + good + " --photons 1.5", "--photons"},
      {"solve " + good + " --tolerance nan", "--tolerance"},
      {"solve " + good + " --tolerance 2", "--tolerance"},
      {"solve " + good + " --elements 0", "--elements"},
      {"solve " + good + " --basis quintic", "--basis"},
      {"solve " + good + " --sampling sideways", "--sampling"},
      {"solve " + good + " --estimator magic", "--estimator"},
      {"solve " + good + " --samples -3", "--samples"},
      {"solve " + (directory_ / "missing.json").string(), "missing.json"},
      {"solve " + directory_.string(), directory_.filename().string()},
  };
  for (const auto& [arguments, mentions] : cases) {
    const CommandRun r = run(arguments);
    EXPECT_EQ(r.exit_code, 2) << arguments << "\n" << r.err;
    EXPECT_EQ(lines(r.err), 1) << arguments << "\n" << r.err;
    EXPECT_NE(r.err.find(mentions), std::string::npos) << arguments << "\n" << r.err;
  }
}

TEST_F(Cli, MalformedSceneNamesFileAndLine) {
  const fs::path bad = directory_ / "broken.json";
  std::ofstream(bad) << "{\n  \"flatland\": 1,\n  \"curves\": [ oops ]\n}\n";
  const CommandRun r = run("solve " + bad.string());
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_EQ(lines(r.err), 1) << r.err;
  EXPECT_NE(r.err.find("broken.json:3"), std::string::npos) << r.err;
}

TEST_F(Cli, CompareAgainstAReference) {
  const fs::path a = directory_ / "a.json";
  const fs::path b = directory_ / "b.json";
  const std::string scene_path = scene("penumbra.json");
  ASSERT_EQ(run("solve " + scene_path + " --photons 50000 --seed 1 --samples 40 --quiet --out " + a.string()).exit_code, 0);
  ASSERT_EQ(run("solve " + scene_path + " --photons 50000 --seed 2 --samples 40 --quiet --out " + b.string()).exit_code, 0);
  const CommandRun same = run("compare " + a.string() + " " + a.string());
  EXPECT_EQ(same.exit_code, 0) << same.err;
  EXPECT_NE(same.out.find("(scene)"), std::string::npos);
  EXPECT_NE(same.out.find("0.0000e+00"), std::string::npos);
  const CommandRun differ = run("compare " + a.string() + " " + b.string());
  EXPECT_EQ(differ.exit_code, 0);
  EXPECT_NE(differ.out.find("receiver"), std::string::npos);
  // solve --reference prints the same table.
  const CommandRun with_reference = run("solve " + scene_path + " --photons 50000 --samples 40 --reference " + b.string());
  EXPECT_EQ(with_reference.exit_code, 0) << with_reference.err;
  EXPECT_NE(with_reference.out.find("rel. L2"), std::string::npos);
  // Different sampling: a clear error, exit 2.
  const fs::path c = directory_ / "c.json";
  ASSERT_EQ(run("solve " + scene_path + " --photons 50000 --samples 41 --quiet --out " + c.string()).exit_code, 0);
  const CommandRun mismatch = run("compare " + a.string() + " " + c.string());
  EXPECT_EQ(mismatch.exit_code, 2);
  EXPECT_EQ(lines(mismatch.err), 1) << mismatch.err;
  EXPECT_NE(mismatch.err.find("--samples"), std::string::npos) << mismatch.err;
  const CommandRun missing = run("compare " + a.string() + " " + (directory_ / "none.json").string());
  EXPECT_EQ(missing.exit_code, 2);
  EXPECT_NE(missing.err.find("none.json"), std::string::npos);
}

TEST_F(Cli, ReferenceWritesTheResultFormat) {
  const fs::path ref = directory_ / "ref.json";
  const CommandRun r = run("reference " + scene("penumbra.json") + " --elements 200 --samples 30 --out " + ref.string());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const nlohmann::json result = nlohmann::json::parse(read_file(ref));
  EXPECT_EQ(result["settings"]["method"], "reference");
  EXPECT_GT(result["stats"]["elements"].get<int>(), 0);
  // The linear solve's guaranteed error, and the discretisation error estimated from a second
  // solve: the penumbra's one bounce is reproduced exactly by the final gather, so both are tiny.
  EXPECT_LE(result["stats"]["error_bound"].get<double>(), 1e-10);
  EXPECT_LT(result["stats"]["estimated_error"]["l2"].get<double>(), 1e-9);
  EXPECT_NE(r.out.find("estimated relative error"), std::string::npos) << r.out;
  // converge takes the reference and marks its error floor (here far below the plot: a label).
  const fs::path out = directory_ / "converge";
  const CommandRun converge = run("converge " + scene("penumbra.json") + " --reference " + ref.string() +
                                  " --methods linear --budgets 3000 --seeds 1 --samples 30 --out " + out.string());
  ASSERT_EQ(converge.exit_code, 0) << converge.err;
  EXPECT_NE(read_file(out / "convergence.gp").find("reference error (estimate)"), std::string::npos);
  // A solve with the same samples compares against it.
  const CommandRun solve = run("solve " + scene("penumbra.json") + " --photons 20000 --samples 30 --reference " + ref.string());
  EXPECT_EQ(solve.exit_code, 0) << solve.err;
  EXPECT_NE(solve.out.find("receiver"), std::string::npos);
  const CommandRun bad = run("reference " + scene("penumbra.json") + " --elements 10 --max-element-length 0.1");
  EXPECT_EQ(bad.exit_code, 2);
  EXPECT_EQ(lines(bad.err), 1) << bad.err;
}

TEST_F(Cli, ConvergeWritesTableAndPlots) {
  const fs::path out = directory_ / "convergence";
  const CommandRun r = run("converge " + scene("penumbra.json") +
                           " --methods constant,cubic+sampling=uniform --budgets 2000,8000 --seeds 2 --samples 20 --out " +
                           out.string());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const std::string csv = read_file(out / "convergence.csv");
  EXPECT_EQ(csv.substr(0, csv.find('\n')),
            "method,basis,sampling,discontinuities,estimator,elements,ray_width,ray_mode,ray_profile,"
            "band_rays,tolerance,seed,photons,rounds,unshot,seconds,rel_l1,rel_l2,rel_linf");
  EXPECT_EQ(lines(csv), 1 + 2 * 2 * 2);  // header + methods x budgets x seeds
  EXPECT_NE(csv.find("\"cubic+sampling=uniform\",cubic,uniform"), std::string::npos);
  const std::string png = read_file(out / "convergence.png");
  ASSERT_GT(png.size(), 8u);
  EXPECT_EQ(png.substr(1, 3), "PNG");
  EXPECT_NE(read_file(out / "convergence.svg").find("<svg"), std::string::npos);
  // --replot draws the plot again from the table alone (no solving); a missing table is an error.
  fs::remove(out / "convergence.png");
  const CommandRun replot = run("converge " + scene("penumbra.json") + " --replot --out " + out.string());
  EXPECT_EQ(replot.exit_code, 0) << replot.err;
  EXPECT_EQ(read_file(out / "convergence.png").substr(1, 3), "PNG");
  EXPECT_NE(read_file(out / "convergence.gp").find("2 seeds"), std::string::npos);
  const CommandRun nothing = run("converge " + scene("penumbra.json") + " --replot --out " + (directory_ / "empty").string());
  EXPECT_EQ(nothing.exit_code, 2);
  EXPECT_EQ(lines(nothing.err), 1) << nothing.err;
  const CommandRun bad = run("converge " + scene("penumbra.json") + " --methods cubic+basis=quintic --out " + out.string());
  EXPECT_EQ(bad.exit_code, 2);
  EXPECT_NE(bad.err.find("--methods"), std::string::npos) << bad.err;
}

TEST_F(Cli, FailedWriteLeavesNoFile) {
  const fs::path out = directory_ / "no-such-dir" / "result.json";
  const CommandRun r = run("solve " + scene("penumbra.json") + " --photons 20000 --out " + out.string());
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_FALSE(fs::exists(out));
  EXPECT_NE(r.err.find("no-such-dir"), std::string::npos) << r.err;
}

TEST_F(Cli, SolveWritesResultAndPicture) {
  const fs::path out = directory_ / "result.json";
  const fs::path picture = directory_ / "result.png";
  const CommandRun r = run("solve " + scene("mixed.json") + " --photons 100000 --samples 7 --seed 5 --out " +
                    out.string() + " --picture " + picture.string());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("photons/s"), std::string::npos);
  EXPECT_NE(r.out.find("emitted"), std::string::npos);
  const nlohmann::json result = nlohmann::json::parse(read_file(out));
  EXPECT_EQ(result["flatland_result"], 1);
  EXPECT_EQ(result["settings"]["photons"], 100000);
  EXPECT_EQ(result["settings"]["seed"], 5);
  for (const char* key : {"photons", "rounds", "seconds", "emitted_power", "absorbed_power",
                          "escaped_power", "unshot_power"})
    EXPECT_TRUE(result["stats"].contains(key)) << key;
  const auto& stats = result["stats"];
  EXPECT_NEAR(stats["emitted_power"].get<double>(),
              stats["absorbed_power"].get<double>() + stats["escaped_power"].get<double>() +
                  stats["unshot_power"].get<double>(),
              1e-9 * stats["emitted_power"].get<double>());
  ASSERT_FALSE(result["curves"].empty());
  bool saw_two_sided = false;
  for (const auto& curve : result["curves"]) {
    ASSERT_EQ(curve["samples"].size(), 7u);
    const double length = curve["length"].get<double>();
    const auto& first = curve["samples"][0];
    EXPECT_NEAR(first["s"].get<double>(), 0.5 * length / 7, 1e-12 * length);
    EXPECT_TRUE(first.contains("B"));
    // The stored spline: degree + 1 + coefficients = knots (a clamped B-spline basis).
    ASSERT_TRUE(curve.contains("knots"));
    if (curve.contains("coefficients")) {
      const std::size_t channels = result["scene"]["channels"].get<std::size_t>();
      EXPECT_EQ(curve["knots"].size(),
                curve["coefficients"].size() / channels + curve["degree"].get<std::size_t>() + 1);
    }
    if (curve["sides"] == "both") {
      saw_two_sided = true;
      EXPECT_TRUE(first.contains("B_back"));
    }
  }
  EXPECT_TRUE(saw_two_sided) << "mixed.json should have a two-sided curve";
  // A PNG signature.
  const std::string png = read_file(picture);
  ASSERT_GT(png.size(), 8u);
  EXPECT_EQ(png.substr(1, 3), "PNG");
  // No temporary files left behind.
  int files = 0;
  for (const auto& entry : fs::directory_iterator(directory_)) files += entry.is_regular_file();
  EXPECT_EQ(files, 4);  // result.json, result.png, stdout.txt, stderr.txt
}

}  // namespace
}  // namespace flatland
