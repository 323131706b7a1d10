"""The Python module `flatland` (src/python/flatland_module.cpp, docs/python.md), run by ctest with
PYTHONPATH=build/python and FLATLAND_BINARY set to the command-line program, from the repository's
top directory. Statistical tolerances are derived from the estimator's variance, as in the C++ tests."""
import contextlib
import csv
import json
import math
import os
import signal
import subprocess
import threading
import time

import numpy as np
import pytest

import flatland

BINARY = os.environ.get("FLATLAND_BINARY", "build/flatland")


def run_cli(*args):
    return subprocess.run([BINARY, *args], capture_output=True, text=True)


def without_timing(text):
    document = json.loads(text)
    document["stats"].pop("seconds")
    document["settings"].pop("threads")
    return document


def circle_enclosure(rho, emittance):
    k = 0.5522847498307936
    return {
        "flatland": 2,
        "materials": {"glow": {"reflectivity": rho, "emittance": emittance}},
        "curves": [{"id": "circle", "material": "glow", "bezier": [
            [1, 0], [1, k], [k, 1], [0, 1], [-k, 1], [-1, k], [-1, 0],
            [-1, -k], [-k, -1], [0, -1], [k, -1], [1, -k], [1, 0]]}],
    }


def test_version_is_the_programs():
    out = run_cli("--version").stdout
    assert flatland.__version__ in out


def test_same_seed_gives_the_same_bits_as_the_command_line(tmp_path):
    out = tmp_path / "result.json"
    cli = run_cli("solve", "scenes2d/mixed.json", "--photons", "200000", "--seed", "7", "--out", str(out), "--quiet")
    assert cli.returncode == 0, cli.stderr
    scene = flatland.Scene.load("scenes2d/mixed.json")
    result = flatland.solve(scene, photons=200_000, seed=7)
    assert without_timing(result.to_json()) == without_timing(out.read_text())
    # And with other settings named as the command line's options.
    cli = run_cli("solve", "scenes2d/mixed.json", "--photons", "50000", "--basis", "linear", "--elements", "24",
                  "--transport", "walk", "--ray-width", "0.05", "--out", str(out), "--quiet")
    assert cli.returncode == 0, cli.stderr
    result = flatland.solve(scene, photons=50_000, basis="linear", elements=24, transport="walk", ray_width=0.05)
    assert without_timing(result.to_json()) == without_timing(out.read_text())
    # Averaged Jacobi iterations, named alike.
    cli = run_cli("solve", "scenes2d/mixed.json", "--photons", "50000", "--transport", "jacobi", "--out", str(out),
                  "--quiet")
    assert cli.returncode == 0, cli.stderr
    result = flatland.solve(scene, photons=50_000, transport="jacobi")
    assert without_timing(result.to_json()) == without_timing(out.read_text())
    assert json.loads(out.read_text())["settings"]["transport"] == "jacobi"
    # A walk's score, named alike, and refused with shooting in the command line's words.
    cli = run_cli("solve", "scenes2d/mixed.json", "--photons", "50000", "--transport", "walk", "--walk-score",
                  "absorption", "--out", str(out), "--quiet")
    assert cli.returncode == 0, cli.stderr
    result = flatland.solve(scene, photons=50_000, transport="walk", walk_score="absorption")
    assert without_timing(result.to_json()) == without_timing(out.read_text())
    assert json.loads(out.read_text())["settings"]["walk_score"] == "absorption"
    cli = run_cli("solve", "scenes2d/mixed.json", "--walk-score", "survival")
    assert cli.returncode == 2 and "--walk-score: survival" in cli.stderr and "transport walk" in cli.stderr
    with pytest.raises(ValueError, match="walk_score: survival"):
        flatland.solve(scene, walk_score="survival")
    # Importance, named alike (a string of ids or a list of them), and an unknown id refused in each
    # front end's words.
    cli = run_cli("solve", "scenes2d/row_of_rooms.json", "--photons", "50000", "--importance", "desk,floor_1",
                  "--out", str(out), "--quiet")
    assert cli.returncode == 0, cli.stderr
    rooms = flatland.Scene.load("scenes2d/row_of_rooms.json")
    result = flatland.solve(rooms, photons=50_000, importance=["desk", "floor_1"])
    assert without_timing(result.to_json()) == without_timing(out.read_text())
    assert json.loads(out.read_text())["settings"]["importance"]["curves"] == ["desk", "floor_1"]
    assert without_timing(flatland.solve(rooms, photons=50_000, importance="desk,floor_1").to_json()) == \
        without_timing(out.read_text())
    cli = run_cli("solve", "scenes2d/row_of_rooms.json", "--importance", "dsk")
    assert cli.returncode == 2 and "--importance: scenes2d/row_of_rooms.json has no curve 'dsk'; did you mean 'desk'?" \
        in cli.stderr
    with pytest.raises(ValueError, match="importance: .* has no curve 'dsk'"):
        flatland.solve(rooms, importance="dsk")
    with pytest.raises(ValueError, match="importance: expected curve ids"):
        flatland.solve(rooms, importance=["desk", 3])
    assert flatland.solve(rooms, photons=20_000, importance=None).to_json() is not None


