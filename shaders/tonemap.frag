// Exposure and tone mapping of the accumulated path light: 1 - exp(-exposure * L) keeps bright
// regions from clipping; the result is encoded for an sRGB display, with its own brightness as its
// coverage (alpha) so that dark parts of the buffer leave the background visible, and written
// premultiplied by that coverage for composite.frag to lay over the background.
// Removing paths by subtraction can leave tiny negative round-off: clamped.

in vec2 v_uv;
out vec4 o_colour;

uniform sampler2D u_hdr;
uniform float u_exposure;

void main() {
  vec3 light = max(texture(u_hdr, v_uv).rgb, vec3(0.0));
  vec3 mapped = vec3(1.0) - exp(-u_exposure * light);
  vec3 encoded = pow(mapped, vec3(1.0 / 2.2));
  float coverage = max(max(encoded.r, encoded.g), encoded.b);
  o_colour = vec4(encoded * coverage, coverage);
}
