// flatland converge: error against run time for several methods, photon budgets and seeds, as a
// CSV table and a log-log plot drawn by gnuplot.
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <optional>
#include <sstream>

#include "app/commands.hpp"
#include "app/converge_table.hpp"
#include "app/output.hpp"
#include "app/processes.hpp"
#include "app/progress.hpp"
#include "flatland/base/bits.hpp"
#include "flatland/reference/coarse_answer.hpp"
#include "flatland/reference/reference.hpp"
#include "flatland/results/result_io.hpp"
#include "flatland/studies/converge.hpp"
#include "flatland/transport/solver.hpp"

namespace flatland::app {

namespace {

namespace fs = std::filesystem;

using Method = ConvergeMethod;

// The longest run --times may ask for: at any rate a machine reaches (below 1e9 photons/s) its
// photons stay below kMaxPhotons.
constexpr double kMaxRunSeconds = 1e6;

// What to run: the methods of --methods and the budgets of --budgets (photons) or --times
// (seconds), parsed and checked before any work.
struct Plan {
  std::vector<Method> methods;
  std::vector<double> budgets;
  bool by_time = false;
};

Result<Plan> parse_plan(const ConvergeOptions& o) {
  Plan plan;
  SolverSettings defaults;
  defaults.threads = o.threads;
  defaults.tolerance = o.tolerance;
  if (Status status = set_solve_option(defaults, SolveOption::Elements, o.elements); !status) return status.error();
  for (const std::string& text : split(o.methods)) {
    for (const Method& earlier : plan.methods)
      if (earlier.name == text) return Error{"--methods: '" + text + "' is given twice; give each method once"};
    Result<Method> method = parse_converge_method(text, defaults);
    if (!method) return method.error();
    plan.methods.push_back(std::move(*method));
  }
  if (plan.methods.empty()) return Error{"--methods: give at least one method"};
  plan.by_time = !o.times.empty();
  for (const std::string& text : split(plan.by_time ? o.times : o.budgets)) {
    char* end = nullptr;
    const double value = std::strtod(text.c_str(), &end);
    if (end == text.c_str() || *end != '\0' || !(value > 0.0) || !std::isfinite(value))
      return Error{std::string(plan.by_time ? "--times" : "--budgets") + ": '" + text + "' is not a positive number"};
    if (plan.by_time && value > kMaxRunSeconds)
      return Error{"--times: '" + text + "' seconds is more than a run may take (at most " +
                   std::to_string(static_cast<long>(kMaxRunSeconds)) + " s, about 12 days)"};
    if (!plan.by_time) {
      if (Result<std::uint64_t> count = parse_count(text, "--budgets"); !count) return count.error();
      if (Status status = check_converge_budget(value, plan.methods); !status)
        return Error{"--" + status.error().message};
    }
    plan.budgets.push_back(value);
  }
  if (plan.budgets.empty()) return Error{"--budgets: give at least one budget"};
  return plan;
}

}  // namespace

Status check_converge_options(const ConvergeOptions& o) {
  Result<Plan> plan = parse_plan(o);
  if (!plan) return plan.error();
  return ok_status();
}

CLI::App* add_converge_command(CLI::App& parent, ConvergeOptions& o) {
  CLI::App* cmd =
      parent.add_subcommand("converge",
                            "Error against run time: solve SCENE with every method over a range of photon budgets (or "
                            "time budgets) and seeds; write DIR/convergence.csv and a log-log plot (PNG and SVG, by "
                            "gnuplot) of the median error against the median time, with the spread over seeds, a guide "
                            "slope of -1/2 and the reference's own error floor; print and plot each method's observed "
                            "slope. The error is that of the reflected part B - E by default (--measure), over the "
                            "scene or on one curve (--curve)");
  cmd->add_option("scene", o.scene, "Scene file (JSON)")->required();
  cmd->add_option("--reference", o.reference, "Reference result (flatland reference --out); computed when not given");
  std::string keys;  // the solve options a method may set (options.hpp)
  for (const SolveOptionSpec& spec : solve_options())
    if (spec.per_method) keys += (keys.empty() ? "" : ", ") + std::string(spec.flag);
  cmd->add_option("--methods", o.methods,
                  "Comma-separated methods: a basis name, or key=value pairs joined by '+' (" + keys +
                      "; as solve's options), e.g. constant,cubic,cubic+sampling=uniform,"
                      "cubic+elements=64+sampler=sobol,cubic+transport=walk; commas separate methods, so "
                      "importance=ID names one curve here (Python's converge takes the methods as a list, so several)")
      ->capture_default_str();
  auto* budgets = cmd->add_option("--budgets", o.budgets, "Comma-separated photon budgets")->capture_default_str();
  auto* times = cmd->add_option("--times", o.times,
                                "Comma-separated wall-time budgets in seconds (photons set from "
                                "each method's measured rate)");
  budgets->excludes(times);
  cmd->add_option("--seeds", o.seeds, "Seeds per method and budget")
      ->capture_default_str()
      ->check(CLI::Range(1, kMaxSeeds));
  cmd->add_option("--samples", o.samples, "Samples per curve (the reference is solved with these)")
      ->capture_default_str()
      ->check(CLI::Range(1, 1000000));
  cmd->add_option("--threads", o.threads, "Worker threads per solve (0: every core)")
      ->capture_default_str()
      ->check(CLI::Range(0u, 1024u));
  cmd->add_option("--elements", o.elements,
                  "Storage elements per curve of every method, or auto (each curve's mesh follows "
                  "its photons); a method's elements=N overrides it")
      ->capture_default_str()
      ->type_name(std::string(spec_of(SolveOption::Elements).value));
  cmd->add_option("--tolerance", o.tolerance,
                  "Unshot-power tolerance of every solve (a method's tolerance=X overrides it); "
                  "small, so that each solve spends its whole budget")
      ->capture_default_str()
      ->check(finite_range(1e-15, 0.5));
  cmd->add_option("--measure", o.measure,
                  "What is measured: 'reflected' (B - E, relative to the reference's B - E; the "
                  "emitters' exact E left out) or 'total' (B)")
      ->capture_default_str()
      ->check(CLI::IsMember({"reflected", "total"}));
  cmd->add_option("--curve", o.curve,
                  "Measure the error on the curve with this id (as in the scene file) instead of "
                  "over the whole scene");
  cmd->add_option("--out", o.out, "Output directory (created when the results are written, in an existing directory)")
      ->required()
      ->check(output_path());
  cmd->add_flag("--replot", o.replot,
                "Solve nothing: draw the plot again from DIR/convergence.csv, with the measure it "
                "was written with (the floor from --reference, when given)");
  return cmd;
}

// The reference's error estimate (relative L2 of B over the scene) converted to what the table
// measures: the estimate's numerator |R_2h - R_h| is the same for B and for B - E, so it scales
// by |R| / |R - E|. None (-1) for one curve: the estimate is the whole scene's.
double floor_for(const nlohmann::json& reference, double floor, const Measured& measured) {
  if (floor <= 0.0 || !measured.curve.empty()) return -1.0;
  if (measured.measure == Measure::Total) return floor;
  Result<Comparison> total = compare_results(reference, reference, Measure::Total);
  Result<Comparison> reflected = compare_results(reference, reference, Measure::Reflected);
  if (!total || !reflected || !(reflected->reference_l2 > 0.0) || !std::isfinite(total->reference_l2)) return -1.0;
  return floor * total->reference_l2 / reflected->reference_l2;
}

// Collective: every process's rows (each run done by exactly one) on rank 0; alone, nothing to do.
// A row travels as integers (its doubles bit for bit), zero where another process did the run.
void gather_rows(std::vector<std::optional<Row>>& rows) {
  if (process_count() == 1) return;
  constexpr std::size_t kFields = 15;
  std::vector<std::int64_t> values(rows.size() * kFields, 0);
  for (std::size_t i = 0; i < rows.size(); ++i) {
    if (!rows[i]) continue;
    const Row& row = *rows[i];
    std::int64_t* out = &values[i * kFields];
    out[0] = 1;
    out[1] = static_cast<std::int64_t>(row.method);
    out[2] = static_cast<std::int64_t>(row.budget);
    out[3] = static_cast<std::int64_t>(row.seed);
    out[4] = static_cast<std::int64_t>(row.photons);
    out[5] = row.rounds;
    out[6] = bit_cast<std::int64_t>(row.unshot);
    out[7] = bit_cast<std::int64_t>(row.seconds);
    out[8] = bit_cast<std::int64_t>(row.error.l1);
    out[9] = bit_cast<std::int64_t>(row.error.l2);
    out[10] = bit_cast<std::int64_t>(row.error.linf);
    out[11] = bit_cast<std::int64_t>(row.estimated.l1);
    out[12] = bit_cast<std::int64_t>(row.estimated.l2);
    out[13] = bit_cast<std::int64_t>(row.estimated.linf);
    out[14] = row.gathered ? 1 : 0;
  }
  std::vector<std::int64_t> rays(rows.size(), 0);
  for (std::size_t i = 0; i < rows.size(); ++i)
    if (rows[i]) rays[i] = static_cast<std::int64_t>(rows[i]->rays);
  shared_processes()->sum(values);
  shared_processes()->sum(rays);
  for (std::size_t i = 0; i < rows.size(); ++i) {
    const std::int64_t* in = &values[i * kFields];
    if (in[0] != 1) continue;  // cannot happen once every process agreed that it finished
    ErrorNorms error;
    error.l1 = bit_cast<double>(in[8]);
    error.l2 = bit_cast<double>(in[9]);
    error.linf = bit_cast<double>(in[10]);
    Row row;
    row.method = static_cast<std::size_t>(in[1]);
    row.budget = static_cast<std::size_t>(in[2]);
    row.seed = static_cast<std::uint64_t>(in[3]);
    row.photons = static_cast<std::uint64_t>(in[4]);
    row.rounds = static_cast<std::uint32_t>(in[5]);
    row.unshot = bit_cast<double>(in[6]);
    row.seconds = bit_cast<double>(in[7]);
    row.error = error;
    row.estimated = {bit_cast<double>(in[11]), bit_cast<double>(in[12]), bit_cast<double>(in[13])};
    row.rays = static_cast<std::uint64_t>(rays[i]);
    row.gathered = in[14] != 0;
    rows[i] = row;
  }
}

namespace {

// `--replot`: the plot of the runs a previous call wrote, drawn again (rank 0 alone).
int replot(const ConvergeOptions& o, const Scene& scene) {
  const fs::path directory(o.out);
  std::vector<std::string> names;
  int seeds = 0;
  int elements = 0;
  Measured table_measured;
  Result<std::vector<Row>> rows = read_rows(directory / "convergence.csv", names, seeds, elements, table_measured);
  if (!rows) return input_error(rows.error());
  double floor = -1.0;
  if (!o.reference.empty()) {
    Result<nlohmann::json> read = read_result_file(o.reference, &interrupt_flag());
    if (!read) return input_error(read.error());
    floor = floor_for(*read, estimated_error_of(*read), table_measured);
  }
  if (Status status = draw_plot({directory, scene.name, elements, seeds, names, *rows, table_measured, floor});
      !status) {
    std::fprintf(stderr, "flatland: error: %s\n", status.error().message.c_str());
    return kExitFailure;
  }
  std::printf("wrote     %s/convergence.png, convergence.svg (%zu runs)\n", o.out.c_str(), rows->size());
  print_slopes(names, *rows, table_measured);
  return kExitOk;
}

// A convergence study of a checked plan on a loaded scene: its steps, in order. Each returns the
// exit code when the study stops there; under mpirun every step that can stop is collective
// (agree), so all processes stop together.
class ConvergeStudy {
 public:
  ConvergeStudy(const ConvergeOptions& o, const Scene& scene, const Plan& plan)
      : o_(o), scene_(scene), plan_(plan), measured_{parse_measure(o.measure), o.curve} {}

