#!/usr/bin/env bash
# Makes the pictures of docs/figures/pictures/ and the Markdown snippet pictures.md that shows them:
#   gallery.png         the seven test scenes, rendered by `flatland render`, labelled
#   error_along_curve.png  B - B_ref along a receiver for constant, linear and cubic storage
#   discontinuities.png close-up of a penumbra: cubic with and without discontinuity nodes
#   extended_ray.png    how an extended ray's power spreads along a receiver (five profiles)
# Run from the repository's top: docs/figures/pictures/make.sh
# FLATLAND selects the executable (default build/flatland). Needs python3 (standard library only)
# and gnuplot with the pngcairo terminal. Uses at most 2 threads, one flatland process at a time.
set -eu

FLATLAND=${FLATLAND:-build/flatland}
out=docs/figures/pictures
[ -x "$FLATLAND" ] || { echo "make.sh: $FLATLAND is not an executable (set FLATLAND)" >&2; exit 1; }
[ -f scenes2d/penumbra.json ] || { echo "make.sh: run from the repository's top" >&2; exit 1; }
command -v gnuplot >/dev/null || { echo "make.sh: gnuplot is needed" >&2; exit 1; }
command -v python3 >/dev/null || { echo "make.sh: python3 is needed" >&2; exit 1; }
mkdir -p "$out"
work=$(mktemp -d)
trap '[ -n "${KEEP:-}" ] || rm -rf "$work"' EXIT; [ -n "${KEEP:-}" ] && echo "work directory: $work"
start=$(date +%s)

# ---------------------------------------------------------------------------------------------
# Settings. Every solve setting is pinned, so that a change of a default does not change a picture.
PHOTONS=1e6
SEED=1
ELEMENTS=16
SAMPLES=1000
SOLVE_FLAGS="--photons $PHOTONS --seed $SEED --elements $ELEMENTS --estimator galerkin --sampler sobol
  --sampling reconstructed --discontinuities auto --ray-width 0 --tolerance 1e-6 --samples $SAMPLES
  --transport shooting --gather none --control-variate none --replicates 8 --target-error 0 --threads 2 --quiet"
REF_FLAGS="--elements 1600 --samples $SAMPLES --threads 2 --quiet"
RENDER_FLAGS="--photons 2e5 --seed 1 --threads 2 --width 480 --height 300 --graph --band --quiet"

# The lit ring is made by a script of its own (docs/figures/time_to_accuracy/make_lit_ring.py). Use
# the file that is there; if it is missing, make it in the work directory (this script writes
# nothing outside docs/figures/pictures/).
lit_ring=docs/figures/time_to_accuracy/lit_ring.json
if [ ! -f "$lit_ring" ]; then
  cp docs/figures/time_to_accuracy/make_lit_ring.py "$work/make_lit_ring.py"
  python3 "$work/make_lit_ring.py" >/dev/null
  lit_ring_file="$work/lit_ring.json"
else
  lit_ring_file="$lit_ring"
fi

# ---------------------------------------------------------------------------------------------
# Python helpers (standard library only): arc length of a curve parameter u from the scene's
# geometry, the stored spline evaluated from knots and coefficients, data files for gnuplot.
cat >"$work/helper.py" <<'PY'
import json, math, sys

GL_X = [-0.9602898564975363, -0.7966664774136267, -0.5255324099163290, -0.1834346424956498,
        0.1834346424956498, 0.5255324099163290, 0.7966664774136267, 0.9602898564975363]
GL_W = [0.1012285362903763, 0.2223810344533745, 0.3137066458802091, 0.3626837833783620,
        0.3626837833783620, 0.3137066458802091, 0.2223810344533745, 0.1012285362903763]

