// The command-line contract: exit codes, one-line errors naming what is wrong, no partial files.
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <csignal>
#include <vector>

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

class Cli : public testing::ScratchDirectoryTest {
 protected:
  Cli() : ScratchDirectoryTest("flatland-cli") {}

  CommandRun run(const std::string& arguments) { return testing::run_flatland(arguments, directory_); }

  std::string scene(const std::string& name) { return testing::source_path("scenes2d/" + name); }
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
  for (const char* count : {"elements=16x", "elements=99999999999", "band-rays=", "elements=1e3"}) {
    const CommandRun wrong = run("converge " + scene("penumbra.json") + " --methods cubic+" + count + " --out " + out.string());
    EXPECT_EQ(wrong.exit_code, 2) << count;
    EXPECT_NE(wrong.err.find("must be a whole number"), std::string::npos) << wrong.err;
  }
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

// An argument for the shell that run_flatland starts: single-quoted, a quote inside as '\''.
std::string shell_quoted(const std::string& text) {
  std::string out = "'";
  for (const char c : text) out += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return out + "'";
}

// A scene file's name, a scene file's stem and the --out directory reach gnuplot (titles, file
// names). Planted commands of every form that used to run (a backquoted command, a newline and
// then `!cmd` or `system('cmd')`, $(cmd) in the directory, a quote that ended the string) must
// print as text and never run, in a solving converge and in --replot.
TEST_F(Cli, ConvergeNeverRunsCommandsFromScenesOrPaths) {
  const fs::path marker = directory_ / "ran";
  const std::string touch = "touch " + marker.string();
  nlohmann::json scene_json = nlohmann::json::parse(read_file(scene("penumbra.json")));
  scene_json["name"] = "a `" + touch + "` b\n!" + touch + "\nsystem('" + touch + "') @x \" it's ^_{}";
  const fs::path named = directory_ / "named.json";
  std::ofstream(named) << scene_json.dump();
  scene_json.erase("name");  // no name: the file's stem is the title
  // A file name cannot hold the marker's path: this one touches "ran" in the working directory
  // (the test's, or the output directory where gnuplot runs).
  const fs::path stem = directory_ / "`touch ran`.json";
  std::ofstream(stem) << scene_json.dump();
  const fs::path out = directory_ / ("x'$(" + touch + ")'y it's");
  for (const fs::path& scene_file : {named, stem}) {
    const CommandRun r = run("converge " + shell_quoted(scene_file.string()) +
                             " --methods constant --budgets 2000 --seeds 1 --samples 10 --out " +
                             shell_quoted(out.string()));
    ASSERT_EQ(r.exit_code, 0) << r.err;
    EXPECT_FALSE(fs::exists(marker)) << "a planted command ran: " << scene_file;
    EXPECT_FALSE(fs::exists(out / "ran") || fs::exists("ran")) << "a planted command ran: " << scene_file;
    EXPECT_EQ(read_file(out / "convergence.png").substr(1, 3), "PNG") << r.err;
    const CommandRun replot = run("converge " + shell_quoted(scene_file.string()) + " --replot --out " +
                                  shell_quoted(out.string()));
    EXPECT_EQ(replot.exit_code, 0) << replot.err;
    EXPECT_FALSE(fs::exists(marker)) << "a planted command ran in --replot: " << scene_file;
  }
  // A method name read back from the table by --replot goes through the same quoting.
  std::string csv = read_file(out / "convergence.csv");
  csv.replace(csv.find("\"constant\""), 10, "\"k`" + touch + "`' system('" + touch + "')\"");
  std::ofstream(out / "convergence.csv") << csv;
  const CommandRun replot = run("converge " + shell_quoted(named.string()) + " --replot --out " + shell_quoted(out.string()));
  EXPECT_EQ(replot.exit_code, 0) << replot.err;
  EXPECT_FALSE(fs::exists(marker)) << "a planted method name ran";
}

TEST_F(Cli, NumbersBeyondADoubleInAResultAreOneLineErrors) {
  const fs::path a = directory_ / "a.json";
  ASSERT_EQ(run("solve " + scene("penumbra.json") + " --photons 20000 --samples 5 --quiet --out " + a.string()).exit_code, 0);
  std::string text = read_file(a);
  const std::size_t at = text.find("\"emitted_power\": ") + 17;
  text.replace(at, text.find(',', at) - at, "1e400");
  const fs::path big = directory_ / "big.json";
  std::ofstream(big) << text;
  for (const std::string& command :
       {"compare " + big.string() + " " + a.string(),
        "solve " + scene("penumbra.json") + " --photons 20000 --samples 5 --quiet --reference " + big.string(),
        "converge " + scene("penumbra.json") + " --methods constant --budgets 1000 --seeds 1 --samples 5 --reference " +
            big.string() + " --out " + (directory_ / "c").string()}) {
    const CommandRun r = run(command);
    EXPECT_EQ(r.exit_code, 2) << command << "\n" << r.err;
    EXPECT_EQ(lines(r.err), 1) << r.err;
    EXPECT_NE(r.err.find("big.json:"), std::string::npos) << r.err;
    EXPECT_NE(r.err.find("beyond the range of a double"), std::string::npos) << r.err;
  }
}

// Every output path is checked before the work starts: a budget of 1e15 photons would take
// months, so these return at once only if nothing is solved.
TEST_F(Cli, OutputPathsAreCheckedBeforeAnyWork) {
  const std::string missing = (directory_ / "missing" / "r.json").string();
  for (const std::string& command :
       {"solve " + scene("penumbra.json") + " --photons 1e15 --out " + missing,
        "solve " + scene("penumbra.json") + " --photons 1e15 --picture " + (directory_ / "missing" / "r.png").string(),
        "solve " + scene("penumbra.json") + " --photons 1e15 --out " + directory_.string(),
        "reference " + scene("penumbra.json") + " --elements 30000 --out " + missing}) {
    const CommandRun r = run(command);
    EXPECT_EQ(r.exit_code, 2) << command;
    EXPECT_EQ(lines(r.err), 1) << r.err;
  }
  std::ofstream(directory_ / "file") << "x";
  const CommandRun converge = run("converge " + scene("penumbra.json") + " --budgets 1e15 --out " + (directory_ / "file").string());
  EXPECT_EQ(converge.exit_code, 2) << converge.err;
}

// A scene path that is not valid UTF-8 ends up in the result's "file": it is written with the
// invalid bytes replaced (it used to abort after the solve).
TEST_F(Cli, AScenePathThatIsNotUtf8IsWritten) {
  const fs::path odd = directory_ / "bad\xff.json";
  fs::copy_file(scene("penumbra.json"), odd);
  const fs::path out = directory_ / "r.json";
  const CommandRun r = run("solve " + shell_quoted(odd.string()) + " --photons 20000 --samples 5 --quiet --out " + out.string());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const nlohmann::json result = nlohmann::json::parse(read_file(out));
  EXPECT_NE(result["scene"]["file"].get<std::string>().find("bad\xEF\xBF\xBD.json"), std::string::npos);
}

TEST_F(Cli, ResultsTooLargeAndStorageBeyondMemoryAreRefusedAtOnce) {
  // 40 curves x 1e6 samples = 4e7 samples > 1e7: refused before the (1e15-photon) solve.
  nlohmann::json many = {{"flatland", 1}, {"materials", {{"lamp", {{"emittance", 1}}}}}, {"curves", nlohmann::json::array()}};
  for (int i = 0; i < 40; ++i)
    many["curves"].push_back({{"id", "c" + std::to_string(i)}, {"material", "lamp"},
                              {"line", {{i, 0}, {i, 1}}}});
  const fs::path file = directory_ / "many.json";
  std::ofstream(file) << many.dump();
  const CommandRun samples = run("solve " + file.string() + " --photons 1e15 --samples 1000000 --out " +
                                 (directory_ / "r.json").string());
  EXPECT_EQ(samples.exit_code, 2);
  EXPECT_NE(samples.err.find("give at most --samples 250000"), std::string::npos) << samples.err;
}

// Starts `flatland ARGUMENTS...` (no shell), sends `signal` after `delay` seconds, and returns the
// exit code and how long the process took to end after the signal.
struct Stopped {
  int exit_code = -1;
  double seconds_to_stop = 0.0;
};
Stopped run_and_signal(const std::vector<std::string>& arguments, int signal, double delay, const fs::path& directory) {
  std::vector<std::string> words = {FLATLAND_BINARY};
  words.insert(words.end(), arguments.begin(), arguments.end());
  std::vector<char*> argv;
  for (std::string& word : words) argv.push_back(word.data());
  argv.push_back(nullptr);
  const std::string log = (directory / "signal.log").string();
  const pid_t child = ::fork();
  if (child == 0) {
    std::FILE* sink = std::freopen(log.c_str(), "w", stderr);
    (void)sink;
    ::execv(argv[0], argv.data());
    ::_exit(127);
  }
  ::usleep(static_cast<useconds_t>(delay * 1e6));
  const auto sent = std::chrono::steady_clock::now();
  ::kill(child, signal);
  int status = 0;
  ::waitpid(child, &status, 0);
  Stopped stopped;
  stopped.seconds_to_stop = std::chrono::duration<double>(std::chrono::steady_clock::now() - sent).count();
  stopped.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return stopped;
}

// Ctrl-C and SIGTERM stop long work within about a second, with exit code 130 and nothing
// written: the reference (which used to ignore both and run for hours) and a solve.
TEST_F(Cli, InterruptsStopLongWorkAndWriteNothing) {
  const fs::path out = directory_ / "r.json";
  const struct {
    std::vector<std::string> arguments;
    int signal;
  } runs[] = {
      {{"reference", scene("default.json"), "--elements", "6000", "--out", out.string()}, SIGINT},
      {{"reference", scene("default.json"), "--elements", "6000", "--out", out.string()}, SIGTERM},
      {{"solve", scene("default.json"), "--photons", "1e12", "--out", out.string()}, SIGINT},
      {{"converge", scene("default.json"), "--budgets", "1e12", "--out", (directory_ / "c").string()}, SIGINT},
  };
  for (const auto& r : runs) {
    const Stopped stopped = run_and_signal(r.arguments, r.signal, 1.0, directory_);
    EXPECT_EQ(stopped.exit_code, 130) << r.arguments[0] << ": " << read_file(directory_ / "signal.log");
    EXPECT_LT(stopped.seconds_to_stop, 2.0) << r.arguments[0];
    EXPECT_FALSE(fs::exists(out)) << r.arguments[0];
    EXPECT_FALSE(fs::exists(directory_ / "c" / "convergence.csv"));
    EXPECT_NE(read_file(directory_ / "signal.log").find("nothing written"), std::string::npos)
        << read_file(directory_ / "signal.log");
  }
}

}  // namespace
}  // namespace flatland