  // Every process checks the curve and the measure; rank 0 alone checks the outputs and reads or
  // computes the reference (processes.hpp).
  std::optional<int> prepare();
  // Rank 0's reference, handed to the others and read as data by every process.
  std::optional<int> share_reference();
  // Every run: run i (methods, then budgets, then seeds) is done by process i mod K; the rows
  // are gathered on every process.
  std::optional<int> run_all();
  // Rank 0: the CSV, the plot and the printed summary.
  int write_outputs() const;

 private:
  std::optional<int> check_curve_and_measure();
  std::optional<int> check_outputs() const;
  std::optional<int> read_reference();
  std::optional<int> compute_reference();
  std::optional<int> check_reference_measures();
  // Photons per second of method m, measured for time budgets.
  std::optional<int> measure_rate(std::size_t m, double& rate) const;
  std::optional<int> run_one(std::size_t m, std::size_t b, int seed, double rate);
  std::string csv() const;

  const ConvergeOptions& o_;
  const Scene& scene_;
  const Plan& plan_;
  // Per method, --control-variate auto's choice, made once at its largest budget (empty: none made).
  std::vector<std::optional<ControlVariate>> variates_;
  // What is measured; a curve is named by its id in the scene file.
  const Measured measured_;
  std::size_t curve_index_ = 0;
  nlohmann::json reference_;
  std::optional<SampledResult> sampled_reference_;
  double floor_ = -1.0;
  std::vector<std::optional<Row>> done_;
  std::size_t own_total_ = 0;
  std::size_t own_done_ = 0;
  std::vector<Row> rows_;
};

// A curve (or a scene) whose materials reflect nothing has no B - E: said now, before any work;
// one that reflects but receives no light is found in the reference (check_reference_measures).
std::optional<int> ConvergeStudy::check_curve_and_measure() {
  const auto reflects = [this](const Curve& curve) {
    const Spectrum& rho = scene_.material_of(curve).reflectivity;
    return std::any_of(rho.begin(), rho.begin() + scene_.channels, [](double r) { return r > 0.0; });
  };
  if (!o_.curve.empty()) {
    std::vector<std::string> ids;
    for (const Curve& curve : scene_.curves) ids.push_back(curve.id);
    Result<std::size_t> index = find_curve(ids, o_.curve);
    if (!index) return usage_error(index.error().message + " (in " + o_.scene + ")");
    curve_index_ = *index;
    if (measured_.measure == Measure::Reflected && !reflects(scene_.curves[curve_index_]))
      return usage_error("--curve: '" + o_.curve +
                         "' reflects no light (its material's reflectivity is 0), so "
                         "it has no relative error of B - E; use --measure total");
  }
  if (measured_.measure == Measure::Reflected && std::none_of(scene_.curves.begin(), scene_.curves.end(), reflects))
    return usage_error("--measure reflected: " + o_.scene +
                       ": no curve reflects light (every reflectivity is 0), "
                       "so B - E is zero everywhere and has no relative error; use --measure total");
  return std::nullopt;
}

// The output directory is made when the results are written (a refused run leaves none): here it
// must exist, or its parent must (checked as a file to be made there, trailing separators off).
std::optional<int> ConvergeStudy::check_outputs() const {
  std::error_code ec;
  const bool exists = fs::exists(o_.out, ec);
  if (exists && !fs::is_directory(o_.out, ec))
    return usage_error("--out " + o_.out + ": is not a directory; give a directory for the results");
  fs::path directory(o_.out);
  while (directory.has_parent_path() && !directory.has_filename()) directory = directory.parent_path();
  const std::string target = exists ? (fs::path(o_.out) / "convergence.csv").string() : directory.string();
  if (Status status = check_output_file(target); !status) return usage_error("--out " + status.error().message);
  if (Status status = check_result_size(scene_, o_.samples); !status) return usage_error(status.error().message);
  return std::nullopt;
}

std::optional<int> ConvergeStudy::read_reference() {
  Result<nlohmann::json> read = read_result_file(o_.reference, &interrupt_flag());
  if (!read) return input_error(read.error());
  reference_ = std::move(*read);
  floor_ = estimated_error_of(reference_);
  // Of this scene, sampled as the runs will be: said now, not after the first solve.
  Result<SampledResult> given = sampled_from_json(reference_, "the reference");
  if (!given) return usage_error(o_.reference + ": " + given.error().message);
  if (Status status = check_reference_of(*given, scene_, o_.samples); !status)
    return usage_error(o_.reference + ": " + status.error().message +
                       (check_reference_of(*given, scene_)
                            ? "; pass --samples " + std::to_string(given->curves[0].samples.size())
                            : std::string()));
  return std::nullopt;
}

// The reference, and an estimate of its own error from solves with elements twice and four times
// as long (the order observed from the three; docs/reference.md): the plot's floor.
std::optional<int> ConvergeStudy::compute_reference() {
  std::fprintf(stderr, "converge: computing the reference of %s\n", o_.scene.c_str());
  ReferenceSettings settings;
  settings.threads = o_.threads;
  settings.cancel = &interrupt_flag();
  Result<ReferenceSolution> fine = solve_reference(scene_, settings);
  if (!fine) return interrupt_flag().load() ? interrupted() : usage_error(fine.error().message);
  const ReferenceSolution& solution = *fine;
  const SampledResult sampled = sample_radiosity(
      scene_, o_.samples, [&solution](std::uint32_t c, Side side, double u) { return solution.radiosity(c, side, u); });
  reference_ = {{"flatland_result", 1}, {"curves", curves_to_json(sampled)}};
  Result<ErrorNorms> estimate = estimate_reference_error(scene_, settings, o_.samples, sampled);
  if (interrupt_flag().load()) return interrupted();
  if (estimate) floor_ = estimate->l2;
  return std::nullopt;
}

// The reference against itself: whether it has the measured quantity (B - E is zero everywhere in
// a scene where nothing reflects, and on a curve that reflects nothing), before any solve.
std::optional<int> ConvergeStudy::check_reference_measures() {
  Result<Comparison> self = compare_results(reference_, reference_, measured_.measure);
  if (!self)
    return usage_error("--measure " + o_.measure + ": " + (o_.reference.empty() ? "" : o_.reference + ": ") +
                       self.error().message + (self.error().message == kNothingReflected ? " (--measure total)" : ""));
  if (!o_.curve.empty() && !self->curves[curve_index_].measured)
    return usage_error("--curve: '" + o_.curve +
                       "' reflects no light in the reference (B - E is zero along "
                       "it), so it has no relative error of B - E; use --measure total");
  floor_ = floor_for(reference_, floor_, measured_);
  return std::nullopt;
}

std::optional<int> ConvergeStudy::prepare() {
  if (std::optional<int> code = check_curve_and_measure()) return code;
  // What the scene refuses of a method, said before the reference is computed.
  for (const Method& method : plan_.methods)
    if (Status status = check_solver_settings(scene_, method.settings); !status)
      return usage_error(status.error().message + " (method '" + method.name + "')");
  if (!speaks_for_the_run()) return std::nullopt;
  if (std::optional<int> code = check_outputs()) return code;
  if (std::optional<int> code = o_.reference.empty() ? compute_reference() : read_reference()) return code;
  return check_reference_measures();
}

std::optional<int> ConvergeStudy::share_reference() {
  if (process_count() > 1) {
    std::string text = speaks_for_the_run() ? reference_.dump() : std::string();
    share_text(text);
    if (!speaks_for_the_run()) reference_ = nlohmann::json::parse(text);
  }
  // (Collective: a reference that another process cannot read stops them all.)
  Result<SampledResult> sampled = sampled_from_json(reference_, "the reference");
  if (sampled) sampled_reference_ = std::move(*sampled);
  return agree(sampled ? std::nullopt : std::optional<int>(usage_error("--reference: " + sampled.error().message)));
}

std::optional<int> ConvergeStudy::measure_rate(std::size_t m, double& rate) const {
  rate = 0.0;
  if (!plan_.by_time) return std::nullopt;
  SolverSettings probe = plan_.methods[m].settings;
  probe.photons = 100'000;
  Result<Solver> solver = create_solver(scene_, probe, &interrupt_flag());
  if (!solver) return interrupt_flag().load() ? interrupted() : usage_error(solver.error().message);
  solver->run(&interrupt_flag());
  rate = static_cast<double>(solver->photons_shot()) / std::max(solver->seconds(), 1e-6);
  return std::nullopt;
}

std::optional<int> ConvergeStudy::run_one(std::size_t m, std::size_t b, int seed, double rate) {
  const std::vector<double>& budgets = plan_.budgets;
  const std::size_t run =
      (m * budgets.size() + b) * static_cast<std::size_t>(o_.seeds) + static_cast<std::size_t>(seed - 1);
  if (run % process_count() != process_rank()) return std::nullopt;
  SolverSettings settings = plan_.methods[m].settings;
  if (variates_[m]) settings.control_variate = *variates_[m];
  // (A time too short for the replicates still shoots one photon each.)
  const double photons =
      std::max(static_cast<double>(settings.replicates), plan_.by_time ? std::floor(budgets[b] * rate) : budgets[b]);
  if (photons > static_cast<double>(kMaxPhotons))
    return usage_error("--times: " + std::to_string(budgets[b]) + " s at the measured " + human_count(rate) +
                       " photons/s is more than the 2^50 photons a solve may shoot");
  settings.photons = static_cast<std::uint64_t>(photons);
  settings.seed = static_cast<std::uint64_t>(seed);
  Result<Row> row = converge_run(scene_, settings, *sampled_reference_, measured_.measure,
                                 o_.curve.empty() ? std::nullopt : std::optional<std::size_t>(curve_index_), o_.samples,
                                 &interrupt_flag());
  if (!row) return interrupt_flag().load() ? interrupted() : usage_error(row.error().message);
  row->method = m;
  row->budget = b;
  done_[run] = *row;
  ++own_done_;
  if (::isatty(STDERR_FILENO) == 1 && speaks_for_the_run())
    std::fprintf(stderr, "\r\033[K  converge: %zu / %zu runs%s (%s, %s photons, seed %d)", own_done_, own_total_,
                 process_count() > 1 ? " of this process" : "", plan_.methods[m].name.c_str(),
                 human_count(static_cast<double>(settings.photons)).c_str(), seed);
  return std::nullopt;
}

std::optional<int> ConvergeStudy::run_all() {
  const std::vector<Method>& methods = plan_.methods;
  const std::size_t total = methods.size() * plan_.budgets.size() * static_cast<std::size_t>(o_.seeds);
  const std::size_t processes = process_count();
  own_total_ = total / processes + (process_rank() < total % processes ? 1 : 0);
  done_.assign(total, std::nullopt);
  variates_.assign(methods.size(), std::nullopt);
  std::optional<int> failure;
  const bool tty = ::isatty(STDERR_FILENO) == 1;
  for (std::size_t m = 0; m < methods.size() && !failure; ++m) {
    double rate = 0.0;
    failure = measure_rate(m, rate);
    // Auto's choice grows with the photons (the storage does): made once, at the method's largest
    // budget, so that a method is the same method at every budget and on every process.
    if (!failure && methods[m].settings.control_variate == ControlVariate::Auto) {
      const double top = *std::max_element(plan_.budgets.begin(), plan_.budgets.end());
      const auto largest = static_cast<std::uint64_t>(std::clamp(plan_.by_time ? std::floor(top * rate) : top,
                                                                 static_cast<double>(methods[m].settings.replicates),
                                                                 static_cast<double>(kMaxPhotons)));
      std::string skipped;
      variates_[m] = converge_variate(scene_, methods[m].settings, largest, skipped);
      if (!skipped.empty() && speaks_for_the_run())
        std::fprintf(stderr, "converge: method %s runs without the control variate: %s (--control-variate auto)\n",
                     methods[m].name.c_str(), skipped.c_str());
    }
    for (std::size_t b = 0; b < plan_.budgets.size() && !failure; ++b)
      for (int seed = 1; seed <= o_.seeds && !failure; ++seed) failure = run_one(m, b, seed, rate);
    if (!failure && !tty && speaks_for_the_run())
      std::fprintf(stderr, "converge: method %zu / %zu done (%s), %zu / %zu runs%s\n", m + 1, methods.size(),
                   methods[m].name.c_str(), own_done_, own_total_, processes > 1 ? " of this process" : "");
  }
  if (tty && speaks_for_the_run()) std::fprintf(stderr, "\r\033[K");
  if (!failure && interrupt_flag().load()) failure = interrupted();
  if (std::optional<int> code = agree(failure)) return code;
  gather_rows(done_);
  for (const std::optional<Row>& row : done_) rows_.push_back(*row);
  return std::nullopt;
}

// The CSV: converge_fields' columns (measure and curve say what rel_* measure: "reflected" (B - E)
// or "total" (B), over the curve with that id, or over the scene when the curve is empty). The
// method's name is always quoted, the curve's id where it must be.
std::string ConvergeStudy::csv() const {
  std::string csv;
  for (const ConvergeField& field : converge_fields({}, {}, {}, measured_.measure, {}))
    csv += std::string(csv.empty() ? "" : ",") + field.name;
  csv += "\n";
  for (const Row& row : rows_) {
    const Method& method = plan_.methods[row.method];
    const std::vector<ConvergeField> fields =
        converge_fields(method.name, method.settings, row, measured_.measure, measured_.curve);
    std::string line;
    for (const ConvergeField& field : fields) {
      if (&field != &fields.front()) line += ',';
      if (const auto* text = std::get_if<std::string>(&field.value)) {
        line += field.name == std::string_view("method")  ? "\"" + *text + "\""
                : field.name == std::string_view("curve") ? csv_field(*text)
                                                          : *text;
      } else if (const auto* number = std::get_if<std::int64_t>(&field.value)) {
        line += std::to_string(*number);
      } else {
        char real[40];
        std::snprintf(real, sizeof real, "%.*g", field.digits, std::get<double>(field.value));
        line += real;
      }
    }
    csv += line + "\n";
  }
  return csv;
}

int ConvergeStudy::write_outputs() const {
  const fs::path directory(o_.out);
  std::error_code ec;
  fs::create_directory(directory, ec);
  if (ec || !fs::is_directory(directory)) return usage_error("--out " + o_.out + ": cannot create the directory");
  if (Status status = write_file_atomically((directory / "convergence.csv").string(), csv(), &interrupt_flag());
      !status)
    return usage_error(status.error().message);
  const std::vector<Method>& methods = plan_.methods;
  int shared_elements = methods.front().settings.elements;
  for (const Method& method : methods)
    if (method.settings.elements != shared_elements) shared_elements = 0;
  if (Status status = draw_plot(
          {directory, scene_.name, shared_elements, o_.seeds, method_names(methods), rows_, measured_, floor_});
      !status) {
    std::fprintf(stderr, "flatland: error: %s; %s/convergence.csv is written, the plot is not\n",
                 status.error().message.c_str(), o_.out.c_str());
    return kExitFailure;
  }
  std::printf("wrote     %s/convergence.csv, convergence.png, convergence.svg (%zu runs)\n", o_.out.c_str(),
              rows_.size());
  if (floor_ > 0.0) std::printf("reference error (estimated) %.3g relative L2\n", floor_);
  print_slopes(method_names(methods), rows_, measured_);
  return kExitOk;
}

}  // namespace

int run_converge(ConvergeOptions& o) {
  // A replot draws what a run wrote: rank 0's work alone.
  if (o.replot && !speaks_for_the_run()) return kExitOk;
  Result<Plan> plan = parse_plan(o);
  Result<Scene> scene = plan ? load_scene(o.scene, &interrupt_flag()) : Result<Scene>(Error{""});
  std::optional<int> unusable;
  if (!plan)
    unusable = usage_error(plan.error().message);
  else if (!scene)
    unusable = input_error(scene.error());
  if (o.replot) return unusable ? *unusable : replot(o, *scene);
  if (const std::optional<int> code = agree(unusable)) return *code;
  if (const std::optional<int> code = agree_on_digest("scene file", o.scene, scene->source_sha256)) return *code;

  ConvergeStudy study(o, *scene, *plan);
  if (const std::optional<int> code = agree(study.prepare())) return *code;
  if (const std::optional<int> code = study.share_reference()) return *code;
  if (const std::optional<int> code = study.run_all()) return *code;
  return speaks_for_the_run() ? study.write_outputs() : kExitOk;
}

}  // namespace flatland::app