def test_a_final_gather_is_the_command_lines(tmp_path):
    # gather="samples": the same gathered samples and estimated error as solve --gather samples.
    out = tmp_path / "gathered.json"
    cli = run_cli("solve", "scenes2d/default.json", "--photons", "100000", "--seed", "5", "--gather", "samples",
                  "--out", str(out), "--quiet")
    assert cli.returncode == 0, cli.stderr
    result = flatland.solve(flatland.Scene.load("scenes2d/default.json"), photons=100_000, seed=5, gather="samples")
    assert without_timing(result.to_json()) == without_timing(out.read_text())
    document = json.loads(out.read_text())
    assert document["settings"]["final_gather"]["element_length"] > 0
    assert "gather" in document["stats"]["estimated_error"]["parts"]
    # Glass is refused with the command line's words.
    cli = run_cli("solve", "scenes2d/prism.json", "--gather", "samples")
    assert cli.returncode == 2
    with pytest.raises(ValueError) as error:
        flatland.solve(flatland.Scene.load("scenes2d/prism.json"), gather="samples")
    assert "a final gather handles diffuse surfaces" in str(error.value)
    assert "a final gather handles diffuse surfaces" in cli.stderr


def test_the_coarse_control_variate_is_the_command_lines(tmp_path):
    # control_variate="coarse": the command line's bits (with and without the gather), the variate
    # named in the result, and what it refuses refused in the command line's words.
    out = tmp_path / "variate.json"
    for gather in ("none", "samples"):
        cli = run_cli("solve", "scenes2d/default.json", "--photons", "100000", "--seed", "4", "--gather", gather,
                      "--control-variate", "coarse", "--out", str(out), "--quiet")
        assert cli.returncode == 0, cli.stderr
        result = flatland.solve(flatland.Scene.load("scenes2d/default.json"), photons=100_000, seed=4,
                                gather=gather, control_variate="coarse")
        assert without_timing(result.to_json()) == without_timing(out.read_text())
    variate = json.loads(out.read_text())["settings"]["control_variate"]
    assert variate["kind"] == "coarse"
    assert variate["coarse_elements"] > 0
    assert 0 < variate["source_fraction"] < 1
    cli = run_cli("solve", "scenes2d/mirror_room.json", "--control-variate", "coarse")
    assert cli.returncode == 2
    with pytest.raises(ValueError) as error:
        flatland.solve(flatland.Scene.load("scenes2d/mirror_room.json"), control_variate="coarse")
    assert "needs diffuse surfaces only" in str(error.value)
    assert "needs diffuse surfaces only" in cli.stderr
    with pytest.raises(ValueError, match="control_variate"):
        flatland.solve(flatland.Scene.load("scenes2d/default.json"), control_variate="fine")


