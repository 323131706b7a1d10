// Control variates for progressive shooting, predicted before they are built:
// the reference's discrete model of a scene (constant elements, exact form
// factors; channel 0, the red of a coloured scene) stands in for the scene,
// twice over:
//
// - predicted: progressive shooting gives every photon of a round the same
// power, so a round
//   shooting a pool of total power T_k (signed pools: the sum of |power|)
//   deposits on patch q a count of photons with variance about (T / N) A_q,
//   where T = sum_k T_k is all the power shot, N the photons and A_q = sum_k
//   sum_p |pool_k(p)| F(p -> q) the power that flows into q whatever its sign.
//   B's error on q is rho_q / L_q times the deposits', so the relative L2
//   variance of B - E is V = (T / N) sum_q L_q (rho_q / L_q)^2 A_q / sum_q L_q
//   (B_q - E_q)^2, and 1 / V is the efficiency at equal photons (the passing on
//   of a round's noise to the next rounds is left out);
// - simulated: the same shooting by N photons of about equal power in the
// discrete model (each
//   leaves a patch chosen by |pool| and lands on one chosen by the form
//   factors), the noise passing on from round to round; the median over seeds
//   of the relative L2 error of B - E.
// Neither has the solver's quasi-Monte Carlo stratification or its storage:
// ratios of two methods are what to read. Each control variate writes B = C +
// B', with C known exactly, and shoots the source of B' (B' = S + rho K B')
// instead of E:
//
//  - direct light exact (the baseline a final gather compares with): C = E +
//  rho K E, and the
//    first round shoots D_0 = rho K E, the first bounce, whose reflections
//    follow as usual;
//  - constant: C = beta on every reflecting side, and S = E - beta + rho beta
//  F_R on them (F_R(x)
//    the form factor from x to all reflecting sides, the exact transport of the
//    constant), with beta the area-weighted mean of B, the balance of the
//    reflecting sides' power (beta sum_R L (1 - rho F_R) = sum_R L (E + rho K
//    E), exact in a furnace), and the best of a scan of beta over [0, 1.6]
//    times the mean;
//  - coarse: C = B_c, a coarse reference's answer b_c (constant on coarse
//  elements) gathered at
//    every fine patch, B_c = E + rho K b_c (in the fine model: each fine
//    patch's form factors to the fine patches, each taking the value of the
//    coarse element it lies in), and either S = E + rho K B_c - B_c shot (the
//    residual, which needs K of B_c at every origin: a second gather), or D =
//    B_c - b_c (the gathered answer less its own coarse element's constant)
//    shot as the first round, its reflections following as usual: B_c + B' = E
//    + rho K (B_c + B') and B_c - E = rho K b_c give B' = rho K (D + B'), so no
//    second gather is needed. (Direct light exact is this with b_c = E on the
//    emitters and 0 elsewhere.)
//
// Every variant's B is checked against the fine reference's (the last column:
// the largest absolute difference over every variant, plain shooting's
// included: the reference's own solve tolerance and the iteration's, so the
// algebra is right).
//
//   flatland_control_variates SCENE.json... [--fine 200] [--coarse 50[,100...]]
//   [--photons 1e6]
//                                           [--seeds 5]
// (elements at most scale / fine and scale / coarse long.) Output: a Markdown
// table, a row per scene; each control variate's cell: its efficiency over
// plain shooting at equal photons, predicted and simulated, and in brackets the
// power it shoots over what plain shooting shoots.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <random>
#include <string>
#include <vector>

#include "flatland/reference/reference.hpp"
#include "flatland/scene/scene.hpp"

using namespace flatland;