class Geometry:
    """A scene curve's segments; u = segment index + t as in docs/result-format.md."""
    def __init__(self, scene_file, cid):
        scene = json.load(open(scene_file))
        c = next(c for c in scene["curves"] if c["id"] == cid)
        self.segs = []
        if "line" in c:
            p = c["line"]
            self.segs = [("line", [p[i], p[i + 1]]) for i in range(len(p) - 1)]
        else:
            p = c["bezier"]
            self.segs = [("bezier", p[3 * i:3 * i + 4]) for i in range((len(p) - 1) // 3)]
        self.cum = [0.0]
        for i in range(len(self.segs)):
            self.cum.append(self.cum[-1] + self.seg_length(i, 1.0))

    def seg_length(self, i, t):
        kind, p = self.segs[i]
        if kind == "line":
            return t * math.hypot(p[1][0] - p[0][0], p[1][1] - p[0][1])
        total, panels = 0.0, 16
        for k in range(panels):
            a, b = t * k / panels, t * (k + 1) / panels
            for x, w in zip(GL_X, GL_W):
                tt = 0.5 * (a + b) + 0.5 * (b - a) * x
                m = 1.0 - tt
                dx = 3 * (m * m * (p[1][0] - p[0][0]) + 2 * m * tt * (p[2][0] - p[1][0]) + tt * tt * (p[3][0] - p[2][0]))
                dy = 3 * (m * m * (p[1][1] - p[0][1]) + 2 * m * tt * (p[2][1] - p[1][1]) + tt * tt * (p[3][1] - p[2][1]))
                total += 0.5 * (b - a) * w * math.hypot(dx, dy)
        return total

    def s_of_u(self, u):
        i = min(max(int(math.floor(u)), 0), len(self.segs) - 1)
        return self.cum[i] + self.seg_length(i, u - i)

    def u_of_s(self, s):
        lo, hi = 0.0, float(len(self.segs))
        for _ in range(60):
            mid = 0.5 * (lo + hi)
            if self.s_of_u(mid) < s:
                lo = mid
            else:
                hi = mid
        return 0.5 * (lo + hi)

def bspline(knots, degree, coeffs, u):
    """sum_k coeffs[k] phi_k(u), Cox-de Boor; the right limit at a knot (the left one at the end)."""
    n = len(coeffs)
    span = degree
    while span < n - 1 and knots[span + 1] <= u:
        span += 1
    while span > degree and knots[span] == knots[span + 1]:
        span -= 1
    d = [coeffs[j + span - degree] for j in range(degree + 1)]
    for r in range(1, degree + 1):
        for j in range(degree, r - 1, -1):
            i = j + span - degree
            den = knots[i + degree + 1 - r] - knots[i]
            a = 0.0 if den == 0 else (u - knots[i]) / den
            d[j] = (1 - a) * d[j - 1] + a * d[j]
    return d[degree]

def curve_of(result, cid):
    return next(c for c in result["curves"] if c["id"] == cid)

def reflected(sample):
    return sample["B"] - sample.get("E", 0.0)

def nodes(curve, geom):
    """(s, continuity) of every interior node of the storage mesh (element boundaries are C1)."""
    return [(geom.s_of_u(n["u"]), n["continuity"]) for n in curve["continuity"]]

def check_mapping(curve, geom):
    """Largest |B(u(s)) - B sample| over the samples: checks the u <-> s mapping and the spline."""
    if curve.get("periodic") or "coefficients" not in curve:
        return float("nan")
    worst = 0.0
    for smp in curve["samples"][::7]:
        u = geom.u_of_s(smp["s"])
        b = bspline(curve["knots"], curve["degree"], curve["coefficients"], u)
        worst = max(worst, abs(b - reflected(smp)))
    return worst

def cmd_errors(args):
    """errors SCENE CURVE REF TAG CONST LIN CUBIC: TAG.dat (s, three errors), TAG_nodes.gp."""
    scene, cid, ref, tag = args[:4]
    results = [json.load(open(f)) for f in args[4:7]]
    geom = Geometry(scene, cid)
    rc = curve_of(json.load(open(ref)), cid)
    cs = [curve_of(r, cid) for r in results]
    for c in cs:
        assert len(c["samples"]) == len(rc["samples"]), "samples differ from the reference's"
    with open(tag + ".dat", "w") as f:
        for j, rs in enumerate(rc["samples"]):
            f.write("%.9g" % rs["s"])
            for c in cs:
                f.write(" %.9g" % (reflected(c["samples"][j]) - reflected(rs)))
            f.write("\n")
    # The three storage meshes share their nodes (same regions, same elements); checked here.
    same = all(sorted(set(round(k, 12) for k in c["knots"])) == sorted(set(round(k, 12) for k in cs[2]["knots"]))
               for c in cs)
    with open(tag + "_nodes.gp", "w") as f:
        for s, cont in nodes(cs[2], geom):
            style = {"C1": 'lc rgb "#bbbbbb" lw 1 dt 3', "C0": 'lc rgb "#444444" lw 1.5 dt 2',
                     "C-1": 'lc rgb "#e41a1c" lw 2 dt 1'}[cont]
            f.write("set arrow from %.9g, graph 0 to %.9g, graph 1 nohead back %s\n" % (s, s, style))
    count = {k: sum(1 for _, c in nodes(cs[2], geom) if c == k) for k in ("C1", "C0", "C-1")}
    print(json.dumps({"tag": tag, "same_nodes": same, "length": rc["length"],
                      "elements": cs[2]["elements"], "nodes": count,
                      "mapping_check": check_mapping(cs[2], geom)}))

def cmd_closeup(args):
    """closeup SCENE CURVE REF AUTO NONE TAG S0 S1: TAG.dat and the nodes of both meshes."""
    scene, cid, ref, auto, none, tag = args[:6]
    s0, s1 = float(args[6]), float(args[7])
    geom = Geometry(scene, cid)
    rc = curve_of(json.load(open(ref)), cid)
    ca = curve_of(json.load(open(auto)), cid)
    cn = curve_of(json.load(open(none)), cid)
    with open(tag + ".dat", "w") as f:
        for j, rs in enumerate(rc["samples"]):
            if True:
                f.write("%.9g %.9g %.9g %.9g\n" % (rs["s"], reflected(rs), reflected(ca["samples"][j]),
                                                   reflected(cn["samples"][j])))
    for c, name in ((ca, "auto"), (cn, "none")):
        with open("%s_%s_nodes.dat" % (tag, name), "w") as f:
            for n in c["continuity"]:
                s = geom.s_of_u(n["u"])
                if s0 <= s <= s1:
                    b = bspline(c["knots"], c["degree"], c["coefficients"], n["u"])
                    f.write("%.9g %.9g %s\n" % (s, b, n["continuity"]))
    for name, lo, hi in (("_events.gp", s0, s1), ("_all_events.gp", -1e300, 1e300)):
      with open(tag + name, "w") as f:
        for n in ca["continuity"]:
            s = geom.s_of_u(n["u"])
            if n["continuity"] != "C1" and lo <= s <= hi:
                f.write('set arrow from %.9g, graph 0 to %.9g, graph 1 nohead back lc rgb "#444444" lw 1.5 dt 2\n' % (s, s))
    win = [(rs["s"], reflected(rs), reflected(ca["samples"][j]), reflected(cn["samples"][j]))
           for j, rs in enumerate(rc["samples"]) if s0 <= rs["s"] <= s1]
    umbra = [w for w in win if w[1] == 0.0]
    print(json.dumps({"tag": tag, "mapping_check_auto": check_mapping(ca, geom),
                      "elements_auto": ca["elements"], "elements_none": cn["elements"],
                      "max_error_auto": max(abs(w[2] - w[1]) for w in win),
                      "max_error_none": max(abs(w[3] - w[1]) for w in win),
                      "min_none_in_umbra": min(w[3] for w in umbra) if umbra else float("nan"),
                      "mapping_check_none": check_mapping(cn, geom),
                      "events": [round(geom.s_of_u(n["u"]), 4) for n in ca["continuity"] if n["continuity"] != "C1"]}))

def profile_density(name, x):
    """Density on x in [-1, 1] (x = offset / (W/2)); src/flatland/transport/ray_profiles.hpp."""
    if abs(x) > 1:
        return 0.0
    if name == "box":
        return 0.5
    if name == "tent":
        return 1 - abs(x)
    if name == "epanechnikov":
        return 0.75 * (1 - x * x)
    if name == "cosine":
        return math.pi / 4 * math.cos(math.pi * x / 2)
    sigma = 1.0 / 3.0
    z = sigma * math.sqrt(2 * math.pi) * math.erf(3 / math.sqrt(2))
    return math.exp(-x * x / (2 * sigma * sigma)) / z

def cmd_profiles(args):
    """profiles W TAG ANGLE...: TAG_ANGLE.dat, the spread density along the receiver (1/m)."""
    width, tag = float(args[0]), args[1]
    names = ["box", "tent", "epanechnikov", "cosine", "gauss"]
    for angle in args[2:]:
        cosine = max(abs(math.cos(math.radians(float(angle)))), 0.05)
        a = width / (2 * cosine)
        with open("%s_%s.dat" % (tag, angle), "w") as f:
            n = 2500
            for i in range(n + 1):
                d = -0.125 + 0.25 * i / n
                # Points just inside and just outside the ends, so the jumps of box and gauss are vertical.
                for dd in ([d] if abs(abs(d) - a) > 1e-12 else [math.copysign(a - 1e-12, d), math.copysign(a + 1e-12, d)]):
                    f.write("%.9g %s\n" % (dd, " ".join("%.9g" % (profile_density(p, dd / a) / a) for p in names)))
        # Check: each density integrates to 1 over the receiver (midpoint rule).
        m = 20000
        masses = [sum(profile_density(p, -1 + (2 * k + 1) / m) for k in range(m)) * 2 / m for p in names]
        print(json.dumps({"angle": angle, "half_length": a, "masses": [round(v, 6) for v in masses]}))

{"errors": cmd_errors, "closeup": cmd_closeup, "profiles": cmd_profiles}[sys.argv[1]](sys.argv[2:])
PY
helper() { python3 "$work/helper.py" "$@"; }
# The relative L2 error of B - E on one curve, from flatland compare.
rel_l2() {
  "$FLATLAND" compare "$1" "$2" --curve "$3" --json |
    python3 -c 'import json,sys; d=json.load(sys.stdin); print("%.2f %%" % (100 * d["curves"][0]["l2"]))'
}

# =============================================================================================
# 1. Gallery of the test scenes
echo "make.sh: 1/4 gallery"
gallery_scenes="scenes2d/penumbra.json scenes2d/tests/reference_round_occluder.json $lit_ring
scenes2d/tests/reference_ring_profile.json scenes2d/curved_room.json scenes2d/room_reflector.json
scenes2d/syndrome.json"
i=0
for scene in $gallery_scenes; do
  i=$((i + 1))
  file=$scene
  [ "$scene" = "$lit_ring" ] && file=$lit_ring_file
  "$FLATLAND" render "$file" $RENDER_FLAGS --out "$work/g$i.png"
  echo "$scene" >"$work/g$i.name"
done
{
  echo 'set terminal pngcairo size 1480,640 font ",11" background rgb "white"'
  echo "set output \"$out/gallery.png\""
  echo 'set multiplot layout 2,4 margins 0.004,0.996,0.01,0.91 spacing 0.006,0.075 title "The test scenes: flatland render, 2e5 photons, seed 1, default storage (--elements auto); B along each curve as a colour band" font ",14"'
  echo 'unset border; unset tics; unset key; set size ratio -1; set xrange [0:479]; set yrange [0:299]'
  i=0
  for scene in $gallery_scenes; do
    i=$((i + 1))
    echo "set title \"$i. $scene\" noenhanced font \",11\""
    echo "plot \"$work/g$i.png\" binary filetype=png with rgbimage"
  done
  # The eighth cell: how to read the pictures.
  cat <<'GP'
unset title; set size noratio; set xrange [0:1]; set yrange [0:1]
set label 1 "How to read them" at 0.02,0.93 font ",12:Bold"
set label 2 "grey strokes: photon paths (20,000 kept,\n  brighter where more power passed)" at 0.02,0.81
set label 3 "colour band beside a lit side: B there,\n  dark (0) to bright (99th percentile of B;\n  the lamps saturate)" at 0.02,0.66
set label 4 "thin light-blue curve: graph of B along the\n  side's normal, its curve the baseline" at 0.02,0.44
set label 5 "diamonds: storage nodes where B may kink\n  (C0, green) or jump (C-1, red)" at 0.02,0.27
set label 6 "thick arrow: the newest photon's flight" at 0.02,0.11
plot NaN
GP
  echo 'unset multiplot'
} >"$work/gallery.gp"
gnuplot "$work/gallery.gp"

# =============================================================================================
# 2. The error along a curve: constant, linear and cubic storage at equal photons
echo "make.sh: 2/4 error along a curve"
# scene | curve | tag
cases="scenes2d/penumbra.json receiver pen
scenes2d/tests/reference_round_occluder.json floor round
scenes2d/room_reflector.json walls room"
echo "$cases" | while read -r scene cid tag; do
  "$FLATLAND" reference "$scene" $REF_FLAGS --out "$work/${tag}_ref.json"
  for basis in constant linear cubic; do
    "$FLATLAND" solve "$scene" --basis "$basis" $SOLVE_FLAGS --out "$work/${tag}_$basis.json"
    rel_l2 "$work/${tag}_$basis.json" "$work/${tag}_ref.json" "$cid" >"$work/${tag}_$basis.l2"
  done
  (cd "$work" && helper errors "$OLDPWD/$scene" "$cid" "${tag}_ref.json" "$tag" \
     "${tag}_constant.json" "${tag}_linear.json" "${tag}_cubic.json") >"$work/${tag}_errors.json"
  cat "$work/${tag}_errors.json"
done
l2() { cat "$work/$1.l2"; }
{
  cat <<GP
set terminal pngcairo size 1700,1200 font ",11" background rgb "white"
set output "$out/error_along_curve.png"
set multiplot title "Reflected radiosity error B - B_{ref} along a curve: constant, linear and cubic storage at equal photons\n($PHOTONS photons, seed $SEED, --elements $ELEMENTS, --discontinuities auto, --estimator galerkin, --sampler sobol)" font ",13"
set grid ytics lc rgb "#eeeeee"
set xlabel "arc length s along the curve [m]"
set ylabel "B - B_{ref}  [W/m]"
set xzeroaxis lt 1 lc rgb "#888888"
nodes = 'keyentry with lines lc rgb "#bbbbbb" lw 1 dt 3 title "element boundary (C1)", keyentry with lines lc rgb "#444444" lw 1.5 dt 2 title "C0 node", keyentry with lines lc rgb "#e41a1c" lw 2 dt 1 title "C-1 node"'
GP
  row=0
  echo "$cases" | while read -r scene cid tag; do
    row=$((row + 1))
    top=$(echo "$row" | awk '{printf "%.3f", 0.895 - 0.31 * ($1 - 1)}')
    bottom=$(echo "$row" | awk '{printf "%.3f", 0.895 - 0.31 * ($1 - 1) - 0.215}')
    case $tag in
      pen) what="penumbra: floor \\\"receiver\\\", 6 m" ;;
      round) what="round occluder: floor \\\"floor\\\", 4 m" ;;
      room) what="room with reflector: \\\"walls\\\", 16 m ccw from (0,0)" ;;
    esac
    cat <<GP