def test_mirrors_glass_and_detectors_are_the_command_lines(tmp_path):
    # The prism's glass and detector, as the command line solves them: the same bits, the chain's
    # books and the detector's tallies.
    out = tmp_path / "prism.json"
    cli = run_cli("solve", "scenes2d/prism.json", "--photons", "100000", "--seed", "3", "--out", str(out), "--quiet")
    assert cli.returncode == 0, cli.stderr
    result = flatland.solve(flatland.Scene.load("scenes2d/prism.json"), photons=100_000, seed=3)
    assert without_timing(result.to_json()) == without_timing(out.read_text())
    stats = result.stats
    assert stats["emitted_power"] == pytest.approx(
        stats["absorbed_power"] + stats["escaped_power"] + stats["unshot_power"] + stats["absorbed_by_mirrors_power"]
        + stats["absorbed_in_glass_power"] + stats["cut_power"], rel=1e-12)
    (probe,) = result.detectors
    assert probe["id"] == "probe" and probe["bins"] == 60
    # White light through the prism: a colour scene, [r, g, b] per bin.
    assert sum(sum(rgb) for rgb in probe["front"]) == pytest.approx(sum(probe["front_total"]), rel=1e-12)
    assert sum(probe["front_total"]) > 0.5 * stats["emitted_power"]
    # A mirror in a scene built from a dict: its back absorbs, on the books' own line.
    scene = flatland.Scene.from_dict({
        "flatland": 2,
        "materials": {"lamp": {"emittance": 1}, "mirror": {"type": "mirror", "reflectance": 0.5}},
        "curves": [{"id": "lamp", "material": "lamp", "line": [[1, -1], [1, 1]]},
                   {"id": "mirror", "material": "mirror", "line": [[0, -50], [0, 50]], "sides": "back"}]})
    stats = flatland.solve(scene, photons=20_000).stats
    assert stats["absorbed_by_mirrors_power"] == pytest.approx(0.5 * stats["emitted_power"], rel=0.02)
    assert flatland.solve(flatland.Scene.load("scenes2d/penumbra.json"), photons=10_000).detectors == []


def test_bad_scenes_and_options_raise_the_command_lines_message(tmp_path):
    bad = tmp_path / "bad.json"
    bad.write_text('{"flatland": 2, "curves": [{"id": "a", "line": [[0, 0], [1, 0]], "material": "nope"}]}')
    cli = run_cli("solve", str(bad))
    assert cli.returncode == 2
    with pytest.raises(ValueError) as error:
        flatland.Scene.load(str(bad))
    assert str(error.value) in cli.stderr
    assert "\n" not in str(error.value)
    scene = flatland.Scene.load("scenes2d/penumbra.json")
    with pytest.raises(ValueError, match="basis"):
        flatland.solve(scene, basis="quartic")
    with pytest.raises(ValueError, match="photons"):
        flatland.solve(scene, photons=2.5)
    assert flatland.solve(scene, photons=1e4).stats["photons"] <= 10_000  # 1e4 reads as --photons 1e4 does
    # The keyword's own name, never a command-line flag the user did not type.
    with pytest.raises(ValueError, match="^tolerance: ") as error:
        flatland.solve(scene, tolerance=2.0)
    assert "--" not in str(error.value)
    with pytest.raises(ValueError, match="^ray_width: "):
        flatland.solve(scene, ray_width=-1.0)
    with pytest.raises(TypeError, match="did you mean 'ray_width'"):
        flatland.solve(scene, ray_widht=0.1)
    with pytest.raises(ValueError, match="no curve 'floor'"):
        flatland.solve(scene, photons=1000).B("floor", np.array([0.0]))
    with pytest.raises(ValueError):
        flatland.Scene.from_dict({"flatland": 2, "curves": []})


