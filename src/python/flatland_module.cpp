// The Python module `flatland` (docs/python.md): a thin layer over the core, with the command line's
// option names as keywords and its one-line messages as exceptions. No second copy of anything:
// scenes are parsed by the core's parser, solves are the core's Solver, results are written by the
// core's result_to_json (so to_json() is the document `flatland solve --out` writes), comparisons
// are the core's compare_results.
#include <pybind11/functional.h>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <memory>
#include <optional>
#include <string>
#include <thread>
#include <tuple>
#include <vector>

#include <nlohmann/json.hpp>

#include "flatland/base/text.hpp"
#include "flatland/base/version.hpp"
#include "flatland/reference/coarse_answer.hpp"
#include "flatland/reference/final_gather.hpp"
#include "flatland/reference/reference.hpp"
#include "flatland/reference/reference_io.hpp"
#include "flatland/results/metrics.hpp"
#include "flatland/results/result_io.hpp"
#include "flatland/results/sampled_result.hpp"
#include "flatland/scene/discontinuities.hpp"
#include "flatland/scene/scene.hpp"
#include "flatland/studies/converge.hpp"
#include "flatland/transport/footprint.hpp"
#include "flatland/transport/options.hpp"
#include "flatland/transport/solver.hpp"

namespace py = pybind11;

