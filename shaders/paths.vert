// Photon paths, one instance per path, drawn additively into a floating-point (HDR) buffer.
// Point rays are antialiased lines: quads 2 pixels wide whose fragments weigh the path's power by a
// tent of the distance from its centre line (1 - |d| for |d| < 1 pixel). The tent integrates to 1
// across the line, so every path puts the same light per unit of its length into the buffer at any
// angle, and a line between pixel centres is shared by both instead of jumping to one (no aliasing
// staircase, no density bias). Extended rays are quads as wide as the ray, carrying their power
// divided by their width in pixels: the same light per unit length at any angle.
// A negative colour removes a path drawn earlier (it has left the set of kept paths).

layout(location = 0) in vec4 a_ends;    // from.xy, to.xy in scene units
layout(location = 1) in vec4 a_colour;  // rgb power (weighted), a unused
layout(location = 2) in float a_width;  // ray width in scene units (0: a point ray)

uniform vec2 u_center;    // scene point at the viewport centre
uniform float u_scale;    // pixels per scene unit
uniform vec2 u_viewport;  // viewport size in pixels
uniform bool u_lines;     // point rays: antialiased lines, else quads as wide as the ray

out vec3 v_colour;
out float v_across;  // lines: distance from the centre line in pixels (-1 .. 1); quads: 0

void main() {
  vec2 from = (a_ends.xy - u_center) * u_scale;
  vec2 to = (a_ends.zw - u_center) * u_scale;
  vec2 d = to - from;
  float len = length(d);
  vec2 along = len > 0.0 ? d / len : vec2(1.0, 0.0);
  vec2 across = vec2(-along.y, along.x);
  vec2 p = (gl_VertexID & 1) == 0 ? from : to;
  float side = gl_VertexID < 2 ? -1.0 : 1.0;
  if (u_lines) {
    p += across * side;
    v_across = side;
    v_colour = a_colour.rgb;
  } else {
    float width = max(a_width * u_scale, 1.0);
    p += across * 0.5 * side * width;
    v_across = 0.0;
    v_colour = a_colour.rgb / width;
  }
  gl_Position = vec4(2.0 * p / u_viewport, 0.0, 1.0);
}
