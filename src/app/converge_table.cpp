// The table and plot of flatland converge (see converge_table.hpp).
#include "app/converge_table.hpp"

#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <climits>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <optional>
#include <sstream>

#include "app/commands.hpp"
#include "app/output.hpp"
#include "app/processes.hpp"

namespace flatland::app {

namespace fs = std::filesystem;

// The non-empty parts of `text` between separators (the lists of the options, a method's
// key=value parts).
std::vector<std::string> split(const std::string& text, char separator) {
  std::vector<std::string> out;
  std::stringstream parts(text);
  std::string part;
  while (std::getline(parts, part, separator))
    if (!part.empty()) out.push_back(part);
  return out;
}

double median(std::vector<double> values) {
  std::sort(values.begin(), values.end());
  const std::size_t n = values.size();
  return n % 2 == 1 ? values[n / 2] : 0.5 * (values[n / 2 - 1] + values[n / 2]);
}

namespace {

// A gnuplot string constant holding `text` exactly as it is, whatever it holds: single-quoted,
// because gnuplot performs no backquote (command) substitution, macro expansion or backslash
// processing inside single quotes; a quote inside is doubled, and control characters (a newline
// would end the command and start another) become spaces. Used with `noenhanced`, so ^ _ @ { }
// print as they are too.
std::string gnuplot_string(const std::string& text) {
  std::string out = "'";
  for (const char c : text) {
    if (c == '\'')
      out += "''";
    else if (static_cast<unsigned char>(c) < 0x20 || c == 0x7f)
      out += ' ';
    else
      out += c;
  }
  return out + "'";
}

// Runs `gnuplot SCRIPT` in `directory` without a shell (an argument vector, so no path or text is
// ever interpreted as a command), its output passed on to stderr. An error when gnuplot cannot be
// started or fails.
Status run_gnuplot(const fs::path& directory, const std::string& script) {
  int pipe_ends[2];
  if (::pipe(pipe_ends) != 0) return Error{std::string("cannot run gnuplot: ") + std::strerror(errno)};
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_addchdir_np(&actions, directory.c_str());
  posix_spawn_file_actions_adddup2(&actions, pipe_ends[1], STDOUT_FILENO);
  posix_spawn_file_actions_adddup2(&actions, pipe_ends[1], STDERR_FILENO);
  posix_spawn_file_actions_addclose(&actions, pipe_ends[0]);
  std::string program = "gnuplot";
  std::string argument = script;
  char* argv[] = {program.data(), argument.data(), nullptr};
  // gnuplot gets the default SIGPIPE back (flatland ignores it, and an ignored signal is inherited).
  posix_spawnattr_t attributes;
  posix_spawnattr_init(&attributes);
  sigset_t defaults;
  sigemptyset(&defaults);
  sigaddset(&defaults, SIGPIPE);
  posix_spawnattr_setsigdefault(&attributes, &defaults);
  posix_spawnattr_setflags(&attributes, POSIX_SPAWN_SETSIGDEF);
  pid_t child = 0;
  const int spawned = ::posix_spawnp(&child, "gnuplot", &actions, &attributes, argv, environ);
  posix_spawnattr_destroy(&attributes);
  posix_spawn_file_actions_destroy(&actions);
  ::close(pipe_ends[1]);
  if (spawned != 0) {
    ::close(pipe_ends[0]);
    return Error{std::string("cannot run gnuplot (") + std::strerror(spawned) +
                 "); install it: apt-get install gnuplot-nox"};
  }
  std::string output;
  char buffer[512];
  for (;;) {
    const ssize_t got = ::read(pipe_ends[0], buffer, sizeof buffer);
    if (got > 0)
      output.append(buffer, static_cast<std::size_t>(got));
    else if (got == 0 || errno != EINTR)
      break;
  }
  ::close(pipe_ends[0]);
  int status = 0;
  while (::waitpid(child, &status, 0) < 0 && errno == EINTR) {
  }
  if (!output.empty()) std::fprintf(stderr, "%s", output.c_str());
  if (!WIFEXITED(status) || WEXITSTATUS(status) != 0) return Error{"gnuplot failed (its messages are above)"};
  return ok_status();
}

}  // namespace

std::vector<std::string> method_names(const std::vector<ConvergeMethod>& methods) {
  std::vector<std::string> names;
  for (const ConvergeMethod& method : methods) names.push_back(method.name);
  return names;
}

namespace {

// Each method's observed convergence rate: the exponent of the power law fitted by least squares
// to the relative L2 error of every run (each seed a point) against the photons shot and against
// the solve time, on log-log axes (power_law_exponent); nullopt with fewer than two distinct
// photon counts (or times).
struct Slopes {
  std::optional<double> photons;
  std::optional<double> seconds;
};

std::vector<Slopes> observed_slopes(const std::vector<Row>& rows, std::size_t methods) {
  std::vector<Slopes> slopes(methods);
  for (std::size_t m = 0; m < methods; ++m) {
    std::vector<double> photons, seconds, errors;
    for (const Row& row : rows)
      if (row.method == m) {
        photons.push_back(static_cast<double>(row.photons));
        seconds.push_back(row.seconds);
        errors.push_back(row.error.l2);
      }
    slopes[m] = {power_law_exponent(photons, errors), power_law_exponent(seconds, errors)};
  }
  return slopes;
}

std::string slope_text(const std::optional<double>& slope) {
  if (!slope) return "n/a";
  char text[32];
  std::snprintf(text, sizeof text, "%.2f", *slope);
  return text;
}

}  // namespace

// The slopes as a table on stdout, one line per method.
void print_slopes(const std::vector<std::string>& methods, const std::vector<Row>& rows, const Measured& measured) {
  const std::vector<Slopes> slopes = observed_slopes(rows, methods.size());
  std::printf("observed slopes of the relative L2 error of %s (least squares on log-log axes over every run):\n",
              measured.describe().c_str());
  std::printf("  %-40s %12s %12s\n", "method", "vs photons", "vs time");
  for (std::size_t m = 0; m < methods.size(); ++m)
    std::printf("  %-40s %12s %12s\n", methods[m].c_str(), slope_text(slopes[m].photons).c_str(),
                slope_text(slopes[m].seconds).c_str());
}

namespace {

// The legend's names: the settings every method shares ("key=value" parts of the method strings,
// joined by '+') are said once, in `shared`, and each method is named by the parts that set it
// apart, so that methods spelled out in full still fit a line each. A method with no part of its
// own (every part shared) keeps its whole name.
struct LegendNames {
  std::string shared;
  std::vector<std::string> names;
};

LegendNames legend_names(const std::vector<std::string>& methods) {
  std::vector<std::vector<std::string>> parts;
  for (const std::string& method : methods) parts.push_back(split(method, '+'));
  LegendNames out;
  std::vector<std::string> shared;
  if (methods.size() > 1)
    for (const std::string& part : parts.front())
      if (std::all_of(parts.begin(), parts.end(),
                      [&](const auto& p) { return std::find(p.begin(), p.end(), part) != p.end(); }))
        shared.push_back(part);
  for (std::size_t m = 0; m < methods.size(); ++m) {
    std::string name;
    for (const std::string& part : parts[m])
      if (std::find(shared.begin(), shared.end(), part) == shared.end()) name += (name.empty() ? "" : "+") + part;
    out.names.push_back(name.empty() ? methods[m] : name);
  }
  for (const std::string& part : shared) out.shared += (out.shared.empty() ? "" : "+") + part;
  return out;
}

}  // namespace

// The log-log plot of the median L2 error against the median solve time per method and budget,
// with bars from the smallest to the largest error over the seeds, a -1/2 guide through the first
// run and the reference's error floor: convergence.{dat,gp} for gnuplot, which writes the PNG and
// SVG under temporary names that are renamed once it succeeded.
Status draw_plot(const PlotInput& in) {
  const fs::path& directory = in.directory;
  std::size_t budgets = 0;
  for (const Row& row : in.rows) budgets = std::max(budgets, row.budget + 1);
  std::string data;
  for (std::size_t m = 0; m < in.methods.size(); ++m) {
    for (std::size_t b = 0; b < budgets; ++b) {
      std::vector<double> seconds;
      std::vector<double> errors;
      std::vector<double> estimated;  // the solver's own bounds (NaN where a run has none)
      for (const Row& row : in.rows)
        if (row.method == m && row.budget == b) {
          seconds.push_back(std::max(row.seconds, 1e-6));
          errors.push_back(row.error.l2);
          if (std::isfinite(row.estimated.l2)) estimated.push_back(row.estimated.l2);
        }
      if (errors.empty()) continue;
      // Column 5: the median estimated bound, or NaN (gnuplot leaves it out) when fewer than half
      // the runs have one.
      const double bound = 2 * estimated.size() >= errors.size() ? median(estimated) : NAN;
      char line[320];
      std::snprintf(line, sizeof line, "%.9g %.9g %.9g %.9g %.9g\n", median(seconds), median(errors),
                    *std::min_element(errors.begin(), errors.end()), *std::max_element(errors.begin(), errors.end()),
                    bound);
      data += line;
    }
    data += "\n\n";  // a gnuplot data block per method
  }
  if (Status status = write_file_atomically((directory / "convergence.dat").string(), data, &interrupt_flag()); !status)
    return status;

  // gnuplot runs in the directory, so the script names its files without the directory's path;
  // the only text from the user (scene and method names) goes through gnuplot_string.
  const Row& anchor = in.rows.front();
  const LegendNames legend = legend_names(in.methods);
  const std::string subtitle = (in.elements > 0 ? std::to_string(in.elements) + " elements per curve, " : "") +
                               "median over " + std::to_string(in.seeds) + " seeds, bars from min to max";
  std::string script = "set logscale xy\nset xlabel 'solve time (s)'\nset ylabel " +
                       gnuplot_string("relative L2 error of " + in.measured.describe()) +
                       " noenhanced\n"
                       "set key below vertical maxcols 1 Left reverse font ',9'\nset grid\n"
                       "set title " +
                       gnuplot_string(in.scene_name) + ".\"\\n\"." + gnuplot_string(subtitle) +
                       (legend.shared.empty() ? "" : ".\"\\n\"." + gnuplot_string("every method: " + legend.shared)) +
                       " noenhanced\n";
  // Each method's legend entry carries its observed slopes (observed_slopes).
  const std::vector<Slopes> slopes = observed_slopes(in.rows, in.methods.size());
  std::string plot = "plot ";
  for (std::size_t m = 0; m < in.methods.size(); ++m) {
    const std::string title = legend.names[m] + ": slope " + slope_text(slopes[m].seconds) + " vs time, " +
                              slope_text(slopes[m].photons) + " vs photons";
    // Twelve distinct colours, then the same colours dash-dotted: gnuplot's own cycle repeats after
    // eight. One dash type a line: the bound's own dashes are set apart from the method's line.
    static constexpr const char* kColours[] = {"#9400d3", "#009e73", "#56b4e9", "#e69f00", "#0072b2", "#e51e10",
                                               "#000000", "#c0a000", "#8c564b", "#e377c2", "#7f7f7f", "#17becf"};
    const std::string colour = std::string(" lc rgb '") + kColours[m % 12] + "'";
    const std::string dashes = m >= 12 ? " dt 4" : "";
    plot += "'convergence.dat' index " + std::to_string(m) + " using 1:2:3:4 with yerrorlines lw 2" + colour + dashes +
            " title " + gnuplot_string(title) + " noenhanced, ";
    // The method's estimated bound, dashed in its colour (no legend entry: one says what dashes are).
    plot +=
        "'convergence.dat' index " + std::to_string(m) + " using 1:5 with lines dt 2 lw 1.5" + colour + " notitle, ";
  }
  plot += "NaN with lines dt 2 lw 1.5 lc rgb 'gray20' title " +
          gnuplot_string("dashed: each method's estimated bound (median over seeds)") + " noenhanced, ";
  char guide[256];
  std::snprintf(guide, sizeof guide, "%.9g * (x / %.9g)**(-0.5) with lines dt 2 lc rgb 'gray40' title 'slope -1/2'",
                anchor.error.l2, std::max(anchor.seconds, 1e-6));
  plot += guide;
  double smallest_error = INFINITY;
  for (const Row& row : in.rows) smallest_error = std::min(smallest_error, row.error.l2);
  // A floor far below every error would only stretch the axis: say it in a label instead.
  if (in.floor > 0.0 && in.floor < 0.01 * smallest_error) {
    char line[160];
    std::snprintf(line, sizeof line,
                  "set label 1 'reference error (estimate) %.2g: below the plot' at graph 0.02, graph 0.04\n",
                  in.floor);
    script += line;
  } else if (in.floor > 0.0) {
    char line[160];
    std::snprintf(line, sizeof line, ", %.9g with lines dt 3 lc rgb 'black' title 'reference error (estimate)'",
                  in.floor);
    plot += line;
  }
  plot += "\n";
  const fs::path png_temporary = directory / ".convergence.png.tmp";
  const fs::path svg_temporary = directory / ".convergence.svg.tmp";
  // The key lists one method per line below the axes, so the picture grows by a line per method
  // and keeps its axes' height whatever the number of methods; it is wide enough for the longest
  // entry (gnuplot reserves about 8 pixels a character, whatever the key's font, and drops the
  // whole key when an entry is wider than the picture).
  std::size_t longest = legend.shared.size();
  for (const std::string& name : legend.names) longest = std::max(longest, name.size() + 40);
  const std::string size = std::to_string(std::max<std::size_t>(900, 8 * longest + 160)) + "," +
                           std::to_string(600 + 17 * (in.methods.size() + 4));
  script += "set terminal pngcairo size " + size + "\nset output '.convergence.png.tmp'\n" + plot;
  script += "set terminal svg size " + size + "\nset output '.convergence.svg.tmp'\n" + plot;
  if (Status status = write_file_atomically((directory / "convergence.gp").string(), script, &interrupt_flag());
      !status)
    return status;
  std::error_code ec;
  if (Status status = run_gnuplot(directory, "convergence.gp"); !status) {
    fs::remove(png_temporary, ec);
    fs::remove(svg_temporary, ec);
    return status;
  }
  fs::rename(png_temporary, directory / "convergence.png", ec);
  fs::rename(svg_temporary, directory / "convergence.svg", ec);
  return ok_status();
}

// flatland reference writes its own error estimate (stats.estimated_error.l2); other results have
// none: -1.
double estimated_error_of(const nlohmann::json& result) {
  if (!result.contains("stats") || !result["stats"].is_object()) return -1.0;
  const nlohmann::json& stats = result["stats"];
  if (!stats.contains("estimated_error") || !stats["estimated_error"].is_object()) return -1.0;
  const nlohmann::json& estimate = stats["estimated_error"];
  return estimate.contains("l2") && estimate["l2"].is_number() ? estimate["l2"].get<double>() : -1.0;
}

// A CSV field: quoted when it holds a comma, a quote or a space (a quote inside doubled), with
// control characters (a line break would split the row) turned into spaces.
std::string csv_field(const std::string& text) {
  std::string out;
  bool quote = false;
  for (const char c : text) {
    if (c == '"')
      out += "\"\"";
    else if (static_cast<unsigned char>(c) < 0x20 || c == 0x7f)
      out += ' ';
    else
      out += c;
    quote = quote || c == ',' || c == '"' || c == ' ' || static_cast<unsigned char>(c) < 0x20;
  }
  return quote ? "\"" + out + "\"" : out;
}

namespace {

// The fields of one CSV line: commas inside double quotes belong to the field, "" is a quote.
std::vector<std::string> csv_fields(const std::string& line) {
  std::vector<std::string> fields(1);
  bool quoted = false;
  for (std::size_t i = 0; i < line.size(); ++i) {
    const char c = line[i];
    if (quoted && c == '"' && i + 1 < line.size() && line[i + 1] == '"') {
      fields.back() += '"';
      ++i;
    } else if (c == '"') {
      quoted = !quoted;
    } else if (c == ',' && !quoted) {
      fields.emplace_back();
    } else {
      fields.back() += c;
    }
  }
  return fields;
}

}  // namespace

Result<std::vector<Row>> read_rows(const fs::path& path, std::vector<std::string>& methods, int& seeds, int& elements,
                                   Measured& measured) {
  Result<std::string> table =
      read_input_file(path.string(), "convergence table", &interrupt_flag(), InputContent::Text);
  if (!table) {
    if (table.error().message == kFileWaitCancelled) return table.error();
    return Error{table.error().message + " (run converge without --replot first)"};
  }
  std::istringstream in(*table);
  std::string line;
  std::getline(in, line);
  std::vector<std::string> header = split(line);
  auto column = [&header](const std::string& name) -> int {
    const auto it = std::find(header.begin(), header.end(), name);
    return it == header.end() ? -1 : static_cast<int>(it - header.begin());
  };
  const int c_method = column("method"), c_seed = column("seed"), c_photons = column("photons"),
            c_seconds = column("seconds"), c_l1 = column("rel_l1"), c_l2 = column("rel_l2"),
            c_linf = column("rel_linf"), c_elements = column("elements"), c_measure = column("measure"),
            c_curve = column("curve"), c_estimated = column("est_l2");
  if (c_method < 0 || c_seed < 0 || c_photons < 0 || c_seconds < 0 || c_l1 < 0 || c_l2 < 0 || c_linf < 0)
    return Error{path.string() +
                 ":1: not a convergence table (expected the columns method, seed, "
                 "photons, seconds, rel_l1, rel_l2, rel_linf)"};
  struct Parsed {
    std::string method;
    std::uint64_t seed;
    std::uint64_t photons;
    double seconds;
    ErrorNorms error;
    int elements;
    double estimated;  // est_l2, NaN where the table has none
  };
  std::vector<Parsed> parsed;
  std::vector<std::uint64_t> seed_values;
  int number = 1;
  while (std::getline(in, line)) {
    ++number;
    if (line.empty()) continue;
    const std::vector<std::string> fields = csv_fields(line);
    if (fields.size() != header.size())
      return Error{path.string() + ":" + std::to_string(number) + ": " + std::to_string(fields.size()) +
                   " fields against " + std::to_string(header.size()) + " in the header"};
    Parsed p;
    p.method = fields[static_cast<std::size_t>(c_method)];
    // A table written before converge measured B - E has no measure column: it measured B.
    if (parsed.empty()) {
      measured.measure = c_measure >= 0 ? parse_measure(fields[static_cast<std::size_t>(c_measure)]) : Measure::Total;
      measured.curve = c_curve >= 0 ? fields[static_cast<std::size_t>(c_curve)] : "";
    }
    char* end = nullptr;
    auto number_at = [&](int c) {
      const std::string& text = fields[static_cast<std::size_t>(c)];
      const double value = std::strtod(text.c_str(), &end);
      return end == text.c_str() || *end != '\0' ? NAN : value;
    };
    const double values[] = {number_at(c_seed), number_at(c_photons), number_at(c_seconds),
                             number_at(c_l1),   number_at(c_l2),      number_at(c_linf)};
    for (const double value : values)
      if (!std::isfinite(value))
        return Error{path.string() + ":" + std::to_string(number) + ": a field that should be a number is not"};
    p.seed = static_cast<std::uint64_t>(values[0]);
    p.photons = static_cast<std::uint64_t>(values[1]);
    p.seconds = values[2];
    p.error = {values[3], values[4], values[5]};
    p.estimated = c_estimated >= 0 ? number_at(c_estimated) : NAN;
    const double element_count = c_elements >= 0 ? number_at(c_elements) : 0.0;
    p.elements = std::isfinite(element_count) && element_count >= 1.0 && element_count < 1e9
                     ? static_cast<int>(element_count)
                     : 0;
    if (std::find(seed_values.begin(), seed_values.end(), p.seed) == seed_values.end()) seed_values.push_back(p.seed);
    parsed.push_back(p);
  }
  if (parsed.empty()) return Error{path.string() + ": no runs in the table"};
  seeds = static_cast<int>(seed_values.size());
  elements = parsed.front().elements;
  for (const Parsed& p : parsed)
    if (p.elements != elements) elements = 0;
  std::vector<Row> rows;
  std::vector<std::size_t> seen;  // rows so far per method
  for (const Parsed& p : parsed) {
    auto it = std::find(methods.begin(), methods.end(), p.method);
    if (it == methods.end()) {
      methods.push_back(p.method);
      seen.push_back(0);
      it = methods.end() - 1;
    }
    const auto m = static_cast<std::size_t>(it - methods.begin());
    Row row{m, seen[m]++ / static_cast<std::size_t>(seeds), p.seed, p.photons, 0, 0.0, p.seconds, p.error, 0};
    row.estimated.l2 = p.estimated;
    rows.push_back(row);
  }
  return rows;
}

}  // namespace flatland::app