namespace flatland::python {
namespace {

// The module's exception: a ValueError whose message is the command line's one-line error.
[[noreturn]] void fail(const std::string& message) { throw py::value_error(message); }

// A RuntimeWarning (something the user should know that changes no result).
void warn(const std::string& message) {
  if (PyErr_WarnEx(PyExc_RuntimeWarning, message.c_str(), 1) != 0) throw py::error_already_set();
}

template <typename T>
T value_or_fail(Result<T> result) {
  if (!result) fail(result.error().message);
  return std::move(*result);
}

// A scene shared by every solver made from it (a Solver keeps a pointer to its scene).
struct PyScene {
  std::shared_ptr<const Scene> scene;
  std::uint32_t curve_index(const std::string& id) const {
    for (std::uint32_t c = 0; c < scene->curves.size(); ++c)
      if (scene->curves[c].id == id) return c;
    std::string ids;
    for (const Curve& curve : scene->curves) ids += (ids.empty() ? "" : ", ") + curve.id;
    fail(scene->source + ": no curve '" + id + "'; the curves are " + ids);
  }
};

// Runs work(cancel) with the GIL released on a helper thread, while this thread looks for signals
// every 50 ms: Ctrl-C (KeyboardInterrupt, or whatever a handler raises) sets `cancel`, waits for
// the work to stop and is raised here. Work that polls `cancel` (a wait on a pipe, a reference's
// rows) so stops within a fraction of a second. Without a thread to spare, the work runs on this
// thread and only ends by itself.
void run_watching_signals(const std::function<void(const std::atomic<bool>*)>& work) {
  std::atomic<bool> cancel{false};
  std::atomic<bool> done{false};
  std::exception_ptr failure;
  std::optional<py::error_already_set> raised;
  std::thread helper;
  try {
    helper = std::thread([&] {
      try {
        work(&cancel);
      } catch (...) {
        failure = std::current_exception();
      }
      done.store(true);
    });
  } catch (const std::system_error&) {
    py::gil_scoped_release release;
    work(&cancel);
    return;
  }
  {
    py::gil_scoped_release release;
    while (!done.load()) {
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
      py::gil_scoped_acquire gil;
      if (!raised && PyErr_CheckSignals() != 0) {
        raised.emplace();  // fetches the handler's exception
        cancel.store(true);
      }
    }
    helper.join();
  }
  if (raised) throw *raised;
  if (failure) std::rethrow_exception(failure);
}

PyScene load(const std::string& path) {
  std::optional<Result<Scene>> loaded;
  run_watching_signals([&](const std::atomic<bool>* cancel) { loaded.emplace(load_scene(path, cancel)); });
  return {std::make_shared<const Scene>(value_or_fail(std::move(*loaded)))};
}

// A Python value as JSON for the scene parser: dicts (string keys), lists, tuples, NumPy arrays and
// scalars (by tolist()), strings, bools, ints and finite floats. Anything else, a NaN or infinite
// number (which JSON cannot hold), or nesting deeper than the parser's limit is an error naming
// its place in the document ("curves[2].bezier[1][0]").
nlohmann::ordered_json json_of(const py::handle& value, const std::string& place, const std::string& name, int depth) {
  const auto where = [&] { return name + ": " + (place.empty() ? std::string("the document") : place) + ": "; };
  if (depth > 64) fail(where() + "nested more than 64 deep (or it contains itself)");
  if (value.is_none()) return nullptr;
  if (py::isinstance<py::bool_>(value)) return value.cast<bool>();
  if (py::isinstance<py::int_>(value)) {
    try {
      return value.cast<long long>();
    } catch (const py::cast_error&) {
      fail(where() + py::repr(value).cast<std::string>() + " is too large a number");
    }
  }
  if (py::isinstance<py::float_>(value)) {
    const double number = value.cast<double>();
    if (!std::isfinite(number))
      fail(where() + py::repr(value).cast<std::string>() + " is not a finite number; give a finite number");
    return number;
  }
  if (py::isinstance<py::str>(value)) return value.cast<std::string>();
  if (py::isinstance<py::dict>(value)) {
    nlohmann::ordered_json object = nlohmann::ordered_json::object();
    for (const auto& [key, item] : value.cast<py::dict>()) {
      if (!py::isinstance<py::str>(key))
        fail(where() + "keys must be strings, got " + py::repr(key).cast<std::string>());
      const std::string text = key.cast<std::string>();
      object[text] = json_of(item, place.empty() ? text : place + "." + text, name, depth + 1);
    }
    return object;
  }
  if (py::isinstance<py::list>(value) || py::isinstance<py::tuple>(value)) {
    nlohmann::ordered_json array = nlohmann::ordered_json::array();
    std::size_t i = 0;
    for (const py::handle item : value)
      array.push_back(json_of(item, place + "[" + std::to_string(i++) + "]", name, depth + 1));
    return array;
  }
  if (py::hasattr(value, "tolist")) return json_of(value.attr("tolist")(), place, name, depth + 1);
  fail(where() + "a " + py::str(py::type::handle_of(value).attr("__name__")).cast<std::string>() +
       " cannot be held in a scene (numbers, strings, lists and dicts can)");
}

PyScene from_dict(const py::dict& document, const std::string& name) {
  const std::string text = json_of(document, "", name, 0).dump();
  return {std::make_shared<const Scene>(value_or_fail(parse_scene(text, name)))};
}

// A keyword's value as the text the command line would take for the option (options.hpp): an int
// as its digits, a float as its shortest round-trip form, a string as it is, a NumPy scalar as the
// Python number it holds; importance's curve ids also as a list or tuple of strings (joined by
// commas, as the command line takes them), or None for none. Booleans and other types are refused here, with the
// keyword's name.
std::string option_text(const py::handle& value, const SolveOptionSpec& spec) {
  const bool ids = spec.option == SolveOption::Importance;
  const auto refuse = [&] {
    fail(std::string(spec.keyword) + ": expected " +
         (ids                    ? "curve ids (a string such as 'desk,floor', or a list of strings)"
          : spec.choices.empty() ? "a number"
                                 : "a name") +
         ", got " + py::repr(value).cast<std::string>());
  };
  if (ids && value.is_none()) return {};
  if (ids && (py::isinstance<py::list>(value) || py::isinstance<py::tuple>(value))) {
    std::string text;
    for (const py::handle item : value) {
      if (!py::isinstance<py::str>(item)) refuse();
      text += (text.empty() ? "" : ",") + item.cast<std::string>();
    }
    return text;
  }
  if (py::isinstance<py::bool_>(value) || value.is_none()) refuse();
  if (py::isinstance<py::int_>(value)) return py::str(value).cast<std::string>();
  if (py::isinstance<py::float_>(value)) return format_number(value.cast<double>());
  if (py::isinstance<py::str>(value)) return value.cast<std::string>();
  if (py::hasattr(value, "item") && !py::hasattr(value, "__len__")) return option_text(value.attr("item")(), spec);
  refuse();
  return {};
}

// A keyword's settings: each one an option of options.hpp, named as the command line names it with
// underscores (--ray-width is ray_width), set as the command line sets it; the rest take the
// defaults of `flatland solve`. Messages name the keywords.
SolverSettings settings_from(const py::kwargs& keywords) {
  SolverSettings s;
  std::vector<std::string> names;
  for (const SolveOptionSpec& spec : solve_options()) names.emplace_back(spec.keyword);
  for (const auto& [key, value] : keywords) {
    const std::string keyword = py::str(key).cast<std::string>();
    const std::optional<SolveOption> option = option_by_keyword(keyword);
    if (!option) {
      std::string message = "unknown keyword '" + keyword + "'";
      if (const auto hint = closest_match(keyword, names)) message += "; did you mean '" + *hint + "'?";
      message += "; the keywords are";
      for (const std::string& name : names) message += " " + name;
      throw py::type_error(message);
    }
    if (Status status = set_solve_option(s, *option, option_text(value, spec_of(*option))); !status)
      fail(spelled(status.error().message, Spelling::Python));
  }
  if (Status status = validate(s); !status) fail(spelled(status.error().message, Spelling::Python));
  return s;
}

// The keywords with their defaults, for the docstrings of solve and Solver.
std::string keywords_help() {
  std::string text = "Keywords (the command line's options, with underscores) and their defaults:";
  const SolverSettings defaults;
  for (const SolveOptionSpec& spec : solve_options())
    text += "\n  " + std::string(spec.keyword) + "=" + solve_option_text(defaults, spec.option);
  return text;
}

// A solve: steppable (step_round, step_photons, run) and readable at any time.
class PySolver {
 public:
  PySolver(PyScene scene, const SolverSettings& settings) : scene_(std::move(scene)) {
    // A final gather's elements first: a scene it cannot gather is refused before any set-up.
    // (auto decides at the default 100 samples per curve).
    gather_ = value_or_fail(choose_gather(*scene_.scene, settings, Solver::kTargetSamples)).gather;
    // The set-up (the control variate's coarse solve and projection) stops on Ctrl-C too.
    std::optional<Result<Solver>> created;
    run_watching_signals(
        [&](const std::atomic<bool>* cancel) { created.emplace(create_solver(*scene_.scene, settings, cancel)); });
    solver_ = std::make_unique<Solver>(value_or_fail(std::move(*created)));
    if (gather_) solver_->check_target_through(gather_.get());
  }