def test_enclosure_matches_its_closed_form():
    # B = E / (1 - rho) on a closed circle; the reflected part of a coefficient is a sum of
    # binomial hits: relative standard deviation sqrt((1 - p) / (n p)), p the smallest element's
    # share; stopping at tolerance t adds at most t of bias.
    rho, tolerance = 0.5, 1e-4
    scene = flatland.Scene.from_dict(circle_enclosure(rho, 1.0))
    result = flatland.solve(scene, photons=1_000_000, basis="constant", elements=16, sampler="random",
                            tolerance=tolerance, seed=12)
    assert result.stats["stop_reason"] == "converged"
    length = scene.length("circle")
    s = (np.arange(200) + 0.5) * length / 200
    b = result.B("circle", s)
    exact = 1.0 / (1.0 - rho)
    p = 1.0 / 16
    n = result.stats["photons"]
    sigma = (exact - 1.0) * math.sqrt((1 - p) / (n * p))
    assert np.all(np.abs(b - exact) < 5 * sigma + tolerance * exact)
    books = result.stats
    assert books["emitted_power"] == pytest.approx(books["absorbed_power"] + books["escaped_power"] + books["unshot_power"], rel=1e-9)


def test_stepping_gives_the_bits_of_one_solve():
    scene = flatland.Scene.load("scenes2d/penumbra.json")
    whole = flatland.solve(scene, photons=100_000, seed=4)
    stepped = flatland.Solver(scene, photons=100_000, seed=4)
    sizes = [1, 3, 4000, 97, 8192]
    i = 0
    while not stepped.stats["stopped"]:
        stepped.step_photons(sizes[i % len(sizes)])
        i += 1
    assert without_timing(stepped.to_json()) == without_timing(whole.to_json())
    rounds = flatland.Solver(scene, photons=100_000, seed=4)
    while rounds.step_round():
        pass
    assert without_timing(rounds.to_json()) == without_timing(whole.to_json())


def test_results_as_arrays():
    scene = flatland.Scene.load("scenes2d/default.json")
    assert scene.channels == 3
    result = flatland.solve(scene, photons=50_000)
    b = result.B("screen", np.array([0.1, 0.5]))
    assert b.shape == (2, 3)
    back = result.B("screen", np.array([0.1, 0.5]), back=True)
    assert back.shape == (2, 3)
    knots = result.knots("screen")
    coefficients = result.coefficients("screen")
    assert np.all(np.diff(knots) >= 0)
    assert coefficients.size % 3 == 0 and coefficients.size > 0
    document = json.loads(result.to_json(samples=7))
    assert len(document["curves"][0]["samples"]) == 7


def test_compare_against_a_reference():
    scene = flatland.Scene.load("scenes2d/penumbra.json")
    reference = flatland.reference(scene)
    assert json.loads(reference)["settings"]["method"] == "reference"
    itself = flatland.compare(reference, reference)
    assert itself["scene"]["l2"] == 0.0
    result = flatland.solve(scene, photons=200_000, gather="none")
    errors = flatland.compare(result, reference)
    assert errors["measure"] == "reflected"
    assert 0.0 < errors["scene"]["l2"] < 0.05
    assert set(errors["curves"]) == set(scene.curves)
    # Gathered (the default), the penumbra's reflected light is direct only: the reference's own.
    assert flatland.compare(flatland.solve(scene, photons=20_000), reference)["scene"]["l2"] < 1e-12