namespace {

Side side_of(std::size_t patch) { return patch % 2 != 0 ? Side::Back : Side::Front; }

// The fine discrete model, channel 0 (patch = 2 element + side).
struct Model {
  std::size_t n = 0;
  std::vector<double> length, rho, emittance, radiosity;          // per patch
  std::vector<std::vector<std::pair<std::size_t, double>>> rows;  // F from a patch that shoots
  std::vector<std::vector<double>> cumulative;                    // per row, the running sums of F
};

// Progressive shooting of `source` (power per patch) to convergence: T, the
// received power H and the absolute inflow A per patch.
struct Shot {
  double total = 0.0;
  std::vector<double> received, inflow;
};

Shot shoot(const Model& m, std::vector<double> pool) {
  Shot shot;
  shot.received.assign(m.n, 0.0);
  shot.inflow.assign(m.n, 0.0);
  double first = 0.0;
  for (double v : pool) first += std::fabs(v);
  std::vector<double> received(m.n), inflow(m.n);
  for (int round = 0; round < 10'000 && first > 0.0; ++round) {
    double power = 0.0;
    for (double v : pool) power += std::fabs(v);
    if (!(power > 1e-13 * first)) break;
    shot.total += power;
    std::fill(received.begin(), received.end(), 0.0);
    std::fill(inflow.begin(), inflow.end(), 0.0);
    for (std::size_t p = 0; p < m.n; ++p) {
      if (pool[p] == 0.0) continue;
      for (const auto& [q, f] : m.rows[p]) {
        received[q] += pool[p] * f;
        inflow[q] += std::fabs(pool[p]) * f;
      }
    }
    for (std::size_t q = 0; q < m.n; ++q) {
      shot.received[q] += received[q];
      shot.inflow[q] += inflow[q];
      pool[q] = m.rho[q] * received[q];
    }
  }
  return shot;
}

// The same shooting by photons, in the discrete model: every round's photons
// carry about `photon_power` (plain shooting's photons of equal power), each
// leaves a patch chosen by |pool| with the sign of its pool and lands on a
// patch chosen by the form factors (or is lost: escaped, or absorbed by a side
// that neither reflects nor emits). A round's pool is rho times the last
// round's noisy deposits, so the noise passes on as it does in the solver.
// Returns the received power per patch.
std::vector<double> simulate(const Model& m, std::vector<double> pool, double photon_power, std::mt19937_64& rng) {
  std::vector<double> total(m.n, 0.0), received(m.n), cumulative(m.n);
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  for (int round = 0; round < 10'000; ++round) {
    double power = 0.0;
    for (std::size_t p = 0; p < m.n; ++p) cumulative[p] = power += std::fabs(pool[p]);
    const auto photons = static_cast<std::uint64_t>(std::llround(power / photon_power));
    if (photons == 0) break;
    const double each = power / static_cast<double>(photons);
    std::fill(received.begin(), received.end(), 0.0);
    for (std::uint64_t i = 0; i < photons; ++i) {
      const auto p = std::min<std::size_t>(
          static_cast<std::size_t>(std::upper_bound(cumulative.begin(), cumulative.end(), uniform(rng) * power) -
                                   cumulative.begin()),
          m.n - 1);
      const std::vector<double>& row = m.cumulative[p];
      const auto j = static_cast<std::size_t>(std::upper_bound(row.begin(), row.end(), uniform(rng)) - row.begin());
      if (j == row.size()) continue;
      received[m.rows[p][j].first] += pool[p] > 0.0 ? each : -each;
    }
    for (std::size_t q = 0; q < m.n; ++q) {
      total[q] += received[q];
      pool[q] = m.rho[q] * received[q];
    }
  }
  return total;
}

double distance_to_chord(Vec2 x, const ReferenceElement& e) {
  const Vec2 d = e.b - e.a;
  const double t = std::clamp(dot(x - e.a, d) / dot(d, d), 0.0, 1.0);
  const Vec2 r = x - (e.a + t * d);
  return std::sqrt(dot(r, r));
}

std::vector<double> parse_list(const char* text) {
  std::vector<double> values;
  for (const char* p = text; *p != '\0';) {
    char* end = nullptr;
    values.push_back(std::strtod(p, &end));
    if (end == p) break;
    p = *end == ',' ? end + 1 : end;
  }
  return values;
}

}  // namespace

