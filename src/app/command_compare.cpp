// flatland compare: errors of a result against a reference along arc length.
#include <cstdio>

#include "app/commands.hpp"
#include "flatland/result_io.hpp"

namespace flatland::app {

void print_comparison(const Comparison& comparison) {
  std::printf("%-24s %12s %12s %12s\n", "curve", "rel. L1", "rel. L2", "rel. Linf");
  for (const CurveError& curve : comparison.curves)
    std::printf("%-24s %12.4e %12.4e %12.4e\n", curve.id.c_str(), curve.norms.l1, curve.norms.l2,
                curve.norms.linf);
  std::printf("%-24s %12.4e %12.4e %12.4e\n", "(scene)", comparison.scene.l1, comparison.scene.l2,
              comparison.scene.linf);
}

CLI::App* add_compare_command(CLI::App& parent, CompareOptions& o) {
  CLI::App* cmd = parent.add_subcommand(
      "compare",
      "Relative L1, L2 and L-infinity errors of B along arc length, per curve and for the scene, "
      "of RESULT against REFERENCE (both written by 'flatland solve --out' with the same --samples)");
  cmd->add_option("result", o.result, "The result to judge (JSON)")->required();
  cmd->add_option("reference", o.reference, "The reference result (JSON)")->required();
  return cmd;
}

int run_compare(const CompareOptions& o) {
  Result<nlohmann::json> result = read_result_file(o.result);
  if (!result) {
    std::fprintf(stderr, "flatland: error: %s\n", result.error().message.c_str());
    return kExitUsage;
  }
  Result<nlohmann::json> reference = read_result_file(o.reference);
  if (!reference) {
    std::fprintf(stderr, "flatland: error: %s\n", reference.error().message.c_str());
    return kExitUsage;
  }
  Result<Comparison> comparison = compare_results(*result, *reference);
  if (!comparison) {
    std::fprintf(stderr, "flatland: error: %s and %s: %s\n", o.result.c_str(), o.reference.c_str(),
                 comparison.error().message.c_str());
    return kExitUsage;
  }
  print_comparison(*comparison);
  return kExitOk;
}

}  // namespace flatland::app
