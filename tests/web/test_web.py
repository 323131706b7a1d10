"""The web page (docs/web.md) in headless Chromium, served from 127.0.0.1 as a static site.

The testing hook (report=1) must give what `flatland solve --out` writes for the same scene and
options, bit for bit but for the timing and the scene file's path; a bad scene or option must give
the command line's one-line error in the page; the live viewer must show the lit scene.

Needs the built site (.ci/web: build-web/site, or FLATLAND_SITE), chromium and the desktop program
(FLATLAND_BINARY, default build/flatland); skipped without them. FLATLAND_WEB_FIGURES=DIR keeps the
screenshots there (docs/figures/web-*.png are made so).
"""
import functools
import html
import http.server
import json
import os
import re
import shutil
import subprocess
import threading

import pytest

from png_pixels import png_pixels

SITE = os.path.abspath(os.environ.get("FLATLAND_SITE", "build-web/site"))
BINARY = os.path.abspath(os.environ.get("FLATLAND_BINARY", "build/flatland"))
SOURCE = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
CHROMIUM = shutil.which("chromium")

pytestmark = pytest.mark.skipif(
    CHROMIUM is None or not os.path.exists(os.path.join(SITE, "flatland.wasm")) or not os.path.exists(BINARY),
    reason="needs chromium, the web build (.ci/web) and build/flatland")


class QuietHandler(http.server.SimpleHTTPRequestHandler):
    def log_message(self, *args):
        pass


@pytest.fixture(scope="module")
def page(tmp_path_factory):
    """The page's address on a local static server whose root also holds a broken scene."""
    root = tmp_path_factory.mktemp("web")
    os.symlink(SITE, root / "site")
    # A scene whose curve names a material that does not exist.
    (root / "bad.json").write_text(
        '{"flatland": 2, "materials": {"wall": {"reflectivity": 0.5}},\n'
        ' "curves": [{"id": "a", "material": "lamp", "line": [[0, 0], [1, 0]]}]}\n')
    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), functools.partial(QuietHandler, directory=str(root)))
    threading.Thread(target=server.serve_forever, daemon=True).start()
    yield {"url": f"http://127.0.0.1:{server.server_address[1]}/site/index.html", "root": root}
    server.shutdown()


