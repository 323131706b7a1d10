// The solve options' one table (options.hpp): every front end's names, values and messages.
#include "flatland/transport/options.hpp"

#include <set>
#include <string>
#include <vector>

#include <gtest/gtest.h>

namespace flatland {
namespace {

// Each choice sets the enum value whose to_string is that very name, and reads back as it: the
// table's lists follow the enums' order.
TEST(Options, EveryChoiceSetsTheValueOfItsName) {
  for (const SolveOptionSpec& spec : solve_options()) {
    for (const std::string_view choice : spec.choices) {
      SolverSettings settings;
      ASSERT_TRUE(set_solve_option(settings, spec.option, choice).ok()) << spec.name << " " << choice;
      EXPECT_EQ(solve_option_text(settings, spec.option), choice) << spec.name;
      std::string named;
      switch (spec.option) {
        case SolveOption::Basis: named = to_string(settings.basis); break;
        case SolveOption::Sampling: named = to_string(settings.sampling); break;
        case SolveOption::Discontinuities: named = to_string(settings.discontinuities); break;
        case SolveOption::Estimator: named = to_string(settings.estimator); break;
        case SolveOption::Sampler: named = to_string(settings.sampler); break;
        case SolveOption::Transport: named = to_string(settings.transport); break;
        case SolveOption::WalkScore: named = to_string(settings.walk_score); break;
        case SolveOption::Gather: named = to_string(settings.gather); break;
        case SolveOption::ControlVariate: named = to_string(settings.control_variate); break;
        case SolveOption::RayProfile: named = to_string(settings.ray_profile); break;
        case SolveOption::RayMode: named = to_string(settings.ray_mode); break;
        case SolveOption::ReplicateLayout: named = to_string(settings.replicate_layout); break;
        default: FAIL() << spec.name << " has choices but no enum";
      }
      EXPECT_EQ(named, choice) << spec.name;
    }
  }
}

// The defaults' text reads back as the defaults, and the names, flags and keywords are unique.
TEST(Options, DefaultsReadBackAndNamesAreUnique) {
  const SolverSettings defaults;
  SolverSettings read;
  read.photons = 7;
  read.seed = 9;
  read.basis = BasisKind::Constant;
  read.ray_width = 3.0;
  std::set<std::string_view> names, flags, keywords;
  for (const SolveOptionSpec& spec : solve_options()) {
    ASSERT_TRUE(set_solve_option(read, spec.option, solve_option_text(defaults, spec.option)).ok()) << spec.name;
    EXPECT_TRUE(names.insert(spec.name).second) << spec.name;
    EXPECT_TRUE(flags.insert(spec.flag).second) << spec.flag;
    EXPECT_TRUE(keywords.insert(spec.keyword).second) << spec.keyword;
    EXPECT_EQ(option_by_flag(spec.flag), spec.option);
    EXPECT_EQ(option_by_keyword(spec.keyword), spec.option);
    EXPECT_EQ(spec_of(spec.option).name, spec.name);
    // A number has a letter for the help, a list has its names; every option has its help.
    EXPECT_NE(spec.value.empty(), spec.choices.empty()) << spec.name;
    EXPECT_GT(spec.help.size(), 20u) << spec.name;
  }
  EXPECT_EQ(read.photons, defaults.photons);
  EXPECT_EQ(solve_option_text(defaults, SolveOption::Photons), "1e6");
  EXPECT_EQ(read.seed, defaults.seed);
  EXPECT_EQ(read.basis, defaults.basis);
  EXPECT_EQ(read.ray_width, defaults.ray_width);
  EXPECT_EQ(read.elements, kAutoElements);
  EXPECT_FALSE(option_by_flag("ray_width").has_value());
}

// Importance takes curve ids separated by commas, each once; empty text names none.
TEST(Options, ImportanceTakesCurveIdsOnce) {
  SolverSettings s;
  ASSERT_TRUE(set_solve_option(s, SolveOption::Importance, "desk,left floor").ok());
  EXPECT_EQ(s.importance, (std::vector<std::string>{"desk", "left floor"}));
  EXPECT_EQ(solve_option_text(s, SolveOption::Importance), "desk,left floor");
  for (const char* bad : {",desk", "desk,", "desk,,floor", "desk,desk"}) {
    const Status status = set_solve_option(s, SolveOption::Importance, bad);
    ASSERT_FALSE(status) << bad;
    EXPECT_EQ(status.error().message.rfind("importance: ", 0), 0u) << status.error().message;
  }
  EXPECT_EQ(s.importance.size(), 2u);  // a refused value leaves the setting as it was
  ASSERT_TRUE(set_solve_option(s, SolveOption::Importance, "").ok());
  EXPECT_TRUE(s.importance.empty());
  EXPECT_EQ(spelled("importance: s.json has no curve 'x'", Spelling::CommandLine),
            "--importance: s.json has no curve 'x'");
}

// Numbers read back exactly as written; bad values name the option in the core's words, and each
// front end spells the name its own way.
TEST(Options, ValuesReadBackAndErrorsNameTheOption) {
  SolverSettings s;
  for (const char* width : {"0.05", "1e-07", "0.1", "3"}) {
    ASSERT_TRUE(set_solve_option(s, SolveOption::RayWidth, width).ok());
    EXPECT_EQ(solve_option_text(s, SolveOption::RayWidth), width);
  }
  ASSERT_TRUE(set_solve_option(s, SolveOption::Photons, "2.5e5").ok());
  EXPECT_EQ(s.photons, 250'000u);
  EXPECT_EQ(solve_option_text(s, SolveOption::Photons), "250000");
  ASSERT_TRUE(set_solve_option(s, SolveOption::Seed, "18446744073709551615").ok());
  EXPECT_EQ(s.seed, 18446744073709551615ull);
  const struct {
    SolveOption option;
    const char* text;
    const char* core;
  } bad[] = {
      {SolveOption::RayWidth, "-1", "ray width: "},
      {SolveOption::RayWidth, "nan", "ray width: "},
      {SolveOption::Photons, "0", "photons: "},
      {SolveOption::Photons, "1.5", "photons: "},
      {SolveOption::Photons, "1e16", "photons: "},
      {SolveOption::Seed, "-1", "seed: "},
      {SolveOption::Seed, "18446744073709551616", "seed: "},
      {SolveOption::Seed, "1e3", "seed: "},
      {SolveOption::Threads, "1025", "threads: "},
      {SolveOption::Elements, "0", "elements: "},
      {SolveOption::Elements, "65537", "elements: "},
      {SolveOption::BandRays, "257", "band rays: "},
      {SolveOption::Tolerance, "1", "tolerance: "},
      {SolveOption::Basis, "cubik", "basis: "},
  };
  for (const auto& b : bad) {
    const Status status = set_solve_option(s, b.option, b.text);
    ASSERT_FALSE(status.ok()) << b.text;
    EXPECT_EQ(status.error().message.rfind(b.core, 0), 0u) << status.error().message;
  }
  const std::string message = set_solve_option(s, SolveOption::Basis, "cubik").error().message;
  EXPECT_NE(message.find("did you mean 'cubic'"), std::string::npos) << message;
  const std::string wide = set_solve_option(s, SolveOption::RayWidth, "-1").error().message;
  EXPECT_EQ(spelled(wide, Spelling::CommandLine).rfind("--ray-width: ", 0), 0u);
  EXPECT_EQ(spelled(wide, Spelling::Python).rfind("ray_width: ", 0), 0u);
  EXPECT_EQ(spelled("scene.json: no curves", Spelling::CommandLine), "scene.json: no curves");
  EXPECT_EQ(spelled("max element length: must be", Spelling::CommandLine), "--max-element-length: must be");
}

}  // namespace
}  // namespace flatland