def test_converge_gives_the_rows_of_the_command_line(tmp_path):
    # The same runs as `flatland converge`, against the same reference file: the same rows, bit
    # for bit in the errors (the CSV has 9 significant digits), but for the wall times.
    reference = tmp_path / "reference.json"
    made = run_cli("reference", "scenes2d/penumbra.json", "--out", str(reference), "--quiet")
    assert made.returncode == 0, made.stderr
    methods = ["linear", "basis=cubic+sampler=random"]
    cli = run_cli("converge", "scenes2d/penumbra.json", "--reference", str(reference), "--methods", ",".join(methods),
                  "--budgets", "1e4,3e4", "--seeds", "2", "--threads", "1", "--out", str(tmp_path / "c"))
    assert cli.returncode == 0, cli.stderr
    table = list(csv.DictReader(open(tmp_path / "c" / "convergence.csv")))
    seen = []
    rows = flatland.converge(flatland.Scene.load("scenes2d/penumbra.json"), methods=methods, budgets=[1e4, 3e4],
                             seeds=2, threads=1, reference=reference.read_text(), progress=seen.append)
    assert len(rows) == len(table) == 8
    assert [p["runs"] for p in seen] == list(range(1, 9)) and seen[-1]["total"] == 8
    for row, line in zip(rows, table):
        assert list(row) == list(line)  # the CSV's columns, in order
        for key, text in line.items():
            if key == "seconds":
                continue
            value = row[key]
            if isinstance(value, float):
                assert f"{value:.9g}" == text or float(text) == value, key
            else:
                assert str(value) == text, key
    with pytest.raises(ValueError, match="^methods: 'cubic:x'"):
        flatland.converge(flatland.Scene.load("scenes2d/penumbra.json"), methods=["cubic:x"], budgets=[1e4])
    # A solve as the reference, at the runs' own samples; a reference sampled otherwise is refused
    # before any run.
    penumbra = flatland.Scene.load("scenes2d/penumbra.json")
    rows = flatland.converge(penumbra, methods=["linear+gather=none"], budgets=[1e4], seeds=1, samples=40,
                             reference=flatland.solve(penumbra, photons=100_000))
    assert len(rows) == 1 and 0.0 < rows[0]["rel_l2"] < 1.0
    with pytest.raises(ValueError, match="100 samples per curve, the runs 40"):
        flatland.converge(penumbra, budgets=[1e4], samples=40, reference=reference.read_text())
    with pytest.raises(ValueError, match="no curve 'nowhere'"):
        flatland.converge(flatland.Scene.load("scenes2d/penumbra.json"), budgets=[1e4], curve="nowhere",
                          reference=reference.read_text())


def test_progress_callback_and_its_errors():
    scene = flatland.Scene.load("scenes2d/curved_room.json")
    seen = []
    flatland.solve(scene, photons=300_000, elements=16, progress=lambda p: seen.append(p["photons"]))
    assert seen, "the callback was never called"
    assert all(a <= b for a, b in zip(seen, seen[1:]))
    assert seen[-1] <= 300_000

    def boom(_):
        raise RuntimeError("stop here")

    with pytest.raises(RuntimeError, match="stop here"):
        flatland.solve(scene, photons=5_000_000, elements=16, progress=boom)


def test_walks_step_like_one_solve_and_a_busy_solver_is_refused():
    scene = flatland.Scene.load("scenes2d/room_reflector.json")
    whole = flatland.solve(scene, photons=30_000, transport="walk", seed=2)
    stepped = flatland.Solver(scene, photons=30_000, transport="walk", seed=2)
    sizes = [1, 5000, 3, 20_000, 10_000]
    i = 0
    while not stepped.stats["stopped"]:
        stepped.step_photons(sizes[i % len(sizes)])
        stepped.B(scene.curves[0], np.array([0.0]))  # reading an open round is allowed between steps
        i += 1
    assert without_timing(stepped.to_json()) == without_timing(whole.to_json())
    assert whole.stats["rays"] > whole.stats["photons"]
    # From its own progress callback (the GIL is released meanwhile) the solver refuses to be read.
    busy = flatland.Solver(scene, photons=2_000_000, elements=16)
    with pytest.raises(RuntimeError, match="busy"):
        busy.run(progress=lambda p: busy.stats, interval=0.01)


def test_the_gil_is_released_while_solving():
    scene = flatland.Scene.load("scenes2d/curved_room.json")
    ticks = [0]
    done = threading.Event()

    def count():
        while not done.is_set():
            ticks[0] += 1
            time.sleep(0.001)

    counter = threading.Thread(target=count)
    counter.start()
    start = time.perf_counter()
    flatland.solve(scene, photons=2_000_000, elements=16, threads=1)
    elapsed = time.perf_counter() - start
    done.set()
    counter.join()
    # A thread sleeping 1 ms at a time ticks hundreds of times a second unless the GIL is held.
    assert ticks[0] > 20 * elapsed