def chromium(tmp_path, url, *args, budget=60000):
    """Runs headless Chromium on the page until the page is idle (virtual time) and returns it."""
    command = [CHROMIUM, "--headless", "--no-sandbox", "--no-first-run", f"--user-data-dir={tmp_path / 'profile'}",
               "--enable-unsafe-swiftshader", "--use-angle=swiftshader", f"--virtual-time-budget={budget}", *args, url]
    run = subprocess.run(command, capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr[-2000:]
    return run.stdout


def element(dom, tag, id):
    match = re.search(rf'<{tag} id="{id}"[^>]*>(.*?)</{tag}>', dom, re.S)
    assert match, f"no {tag}#{id} in the page"
    return html.unescape(match.group(1))


def report(tmp_path, url, query):
    return json.loads(element(chromium(tmp_path, f"{url}?report=1&{query}", "--dump-dom"), "pre", "flatland-report"))


def comparable(document):
    """The result without what differs between runs and places: the timing, the scene file's path."""
    document["stats"].pop("seconds")
    document["scene"].pop("file")
    return document


def same_as_solve(page, tmp_path, scene, options, scene_file):
    query = "&".join(f"{key}={value}" for key, value in {"scene": scene, **options}.items())
    web = report(tmp_path, page["url"], query)
    assert "error" not in web, web
    out = tmp_path / "native.json"
    arguments = [f"--{key}={value}" for key, value in options.items()]
    subprocess.run([BINARY, "solve", scene_file, *arguments, "--threads", "1", "--quiet", "--out", str(out)],
                   check=True)
    native = json.loads(out.read_text())
    return web["scene"]["file"], comparable(web) == comparable(native)


@pytest.mark.parametrize("scene,options", [
    ("penumbra", {"photons": "200000", "seed": "3", "basis": "linear"}),          # grey
    ("default", {"photons": "100000", "seed": "2", "estimator": "local"}),       # colour
    ("enclosure", {"photons": "100000", "transport": "walk", "sampler": "random"}),  # a closed curve
    # Every shipped scene, and every basis, estimator, sampler, transport, walk score, ray mode and profile.
    ("curved_room", {"photons": "100000", "basis": "hermite"}),
    ("arch", {"photons": "100000", "estimator": "galerkin", "discontinuities": "secondary"}),
    ("syndrome", {"photons": "100000", "basis": "constant", "sampling": "uniform"}),
    ("mixed", {"photons": "100000", "estimator": "lumped", "elements": "64"}),
    ("room_reflector", {"photons": "100000", "transport": "walk", "walk-score": "absorption", "ray-width": "0.02",
                        "ray-profile": "tent"}),
    ("penumbra", {"photons": "100000", "ray-width": "0.05", "ray-profile": "gauss"}),
    ("penumbra", {"photons": "100000", "ray-width": "0.05", "ray-profile": "cosine", "ray-mode": "band"}),
    ("default", {"photons": "100000", "ray-width": "0.03", "ray-profile": "epanechnikov", "ray-mode": "band"}),
    # Mirrors, glass, detectors and spectral light: the same bits (its wavelengths, Fresnel draws and
    # dispersion use no library function that differs between platforms).
    ("prism", {"photons": "100000", "seed": "4"}),
    ("lens", {"photons": "100000", "transport": "walk", "walk-score": "survival"}),
    ("light_guide", {"photons": "50000", "transport": "jacobi"}),
    ("mirror_room", {"photons": "100000", "ray-width": "0.02"}),
    ("parabolic_mirror", {"photons": "100000", "sampler": "random"}),
    # Importance: its adjoint solve and each round's count of the sources run in the page too.
    ("row_of_rooms", {"photons": "100000", "importance": "desk,floor_1"}),
])
def test_the_report_is_what_solve_writes(page, tmp_path, scene, options):
    file, same = same_as_solve(page, tmp_path, scene, options, os.path.join(SOURCE, "scenes2d", scene + ".json"))
    assert file == f"/scenes2d/{scene}.json"
    assert same


def test_a_lobe_emitter_gives_the_same_bits(page, tmp_path):
    # Its directions need cos, sin and pow (the core's portable ones: a C library's differ).
    scene = json.load(open(os.path.join(SOURCE, "scenes2d", "penumbra.json")))
    for material in scene["materials"].values():
        if material.get("emittance", 0):
            material["emission"] = {"lobe": 7.3}
    (page["root"] / "lobe.json").write_text(json.dumps(scene))
    _, same = same_as_solve(page, tmp_path, "../lobe.json", {"photons": "100000"}, str(page["root"] / "lobe.json"))
    assert same


def cli_error(*arguments):
    run = subprocess.run([BINARY, *arguments], capture_output=True, text=True)
    assert run.returncode == 2
    return run.stderr.strip()


def test_a_bad_scene_gives_the_command_lines_message(page, tmp_path):
    web = report(tmp_path, page["url"], "scene=../bad.json")
    native = cli_error("solve", str(page["root"] / "bad.json"), "--threads", "1", "--out", str(tmp_path / "o.json"))
    assert web == {"error": native.replace(str(page["root"] / "bad.json"), "/fetched/bad.json")}
    # The viewer says the same in the page, where it would have been.
    dom = chromium(tmp_path, f"{page['url']}?scene=../bad.json", "--dump-dom")
    assert element(dom, "div", "status") == web["error"]


def test_a_bad_option_gives_the_command_lines_message(page, tmp_path):
    web = report(tmp_path, page["url"], "scene=default&basis=quintic")
    scene = os.path.join(SOURCE, "scenes2d", "default.json")
    assert web == {"error": cli_error("solve", scene, "--basis", "quintic", "--threads", "1", "--out",
                                      str(tmp_path / "o.json"))}
    web = report(tmp_path, page["url"], "scene=no_such_scene")
    assert web["error"].startswith("flatland: error: /scenes2d/no_such_scene.json: ")


def test_a_result_too_large_for_the_page_is_refused_not_crashed(page, tmp_path):
    # 65,536 elements on each of six curves: a result document of about 124 MB.
    web = report(tmp_path, page["url"], "scene=default&elements=65536&photons=10000")
    assert web["error"].startswith("flatland: error: the result is ")
    assert "more than the page shows in its report (32 MB)" in web["error"]


def lit_fraction(rows, x0, x1, y0, y1):
    """The share of pixels in the box (fractions of the picture) that are clearly lit."""
    height, width = len(rows), len(rows[0])
    box = [rows[y][x] for y in range(int(y0 * height), int(y1 * height), 2)
           for x in range(int(x0 * width), int(x1 * width), 2)]
    return sum(1 for pixel in box if max(pixel) > 60) / len(box)


def screenshot(page, tmp_path, query, width, height, name):
    shot = tmp_path / f"{name}.png"
    chromium(tmp_path, f"{page['url']}?{query}", f"--window-size={width},{height}", f"--screenshot={shot}",
             budget=8000)
    figures = os.environ.get("FLATLAND_WEB_FIGURES")
    if figures:
        shutil.copy(shot, os.path.join(figures, f"{name}.png"))
    found_width, found_height, rows = png_pixels(shot)
    assert (found_width, found_height) == (width, height)
    return rows


def test_the_live_viewer_shows_the_lit_scene(page, tmp_path):
    rows = screenshot(page, tmp_path, "scene=default&seed=1", 1280, 720, "web-viewer")
    # The stage lies between the panels' columns: photon paths light most of it.
    assert lit_fraction(rows, 0.35, 0.65, 0.35, 0.65) > 0.3
    # The panels are drawn (their text is light on dark).
    assert lit_fraction(rows, 0.0, 0.25, 0.05, 0.5) > 0.02


def test_presentation_mode_fills_a_projector(page, tmp_path):
    rows = screenshot(page, tmp_path, "scene=default&seed=1&present=1&ui-scale=2&select=sofa", 1920, 1080,
                      "web-presentation")
    # The stage starts at the left edge: light reaches the left quarter, where the panels would be;
    # the inspected curve's B(s) has a column of a third of the width at the right, beside it.
    assert lit_fraction(rows, 0.2, 0.5, 0.3, 0.6) > 0.3
    # The colour key's strip at the bottom, under the stage: some row there is a bar from dark to
    # light across the stage's width.
    width = len(rows[0])

    def ramp(y):
        bar = [max(rows[y][x]) for x in range(int(0.05 * width), int(0.62 * width), 40)]
        return bar[-1] > bar[0] + 100 and all(b >= a - 8 for a, b in zip(bar, bar[1:]))

    assert any(ramp(y) for y in range(int(0.75 * len(rows)), len(rows)))


def test_every_lesson_link_opens_its_lesson(page, tmp_path):
    # docs/web.md's lesson links: each loads without the command line's error in the page (the
    # status line stays empty), First photons included (first-photons=1, the flag --first-photons).
    text = open(os.path.join(SOURCE, "docs", "web.md")).read()
    links = re.findall(r"`index\.html\?([^`]+)`", text.split("## Lesson links", 1)[1].split("\n## ", 1)[0])
    assert len(links) >= 8
    for query in links:
        dom = chromium(tmp_path, f"{page['url']}?{query}", "--dump-dom", budget=4000)
        assert not element(dom, "div", "status").startswith("flatland: error"), query
    # The check sees a broken lesson: a value the viewer refuses is the page's error.
    dom = chromium(tmp_path, f"{page['url']}?scene=default&first-photons=1&colour-by=rainbow", "--dump-dom",
                   budget=4000)
    assert element(dom, "div", "status").startswith("flatland: error: --colour-by"), dom


def test_an_error_page_offers_a_way_on(page, tmp_path):
    # A link the viewer refuses: the message names the page's help, not a command a browser user
    # cannot run, and the page offers the scene with its defaults, the default scene and the menu.
    dom = chromium(tmp_path, f"{page['url']}?scene=prism&colour-by=rainbow", "--dump-dom", budget=4000)
    status = element(dom, "div", "status")
    assert status.startswith("flatland: error: --colour-by"), status
    assert "flatland view --help" not in status and "the page's help" in status, status
    assert 'id="recover-defaults" href="?scene=prism"' in dom
    assert 'id="recover" style="display: block;"' in dom
    assert re.search(r'<select id="scenes"[^>]*>.*<option value="/scenes2d/penumbra.json">penumbra</option>', dom, re.S)