set title "$what ($scene)" noenhanced
load "$work/${tag}_nodes.gp"
set tmargin at screen $top; set bmargin at screen $bottom
set lmargin at screen 0.05; set rmargin at screen 0.36
unset key
plot "$work/$tag.dat" u 1:2 w l lw 1.5 lc rgb "#d95f02" dt 1 notitle, \\
     "" u 1:3 w l lw 1.5 lc rgb "#7570b3" dt 4 notitle, \\
     "" u 1:4 w l lw 2 lc rgb "#1b9e77" dt 1 notitle
set title "the same, zoomed on linear and cubic (constant left out)"
set lmargin at screen 0.43; set rmargin at screen 0.74
set key at screen 0.75, screen $top left top box opaque Left reverse width -3 spacing 1.15
plot keyentry with lines lw 1.5 lc rgb "#d95f02" dt 1 t "constant, rel. L2 $(l2 ${tag}_constant) (left panel only)", \\
     "$work/$tag.dat" u 1:3 w l lw 1.5 lc rgb "#7570b3" dt 4 t "linear, rel. L2 $(l2 ${tag}_linear)", \\
     "" u 1:4 w l lw 2 lc rgb "#1b9e77" dt 1 t "cubic, rel. L2 $(l2 ${tag}_cubic)", @nodes