  // Runs (with the GIL released) until the solve stops; `progress` (called about every
  // `interval` seconds with a dict) may be None. Ctrl-C stops the solve and raises KeyboardInterrupt.
  void run(const py::object& progress, double interval) {
    drive(progress, interval, [this](const std::atomic<bool>* cancel, const ProgressCallback& report, double every) {
      solver_->run(cancel, report, every);
    });
  }
  bool step_round(const py::object& progress, double interval) {
    bool stepped = false;
    drive(progress, interval, [&](const std::atomic<bool>* cancel, const ProgressCallback& report, double every) {
      stepped = solver_->step_round(cancel, report, every);
    });
    return stepped;
  }
  std::uint64_t step_photons(std::uint64_t photons) {
    std::uint64_t shot = 0;
    drive(py::none(), 0.25, [&](const std::atomic<bool>* cancel, const ProgressCallback& report, double every) {
      shot = solver_->step_photons(photons, cancel, nullptr, 0, report, every);
      solver_->include_open_round();
    });
    return shot;
  }

  // B at arc lengths `s` along a curve, front side unless `back`: shape (n,) for grey scenes,
  // (n, 3) for colour.
  py::array_t<double> radiosity(const std::string& curve_id, const py::array_t<double>& s, bool back) const {
    check_idle();
    const std::uint32_t c = scene_.curve_index(curve_id);
    const Curve& curve = scene_.scene->curves[c];
    const Side side = back ? Side::Back : Side::Front;
    // A side the curve does not have (its "sides" in the scene) neither emits nor reflects: asked
    // for, it is an error on every curve, emitter or not.
    const bool listed = curve.sides == Sides::Both || (curve.sides == Sides::Back) == back;
    if (!listed)
      fail("curve '" + curve_id + "' has no " + (back ? "back" : "front") + " side that emits or reflects (sides: " +
           (curve.sides == Sides::Front ? "front" : "back") + "); ask for back=" + (back ? "False" : "True"));
    const auto values = s.unchecked<1>();
    const int channels = scene_.scene->channels;
    std::vector<py::ssize_t> shape{values.shape(0)};
    if (channels == 3) shape.push_back(3);
    py::array_t<double> out(shape);
    double* data = out.mutable_data();
    for (py::ssize_t i = 0; i < values.shape(0); ++i) {
      const double at = values(i);
      if (!(at >= 0.0 && at <= curve.length))
        fail("s: arc lengths along '" + curve_id + "' run from 0 to " + std::to_string(curve.length) + ", got " +
             std::to_string(at));
      const Spectrum b = solver_->radiosity(c, side, point_at_arc_length(*scene_.scene, curve, at).u);
      for (int ch = 0; ch < channels; ++ch) data[i * channels + ch] = b[static_cast<std::size_t>(ch)];
    }
    return out;
  }
  py::array_t<double> coefficients(const std::string& curve_id, bool back) const {
    check_idle();
    const std::vector<double> b =
        solver_->radiosity_coefficients(scene_.curve_index(curve_id), back ? Side::Back : Side::Front);
    return py::array_t<double>(static_cast<py::ssize_t>(b.size()), b.data());
  }
  py::array_t<double> knots(const std::string& curve_id) const {
    check_idle();
    const std::vector<double>& k = solver_->storage(scene_.curve_index(curve_id)).basis.knots();
    return py::array_t<double>(static_cast<py::ssize_t>(k.size()), k.data());
  }
  py::dict stats() const {
    check_idle();
    const EnergyBooks books = solver_->books();
    py::dict d;
    d["photons"] = solver_->photons_shot();
    d["rounds"] = solver_->rounds();
    d["rays"] = solver_->rays_traced();
    d["seconds"] = solver_->seconds();
    d["stop_reason"] = to_string(solver_->stop_reason());
    d["emitted_power"] = books.emitted;
    d["absorbed_power"] = books.absorbed;
    d["escaped_power"] = books.escaped;
    d["unshot_power"] = books.unshot;
    if (scene_.scene->has_specular()) {
      d["absorbed_by_mirrors_power"] = books.absorbed_mirrors;
      d["absorbed_in_glass_power"] = books.absorbed_glass;
      d["cut_power"] = books.cut;
      d["chains_cut"] = solver_->chains_cut();
    }
    d["stopped"] = solver_->stopped();
    d["coefficients"] = solver_->coefficient_count();
    return d;
  }
  // The detectors' tallies as `flatland solve --out` writes them ("detectors"); [] without any.
  py::object detectors() const {
    check_idle();
    if (solver_->detector_layout().size == 0) return py::list();
    return py::module_::import("json").attr("loads")(detectors_to_json(*solver_).dump());
  }
  // The solve's estimated error as `flatland solve --out` writes it (stats.estimated_error).
  py::object estimated_error(int samples) const {
    check_idle();
    if (samples < 1 || samples > 1'000'000) fail("samples: must be between 1 and 1000000");
    const ErrorEstimate estimate = gather_ ? *gather_->gather_result(*solver_, samples).stats->estimated_error
                                           : estimate_error(*solver_, {solver_->settings().confidence, samples});
    return py::module_::import("json").attr("loads")(estimated_error_to_json(estimate).dump());
  }
  // With a final gather (gather="samples", or "auto" where it gathers) the samples' B and the
  // estimated error are the gather's.
  SampledResult sampled(int samples) const {
    check_idle();
    return gather_ ? gather_->gather_result(*solver_, samples) : sample_solver(*solver_, samples);
  }
  std::string to_json(int samples) const {
    check_idle();
    if (samples < 1 || samples > 1'000'000) fail("samples: must be between 1 and 1000000");
    return gather_ ? result_text(*solver_, samples, gather_->gather_result(*solver_, samples))
                   : result_text(*solver_, samples);
  }
  const PyScene& scene() const { return scene_; }

