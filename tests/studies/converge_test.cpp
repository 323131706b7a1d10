#include "flatland/studies/converge.hpp"

#include <cmath>
#include <string>

#include <gtest/gtest.h>

#include "flatland/reference/coarse_answer.hpp"
#include "test_support.hpp"

namespace flatland {
namespace {

// A study makes auto's choice once per method, at its largest budget: the same choice as
// control_variate_auto_skip at that budget, whatever budget the method's own settings hold, and a
// method that names its variate keeps it. (The command line and the Python module both take it from
// here, so their rows cannot differ; test_converge_gives_the_rows_of_the_command_line compares them.)
TEST(Converge, ChoosesAutosVariateAtTheLargestBudget) {
  const Scene room = testing::scene_from_file("scenes2d/curved_room.json");
  SolverSettings settings;
  settings.photons = 10'000;
  settings.elements = 16 * 1024;  // a set-up above auto's bound at small budgets
  std::string skipped;
  EXPECT_EQ(converge_variate(room, settings, 10'000, skipped), ControlVariate::None);
  EXPECT_NE(skipped.find("point-chord pairs"), std::string::npos) << skipped;
  // The budget at which the bound allows the set-up, from the work it counts.
  const auto enough =
      static_cast<std::uint64_t>(std::ceil(control_variate_work(room, settings) / kAutoControlVariateWorkPerPhoton));
  EXPECT_EQ(converge_variate(room, settings, enough, skipped), ControlVariate::Coarse);
  EXPECT_EQ(skipped, "");
  EXPECT_EQ(settings.photons, 10'000u);  // the method's settings are not changed
  // Auto's refusals by the settings hold at any budget; a named variate is kept.
  SolverSettings walks = settings;
  walks.elements = 16;
  walks.transport = Transport::Walk;
  EXPECT_EQ(converge_variate(room, walks, enough, skipped), ControlVariate::None);
  EXPECT_NE(skipped.find("walk"), std::string::npos) << skipped;
  for (ControlVariate named : {ControlVariate::None, ControlVariate::Coarse}) {
    settings.control_variate = named;
    EXPECT_EQ(converge_variate(room, settings, 10'000, skipped), named);
    EXPECT_EQ(skipped, "");
  }
}

}  // namespace
}  // namespace flatland