@contextlib.contextmanager
def ctrl_c_stops_within(seconds):
    """Sends this process SIGINT after 0.5 s and checks that the block ends in KeyboardInterrupt
    within `seconds` of its start; the timer is cancelled whatever happens (a stray SIGINT after a
    failure would stop the whole session)."""
    timer = threading.Timer(0.5, lambda: os.kill(os.getpid(), signal.SIGINT))
    timer.start()
    start = time.perf_counter()
    try:
        with pytest.raises(KeyboardInterrupt):
            yield
    finally:
        timer.cancel()
    assert time.perf_counter() - start < seconds


def test_ctrl_c_interrupts_a_solve():
    scene = flatland.Scene.load("scenes2d/curved_room.json")
    with ctrl_c_stops_within(10):
        flatland.solve(scene, photons=10**12, elements=16, tolerance=1e-9)


def test_ctrl_c_interrupts_a_solves_set_up():
    # The control variate's projection onto 16,384 elements a curve takes tens of seconds; Ctrl-C
    # stops it within 64 spans.
    scene = flatland.Scene.load("scenes2d/curved_room.json")
    with ctrl_c_stops_within(3):
        flatland.solve(scene, photons=10**6, elements=16384, control_variate="coarse")


def test_ctrl_c_interrupts_a_reference():
    # The form factors of 12,000 elements take about a minute; Ctrl-C stops them within a row.
    scene = flatland.Scene.load("scenes2d/default.json")
    with ctrl_c_stops_within(3):
        flatland.reference(scene, max_element_length=0.003)


def test_a_fifo_with_no_writer_is_waited_for_and_ctrl_c_ends_the_wait(tmp_path):
    fifo = tmp_path / "scene.json"
    os.mkfifo(fifo)
    with ctrl_c_stops_within(2):
        flatland.Scene.load(str(fifo))


def test_misused_keywords_raise_value_errors_as_the_command_line_refuses_them(tmp_path):
    scene = flatland.Scene.load("scenes2d/penumbra.json")
    # A path holds no NUL: "a.json\0junk" used to load a.json.
    with pytest.raises(ValueError, match="NUL"):
        flatland.Scene.load("scenes2d/penumbra.json\0junk")
    with pytest.raises(ValueError, match=r"2\^50"):
        flatland.solve(scene, photons=2**51)
    for elements in (2**64, 0, 65537, True, "many"):
        with pytest.raises(ValueError, match="elements"):
            flatland.solve(scene, photons=1000, elements=elements)
    with pytest.raises(ValueError, match="elements"):
        flatland.converge(scene, budgets=[1e3], elements=2**64)
    with pytest.raises(ValueError, match="curve"):
        flatland.converge(scene, budgets=[1e3], curve=5)
    with pytest.raises(ValueError, match="seeds"):
        flatland.converge(scene, budgets=[1e3], seeds=1001)  # the command line's --seeds limit
    with pytest.raises(ValueError, match="given twice"):
        flatland.converge(scene, budgets=[1e3], methods=["cubic", "cubic"])
    # Every round shoots a multiple of the replicates: fewer photons would shoot none.
    with pytest.raises(ValueError, match="multiple of the 8 replicates, so 5 photons would shoot none"):
        flatland.solve(scene, photons=5)
    with pytest.raises(ValueError, match="budgets: 4 photons is fewer than the 8 replicates"):
        flatland.converge(scene, budgets=[4, 1e3], methods=["cubic"])
    # What the scene refuses of a method is said before the reference is computed.
    with pytest.raises(ValueError, match="no curve 'nosuch'.*method 'cubic\\+importance=nosuch'"):
        flatland.converge(scene, budgets=[1e3], methods=["cubic+importance=nosuch"])
    with pytest.raises(ValueError, match="wider than the scene"):
        flatland.solve(scene, photons=1000, ray_width=1e300)
    cli = run_cli("solve", "scenes2d/penumbra.json", "--photons", "1000", "--ray-width", "1e300")
    assert cli.returncode == 2 and "wider than the scene" in cli.stderr


