// The viewer with a real GL context: `flatland view` headless under Xvfb (Mesa's software GL),
// `flatland render` offscreen, their error paths, and a UI smoke test that clicks the ImGui controls
// and checks that the solve follows. This executable re-runs itself under xvfb-run when no display
// is set.
#include "viewer/picture_labels.hpp"
#include "viewer/viewer_app.hpp"
#include "viewer/window.hpp"

#include <gtest/gtest.h>
#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>
#include <thread>
#include <tuple>

#include <nlohmann/json.hpp>

#include "png/png_io.hpp"
#include "test_support.hpp"

namespace fs = std::filesystem;

namespace flatland::viewer {
namespace {

using testing::CommandRun;

std::string read_file(const fs::path& path) { return testing::read_text_file(path); }

class Viewer : public testing::ScratchDirectoryTest {
 protected:
  Viewer() : ScratchDirectoryTest("flatland-viewer") {}

  CommandRun run(const std::string& arguments, const std::string& environment = "") {
    return testing::run_flatland(arguments, directory_, environment);
  }
  std::string scene(const std::string& name) { return testing::source_path("scenes2d/" + name); }
  // A window of `width` x `height` on scenes2d/`name`, unpaced.
  ViewOptions window(const std::string& name, int width, int height) {
    ViewOptions options;
    options.scene = scene(name);
    options.width = width;
    options.height = height;
    options.vsync = false;
    return options;
  }
  // 1100 x 760, paused (UI tests step it).
  ViewOptions paused_window(const std::string& name, std::uint64_t photons) {
    ViewOptions options = window(name, 1100, 760);
    options.paused = true;
    options.settings.photons = photons;
    return options;
  }
  // 640 x 480 without panels on scenes2d/`name`, one round a frame, 12,000 paths kept of 200,000
  // photons.
  ViewOptions stepped_rounds(const std::string& name) {
    ViewOptions options = window(name, 640, 480);
    options.show_ui = false;
    options.step = "rounds=1";
    options.keep_paths = 12'000;
    options.settings.photons = 200'000;
    return options;
  }
  // A second window in one process under Xvfb now and then fails to open the display (SDL torn down
  // and set up again; seen about once in a hundred runs under the sanitizers): such a failure is
  // retried, twice, after a pause. Any other error is returned at once.
  static Result<std::unique_ptr<viewer::Viewer>> create_window(const ViewOptions& options) {
    Result<std::unique_ptr<viewer::Viewer>> created = viewer::Viewer::create(options);
    for (int attempt = 0; attempt < 2 && !created && created.error().message.find("cannot open the display") == 0;
         ++attempt) {
      std::this_thread::sleep_for(std::chrono::milliseconds(500));
      created = viewer::Viewer::create(options);
    }
    return created;
  }
};

struct Rgb {
  int r = 0, g = 0, b = 0;
};
Rgb pixel(const png::PngImage& image, int x, int y) {
  const std::size_t i =
      (static_cast<std::size_t>(y) * static_cast<std::size_t>(image.width) + static_cast<std::size_t>(x)) * 4;
  return {image.pixels[i], image.pixels[i + 1], image.pixels[i + 2]};
}
// The background colour the renderer clears to, as 8-bit values.
bool is_background(Rgb c) { return std::abs(c.r - 18) <= 3 && std::abs(c.g - 19) <= 3 && std::abs(c.b - 23) <= 3; }
// Whether any pixel within `radius` of (x, y) satisfies `test`.
template <typename Test>
bool near(const png::PngImage& image, Vec2 p, int radius, Test test) {
  for (int dy = -radius; dy <= radius; ++dy)
    for (int dx = -radius; dx <= radius; ++dx) {
      const int x = static_cast<int>(std::lround(p.x)) + dx;
      const int y = static_cast<int>(std::lround(p.y)) + dy;
      if (x >= 0 && y >= 0 && x < image.width && y < image.height && test(pixel(image, x, y))) return true;
    }
  return false;
}

// Checks a picture of the penumbra scene: curve pixels along every curve, a lit band on the lit
// part of the receiver and a dark one in the umbra, paths only inside the scene.
void check_penumbra_picture(const png::PngImage& image) {
  const Scene scene = testing::scene_from_file("scenes2d/penumbra.json");
  const ViewTransform view = fit_view(scene.bounds, image.width, image.height);
  const std::vector<CurveTrace> traces = trace_curves(scene, 8);
  for (std::size_t c = 0; c < traces.size(); ++c)
    for (const Vec2 p : traces[c].points)
      EXPECT_TRUE(near(image, view.to_pixels(p), 2, [](Rgb q) { return q.r > 150 && q.g > 150 && q.b > 150; }))
          << "no curve pixel at curve " << c << " (" << p.x << ", " << p.y << ")";
  // The receiver's band (2..9 pixels above it): bright where it sees the whole emitter (x = -1.5),
  // dark in the umbra (x = 0.3, straight under the occluder and the emitter's middle).
  auto band = [&](double x) {
    const Vec2 p = view.to_pixels({x, 0.0}) - Vec2{0.0, 5.0};
    return pixel(image, static_cast<int>(p.x), static_cast<int>(p.y));
  };
  const Rgb lit = band(-1.2);
  const Rgb umbra = band(0.3);
  EXPECT_GT(lit.r + lit.g + lit.b, 3 * 120) << "lit band " << lit.r << " " << lit.g << " " << lit.b;
  EXPECT_LT(umbra.r + umbra.g + umbra.b, lit.r + lit.g + lit.b - 150);
  // Photon paths: lit pixels between the emitter and the receiver; nothing outside the scene's
  // box (escaping paths are drawn to its edge) beyond the reach of the graphs (100 pixels).
  EXPECT_TRUE(near(image, view.to_pixels({-1.0, 0.6}), 6, [](Rgb c) { return !is_background(c); }));
  const Vec2 top_left = view.to_pixels({scene.bounds.lower.x, scene.bounds.upper.y}) - Vec2{100.0, 100.0};
  const Vec2 bottom_right = view.to_pixels({scene.bounds.upper.x, scene.bounds.lower.y}) + Vec2{100.0, 100.0};
  int outside = 0;
  for (int x = 0; x < image.width; x += 3)
    for (int y = 0; y < image.height; y += 3)
      if (x < top_left.x || y < top_left.y || x > bottom_right.x || y > bottom_right.y) {
        ++outside;
        ASSERT_TRUE(is_background(pixel(image, x, y))) << "light outside the scene at " << x << ", " << y;
      }
  EXPECT_GT(outside, 1000);  // the picture has room around the scene to check
}

TEST_F(Viewer, HeadlessViewWritesTheSceneWithCurvesLightAndPaths) {
  const fs::path shot = directory_ / "view.png";
  const fs::path whole = directory_ / "window.png";
  const CommandRun result = run("view " + scene("penumbra.json") +
                                " --frames 4 --step rounds=1 --width 640 --height 640 --photons 2e5 "
                                "--screenshot " +
                                shot.string() + " --screenshot-ui " + whole.string());
  ASSERT_EQ(result.exit_code, 0) << result.err;
  Result<png::PngImage> image = png::read_png(shot.string());
  ASSERT_TRUE(image) << image.error().message;
  EXPECT_EQ(image->width, 640);
  EXPECT_EQ(image->height, 640);
  check_penumbra_picture(*image);
  // The window's own picture has the panels over the scene: ImGui's window title bars.
  Result<png::PngImage> window = png::read_png(whole.string());
  ASSERT_TRUE(window) << window.error().message;
  EXPECT_NE(image->pixels, window->pixels);
}

TEST_F(Viewer, RenderNeedsNoDisplayAndDrawsTheSamePicture) {
  const fs::path out = directory_ / "render.png";
  const fs::path json = directory_ / "render.json";
  const CommandRun result =
      run("render " + scene("penumbra.json") + " --photons 2e5 --width 640 --height 640 --no-labels --out " +
              out.string() + " --result " + json.string(),
          "env -u DISPLAY -u WAYLAND_DISPLAY");
  ASSERT_EQ(result.exit_code, 0) << result.err;
  Result<png::PngImage> image = png::read_png(out.string());
  ASSERT_TRUE(image) << image.error().message;
  check_penumbra_picture(*image);
  // Its result is the solve's with the same settings, bit for bit (render steps the solver in
  // pieces to keep paths; its control variate is the viewer's default, none).
  const fs::path solved = directory_ / "solve.json";
  ASSERT_EQ(
      run("solve " + scene("penumbra.json") + " --photons 2e5 --control-variate none --quiet --out " + solved.string())
          .exit_code,
      0);
  nlohmann::json a = nlohmann::json::parse(read_file(json));
  nlohmann::json b = nlohmann::json::parse(read_file(solved));
  a["stats"].erase("seconds");
  b["stats"].erase("seconds");
  EXPECT_EQ(a, b);
}

// A picture for a reader, not a session: render leaves out the newest journey and the nodes'
// diamonds (unexplained in a picture without the viewer's legends) unless asked for them.
TEST_F(Viewer, RenderDrawsTheJourneyAndNodesOnlyWhenAsked) {
  auto render = [&](const std::string& name, const std::string& flags) {
    const fs::path out = directory_ / name;
    const CommandRun r = run("render " + scene("penumbra.json") + " --photons 2e4 --width 320 --height 320 --quiet " +
                                 flags + " --out " + out.string(),
                             "env -u DISPLAY -u WAYLAND_DISPLAY");
    EXPECT_EQ(r.exit_code, 0) << r.err;
    Result<png::PngImage> image = png::read_png(out.string());
    EXPECT_TRUE(image) << (image ? "" : image.error().message);
    return image ? image->pixels : std::vector<std::uint8_t>{};
  };
  const std::vector<std::uint8_t> plain = render("plain.png", "");
  const std::vector<std::uint8_t> marked = render("marked.png", "--journey --nodes");
  ASSERT_EQ(plain.size(), marked.size());
  std::size_t differing = 0;
  for (std::size_t i = 0; i < plain.size(); ++i) differing += plain[i] != marked[i];
  EXPECT_GT(differing, 30u);  // the journey's line and four diamonds at least
}

TEST_F(Viewer, NoDisplayIsOneLineAndExitTwo) {
  const CommandRun result = run("view " + scene("penumbra.json") + " --frames 1", "env -u DISPLAY -u WAYLAND_DISPLAY");
  EXPECT_EQ(result.exit_code, 2);
  EXPECT_EQ(std::count(result.err.begin(), result.err.end(), '\n'), 1) << result.err;
  EXPECT_NE(result.err.find("display"), std::string::npos) << result.err;
  EXPECT_NE(result.err.find("flatland render"), std::string::npos) << result.err;
  // A display that is named but cannot be reached: the message names it, still one line (no
  // Wayland library complaining about XDG_RUNTIME_DIR on the side).
  const CommandRun unreachable =
      run("view " + scene("penumbra.json") + " --frames 1", "env -u WAYLAND_DISPLAY -u XDG_RUNTIME_DIR DISPLAY=:9731");
  EXPECT_EQ(unreachable.exit_code, 2);
  EXPECT_EQ(std::count(unreachable.err.begin(), unreachable.err.end(), '\n'), 1) << unreachable.err;
  EXPECT_NE(unreachable.err.find("':9731'"), std::string::npos) << unreachable.err;
}

TEST_F(Viewer, ShaderErrorsPrintTheGlLogAndExitTwo) {
  const fs::path shaders = directory_ / "shaders";
  fs::copy(testing::source_path("shaders"), shaders);
  {
    std::ofstream broken(shaders / "paths.frag");
    broken << "#version 330 core\nout vec4 o_colour;\nvoid main() { o_colour = undefined_thing; }\n";
  }
  const fs::path out = directory_ / "never.png";
  CommandRun result = run("render " + scene("penumbra.json") + " --photons 1e4 --out " + out.string() + " --shaders " +
                          shaders.string());
  EXPECT_EQ(result.exit_code, 2);
  EXPECT_NE(result.err.find("paths.frag"), std::string::npos) << result.err;
  EXPECT_NE(result.err.find("undefined_thing"), std::string::npos) << result.err;  // the GL log
  EXPECT_FALSE(fs::exists(out));
  // The viewer reports the same way.
  result = run("view " + scene("penumbra.json") + " --frames 1 --shaders " + shaders.string());
  EXPECT_EQ(result.exit_code, 2);
  EXPECT_NE(result.err.find("paths.frag"), std::string::npos) << result.err;
}

// The light as a field (render's default): in the mirror room the sunbeam between the window and
// the floor mirror stands out of the interreflected haze, which is not washed out to white; as
// paths, the haze of the last rounds is as bright as the beam.
TEST_F(Viewer, RenderFieldShowsTheBeamAboveTheHaze) {
  const Scene scene = testing::scene_from_file("scenes2d/mirror_room.json");
  auto contrast = [&](const std::string& light) {
    const fs::path out = directory_ / ("mirror_" + light + ".png");
    const CommandRun r = run("render " + this->scene("mirror_room.json") +
                             " --photons 2e5 --width 400 --height 400 --quiet --no-graph --no-labels --light " + light +
                             " --out " + out.string());
    EXPECT_EQ(r.exit_code, 0) << r.err;
    Result<png::PngImage> image = png::read_png(out.string());
    EXPECT_TRUE(image) << image.error().message;
    const ViewTransform view = fit_view(scene.bounds, 400, 400);
    auto brightness = [&](Vec2 p) {
      const Vec2 q = view.to_pixels(p);
      double sum = 0.0;
      for (int dy = -2; dy <= 2; ++dy)
        for (int dx = -2; dx <= 2; ++dx) {
          const Rgb c = pixel(*image, static_cast<int>(q.x) + dx, static_cast<int>(q.y) + dy);
          sum += (c.r + c.g + c.b) / 3.0;
        }
      return sum / 25.0;
    };
    // In the beam halfway from the window to the mirror; in the haze of the upper left corner.
    return std::pair{brightness({1.0, 0.8}), brightness({0.8, 2.6})};
  };
  const auto [beam, haze] = contrast("field");
  EXPECT_GT(beam, 2.0 * haze) << "beam " << beam << ", haze " << haze;
  EXPECT_LT(haze, 160.0);
  const auto [path_beam, path_haze] = contrast("paths");
  EXPECT_LT(path_beam / path_haze, beam / haze);
}

// Every lesson link of docs/web.md round-trips through the viewer's link (the web page's Copy
// link; --report prints it): what a link sets that the link carries comes back with its value,
// and the link of a viewer opened from a link is that link again.
TEST_F(Viewer, LessonLinksRoundTripThroughTheViewersLink) {
  const std::string web = read_file(testing::source_path("docs/web.md"));
  const std::size_t section = web.find("## Lesson links");
  ASSERT_NE(section, std::string::npos);
  const std::string lessons = web.substr(section, web.find("\n## ", section + 1) - section);
  std::vector<std::string> queries;
  for (std::size_t at = lessons.find("`index.html?"); at != std::string::npos;
       at = lessons.find("`index.html?", at + 1)) {
    const std::size_t begin = at + std::string("`index.html?").size();
    queries.push_back(lessons.substr(begin, lessons.find('`', begin) - begin));
  }
  ASSERT_GE(queries.size(), 8u);
  using Params = std::vector<std::pair<std::string, std::string>>;
  auto parse = [](const std::string& query) {
    Params params;
    std::stringstream items(query);
    for (std::string item; std::getline(items, item, '&');) {
      const std::size_t eq = item.find('=');
      params.emplace_back(item.substr(0, eq), eq == std::string::npos ? "" : item.substr(eq + 1));
    }
    return params;
  };
  // The page's translation: scene=NAME is scenes2d/NAME.json, flags given as 1, the rest --NAME VALUE.
  auto link_of = [&](const std::string& scene_name, const Params& params) {
    std::string arguments = "view " + scene(scene_name + ".json") + " --frames 2 --width 900 --height 640 --report";
    for (const auto& [key, value] : params) {
      if (key == "scene") continue;
      if (key == "present" || key == "first-photons" || key == "paused")
        arguments += " --" + key;
      else
        arguments += " --" + key + " " + value;
    }
    const CommandRun r = run(arguments);
    EXPECT_EQ(r.exit_code, 0) << arguments << ": " << r.err;
    const std::size_t at = r.out.find("link      ");
    EXPECT_NE(at, std::string::npos) << r.out;
    if (at == std::string::npos) return std::string();
    const std::size_t begin = at + 10;
    std::string link = r.out.substr(begin, r.out.find('\n', begin) - begin);
    return link == "(every setting at its default)" ? std::string() : link;
  };
  // Parameters the viewer's link does not carry: how frames are stepped and shown.
  const std::set<std::string> uncarried = {"scene",   "step",     "paused", "ui-scale",
                                           "no-ui",   "exposure", "fade",   "paths-per-frame",
                                           "max-fps", "width",    "height", "frames"};
  for (const std::string& query : queries) {
    SCOPED_TRACE(query);
    const Params params = parse(query);
    std::string scene_name;
    bool first_photons = false;
    for (const auto& [key, value] : params) {
      if (key == "scene") scene_name = value;
      if (key == "first-photons") first_photons = true;
    }
    ASSERT_FALSE(scene_name.empty());
    const std::string link = link_of(scene_name, params);
    const Params carried = parse(link);
    auto value_of = [&](const std::string& key) -> std::optional<std::string> {
      for (const auto& [k, v] : carried)
        if (k == key) return v;
      return std::nullopt;
    };
    const Scene loaded = testing::scene_from_file("scenes2d/" + scene_name + ".json");
    for (const auto& [key, value] : params) {
      if (uncarried.count(key) != 0) continue;
      if (key == "colour-by" && first_photons) continue;  // the preset's own colouring
      const std::optional<std::string> back = value_of(key);
      ASSERT_TRUE(back.has_value()) << key << " is not in the link " << link;
      if (key == "select") {
        // By index: the curve the id names.
        std::size_t index = loaded.curves.size();
        for (std::size_t c = 0; c < loaded.curves.size(); ++c)
          if (loaded.curves[c].id == value) index = c;
        EXPECT_EQ(*back, std::to_string(index)) << link;
      } else if (key == "present" || key == "first-photons") {
        EXPECT_EQ(*back, "1");
      } else {
        EXPECT_EQ(*back, value) << key << " in " << link;
      }
    }
    Params again = carried;
    EXPECT_EQ(link_of(scene_name, again), link);
  }
}

// A picture says what it shows: a title band above the stage and the colour key below it (the
// key's scale ends in its brightest colour), the scene fitted between them.
TEST_F(Viewer, RenderLabelsTheSceneAboveAndTheKeyBelow) {
  const fs::path out = directory_ / "labelled.png";
  const CommandRun r =
      run("render " + scene("penumbra.json") + " --photons 2e4 --width 640 --height 480 --quiet --out " + out.string());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  Result<png::PngImage> image = png::read_png(out.string());
  ASSERT_TRUE(image) << image.error().message;
  const PictureLayout layout = picture_layout(640, 480, true);
  ASSERT_GT(layout.title.height(), 20.0f);
  ASSERT_GT(layout.key.height(), 60.0f);
  EXPECT_EQ(layout.stage.y0, layout.title.y1);
  EXPECT_EQ(layout.stage.y1, layout.key.y0);
  auto text_pixels = [&](const PixelRect& band) {
    int count = 0;
    for (int y = static_cast<int>(band.y0); y < static_cast<int>(band.y1); ++y)
      for (int x = 0; x < 640; ++x)
        if (!is_background(pixel(*image, x, y))) ++count;
    return count;
  };
  EXPECT_GT(text_pixels(layout.title), 300);
  EXPECT_GT(text_pixels(layout.key), 1000);
  // The scene lies on the stage: the receiver's ends (y = 0) are drawn between the bands.
  const Scene penumbra = testing::scene_from_file("scenes2d/penumbra.json");
  const ViewTransform view = fit_view(penumbra.bounds, 640, 480, layout.stage);
  const Vec2 end = view.to_pixels(penumbra.curves[0].points.front());
  EXPECT_GT(end.y, layout.stage.y0);
  EXPECT_LT(end.y, layout.stage.y1);
  EXPECT_FALSE(is_background(pixel(*image, static_cast<int>(end.x), static_cast<int>(end.y))));
  // Too small for text: the whole picture is the stage.
  EXPECT_EQ(picture_layout(300, 200, true).title.height(), 0.0f);
  EXPECT_EQ(picture_layout(640, 480, false).stage, (PixelRect{0.0f, 0.0f, 640.0f, 480.0f}));
}

TEST_F(Viewer, BadOptionsAreOneLineErrors) {
  for (const char* arguments :
       {"view --step sometimes --frames 1", "view --frames 2 --photons -5", "view no-such-scene.json --frames 1",
        "render --out x.png", "view --exposure nan --frames 1", "render --exposure nan --out x.png",
        "view --max-fps -5 --frames 1", "view --fade 2 --frames 1", "view --light rays --frames 1",
        "render --light rays --out x.png", "render --field-flights -1 --out x.png"}) {
    const CommandRun result = run(arguments);
    EXPECT_EQ(result.exit_code, 2) << arguments;
    EXPECT_EQ(std::count(result.err.begin(), result.err.end(), '\n'), 1) << arguments << ": " << result.err;
  }
}

// Runs frames until `done` or a frame limit.
template <typename Done>
void frames_until(viewer::Viewer& viewer, Done done, int limit = 200) {
  for (int i = 0; i < limit && !done(); ++i) viewer.frame();
}

void click(viewer::Viewer& viewer, const std::string& label) {
  const auto rect = viewer.widget_rect(label);
  ASSERT_TRUE(rect.has_value()) << "no widget '" << label << "'";
  viewer.queue_click(0.5f * ((*rect)[0] + (*rect)[2]), 0.5f * ((*rect)[1] + (*rect)[3]));
  for (int i = 0; i < 4; ++i) viewer.frame();  // move, press, release, and one to react
}

TEST_F(Viewer, UiControlsDriveTheSolve) {
  const ViewOptions options = paused_window("penumbra.json", 100'000);
  Result<std::unique_ptr<viewer::Viewer>> created = viewer::Viewer::create(options);
  ASSERT_TRUE(created) << created.error().message;
  viewer::Viewer& viewer = **created;
  frames_until(
      viewer, [] { return false; }, 3);
  EXPECT_EQ(viewer.settings().basis, BasisKind::Cubic);

  // Change the basis through its combo box: the solve restarts with it.
  click(viewer, "basis");
  click(viewer, "basis:linear");
  EXPECT_EQ(viewer.settings().basis, BasisKind::Linear);
  viewer.session().wait_idle();
  frames_until(viewer, [&] { return viewer.session().snapshot()->settings.basis == BasisKind::Linear; });
  EXPECT_EQ(viewer.session().snapshot()->settings.basis, BasisKind::Linear);

  // Step one photon, then one round.
  click(viewer, "Photon");
  viewer.session().wait_idle();
  EXPECT_EQ(viewer.session().snapshot()->progress.photons, 1u);
  click(viewer, "Round");
  viewer.session().wait_idle();
  EXPECT_EQ(viewer.session().snapshot()->progress.rounds, 1u);
  EXPECT_EQ(viewer.session().snapshot()->round_photons, 0u);

  // Run to the end of the budget; then the solve is no longer running (the button says Run).
  click(viewer, "Run");
  viewer.session().wait_idle();
  EXPECT_NE(viewer.session().snapshot()->stop_reason, StopReason::Running);
  EXPECT_FALSE(viewer.session().running());

  // Click the receiver (curve 2): the curve panel opens on it.
  const Vec2 at = viewer.view().to_pixels({2.5, 0.0});
  viewer.queue_click(static_cast<float>(at.x), static_cast<float>(at.y));
  frames_until(
      viewer, [&] { return viewer.selected_curve() == 2; }, 6);
  EXPECT_EQ(viewer.selected_curve(), 2);
  EXPECT_TRUE(viewer.widget_rect("Run").has_value());

  // Keyboard: Space pauses, Backspace restarts the solve.
  const std::uint64_t generation = viewer.session().snapshot()->generation;
  viewer.queue_key(' ');
  viewer.queue_key(viewer::keys::kBackspace);
  frames_until(
      viewer, [] { return false; }, 3);
  viewer.session().wait_idle();
  EXPECT_FALSE(viewer.session().running());
  EXPECT_NE(viewer.session().snapshot()->generation, generation);
  EXPECT_EQ(viewer.session().snapshot()->progress.photons, 0u);

  // The gather menu restarts the solve with the choice; the light menu switches the stage between
  // the paths and the field; the link carries both.
  EXPECT_EQ(viewer.settings().gather, GatherMode::Auto);
  click(viewer, "gather");
  click(viewer, "gather:none");
  viewer.session().wait_idle();
  frames_until(viewer, [&] { return viewer.session().snapshot()->settings.gather == GatherMode::None; });
  EXPECT_EQ(viewer.session().snapshot()->settings.gather, GatherMode::None);
  EXPECT_EQ(viewer.light_view(), LightView::Auto);
  click(viewer, "light as");
  click(viewer, "light as:field");
  EXPECT_EQ(viewer.light_view(), LightView::Field);
  EXPECT_NE(viewer.link_query().find("light=field"), std::string::npos) << viewer.link_query();
  EXPECT_NE(viewer.link_query().find("gather=none"), std::string::npos) << viewer.link_query();
}

// The docked layout: with every default panel and the curve panel open, at several window sizes
// (the window resized as a user would), no panel covers the scene's bounding box on screen; the
// status panel shows the energy books without a scroll bar at the default size; Tab hides the
// panels and the scene is fitted to the whole window.
TEST_F(Viewer, PanelsNeverCoverTheScene) {
  // One window for every scene and size (SDL, torn down and set up again many times in one
  // process under Xvfb, now and then failed to open the display).
  ViewOptions options = paused_window("room_reflector.json", 10'000);
  options.width = 1280;
  options.height = 800;
  Result<std::unique_ptr<viewer::Viewer>> created = viewer::Viewer::create(options);
  ASSERT_TRUE(created) << created.error().message;
  viewer::Viewer& viewer = **created;
  for (const char* name : {"room_reflector.json", "syndrome.json", "curved_room.json", "penumbra.json"}) {
    ASSERT_TRUE(viewer.open_scene(scene(name))) << name;
    viewer.select_curve(0);
    for (const auto& [width, height] : {std::pair{1280, 800}, {1024, 768}, {1366, 768}, {1200, 900}}) {
      viewer.resize_window(width, height);
      frames_until(
          viewer, [&] { return viewer.view().width == width && viewer.view().height == height; }, 50);
      frames_until(
          viewer, [] { return false; }, 3);
      ASSERT_EQ(viewer.view().width, width) << name;
      ASSERT_EQ(viewer.view().height, height) << name;
      const Box& bounds = viewer.scene().bounds;
      const Vec2 a = viewer.view().to_pixels(bounds.lower);
      const Vec2 b = viewer.view().to_pixels(bounds.upper);
      const PixelRect box{static_cast<float>(std::min(a.x, b.x)), static_cast<float>(std::min(a.y, b.y)),
                          static_cast<float>(std::max(a.x, b.x)), static_cast<float>(std::max(a.y, b.y))};
      EXPECT_GT(box.width(), 0.3f * static_cast<float>(width)) << name << ": the scene fills its stage";
      for (const char* panel : {"Solve", "Display", "Status", "Curve"}) {
        const std::optional<PixelRect> rect = viewer.panel_rect(panel);
        ASSERT_TRUE(rect.has_value()) << panel;
        EXPECT_FALSE(rect->overlaps(box)) << name << " at " << width << "x" << height << ": " << panel;
      }
      if (width == 1280) {
        EXPECT_FALSE(viewer.panel_scrolls("Status")) << name;
      }
    }
  }
  viewer.queue_key(viewer::keys::kTab);
  frames_until(
      viewer, [] { return false; }, 3);
  EXPECT_FALSE(viewer.panel_rect("Solve").has_value());
  EXPECT_EQ(viewer.layout().stage.width(), static_cast<float>(viewer.view().width));
}

// The classroom sizes: at 1280x720 and at 1920x1080 with --ui-scale 2 no panel cuts its labels
// off, the colour key's strip lies inside the window under the stage and beside the columns; in
// presentation mode (M) the stage spans the window's width but for the inspected curve's B(s) in
// a column at the right, with the counter above it and the key under it: nothing lies on the
// stage. M again brings the panels back.
TEST_F(Viewer, ClassroomSizesKeepLabelsAndTheKeyInView) {
  std::unique_ptr<viewer::Viewer> last;
  for (const auto& [width, height, scale] : {std::tuple{1280, 720, 1.0f}, {1920, 1080, 2.0f}}) {
    ViewOptions options = paused_window("default.json", 10'000);
    options.width = width;
    options.height = height;
    options.ui_scale = scale;
    last.reset();  // one window at a time
    Result<std::unique_ptr<viewer::Viewer>> created = create_window(options);
    ASSERT_TRUE(created) << created.error().message;
    last = std::move(*created);
    viewer::Viewer& viewer = *last;
    viewer.select_curve(4);
    frames_until(
        viewer, [] { return false; }, 4);
    ASSERT_EQ(viewer.view().width, width);
    for (const char* panel : {"Solve", "Display", "Status", "Curve", "Key"}) {
      ASSERT_TRUE(viewer.panel_rect(panel).has_value()) << panel;
      EXPECT_FALSE(viewer.panel_clips(panel)) << panel << " at " << width << "x" << height << " scale " << scale;
    }
    // Every control in view: Solve and Display need no scroll bar (Display moves to the right
    // column when the left one is too short for it).
    EXPECT_FALSE(viewer.panel_scrolls("Solve")) << width << "x" << height;
    EXPECT_FALSE(viewer.panel_scrolls("Display")) << width << "x" << height;
    const PixelRect key = *viewer.panel_rect("Key");
    EXPECT_GE(key.x0, viewer.panel_rect("Solve")->x1 - 0.5f);
    EXPECT_LE(key.x1, viewer.panel_rect("Status")->x0 + 0.5f);
    EXPECT_LE(key.y1, static_cast<float>(height) + 0.5f);
    EXPECT_GE(key.y0, viewer.layout().stage.y1 - 0.5f);
  }
  viewer::Viewer& viewer = *last;
  viewer.queue_key('m');
  frames_until(
      viewer, [] { return false; }, 4);
  EXPECT_TRUE(viewer.presentation());
  EXPECT_FALSE(viewer.panel_rect("Solve").has_value());
  const PixelRect stage = viewer.layout().stage;
  const std::optional<PixelRect> plot = viewer.panel_rect("Curve plot");
  ASSERT_TRUE(plot.has_value());
  EXPECT_EQ(stage.x0, 0.0f);
  EXPECT_NEAR(stage.x1, plot->x0, 0.5f);
  EXPECT_GE(stage.width(), 0.55f * static_cast<float>(viewer.view().width));
  for (const char* overlay : {"Counter", "Curve plot", "Key"}) {
    const std::optional<PixelRect> rect = viewer.panel_rect(overlay);
    ASSERT_TRUE(rect.has_value()) << overlay;
    EXPECT_FALSE(viewer.panel_clips(overlay)) << overlay;
    EXPECT_GE(rect->x0, 0.0f);
    EXPECT_LE(rect->x1, static_cast<float>(viewer.view().width) + 0.5f);
    // Beside, above or below the stage, never on it.
    const bool apart = rect->x1 <= stage.x0 + 0.5f || rect->x0 >= stage.x1 - 0.5f || rect->y1 <= stage.y0 + 0.5f ||
                       rect->y0 >= stage.y1 - 0.5f;
    EXPECT_TRUE(apart) << overlay << " lies on the stage";
  }
  viewer.queue_key('m');
  frames_until(
      viewer, [] { return false; }, 3);
  EXPECT_TRUE(viewer.panel_rect("Solve").has_value());
}

// The transport control switches to random walks; stepping photons then keeps whole journeys (a run
// of paths with bounce 0, 1, 2, ..., each starting where the last landed, ending once), and the
// paths can be coloured by bounce.
TEST_F(Viewer, WalkTransportStepsWholeJourneys) {
  const ViewOptions options = paused_window("room_reflector.json", 10'000);
  Result<std::unique_ptr<viewer::Viewer>> created = viewer::Viewer::create(options);
  ASSERT_TRUE(created) << created.error().message;
  viewer::Viewer& viewer = **created;
  frames_until(
      viewer, [] { return false; }, 3);
  click(viewer, "transport");
  click(viewer, "transport:walk");
  EXPECT_EQ(viewer.settings().transport, Transport::Walk);
  viewer.session().wait_idle();
  frames_until(viewer, [&] { return viewer.session().snapshot()->settings.transport == Transport::Walk; });
  for (int i = 0; i < 5; ++i) {
    click(viewer, "Photon");
    viewer.session().wait_idle();
  }
  frames_until(viewer, [&] { return viewer.session().snapshot()->progress.photons == 5; });
  const std::vector<PathRecord>& paths = viewer.session().snapshot()->paths;
  ASSERT_FALSE(paths.empty());
  int walks = 0;
  for (std::size_t i = 0; i < paths.size(); ++i) {
    if (paths[i].bounce == 0) {
      ++walks;
    } else {
      ASSERT_GT(i, 0u);
      EXPECT_EQ(paths[i].bounce, paths[i - 1].bounce + 1);
      EXPECT_LT(flatland::length(paths[i].from - paths[i - 1].to), 1e-9 * viewer.scene().scale);
    }
    const bool last = i + 1 == paths.size() || paths[i + 1].bounce == 0;
    EXPECT_EQ(last, paths[i].escaped || paths[i].absorbed) << "path " << i;
  }
  EXPECT_EQ(walks, 5);
  click(viewer, "colour by");
  click(viewer, "colour by:bounce");
  EXPECT_EQ(viewer.path_colour(), PathColour::Bounce);
  // With walks the panel offers their score; back to shooting, the score is collision again (a
  // score with shooting would be refused).
  click(viewer, "walk score");
  click(viewer, "walk score:survival");
  EXPECT_EQ(viewer.settings().walk_score, WalkScore::Survival);
  viewer.session().wait_idle();
  frames_until(viewer, [&] { return viewer.session().snapshot()->settings.walk_score == WalkScore::Survival; });
  click(viewer, "transport");
  click(viewer, "transport:shooting");
  EXPECT_EQ(viewer.settings().transport, Transport::Shooting);
  EXPECT_EQ(viewer.settings().walk_score, WalkScore::Collision);
  viewer.session().wait_idle();
  frames_until(viewer, [&] { return viewer.session().snapshot()->settings.transport == Transport::Shooting; });
}

// The inspected curve's "importance" box adds it to the curves importance favours (the solve
// restarts with them, and the link carries them); unticked, it leaves them; with walks, which
// refuse importance, the curves are cleared.
TEST_F(Viewer, ImportanceBoxFavoursTheInspectedCurve) {
  const ViewOptions options = paused_window("row_of_rooms.json", 20'000);
  Result<std::unique_ptr<viewer::Viewer>> created = viewer::Viewer::create(options);
  ASSERT_TRUE(created) << created.error().message;
  viewer::Viewer& viewer = **created;
  std::size_t desk = 0;
  while (desk < viewer.scene().curves.size() && viewer.scene().curves[desk].id != "desk") ++desk;
  ASSERT_LT(desk, viewer.scene().curves.size());
  viewer.select_curve(static_cast<int>(desk));
  frames_until(
      viewer, [] { return false; }, 3);
  click(viewer, "importance");
  EXPECT_EQ(viewer.settings().importance, std::vector<std::string>{"desk"});
  viewer.session().wait_idle();
  frames_until(viewer, [&] { return viewer.session().snapshot()->settings.importance.size() == 1; });
  EXPECT_NE(viewer.link_query().find("importance=desk"), std::string::npos) << viewer.link_query();
  // The status panel's new line moves the curve panel, and the box with it.
  frames_until(
      viewer, [] { return false; }, 3);
  click(viewer, "importance");
  EXPECT_TRUE(viewer.settings().importance.empty());
  frames_until(
      viewer, [] { return false; }, 3);
  click(viewer, "importance");
  EXPECT_EQ(viewer.settings().importance.size(), 1u);
  click(viewer, "transport");
  click(viewer, "transport:walk");
  EXPECT_EQ(viewer.settings().transport, Transport::Walk);
  EXPECT_TRUE(viewer.settings().importance.empty());
  viewer.session().wait_idle();
  frames_until(viewer, [&] { return viewer.session().snapshot()->settings.transport == Transport::Walk; });
  EXPECT_TRUE(viewer.session().snapshot()->settings.importance.empty());
  // The First photons preset (walks) clears them too; another scene keeps only the ids it has.
  const auto favour_the_desk_with_shooting = [&] {
    click(viewer, "transport");
    click(viewer, "transport:shooting");
    frames_until(
        viewer, [] { return false; }, 3);
    click(viewer, "importance");
    return viewer.settings().importance.size() == 1;
  };
  ASSERT_TRUE(favour_the_desk_with_shooting());
  click(viewer, "First photons");
  EXPECT_EQ(viewer.settings().transport, Transport::Walk);
  EXPECT_TRUE(viewer.settings().importance.empty());
  ASSERT_TRUE(favour_the_desk_with_shooting());
  ASSERT_TRUE(viewer.open_scene(testing::source_path("scenes2d/penumbra.json")));
  EXPECT_TRUE(viewer.settings().importance.empty());
  viewer.session().wait_idle();
  EXPECT_EQ(viewer.session().snapshot()->error, "");  // a solve, not "has no curve 'desk'"
}

// The lecture preset: one button switches to random walks coloured by bounce and steps a photon
// every kFirstPhotonsSeconds on its own; stepping by hand takes over.
TEST_F(Viewer, FirstPhotonsPresetStepsWalksSlowly) {
  const ViewOptions options = paused_window("room_reflector.json", 10'000);
  Result<std::unique_ptr<viewer::Viewer>> created = viewer::Viewer::create(options);
  ASSERT_TRUE(created) << created.error().message;
  viewer::Viewer& viewer = **created;
  frames_until(
      viewer, [] { return false; }, 3);
  click(viewer, "First photons");
  EXPECT_EQ(viewer.settings().transport, Transport::Walk);
  EXPECT_EQ(viewer.path_colour(), PathColour::Bounce);
  EXPECT_TRUE(viewer.slow_stepping());
  const auto start = std::chrono::steady_clock::now();
  frames_until(
      viewer, [&] { return viewer.session().snapshot()->progress.photons >= 2; }, 100'000);
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  EXPECT_GE(viewer.session().snapshot()->progress.photons, 2u);
  EXPECT_GE(seconds, viewer::Viewer::kFirstPhotonsSeconds * 0.9);  // slowly: two photons take a step's wait
  click(viewer, "Photon");
  EXPECT_FALSE(viewer.slow_stepping());
}

// A lesson from a link: --first-photons (the web page's first-photons=1) starts in the preset, as
// pressing 1 does, and the command line accepts it.
TEST_F(Viewer, FirstPhotonsOptionStartsInThePreset) {
  ViewOptions options = paused_window("room_reflector.json", 10'000);
  options.first_photons = true;
  Result<std::unique_ptr<viewer::Viewer>> created = create_window(options);
  ASSERT_TRUE(created) << created.error().message;
  viewer::Viewer& viewer = **created;
  EXPECT_EQ(viewer.settings().transport, Transport::Walk);
  EXPECT_EQ(viewer.path_colour(), PathColour::Bounce);
  EXPECT_EQ(viewer.paths_kept(), 24u);
  EXPECT_TRUE(viewer.slow_stepping());
  frames_until(
      viewer, [&] { return viewer.session().snapshot()->progress.photons >= 1; }, 100'000);
  EXPECT_GE(viewer.session().snapshot()->progress.photons, 1u);
  const CommandRun help = run("view --help");
  EXPECT_NE(help.out.find("--first-photons"), std::string::npos);
}

// Stepping walks one photon a frame draws the newest journey over the kept paths: each of its hops
// in its bounce's colour (sampled a third of the way along, away from the arrowhead).
TEST_F(Viewer, SteppedWalksDrawTheNewestJourney) {
  ViewOptions options;
  options.scene = scene("room_reflector.json");
  options.width = 900;
  options.height = 600;
  options.vsync = false;
  options.step = "photons=1";
  options.colour_by = "power";  // the kept paths grey: only the journey has the bounce colours
  options.keep_paths = 30;
  options.path_exposure = 0.2f;
  options.settings.photons = 1000;
  options.settings.transport = Transport::Walk;
  Result<std::unique_ptr<viewer::Viewer>> created = viewer::Viewer::create(options);
  ASSERT_TRUE(created) << created.error().message;
  viewer::Viewer& viewer = **created;
  // Frames until the newest walk has at least two hops that land inside the scene.
  std::pair<std::size_t, std::size_t> journey{0, 0};
  for (int i = 0; i < 60; ++i) {
    viewer.frame();
    journey = newest_journey(viewer.session().snapshot()->paths);
    if (journey.second - journey.first >= 2) break;
  }
  ASSERT_GE(journey.second - journey.first, 2u);
  const fs::path shot = directory_ / "journey.png";
  ASSERT_TRUE(viewer.save_screenshot(shot.string()));
  Result<png::PngImage> image = png::read_png(shot.string());
  ASSERT_TRUE(image) << image.error().message;
  const ViewTransform view = fit_view(viewer.scene().bounds, image->width, image->height);
  const std::vector<PathRecord>& paths = viewer.session().snapshot()->paths;
  for (std::size_t i = journey.first; i < journey.second; ++i) {
    const PathRecord& hop = paths[i];
    const std::array<float, 3> expected = path_palette(hop.bounce);
    const Vec2 at = view.to_pixels(hop.from + (1.0 / 3.0) * (hop.to - hop.from));
    EXPECT_TRUE(near(*image, at, 1,
                     [&](Rgb c) {
                       auto close = [](int value, float wanted) {
                         return std::fabs(static_cast<float>(value) - wanted * 255.0f) < 60.0f;
                       };
                       return close(c.r, expected[0]) && close(c.g, expected[1]) && close(c.b, expected[2]);
                     }))
        << "hop " << i - journey.first << " (bounce " << hop.bounce << ") not drawn in its colour";
  }
}

// A deterministic step (--step rounds=1) draws every path it kept before the frame is shown; live
// frames draw at most path_budget new ones each.
TEST_F(Viewer, SteppedFramesDrawEveryKeptPath) {
  ViewOptions options = stepped_rounds("penumbra.json");
  options.path_budget = 600;
  options.light = "paths";
  Result<std::unique_ptr<viewer::Viewer>> created = viewer::Viewer::create(options);
  ASSERT_TRUE(created) << created.error().message;
  viewer::Viewer& viewer = **created;
  viewer.frame();
  const std::uint64_t shot = viewer.session().snapshot()->progress.photons;
  ASSERT_GT(shot, 0u);
  EXPECT_EQ(viewer.paths_drawn(), std::min<std::uint64_t>(shot, 12'000));
}

// By default (light as auto) the kept paths give way to the field once there are many: it stands
// for every photon shot, its image is there as soon as the step's snapshot is, and the path
// buffer holds no paths.
TEST_F(Viewer, ManyKeptPathsShowTheFieldOfEveryPhoton) {
  const ViewOptions options = stepped_rounds("penumbra.json");
  Result<std::unique_ptr<viewer::Viewer>> created = viewer::Viewer::create(options);
  ASSERT_TRUE(created) << created.error().message;
  viewer::Viewer& viewer = **created;
  viewer.frame();
  const std::shared_ptr<const viewer::Snapshot> snapshot = viewer.session().snapshot();
  ASSERT_GE(snapshot->paths.size(), viewer::kFieldAutoPaths);
  ASSERT_NE(snapshot->field, nullptr);
  EXPECT_EQ(snapshot->field->photons, static_cast<double>(snapshot->progress.photons));
  EXPECT_EQ(viewer.paths_drawn(), 0u);
  ViewOptions bad = options;
  bad.light = "rays";
  Result<std::unique_ptr<viewer::Viewer>> refused = viewer::Viewer::create(bad);
  ASSERT_FALSE(refused);
  EXPECT_NE(refused.error().message.find("--light"), std::string::npos) << refused.error().message;
}

TEST_F(Viewer, DraggingAControlPointEditsTheSceneAndRestarts) {
  ViewOptions options;
  options.scene = scene("penumbra.json");
  options.width = 900;
  options.height = 600;
  options.paused = true;
  options.vsync = false;
  options.show_control_points = true;
  options.show_ui = false;
  Result<std::unique_ptr<viewer::Viewer>> created = viewer::Viewer::create(options);
  ASSERT_TRUE(created) << created.error().message;
  viewer::Viewer& viewer = **created;
  viewer.frame();
  const ViewTransform view = viewer.view();  // fitted to the stage between the panels
  // The occluder's right end (0.7, 1) dragged to (1.2, 1.1).
  const std::uint64_t generation = viewer.session().snapshot()->generation;
  const Vec2 from = view.to_pixels({0.7, 1.0});
  const Vec2 to = view.to_pixels({1.2, 1.1});
  viewer.queue_drag(static_cast<float>(from.x), static_cast<float>(from.y), static_cast<float>(to.x),
                    static_cast<float>(to.y));
  frames_until(
      viewer, [] { return false; }, 10);
  const Vec2 moved = viewer.scene().curves[1].points[1];
  EXPECT_NEAR(moved.x, 1.2, 2.0 / view.scale);  // to within a pixel or two
  EXPECT_NEAR(moved.y, 1.1, 2.0 / view.scale);
  EXPECT_NEAR(viewer.scene().curves[1].points[0].x, -0.1, 1e-12);  // the other end stays
  viewer.session().wait_idle();
  EXPECT_NE(viewer.session().snapshot()->generation, generation);
  EXPECT_EQ(viewer.session().snapshot()->scene->curves[1].points[1].x, moved.x);
}

TEST_F(Viewer, ReloadsTheSceneWhenItsFileChangesAndSavesResults) {
  const fs::path file = directory_ / "scene.json";
  fs::copy_file(scene("penumbra.json"), file);
  ViewOptions options;
  options.scene = file.string();
  options.width = 640;
  options.height = 480;
  options.paused = true;
  options.vsync = false;
  options.show_ui = false;
  options.settings.photons = 20'000;
  Result<std::unique_ptr<viewer::Viewer>> created = viewer::Viewer::create(options);
  ASSERT_TRUE(created) << created.error().message;
  viewer::Viewer& viewer = **created;
  viewer.frame();
  EXPECT_NEAR(viewer.scene().curves[1].points[1].x, 0.7, 1e-12);
  // Move the occluder's end in the file: the viewer picks the change up (it looks twice a second).
  std::string text = read_file(file);
  const std::string from = "[0.7, 1.0]";
  ASSERT_NE(text.find(from), std::string::npos);
  text.replace(text.find(from), from.size(), "[0.9, 1.0]");
  {
    std::ofstream out(file);
    out << text;
  }
  fs::last_write_time(file, fs::last_write_time(file) + std::chrono::seconds(2));
  const auto start = std::chrono::steady_clock::now();
  while (viewer.scene().curves[1].points[1].x != 0.9 &&
         std::chrono::steady_clock::now() - start < std::chrono::seconds(5))
    viewer.frame();
  EXPECT_EQ(viewer.scene().curves[1].points[1].x, 0.9);

  // Ctrl+E saves the result, Ctrl+S a screenshot, in the working directory.
  const fs::path previous = fs::current_path();
  fs::current_path(directory_);
  viewer.queue_key('r');
  viewer.frame();
  viewer.session().wait_idle();
  viewer.queue_key('e', true);
  viewer.queue_key('s', true);
  for (int i = 0; i < 3; ++i) viewer.frame();
  fs::current_path(previous);
  const std::string result = read_file(directory_ / "flatland-penumbra-result.json");
  EXPECT_NE(result.find("\"flatland_result\""), std::string::npos);
  int pictures = 0;
  for (const auto& entry : fs::directory_iterator(directory_))
    pictures += entry.path().extension() == ".png" && png::read_png(entry.path().string()).ok();
  EXPECT_EQ(pictures, 1);
}

TEST_F(Viewer, HeadlessViewShowsTheErrorAgainstAReference) {
  const fs::path reference = directory_ / "reference.json";
  ASSERT_EQ(
      run("reference " + scene("penumbra.json") + " --elements 100 --samples 50 --quiet --out " + reference.string())
          .exit_code,
      0);
  const fs::path whole = directory_ / "window.png";
  const CommandRun result =
      run("view " + scene("penumbra.json") + " --reference " + reference.string() +
          " --frames 3 --step rounds=1 --select receiver --report --screenshot-ui " + whole.string());
  ASSERT_EQ(result.exit_code, 0) << result.err;
  EXPECT_TRUE(png::read_png(whole.string()).ok());
  // --report prints the error against the reference: a few per cent after three rounds of 1e6.
  const std::size_t at = result.out.find("error     ");
  ASSERT_NE(at, std::string::npos) << result.out;
  const double error = std::stod(result.out.substr(at + 10));
  EXPECT_GT(error, 0.0);
  EXPECT_LT(error, 0.1);
  // A reference of another scene is refused before any window opens.
  const CommandRun wrong =
      run("view " + scene("enclosure.json") + " --reference " + reference.string() + " --frames 2 --step rounds=1");
  EXPECT_EQ(wrong.exit_code, 2);
  EXPECT_EQ(std::count(wrong.err.begin(), wrong.err.end(), '\n'), 1) << wrong.err;
  EXPECT_NE(wrong.err.find("another scene"), std::string::npos) << wrong.err;
}

}  // namespace
}  // namespace flatland::viewer

int main(int argc, char** argv) {
  // The GL tests need a display: without one, run again under a virtual X server.
  bool listing = false;
  for (int i = 1; i < argc; ++i) listing |= std::string(argv[i]).rfind("--gtest_list_tests", 0) == 0;
  if (!listing && std::getenv("DISPLAY") == nullptr && std::getenv("FLATLAND_NO_XVFB") == nullptr) {
    std::vector<char*> args;
    std::string xvfb = "xvfb-run";
    std::string auto_number = "-a";
    // The search for a free display starts at a number of this process's own: consecutive tests
    // starting at the same :99 raced the last one's server, still shutting down there ("cannot open
    // the display ':99'"), about once in a few hundred runs.
    std::string first_number = "--server-num=" + std::to_string(100 + ::getpid() % 800);
    std::string server = "-s";
    std::string screen = "-screen 0 1600x1000x24";
    args.push_back(xvfb.data());
    args.push_back(auto_number.data());
    args.push_back(first_number.data());
    args.push_back(server.data());
    args.push_back(screen.data());
    for (int i = 0; i < argc; ++i) args.push_back(argv[i]);
    args.push_back(nullptr);
    ::setenv("FLATLAND_NO_XVFB", "1", 1);
    execvp("xvfb-run", args.data());
    std::fprintf(stderr, "viewer_test: no DISPLAY and xvfb-run is missing (apt-get install xvfb xauth)\n");
    return 1;
  }
  ::testing::InitGoogleTest(&argc, argv);
  return RUN_ALL_TESTS();
}
