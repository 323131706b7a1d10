// The table and plot of flatland converge: convergence.csv written and read back (--replot), the
// observed slopes, and the log-log plot drawn by gnuplot.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "flatland/base/status.hpp"
#include "flatland/studies/converge.hpp"

namespace flatland::app {

// The non-empty parts of `text` between separators (the lists of the options, a method's
// key=value parts).
std::vector<std::string> split(const std::string& text, char separator = ',');

double median(std::vector<double> values);

// One run: a row of convergence.csv.
using Row = ConvergeRow;

std::vector<std::string> method_names(const std::vector<ConvergeMethod>& methods);

// What the table's errors measure: B or B - E, over the scene or on one curve.
struct Measured {
  Measure measure = Measure::Reflected;
  std::string curve;  // a curve id, or empty for the whole scene

  std::string describe() const {
    return std::string(measure == Measure::Reflected ? "B - E" : "B") +
           (curve.empty() ? "" : " on curve '" + curve + "'");
  }
};

// Each method's observed convergence rate against photons and against time, as a table on stdout,
// one line per method.
void print_slopes(const std::vector<std::string>& methods, const std::vector<Row>& rows, const Measured& measured);

struct PlotInput {
  std::filesystem::path directory;
  std::string scene_name;
  int elements;  // shared by every method, or 0 when they differ
  int seeds;
  std::vector<std::string> methods;
  const std::vector<Row>& rows;
  Measured measured;
  double floor;  // the reference's estimated error, or <= 0 when unknown
};

// The log-log plot of the median L2 error against the median solve time per method and budget,
// with bars from the smallest to the largest error over the seeds, a -1/2 guide through the first
// run and the reference's error floor: convergence.{dat,gp} for gnuplot, which writes the PNG and
// SVG under temporary names that are renamed once it succeeded.
Status draw_plot(const PlotInput& in);

// flatland reference writes its own error estimate (stats.estimated_error.l2); other results have
// none: -1.
double estimated_error_of(const nlohmann::json& result);

// A CSV field: quoted when it holds a comma, a quote or a space (a quote inside doubled), with
// control characters (a line break would split the row) turned into spaces.
std::string csv_field(const std::string& text);

// Reads DIR/convergence.csv back (as written by converge) for --replot: methods in order of first
// appearance; within a method, rows come budget by budget with the seeds innermost.
Result<std::vector<Row>> read_rows(const std::filesystem::path& path, std::vector<std::string>& methods, int& seeds,
                                   int& elements, Measured& measured);

}  // namespace flatland::app