def test_back_sides_that_a_curve_lacks_are_refused_on_every_curve():
    scene = flatland.Scene.load("scenes2d/penumbra.json")  # every curve one-sided; one is the lamp
    result = flatland.solve(scene, photons=10_000)
    s = np.array([0.1])
    assert result.B("emitter", s)[0] == 1.0  # the lamp's front: B = E
    for curve in ("emitter", "occluder", "receiver"):
        with pytest.raises(ValueError, match="no back side"):
            result.B(curve, s, back=True)


def test_scenes_from_dicts_take_numpy_and_name_the_field_of_a_bad_number():
    document = json.load(open("scenes2d/penumbra.json"))
    as_arrays = json.loads(json.dumps(document))
    for curve in as_arrays["curves"]:
        curve["line"] = np.array(curve["line"], dtype=np.float64)
    as_arrays["materials"]["receiver"]["reflectivity"] = np.float32(0.5)
    plain = flatland.solve(flatland.Scene.from_dict(document), photons=20_000)
    numpy = flatland.solve(flatland.Scene.from_dict(as_arrays), photons=20_000)
    assert np.array_equal(plain.B("receiver", np.linspace(0, 6, 7)), numpy.B("receiver", np.linspace(0, 6, 7)))
    bad = json.loads(json.dumps(document))
    bad["curves"][2]["line"][1][0] = float("nan")
    with pytest.raises(ValueError, match=r"curves\[2\]\.line\[1\]\[0\]: nan is not a finite number"):
        flatland.Scene.from_dict(bad)
    cyclic = {"flatland": 2, "curves": []}
    cyclic["curves"].append(cyclic)
    with pytest.raises(ValueError, match="nested more than 64 deep"):
        flatland.Scene.from_dict(cyclic)
    with pytest.raises(ValueError, match="cannot be held in a scene"):
        flatland.Scene.from_dict({"flatland": 2, "curves": [object()]})


def test_results_of_different_scene_files_are_not_compared(tmp_path):
    penumbra = flatland.solve(flatland.Scene.load("scenes2d/penumbra.json"), photons=10_000)
    changed = json.load(open("scenes2d/penumbra.json"))
    changed["materials"]["emitter"]["emittance"] = 2.0
    other = tmp_path / "other.json"
    other.write_text(json.dumps(changed))
    brighter = flatland.solve(flatland.Scene.load(str(other)), photons=10_000)
    with pytest.raises(ValueError, match="different scenes"):
        flatland.compare(penumbra.to_json(), brighter.to_json())
    # The same scene from a dict, or reformatted, is the same scene: compared.
    same = flatland.solve(flatland.Scene.from_dict(json.load(open("scenes2d/penumbra.json"))), photons=10_000)
    assert flatland.compare(same.to_json(), penumbra.to_json())["scene"]["l2"] == 0.0
    reformatted = tmp_path / "reformatted.json"
    reformatted.write_text(json.dumps(json.load(open("scenes2d/penumbra.json")), indent=4))
    again = flatland.solve(flatland.Scene.load(str(reformatted)), photons=10_000)
    assert flatland.compare(again.to_json(), penumbra.to_json())["scene"]["l2"] == 0.0


