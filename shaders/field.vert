// The light field (the fluence of the photons' flights on a grid over the scene, normalised on the
// CPU) as a quad over its box in scene units, drawn into the floating-point path buffer, where the
// same tone map as the paths' takes it (tonemap.frag).

uniform vec2 u_center;    // scene point at the viewport centre
uniform float u_scale;    // pixels per scene unit
uniform vec2 u_viewport;  // viewport size in pixels
uniform vec4 u_box;       // the field's box: lower.xy, upper.xy in scene units

out vec2 v_uv;

void main() {
  vec2 corner = vec2(float(gl_VertexID & 1), float((gl_VertexID >> 1) & 1));
  vec2 p = mix(u_box.xy, u_box.zw, corner);
  v_uv = corner;  // texture row 0 is the box's lower edge
  gl_Position = vec4(2.0 * (p - u_center) * u_scale / u_viewport, 0.0, 1.0);
}
