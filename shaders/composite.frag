// The tone-mapped paths (premultiplied by their coverage, at the path buffer's resolution) laid
// over the background: bilinear upsampling of premultiplied colour, blended (one, one minus alpha).

in vec2 v_uv;
out vec4 o_colour;

uniform sampler2D u_mapped;

void main() { o_colour = texture(u_mapped, v_uv); }