unset arrow
GP
  done
  echo 'unset multiplot'
} >"$work/error.gp"
gnuplot "$work/error.gp"

# =============================================================================================
# 3. Close-up of the discontinuity mesh on the penumbra floor
echo "make.sh: 3/4 discontinuity close-up"
S0=3.1
S1=4.1
"$FLATLAND" solve scenes2d/penumbra.json --basis cubic $(echo "$SOLVE_FLAGS" | sed 's/--discontinuities auto/--discontinuities none/') \
  --out "$work/pen_none.json"
rel_l2 "$work/pen_none.json" "$work/pen_ref.json" receiver >"$work/pen_none.l2"
(cd "$work" && helper closeup "$OLDPWD/scenes2d/penumbra.json" receiver pen_ref.json pen_cubic.json pen_none.json \
   close "$S0" "$S1") >"$work/close.json"
cat "$work/close.json"
cat >"$work/close.gp" <<GP
set terminal pngcairo size 1300,1150 font ",11" background rgb "white"
set output "$out/discontinuities.png"
set multiplot title "Penumbra scene, floor (\"receiver\"): cubic storage with and without discontinuity nodes\n($PHOTONS photons, seed $SEED, --elements $ELEMENTS, otherwise as in the error picture)" font ",13" noenhanced
set grid ytics lc rgb "#eeeeee"
set lmargin at screen 0.08; set rmargin at screen 0.68
set xlabel "arc length s along the floor [m]   (x = s - 3 m)"
set ylabel "B  [W/m]"
# (a) the whole floor, the close-up's window shaded
set tmargin at screen 0.895; set bmargin at screen 0.715
set title "(a) the whole floor; shaded: the close-up below"
set object 1 rect from $S0, graph 0 to $S1, graph 1 fc rgb "#fee8c8" fs solid 1.0 noborder behind
load "$work/close_all_events.gp"
set xrange [0:6]
set key at screen 0.69, screen 0.895 left top box opaque Left reverse width -2 spacing 1.15
plot "$work/close.dat" u 1:2 w l lw 4 lc rgb "#000000" t "reference (closed form)", \
     "" u 1:3 w l lw 2 lc rgb "#1b9e77" dt 1 t "cubic, --discontinuities auto", \
     "" u 1:4 w l lw 2 lc rgb "#d95f02" dt 2 t "cubic, --discontinuities none", \
     keyentry with lines lc rgb "#444444" lw 1.5 dt 2 t "penumbra boundary (C0 node of auto)"