 private:
  // A solve runs with the GIL released, so another Python thread (or the progress callback) could
  // reach the solver meanwhile: it is refused rather than left to read half-written storage.
  void check_idle() const {
    if (busy_)
      throw std::runtime_error(
          "this Solver is busy: a run or step is in progress (from another thread or its progress callback)");
  }

  template <typename Work>
  void drive(const py::object& progress, double interval, Work&& work) {
    check_idle();
    if (solver_->stop_reason() == StopReason::Cancelled) fail("this solve was interrupted; make a new one");
    if (!std::isfinite(interval) || interval < 0.0) fail("interval: must be a number of seconds >= 0");
    std::atomic<bool> cancel{false};
    // What stops the work: an exception from a signal handler (Ctrl-C: KeyboardInterrupt) or from
    // the callback, kept to be raised once the solver is back in a consistent state.
    std::optional<py::error_already_set> raised;
    std::exception_ptr failure;
    // Called on this thread with the GIL released: take it, check for signals, report.
    const ProgressCallback report = [&](const SolverProgress& p) {
      py::gil_scoped_acquire gil;
      if (raised || failure) return;
      if (PyErr_CheckSignals() != 0) {
        raised.emplace();  // fetches the handler's exception
        cancel.store(true);
        return;
      }
      if (progress.is_none()) return;
      try {
        py::dict d;
        d["photons"] = p.photons;
        d["budget"] = p.budget;
        d["rounds"] = p.rounds;
        d["unshot_fraction"] = p.unshot_fraction;
        d["seconds"] = p.seconds;
        progress(d);
      } catch (py::error_already_set& error) {
        raised.emplace(std::move(error));
        cancel.store(true);
      } catch (...) {
        failure = std::current_exception();
        cancel.store(true);
      }
    };
    {
      struct Busy {
        std::atomic<bool>& flag;
        explicit Busy(std::atomic<bool>& f) : flag(f) { flag = true; }
        ~Busy() { flag = false; }
      } busy(busy_);
      py::gil_scoped_release release;
      work(&cancel, report, std::max(interval, 0.02));
    }
    if (raised) throw *raised;
    if (failure) std::rethrow_exception(failure);
    if (!warned_threads_ && !solver_->thread_shortfall().empty()) {
      warned_threads_ = true;
      warn(solver_->thread_shortfall() + "; the results are the same bits on any thread count");
    }
    if (solver_->stop_reason() == StopReason::Cancelled) {
      PyErr_SetNone(PyExc_KeyboardInterrupt);
      throw py::error_already_set();
    }
    if (solver_->stop_reason() == StopReason::BooksUnbalanced) throw std::runtime_error(solver_->books_error());
  }