int main(int argc, char** argv) {
  double fine = 200.0;
  double photons = 1e6;
  int seeds = 5;
  std::vector<double> coarse_levels = {50.0};
  std::vector<std::string> scenes;
  for (int a = 1; a < argc; ++a) {
    if (std::strcmp(argv[a], "--fine") == 0 && a + 1 < argc) {
      fine = std::atof(argv[++a]);
    } else if (std::strcmp(argv[a], "--photons") == 0 && a + 1 < argc) {
      photons = std::atof(argv[++a]);
    } else if (std::strcmp(argv[a], "--seeds") == 0 && a + 1 < argc) {
      seeds = std::atoi(argv[++a]);
    } else if (std::strcmp(argv[a], "--coarse") == 0 && a + 1 < argc) {
      coarse_levels = parse_list(argv[++a]);
    } else {
      scenes.emplace_back(argv[a]);
    }
  }
  if (scenes.empty() || !(fine > 0.0) || !(photons >= 1.0) || seeds < 1) {
    std::fprintf(stderr,
                 "usage: flatland_control_variates SCENE.json... "
                 "[--fine 200] [--coarse 50[,100...]]\n");
    return 2;
  }
  std::printf(
      "| scene | fine patches | plain: power shot / emitted | direct "
      "light exact | constant, beta = mean of B | "
      "constant, beta = balance | constant, the best beta of a scan");
  for (double level : coarse_levels)
    std::printf(
        " | coarse answer (scale / %g), residual shot | coarse answer "
        "(scale / %g), D shot",
        level, level);
  std::printf(" | largest abs(B - B_ref), any variant |\n|---|---|---|---|---|---|---");
  for (std::size_t i = 0; i < coarse_levels.size(); ++i) std::printf("|---|---");
  std::printf("|---|\n");
  for (const std::string& path : scenes) {
    auto scene = load_scene(path);
    if (!scene.ok()) {
      std::fprintf(stderr, "%s: %s\n", path.c_str(), scene.error().message.c_str());
      return 2;
    }
    // The reference with elements at most scale / divisions long (or why not, on stderr).
    const auto solve_at = [&](double divisions) {
      ReferenceSettings settings;
      settings.max_element_length = scene->scale / divisions;
      auto solution = solve_reference(*scene, settings);
      if (!solution.ok()) std::fprintf(stderr, "%s: %s\n", path.c_str(), solution.error().message.c_str());
      return solution;
    };
    auto reference = solve_at(fine);
    if (!reference.ok()) return 2;
    const std::vector<ReferenceElement>& elements = reference->element_list();
    Model m;
    m.n = 2 * elements.size();
    m.length.resize(m.n);
    m.rho.resize(m.n);
    m.emittance.resize(m.n);
    m.radiosity.resize(m.n);
    m.rows.resize(m.n);
    for (std::size_t p = 0; p < m.n; ++p) {
      const ReferenceElement& e = elements[p / 2];
      m.length[p] = e.length;
      m.rho[p] = e.reflectivity[p % 2][0];
      m.emittance[p] = e.emittance[p % 2][0];
      m.radiosity[p] = reference->element_radiosity(static_cast<std::uint32_t>(p / 2), side_of(p))[0];
    }
    // Rows of reflecting patches are the reference's; an emitter that does not
    // reflect shoots by reciprocity, L_e F(e -> q) = L_q F(q -> e).
    for (std::size_t p = 0; p < m.n; ++p) {
      if (!(m.rho[p] > 0.0)) continue;
      for (std::size_t q = 0; q < m.n; ++q) {
        const double f = reference->form_factor(static_cast<std::uint32_t>(p / 2), side_of(p),
                                                static_cast<std::uint32_t>(q / 2), side_of(q));
        if (f == 0.0) continue;
        m.rows[p].push_back({q, f});
        if (!(m.rho[q] > 0.0) && m.emittance[q] > 0.0) m.rows[q].push_back({p, f * m.length[p] / m.length[q]});
      }
    }
    m.cumulative.resize(m.n);
    for (std::size_t p = 0; p < m.n; ++p) {
      double sum = 0.0;
      for (const auto& entry : m.rows[p]) m.cumulative[p].push_back(sum += entry.second);
    }
    double denominator = 0.0;
    for (std::size_t p = 0; p < m.n; ++p)
      if (m.rho[p] > 0.0) denominator += m.length[p] * std::pow(m.radiosity[p] - m.emittance[p], 2);
    if (!(denominator > 0.0)) {
      std::printf("| %s | %zu | no reflected light: nothing to compare |\n", path.c_str(), m.n);
      continue;
    }
    const auto variance = [&](const Shot& shot) {
      double sum = 0.0;
      for (std::size_t p = 0; p < m.n; ++p)
        if (m.rho[p] > 0.0) sum += m.length[p] * std::pow(m.rho[p] / m.length[p], 2) * shot.total * shot.inflow[p];
      return sum / denominator;
    };
    // The largest |B - B_ref| over reflecting patches, B = C + rho H / L plus,
    // where the source is part of B' (`source_in_b`: the residual's S, as E is
    // part of B), S / L.
    const auto check = [&](const std::vector<double>& known, const std::vector<double>& source, const Shot& shot,
                           bool source_in_b) {
      double largest = 0.0;
      for (std::size_t p = 0; p < m.n; ++p) {
        if (!(m.rho[p] > 0.0)) continue;
        const double b =
            known[p] + (source_in_b ? source[p] / m.length[p] : 0.0) + m.rho[p] * shot.received[p] / m.length[p];
        largest = std::max(largest, std::fabs(b - m.radiosity[p]));
      }
      return largest;
    };
    // The median over seeds of the relative L2 error of B - E that `photons`
    // photons leave.
    const auto simulated = [&](const std::vector<double>& known, const std::vector<double>& source, const Shot& shot,
                               bool source_in_b) {
      std::vector<double> errors;
      for (int seed = 1; seed <= seeds; ++seed) {
        std::mt19937_64 rng(static_cast<std::uint64_t>(seed));
        const std::vector<double> received = simulate(m, source, shot.total / photons, rng);
        double sum = 0.0;
        for (std::size_t p = 0; p < m.n; ++p) {
          if (!(m.rho[p] > 0.0)) continue;
          const double b =
              known[p] + (source_in_b ? source[p] / m.length[p] : 0.0) + m.rho[p] * received[p] / m.length[p];
          sum += m.length[p] * std::pow(b - m.radiosity[p], 2);
        }
        errors.push_back(std::sqrt(sum / denominator));
      }
      std::nth_element(errors.begin(), errors.begin() + static_cast<std::ptrdiff_t>(errors.size() / 2), errors.end());
      return errors[errors.size() / 2];
    };
    std::vector<double> emitted(m.n), zero(m.n, 0.0);
    for (std::size_t p = 0; p < m.n; ++p) emitted[p] = m.emittance[p] * m.length[p];
    const Shot plain = shoot(m, emitted);
    const double plain_variance = variance(plain);
    const double plain_error = simulated(m.emittance, emitted, plain, false);
    std::string cells;
    double largest_difference = check(m.emittance, zero, plain, false);
    const auto row = [&](const char* note, const std::vector<double>& known, const std::vector<double>& source,
                         const Shot& shot, bool source_in_b, double largest) {
      char cell[200];
      const double power = shot.total / plain.total;
      if (power < 1e-9) {
        std::snprintf(cell, sizeof cell, " | exact%s", note);
      } else {
        const double error = simulated(known, source, shot, source_in_b);
        std::snprintf(cell, sizeof cell, " | %.3gx, %.3gx [%.3g]%s", plain_variance / variance(shot),
                      std::pow(plain_error / error, 2), power, note);
      }
      cells += cell;
      largest_difference = std::max(largest_difference, largest);
    };
    double emitted_sum = 0.0;
    for (double v : emitted) emitted_sum += v;
    // A constant-element answer b (per fine patch) gathered at every fine patch
    // in the fine model, gathered = E + rho sum_q F b(q), the residual S = E +
    // rho K gathered - gathered and the difference D = gathered - b, as power
    // per patch (zero on the sides that do not reflect).
    const auto gather = [&](const std::vector<double>& b, std::vector<double>& gathered, std::vector<double>& residual,
                            std::vector<double>& difference) {
      gathered = b;
      for (std::size_t p = 0; p < m.n; ++p) {
        if (!(m.rho[p] > 0.0)) continue;
        double seen = 0.0;
        for (const auto& [q, f] : m.rows[p]) seen += f * b[q];
        gathered[p] = m.emittance[p] + m.rho[p] * seen;
      }
      residual.assign(m.n, 0.0);
      difference.assign(m.n, 0.0);
      for (std::size_t p = 0; p < m.n; ++p) {
        if (!(m.rho[p] > 0.0)) continue;
        double transported = 0.0;
        for (const auto& [q, f] : m.rows[p]) transported += f * gathered[q];
        residual[p] = (m.emittance[p] + m.rho[p] * transported - gathered[p]) * m.length[p];
        difference[p] = (gathered[p] - b[p]) * m.length[p];
      }
    };

    // Direct light exact: b = E (the emitters' light, nothing reflected), D =
    // rho K E.
    {
      std::vector<double> gathered, residual, difference;
      gather(m.emittance, gathered, residual, difference);
      const Shot shot = shoot(m, difference);
      row("", gathered, difference, shot, false, check(gathered, zero, shot, false));
    }

    // The constant.
    std::vector<double> to_reflecting(m.n, 0.0);
    double mean = 0.0, reflecting_length = 0.0, absorbing = 0.0, first_bounce = 0.0;
    for (std::size_t p = 0; p < m.n; ++p) {
      if (!(m.rho[p] > 0.0)) continue;
      for (const auto& [q, f] : m.rows[p])
        if (m.rho[q] > 0.0) to_reflecting[p] += f;
      mean += m.length[p] * m.radiosity[p];
      reflecting_length += m.length[p];
      absorbing += m.length[p] * (1.0 - m.rho[p] * to_reflecting[p]);
      double direct = 0.0;
      for (const auto& [q, f] : m.rows[p])
        if (!(m.rho[q] > 0.0)) direct += f * m.emittance[q];
      first_bounce += m.length[p] * (m.emittance[p] + m.rho[p] * direct);
    }
    mean /= reflecting_length;
    std::vector<double> source(m.n), known(m.n);
    const auto constant = [&](double beta, Shot& shot) {
      for (std::size_t p = 0; p < m.n; ++p) {
        const bool reflects = m.rho[p] > 0.0;
        source[p] = reflects ? (m.emittance[p] - beta + m.rho[p] * beta * to_reflecting[p]) * m.length[p] : emitted[p];
        known[p] = reflects ? m.emittance[p] + m.rho[p] * beta * to_reflecting[p] : m.emittance[p];
      }
      shot = shoot(m, source);
      return check(known, zero, shot, false);
    };
    double best_beta = 0.0, best = plain_variance;
    for (int step = 1; step <= 32; ++step) {
      Shot shot;
      constant(step * 0.05 * mean, shot);
      if (variance(shot) < best) {
        best = variance(shot);
        best_beta = step * 0.05 * mean;
      }
    }
    for (const auto& [label, beta] : {std::pair<const char*, double>{"mean", mean},
                                      {"balance", absorbing > 0.0 ? first_bounce / absorbing : 0.0},
                                      {"best", best_beta}}) {
      Shot shot;
      const double largest = constant(beta, shot);
      char note[80] = "";
      if (std::strcmp(label, "mean") != 0 && mean > 0.0)
        std::snprintf(note, sizeof note, " (beta %.2g x the mean)", beta / mean);
      row(note, known, source, shot, false, largest);
    }

    // The coarse reference's answer.
    for (double level : coarse_levels) {
      auto coarse = solve_at(level);
      if (!coarse.ok()) return 2;
      const std::vector<ReferenceElement>& coarse_elements = coarse->element_list();
      std::vector<double> gathered, constant_part(m.n);
      for (std::size_t p = 0; p < m.n; ++p) {
        const ReferenceElement& e = elements[p / 2];
        if (!(m.rho[p] > 0.0)) {
          constant_part[p] = m.emittance[p];
          continue;
        }
        // The coarse element of the same segment whose chord is nearest the
        // fine one's middle.
        const Vec2 middle = 0.5 * (e.a + e.b);
        std::size_t nearest = coarse_elements.size();
        double distance = INFINITY;
        for (std::size_t c = 0; c < coarse_elements.size(); ++c) {
          if (coarse_elements[c].segment != e.segment) continue;
          const double d = distance_to_chord(middle, coarse_elements[c]);
          if (d < distance) {
            distance = d;
            nearest = c;
          }
        }
        if (nearest == coarse_elements.size()) {
          std::fprintf(stderr, "%s: no coarse element on segment %u\n", path.c_str(), e.segment);
          return 2;
        }
        constant_part[p] = coarse->element_radiosity(static_cast<std::uint32_t>(nearest), side_of(p))[0];
      }
      std::vector<double> residual, difference;
      gather(constant_part, gathered, residual, difference);
      char note[80];
      std::snprintf(note, sizeof note, " (%zu elements)", coarse_elements.size());
      const Shot by_residual = shoot(m, residual);
      row(note, gathered, residual, by_residual, true, check(gathered, residual, by_residual, true));
      const Shot by_difference = shoot(m, difference);
      // B = B_c + rho H' with H' = K (D + B'): the shot D is not part of B.
      row("", gathered, difference, by_difference, false, check(gathered, zero, by_difference, false));
    }
    std::printf("| %s | %zu | %.3g%s | %.1e |\n", path.c_str(), m.n, plain.total / emitted_sum, cells.c_str(),
                largest_difference);
  }
  return 0;
}
