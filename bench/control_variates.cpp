// Control variates for progressive shooting, predicted before they are built: the reference's
// discrete model of a scene (constant elements, exact form factors) stands in for the photons.
//
// Progressive shooting gives every photon of a round the same power, so a round shooting a pool
// of total power T_k (signed pools: sum of |power|) with photons in proportion to it deposits on
// patch q a count of photons with variance about (T / N) A_q, where T = sum_k T_k is all the power
// shot, N the photons and A_q = sum_k sum_p |pool_k(p)| F(p -> q) the power that flows into q
// whatever its sign. B's error on q is rho_q / L_q times the deposits' error, so the relative L2
// variance of B - E is
//
//   V = (T / N) sum_q L_q (rho_q / L_q)^2 A_q / sum_q L_q (B_q - E_q)^2,
//
// and 1 / V is the efficiency at equal photons. (Rounds propagate their noise to later rounds
// and quasi-Monte Carlo points stratify it; neither is modelled, for either method, so only the
// ratio of two V is read.) Each control variate below writes B = C + B', where C is known
// exactly, and B' solves B' = S + rho K B' for a signed source S that progressive shooting would
// shoot instead of E:
//
//  - constant: C = beta on every reflecting side, and S = E - beta + rho beta F_R on them (F_R(x)
//    the form factor from x to all reflecting sides, the exact transport of the constant), with
//    beta the area-weighted mean of B, the balance of emitted and absorbed power
//    (sum E L / sum L (1 - rho F_R)), and the best of a scan over [0, 1.6] times the mean;
//  - coarse: C = B_c, a coarse reference's answer b_c (constant on coarse elements) gathered at
//    every fine patch, B_c = E + rho K b_c (in the fine model: each fine patch's form factors to
//    the fine patches, each taking the value of the coarse element it lies in), and either
//    S = E + rho K B_c - B_c (the residual, which needs K of B_c at every origin: a second
//    gather) or, with the same C, the first round shooting D = B_c - b_c (the gathered answer
//    less its own coarse element's constant) and the rest reflected as usual, B' = rho K (D + B'),
//    since B_c + B' = E + rho K (B_c + B') and B_c - E = rho K b_c: no second gather, and a
//    source one bounce earlier.
//
// Every variant's B is checked against the fine reference's (the largest absolute difference is
// printed: the reference's own solve tolerance and the iteration's, so the algebra is right).
//
//   flatland_control_variates SCENE.json... [--fine 200] [--coarse 50[,100...]]
// (elements of scale / fine and scale / coarse.) Output: a Markdown table, a row per scene; each
// control variate's cell is its efficiency over plain shooting at equal photons (1 / V over plain
// shooting's) and, in brackets, the power it shoots over the power plain shooting shoots.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
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
};

