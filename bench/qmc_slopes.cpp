// Error against photons for the pseudo-random and the Sobol' (RQMC) samplers, on two scenes whose
// expected coefficients are known in closed form, so that only the Monte Carlo error is measured
// (not the storage mesh's bias):
//  - direct light: a line lamp over a floor with a black occluder between them (a penumbra); the
//    floor's coefficients after the first round against rho integral(phi_k H ds) / integral(phi_k
//    ds), H the closed-form irradiance;
//  - many bounces: a closed circular enclosure (four cubics) of rho = 0.9 emitting E = 1
//    everywhere, B = E / (1 - rho), run to a tolerance of 1e-4 (about 90 bounces).
// Prints, per scene, method and budget, the RMS over seeds of the relative L2 error of the
// reflected coefficients (weighted by the basis functions' lengths), and the fitted slope of
// log RMS against log photons.
//
//   flatland_qmc_slopes [seeds=8] [largest budget=1e7]
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include "flatland/scene/scene.hpp"
#include "flatland/transport/solver.hpp"

using namespace flatland;

namespace {

const char* kPenumbra = R"({"flatland": 1, "materials": {"lamp": {"emittance": 1}, "black": {},
  "floor": {"reflectivity": 0.5}}, "curves": [
  {"id": "lamp", "material": "lamp", "line": [[0.5,2],[-0.5,2]]},
  {"id": "floor", "material": "floor", "line": [[-3,0],[3,0]]},
  {"id": "occluder", "material": "black", "sides": "both", "line": [[-0.2,1],[0.6,1]]}]})";

double penumbra_irradiance(double x) {
  auto sine = [x](double px, double py) { return (px - x) / std::hypot(px - x, py); };
  const double a = sine(-0.5, 2.0);
  const double b = sine(0.5, 2.0);
  double visible = b - a;
  const double c = std::max(a, sine(-0.2, 1.0));
  const double d = std::min(b, sine(0.6, 1.0));
  if (d > c) visible -= d - c;
  return 0.5 * visible;
}

std::string enclosure(double rho) {
  const double k = 0.5522847498307936;
  char text[1024];
  std::snprintf(text, sizeof text, R"({"flatland": 2,
    "materials": {"glow": {"reflectivity": %.17g, "emittance": 1}},
    "curves": [{"id": "circle", "material": "glow", "bezier": [
      [1,0],[1,%.17g],[%.17g,1],[0,1],[%.17g,1],[-1,%.17g],[-1,0],
      [-1,%.17g],[%.17g,-1],[0,-1],[%.17g,-1],[1,%.17g],[1,0]]}]})",
                rho, k, k, -k, k, -k, -k, k, -k);
  return text;
}

struct Method {
  const char* name;
  BasisKind basis;
  PositionSampling sampling;
};

double slope(const std::vector<double>& x, const std::vector<double>& y) {
  const auto n = static_cast<double>(x.size());
  double mx = 0, my = 0;
  for (std::size_t i = 0; i < x.size(); ++i) {
    mx += std::log(x[i]) / n;
    my += std::log(y[i]) / n;
  }
  double sxy = 0, sxx = 0;
  for (std::size_t i = 0; i < x.size(); ++i) {
    sxy += (std::log(x[i]) - mx) * (std::log(y[i]) - my);
    sxx += (std::log(x[i]) - mx) * (std::log(x[i]) - mx);
  }
  return sxy / sxx;
}

}  // namespace

int main(int argc, char** argv) {
  const int seeds = argc > 1 ? std::atoi(argv[1]) : 8;
  const double largest = argc > 2 ? std::atof(argv[2]) : 1e7;
  const Method methods[] = {{"cubic", BasisKind::Cubic, PositionSampling::Reconstructed},
                            {"classic", BasisKind::Constant, PositionSampling::Uniform}};
  for (int scene_index = 0; scene_index < 2; ++scene_index) {
    const bool direct = scene_index == 0;
    Result<Scene> loaded = parse_scene(direct ? std::string(kPenumbra) : enclosure(0.9), "measure");
    if (!loaded) {
      std::fprintf(stderr, "%s\n", loaded.error().message.c_str());
      return 1;
    }
    const Scene scene = std::move(loaded).value();
    const std::uint32_t curve = direct ? 1 : 0;
    for (const Method& method : methods) {
      for (SamplerKind sampler : {SamplerKind::Random, SamplerKind::Sobol}) {
        std::vector<double> budgets;
        std::vector<double> errors;
        for (double n = direct ? 1e4 : 1e6; n <= largest * 1.0001; n *= direct ? 10.0 : std::sqrt(10.0)) {
          double sum = 0.0;
          for (int seed = 1; seed <= seeds; ++seed) {
            SolverSettings settings;
            settings.photons = static_cast<std::uint64_t>(n);
            settings.seed = static_cast<std::uint64_t>(seed);
            settings.basis = method.basis;
            settings.sampling = method.sampling;
            settings.estimator = Estimator::Lumped;
            settings.sampler = sampler;
            settings.tolerance = direct ? 1e-3 : 1e-4;
            Result<Solver> created = Solver::create(scene, settings);
            if (!created) {
              std::fprintf(stderr, "%s\n", created.error().message.c_str());
              return 1;
            }
            Solver solver = std::move(created).value();
            if (direct)
              solver.step_round();
            else
              solver.run();
            const CurveStorage& storage = solver.storage(curve);
            const std::vector<double> b = solver.radiosity_coefficients(curve, Side::Front);
            std::vector<double> expected(b.size(), 0.0);
            if (direct) {
              const int steps = 200'000;
              std::array<double, SplineBasis::kMaxDegree + 1> phi{};
              for (int i = 0; i < steps; ++i) {
                const double u = (i + 0.5) / steps;
                const double h = penumbra_irradiance(-3.0 + 6.0 * u);
                const std::size_t first = storage.basis.evaluate(u, phi.data());
                for (int j = 0; j <= storage.basis.degree(); ++j)
                  expected[first + static_cast<std::size_t>(j)] += phi[static_cast<std::size_t>(j)] * h * 6.0 / steps;
              }
              for (std::size_t k = 0; k < b.size(); ++k) expected[k] *= 0.5 / storage.basis_length[k];
            } else {
              for (double& e : expected) e = 0.9 / (1.0 - 0.9);
            }
            double error = 0.0, norm = 0.0;
            for (std::size_t k = 0; k < b.size(); ++k) {
              error += storage.basis_length[k] * (b[k] - expected[k]) * (b[k] - expected[k]);
              norm += storage.basis_length[k] * expected[k] * expected[k];
            }
            sum += error / norm;
            if (seed == 1 && n == (direct ? 1e4 : 1e6))
              std::printf("# %s: %zu photons in the measured solve, %u rounds\n", direct ? "penumbra" : "enclosure",
                          static_cast<std::size_t>(solver.photons_shot()), solver.rounds());
          }
          budgets.push_back(n);
          errors.push_back(std::sqrt(sum / seeds));
          std::printf("%-9s %-7s %-6s %9.3g photons  RMS relative L2 %.4g\n", direct ? "penumbra" : "enclosure",
                      method.name, to_string(sampler), n, errors.back());
          std::fflush(stdout);
        }
        std::printf("%-9s %-7s %-6s slope %.3f\n", direct ? "penumbra" : "enclosure", method.name, to_string(sampler),
                    slope(budgets, errors));
      }
    }
  }
  return 0;
}
