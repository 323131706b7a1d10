// Curves, radiosity bands, graphs and markers: triangles whose vertices sit at a scene point plus
// an offset in pixels, so strokes keep their on-screen width at any zoom.

layout(location = 0) in vec2 a_position;  // scene units
layout(location = 1) in vec2 a_offset;    // pixels, y up
layout(location = 2) in vec4 a_colour;    // straight (not premultiplied) RGBA, display encoded

uniform vec2 u_center;
uniform float u_scale;
uniform vec2 u_viewport;

out vec4 v_colour;

void main() {
  vec2 p = (a_position - u_center) * u_scale + a_offset;
  gl_Position = vec4(2.0 * p / u_viewport, 0.0, 1.0);
  v_colour = a_colour;
}
