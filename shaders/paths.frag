// Additive accumulation of path power into a floating-point (HDR) target; a point ray's power
// weighted by the tent across its line (paths.vert).

in vec3 v_colour;
in float v_across;
out vec4 o_colour;

void main() { o_colour = vec4(v_colour * (1.0 - abs(v_across)), 1.0); }