  PyScene scene_;
  std::unique_ptr<Solver> solver_;
  std::unique_ptr<FinalGather> gather_;  // with gather "samples", or "auto" where it gathers
  std::atomic<bool> busy_{false};
  bool warned_threads_ = false;
};

// flatland.reference: the deterministic reference solution (flatland reference), as the document
// `flatland reference --out` writes.
std::string reference(const PyScene& scene, int samples, double max_element_length, bool estimate_error) {
  ReferenceSettings settings;
  settings.max_element_length = max_element_length;
  if (Status status = validate(settings); !status) fail(status.error().message);
  if (samples < 1 || samples > 1'000'000) fail("samples: must be between 1 and 1000000");
  const auto start = std::chrono::steady_clock::now();
  // Ctrl-C stops the form factors (and the estimate's two solves) within a row.
  std::optional<Result<ReferenceSolution>> solved;
  run_watching_signals([&](const std::atomic<bool>* cancel) {
    ReferenceSettings watched = settings;
    watched.cancel = cancel;
    solved.emplace(solve_reference(*scene.scene, watched));
  });
  const ReferenceSolution solution = value_or_fail(std::move(*solved));
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  const ReferenceSolution& r = solution;
  if (!r.thread_shortfall().empty()) warn(r.thread_shortfall() + "; the reference is the same on any thread count");
  const SampledResult sampled = sample_radiosity(
      *scene.scene, samples, [&r](std::uint32_t c, Side side, double u) { return r.radiosity(c, side, u); });
  const nlohmann::json curves = curves_to_json(sampled);
  std::optional<ReferenceErrorEstimate> estimate;
  if (estimate_error) {
    std::optional<Result<ReferenceErrorEstimate>> estimated;
    run_watching_signals([&](const std::atomic<bool>* cancel) {
      ReferenceSettings watched = settings;
      watched.cancel = cancel;
      estimated.emplace(estimate_discretisation_error(*scene.scene, watched, samples, sampled));
    });
    estimate = value_or_fail(std::move(*estimated));
  }
  return json_text(reference_result_to_json(*scene.scene, settings, solution, samples, seconds,
                                            estimate ? &*estimate : nullptr, curves));
}

// A result as data: a Solver's (sampled `samples` times per curve; to_json() writes 100), or a result
// document's text (JSON only here, at the edge).
SampledResult sampled_of(const py::object& value, const char* what, int samples = 100) {
  if (py::isinstance<PySolver>(value)) return value.cast<const PySolver&>().sampled(samples);
  if (!py::isinstance<py::str>(value))
    fail(std::string(what) + ": expected a Solver (a solve) or a result's JSON text");
  const nlohmann::json document = value_or_fail(parse_result(value.cast<std::string>(), what));
  return value_or_fail(
      sampled_from_json(document, std::string("the ") + what, std::string(what) == "reference" ? " (reference)" : ""));
}

py::dict norms(const ErrorNorms& e) {
  py::dict d;
  d["l1"] = e.l1;
  d["l2"] = e.l2;
  d["linf"] = e.linf;
  return d;
}

// flatland.compare: the errors of a result against a reference, as `compare --json` prints them.
py::dict compare(const py::object& result, const py::object& reference, const std::string& measure) {
  if (measure != "reflected" && measure != "total") fail("measure: expected reflected or total, got '" + measure + "'");
  Result<Comparison> compared = compare_sampled(sampled_of(result, "result"), sampled_of(reference, "reference"),
                                                measure == "total" ? Measure::Total : Measure::Reflected);
  if (!compared && compared.error().message == kNothingReflected)
    fail(compared.error().message + " (measure=\"total\")");
  const Comparison comparison = value_or_fail(std::move(compared));
  py::dict d;
  d["measure"] = measure;
  d["scene"] = norms(comparison.scene);
  py::dict curves;
  for (const CurveError& curve : comparison.curves) curves[py::str(curve.id)] = norms(curve.norms);
  d["curves"] = curves;
  return d;
}

// converge's methods, checked and parsed as `flatland converge --methods` parses them, with the
// study's elements, tolerance and threads as their defaults.
std::vector<ConvergeMethod> converge_methods(const std::vector<std::string>& methods, unsigned threads,
                                             const py::object& elements, double tolerance) {
  if (methods.empty()) fail("methods: give at least one method");
  SolverSettings defaults;
  defaults.threads = threads;
  defaults.tolerance = tolerance;
  if (Status status =
          set_solve_option(defaults, SolveOption::Elements, option_text(elements, spec_of(SolveOption::Elements)));
      !status)
    fail(spelled(status.error().message, Spelling::Python));
  for (std::size_t m = 0; m < methods.size(); ++m)
    for (std::size_t earlier = 0; earlier < m; ++earlier)
      if (methods[m] == methods[earlier]) fail("methods: '" + methods[m] + "' is given twice; give each method once");
  std::vector<ConvergeMethod> parsed;
  for (const std::string& text : methods) {
    Result<ConvergeMethod> method = parse_converge_method(text, defaults);
    if (!method) fail(spelled(method.error().message, Spelling::Python));
    parsed.push_back(std::move(*method));
  }
  return parsed;
}

// converge's reference: given (a Solver or a result's JSON text), or computed as converge computes
// it on `threads` threads (Ctrl-C stops it within a row). It must be of this scene, sampled as the
// runs will be, and have the measured quantity on the curve measured: said before any run.
SampledResult converge_reference(const PyScene& scene, const py::object& reference, int samples, unsigned threads,
                                 Measure measured, const std::optional<std::size_t>& curve_index,
                                 const py::object& curve) {
  SampledResult document;
  if (!reference.is_none()) {
    document = sampled_of(reference, "reference", samples);
  } else {
    std::optional<Result<ReferenceSolution>> solved;
    run_watching_signals([&](const std::atomic<bool>* cancel) {
      ReferenceSettings settings;
      settings.threads = threads;
      settings.cancel = cancel;
      solved.emplace(solve_reference(*scene.scene, settings));
    });
    const ReferenceSolution& r = value_or_fail(std::move(*solved));
    document = sample_radiosity(*scene.scene, samples,
                                [&r](std::uint32_t c, Side side, double u) { return r.radiosity(c, side, u); });
  }
  if (Status status = check_reference_of(document, *scene.scene, samples); !status)
    fail("reference: " + status.error().message +
         (check_reference_of(document, *scene.scene)
              ? "; pass samples=" + std::to_string(document.curves[0].samples.size())
              : std::string()));
  const Comparison self = value_or_fail(compare_sampled(document, document, measured));
  if (curve_index && !self.curves.at(*curve_index).measured)
    fail("curve: '" + curve.cast<std::string>() + "' has no " + (measured == Measure::Reflected ? "B - E" : "B") +
         " in the reference, so no relative error" + (measured == Measure::Reflected ? "; use measure=\"total\"" : ""));
  return document;
}

// One converge run, Ctrl-C stopping it (its set-up too) with KeyboardInterrupt: the columns of the
// command line's convergence.csv as a dict, with Python's types.
py::dict converge_row(const PyScene& scene, const ConvergeMethod& method, const SolverSettings& settings,
                      const SampledResult& document, Measure measured, const std::optional<std::size_t>& curve_index,
                      const py::object& curve, int samples) {
  std::optional<Result<ConvergeRow>> run;
  run_watching_signals([&](const std::atomic<bool>* cancel) {
    run.emplace(converge_run(*scene.scene, settings, document, measured, curve_index, samples, cancel));
  });
  const ConvergeRow row = value_or_fail(std::move(*run));
  py::dict d;
  for (const ConvergeField& field : converge_fields(method.name, settings, row, measured,
                                                    curve.is_none() ? std::string() : curve.cast<std::string>()))
    std::visit([&](const auto& value) { d[field.name] = value; }, field.value);
  return d;
}

// flatland.converge: every method at every budget and seed against one reference, as `flatland
// converge` runs them; one dict per run with the keys of its CSV's columns.
py::list converge(const PyScene& scene, const std::vector<std::string>& methods, const std::vector<double>& budgets,
                  int seeds, const py::object& reference, const std::string& measure, const py::object& curve,
                  int samples, unsigned threads, const py::object& elements, double tolerance,
                  const py::object& progress) {
  if (measure != "reflected" && measure != "total") fail("measure: expected reflected or total, got '" + measure + "'");
  if (samples < 1 || samples > 1'000'000) fail("samples: must be between 1 and 1000000");
  if (seeds < 1 || seeds > kMaxSeeds) fail("seeds: must be between 1 and " + std::to_string(kMaxSeeds));
  if (budgets.empty()) fail("budgets: give at least one budget");
  for (const double budget : budgets)
    if (!(budget >= 1.0 && budget <= static_cast<double>(kMaxPhotons)) || budget != std::floor(budget))
      fail("budgets: each must be a whole photon count from 1 to 2^50 (about 1.1e15), got " + std::to_string(budget));
  if (!curve.is_none() && !py::isinstance<py::str>(curve))
    fail("curve: expected a curve's id (a string), got " + py::repr(curve).cast<std::string>());
  const std::vector<ConvergeMethod> parsed = converge_methods(methods, threads, elements, tolerance);
  for (const double budget : budgets)
    if (Status status = check_converge_budget(budget, parsed); !status) fail(status.error().message);
  std::optional<std::size_t> curve_index;
  if (!curve.is_none()) curve_index = scene.curve_index(curve.cast<std::string>());
  const Measure measured = measure == "total" ? Measure::Total : Measure::Reflected;
  // What the scene refuses of a method, before the reference is computed.
  for (const ConvergeMethod& method : parsed)
    if (Status status = check_solver_settings(*scene.scene, method.settings); !status)
      fail(spelled(status.error().message, Spelling::Python) + " (method '" + method.name + "')");
  const SampledResult document = converge_reference(scene, reference, samples, threads, measured, curve_index, curve);

  py::list rows;
  const std::size_t total = parsed.size() * budgets.size() * static_cast<std::size_t>(seeds);
  const double largest = budgets.empty() ? 0.0 : *std::max_element(budgets.begin(), budgets.end());
  for (const ConvergeMethod& method : parsed) {
    // Auto's choice once per method, at its largest budget, as `flatland converge` makes it.
    std::string skipped;
    const ControlVariate variate =
        converge_variate(*scene.scene, method.settings, static_cast<std::uint64_t>(largest), skipped);
    for (const double budget : budgets) {
      for (int seed = 1; seed <= seeds; ++seed) {
        SolverSettings settings = method.settings;
        settings.control_variate = variate;
        settings.photons = static_cast<std::uint64_t>(budget);
        settings.seed = static_cast<std::uint64_t>(seed);
        const py::dict d = converge_row(scene, method, settings, document, measured, curve_index, curve, samples);
        rows.append(d);
        if (!progress.is_none()) {
          py::dict p;
          p["runs"] = rows.size();
          p["total"] = total;
          p["row"] = d;
          progress(p);
        }
      }
    }
  }
  return rows;
}

}  // namespace
}  // namespace flatland::python

