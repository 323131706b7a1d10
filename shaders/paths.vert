// Photon paths, one instance per path, drawn additively into a floating-point (HDR) buffer.
// Point rays are 1-pixel lines (two vertices per instance); their power is scaled by
// length / max(|dx|, |dy|), the path's length over the number of pixels a line rasteriser lights,
// so diagonal paths are as bright per unit length as axis-aligned ones (no line-raster density
// bias). Extended rays are quads (four vertices, a triangle strip) as wide as the ray, carrying their
// power divided by their width in pixels: the same light per unit length at any angle.
// A negative colour removes a path drawn earlier (it has left the set of kept paths).
#version 330 core

layout(location = 0) in vec4 a_ends;    // from.xy, to.xy in scene units
layout(location = 1) in vec4 a_colour;  // rgb power (weighted), a unused
layout(location = 2) in float a_width;  // ray width in scene units (0: a point ray)

uniform vec2 u_center;    // scene point at the viewport centre
uniform float u_scale;    // pixels per scene unit
uniform vec2 u_viewport;  // viewport size in pixels
uniform bool u_lines;     // point rays as lines, else quads

out vec3 v_colour;

void main() {
  vec2 from = (a_ends.xy - u_center) * u_scale;
  vec2 to = (a_ends.zw - u_center) * u_scale;
  vec2 d = to - from;
  float len = length(d);
  vec2 p;
  if (u_lines) {
    p = gl_VertexID == 0 ? from : to;
    float lit = max(abs(d.x), abs(d.y));
    v_colour = a_colour.rgb * (lit > 0.0 ? len / lit : 1.0);
  } else {
    vec2 along = len > 0.0 ? d / len : vec2(1.0, 0.0);
    vec2 across = vec2(-along.y, along.x);
    float width = max(a_width * u_scale, 1.0);
    p = (gl_VertexID & 1) == 0 ? from : to;
    p += across * (gl_VertexID < 2 ? -0.5 : 0.5) * width;
    v_colour = a_colour.rgb / width;
  }
  gl_Position = vec4(2.0 * p / u_viewport, 0.0, 1.0);
}