unset object 1
unset arrow
# (b) close-up of B
set tmargin at screen 0.625; set bmargin at screen 0.375
set title "(b) close-up: the umbra (B = 0 from s = 3.3 to 3.9 m) between the inner edges of the two penumbrae"
set xrange [$S0:$S1]
load "$work/close_events.gp"
set key at screen 0.69, screen 0.625 left top box opaque Left reverse width -2 spacing 1.15
plot "$work/close.dat" u 1:2 w l lw 4 lc rgb "#000000" t "reference (closed form)", \
     "" u 1:3 w l lw 2 lc rgb "#1b9e77" dt 1 t "cubic, --discontinuities auto", \
     "" u 1:4 w l lw 2 lc rgb "#d95f02" dt 2 t "cubic, --discontinuities none", \
     "$work/close_auto_nodes.dat" u 1:(strcol(3) eq "C1" ? \$2 : NaN) w p pt 7 ps 1.3 lc rgb "#1b9e77" t "auto: element boundary (C1 node)", \
     "" u 1:(strcol(3) eq "C0" ? \$2 : NaN) w p pt 5 ps 1.6 lc rgb "#08519c" t "auto: C0 node (visibility event)", \
     "$work/close_none_nodes.dat" u 1:2 w p pt 6 ps 1.5 lw 1.5 lc rgb "#d95f02" t "none: element boundary (C1 node)", \
     keyentry with lines lc rgb "#444444" lw 1.5 dt 2 t "penumbra boundary (C0 node of auto)"
# (c) the error in the close-up
set tmargin at screen 0.285; set bmargin at screen 0.065
set title "(c) the error of each against the reference, same window"
set ylabel "B - B_{ref}  [W/m]"
set xzeroaxis lt 1 lc rgb "#888888"
set key at screen 0.69, screen 0.285 left top box opaque Left reverse width -2 spacing 1.15
plot "$work/close.dat" u 1:(\$3-\$2) w l lw 2 lc rgb "#1b9e77" dt 1 t "auto: rel. L2 $(l2 pen_cubic) on the floor", \
     "" u 1:(\$4-\$2) w l lw 2 lc rgb "#d95f02" dt 2 t "none: rel. L2 $(l2 pen_none) on the floor", \
     keyentry with lines lc rgb "#444444" lw 1.5 dt 2 t "penumbra boundary (C0 node of auto)"