PYBIND11_MODULE(flatland, m) {
  using namespace flatland;
  using namespace flatland::python;
  m.doc() = "Flatland: Monte Carlo radiosity in 2D (docs/python.md)";
  m.attr("__version__") = program_version();

  py::class_<PyScene>(m, "Scene", "A scene (docs/scene-format.md), checked as the command line checks it")
      .def_static("load", &load, py::arg("path"),
                  "Loads a scene file; ValueError with the one-line message if it is bad")
      .def_static("from_dict", &from_dict, py::arg("document"), py::arg("name") = "<dict>",
                  "A scene from a dict in the scene format")
      .def_property_readonly("name", [](const PyScene& s) { return s.scene->name; })
      .def_property_readonly("channels", [](const PyScene& s) { return s.scene->channels; })
      .def_property_readonly(
          "curves",
          [](const PyScene& s) {
            std::vector<std::string> ids;
            for (const Curve& curve : s.scene->curves) ids.push_back(curve.id);
            return ids;
          },
          "The curves' ids, in order")
      .def(
          "length", [](const PyScene& s, const std::string& id) { return s.scene->curves[s.curve_index(id)].length; },
          py::arg("curve"), "Arc length of a curve")
      .def("__repr__", [](const PyScene& s) {
        return "<flatland.Scene '" + s.scene->name + "': " + std::to_string(s.scene->curves.size()) + " curves>";
      });

  // The solve's keywords are its options (options.hpp), taken as **kwargs and checked one by one
  // as the command line checks them; their names and defaults are in the docstrings.
  static const std::string solver_help =
      "A solve that can be stepped and read at any time (the viewer's object).\n" + keywords_help();
  py::class_<PySolver> solver_class(m, "Solver", solver_help.c_str());
  solver_class.def(py::init([](const PyScene& scene, const py::kwargs& keywords) {
                     return std::make_unique<PySolver>(scene, settings_from(keywords));
                   }),
                   py::arg("scene"));
  solver_class
      .def("run", &PySolver::run, py::arg("progress") = py::none(), py::arg("interval") = 0.25,
           "Shoots until converged or the budget is spent (GIL released; Ctrl-C raises KeyboardInterrupt)")
      .def("step_round", &PySolver::step_round, py::arg("progress") = py::none(), py::arg("interval") = 0.25,
           "Shoots one whole round; False once the solve has stopped")
      .def("step_photons", &PySolver::step_photons, py::arg("photons"),
           "Shoots up to this many photons of the current round (bit-identical to whole rounds)")
      .def("B", &PySolver::radiosity, py::arg("curve"), py::arg("s"), py::arg("back") = false,
           "Radiosity at arc lengths s (NumPy array) along a curve, front side unless back=True")
      .def("coefficients", &PySolver::coefficients, py::arg("curve"), py::arg("back") = false,
           "Reflected radiosity coefficients b_k (B = E + sum b_k phi_k); channels interleaved")
      .def("knots", &PySolver::knots, py::arg("curve"), "Knots of the curve's storage B-splines, in u")
      .def_property_readonly("stats", &PySolver::stats)
      .def_property_readonly("detectors", &PySolver::detectors,
                             "Per detector curve: id, length, bins and the power crossing each bin from its front "
                             "and from its back (as `flatland solve --out` writes them)")
      .def_property_readonly(
          "estimated_error", [](const PySolver& s) { return s.estimated_error(100); },
          "Upper bound, at the confidence asked for (0.95), of the relative L1, L2 and Linf error of B - E, "
          "over the scene and per curve, with its parts (noise, storage, unshot): a dict as in the result file")
      .def("estimate_error", &PySolver::estimated_error, py::arg("samples") = 100,
           "The estimated error evaluated at this many samples per curve")
      .def_property_readonly("scene", &PySolver::scene)
      .def("to_json", &PySolver::to_json, py::arg("samples") = 100, "The document `flatland solve --out` writes");

  static const std::string solve_help =
      "Solves a scene (as `flatland solve`: the same options, the same bits for the same seed); returns "
      "the Solver. progress=callable is called about every quarter second with a dict.\n" +
      keywords_help();
  m.def(
      "solve",
      [](const PyScene& scene, py::kwargs keywords) {
        py::object progress = py::none();
        if (keywords.contains("progress")) {
          progress = keywords["progress"];
          PyDict_DelItemString(keywords.ptr(), "progress");
        }
        auto solver = std::make_unique<PySolver>(scene, settings_from(keywords));
        solver->run(progress, 0.25);
        return solver;
      },
      py::arg("scene"), solve_help.c_str());
  m.def("reference", &reference, py::arg("scene"), py::kw_only(), py::arg("samples") = 100,
        py::arg("max_element_length") = 0.0, py::arg("estimate_error") = false,
        "The reference solution's JSON document (as `flatland reference --out`)");
  m.def("converge", &converge, py::arg("scene"), py::kw_only(),
        py::arg("methods") = std::vector<std::string>{"constant", "linear", "cubic"},
        py::arg("budgets") = std::vector<double>{1e4, 1e5, 1e6}, py::arg("seeds") = 3,
        py::arg("reference") = py::none(), py::arg("measure") = "reflected", py::arg("curve") = py::none(),
        py::arg("samples") = 100, py::arg("threads") = 0, py::arg("elements") = py::str("auto"),
        py::arg("tolerance") = 1e-6, py::arg("progress") = py::none(),
        "Every method at every budget and seed against a reference (computed when not given), as "
        "`flatland converge` runs them; a list of dicts, one per run, keyed as its CSV's columns");
  m.def("compare", &compare, py::arg("result"), py::arg("reference"), py::arg("measure") = "reflected",
        "Relative errors (l1, l2, linf) of a result against a reference, over the scene and per curve");
}