// Progressive shooting of `source` (power per patch) to convergence: T, the received power H
// and the absolute inflow A per patch.
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
  std::vector<double> coarse_levels = {50.0};
  std::vector<std::string> scenes;
  for (int a = 1; a < argc; ++a) {
    if (std::strcmp(argv[a], "--fine") == 0 && a + 1 < argc) {
      fine = std::atof(argv[++a]);
    } else if (std::strcmp(argv[a], "--coarse") == 0 && a + 1 < argc) {
      coarse_levels = parse_list(argv[++a]);
    } else {
      scenes.emplace_back(argv[a]);
    }
  }
  if (scenes.empty() || !(fine > 0.0)) {
    std::fprintf(stderr, "usage: flatland_control_variates SCENE.json... [--fine 200] [--coarse 50[,100...]]\n");
    return 2;
  }
  std::printf(
      "| scene | fine patches | plain: power shot / emitted | constant, beta = mean of B | constant, beta = "
      "balance | constant, the best beta of a scan");
  for (double level : coarse_levels)
    std::printf(" | coarse answer (scale / %g), residual shot | coarse answer (scale / %g), D shot", level, level);
  std::printf(" | largest abs(B - B_ref) |\n|---|---|---|---|---|---");
  for (std::size_t i = 0; i < coarse_levels.size(); ++i) std::printf("|---|---");
  std::printf("|---|\n");
  for (const std::string& path : scenes) {
    auto scene = load_scene(path);
    if (!scene.ok()) {
      std::fprintf(stderr, "%s: %s\n", path.c_str(), scene.error().message.c_str());
      return 2;
    }
    ReferenceSettings settings;
    settings.max_element_length = scene->scale / fine;
    auto reference = solve_reference(*scene, settings);
    if (!reference.ok()) {
      std::fprintf(stderr, "%s: %s\n", path.c_str(), reference.error().message.c_str());
      return 2;
    }
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
    // Rows of reflecting patches are the reference's; an emitter that does not reflect shoots by
    // reciprocity, L_e F(e -> q) = L_q F(q -> e).
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
    double denominator = 0.0;
    for (std::size_t p = 0; p < m.n; ++p)
      if (m.rho[p] > 0.0) denominator += m.length[p] * std::pow(m.radiosity[p] - m.emittance[p], 2);
    const auto variance = [&](const Shot& shot) {
      double sum = 0.0;
      for (std::size_t p = 0; p < m.n; ++p)
        if (m.rho[p] > 0.0) sum += m.length[p] * std::pow(m.rho[p] / m.length[p], 2) * shot.total * shot.inflow[p];
      return sum / denominator;
    };
    // The largest |B - B_ref| over reflecting patches, B = C + rho H / L plus, where the source is
    // part of B' (`source_in_b`: the residual's S, as E is part of B), S / L.
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
    std::vector<double> emitted(m.n), zero(m.n, 0.0);
    for (std::size_t p = 0; p < m.n; ++p) emitted[p] = m.emittance[p] * m.length[p];
    const Shot plain = shoot(m, emitted);
    const double plain_variance = variance(plain);
    std::string cells;
    double largest_difference = check(m.emittance, zero, plain, false);
    const auto row = [&](const char* note, const Shot& shot, double largest) {
      char cell[200];
      const double power = shot.total / plain.total;
      if (power < 1e-9)
        std::snprintf(cell, sizeof cell, " | exact%s", note);
      else
        std::snprintf(cell, sizeof cell, " | %.3gx [%.3g]%s", plain_variance / variance(shot), power, note);
      cells += cell;
      largest_difference = std::max(largest_difference, largest);
    };
    double emitted_sum = 0.0;
    for (double v : emitted) emitted_sum += v;

    // The constant.
    std::vector<double> to_reflecting(m.n, 0.0);
    double mean = 0.0, reflecting_length = 0.0, absorbing = 0.0, emitted_power = 0.0;
    for (std::size_t p = 0; p < m.n; ++p) {
      emitted_power += emitted[p];
      if (!(m.rho[p] > 0.0)) continue;
      for (const auto& [q, f] : m.rows[p])
        if (m.rho[q] > 0.0) to_reflecting[p] += f;
      mean += m.length[p] * m.radiosity[p];
      reflecting_length += m.length[p];
      absorbing += m.length[p] * (1.0 - m.rho[p] * to_reflecting[p]);
    }
    mean /= reflecting_length;
    const auto constant = [&](double beta, Shot& shot) {
      std::vector<double> source(m.n), known(m.n);
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
                                      {"balance", absorbing > 0.0 ? emitted_power / absorbing : 0.0},
                                      {"best", best_beta}}) {
      Shot shot;
      const double largest = constant(beta, shot);
      char note[80] = "";
      if (std::strcmp(label, "mean") != 0) std::snprintf(note, sizeof note, " (beta %.2g x the mean)", beta / mean);
      row(note, shot, largest);
    }

    // The coarse reference's answer.
    for (double level : coarse_levels) {
      ReferenceSettings coarse_settings;
      coarse_settings.max_element_length = scene->scale / level;
      auto coarse = solve_reference(*scene, coarse_settings);
      if (!coarse.ok()) {
        std::fprintf(stderr, "%s: %s\n", path.c_str(), coarse.error().message.c_str());
        return 2;
      }
      const std::vector<ReferenceElement>& coarse_elements = coarse->element_list();
      std::vector<double> gathered(m.n), constant_part(m.n);
      for (std::size_t p = 0; p < m.n; ++p) {
        const ReferenceElement& e = elements[p / 2];
        if (!(m.rho[p] > 0.0)) {
          gathered[p] = constant_part[p] = m.emittance[p];
          continue;
        }
        // The coarse element of the same segment whose chord is nearest the fine one's middle.
        const Vec2 middle = 0.5 * (e.a + e.b);
        std::size_t nearest = 0;
        double distance = INFINITY;
        for (std::size_t c = 0; c < coarse_elements.size(); ++c) {
          if (coarse_elements[c].segment != e.segment) continue;
          const double d = distance_to_chord(middle, coarse_elements[c]);
          if (d < distance) {
            distance = d;
            nearest = c;
          }
        }
        constant_part[p] = coarse->element_radiosity(static_cast<std::uint32_t>(nearest), side_of(p))[0];
      }
      // The coarse answer gathered at every fine patch, in the fine model: E + rho sum_q F b_c(q).
      for (std::size_t p = 0; p < m.n; ++p) {
        if (!(m.rho[p] > 0.0)) continue;
        double seen = 0.0;
        for (const auto& [q, f] : m.rows[p]) seen += f * constant_part[q];
        gathered[p] = m.emittance[p] + m.rho[p] * seen;
      }
      std::vector<double> residual(m.n, 0.0), difference(m.n, 0.0);
      for (std::size_t p = 0; p < m.n; ++p) {
        if (!(m.rho[p] > 0.0)) continue;
        double transported = 0.0;
        for (const auto& [q, f] : m.rows[p]) transported += f * gathered[q];
        residual[p] = (m.emittance[p] + m.rho[p] * transported - gathered[p]) * m.length[p];
        difference[p] = (gathered[p] - constant_part[p]) * m.length[p];
      }
      char note[80];
      std::snprintf(note, sizeof note, " (%zu elements)", coarse_elements.size());
      const Shot by_residual = shoot(m, residual);
      row(note, by_residual, check(gathered, residual, by_residual, true));
      const Shot by_difference = shoot(m, difference);
      // B = B_c + rho H' with H' = K (D + B'): the shot D is not part of B.
      row("", by_difference, check(gathered, zero, by_difference, false));
    }
    std::printf("| %s | %zu | %.3g%s | %.1e |\n", path.c_str(), m.n, plain.total / emitted_sum, cells.c_str(),
                largest_difference);
  }
  return 0;
}