unset multiplot
GP
gnuplot "$work/close.gp"

# =============================================================================================
# 4. The extended ray's energy distribution along a receiver (analytic, from the definitions)
echo "make.sh: 4/4 extended ray"
W=0.1
(cd "$work" && helper profiles "$W" ray 0 60) >"$work/ray.json"
cat "$work/ray.json"
{
  cat <<GP
set terminal pngcairo size 1400,900 font ",11" background rgb "white"
set output "$out/extended_ray.png"
set multiplot title "One extended ray of width W = $W m (footprint mode): how its power is spread along the receiver, for the five --ray-profile choices" font ",13"
W = $W
L = 0.23
GP
  row=0
  for angle in 0 60; do
    row=$((row + 1))
    if [ $row = 1 ]; then bottom=0.555; top=0.88; else bottom=0.075; top=0.40; fi
    if [ $angle = 0 ]; then what="normal incidence, theta_{in} = 0"; else what="oblique incidence, theta_{in} = $angle degrees"; fi
    cat <<GP
# The beam (left): a band of width W arriving at angle th from the receiver's normal.
reset
th = $angle * pi / 180
a = W / (2 * cos(th))
set tmargin at screen $top; set bmargin at screen $bottom
set lmargin at screen 0.03; set rmargin at screen 0.25
set size ratio -1
set xrange [-0.30:0.17]; set yrange [-0.06:0.26]
unset border; unset tics; unset key
set title "$what"
set object 1 polygon from -a,0 to a,0 to W/2*cos(th) - L*sin(th), L*cos(th) + W/2*sin(th) to -W/2*cos(th) - L*sin(th), L*cos(th) - W/2*sin(th) to -a,0 fc rgb "#fdae61" fs transparent solid 0.45 noborder back
set arrow 1 from -L*sin(th), L*cos(th) to 0,0 head filled lw 2 lc rgb "#b2182b"
set arrow 2 from -0.28,0 to 0.16,0 nohead lw 3 lc rgb "#000000"
set arrow 3 from -a,-0.012 to a,-0.012 heads size 0.008,90 lw 2 lc rgb "#2166ac"
t0 = 0.10
set arrow 4 from -t0*sin(th) - W/2*cos(th), t0*cos(th) - W/2*sin(th) to -t0*sin(th) + W/2*cos(th), t0*cos(th) + W/2*sin(th) heads size 0.008,90 lw 1.5 lc rgb "#000000"
set label 1 "W" at -t0*sin(th) + (W/2 + 0.02)*cos(th), t0*cos(th) + (W/2 + 0.02)*sin(th) center font ",12"
set label 2 "2a = W / |cos theta_{in}|" at 0, -0.035 center tc rgb "#2166ac"
set label 3 "receiver" at 0.16, 0.015 right
set label 4 "centre ray" at -L*sin(th), L*cos(th) + 0.035 center tc rgb "#b2182b"
plot NaN
# The density along the receiver (right).
reset
set tmargin at screen $top; set bmargin at screen $bottom
set lmargin at screen 0.32; set rmargin at screen 0.73
set key at screen 0.745, screen $top left top box opaque Left reverse width -1 spacing 1.15
set grid lc rgb "#eeeeee"
set xrange [-0.125:0.125]; set yrange [0:26]
set xtics 0.025
set xlabel "offset along the receiver from the centre ray's hit, s - s_{hit}  [m]"
set ylabel "fraction of the ray's power per metre  [1/m]"
set title sprintf("$what: a = W / (2 |cos theta_{in}|) = %.3g m", a)
set arrow from -a, graph 0 to -a, graph 1 nohead back lc rgb "#888888" dt 3
set arrow from a, graph 0 to a, graph 1 nohead back lc rgb "#888888" dt 3
plot "$work/ray_$angle.dat" u 1:2 w l lw 2 lc rgb "#e41a1c" dt 1 t "box", \\
     "" u 1:3 w l lw 2 lc rgb "#377eb8" dt 2 t "tent", \\
     "" u 1:4 w l lw 2 lc rgb "#4daf4a" dt 4 t "epanechnikov", \\
     "" u 1:5 w l lw 2 lc rgb "#984ea3" dt 5 t "cosine", \\
     "" u 1:6 w l lw 2 lc rgb "#ff7f00" dt 1 t "gauss, sigma = W/6, 3-sigma cut", \\
     keyentry with lines lc rgb "#888888" dt 3 t "+- a (the footprint's ends)"
GP
  done
  echo 'unset multiplot'
} >"$work/ray.gp"
gnuplot "$work/ray.gp"