def test_estimated_error_and_target_error_as_the_command_line(tmp_path):
    # The estimate in Python is the result file's, bit for bit; a target error ends the solve with
    # the command line's stop reason and an estimate below the target.
    out = tmp_path / "result.json"
    cli = run_cli("solve", "scenes2d/penumbra.json", "--photons", "100000", "--seed", "3", "--out", str(out), "--quiet")
    assert cli.returncode == 0, cli.stderr
    scene = flatland.Scene.load("scenes2d/penumbra.json")
    result = flatland.solve(scene, photons=100_000, seed=3)
    estimate = result.estimated_error
    assert estimate == json.loads(out.read_text())["stats"]["estimated_error"]
    assert estimate["available"] and estimate["confidence"] == 0.95 and estimate["replicates"] == 8
    assert 0 < estimate["l1"] < 0.05
    assert set(estimate["curves"]) == {"emitter", "occluder", "receiver"}
    assert estimate["curves"]["emitter"] is None  # it reflects nothing: no relative error
    targeted = flatland.solve(scene, photons=10**8, target_error=0.01, seed=3)
    assert targeted.stats["stop_reason"] == "target error reached"
    assert targeted.estimated_error["l1"] <= 0.0105
    with pytest.raises(ValueError, match="replicates"):
        flatland.solve(scene, replicates=3)
    with pytest.raises(ValueError, match="target_error"):
        flatland.solve(scene, target_error=2)
    # Replicates as blocks of one net: the command line's bits and estimate, and the layout named.
    out_blocks = tmp_path / "blocks.json"
    cli = run_cli("solve", "scenes2d/penumbra.json", "--photons", "100000", "--seed", "3", "--replicate-layout",
                  "blocks", "--out", str(out_blocks), "--quiet")
    assert cli.returncode == 0, cli.stderr
    blocks = flatland.solve(scene, photons=100_000, seed=3, replicate_layout="blocks")
    written = json.loads(out_blocks.read_text())
    assert written["settings"]["replicate_layout"] == "blocks"
    assert blocks.estimated_error == written["stats"]["estimated_error"]
    assert blocks.estimated_error["available"]
    with pytest.raises(ValueError, match="replicate_layout"):
        flatland.solve(scene, replicate_layout="interleaved")


def test_what_was_silently_wrong_is_right_or_refused_as_on_the_command_line():
    # Mirrors facing each other: the reference follows one reflection, so it refuses, naming them.
    facing = flatland.Scene.from_dict({
        "flatland": 2,
        "materials": {"lamp": {"emittance": 1}, "wall": {"reflectivity": 0.5}, "mirror": {"type": "mirror"}},
        "curves": [{"id": "lamp", "material": "lamp", "line": [[1.5, 2], [0.5, 2]]},
                   {"id": "floor", "material": "wall", "line": [[0, 0], [2, 0]]},
                   {"id": "left", "material": "mirror", "line": [[0, 2], [0, 0]]},
                   {"id": "right", "material": "mirror", "line": [[2, 0], [2, 2]]}]})
    with pytest.raises(ValueError, match="mirrors 'left' and 'right' face each other"):
        flatland.reference(facing)
    # A target error where nothing reflects: refused before the first photon of a 1e9 cap.
    black = flatland.Scene.from_dict({
        "flatland": 2,
        "materials": {"lamp": {"emittance": 1}, "black": {"reflectivity": 0}},
        "curves": [{"id": "lamp", "material": "lamp", "line": [[1, 1], [-1, 1]]},
                   {"id": "floor", "material": "black", "line": [[-3, 0], [3, 0]]}]})
    with pytest.raises(ValueError, match="relative error is not defined"):
        flatland.solve(black, photons=10**9, target_error=1e-3)
    # Deep red light over a grey floor is red.
    red = flatland.Scene.from_dict({
        "flatland": 2,
        "materials": {"lamp": {"emittance": 1, "spectrum": {"line": 780}}, "floor": {"reflectivity": 0.5}},
        "curves": [{"id": "lamp", "material": "lamp", "line": [[1, 1], [-1, 1]]},
                   {"id": "floor", "material": "floor", "line": [[-3, 0], [3, 0]]}]})
    b = flatland.solve(red, photons=20_000).B("floor", np.linspace(0.5, 5.5, 11))
    assert np.all(b[:, 0] > 0) and np.all(b[:, 1] == 0) and np.all(b[:, 2] == 0)
