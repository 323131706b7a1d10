#!/usr/bin/env python3
# Writes the closed-form test scenes of the reference solver (docs/reference.md):
# scenes2d/tests/reference_round_occluder.json and scenes2d/tests/reference_ring_profile.json.
# Circles are chains of cubic Bezier arcs with handles k r, k = 4/3 tan(a/4) for an arc of angle a.
# Usage: docs/figures/reference/make_closed_form_scenes.py
import os
root = os.path.normpath(os.path.join(os.path.dirname(os.path.abspath(__file__)), '..', '..', '..'))
import math
def circle(cx, cy, r, n, start=0.0):
    th = 2*math.pi/n
    k = 4.0/3.0*math.tan(th/4)
    pts = []
    for s in range(n):
        a = start + s*th; b = a + th
        p0 = (cx + r*math.cos(a), cy + r*math.sin(a))
        p3 = (cx + r*math.cos(b), cy + r*math.sin(b))
        p1 = (p0[0] - k*r*math.sin(a), p0[1] + k*r*math.cos(a))
        p2 = (p3[0] + k*r*math.sin(b), p3[1] - k*r*math.cos(b))
        if s == 0: pts.append(p0)
        pts += [p1, p2, p3 if s < n-1 else pts[0]]
    return pts
def num(v):
    return repr(0.0 if abs(v) < 1e-15 else v)
def fmt(pts):
    return "[" + ", ".join("[%s, %s]" % (num(x), num(y)) for x, y in pts) + "]"
occ = circle(0.0, 1.0, 0.3, 8)
text = '''{
  "flatland": 1,
  "name": "reference_round_occluder",
  "description": "Closed-form test of the reference solver (docs/reference.md). Open scene: a black line lamp (E = 1) from x = -0.5 to 0.5 at height 2 emitting downward, a black round occluder (a circle of radius 0.3 centred at (0, 1), a closed chain of 8 cubic Bezier segments of 45 degrees), and a flat floor from x = -2 to 2 facing up with rho = 0.5. The floor sees only the lamp and the occluder, so one bounce is exact: B(x) = rho E (1/2) sum over the visible parts of the lamp of (sin theta_b - sin theta_a), the hidden part bounded by the tangent lines from x to the Bezier occluder.",
  "materials": {
    "lamp": {"reflectivity": 0.0, "emittance": 1.0},
    "black": {"reflectivity": 0.0},
    "floor": {"reflectivity": 0.5}
  },
  "curves": [
    {"id": "lamp", "material": "lamp", "line": [[0.5, 2.0], [-0.5, 2.0]]},
    {"id": "occluder", "material": "black",
     "bezier": %s},
    {"id": "floor", "material": "floor", "line": [[-2.0, 0.0], [2.0, 0.0]]}
  ]
}
''' % fmt(occ)
open(root + '/scenes2d/tests/reference_round_occluder.json', 'w').write(text)

n = 32
ring = circle(0.0, 0.0, 1.0, n)
# Emittance profile: f(phi) = 1 + 0.5 cos(phi) + 0.25 sin(2 phi); Bernstein factors of each
# segment from the values and slopes at its ends (a C1 piecewise cubic in t ~ phi).
f = lambda p: 1 + 0.5*math.cos(p) + 0.25*math.sin(2*p)
df = lambda p: -0.5*math.sin(p) + 0.5*math.cos(2*p)
th = 2*math.pi/n
prof = []
for s in range(n):
    a = s*th; b = a + th
    if s == 0: prof.append(f(a))
    prof += [f(a) + df(a)*th/3, f(b) - df(b)*th/3, f(b) if s < n-1 else prof[0]]
text = '''{
  "flatland": 1,
  "name": "reference_ring_profile",
  "description": "Closed-form test of the reference solver (docs/reference.md). A closed ring of radius 1 (32 cubic Bezier segments of 11.25 degrees, counter-clockwise, so its front faces inward) with rho = 0.5 and emittance 1 times a smooth profile: on each segment the Bernstein polynomial of the factors, which follow f(phi) = 1 + 0.5 cos(phi) + 0.25 sin(2 phi) and its slope at the joints. On a circle the kernel per unit angle is |sin(psi/2)| / 4, so B_n = E_n / (1 - rho lambda_n), lambda_0 = 1, lambda_n = -1 / (4 n^2 - 1), E_n the Fourier coefficients of the emittance along the angle.",
  "materials": {
    "ring": {"reflectivity": 0.5, "emittance": 1.0}
  },
  "curves": [
    {"id": "ring", "material": "ring",
     "bezier": %s,
     "emittance_profile": [%s]}
  ]
}
''' % (fmt(ring), ", ".join(repr(v) for v in prof))
open(root + '/scenes2d/tests/reference_ring_profile.json', 'w').write(text)