# =============================================================================================
# The Markdown snippet. Numbers in it come from this run.
mapcheck=$(cat "$work/pen_errors.json" "$work/round_errors.json" "$work/room_errors.json" "$work/close.json" |
  python3 -c 'import json,sys; print("%.0e" % max(max(v for k, v in json.loads(l).items() if k.startswith("mapping_check")) for l in sys.stdin))')
nodes_of() { python3 -c 'import json,sys; d=json.load(open(sys.argv[1])); n=d["nodes"]; print("%d elements, %d C0 and %d C-1 nodes" % (d["elements"], n["C0"], n["C-1"]))' "$work/$1_errors.json"; }
close_value() { python3 -c 'import json,sys; v=json.load(open(sys.argv[1]))[sys.argv[2]]; print(v if isinstance(v, int) else "%.2g" % v)' "$work/close.json" "$1"; }
end_error() {  # the cubic's largest |B - B_ref| within 0.1 m of the ends and elsewhere
  awk 'NR == 1 {} { e = $4 < 0 ? -$4 : $4; if ($1 < 0.1 || $1 > L - 0.1) { if (e > a) a = e } else if (e > b) b = e }
       END { printf "%.2g W/m at the ends against %.2g W/m elsewhere", a, b }' L="$2" "$work/$1.dat"
}
events=$(python3 -c 'import json,sys; print(", ".join("%g" % e for e in json.load(open(sys.argv[1]))["events"]))' "$work/close.json")
cat >"$out/pictures.md" <<MD
### The test scenes

![The seven test scenes rendered by flatland render, each labelled with its file](gallery.png)

