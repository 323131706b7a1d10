#!/usr/bin/env python3
"""Write lit_ring.json: a closed ring lit from inside by a short off-centre lamp (issue 12, part 5)."""
import json, math, os
n, r = 8, 1.0
k = 4.0 / 3.0 * math.tan(math.pi / (2 * n))          # control-arm length of a 360/n-degree cubic arc
pts = []
for i in range(n):
    a, b = 2 * math.pi * i / n, 2 * math.pi * (i + 1) / n
    p0 = [r * math.cos(a), r * math.sin(a)]
    p1 = [p0[0] - k * r * math.sin(a), p0[1] + k * r * math.cos(a)]
    p3 = [r * math.cos(b), r * math.sin(b)]
    p2 = [p3[0] + k * r * math.sin(b), p3[1] - k * r * math.cos(b)]
    if i == 0:
        pts.append(p0)
    pts += [p1, p2, p3]
pts[-1] = pts[0]                                      # close exactly
pts = [[round(x, 12), round(y, 12)] for x, y in pts]
scene = {
    "flatland": 2,
    "name": "lit ring",
    "description": "A closed ring of radius 1 (8 cubic Bezier segments of 45 degrees, counter-clockwise, fronts inward, rho = 0.5) lit from inside by a short black lamp strip (E = 1, emitting from both sides) from (-0.6, 0.2) to (-0.2, 0.2), off centre, so the ring's direct light varies smoothly and the lamp shadows part of the interreflected light. Made for issue 12, part 5.",
    "materials": {"ring": {"reflectivity": 0.5}, "lamp": {"reflectivity": 0.0, "emittance": 1.0}},
    "curves": [
        {"id": "ring", "material": "ring", "bezier": pts},
        {"id": "lamp", "material": "lamp", "sides": "both", "line": [[-0.6, 0.2], [-0.2, 0.2]]},
    ],
}
out = os.path.join(os.path.dirname(os.path.abspath(__file__)), "lit_ring.json")
with open(out, "w") as f:
    json.dump(scene, f, indent=1)
print(out)
