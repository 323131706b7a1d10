// Every option of a solve, declared once: its name in the core's messages, how the command line
// and Python spell it, what it accepts, its default and its help. The command line (CLI11's
// options), the Python keywords, converge's method keys and the viewer's controls are all made
// from this table, and every value they take goes through set_solve_option, so the four front
// ends accept the same values and refuse the same ones with the same words.
#pragma once

#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "flatland/base/status.hpp"
#include "flatland/transport/settings.hpp"

namespace flatland {

enum class SolveOption {
  Photons,
  Seed,
  Threads,
  Basis,
  Elements,
  Sampling,
  Discontinuities,
  Estimator,
  Sampler,
  Transport,
  WalkScore,
  Gather,
  Importance,
  ControlVariate,
  RayWidth,
  RayProfile,
  RayMode,
  BandRays,
  Tolerance,
  Replicates,
  ReplicateLayout,
  Confidence,
  TargetError,
};

struct SolveOptionSpec {
  SolveOption option;
  std::string_view name;     // in the core's messages: "ray width"
  std::string_view flag;     // on the command line (--ray-width) and in converge's methods (ray-width=)
  std::string_view keyword;  // in Python: ray_width
  // The names it accepts when it takes one of a list (empty: it takes a number; elements takes
  // "auto" or a number).
  std::vector<std::string_view> choices;
  std::string_view value;  // what a number stands for in the help (N, W, X); empty for choices
  std::string_view help;
  // Whether a converge method may set it (photons, seed and threads belong to the study).
  bool per_method = true;
};

// The options in the order the command line's help lists them.
std::span<const SolveOptionSpec> solve_options();
const SolveOptionSpec& spec_of(SolveOption option);
// The option whose flag (or Python keyword) this is; nullopt for none.
std::optional<SolveOption> option_by_flag(std::string_view flag);
std::optional<SolveOption> option_by_keyword(std::string_view keyword);

// Sets `option` in `settings` from its text, as typed on the command line or in a converge method
// (a Python value converted to text: an int's digits, a float's shortest round-trip form, a
// string as it is). The error names the option ("ray width: must be ..."), says what it accepts
// and, for a name that is not one of its choices, the likely one meant.
Status set_solve_option(SolverSettings& settings, SolveOption option, std::string_view text);
// The option's value in `settings` as set_solve_option reads it ("cubic", "auto", "0.05").
std::string solve_option_text(const SolverSettings& settings, SolveOption option);

// How a front end names options in the messages it shows.
enum class Spelling { CommandLine, Python };
// `message` as a front end shows it: a leading option name ("ray width: ...") becomes the front
// end's spelling ("--ray-width: ...", "ray_width: ..."); any other message is unchanged.
std::string spelled(std::string_view message, Spelling spelling);

// A photon count as --photons and converge's budgets take it: a whole number in [1, kMaxPhotons]
// written as digits or in exponent form ("250000", "1e6", "2.5e5"); the error names `name`.
Result<std::uint64_t> parse_photon_count(std::string_view text, std::string_view name);
// A seed: decimal digits, 0 .. 2^64 - 1 (a sign, an exponent or more is refused, not wrapped).
Result<std::uint64_t> parse_seed(std::string_view text, std::string_view name);

}  // namespace flatland