*The seven scenes the tests and the time-to-accuracy runs use, each drawn as the viewer draws it and
labelled with its file: 1. penumbra (a lamp, a bar occluder and a reflecting floor; closed form),
2. round occluder (a circle of eight cubic Bezier segments between a lamp and a floor; closed form),
3. lit ring (a closed cubic ring lit from inside by an off-centre lamp strip), 4. ring profile (an
emitting ring with a smooth emittance profile; closed form by Fourier series; B is smooth all round, and its one red diamond is the closing point,
which the solve stores as C-1: \`"closing": "C-1"\` in its result),
5. curved room (a rounded room with a curved baffle and a round pillar), 6. room with a parabolic
reflector, 7. constant radiosity syndrome (a floor lamp at the left end of a long floor; the ceiling
sees only the floor's reflection). Made by \`docs/figures/pictures/make.sh\`: each scene by
\`flatland render SCENE --photons 2e5 --seed 1 --threads 2 --width 480 --height 300 --graph --band
--out gN.png\` (storage and every other setting at their defaults; the lit ring is the file
\`docs/figures/time_to_accuracy/make_lit_ring.py\` writes), the seven pictures placed in one image by
gnuplot (\`plot 'gN.png' binary filetype=png with rgbimage\` in a multiplot). Read: the grey strokes
are photon paths; the band beside each lit side is B, from dark (0) to bright (the 99th percentile
of B over the curves that do not emit, so the lamps saturate to pale yellow, and the scale is each
picture's own: brightness does not compare between panels); the thin light-blue curve is B drawn as
a graph along the side's normal; the diamonds are storage nodes where B may kink (C0, green: the
penumbra boundaries that \`--discontinuities auto\` finds) or jump (C-1, red: corners, a closed
curve's closing point); the thick arrow is the newest photon's flight. Shadows show as dark stretches
of the band, and the green diamonds sit at their edges.*

### The error along a curve

![B - B_ref along three curves for constant, linear and cubic storage](error_along_curve.png)

*The error of the reflected radiosity, B - B_ref, against arc length s along one curve of three
scenes, for constant, linear and cubic storage at equal photons and equal storage: the penumbra
scene's floor ($(nodes_of pen)), the round occluder's floor ($(nodes_of round)) and the walls of the
room with the parabolic reflector ($(nodes_of room); s runs counter-clockwise from the corner at
(0, 0), whose C-1 closing point is s = 0 = 16 m). Left: all three; right: the same zoomed on linear
and cubic. Vertical lines mark the storage mesh's nodes: dotted grey the plain element boundaries
(C1 in the result's \`continuity\`), dashed dark grey C0 nodes (visibility events), solid red C-1 nodes
(corners). The key gives each curve's relative L2 error of B - E, from \`flatland compare RESULT REF
--curve ID --json\`. Made by \`docs/figures/pictures/make.sh\`: \`flatland reference SCENE --elements
1600 --samples $SAMPLES --threads 2 --out ref.json\` and, per basis, \`flatland solve SCENE --basis
constant|linear|cubic --photons $PHOTONS --seed $SEED --elements $ELEMENTS --estimator galerkin --sampler
sobol --sampling reconstructed --discontinuities auto --ray-width 0 --tolerance 1e-6 --samples
$SAMPLES --transport shooting --gather none --control-variate none --replicates 8 --target-error 0 --threads 2 --out B.json\`; B - B_ref
is taken sample by sample (both at s = (j + 0.5) L / $SAMPLES). The result gives its nodes in the curve
parameter u (\`knots\`, \`continuity\`), not in arc length, so the script maps u to s from the scene's
geometry (a line segment is linear in u; a Bezier segment's arc length is integrated) and checks the
mapping by evaluating the stored spline (\`knots\`, \`coefficients\`) at every seventh sample's s: it
reproduces the samples' B to $mapcheck. The three bases share one mesh (the same regions and
elements; the script checks their knots), but the \`continuity\` labels are the mesh's: a constant
spline jumps at every node and a linear one is only C0 at an element boundary. Read: constant storage
is a saw-tooth (its error is the slope of B times the distance from the element's centre) and
largest where B is steepest, in the penumbrae; on the two floors linear storage's error is an order
of magnitude smaller and largest in the penumbrae, where B bends most; the cubic's is smaller again and noise-like, with no
step at the C0 nodes, where the kinks of B sit exactly on the mesh (on the round occluder's floor a
small peak remains beside its outer C0 nodes). The cubic's largest error is at the curve's very ends
(penumbra floor: $(end_error pen 6); round occluder floor: $(end_error round 4)). On the room's walls the C-1 corners
(s = 5, 8 and 13 m) let B jump and the errors beside them stay small, but all three bases err most at s = 1.03 m (floor) and s = 11.97 m (ceiling): there the lamp's
light grazes past the reflector's lower and upper tips, and the penumbra is only 0.044 m wide, so its
two boundaries, closer than 5 % of an element, are merged into one C0 node at their mean
(docs/storage-mesh.md, "Direct-light events"); a near-jump that narrow is not resolved by 16 elements.*

### A close-up of the discontinuity mesh

![B in a penumbra on the floor: cubic with and without discontinuity nodes](discontinuities.png)

*Reconstruction with selected discontinuities, on the penumbra scene's floor: B from cubic storage
with \`--discontinuities auto\` (C0 nodes at the visibility events, here at s = $events m) and with
\`--discontinuities none\` (C1 everywhere), against the closed form; both asked for 16 elements,
auto's nodes cut the floor into regions split evenly, which gives it $(close_value elements_auto) against
none's $(close_value elements_none). (a)
the whole floor, the close-up's window shaded; (b) the close-up, from s = $S0 to $S1 m: the umbra
(B = 0) between the inner edges of the two penumbrae, with each mesh's nodes marked on its own curve
(filled circles and squares: auto's element boundaries and C0 nodes; open circles: none's element
boundaries); (c) B - B_ref in the same window. Made by \`docs/figures/pictures/make.sh\`: the cubic
solve and the reference of the error picture above, and the same solve with \`--discontinuities none\`;
node values are the stored spline evaluated at the node. Read: where B kinks (at the
penumbra's boundary B goes flat at 0 in the umbra), the smooth spline without nodes cannot follow:
it rounds the kink off, so light leaks into the umbra's edges, dips below zero inside it (down to
$(close_value min_none_in_umbra) W/m) and rings on both sides: its error in the window reaches
$(close_value max_error_none) W/m, against $(close_value max_error_auto) W/m for the cubic with C0 nodes at the
events, which follows the kink and stays at the noise level. Over the whole floor the relative L2 error of B - E is $(l2 pen_cubic) with the
nodes and $(l2 pen_none) without.*

### The extended ray's energy distribution

![How one extended ray spreads its power along a receiver, for five profiles](extended_ray.png)

*How one extended ray of width W = $W m spreads its power along the receiver in footprint mode (the
default \`--ray-mode\`): only the centre ray is traced, and its power is spread over arc length
s_hit +- a, a = W / (2 |cos theta_in|) (capped at 10 W for grazing incidence), with density
k((s - s_hit) / a) / a, for the five \`--ray-profile\` choices: box 1/2, tent 1 - |x|, Epanechnikov
3/4 (1 - x^2), cosine pi/4 cos(pi x / 2), and a Gaussian with sigma = W/6 cut at 3 sigma and
renormalised (x = offset / a in [-1, 1]). Left: the beam of width W meeting the receiver at normal
incidence and at 60 degrees; right: the density along the receiver, in fraction of the ray's power
per metre, both rows on one scale. Made by \`docs/figures/pictures/make.sh\` from these definitions
(docs/method.md, "Extended rays"; src/flatland/transport/ray_profiles.hpp), in Python, not from a
solve (a solve stores the sum of every photon's spread, projected on the storage basis, so no single
ray's footprint can be read back from a result); each density integrates to 1 (checked by the
script). Read: every profile puts all of the ray's power within +- a; the box spreads it evenly and
jumps at the ends, the tent, Epanechnikov and cosine profiles fall to zero there (the Gaussian almost:
its density jumps to 0.0133 / a at the cut), and the Gaussian concentrates it most. At 60 degrees the
footprint is twice as long and half as high: an oblique ray smears its power over a longer stretch
of the receiver: the spread smooths what is stored on the scale of a, so oblique hits smooth more. Where the
footprint would run past a corner or a curve's end, the part beyond is reflected back inside (not
drawn here).*
MD

echo "make.sh: done in $(( $(date +%s) - start )) s"
